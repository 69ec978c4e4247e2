//! The gradient of a run's objective by the discrete adjoint against central finite
//! differences and the Taylor remainder test.
//!
//! The finite differences use h = 10⁻⁴·|p|: their truncation error (∝ h²) is then about 10⁻⁸ of
//! the derivative, and the forward solves, converged to a relative residual of 10⁻¹³, add an
//! error of about 10⁻¹³/10⁻⁴ = 10⁻⁹; a relative difference of 10⁻⁶ leaves a margin for both.

mod common;
use common::gradient::{assert_checked, checked_film_vibration};
use deasim::api::{Error, GradientOptions, GradientReport, Simulation};

/// The film example (a quarter of a 10 × 10 × 1 mm film) with the parameters and objective of
/// `extra`, on a coarse mesh, its top electrode ramped to 20 kV in 5 steps.
fn film(extra: &str, dir: &std::path::Path) -> Simulation {
    let base = deasim::io::examples::example("film").unwrap();
    let text = format!("{base}\n{extra}");
    Simulation::from_toml(&text, Some(dir)).with_overrides(&[
        "mesh.divisions=[2, 2, 1]".into(),
        "stages.0.steps=5".into(),
        "electrodes.top.voltage.amplitude=20e3".into(),
        "solver.newton_rtol=1e-13".into(),
    ])
}

/// A static film: the thickness stretch at the end against a target and its history against
/// data, in μ, Λ, εᵣ and the voltage amplitude.
#[test]
fn static_film_gradient_matches_finite_differences() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("data.csv"),
        "time,value\n0,1\n0.5,0.99\n1,0.96\n",
    )
    .unwrap();
    let sim = film(
        r#"
[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.lambda"
[[parameters]]
path = "materials.elastomer.permittivity"
[[parameters]]
path = "electrodes.top.voltage.amplitude"

[[objective]]
kind = "probe-final"
probe = "thickness_stretch"
target = 0.9
weight = 100.0

[[objective]]
kind = "probe-misfit"
probe = "inplane_stretch"
data = "data.csv"
"#,
        dir.path(),
    );
    let r = sim
        .gradient(&GradientOptions {
            check: true,
            ..Default::default()
        })
        .unwrap();
    assert!(r.objective > 0.0);
    assert_checked(&r, 1e-6);
}

/// The field penalty (the breakdown margin) of the static film above 15 MV/m, alone: its
/// derivatives in μ, εᵣ and the voltage amplitude through every step's state.
#[test]
fn static_field_penalty_gradient_matches_finite_differences() {
    let dir = tempfile::tempdir().unwrap();
    let sim = film(
        r#"
[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.permittivity"
[[parameters]]
path = "electrodes.top.voltage.amplitude"

[[objective]]
kind = "field-penalty"
limit = 1.5e7
weight = 1e-6
"#,
        dir.path(),
    );
    let r = sim
        .gradient(&GradientOptions {
            check: true,
            ..Default::default()
        })
        .unwrap();
    println!("field penalty J = {:e}", r.objective);
    assert!(r.objective > 0.0);
    assert_checked(&r, 1e-6);
}

/// Two stages: the film charged, then released by a second static stage with its electrodes
/// off; the objective reads the release, which starts from the charged state, so the voltage
/// reaches it through the supports' start values.
#[test]
fn a_later_stage_carries_the_derivative_of_the_one_before() {
    let dir = tempfile::tempdir().unwrap();
    let sim = film(
        r#"
[[stages]]
name = "release"
kind = "static"
steps = 3
electrodes_on = false

[[parameters]]
path = "electrodes.top.voltage.amplitude"
[[parameters]]
path = "materials.elastomer.mu"

[[objective]]
kind = "probe-misfit"
probe = "thickness_stretch"
stage = "release"
data = "d.csv"
"#,
        dir.path(),
    );
    std::fs::write(dir.path().join("d.csv"), "time,value\n1,0.9\n2,0.95\n").unwrap();
    let r = sim
        .gradient(&GradientOptions {
            check: true,
            ..Default::default()
        })
        .unwrap();
    assert_checked(&r, 1e-6);
}

/// What the adjoint does not cover yet, and bad objectives, are refused naming the key.
#[test]
fn unsupported_and_bad_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let bad = |extra: &str| film(extra, dir.path()).gradient(&GradientOptions::default());
    let probe_final =
        "[[objective]]\nkind = \"probe-final\"\nprobe = \"thickness_stretch\"\ntarget = 1.0\n";
    let e = bad(&format!(
        "[[parameters]]\npath = \"mesh.divisions\"\n{probe_final}"
    ))
    .unwrap_err();
    assert!(matches!(e, Error::Input(_)), "{e}");
    assert!(e.to_string().contains("mesh.divisions"), "{e}");
    let e = bad("[[parameters]]\npath = \"materials.elastomer.mu\"\n[[objective]]\nkind = \"probe-final\"\nprobe = \"capacitance\"\ntarget = 1.0\n").unwrap_err();
    assert!(
        e.to_string()
            .contains("`capacitance` is not differentiated"),
        "{e}"
    );
    let e = bad("[[parameters]]\npath = \"materials.elastomer.mu\"\n[[objective]]\nkind = \"probe-misfit\"\nprobe = \"thickness_stretch\"\ndata = \"missing.csv\"\n").unwrap_err();
    assert!(e.to_string().contains("missing.csv"), "{e}");
    let e = bad(&format!("[[parameters]]\npath = \"materials.elastomer.mu\"\n{probe_final}[[objective]]\nkind = \"field-penalty\"\n")).unwrap_err();
    assert!(e.to_string().contains("objective.1.limit"), "{e}");
    let e = bad(&format!("[[parameters]]\npath = \"materials.elastomer.mu\"\n{probe_final}[[objective]]\nkind = \"field-penalty\"\nlimit = -1.0\n")).unwrap_err();
    assert!(e.to_string().contains("objective.1.limit"), "{e}");
    let e = bad(&format!("[[parameters]]\npath = \"materials.elastomer.mu\"\n{probe_final}[[objective]]\nkind = \"field-penalty\"\nlimit = 1e7\nprobe = \"charge\"\n")).unwrap_err();
    assert!(e.to_string().contains("objective.1.probe"), "{e}");
    let e = bad(&format!("[[parameters]]\npath = \"materials.elastomer.mu\"\n{probe_final}[[objective]]\nkind = \"rest\"\n")).unwrap_err();
    assert!(e.to_string().contains("objective.1.stage"), "{e}");
    let e = bad(&format!("[[parameters]]\npath = \"materials.elastomer.mu\"\n{probe_final}[[objective]]\nkind = \"drive-effort\"\nelectrode = \"top\"\n")).unwrap_err();
    assert!(e.to_string().contains("objective.1.electrode"), "{e}");
    let e = bad(probe_final).unwrap_err();
    assert!(e.to_string().contains("parameters"), "{e}");
}

