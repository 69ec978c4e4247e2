//! The PID controller of an electrode (`electrodes.<e>.controller`) on the coarse `diaphragm-pid`
//! example: the sampled loop on the finite element model against the same loop on the reduced
//! model, disturbance rejection, output limits with anti-windup, reproducible noise, the energy
//! balance, and the refusals of bad input.

mod common;

use deasim::api::{self, Error, RunOptions, Simulation};
use deasim::job::state::StepRecord;
use deasim::time::reduced::ReducedModel;
use nalgebra::{DMatrix, DVector};

/// The coarse `diaphragm-pid` (8 radial cells, 1 layer) without field files or plots.
fn coarse() -> Simulation {
    Simulation::from_example("diaphragm-pid")
        .unwrap()
        .set("mesh.radial", "8")
        .set("mesh.layers", "1")
        .set("output.fields_every", "0")
        .set("output.plots", "false")
}

/// The controller's key `k` set to `v`.
fn with(sim: Simulation, k: &str, v: impl ToString) -> Simulation {
    sim.set(&format!("electrodes.top.controller.{k}"), &v.to_string())
}

/// The records of the controlled stage `hold`, with the last record before it (the state the
/// stage starts from) first.
fn hold(records: &[StepRecord]) -> Vec<&StepRecord> {
    let first = records.iter().position(|r| r.stage == "hold").unwrap();
    records[first - 1..].iter().collect()
}

/// The index of probe `name` in the plan of `sim`.
fn probe(sim: &Simulation, name: &str) -> usize {
    let plan = sim.plan().unwrap();
    plan.probes.iter().position(|(n, _)| n == name).unwrap()
}

/// The top electrode's applied voltage in a record (`electrodes.csv`'s `voltage:top`).
fn top_voltage(sim: &Simulation, r: &StepRecord) -> f64 {
    let plan = sim.plan().unwrap();
    let e = plan
        .electrodes
        .iter()
        .position(|e| e.name == "top")
        .unwrap();
    r.electrodes[e][0]
}

fn run(sim: &Simulation) -> Vec<StepRecord> {
    sim.run(RunOptions::default()).unwrap().records
}

/// The reduced model about the 2 kV bias with 4 modes, the deflection's row and its static
/// gain (m/V).
fn reduced() -> (ReducedModel, usize, f64) {
    let p = api::prepare(
        coarse().plan().unwrap(),
        Some("top"),
        Some(2000.0),
        RunOptions::default(),
    )
    .unwrap();
    let m = p.reduced_model(4).unwrap();
    let row = m
        .outputs
        .iter()
        .position(|n| n == "center_deflection")
        .unwrap();
    let (a, b, c, d) = matrices(&m, row);
    let gain = d - (c.transpose() * a.lu().solve(&b).unwrap())[0];
    (m, row, gain)
}

/// A, B, the output row `row` of C (as a column) and its D.
fn matrices(m: &ReducedModel, row: usize) -> (DMatrix<f64>, DVector<f64>, DVector<f64>, f64) {
    let n = m.a.len();
    let a = DMatrix::from_fn(n, n, |i, j| m.a[i][j]);
    let b = DVector::from_fn(n, |i, _| m.b[i][0]);
    let c = DVector::from_fn(n, |j, _| m.c[row][j]);
    (a, b, c, m.d[row][0])
}

