//! Charge-controlled electrodes whose charge follows a waveform or a control: the forward run
//! against the voltage-driven run whose charge history it replays, its energy balance, and the
//! adjoint of a charge control against finite differences.

mod common;
use common::gradient::assert_checked;
use deasim::api::{
    ControlQuantity, GradientOptions, GradientReport, Results, RunOptions, Simulation,
};
use std::path::Path;

/// The film of `film-vibration` (a quarter of a 10 × 10 × 1 mm neo-Hookean film with mass) on
/// 2 × 2 × 1 hex8 cells: a static stage `bias` then its 10 ms of dynamics `vibrate` (Δt set by
/// the caller), with the top electrode's drive `top` (a TOML line `voltage = …` or
/// `charge = …`).
fn film(top: &str) -> String {
    let text = deasim::io::examples::example("film-vibration").unwrap();
    let step = "voltage = { waveform = \"step\", amplitude = 20e3, at = 0.0 }";
    let stage = "[[stages]]\nname = \"vibrate\"";
    assert!(
        text.contains(step) && text.contains(stage),
        "the example changed"
    );
    text.replace(step, top).replace(
        stage,
        &format!("[[stages]]\nname = \"bias\"\nkind = \"static\"\nsteps = 4\n\n{stage}"),
    )
}

fn run(text: &str, dir: &Path, dt: f64) -> Results {
    Simulation::from_toml(text, Some(dir))
        .with_overrides(&[
            "mesh.divisions=[2, 2, 1]".into(),
            format!("stages.1.dt={dt}"),
        ])
        .run(RunOptions::default())
        .unwrap()
}

/// The rows of stage `name`: (time, column values).
fn stage_rows(r: &Results, name: &str, column: &str) -> Vec<(f64, f64)> {
    let time = r.history.column("time").unwrap();
    let values = r.history.column(column).unwrap();
    r.history
        .stage
        .iter()
        .enumerate()
        .filter(|(_, s)| *s == name)
        .map(|(i, _)| (time[i], values[i]))
        .collect()
}

/// A film driven by a voltage sine about 8 kV, and the same film driven by the charge history
/// that run recorded (a table through the charges at its step ends): the charges agree at the
/// step ends, and the motions differ by the midpoint step's different drive (the voltage at
/// t_{n+½} against the charge interpolated there), an error that falls as Δt². The charge run's
/// energy balance (the source's work −Q·ΔΦ among the boundary work) drifts as Δt² too.
#[test]
fn a_charge_history_replays_the_voltage_driven_motion() {
    let dir = tempfile::tempdir().unwrap();
    let voltage = film(
        "voltage = { waveform = \"sine\", amplitude = 2000.0, offset = 8000.0, frequency = 200.0 }",
    );
    let mut errors = Vec::new();
    let mut drifts = Vec::new();
    for dt in [1e-4, 5e-5] {
        let v = run(&voltage, dir.path(), dt);
        let bias = *stage_rows(&v, "bias", "probe:charge").last().unwrap();
        let vibrate = stage_rows(&v, "vibrate", "probe:charge");
        let t0 = bias.0;
        // stage time; the bias stage (1 s) ends at the table's last point, its charge
        let mut csv = format!("time,value\n0,{:e}\n", bias.1);
        for (t, q) in &vibrate {
            csv += &format!("{:e},{:e}\n", t - t0, q);
        }
        csv += &format!("1.0,{:e}\n", bias.1);
        std::fs::write(dir.path().join("q.csv"), csv).unwrap();
        let q = run(
            &film("charge = { waveform = \"table\", file = \"q.csv\" }"),
            dir.path(),
            dt,
        );
        // the same charges at every step end (the table's knots), within the projection's Newton
        // tolerance
        let charges = stage_rows(&q, "vibrate", "probe:charge");
        assert_eq!(charges.len(), vibrate.len());
        for (a, b) in charges.iter().zip(&vibrate) {
            assert!((a.1 - b.1).abs() <= 1e-10 * b.1.abs(), "{a:?} vs {b:?}");
        }
        // the motion: the largest difference of the top face's displacement over the stage,
        // against the range the voltage-driven run covers
        let (uv, uq) = (
            stage_rows(&v, "vibrate", "probe:thickness_stretch"),
            stage_rows(&q, "vibrate", "probe:thickness_stretch"),
        );
        let range = uv.iter().map(|p| p.1).fold(f64::MIN, f64::max)
            - uv.iter().map(|p| p.1).fold(f64::MAX, f64::min);
        let error = uv
            .iter()
            .zip(&uq)
            .map(|(a, b)| (a.1 - b.1).abs())
            .fold(0.0, f64::max);
        assert!(range > 1e-4, "the film hardly moves: {range:e} in stretch");
        errors.push(error / range);
        let energy = stage_rows(&q, "vibrate", "energy_error");
        let drift = energy.iter().map(|p| p.1).fold(f64::MIN, f64::max)
            - energy.iter().map(|p| p.1).fold(f64::MAX, f64::min);
        let kinetic = stage_rows(&q, "vibrate", "kinetic")
            .iter()
            .map(|p| p.1)
            .fold(0.0, f64::max);
        drifts.push(drift / kinetic);
    }
    println!("motion errors {errors:?}, energy drifts {drifts:?}");
    // measured: 1.8·10⁻³, then 4.4·10⁻⁴ of the range; drifts 4.0·10⁻³, then 1.0·10⁻³ of the
    // largest kinetic energy
    assert!(errors[1] < 2e-3, "motion errors {errors:?}");
    assert!(errors[0] / errors[1] > 3.5, "motion errors {errors:?}");
    assert!(drifts[1] < 2e-3, "energy drifts {drifts:?}");
    assert!(drifts[0] / drifts[1] > 3.5, "energy drifts {drifts:?}");
}

