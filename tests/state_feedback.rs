//! The state-feedback controller (`kind = "state-feedback"`) and its design by
//! `deasim reduce --lqr` on the coarse `diaphragm-pid` example: the Riccati equations of the
//! design, the observer on the reduced model, a set-point step on the finite element model
//! against the open-loop step, a resumed run, and the refusals of a design that does not fit the
//! scenario.

mod common;

use deasim::api::{self, Error, RunOptions, Simulation};
use deasim::job::state::StepRecord;
use deasim::time::lqr::{design, LqrSettings, StateFeedbackDesign, Weights};
use deasim::time::riccati::{solve_dare, spectral_radius};
use nalgebra::{DMatrix, DVector};
use std::path::Path;

/// The coarse mesh and no field files or plots, as `--set` arguments.
const COARSE: [&str; 4] = [
    "mesh.radial=8",
    "mesh.layers=1",
    "output.fields_every=0",
    "output.plots=false",
];

/// The weights of the tests' design: q/r = 10, an observer that trusts the measurement
/// (v/w = 1e-2).
const WEIGHTS: Weights = Weights {
    q: 10.0,
    r: 1.0,
    w: 1.0,
    v: 1e-2,
    qi: 0.0,
};

/// The design of the coarse example about its 2 kV bias, 4 modes, sampled at 1 ms, tracking and
/// measuring the pad deflection.
fn designed() -> StateFeedbackDesign {
    let mut sim = Simulation::from_example("diaphragm-pid").unwrap();
    for s in COARSE {
        let (k, v) = s.split_once('=').unwrap();
        sim = sim.set(k, v);
    }
    let p = api::prepare(
        sim.plan().unwrap(),
        Some("top"),
        Some(2000.0),
        RunOptions::default(),
    )
    .unwrap();
    let model = p.reduced_model(4).unwrap();
    design(
        &model,
        "diaphragm-pid",
        &LqrSettings {
            weights: WEIGHTS,
            sample_time: 1e-3,
            tracked: "center_deflection".into(),
            measured: Vec::new(),
        },
    )
    .unwrap()
}

fn matrix(rows: &[Vec<f64>]) -> DMatrix<f64> {
    DMatrix::from_fn(rows.len(), rows[0].len(), |i, j| rows[i][j])
}

/// 1. The design's gains solve their Riccati equations: X of the control equation (solved again
///    here) satisfies it to round-off, K = (R + BᵀXB)⁻¹BᵀXA is the design's, and the sampled
///    closed loop A_d − B_d K and the observer's error (I − LC)A_d are stable and faster than the
///    open loop; N̄ makes the set point the model's steady state.
#[test]
fn the_design_solves_its_riccati_equations_and_stabilises_the_loop() {
    let d = designed();
    let (ad, bd, c, k, l) = (
        matrix(&d.ad),
        matrix(&d.bd),
        matrix(&d.c),
        matrix(&d.k),
        matrix(&d.l),
    );
    let n = ad.nrows();
    assert_eq!(n, 10, "4 modes and the static correction");
    let g = d.static_gains[0];
    assert!(g > 1e-10 && g < 3e-10, "{g:e} m/V");
    let c1 = c.rows(0, 1).into_owned();
    let q = c1.transpose() * &c1 * (WEIGHTS.q / (g * g));
    let r = DMatrix::from_element(1, 1, WEIGHTS.r);
    let x = solve_dare(&ad, &bd, &q, &r).unwrap();
    // the residual by the equation's own terms
    let s = &r + bd.transpose() * &x * &bd;
    let bxa = bd.transpose() * &x * &ad;
    let res = ad.transpose() * &x * &ad - bxa.transpose() * s.clone().try_inverse().unwrap() * &bxa
        + &q
        - &x;
    let rel = res.norm() / x.norm();
    eprintln!(
        "control Riccati residual {rel:e} (design file: {:e})",
        d.control_residual
    );
    assert!(rel < 1e-12, "{rel:e}");
    assert!(d.control_residual < 1e-12 && d.filter_residual < 1e-12);
    let k_again = s.try_inverse().unwrap() * &bxa;
    assert!((&k_again - &k).norm() <= 1e-10 * k.norm());
    let open = spectral_radius(&ad);
    let closed = spectral_radius(&(&ad - &bd * &k));
    let observer = spectral_radius(&((DMatrix::identity(n, n) - &l * &c1) * &ad));
    eprintln!("spectral radii: open loop {open}, closed loop {closed}, observer {observer}");
    assert!(
        open < 1.0 && closed < open && observer < open,
        "{open} {closed} {observer}"
    );
    assert!((closed - d.closed_loop_radius).abs() < 1e-12);
    // the steady state of u = N̄ r̃ − K z is z = N_x r̃ with C₁ z + D₁ ṽ = r̃
    let nx = DVector::from_column_slice(&d.nx);
    let zs = (DMatrix::identity(n, n) - &ad + &bd * &k)
        .lu()
        .solve(&(&bd * d.n_bar))
        .unwrap();
    assert!((&zs - &nx).norm() <= 1e-9 * nx.norm());
    let y = (&c1 * &zs)[(0, 0)] + d.d[0][0] * (d.n_bar - (&k * &zs)[(0, 0)]);
    assert!((y - 1.0).abs() < 1e-9, "{y}");
}