/// The PI loop of the example on the reduced model, sampled every `period` s for `samples`
/// samples, the plant's input held between samples (exact discretisation: the exponential of
/// [[A, B], [0, 0]]·T). The law is the controller's: e_k = r_k − y_k, u_k = u_ff + kp e_k + I_k,
/// I_{k+1} = I_k + ki T e_k (no limit reached). Returns y_k, the output at each sample.
#[allow(clippy::too_many_arguments)]
fn reduced_loop(
    m: &ReducedModel,
    row: usize,
    (kp, ki): (f64, f64),
    period: f64,
    setpoint: impl Fn(f64) -> f64,
    feedforward: f64,
    samples: usize,
) -> Vec<f64> {
    let (a, b, c, d) = matrices(m, row);
    let n = a.nrows();
    let mut aug = DMatrix::zeros(n + 1, n + 1);
    aug.view_mut((0, 0), (n, n)).copy_from(&(&a * period));
    aug.view_mut((0, n), (n, 1)).copy_from(&(&b * period));
    let e = aug.exp();
    let phi = e.view((0, 0), (n, n)).into_owned();
    let gamma = e.view((0, n), (n, 1)).column(0).into_owned();
    let (offset, bias) = (m.output_offsets[row], m.bias_v);
    let mut z = DVector::zeros(n);
    let (mut integral, mut held) = (0.0, bias);
    let mut out = Vec::new();
    for k in 0..samples {
        let t = k as f64 * period;
        // the potential still at the held voltage of the previous sample
        let y = offset + c.dot(&z) + d * (held - bias);
        out.push(y);
        let err = setpoint(t) - y;
        held = feedforward + kp * err + integral;
        integral += ki * period * err;
        z = &phi * &z + &gamma * (held - bias);
    }
    out
}

/// 1. A small set-point step: the PI loop on the finite element model follows the same sampled
///    loop on the reduced model (4 modes and the static correction about the 2 kV bias) within
///    2 % of the step at every sample.
#[test]
fn the_loop_on_the_fe_model_follows_the_loop_on_the_reduced_model() {
    let (m, row, gain) = reduced();
    assert!(gain > 0.0, "{gain}");
    let y_bias = m.output_offsets[row];
    let step = 2e-8;
    let (kp, ki) = (0.2 / gain, 20.0 / gain);
    let (at, duration) = (0.0105, 0.25);
    let sim = with(
        with(
            with(with(coarse(), "setpoint.offset", y_bias), "setpoint.at", at),
            "kp",
            kp,
        ),
        "ki",
        ki,
    )
    .set("stages.2.duration", &duration.to_string());
    let yi = probe(&sim, "center_deflection");
    let records = run(&sim);
    let fe: Vec<f64> = hold(&records).iter().map(|r| r.probes[yi]).collect();
    let setpoint = |t: f64| y_bias + if t >= at { step } else { 0.0 };
    let rom = reduced_loop(&m, row, (kp, ki), 1e-3, setpoint, 2000.0, fe.len());
    let mut worst: f64 = 0.0;
    for (k, (a, b)) in fe.iter().zip(&rom).enumerate() {
        let d = (a - b).abs() / step;
        assert!(
            d <= 0.02,
            "sample {k} (t = {} s): FE {a:e}, reduced {b:e}: {:.2} % of the step",
            k as f64 * 1e-3,
            100.0 * d
        );
        worst = worst.max(d);
    }
    // the step was followed: the pad moved most of the way in both models
    let last = fe.len() - 1;
    assert!((fe[last] - y_bias) > 0.8 * step, "{:e}", fe[last] - y_bias);
    eprintln!("largest difference {:.3} % of the step", 100.0 * worst);
}

/// 2. A constant disturbance (the feedforward 200 V above the bias): the PI loop brings the
///    deflection back to its set point (steady error below 1e-3 of the disturbance's open-loop
///    deflection); the P loop leaves a finite error.
#[test]
fn the_pi_loop_rejects_a_constant_disturbance() {
    let (m, row, gain) = reduced();
    let y_bias = m.output_offsets[row];
    let open_loop = 200.0 * gain;
    let base = with(
        with(
            with(coarse(), "setpoint.amplitude", 0.0),
            "setpoint.offset",
            y_bias,
        ),
        "feedforward",
        2200.0,
    )
    .set("stages.2.duration", "1.5");
    let yi = probe(&base, "center_deflection");
    let error = |sim: &Simulation| {
        let records = run(sim);
        (records.last().unwrap().probes[yi] - y_bias) / open_loop
    };
    let pi = error(&with(
        with(base.clone(), "kp", 0.2 / gain),
        "ki",
        20.0 / gain,
    ));
    let p = error(&with(with(base, "kp", 0.2 / gain), "ki", 0.0));
    eprintln!("steady error: PI {pi:e}, P {p:e} of the disturbance's deflection");
    assert!(pi.abs() < 1e-3, "PI: {pi:e} of the disturbance");
    // kp·gain = 0.2: the P loop keeps 1/(1 + 0.2) of the open-loop deflection
    assert!((p - 1.0 / 1.2).abs() < 0.05, "P: {p:e} of the disturbance");
}