/// The axisymmetric balloon (mean-dilatation kernel) charged, then inflated by a follower
/// pressure in a static stage: the pressure's load stiffness makes the step Jacobian
/// unsymmetric, and the adjoint solves with its transpose; the pressure's value is one of the
/// parameters.
#[test]
fn an_axisymmetric_balloon_under_a_follower_pressure() {
    let dir = tempfile::tempdir().unwrap();
    let base = deasim::io::examples::example("balloon").unwrap();
    let start = base.find("[[stages]]\nname = \"inflate\"").unwrap();
    let end = base[start..].find("[probes.").unwrap() + start;
    let text = format!(
        "{}[[stages]]\nname = \"inflate\"\nkind = \"static\"\nsteps = 4\n\n{}{}",
        &base[..start],
        &base[end..],
        r#"
[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.jm"
[[parameters]]
path = "materials.elastomer.permittivity"
[[parameters]]
path = "electrodes.outside.voltage"
[[parameters]]
path = "loads.pressure.0.value"

[[objective]]
kind = "probe-final"
probe = "stretch"
stage = "inflate"
target = 1.5
"#
    );
    let sim = Simulation::from_toml(&text, Some(dir.path())).with_overrides(&[
        "loads.pressure.0.value=4e3".into(),
        "mesh.radial=8".into(),
        "solver.newton_rtol=1e-13".into(),
    ]);
    let r = sim
        .gradient(&GradientOptions {
            check: true,
            ..Default::default()
        })
        .unwrap();
    assert_checked(&r, 1e-6);
}

/// The film stepped to a voltage and vibrating (a dynamic stage) under the integrator
/// `integrator`, with Kelvin–Voigt viscosity: the probe's history against data and its final
/// value, in μ, εᵣ, the viscosity and the voltage amplitude.
fn vibrating_film(integrator: &str) -> GradientReport {
    let dir = tempfile::tempdir().unwrap();
    let base = deasim::io::examples::example("film-vibration").unwrap();
    std::fs::write(
        dir.path().join("d.csv"),
        "time,value\n0,1\n0.002,0.97\n0.004,0.95\n",
    )
    .unwrap();
    let text = format!(
        "{base}\n{}",
        r#"
[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.permittivity"
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
"#
    );
    checked_film_vibration(&text, dir.path(), 0, 4e-3, integrator, &[])
}

/// The field penalty over a dynamic stage (midpoint) beside the probe terms.
#[test]
fn dynamic_field_penalty_gradient_matches_finite_differences() {
    let dir = tempfile::tempdir().unwrap();
    let base = deasim::io::examples::example("film-vibration").unwrap();
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
kind = "field-penalty"
limit = 1.0e7
weight = 1e-6
"#
    );
    let r = Simulation::from_toml(&text, Some(dir.path()))
        .with_overrides(&[
            "mesh.divisions=[2, 2, 1]".into(),
            "stages.0.duration=4e-3".into(),
            "stages.0.dt=2e-4".into(),
            "materials.elastomer.viscosity=50.0".into(),
            "solver.newton_rtol=1e-13".into(),
        ])
        .gradient(&GradientOptions {
            check: true,
            ..Default::default()
        })
        .unwrap();
    println!("field penalty J = {:e}", r.objective);
    assert!(r.objective > 0.0);
    assert_checked(&r, 1e-6);
}

/// The midpoint step, its projection of the potential and the velocity update.
#[test]
fn dynamic_midpoint_film_gradient_matches_finite_differences() {
    let r = vibrating_film("midpoint");
    assert_checked(&r, 1e-6);
}

/// The Newmark step and its consistent start acceleration.
#[test]
fn dynamic_newmark_film_gradient_matches_finite_differences() {
    let r = vibrating_film("newmark");
    assert_checked(&r, 1e-6);
}

/// The axisymmetric diaphragm: pre-stretched, the 46 g pad hung in a static stage, then 50 steps
/// of its square-wave drive under `integrator`, with the top electrode's voltage a control with
/// knots every 10th step. The pad's deflection (from the pre-stretched state) against data, in
/// the `parameters`, checked with finite differences of relative step `fd_step`.
///
/// The data lie 30–40 µm from the deflection (0.267 mm), farther than the parameters move it,
/// so that J is nearly linear in them over the steps. (Data within 2 µm make J move by 3 % for a
/// step of 10⁻⁴·C₁₀, and the central difference's truncation error is then 6·10⁻⁶ of the
/// derivative, measured falling as h².)
fn diaphragm(integrator: &str, parameters: &[&str], fd_step: f64) -> GradientReport {
    checked_diaphragm(
        "diaphragm",
        0.01,
        &[
            "stages.1.duration=0.05".into(),
            format!("stages.1.integrator=\"{integrator}\""),
        ],
        parameters,
        fd_step,
    )
}

/// The gradient of the diaphragm `example` (with `sets`; Newton to 10⁻¹³, no plots or fields)
/// with the top electrode a control with knots every `interval` s of its `actuate` stage and
/// the pad's deflection there against data at 0.30–0.31 mm, in the `parameters`, checked with
/// finite differences of relative step `fd_step`.
fn checked_diaphragm(
    example: &str,
    interval: f64,
    sets: &[String],
    parameters: &[&str],
    fd_step: f64,
) -> GradientReport {
    let dir = tempfile::tempdir().unwrap();
    let base = deasim::io::examples::example(example).unwrap();
    std::fs::write(
        dir.path().join("d.csv"),
        "time,value\n0,3.0e-4\n1.05,3.1e-4\n",
    )
    .unwrap();
    let parameters: String = parameters
        .iter()
        .map(|p| format!("[[parameters]]\npath = \"{p}\"\n"))
        .collect();
    let text = format!(
        r#"{base}
{parameters}
[[controls]]
electrode = "top"
stage = "actuate"
interval = {interval}

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "actuate"
data = "d.csv"
weight = 1e8
"#
    );
    let mut sets = sets.to_vec();
    sets.extend([
        "solver.newton_rtol=1e-13".into(),
        "output.plots=false".into(),
        "output.fields_every=0".into(),
    ]);
    Simulation::from_toml(&text, Some(dir.path()))
        .with_overrides(&sets)
        .gradient(&GradientOptions {
            check: true,
            fd_step: Some(fd_step),
            ..Default::default()
        })
        .unwrap()
}

/// The diaphragms' parameters checked together: C₁₀, the pad's mass, the voltage's amplitude
/// and the pre-stretch.
const DIAPHRAGM_PARAMETERS: [&str; 4] = [
    "materials.vhb.c10",
    "loads.rigid.0.mass",
    "electrodes.top.voltage.amplitude",
    "prestretch.stretch",
];

/// Asserts every Taylor remainder order of a checked run within 2 ± 0.1.
fn assert_taylor_orders(r: &GradientReport) {
    let orders = &r.taylor.as_ref().expect("checked").orders;
    assert!(
        orders.iter().all(|o| (o - 2.0).abs() <= 0.1),
        "Taylor orders {orders:?}"
    );
}

/// Asserts each checked knot of each control within `tol` of its finite difference, relative
/// to the knot's own derivative.
fn assert_controls_checked(r: &GradientReport, tol: f64) {
    assert_knots(r, tol, false);
}

/// [`assert_controls_checked`] with each knot's difference taken relative to the control's
/// largest derivative: for knots whose derivative is a small part of the control's, where the
/// noise of J in the central difference is a larger share of their own value.
fn assert_controls_checked_to_largest(r: &GradientReport, tol: f64) {
    assert_knots(r, tol, true);
}

/// The knots' check, relative to each knot's derivative or to the control's largest.
fn assert_knots(r: &GradientReport, tol: f64, to_largest: bool) {
    assert!(!r.controls.is_empty());
    for c in &r.controls {
        assert!(c.finite_differences.len() >= 2);
        let largest = c.gradient.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        for &(k, fd, h) in &c.finite_differences {
            let g = c.gradient[k];
            let scale = if to_largest { largest } else { fd.abs() };
            let rel = (g - fd).abs() / scale;
            assert!(
                rel <= tol,
                "{} knot {k}: adjoint {g:e}, central difference {fd:e} (h = {h:e} V), \
                 scale {scale:e}: {rel:e}",
                c.electrode
            );
        }
    }
}

/// The pad's mass (inertia and weight), the pre-stretch through the supports' targets and the
/// offsets within the pad's tie, C₁₀, the voltage and the knots of the control with
/// h = 3·10⁻⁴·|p|; the viscosity, which moves J by 10⁻⁷ of itself over such a step, with
/// h = 10⁻³·|p|. The dynamic steps converge to their round-off floor, which leaves J a noise of
/// about 10⁻¹⁰ of itself (measured: 2·10⁻⁵ of the voltage's derivative at h = 10⁻⁴·|p|), while
/// the truncation error grows as h² (4·10⁻⁶ of C₁₀'s at 10⁻³·|p|).
fn check_diaphragm(integrator: &str) {
    let r = diaphragm(integrator, &DIAPHRAGM_PARAMETERS, 3e-4);
    assert_checked(&r, 1e-6);
    assert_controls_checked(&r, 1e-6);
    // a control alone, with no [[parameters]]: the same knots' derivatives
    let alone = diaphragm(integrator, &[], 3e-4);
    assert!(alone.parameters.is_empty());
    assert_taylor_orders(&alone);
    assert_controls_checked(&alone, 1e-6);
    for (a, b) in alone.controls.iter().zip(&r.controls) {
        for (x, y) in a.gradient.iter().zip(&b.gradient) {
            assert!(
                (x - y).abs() <= 1e-12 * y.abs().max(1e-300),
                "{x:e} vs {y:e}"
            );
        }
    }
    // The viscosity moves J by 10⁻⁷ of itself over h = 10⁻³·|p|, so J's round-off (about
    // 10⁻¹² of itself with the steps converged to their floor) is 10⁻⁶ of the difference:
    // central differences at h = 3·10⁻⁴, 10⁻³, 3·10⁻³ and 10⁻²·|p| gave 8.280100, 8.280109,
    // 8.280107 and 8.280102·10⁻⁷ against the adjoint's 8.280111·10⁻⁷ (midpoint); a change of
    // the tangent's round-off alone (not kept) moved the one at 10⁻³ to 8.280127·10⁻⁷, 1.9·10⁻⁶
    // away. The scatter is the run's round-off; 4·10⁻⁶ bounds it.
    let r = diaphragm(integrator, &["materials.vhb.viscosity"], 1e-3);
    assert_checked(&r, 4e-6);
}

/// The 3-D quarter diaphragm (`diaphragm-3d`: mean-dilatation hex8, Yeoh, Kelvin–Voigt
/// viscosity, the pad tied): pre-stretched, the pad hung, then 20 midpoint steps of its square
/// wave with knots every 5 ms, its deflection against data 30–40 µm away. C₁₀, the pad's mass,
/// the voltage's amplitude, the pre-stretch and the knots with h = 10⁻⁴·|p| within 10⁻⁶ of
/// the central differences (at 3·10⁻⁴·|p| the truncation error of C₁₀'s and the pre-stretch's
/// was 4·10⁻⁷); the viscosity (its step Jacobian's viscous blocks are formed in
/// the kernel's point blocks) with h = 10⁻³·|p| within 4·10⁻⁶, as for the axisymmetric one;
/// Taylor orders 2 ± 0.1.
#[test]
fn dynamic_3d_diaphragm_gradient_matches_finite_differences() {
    let run = |parameters: &[&str], fd_step: f64| {
        checked_diaphragm(
            "diaphragm-3d",
            0.005,
            &["stages.1.duration=0.02".into()],
            parameters,
            fd_step,
        )
    };
    let r = run(&DIAPHRAGM_PARAMETERS, 1e-4);
    assert_checked(&r, 1e-6);
    assert_controls_checked(&r, 1e-6);
    assert_taylor_orders(&r);
    let r = run(&["materials.vhb.viscosity"], 1e-3);
    assert_checked(&r, 4e-6);
}

/// The midpoint step and its projection of the potential.
#[test]
fn dynamic_midpoint_diaphragm_gradient_matches_finite_differences() {
    check_diaphragm("midpoint");
}

/// The Newmark step and its consistent start acceleration on the pre-stretched diaphragm with
/// its Yeoh material and pad.
#[test]
fn dynamic_newmark_diaphragm_gradient_matches_finite_differences() {
    check_diaphragm("newmark");
}

/// The adjoint solves of the 50 steps and their projections with the factorisations of a few
/// Jacobians: GMRES preconditioned by a held factorisation stops where a direct solve would
/// (a step's direct solve leaves about 10⁻¹² of its right-hand side here; asking for 10⁻¹³
/// made every step factor its own Jacobian), and the derivatives are those of the checked run.
#[test]
fn held_factorisations_serve_the_dynamic_steps() {
    let params = ["materials.vhb.c10", "loads.rigid.0.mass"];
    let r = diaphragm("midpoint", &params, 3e-4);
    let steps = 50;
    assert!(
        r.adjoint_factorizations <= 12,
        "{} factorisations for {steps} steps",
        r.adjoint_factorizations
    );
    assert!(r.adjoint_krylov_iterations >= 2 * steps);
    assert_checked(&r, 1e-6);
}

/// A control's bad keys are refused naming them.
#[test]
fn bad_controls_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let bad = |extra: &str| {
        let base = deasim::io::examples::example("film-vibration").unwrap();
        Simulation::from_toml(&format!("{base}\n{extra}"), Some(dir.path()))
            .plan()
            .unwrap_err()
            .to_string()
    };
    let e = bad("[[controls]]\nelectrode = \"side\"\n");
    assert!(
        e.contains("controls.0.electrode") && e.contains("top"),
        "{e}"
    );
    let e = bad("[[controls]]\nelectrode = \"top\"\ninterval = -1.0\n");
    assert!(e.contains("controls.0.interval"), "{e}");
    let e = bad("[[controls]]\nelectrode = \"top\"\ninterval = 5e-3\nvalues = [1.0]\n");
    assert!(
        e.contains("controls.0.values") && e.contains("3 knots"),
        "{e}"
    );
    let e = bad("[[controls]]\nelectrode = \"top\"\nlower = 10.0\nupper = 1.0\n");
    assert!(e.contains("controls.0.upper"), "{e}");
    // 0, like no interval, puts a knot at every nominal step: 0.01 s / 20 µs + 1 knots
    let base = deasim::io::examples::example("film-vibration").unwrap();
    for interval in ["", "interval = 0.0\n"] {
        let plan = Simulation::from_toml(
            &format!("{base}\n[[controls]]\nelectrode = \"top\"\n{interval}"),
            None,
        )
        .plan()
        .unwrap();
        assert_eq!(plan.stages[0].controls[0].1.len(), 501, "{interval}");
    }
}