/// 2. On the sampled reduced model alone, started away from the bias while the observer starts
///    at it, the estimate converges to the state: after 100 samples its error is below 1e-8 of
///    the initial one, where the model's own prediction (no correction) keeps more than a tenth
///    of it.
#[test]
fn the_observer_converges_on_the_reduced_model() {
    let d = designed();
    let (ad, bd, c, l) = (matrix(&d.ad), matrix(&d.bd), matrix(&d.c), matrix(&d.l));
    let n = ad.nrows();
    // a state the drive leaves behind: 50 samples of a 100 V pulse
    let mut z = DVector::<f64>::zeros(n);
    for _ in 0..50 {
        z = &ad * &z + &bd * 100.0;
    }
    let e0 = z.norm();
    let (mut corrected, mut predicted) = (DVector::<f64>::zeros(n), DVector::<f64>::zeros(n));
    let mut u_prev = 0.0;
    for k in 0..100 {
        // a drive the observer knows: a slow sine
        let u = 50.0 * (0.3 * k as f64).sin();
        if k > 0 {
            z = &ad * &z + &bd * u_prev;
            corrected = &ad * &corrected + &bd * u_prev;
            predicted = &ad * &predicted + &bd * u_prev;
        }
        let y = (c.row(0) * &z)[(0, 0)];
        let innovation = y - (c.row(0) * &corrected)[(0, 0)];
        corrected += l.column(0) * innovation;
        u_prev = u;
    }
    let (ec, ep) = ((&z - &corrected).norm() / e0, (&z - &predicted).norm() / e0);
    eprintln!("estimate error after 100 samples: observer {ec:e}, prediction alone {ep:e}");
    assert!(ec < 1e-8, "{ec:e}");
    assert!(ep > 0.1, "{ep:e}");
}

/// The records of stage `hold`, with the last record before it first.
fn hold(records: &[StepRecord]) -> Vec<&StepRecord> {
    let first = records.iter().position(|r| r.stage == "hold").unwrap();
    records[first - 1..].iter().collect()
}

/// The example's text with its PID replaced by `controller` (TOML lines of the table), and
/// `extra` appended.
fn with_controller(controller: &str, extra: &str) -> String {
    let text = deasim::io::examples::example("diaphragm-pid").unwrap();
    let start = text.find("[electrodes.top.controller]").unwrap();
    let end = text.find("[electrodes.bottom]").unwrap();
    let table = if controller.is_empty() {
        String::new()
    } else {
        format!("[electrodes.top.controller]\n{controller}\n\n")
    };
    format!("{}{table}{}{extra}", &text[..start], &text[end..])
}

/// A state-feedback table on the design `model` with a set-point step of `step` at 10.5 ms
/// about the biased deflection `offset`.
fn state_feedback(model: &str, offset: f64, step: f64) -> String {
    format!(
        "kind = \"state-feedback\"\nmodel = \"{model}\"\nsetpoint = {{ waveform = \"step\", \
         offset = {offset:e}, amplitude = {step:e}, at = 0.0105 }}\nlower = 0.0\nupper = 4000.0"
    )
}

/// Writes the design of `deasim reduce --lqr` (the tests' weights) into `dir/red/lqr.json`.
fn reduce_into(dir: &Path) -> StateFeedbackDesign {
    reduce_with(dir, "red", &[])
}