/// 3. A set point beyond reach saturates the output: the voltage stays within its limits at
///    every step, and with the integrator held while saturated the loop leaves the limit within
///    a few samples once the set point comes back (a wound-up integral of ~ki·0.1 s·error would
///    hold it there for seconds).
#[test]
fn the_output_limits_hold_and_the_integrator_does_not_wind_up() {
    let (m, row, _) = reduced();
    let y_bias = m.output_offsets[row];
    let dir = common::tempdir("controller-limits");
    // up by 1 µm (far beyond 2.1 kV) from 0.02 s to 0.12 s, then back to the bias deflection
    std::fs::write(
        &*dir.join("setpoint.csv"),
        format!(
            "time,value\n0,{y_bias}\n0.0195,{y_bias}\n0.0196,{0}\n0.1195,{0}\n0.1196,{y_bias}\n",
            y_bias + 1e-6
        ),
    )
    .unwrap();
    let text = deasim::io::examples::example("diaphragm-pid").unwrap();
    let line = text.lines().find(|l| l.starts_with("setpoint = ")).unwrap();
    let text = text.replace(
        line,
        "setpoint = { waveform = \"table\", file = \"setpoint.csv\" }",
    );
    let sim = Simulation::from_toml(&text, Some(&dir))
        .set("mesh.radial", "8")
        .set("mesh.layers", "1")
        .set("output.fields_every", "0")
        .set("output.plots", "false")
        .set("stages.2.duration", "0.2");
    let sim = with(with(sim, "upper", 2100.0), "lower", 1900.0);
    let records = run(&sim);
    let rows = hold(&records);
    let volts: Vec<f64> = rows.iter().map(|r| top_voltage(&sim, r)).collect();
    assert!(volts.iter().all(|v| (1900.0..=2100.0).contains(v)));
    // saturated while the set point is out of reach
    let at = |t: f64| (t / 1e-3).round() as usize;
    assert!(volts[at(0.03)..at(0.12)].iter().all(|&v| v == 2100.0));
    // back within the limits a few samples after the set point returns at 0.1196 s
    let leaves = (at(0.12)..volts.len())
        .find(|&k| volts[k] < 2100.0)
        .unwrap();
    assert!(
        leaves <= at(0.12) + 3,
        "still saturated {} samples after",
        leaves - at(0.12)
    );
}

/// 4. Measurement noise with a seed: two runs are equal bit for bit, another seed differs.
#[test]
fn noise_is_reproducible_with_its_seed() {
    let noisy = |seed: u64| {
        let sim = with(
            with(coarse(), "noise", 1e-9).set("stages.2.duration", "0.02"),
            "seed",
            seed,
        );
        let records = run(&sim);
        hold(&records)
            .iter()
            .map(|r| top_voltage(&sim, r).to_bits())
            .collect::<Vec<_>>()
    };
    let (a, b, c) = (noisy(3), noisy(3), noisy(4));
    assert_eq!(a, b);
    assert_ne!(a, c);
    let quiet = {
        let sim = coarse().set("stages.2.duration", "0.02");
        let records = run(&sim);
        hold(&records)
            .iter()
            .map(|r| top_voltage(&sim, r).to_bits())
            .collect::<Vec<_>>()
    };
    assert_ne!(a, quiet);
}

