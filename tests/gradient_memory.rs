//! The gradient under a memory budget: the dynamic stages beyond it are recomputed from
//! checkpoints, and J, dJ/dp and dJ/dV at a control's knots come out bit for bit as when every
//! state is held, while the tape holds at most the budget plus two units (a taped step or a
//! checkpoint, the larger).

mod common;

use deasim::api::{Error, GradientOptions, GradientReport, Simulation};

/// The gradient of `sim` with the memory budget `memory` (bytes).
fn gradient(sim: &Simulation, memory: usize) -> GradientReport {
    sim.gradient(&GradientOptions {
        memory: Some(memory),
        ..Default::default()
    })
    .unwrap()
}

/// Runs `sim` holding every state and under `budget`: the same J, derivatives and control
/// derivatives, bit for bit; the first recomputes nothing, the second more than its steps
/// (the schedule recomputes some steps more than once), within its bound.
fn same_under_budget(sim: &Simulation, budget: usize) -> (GradientReport, GradientReport) {
    let all = gradient(sim, usize::MAX / 4);
    let tight = gradient(sim, budget);
    assert_eq!(all.recomputed_steps, 0);
    let steps: usize = sim
        .plan()
        .unwrap()
        .stages
        .iter()
        .filter(|s| matches!(s.kind, deasim::job::plan::StageKind::Dynamic { .. }))
        .map(|s| s.kind.nominal_steps(s.duration))
        .sum();
    assert!(
        tight.recomputed_steps > steps,
        "{} steps recomputed of {steps}",
        tight.recomputed_steps
    );
    assert_eq!(all.objective, tight.objective);
    assert!(all.objective > 0.0);
    assert_eq!(all.parameters.len(), tight.parameters.len());
    for (a, b) in all.parameters.iter().zip(&tight.parameters) {
        assert_eq!(a.gradient, b.gradient, "{}", a.path);
        assert!(
            a.gradient != 0.0,
            "{}: a zero derivative checks nothing",
            a.path
        );
    }
    assert_eq!(all.controls.len(), tight.controls.len());
    for (a, b) in all.controls.iter().zip(&tight.controls) {
        assert_eq!(a.gradient, b.gradient, "control of {}", a.electrode);
    }
    // held beyond the budget: at most two units
    let (step, checkpoint) = tight.unit_bytes;
    assert!(step > 0 && checkpoint > 0);
    let bound = budget + 2 * step.max(checkpoint);
    assert!(
        tight.tape_bytes <= bound,
        "peak {} B above the budget {budget} B + 2 × {} B",
        tight.tape_bytes,
        step.max(checkpoint)
    );
    // holding every state takes more than the budget
    assert!(all.tape_bytes > bound, "{} B", all.tape_bytes);
    (all, tight)
}

/// The vibrating film (Kelvin–Voigt viscosity) over 80 steps under `integrator`: a misfit of
/// its thickness stretch, its in-plane stretch at the end, the field penalty and the kinetic
/// energy at the end.
fn vibrating_film(integrator: &str, dir: &std::path::Path) -> Simulation {
    let base = deasim::io::examples::example("film-vibration").unwrap();
    std::fs::write(
        dir.join("d.csv"),
        "time,value\n0,1\n0.002,0.97\n0.004,0.95\n",
    )
    .unwrap();
    let text = format!(
        "{base}\n{}",
        r#"
[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.viscosity"
[[parameters]]
path = "electrodes.top.voltage.amplitude"

[[objective]]
kind = "probe-misfit"
probe = "thickness_stretch"
data = "d.csv"
weight = 100.0

[[objective]]
kind = "probe-final"
probe = "inplane_stretch"
target = 1.02
weight = 100.0

[[objective]]
kind = "field-penalty"
limit = 1.0e7
weight = 1e-6

[[objective]]
kind = "rest"
weight = 1e3
"#
    );
    Simulation::from_toml(&text, Some(dir)).with_overrides(&[
        "mesh.divisions=[2, 2, 1]".into(),
        "stages.0.duration=4e-3".into(),
        "stages.0.dt=5e-5".into(),
        format!("stages.0.integrator=\"{integrator}\""),
        "materials.elastomer.viscosity=50.0".into(),
        "solver.newton_rtol=1e-13".into(),
    ])
}

/// The midpoint step (its projection of the potential) recomputed.
#[test]
fn midpoint_film_recomputed_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    same_under_budget(&vibrating_film("midpoint", dir.path()), 30_000);
}