/// [`reduce_into`] into `dir/out` with more arguments `extra`.
fn reduce_with(dir: &Path, out: &str, extra: &[&str]) -> StateFeedbackDesign {
    let mut args = vec![
        "reduce",
        "diaphragm-pid",
        "--lqr",
        "10,1",
        "--kalman",
        "1,1e-2",
        "--track",
        "center_deflection",
        "--out",
        out,
    ];
    for s in &COARSE[..2] {
        args.extend(["--set", s]);
    }
    args.extend(extra);
    let done = common::deasim(&args, dir);
    assert_eq!(
        done.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    let said = String::from_utf8_lossy(&done.stdout);
    assert!(said.contains("state feedback (lqr.json)"), "{said}");
    serde_json::from_str(&std::fs::read_to_string(dir.join(out).join("lqr.json")).unwrap()).unwrap()
}

fn coarse(sim: Simulation) -> Simulation {
    COARSE.iter().fold(sim, |s, kv| {
        let (k, v) = kv.split_once('=').unwrap();
        s.set(k, v)
    })
}

/// The overshoot (peak above the final value, of the final value's change) and the 2 % settling
/// time after the step at 10.5 ms of the deflection's change `y` (of the step) at times `t`.
fn step_figures(t: &[f64], y: &[f64]) -> (f64, f64) {
    let last = *y.last().unwrap();
    let peak = y.iter().copied().fold(f64::MIN, f64::max);
    let settled = t
        .iter()
        .zip(y)
        .filter(|(_, v)| (*v - last).abs() > 0.02 * last.abs())
        .map(|(t, _)| *t)
        .fold(0.0, f64::max);
    ((peak - last) / last, settled - 0.0105)
}

/// 3. A 5 nm set-point step about the 2 kV bias on the finite element model: the state feedback
///    settles within 1 % of the set point (the rest is the electrostatic force's nonlinearity in
///    the voltage, which N̄ without an integrator does not see), and damps the pad mode's ringing
///    far better than the open-loop voltage step that holds the same deflection: a third of its
///    overshoot and a quarter of its 2 % settling time.
#[test]
fn a_set_point_step_settles_and_the_pad_mode_rings_less_than_open_loop() {
    let dir = common::tempdir("state-feedback-step");
    let d = reduce_into(&dir);
    let (offset, step, g) = (d.output_offsets[0], 5e-9, d.static_gains[0]);
    let duration = "0.25";
    let closed = coarse(Simulation::from_toml(
        &with_controller(&state_feedback("red/lqr.json", offset, step), ""),
        Some(&dir),
    ))
    .set("stages.2.duration", duration);
    // open loop: the voltage that holds the step statically, stepped over the 11th millisecond
    let mut values = vec![2000.0; 11];
    values.extend(std::iter::repeat_n(2000.0 + step / g, 240));
    let controls = format!(
        "\n[[controls]]\nelectrode = \"top\"\nstage = \"hold\"\ninterval = 1e-3\nvalues = [{}]\n",
        values
            .iter()
            .map(|v| format!("{v:e}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let open = coarse(Simulation::from_toml(&with_controller("", &controls), None))
        .set("stages.2.duration", duration);
    let yi = closed
        .plan()
        .unwrap()
        .probes
        .iter()
        .position(|(n, _)| n == "center_deflection")
        .unwrap();
    let figures = |sim: &Simulation| {
        let records = sim.run(RunOptions::default()).unwrap().records;
        let rows = hold(&records);
        let t0 = rows[0].time;
        let t: Vec<f64> = rows.iter().map(|r| r.time - t0).collect();
        let y: Vec<f64> = rows
            .iter()
            .map(|r| (r.probes[yi] - offset) / step)
            .collect();
        let volts: Vec<f64> = rows.iter().map(|r| r.electrodes[1][0]).collect();
        (t, y, volts)
    };
    let (tc, yc, vc) = figures(&closed);
    let (to, yo, _) = figures(&open);
    let (over_c, settle_c) = step_figures(&tc, &yc);
    let (over_o, settle_o) = step_figures(&to, &yo);
    let last = *yc.last().unwrap();
    eprintln!(
        "closed loop: final {last:.4} of the step, overshoot {:.1} %, 2 % settling {settle_c:.4} s, \
         peak voltage {:.1} V; open loop: final {:.4}, overshoot {:.1} %, settling {settle_o:.4} s",
        100.0 * over_c,
        vc.iter().copied().fold(f64::MIN, f64::max),
        yo.last().unwrap(),
        100.0 * over_o
    );
    assert!((last - 1.0).abs() < 0.01, "final {last} of the step");
    // before the step the loop holds the bias
    assert!(yc[..10].iter().all(|y| y.abs() < 1e-6), "{:?}", &yc[..10]);
    assert!(over_o > 0.5, "open-loop overshoot {over_o}");
    assert!(over_c < over_o / 3.0, "{over_c} against {over_o}");
    assert!(
        settle_c < settle_o / 4.0,
        "{settle_c} s against {settle_o} s"
    );
    assert!(vc.iter().all(|v| (0.0..=4000.0).contains(v)));
}

/// The state-feedback loop of design `d` on its own sampled reduced model (the plant z and the
/// controller's estimate, both from the bias), for the set point `r̃(k)` about the biased output:
/// the tracked output at each of `samples` samples, the measurement taken under the voltage held
/// since the sample before (as the finite element run's record at the sample instant is).
fn reduced_loop(d: &StateFeedbackDesign, r: impl Fn(usize) -> f64, samples: usize) -> Vec<f64> {
    let (ad, bd, c, k, l) = (
        matrix(&d.ad),
        matrix(&d.bd),
        matrix(&d.c),
        matrix(&d.k),
        matrix(&d.l),
    );
    let n = ad.nrows();
    let (mut z, mut est) = (DVector::<f64>::zeros(n), DVector::<f64>::zeros(n));
    let mut held = 0.0;
    let mut out = Vec::new();
    for i in 0..samples {
        let y = (c.row(0) * &z)[(0, 0)] + d.d[0][0] * held;
        out.push(y);
        let predicted = if i == 0 {
            DVector::zeros(n)
        } else {
            &ad * &est + &bd * held
        };
        est = &predicted + l.column(0) * (y - d.d[0][0] * held - (c.row(0) * &predicted)[(0, 0)]);
        let u = d.n_bar * r(i) - (&k * &est)[(0, 0)];
        z = &ad * &z + &bd * u;
        held = u;
    }
    out
}

/// 3b. The state-feedback loop on the finite element model follows the same loop on the sampled
///     reduced model it was designed on: within 2 % of a 5 nm set-point step at every sample.
#[test]
fn the_loop_on_the_fe_model_follows_the_loop_on_the_reduced_model() {
    let dir = common::tempdir("state-feedback-follows");
    let d = reduce_into(&dir);
    let (offset, step) = (d.output_offsets[0], 5e-9);
    let sim = coarse(Simulation::from_toml(
        &with_controller(&state_feedback("red/lqr.json", offset, step), ""),
        Some(&dir),
    ))
    .set("stages.2.duration", "0.15");
    let yi = sim
        .plan()
        .unwrap()
        .probes
        .iter()
        .position(|(n, _)| n == "center_deflection")
        .unwrap();
    let records = sim.run(RunOptions::default()).unwrap().records;
    let fe: Vec<f64> = hold(&records)
        .iter()
        .map(|r| r.probes[yi] - offset)
        .collect();
    // the step at 10.5 ms is first sampled at 11 ms
    let rom = reduced_loop(&d, |k| if k >= 11 { step } else { 0.0 }, fe.len());
    let worst = fe
        .iter()
        .zip(&rom)
        .map(|(a, b)| (a - b).abs() / step)
        .fold(0.0, f64::max);
    eprintln!("largest difference {:.3} % of the step", 100.0 * worst);
    assert!(worst < 0.02, "{:.3} % of the step", 100.0 * worst);
    assert!((rom[rom.len() - 1] / step - 1.0).abs() < 1e-3);
}

/// 4. A constant disturbance (the feed-forward 200 V above the bias, the set point at the biased
///    deflection): the state feedback without an integrator keeps a finite part of the
///    disturbance's open-loop deflection; with integral action (`--integral 25000`) the
///    deflection returns to the set point (below 1e-6 of it after 1 s).
#[test]
fn integral_action_rejects_a_constant_disturbance() {
    let dir = common::tempdir("state-feedback-integral");
    let plain = reduce_with(&dir, "plain", &[]);
    let integral = reduce_with(&dir, "integral", &["--integral", "25000"]);
    assert_eq!(plain.k_i, 0.0);
    assert!(integral.k_i != 0.0 && integral.closed_loop_radius < 1.0);
    let offset = plain.output_offsets[0];
    let open_loop = 200.0 * plain.static_gains[0];
    let error = |model: &str| {
        let sim = coarse(Simulation::from_toml(
            &with_controller(
                &(state_feedback(model, offset, 0.0) + "\nfeedforward = 200.0"),
                "",
            ),
            Some(&dir),
        ))
        .set("stages.2.duration", "1.0");
        let yi = sim
            .plan()
            .unwrap()
            .probes
            .iter()
            .position(|(n, _)| n == "center_deflection")
            .unwrap();
        let records = sim.run(RunOptions::default()).unwrap().records;
        (records.last().unwrap().probes[yi] - offset) / open_loop
    };
    let (without, with) = (error("plain/lqr.json"), error("integral/lqr.json"));
    eprintln!("steady error of the disturbance's deflection: {without:e} without, {with:e} with integral action");
    assert!(without > 0.1 && without < 0.9, "{without}");
    assert!(with.abs() < 1e-6, "{with:e}");
}

/// The key and message of a refused scenario.
fn refused(sim: &Simulation) -> (String, String) {
    match sim.plan() {
        Err(Error::Input(e)) => (e.key.clone().unwrap_or_default(), e.to_string()),
        Err(e) => panic!("not an input error: {e}"),
        Ok(_) => panic!("accepted"),
    }
}

/// 5. A design that does not fit the scenario is refused naming the key `model` and the reason:
///    another electrode, a measured probe the scenario lacks, another bias, a sample period
///    below the step, a file that is no design; so are a PID's keys, a quasi-static stage, and
///    `reduce --lqr` without a tracked output, with an unknown one, with malformed weights or
///    with integral action on an output it does not measure. The CLI exits with 2. A scenario
///    whose design file does not exist yet is reduced (open loop) and then accepted.
#[test]
fn a_design_that_does_not_fit_is_refused_naming_the_key() {
    let dir = common::tempdir("state-feedback-refused");
    let d = reduce_into(&dir);
    let offset = d.output_offsets[0];
    let key = "electrodes.top.controller";
    let model_key = format!("{key}.model");
    let variant = |name: &str, change: &dyn Fn(&mut StateFeedbackDesign)| {
        let mut bad = d.clone();
        change(&mut bad);
        std::fs::write(dir.join(name), serde_json::to_string_pretty(&bad).unwrap()).unwrap();
        coarse(Simulation::from_toml(
            &with_controller(&state_feedback(name, offset, 5e-9), ""),
            Some(&dir),
        ))
    };
    std::fs::write(dir.join("junk.json"), "{\"electrode\": \"top\"}").unwrap();
    let cases: Vec<(Simulation, String, &str)> = vec![
        (
            variant("electrode.json", &|m| m.electrode = "bottom".into()),
            model_key.clone(),
            "was designed for electrode `bottom`, not `top`",
        ),
        (
            variant("probe.json", &|m| {
                m.measured = vec!["deflection".into()];
                m.outputs = vec!["deflection".into()];
                m.tracked = "deflection".into();
            }),
            model_key.clone(),
            "measures probe `deflection`, which the scenario does not have",
        ),
        (
            variant("bias.json", &|m| m.bias_v = 2100.0),
            model_key.clone(),
            "designed about a bias of 2100 V; electrode `top` is at 2000 V",
        ),
        (
            variant("slow.json", &|m| m.sample_time = 1e-4),
            model_key.clone(),
            "shorter than the time step 0.001 s of stage `hold`",
        ),
        (
            coarse(Simulation::from_toml(
                &with_controller(&state_feedback("junk.json", offset, 5e-9), ""),
                Some(&dir),
            )),
            model_key.clone(),
            "not a state-feedback design of `deasim reduce --lqr`",
        ),
        (
            coarse(Simulation::from_toml(
                &with_controller(&state_feedback("none.json", offset, 5e-9), ""),
                Some(&dir),
            )),
            model_key.clone(),
            "cannot read",
        ),
        (
            coarse(Simulation::from_toml(
                &with_controller(
                    &(state_feedback("red/lqr.json", offset, 5e-9) + "\nkp = 1.0"),
                    "",
                ),
                Some(&dir),
            )),
            format!("{key}.kp"),
            "not a key of a state feedback",
        ),
        (
            coarse(Simulation::from_toml(
                &with_controller(&state_feedback("red/lqr.json", offset, 5e-9), ""),
                Some(&dir),
            ))
            .set("stages.2.kind", "\"quasi-static\""),
            key.to_string(),
            "stage `hold` is quasi-static",
        ),
    ];
    for (sim, k, message) in cases {
        let (got_key, got) = refused(&sim);
        assert_eq!(got_key, k, "{got}");
        assert!(got.contains(message), "{got}");
    }
    // through the CLI: `check` exits with 2 naming the key; the good design is listed
    let scenario = |model: &str| {
        let path = dir.join(format!("sf-{}.toml", model.replace('/', "-")));
        std::fs::write(
            &path,
            with_controller(&state_feedback(model, offset, 5e-9), ""),
        )
        .unwrap();
        path
    };
    let check = |path: &Path| {
        let mut args = vec!["check", path.to_str().unwrap(), "--no-trial"];
        for s in &COARSE {
            args.extend(["--set", s]);
        }
        common::deasim(&args, &dir)
    };
    let out = check(&scenario("electrode.json"));
    assert_eq!(out.status.code(), Some(2));
    let err =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&model_key) && err.contains("electrode `bottom`"),
        "{err}"
    );
    let ok = check(&scenario("red/lqr.json"));
    assert_eq!(
        ok.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let said = String::from_utf8_lossy(&ok.stdout);
    assert!(
        said.contains("controller: state feedback from `red/lqr.json`"),
        "{said}"
    );
    // a scenario whose design is not written yet is reduced open loop, which writes it
    let pending = scenario("later/lqr.json");
    let mut args = vec![
        "reduce",
        pending.to_str().unwrap(),
        "--lqr",
        "10,1",
        "--track",
        "center_deflection",
        "--out",
        "later",
    ];
    for s in &COARSE[..2] {
        args.extend(["--set", s]);
    }
    assert_eq!(check(&pending).status.code(), Some(2));
    let reduced = common::deasim(&args, &dir);
    assert_eq!(
        reduced.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&reduced.stderr)
    );
    assert_eq!(check(&pending).status.code(), Some(0));
    // `reduce --lqr` needs a tracked output among the probes
    for (extra, message) in [
        (vec![], "--lqr needs --track PROBE"),
        (
            vec!["--track", "deflection"],
            "--track: `deflection` is not a probe",
        ),
        (
            vec!["--track", "center_deflection", "--kalman", "1"],
            "--kalman: expected",
        ),
        (
            vec![
                "--track",
                "center_deflection",
                "--measure",
                "charge",
                "--integral",
                "1",
            ],
            "integral action integrates the measured error of `center_deflection`: measure it too",
        ),
    ] {
        let mut args = vec!["reduce", "diaphragm-pid", "--lqr", "1,1", "--out", "bad"];
        args.extend(extra);
        let out = common::deasim(&args, &dir);
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(message), "{err}");
    }
}

/// 6. A run resumed from a checkpoint inside the controlled stage ends with the same history,
///    bit for bit, as the run that went on: the estimate, the held output, the sample clock and
///    the noise generator are in the run state.
#[test]
fn a_resumed_run_continues_the_state_feedback_bitwise() {
    let dir = common::tempdir("state-feedback-resume");
    let d = reduce_into(&dir);
    let scenario = dir.join("sf.toml");
    std::fs::write(
        &scenario,
        with_controller(
            &(state_feedback("red/lqr.json", d.output_offsets[0], 5e-9)
                + "\nnoise = 1e-10\nseed = 5"),
            "",
        ),
    )
    .unwrap();
    let mut args = vec![
        "run",
        scenario.to_str().unwrap(),
        "--out",
        "full",
        "--checkpoint-every",
        "30",
        "--set",
        "stages.2.duration=0.1",
    ];
    for s in &COARSE {
        args.extend(["--set", s]);
    }
    let full = common::deasim(&args, &dir);
    assert_eq!(
        full.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&full.stderr)
    );
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
    // the checkpoint was taken inside the controlled stage, after its first samples
    let history = read("full", "history.csv");
    let hold_rows = history.lines().filter(|l| l.contains(",hold,")).count();
    let total = history.lines().count() - 1;
    assert!(
        total - hold_rows < 60 && hold_rows > 60,
        "{total} {hold_rows}"
    );
    // the noise reached the loop: the voltage moves about the bias before the set point's step
    let volts = read("full", "electrodes.csv");
    let column = volts
        .lines()
        .next()
        .unwrap()
        .split(',')
        .position(|h| h == "voltage:top")
        .unwrap();
    let before: Vec<f64> = volts
        .lines()
        .filter(|l| l.contains(",hold,"))
        .take(10)
        .map(|l| l.split(',').nth(column).unwrap().parse().unwrap())
        .collect();
    let spread = before
        .iter()
        .map(|v| (v - 2000.0).abs())
        .fold(0.0, f64::max);
    assert!(spread > 0.1, "{before:?}");
}