/// The key and message of a refused scenario.
fn refused(sim: &Simulation) -> (String, String) {
    match sim.plan() {
        Err(Error::Input(e)) => (e.key.clone().unwrap_or_default(), e.to_string()),
        Err(e) => panic!("not an input error: {e}"),
        Ok(_) => panic!("accepted"),
    }
}

/// 5. Bad input names the key: a grounded electrode, an unknown probe, a sample time below the
///    step, lower ≥ upper, an unknown kind, a negative gain, no gain, charge- and circuit-driven
///    electrodes, a `[[controls]]` table on the same electrode and stage; the gradient refuses a
///    controller; the CLI exits with 2.
#[test]
fn bad_controllers_are_refused_naming_the_key() {
    let key = "electrodes.top.controller";
    let cases: Vec<(Simulation, String, &str)> = vec![
        (
            with(coarse(), "probe", "\"deflection\""),
            format!("{key}.probe"),
            "unknown probe `deflection`",
        ),
        (
            with(coarse(), "sample_time", 1e-4),
            format!("{key}.sample_time"),
            "shorter than the time step 0.001 s of stage `hold`",
        ),
        (
            with(coarse(), "lower", 4000.0),
            format!("{key}.upper"),
            "must exceed `lower`",
        ),
        (
            with(coarse(), "kind", "\"pdi\""),
            format!("{key}.kind"),
            "unknown controller kind `pdi` (known: pid, state-feedback); did you mean `pid`?",
        ),
        (
            with(coarse(), "ki", -1.0),
            format!("{key}.ki"),
            "must be a finite number ≥ 0",
        ),
        (
            with(with(coarse(), "kp", 0.0), "ki", 0.0),
            format!("{key}.kp"),
            "every gain is 0",
        ),
        (
            coarse().set("electrodes.top.voltage", "0.0"),
            key.to_string(),
            "electrode `top` is grounded",
        ),
        (
            coarse().set("stages.2.electrodes_on", "false"),
            key.to_string(),
            "no dynamic or quasi-static stage with its electrodes on",
        ),
    ];
    for (sim, k, message) in cases {
        let (got_key, got) = refused(&sim);
        assert_eq!(got_key, k, "{got}");
        assert!(got.contains(message), "{got}");
    }
    let text = deasim::io::examples::example("diaphragm-pid").unwrap();
    let bias_line = "voltage = 2000.0              # V: the bias";
    assert!(text.contains(bias_line));
    for (drive, what) in [
        ("charge = 1e-9 #", "charge-controlled"),
        (
            "circuit = { source = 2000.0, resistance = 1e6 } #",
            "driven through a circuit",
        ),
    ] {
        let sim = Simulation::from_toml(&text.replace(bias_line, drive), None);
        let (got_key, got) = refused(&sim);
        assert_eq!(got_key, key, "{got}");
        assert!(got.contains(what), "{got}");
    }
    let controls =
        format!("{text}\n[[controls]]\nelectrode = \"top\"\nstage = \"hold\"\ninterval = 0.1\n");
    let (got_key, got) = refused(&Simulation::from_toml(&controls, None));
    assert_eq!(got_key, key, "{got}");
    assert!(
        got.contains("`[[controls]]` table in stage `hold` too"),
        "{got}"
    );
    // the adjoint of a feedback loop is not built
    let plan = coarse().plan().unwrap();
    let e = deasim::adjoint::sweep::check_supported(&plan).unwrap_err();
    assert!(e.contains("electrode `top` has a controller"), "{e}");
    // through the CLI: exit status 2 with the key
    let dir = common::tempdir("controller-cli");
    let out = common::deasim(
        &[
            "check",
            "diaphragm-pid",
            "--no-trial",
            "--set",
            "electrodes.top.controller.sample_time=1e-4",
        ],
        &dir,
    );
    assert_eq!(out.status.code(), Some(2));
    let err =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("electrodes.top.controller.sample_time"),
        "{err}"
    );
    // a good one is listed by `check`
    let ok = common::deasim(&["check", "diaphragm-pid", "--no-trial"], &dir);
    assert_eq!(ok.status.code(), Some(0));
    let said = String::from_utf8_lossy(&ok.stdout);
    assert!(
        said.contains("controller: PID on probe `center_deflection`"),
        "{said}"
    );
}

