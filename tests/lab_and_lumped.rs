//! The library functions behind `deasim material` and `deasim lumped`: a material-point test
//! from its numbers, and the lumped diaphragm's linearisation and simulation.

use deasim::material::lab::TestSpec;
use deasim::material::registry::{build, preset};

fn uniaxial(rates: Vec<f64>) -> TestSpec {
    TestSpec {
        test: "uniaxial".into(),
        mode: "uniaxial".into(),
        stretch: 2.0,
        rates,
        stress: None,
        ramp_time: 0.1,
        hold: 0.0,
        cycles: 1,
        steps: 10,
    }
}

/// One curve per rate, ending at the stretch asked, its stress rising; bad numbers are refused
/// with the parameter's name first.
#[test]
fn a_material_test_runs_one_curve_per_rate() {
    let (model, p) = preset("vhb4910-wang2016").unwrap();
    let (mat, _) = build(model, &p).unwrap();
    let spec = uniaxial(vec![0.01, 0.1]);
    spec.check().unwrap();
    let curves = spec.curves(mat.as_ref()).unwrap();
    assert_eq!(curves.len(), 2);
    for c in &curves {
        assert_eq!(c.records.len(), 10);
        assert!((c.records.last().unwrap().stretch - 2.0).abs() < 1e-12);
        assert!(c.records.windows(2).all(|w| w[1].nominal > w[0].nominal));
    }
    let e = uniaxial(vec![]).check().unwrap_err();
    assert!(e.starts_with("rate:"), "{e}");
    let mut bad = uniaxial(vec![0.1]);
    bad.test = "torsion".into();
    assert!(bad.check().unwrap_err().starts_with("test:"));
}

/// The lumped model's simulation starts at its static equilibrium and resolves its natural
/// period.
#[test]
fn the_lumped_simulation_starts_at_rest_and_resolves_the_period() {
    let text = deasim::io::examples::example("diaphragm").unwrap();
    let s = deasim::io::scenario::parse(text, "d.toml", &[]).unwrap();
    let plan = deasim::io::build::build(&s, "d.toml", None).unwrap();
    let setup = deasim::lumped::setup::from_scenario(&s, &plan, "d.toml").unwrap();
    let (lin, history, dt) = setup.simulate().unwrap();
    let first = &history.samples[0];
    assert!((first.deflection - lin.equilibrium).abs() <= 1e-12 * lin.equilibrium.abs());
    assert!(dt <= setup.dt);
    assert!(dt * lin.natural_frequency() <= 1.0 / deasim::lumped::setup::STEPS_PER_PERIOD + 1e-15);
    let last = history.samples.last().unwrap();
    assert!((last.time - setup.duration).abs() < 1e-9 * setup.duration.max(1.0));
}