/// The gradient of a misfit of the film's thickness over a quasi-static and a dynamic stage, in
/// μ, εᵣ, the charge waveform's amplitude and offset (through the bias stage's end value and
/// the knots' start) and the knots of a charge control in each stage (the film's charge follows
/// a sine about its bias, so the run moves), with the midpoint or the Newmark step: against central
/// differences (h = 3·10⁻⁵·|p| for the parameters, 3·10⁻⁵ of the largest charge for the knots)
/// and the Taylor test. (J is strongly nonlinear in the charge: the difference's truncation
/// error of the first knot of `vibrate` measured 9.9·10⁻⁶ at 3·10⁻⁴ and 1.1·10⁻⁶ at 10⁻⁴,
/// falling as h².)
fn charge_controlled(integrator: &str) -> GradientReport {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("d.csv"), "time,value\n0,0.992\n9,0.992\n").unwrap();
    let base = film(
        "charge = { waveform = \"sine\", amplitude = 4e-9, offset = 3.2e-8, frequency = 200.0 }",
    );
    // a quasi-static stage between the bias and the dynamics
    let base = base.replace(
        "[[stages]]\nname = \"vibrate\"",
        "[[stages]]\nname = \"creep\"\nkind = \"quasi-static\"\nduration = 0.01\nsteps = 5\n\n\
         [[stages]]\nname = \"vibrate\"",
    );
    let text = format!(
        r#"{base}
[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.permittivity"
[[parameters]]
path = "electrodes.top.charge.amplitude"
[[parameters]]
path = "electrodes.top.charge.offset"
[[controls]]
electrode = "top"
stage = "creep"
interval = 2.5e-3
[[controls]]
electrode = "top"
stage = "vibrate"
interval = 1e-3
[[objective]]
kind = "probe-misfit"
probe = "thickness_stretch"
stage = "creep"
data = "d.csv"
weight = 1e10
[[objective]]
kind = "probe-misfit"
probe = "thickness_stretch"
stage = "vibrate"
data = "d.csv"
weight = 1e10
"#
    );
    Simulation::from_toml(&text, Some(dir.path()))
        .with_overrides(&[
            "mesh.divisions=[2, 2, 1]".into(),
            "stages.2.dt=1e-4".into(),
            format!("stages.2.integrator=\"{integrator}\""),
            "solver.newton_rtol=1e-13".into(),
        ])
        .gradient(&GradientOptions {
            check: true,
            fd_step: Some(3e-5),
            ..Default::default()
        })
        .unwrap()
}

fn check_charge_controls(integrator: &str) {
    let r = charge_controlled(integrator);
    assert_checked(&r, 1e-6);
    assert_eq!(r.controls.len(), 2);
    for c in &r.controls {
        assert_eq!(c.quantity, ControlQuantity::Charge);
        assert!(c.gradient.iter().any(|g| *g != 0.0));
        assert!(c.finite_differences.len() >= 2, "{}", c.stage);
        for &(k, fd, h) in &c.finite_differences {
            let rel = (c.gradient[k] - fd).abs() / fd.abs();
            assert!(
                rel <= 1e-6,
                "{} knot {k}: adjoint {:e}, central difference {fd:e} (h = {h:e} C): {rel:e}",
                c.stage,
                c.gradient[k]
            );
        }
    }
}

#[test]
fn charge_controls_match_finite_differences_midpoint() {
    check_charge_controls("midpoint");
}

#[test]
fn charge_controls_match_finite_differences_newmark() {
    check_charge_controls("newmark");
}

/// Bad input about charges that follow waveforms is refused naming the key.
#[test]
fn bad_charge_drives_are_refused() {
    let bad = |top: &str, extra: &str| -> String {
        let text = format!("{}{extra}", film(top));
        match Simulation::from_toml(&text, None).plan() {
            Ok(_) => panic!("accepted: {top} {extra}"),
            Err(e) => e.to_string(),
        }
    };
    let e = bad("charge = { waveform = \"sine\", amplitude = 1e-9 }", "");
    assert!(e.contains("electrodes.top.charge"), "{e}");
    let e = bad(
        "charge = { waveform = \"ramp\", amplitude = 1e-9, offset = nan }",
        "",
    );
    assert!(
        e.contains("electrodes.top.charge.offset") && e.contains("C"),
        "{e}"
    );
    let e = bad(
        "charge = 1e-8",
        "[[controls]]\nelectrode = \"top\"\nstage = \"vibrate\"\nlower = 2e-8\nupper = 1e-8\n",
    );
    assert!(e.contains("controls.0.upper") && e.contains(" C"), "{e}");
}