/// 6. The energy balance under the controller: the source's work on the electrode is
///    accounted as for a waveform drive. The same voltages given as a `table` waveform (held
///    over each step) leave the same energy error, and it stays a small fraction of the work
///    the electrode's source does.
#[test]
fn the_energy_balance_stays_closed_under_the_controller() {
    let sim = coarse().set("stages.2.duration", "0.1");
    let records = run(&sim);
    let rows = hold(&records);
    let volts: Vec<f64> = rows.iter().map(|r| top_voltage(&sim, r)).collect();
    let dt = 1e-3;
    // the voltage over step k (from t_k to t_k+1) is the one recorded at t_k+1; held from just
    // after t_k, so that the midpoint and the end of the step see it
    let mut table = String::from("time,value\n0,2000\n");
    for (k, v) in volts.iter().enumerate().skip(1) {
        let t0 = (k - 1) as f64 * dt;
        table.push_str(&format!("{},{v}\n{},{v}\n", t0 + 1e-3 * dt, t0 + dt));
    }
    // back at the bias by stage time 1 s: the end of the static stage `bias`, whose ramp
    // takes the electrode to its value there
    table.push_str("0.9,2000\n");
    let dir = common::tempdir("controller-energy");
    std::fs::write(&*dir.join("drive.csv"), table).unwrap();
    // the example without its controller, the top electrode following the table
    let text = deasim::io::examples::example("diaphragm-pid").unwrap();
    let start_of = text.find("[electrodes.top.controller]").unwrap();
    let end_of = text.find("[electrodes.bottom]").unwrap();
    let waveform = (text[..start_of].to_string() + &text[end_of..]).replace(
        "voltage = 2000.0              # V: the bias",
        "voltage = { waveform = \"table\", file = \"drive.csv\" } #",
    );
    let table_sim = Simulation::from_toml(&waveform, Some(&dir))
        .set("mesh.radial", "8")
        .set("mesh.layers", "1")
        .set("output.fields_every", "0")
        .set("output.plots", "false")
        .set("stages.2.duration", "0.1");
    let table_records = run(&table_sim);
    let table_rows = hold(&table_records);
    assert_eq!(table_rows.len(), rows.len());
    let drift = |rows: &[&StepRecord]| {
        rows.last().unwrap().energies.energy_error - rows[0].energies.energy_error
    };
    let (ours, theirs) = (drift(&rows), drift(&table_rows));
    for (a, b) in rows.iter().zip(&table_rows) {
        let (va, vb) = (top_voltage(&sim, a), top_voltage(&table_sim, b));
        assert!((va - vb).abs() <= 1e-9 * va.abs(), "{va} {vb}");
    }
    assert!(
        (ours - theirs).abs() <= 1e-3 * theirs.abs() + 1e-18,
        "energy error {ours:e} J under the controller, {theirs:e} J under the table"
    );
    // the electrode's source work over the stage: Σ ½(V_n + V_n+1)(Q_n+1 − Q_n)
    let work: f64 = rows
        .windows(2)
        .map(|w| {
            let top = |r: &StepRecord| r.electrodes[1];
            let (a, b) = (top(w[0]), top(w[1]));
            0.5 * (a[0] + b[0]) * (b[1] - a[1])
        })
        .map(f64::abs)
        .sum();
    eprintln!("energy error drift {ours:e} J (table drive {theirs:e} J), source work {work:e} J");
    assert!(work > 0.0);
    assert!(ours.abs() < 1e-2 * work, "{ours:e} J against {work:e} J");
}