/// A run of a scenario with an objective (`deasim run`) tapes its states within the scenario's
/// `gradient.memory` too, and reads J by recomputing from checkpoints beyond it: the same J, bit
/// for bit, as a run that holds every state and as the gradient's.
#[test]
fn a_run_beyond_its_budget_reads_its_objective_from_checkpoints() {
    let dir = tempfile::tempdir().unwrap();
    let sim = vibrating_film("midpoint", dir.path());
    let objective = |sim: &Simulation| {
        let mut tape = sim.objective_tape().unwrap().unwrap();
        sim.run(deasim::api::RunOptions {
            observers: vec![tape.observer()],
            ..Default::default()
        })
        .unwrap();
        (tape.value().unwrap(), tape.peak_bytes())
    };
    let (all, all_bytes) = objective(&sim.clone().set("gradient.memory", "1000000000"));
    let (tight, tight_bytes) = objective(&sim.clone().set("gradient.memory", "30000"));
    let g = gradient(&sim, 30_000);
    assert!(all > 0.0);
    assert_eq!(all, tight);
    assert_eq!(all, g.objective);
    let (step, checkpoint) = g.unit_bytes;
    assert!(
        tight_bytes <= 30_000 + 2 * step.max(checkpoint),
        "{tight_bytes} B held"
    );
    assert!(
        all_bytes > 30_000 + 2 * step.max(checkpoint),
        "{all_bytes} B"
    );
}

/// `sim`'s gradient under `budget` on one thread and on two: the same J and derivatives, bit for
/// bit, none of them zero. Returns the one-thread report.
fn same_on_one_and_two_threads(sim: &Simulation, budget: usize, case: &str) -> GradientReport {
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| gradient(sim, budget))
    };
    let (one, two) = (on(1), on(2));
    assert!(one.objective > 0.0);
    assert_eq!(one.objective, two.objective, "{case}");
    for (a, b) in one.parameters.iter().zip(&two.parameters) {
        assert!(
            a.gradient != 0.0,
            "{case}, {}: a zero derivative checks nothing",
            a.path
        );
        assert_eq!(a.gradient, b.gradient, "{case}, {}", a.path);
    }
    assert_eq!(one.controls.len(), two.controls.len());
    for (a, b) in one.controls.iter().zip(&two.controls) {
        assert!(
            a.gradient.iter().all(|g| *g != 0.0),
            "{case}: {}",
            a.electrode
        );
        assert_eq!(a.gradient, b.gradient, "{case}: control of {}", a.electrode);
    }
    one
}

/// A dynamic stage's sweep evaluates the Jacobians of the step before the current one while the
/// current one's solves run, on a second thread where there is one: one thread and two give the
/// same J and derivatives, bit for bit, with every state held and with the steps recomputed from
/// checkpoints, under both integrators, and for a control's knots.
#[test]
fn one_thread_and_two_give_the_same_gradient() {
    let dir = tempfile::tempdir().unwrap();
    for integrator in ["midpoint", "newmark"] {
        let sim = vibrating_film(integrator, dir.path());
        for budget in [usize::MAX / 4, 30_000] {
            let r = same_on_one_and_two_threads(&sim, budget, integrator);
            assert_eq!(r.parameters.len(), 3);
        }
    }
    let sim = controlled_diaphragm(dir.path());
    let r = same_on_one_and_two_threads(&sim, usize::MAX / 4, "controlled diaphragm");
    assert_eq!(r.controls.len(), 1);
}

/// The Newmark step (its consistent start acceleration from the stage's start) recomputed.
#[test]
fn newmark_film_recomputed_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    same_under_budget(&vibrating_film("newmark", dir.path()), 30_000);
}

/// The axisymmetric diaphragm, pre-stretched and loaded in static stages, then 60 steps of its
/// square wave (midpoint) with the top electrode's voltage a control with knots every 10 ms:
/// its deflection's history against data, its deflection at the end relative to the stage's
/// start, and the drive's effort; dJ/dV at the knots as well as dJ/dp.
#[test]
fn controlled_diaphragm_recomputed_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let sim = controlled_diaphragm(dir.path());
    let (all, _) = same_under_budget(&sim, 200_000);
    assert!(all.controls[0].gradient.iter().all(|g| *g != 0.0));
}