/// A control replaces its electrode's waveform by the table through its knots: a run with the
/// knots at the waveform's values of a linear ramp is the run of the ramp itself.
#[test]
fn a_control_at_its_waveforms_values_runs_the_same_drive() {
    let base = deasim::io::examples::example("film-vibration").unwrap();
    let ramp = base.replace(
        "voltage = { waveform = \"step\", amplitude = 20e3, at = 0.0 }",
        "voltage = { waveform = \"ramp\", amplitude = 20e3, rise_time = 0.02 }",
    );
    assert_ne!(ramp, base);
    let run = |text: &str| {
        let r = Simulation::from_toml(text, None)
            .with_overrides(&[
                "mesh.divisions=[2, 2, 1]".into(),
                "stages.0.duration=2e-3".into(),
                "stages.0.dt=2e-4".into(),
            ])
            .run(Default::default())
            .unwrap();
        r.history
            .column("probe:thickness_stretch")
            .unwrap()
            .to_vec()
    };
    let plain = run(&ramp);
    let controlled = run(&format!(
        "{ramp}\n[[controls]]\nelectrode = \"top\"\ninterval = 1e-3\n"
    ));
    assert_eq!(plain.len(), controlled.len());
    for (a, b) in plain.iter().zip(&controlled) {
        assert!((a - b).abs() <= 1e-12 * a.abs(), "{a} {b}");
    }
}

