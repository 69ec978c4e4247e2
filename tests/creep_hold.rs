//! The creep-hold problem of a viscoelastic actuator (`diaphragm-creep-hold`, VHB 4910 with
//! three Maxwell branches): under a constant 3 kV the pad creeps for the whole minute; the
//! optimised drive (`deasim control`, through the adjoint of the branches) holds it where the
//! step put it after 1 s, and so, within microns, does the sampled PI loop of
//! `diaphragm-creep-pi`.

use deasim::api::{ControlOptions, Results, RunOptions, Simulation};

/// The pad deflection (m) and the voltage (V) at each step of the `hold` stage, and the
/// deflection at its start.
fn hold(r: &Results) -> (Vec<f64>, Vec<f64>, f64) {
    let h = &r.history;
    let d = h.column("probe:center_deflection").unwrap();
    let v = h.column("voltage").unwrap();
    let first = h.stage.iter().position(|s| s == "hold").unwrap();
    let pick = |x: &[f64]| -> Vec<f64> {
        h.stage
            .iter()
            .zip(x)
            .filter(|(s, _)| *s == "hold")
            .map(|(_, &x)| x)
            .collect()
    };
    (pick(d), pick(v), d[first - 1])
}

/// The move the objective asks for (m): the pad 0.19 mm below the loaded state.
const MOVE: f64 = 1.9e-4;

#[test]
fn the_optimised_drive_holds_the_pad_against_the_creep_of_a_constant_voltage() {
    let sim = Simulation::from_example("diaphragm-creep-hold")
        .unwrap()
        .with_overrides(&["output.fields_every=0".into(), "output.plots=false".into()]);
    // the constant 3 kV: the pad creeps by more than 0.15 mm after the first second
    let constant = sim.run(RunOptions::default()).unwrap();
    let (d, v, start) = hold(&constant);
    assert!(v.iter().all(|&v| v == 3000.0), "{v:?}");
    let creep = d[d.len() - 1] - d[0];
    println!(
        "constant 3 kV: {:.1} µm after 1 s, creeps {:.1} µm more in 59 s",
        1e6 * (d[0] - start),
        1e6 * creep
    );
    assert!(creep > 1.5e-4, "{creep:e}");
    assert!((d[0] - start - MOVE).abs() < 5e-6, "{}", d[0] - start);
    // the optimised drive: within 1 nm of the target at every step, the voltage falling as the
    // branches relax, within its bounds
    let o = sim.control(&ControlOptions::default(), |_| {}).unwrap();
    assert!(o.converged, "{}", o.reason);
    let (d, v, start) = hold(&o.results);
    let worst = d
        .iter()
        .map(|d| (d - start - MOVE).abs())
        .fold(0.0f64, f64::max);
    println!(
        "optimised: worst {:.2e} m off the target in {} iterations, {:.0} V … {:.0} V",
        worst,
        o.history.len() - 1,
        v[0],
        v[v.len() - 1]
    );
    assert!(worst < 1e-9, "{worst:e}");
    assert!(v.iter().all(|&v| (0.0..=5000.0).contains(&v)), "{v:?}");
    assert!(
        v[v.len() - 1] < 0.8 * v[0],
        "{} against {}",
        v[v.len() - 1],
        v[0]
    );
}

#[test]
fn the_pi_loop_holds_the_pad_within_microns() {
    let r = Simulation::from_example("diaphragm-creep-pi")
        .unwrap()
        .with_overrides(&["output.fields_every=0".into(), "output.plots=false".into()])
        .run(RunOptions::default())
        .unwrap();
    let (d, v, start) = hold(&r);
    let time = r.history.column("time").unwrap();
    let t0 = time[r.history.stage.iter().position(|s| s == "hold").unwrap()] - 1.0;
    let times: Vec<f64> = r
        .history
        .stage
        .iter()
        .zip(time)
        .filter(|(s, _)| *s == "hold")
        .map(|(_, &t)| t - t0)
        .collect();
    let err: Vec<f64> = d.iter().map(|d| d - start - MOVE).collect();
    let after = |t: f64| {
        err.iter()
            .zip(&times)
            .filter(|(_, &s)| s >= t)
            .map(|(e, _)| e.abs())
            .fold(0.0f64, f64::max)
    };
    println!(
        "PI: peak {:.1} µm, within {:.2} µm after 10 s, {:.2} µm at 60 s; {:.0} V at the end",
        1e6 * after(0.0),
        1e6 * after(10.0),
        1e6 * err[err.len() - 1].abs(),
        v[v.len() - 1]
    );
    assert!(after(0.0) < 3e-5, "{:e}", after(0.0));
    assert!(after(10.0) < 1e-5, "{:e}", after(10.0));
    assert!(err[err.len() - 1].abs() < 3e-6, "{:e}", err[err.len() - 1]);
    assert!(v.iter().all(|&v| (0.0..=4000.0).contains(&v)), "{v:?}");
}