/// The diaphragm of [`controlled_diaphragm_recomputed_bit_for_bit`], its data written into `dir`.
fn controlled_diaphragm(dir: &std::path::Path) -> Simulation {
    std::fs::write(dir.join("d.csv"), "time,value\n0,3.0e-4\n1.06,3.1e-4\n").unwrap();
    let base = deasim::io::examples::example("diaphragm").unwrap();
    let text = format!(
        "{base}\n{}",
        r#"
[[parameters]]
path = "materials.vhb.c10"
[[parameters]]
path = "loads.rigid.0.mass"
[[parameters]]
path = "prestretch.stretch"

[[controls]]
electrode = "top"
stage = "actuate"
interval = 0.01

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "actuate"
data = "d.csv"
weight = 1e8

[[objective]]
kind = "probe-final"
probe = "center_deflection"
stage = "actuate"
relative = true
target = 1e-5
weight = 1e8

[[objective]]
kind = "drive-effort"
stage = "actuate"
electrode = "top"
weight = 1e-9
"#
    );
    Simulation::from_toml(&text, Some(dir)).with_overrides(&[
        "stages.1.duration=0.06".into(),
        "solver.newton_rtol=1e-13".into(),
        "output.plots=false".into(),
    ])
}

/// The viscoelastic diaphragm (three Maxwell branches): stretched and held in real time, the
/// mass hung, then 40 steps of the square wave, whose points the recomputation commits again.
#[test]
fn viscoelastic_diaphragm_recomputed_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("d.csv"),
        "time,value\n2.0,1.0e-3\n2.02,1.1e-3\n2.04,1.2e-3\n",
    )
    .unwrap();
    let base = deasim::io::examples::example("diaphragm-visco").unwrap();
    let text = format!(
        "{base}\n{}",
        r#"
[[parameters]]
path = "materials.vhb.branches.0.mu"
[[parameters]]
path = "materials.vhb.branches.2.tau"
[[parameters]]
path = "materials.vhb.density"
[[parameters]]
path = "electrodes.top.voltage.amplitude"

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "actuate"
data = "d.csv"
weight = 1e6
"#
    );
    let sim = Simulation::from_toml(&text, Some(dir.path())).with_overrides(&[
        "mesh.radial=6".into(),
        "prestretch.steps=8".into(),
        "prestretch.duration=0.5".into(),
        "prestretch.hold=0.5".into(),
        "prestretch.hold_steps=2".into(),
        "stages.0.steps=2".into(),
        "stages.1.duration=0.04".into(),
        "output.plots=false".into(),
        "solver.newton_rtol=1e-13".into(),
    ]);
    same_under_budget(&sim, 450_000);
}

/// A budget that is not a size is refused naming `gradient.memory`, by the library and by the
/// command line (exit status 2); a size with a unit is read.
#[test]
fn bad_memory_budgets_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let sim = vibrating_film("midpoint", dir.path()).with_overrides(&[
        "stages.0.duration=1e-3".into(),
        "gradient.memory=\"lots\"".into(),
    ]);
    match sim.gradient(&GradientOptions::default()) {
        Err(Error::Input(e)) => {
            let m = e.to_string();
            assert!(m.contains("gradient.memory") && m.contains("lots"), "{m}");
        }
        other => panic!("expected an input error, got {other:?}"),
    }
    for bad in ["-5", "0", "\"12 parsecs\""] {
        let s = sim.clone().set("gradient.memory", bad);
        match s.gradient(&GradientOptions::default()) {
            Err(Error::Input(e)) => assert!(e.to_string().contains("gradient.memory"), "{e}"),
            other => panic!("{bad}: expected an input error, got {other:?}"),
        }
    }
    let r = sim
        .clone()
        .set("gradient.memory", "\"64 KiB\"")
        .gradient(&GradientOptions::default())
        .unwrap();
    assert_eq!(r.memory_budget, 65_536);
    let r = sim
        .clone()
        .set("gradient.memory", "3e6")
        .gradient(&GradientOptions::default())
        .unwrap();
    assert_eq!(r.memory_budget, 3_000_000);

    let scenario = dir.path().join("f.toml");
    let text = format!(
        "{}\n[gradient]\nmemory = \"1 GiB\"\n",
        deasim::io::examples::example("film-vibration").unwrap()
    )
    .replace("duration = 0.01", "duration = 1e-4");
    std::fs::write(
        &scenario,
        text + "[[parameters]]\npath = \"materials.elastomer.mu\"\n[[objective]]\nkind = \
                \"rest\"\nweight = 1.0\n",
    )
    .unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args(["gradient", "f.toml", "--memory", "a lot", "--out", "o"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("gradient.memory"), "{stderr}");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args(["gradient", "f.toml", "--memory", "100 kB", "--out", "o"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("o/gradient.json")).unwrap())
            .unwrap();
    assert_eq!(json["memory_budget"], 100_000);
    assert!(json["recomputed_steps"].is_u64());
    assert!(json["peak_memory"].as_u64().unwrap() > 0);
}