/// A controlled film brought to rest: the kinetic energy at the stage's end, the drive's effort
/// in its value and its rate, and a probe's final value, in the control's knots and μ. Each term
/// weighs in J (measured with `deasim gradient`: 0.15, 0.38, 0.60 and 0.006 of J = 1.14).
#[test]
fn rest_and_drive_effort_in_the_knots_of_a_control() {
    let dir = tempfile::tempdir().unwrap();
    let base = deasim::io::examples::example("film-vibration").unwrap();
    let text = format!(
        "{base}\n{}",
        r#"
[[parameters]]
path = "materials.elastomer.mu"

[[controls]]
electrode = "top"
interval = 1e-3
values = [0.0, 8e3, 14e3, 18e3, 20e3]

[[objective]]
kind = "rest"
weight = 1e6

[[objective]]
kind = "drive-effort"
electrode = "top"
weight = 1e-6

[[objective]]
kind = "drive-effort"
electrode = "top"
of = "rate"
weight = 1e-11

[[objective]]
kind = "probe-final"
probe = "inplane_stretch"
target = 1.02
weight = 100.0
"#
    );
    let r = Simulation::from_toml(&text, Some(dir.path()))
        .with_overrides(&[
            "mesh.divisions=[2, 2, 1]".into(),
            "stages.0.duration=4e-3".into(),
            "stages.0.dt=2e-4".into(),
            "materials.elastomer.viscosity=50.0".into(),
            "solver.newton_rtol=1e-13".into(),
            "output.plots=false".into(),
        ])
        .gradient(&GradientOptions {
            check: true,
            ..Default::default()
        })
        .unwrap();
    assert_checked(&r, 1e-6);
    assert_controls_checked(&r, 1e-6);
}

