//! The gradient of a run of a viscoelastic material (Maxwell branches, whose internal variables
//! each accepted step commits) by the discrete adjoint, against central finite differences and
//! the Taylor remainder test.
//!
//! The finite differences use h = 10⁻⁴·|p|, as in the elastic tests: truncation about 10⁻⁸ of
//! the derivative, the forward solves' error (relative residual 10⁻¹³) about 10⁻⁹.

mod common;
use common::gradient::{assert_checked, checked_film_vibration};
use deasim::api::{GradientOptions, GradientReport, Simulation};

/// The parameters every test asks for: the equilibrium μ and each branch's μ and τ.
const BRANCH_PARAMETERS: &str = r#"
[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.branches.0.mu"
[[parameters]]
path = "materials.elastomer.branches.0.tau"
[[parameters]]
path = "materials.elastomer.branches.1.mu"
[[parameters]]
path = "materials.elastomer.branches.1.tau"
"#;

/// A film with two Maxwell branches charged to 20 kV in 0.1 s (a static stage of 5 load steps
/// in real time) and held there for 0.6 s (a quasi-static stage): the thickness creeps as the
/// branches relax. The objective reads the hold's history and its final in-plane stretch.
#[test]
fn a_viscoelastic_film_held_at_a_voltage() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("creep.csv"),
        "time,value\n0.1,0.97\n0.3,0.95\n0.7,0.94\n",
    )
    .unwrap();
    let base = deasim::io::examples::example("film").unwrap();
    let text = format!(
        "{base}\n{BRANCH_PARAMETERS}{}",
        r#"
[[parameters]]
path = "materials.elastomer.permittivity"
[[parameters]]
path = "electrodes.top.voltage.amplitude"

[[stages]]
name = "hold"
kind = "quasi-static"
duration = 0.6
steps = 6

[[objective]]
kind = "probe-misfit"
probe = "thickness_stretch"
stage = "hold"
data = "creep.csv"
weight = 100.0

[[objective]]
kind = "probe-final"
probe = "inplane_stretch"
stage = "hold"
target = 1.03
weight = 100.0
"#
    );
    let r = Simulation::from_toml(&text, Some(dir.path()))
        .with_overrides(&[
            "mesh.divisions=[2, 2, 1]".into(),
            "materials.elastomer.branches=[{ mu = 4e4, tau = 0.05 }, { mu = 2e4, tau = 0.4 }]"
                .into(),
            "stages.0.steps=5".into(),
            "stages.0.duration=0.1".into(),
            "electrodes.top.voltage.amplitude=20e3".into(),
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

/// The vibrating film with two Maxwell branches beside its Kelvin–Voigt viscosity, integrated
/// by `integrator`: the branches evolve at every time step; its density reaches J through the
/// mass.
fn vibrating_viscoelastic_film(integrator: &str) -> GradientReport {
    let dir = tempfile::tempdir().unwrap();
    let base = deasim::io::examples::example("film-vibration").unwrap();
    std::fs::write(
        dir.path().join("d.csv"),
        "time,value\n0,1\n0.002,0.97\n0.004,0.95\n",
    )
    .unwrap();
    let text = format!(
        "{base}\n{BRANCH_PARAMETERS}{}",
        r#"
[[parameters]]
path = "materials.elastomer.viscosity"
[[parameters]]
path = "materials.elastomer.density"
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
    let branches =
        "materials.elastomer.branches=[{ mu = 4e4, tau = 1e-3 }, { mu = 2e4, tau = 1e-2 }]";
    checked_film_vibration(&text, dir.path(), 0, 4e-3, integrator, &[branches.into()])
}

#[test]
fn a_viscoelastic_film_vibrating_midpoint() {
    let r = vibrating_viscoelastic_film("midpoint");
    assert!(r.objective > 0.0);
    assert_checked(&r, 1e-6);
}

#[test]
fn a_viscoelastic_film_vibrating_newmark() {
    let r = vibrating_viscoelastic_film("newmark");
    assert!(r.objective > 0.0);
    assert_checked(&r, 1e-6);
}

/// The viscoelastic diaphragm (axisymmetric, mean-dilatation quad4, VHB 4910 with three
/// branches): stretched in real time and held while the branches relax (a timed pre-stretch),
/// the mass hung in a static stage of real time, then 20 ms of the square wave (midpoint). The
/// objective reads the pad's deflection through the dynamic stage; the parameters reach it
/// through every phase (the density through the membrane's weight in the static stage and its
/// mass and weight in the dynamic one).
#[test]
fn the_viscoelastic_diaphragm_through_its_timed_prestretch() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("d.csv"),
        "time,value\n2.0,1.0e-3\n2.01,1.1e-3\n2.02,1.2e-3\n",
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
path = "materials.vhb.viscosity"
[[parameters]]
path = "materials.vhb.density"
[[parameters]]
path = "loads.rigid.0.mass"
[[parameters]]
path = "electrodes.top.voltage.amplitude"
[[parameters]]
path = "prestretch.stretch"

[[objective]]
kind = "probe-misfit"
probe = "center_deflection"
stage = "actuate"
data = "d.csv"
weight = 1e6
"#
    );
    let r = Simulation::from_toml(&text, Some(dir.path()))
        .with_overrides(&[
            "mesh.radial=6".into(),
            // 8 steps: with 2 the stretch's Newton solves cut their steps back, and where
            // they do depends on the parameters (τ₂ = 61.24 s: 9 accepted steps, 61.25 s: 7),
            // so that J jumps between the runs of a finite difference; the adjoint's
            // derivative is that of one accepted path
            "prestretch.steps=8".into(),
            "prestretch.duration=0.5".into(),
            "prestretch.hold=0.5".into(),
            "prestretch.hold_steps=2".into(),
            "stages.0.steps=2".into(),
            "stages.1.duration=0.02".into(),
            "output.plots=false".into(),
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