/// A recomputed level that differs from the forward run's is an error, not a wrong gradient:
/// the tape's checkpoint moved by 10⁻¹² m stops the sweep.
#[test]
fn a_recomputation_that_departs_from_the_run_is_refused() {
    use deasim::adjoint::{objective::Objective, sweep::gradient, tape::Tape};
    let dir = tempfile::tempdir().unwrap();
    let sim = vibrating_film("midpoint", dir.path());
    let scenario = sim.scenario().unwrap();
    let plan = sim.plan().unwrap();
    let objective = Objective::build(&scenario, &plan, "film", Some(dir.path())).unwrap();
    let path = "materials.elastomer.mu";
    let parameters = vec![(
        path.to_string(),
        deasim::io::build::parameter(&scenario, "film", path).unwrap(),
    )];
    let mut tape = Tape::with_budget(&plan, 30_000);
    deasim::api::run_plan(
        &plan,
        deasim::api::RunOptions {
            observers: vec![&mut tape],
            ..Default::default()
        },
    )
    .unwrap();
    let stage = &tape.stages[0];
    assert!(stage.is_checkpointed());
    let replay = stage.replay.as_ref().unwrap();
    assert!(replay.checkpoints.len() >= 2);
    let g = gradient(&plan, &tape, &objective, &parameters, &[Vec::new()]).unwrap();
    assert!(g.recomputed_steps > stage.count());
    // a displacement of a node the supports leave free, at the second checkpoint (the last
    // segment starts there)
    let free = stage.last_step().v.iter().position(|v| *v != 0.0).unwrap();
    let replay = tape.stages[0].replay.as_mut().unwrap();
    replay.checkpoints[1].record.state[free] += 1e-12;
    let e = gradient(&plan, &tape, &objective, &parameters, &[Vec::new()]).unwrap_err();
    assert!(e.contains("differs from the forward run's"), "{e}");
}

/// Two dynamic stages, both recomputed: the second starts from the first's last level (its
/// positions, velocities and accelerations carry the derivatives back), and a relative term on
/// the second reads the first's last step.
#[test]
fn two_dynamic_stages_recomputed_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let base = deasim::io::examples::example("film-vibration").unwrap();
    let text = format!(
        "{base}\n{}",
        r#"
[[stages]]
name = "ring"
kind = "dynamic"
duration = 2e-3
dt = 5e-5
integrator = "newmark"

[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.viscosity"
[[parameters]]
path = "electrodes.top.voltage.amplitude"

[[objective]]
kind = "probe-final"
probe = "thickness_stretch"
stage = "vibrate"
target = 0.97
weight = 100.0

[[objective]]
kind = "probe-misfit"
probe = "inplane_stretch"
stage = "ring"
relative = true
target = 0.001
weight = 100.0
"#
    );
    let sim = Simulation::from_toml(&text, Some(dir.path())).with_overrides(&[
        "mesh.divisions=[2, 2, 1]".into(),
        "stages.0.duration=3e-3".into(),
        "stages.0.dt=5e-5".into(),
        "materials.elastomer.viscosity=50.0".into(),
        "solver.newton_rtol=1e-13".into(),
    ]);
    same_under_budget(&sim, 40_000);
}

/// The vibrating film driven through a circuit (a 20 kV step source through R = 10⁸ Ω), both
/// integrators: the circuit's coupling enters the step's matrix, which a restart refactors at
/// its resume point, and the charge each step takes from Gauss's law at its start is recomputed
/// with the steps.
#[test]
fn a_circuit_driven_film_recomputed_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let step = "{ waveform = \"step\", amplitude = 20e3, at = 0.0 }";
    let base = common::circuit_instead_of(
        deasim::io::examples::example("film-vibration").unwrap(),
        step,
        step,
        1e8,
    );
    assert!(base.contains("resistance = 1e8"));
    let text = format!(
        "{base}\n{}",
        r#"
[[parameters]]
path = "electrodes.top.circuit.resistance"
[[parameters]]
path = "electrodes.top.circuit.source.amplitude"
[[parameters]]
path = "materials.elastomer.mu"

[[objective]]
kind = "probe-final"
probe = "thickness_stretch"
target = 0.9
weight = 100.0
"#
    );
    for integrator in ["midpoint", "newmark"] {
        let sim = Simulation::from_toml(&text, Some(dir.path())).with_overrides(&[
            "mesh.divisions=[2, 2, 1]".into(),
            "stages.0.duration=4e-3".into(),
            "stages.0.dt=5e-5".into(),
            format!("stages.0.integrator=\"{integrator}\""),
            "materials.elastomer.viscosity=50.0".into(),
            "solver.newton_rtol=1e-13".into(),
        ]);
        same_under_budget(&sim, 30_000);
    }
}