/// Targets measured from a probe's value at its stage's start (`relative`): that start is the
/// state the stage before ended at, or before the first stage the pre-stretched state, and each
/// moves with the parameters. A waveform target of stage time replaces the data.
#[test]
fn relative_targets_differentiate_their_stages_start() {
    let base = deasim::io::examples::example("diaphragm").unwrap();
    let text = format!(
        "{base}\n{}",
        r#"
[probes.rim_uz]
kind = "point"
quantity = "uz"
at = [12e-3, 0.0, 1e-3]

[[parameters]]
path = "materials.vhb.c10"
[[parameters]]
path = "prestretch.stretch"
[[parameters]]
path = "loads.rigid.0.mass"

[[controls]]
electrode = "top"
stage = "actuate"
interval = 0.01

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "actuate"
relative = true
target = { waveform = "ramp", amplitude = 3e-5, rise_time = 0.03, rise = "cosine" }
weight = 1e10

[[objective]]
kind = "probe-final"
probe = "rim_uz"
stage = "load"
relative = true
target = -1e-4
weight = 1e8

[[objective]]
kind = "probe-final"
probe = "rim_uz"
stage = "actuate"
relative = true
target = 1e-6
weight = 1e10
"#
    );
    let r = Simulation::from_toml(&text, None)
        .with_overrides(&[
            "stages.1.duration=0.05".into(),
            "solver.newton_rtol=1e-13".into(),
            "output.plots=false".into(),
        ])
        .gradient(&GradientOptions {
            check: true,
            fd_step: Some(3e-4),
            ..Default::default()
        })
        .unwrap();
    // J is strongly nonlinear along the Taylor test's direction (10² h): its orders approach 2
    // as the step halves (measured 1.83, 1.92, 1.96), so the last is checked
    let mut r = r;
    let orders = r.taylor.as_ref().unwrap().orders.clone();
    assert!((orders[2] - 2.0).abs() <= 0.1, "Taylor orders {orders:?}");
    r.taylor.as_mut().unwrap().orders = vec![2.0; 3];
    assert_checked(&r, 1e-6);
    // the knot at 10 ms has a fifth of the largest knot's derivative, and its central
    // difference differs from the adjoint by 3·10⁻⁷ to 2.5·10⁻⁶ of itself as h goes from
    // 3·10⁻⁴ to 3·10⁻³ of the voltage and as round-off of the tangent changes (measured), while
    // the adjoint stays the same to ten digits: so the knots are checked against the largest
    assert_controls_checked_to_largest(&r, 1e-6);
}