/// A quasi-static stage runs the loop too: without inertia the PI loop settles the deflection
/// on a set-point step, with the integrator removing the error of the P part.
#[test]
fn a_quasi_static_stage_runs_the_loop() {
    let (m, row, gain) = reduced();
    let y_bias = m.output_offsets[row];
    let step = 2e-8;
    let sim = with(
        with(
            with(with(coarse(), "setpoint.offset", y_bias), "kp", 0.2 / gain),
            "ki",
            20.0 / gain,
        ),
        "setpoint.at",
        0.0105,
    )
    .set("stages.2.kind", "\"quasi-static\"")
    .set("stages.2.duration", "0.5");
    let yi = probe(&sim, "center_deflection");
    let records = run(&sim);
    let rows = hold(&records);
    assert!(rows.iter().skip(1).all(|r| r.stage == "hold"));
    // before the step the loop holds the bias; after it the deflection goes to the set point
    let volts: Vec<f64> = rows.iter().map(|r| top_voltage(&sim, r)).collect();
    assert!((volts[5] - 2000.0).abs() < 1e-3, "{}", volts[5]);
    let last = rows.last().unwrap().probes[yi];
    assert!(
        ((last - y_bias) / step - 1.0).abs() < 1e-3,
        "{:e} of the step",
        (last - y_bias) / step
    );
    assert!(volts.last().unwrap() > &2050.0);
}

/// A run resumed from a checkpoint inside the controlled stage ends with the same history,
/// bit for bit, as the run that went on: the integral, the filtered derivative, the last
/// measurement, the held output, the sample clock and the noise generator are in the run state.
#[test]
fn a_resumed_run_continues_the_loop_bitwise() {
    let dir = common::tempdir("controller-resume");
    let scenario = dir.join("pid.toml");
    std::fs::write(
        &scenario,
        deasim::io::examples::example("diaphragm-pid").unwrap(),
    )
    .unwrap();
    let sets = [
        "mesh.radial=8",
        "mesh.layers=1",
        "output.fields_every=0",
        "output.plots=false",
        "stages.2.duration=0.1",
        "electrodes.top.controller.kd=1e6",
        "electrodes.top.controller.derivative_filter=2e-3",
        "electrodes.top.controller.noise=1e-9",
        "electrodes.top.controller.seed=11",
        "electrodes.top.controller.sample_time=2.5e-3",
    ];
    let mut args = vec![
        "run",
        scenario.to_str().unwrap(),
        "--out",
        "full",
        "--checkpoint-every",
        "30",
    ];
    for s in &sets {
        args.extend(["--set", s]);
    }
    let full = common::deasim(&args, &dir);
    assert_eq!(full.status.code(), Some(0));
    let mut ck: Vec<_> = std::fs::read_dir(dir.join("full/checkpoint"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "bin"))
        .collect();
    ck.sort();
    assert_eq!(ck.len(), 2);
    let cut = dir.join("cut");
    std::fs::create_dir_all(cut.join("checkpoint")).unwrap();
    std::fs::copy(
        &ck[0],
        cut.join("checkpoint").join(ck[0].file_name().unwrap()),
    )
    .unwrap();
    let resumed = common::deasim(&["run", "--resume", "cut"], &dir);
    assert_eq!(
        resumed.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&resumed.stderr)
    );
    let read = |d: &str, f: &str| std::fs::read_to_string(dir.join(d).join(f)).unwrap();
    for f in ["history.csv", "electrodes.csv"] {
        let (a, b) = (read("full", f), read("cut", f));
        assert_eq!(a.lines().count(), b.lines().count(), "{f}");
        for (i, (x, y)) in a.lines().zip(b.lines()).enumerate() {
            assert_eq!(x, y, "{f} line {i}");
        }
    }
    // the checkpoint was taken inside the controlled stage
    let history = read("full", "history.csv");
    let hold_rows = history.lines().filter(|l| l.contains(",hold,")).count();
    let total = history.lines().count() - 1;
    assert!(
        total - hold_rows < 60 && hold_rows > 60,
        "{total} {hold_rows}"
    );
}