/// The film under charge control (`film-charge`, its charge ramped by a static stage, on a
/// 2 × 2 × 1 mesh to 60 % of its charge, before the voltage maximum): the derivatives in the
/// charge, μ and εᵣ through the tied potential of the electrode.
#[test]
fn a_charge_controlled_film() {
    let dir = tempfile::tempdir().unwrap();
    let base = deasim::io::examples::example("film-charge").unwrap();
    let text = format!(
        "{base}\n{}",
        r#"
[[parameters]]
path = "electrodes.top.charge"
[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.permittivity"

[[objective]]
kind = "probe-final"
probe = "thickness_stretch"
target = 0.8
weight = 100.0
"#
    );
    let r = Simulation::from_toml(&text, Some(dir.path()))
        .with_overrides(&[
            "mesh.divisions=[2, 2, 1]".into(),
            "electrodes.top.charge=1.0e-6".into(),
            "stages.0.steps=10".into(),
            "solver.newton_rtol=1e-13".into(),
        ])
        .gradient(&GradientOptions {
            check: true,
            ..Default::default()
        })
        .unwrap();
    assert!(r.objective > 0.0);
    assert_checked(&r, 1e-6);
}

/// The vibrating film under charge control: its top electrode holds a charge (the midpoint
/// scheme's projection holds it too) while the film vibrates.
#[test]
fn a_charge_controlled_film_vibrating() {
    let dir = tempfile::tempdir().unwrap();
    let base = deasim::io::examples::example("film-vibration").unwrap();
    let text = format!(
        "{base}\n{}",
        r#"
[[parameters]]
path = "electrodes.top.charge"
[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.viscosity"

[[objective]]
kind = "probe-final"
probe = "thickness_stretch"
target = 0.9
weight = 100.0
"#
    );
    for integrator in ["midpoint", "newmark"] {
        let r = Simulation::from_toml(&text, Some(dir.path()))
            .with_overrides(&[
                "mesh.divisions=[2, 2, 1]".into(),
                "electrodes.top.voltage=0.0".into(),
                "electrodes.top.charge=1.4e-7".into(),
                "stages.0.duration=4e-3".into(),
                "stages.0.dt=2e-4".into(),
                format!("stages.0.integrator=\"{integrator}\""),
                "materials.elastomer.viscosity=50.0".into(),
                "solver.newton_rtol=1e-13".into(),
            ])
            .gradient(&GradientOptions {
                check: true,
                ..Default::default()
            })
            .unwrap();
        assert!(r.objective > 0.0, "{integrator}");
        assert_checked(&r, 1e-6);
    }
}

/// The vibrating film driven through a circuit: a 20 kV step source charges its top electrode
/// through R = 10⁸ Ω (RC ≈ 1.7 ms over a 4 ms run) while the film vibrates. The derivatives
/// in R, the source's amplitude, μ, εᵣ and the viscosity, with both integrators: the charge of
/// each step's Gauss equation, the midpoint scheme's projection at the end charge, and
/// Gauss's law at each step's start.
#[test]
fn a_circuit_driven_film_vibrating() {
    let dir = tempfile::tempdir().unwrap();
    let base = deasim::io::examples::example("film-vibration").unwrap();
    let step = "{ waveform = \"step\", amplitude = 20e3, at = 0.0 }";
    let base = common::circuit_instead_of(base, step, step, 1e8);
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
[[parameters]]
path = "materials.elastomer.permittivity"
[[parameters]]
path = "materials.elastomer.viscosity"

[[objective]]
kind = "probe-final"
probe = "thickness_stretch"
target = 0.9
weight = 100.0
"#
    );
    for integrator in ["midpoint", "newmark"] {
        let r = Simulation::from_toml(&text, Some(dir.path()))
            .with_overrides(&[
                "mesh.divisions=[2, 2, 1]".into(),
                "stages.0.duration=4e-3".into(),
                "stages.0.dt=2e-4".into(),
                format!("stages.0.integrator=\"{integrator}\""),
                "materials.elastomer.viscosity=50.0".into(),
                "solver.newton_rtol=1e-13".into(),
            ])
            .gradient(&GradientOptions {
                check: true,
                ..Default::default()
            })
            .unwrap();
        println!("{integrator}:");
        assert!(r.objective > 0.0, "{integrator}");
        assert_checked(&r, 1e-6);
    }
}

/// The film charged through its circuit by a static stage (the circuit's DC limit: the
/// electrode at the source's voltage), then driven by the source's 200 Hz sine about it in a
/// dynamic stage that starts from the charge the static stage left (Newmark's start-up
/// projects the potential holding that charge). The derivatives in R, the source's amplitude
/// and offset, and εᵣ.
#[test]
fn a_circuit_driven_film_from_a_charged_start() {
    let dir = tempfile::tempdir().unwrap();
    let base = charged_then_sine(true);
    let text = format!(
        "{base}\n{}",
        r#"
[[parameters]]
path = "electrodes.top.circuit.resistance"
[[parameters]]
path = "electrodes.top.circuit.source.amplitude"
[[parameters]]
path = "electrodes.top.circuit.source.offset"
[[parameters]]
path = "materials.elastomer.permittivity"

[[objective]]
kind = "probe-final"
probe = "thickness_stretch"
stage = "vibrate"
target = 0.9
weight = 100.0
"#
    );
    for integrator in ["newmark", "midpoint"] {
        let r = charged_then_vibrating(&text, dir.path(), integrator);
        println!("{integrator}:");
        assert_checked(&r, 1e-6);
    }
}

/// A control of a circuit's source: the knots of the source's table (every 0.5 ms) of the
/// vibrating film charged through R = 10⁸ Ω, against central differences, with both
/// integrators.
#[test]
fn the_knots_of_a_circuit_source_control() {
    let dir = tempfile::tempdir().unwrap();
    let base = deasim::io::examples::example("film-vibration").unwrap();
    let step = "{ waveform = \"step\", amplitude = 20e3, at = 0.0 }";
    let base = common::circuit_instead_of(base, step, step, 1e8);
    let text = format!(
        "{base}\n{}",
        r#"
[[parameters]]
path = "electrodes.top.circuit.resistance"

[[controls]]
electrode = "top"
interval = 5e-4

[[objective]]
kind = "probe-final"
probe = "thickness_stretch"
target = 0.9
weight = 100.0

[[objective]]
kind = "drive-effort"
electrode = "top"
of = "rate"
weight = 1e-12
"#
    );
    for integrator in ["midpoint", "newmark"] {
        let r = Simulation::from_toml(&text, Some(dir.path()))
            .with_overrides(&[
                "mesh.divisions=[2, 2, 1]".into(),
                "stages.0.duration=3e-3".into(),
                "stages.0.dt=2e-4".into(),
                format!("stages.0.integrator=\"{integrator}\""),
                "materials.elastomer.viscosity=50.0".into(),
                "solver.newton_rtol=1e-13".into(),
            ])
            .gradient(&GradientOptions {
                check: true,
                ..Default::default()
            })
            .unwrap();
        let c = &r.controls[0];
        eprintln!(
            "{integrator}: {:?} / {:?}",
            c.gradient, c.finite_differences
        );
        assert_eq!(c.gradient.len(), 7, "{integrator}");
        assert_controls_checked(&r, 1e-6);
    }
}

/// The top electrode's charge over the vibration against 2 nC, the term of the tests below.
const CHARGE_MISFIT: &str = r#"
[[objective]]
kind = "probe-misfit"
probe = "charge"
stage = "vibrate"
target = 2e-9
weight = 1e17
"#;

/// Terms on the top electrode's charge (Gauss's law at each step's state, the product with the
/// tangent and the materials' parameter derivatives of the electrode's forces): its value at
/// the end of a static stage that charges the film, and its misfit over the vibration that
/// follows, with the voltage on the electrode and through a circuit, both integrators.
#[test]
fn terms_on_an_electrodes_charge() {
    let dir = tempfile::tempdir().unwrap();
    let (voltage, circuit) = (charged_then_sine(false), charged_then_sine(true));
    let terms = format!(
        r#"
[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.permittivity"
[[parameters]]
path = "materials.elastomer.viscosity"

[[objective]]
kind = "probe-final"
probe = "charge"
stage = "charge"
target = 0.0
weight = 1e17
{CHARGE_MISFIT}"#
    );
    let voltage = format!(
        "{voltage}\n{terms}\n[[parameters]]\npath = \"electrodes.top.voltage.amplitude\"\n"
    );
    let circuit = format!(
        "{circuit}\n{terms}\n[[parameters]]\npath = \"electrodes.top.circuit.resistance\"\n\
         [[parameters]]\npath = \"electrodes.top.circuit.source.amplitude\"\n"
    );
    for (drive, text) in [("voltage", &voltage), ("circuit", &circuit)] {
        for integrator in ["midpoint", "newmark"] {
            let r = charged_then_vibrating(text, dir.path(), integrator);
            println!("{drive}, {integrator}: J = {:e}", r.objective);
            assert!(r.objective > 0.0);
            assert_checked(&r, 1e-6);
        }
    }
}

/// The checked gradient of a film scenario `text` whose second stage vibrates for 3 ms.
/// A sine drive's frequency (and amplitude): the film charged by the sine's first millisecond
/// in a static stage, then vibrating 3 ms under it, its charge's history against a target, with
/// the voltage on the electrode and through a circuit (its source's frequency), both
/// integrators. The stages are short so that the sine's phase 2πft moves little with the
/// finite differences' step (their truncation error grows as (2πt·h)²).
#[test]
fn the_frequency_of_a_sine_drive() {
    let dir = tempfile::tempdir().unwrap();
    let (voltage, circuit) = (charged_then_sine(false), charged_then_sine(true));
    let terms = CHARGE_MISFIT;
    let voltage = format!(
        "{voltage}\n{terms}\n[[parameters]]\npath = \"electrodes.top.voltage.frequency\"\n\
         [[parameters]]\npath = \"electrodes.top.voltage.amplitude\"\n"
    );
    let circuit = format!(
        "{circuit}\n{terms}\n[[parameters]]\npath = \"electrodes.top.circuit.source.frequency\"\n"
    );
    for (drive, text) in [("voltage", &voltage), ("circuit", &circuit)] {
        for integrator in ["midpoint", "newmark"] {
            let r = checked_film_vibration(
                text,
                dir.path(),
                1,
                3e-3,
                integrator,
                &["stages.0.duration=1e-3".into()],
            );
            println!("{drive}, {integrator}: J = {:e}", r.objective);
            assert!(r.parameters[0].gradient != 0.0);
            assert_checked(&r, 1e-6);
            assert_taylor_orders(&r);
        }
    }
}

fn charged_then_vibrating(text: &str, dir: &std::path::Path, integrator: &str) -> GradientReport {
    checked_film_vibration(text, dir, 1, 3e-3, integrator, &[])
}

/// The vibrating film charged by a static stage of 3 steps (`charge`), then driven in its
/// `vibrate` stage by a 200 Hz sine of 5 kV about 15 kV: on the electrode, or through
/// R = 10⁸ Ω (`circuit`).
fn charged_then_sine(circuit: bool) -> String {
    let step = "{ waveform = \"step\", amplitude = 20e3, at = 0.0 }";
    let sine = "{ waveform = \"sine\", amplitude = 5e3, offset = 15e3, frequency = 200.0 }";
    let text = deasim::io::examples::example("film-vibration").unwrap();
    assert!(text.contains(step));
    let text = text.replace(step, sine).replace(
        "[[stages]]\nname = \"vibrate\"",
        "[[stages]]\nname = \"charge\"\nkind = \"static\"\nsteps = 3\n\n[[stages]]\nname = \"vibrate\"",
    );
    assert!(
        text.contains("name = \"charge\""),
        "the example's stages moved"
    );
    if circuit {
        common::circuit_instead_of(&text, sine, sine, 1e8)
    } else {
        text
    }
}
