//! Checks of a gradient report against its finite differences and Taylor test.

use deasim::api::GradientReport;

/// Asserts each derivative within `tol` (relative) of its central difference, none zero, and a
/// Taylor remainder order of 2 ± 0.1 at the first two halvings; prints each comparison.
pub fn assert_checked(r: &GradientReport, tol: f64) {
    for p in &r.parameters {
        let (fd, h) = p.finite_difference.expect("checked");
        let rel = (p.gradient - fd).abs() / fd.abs();
        println!(
            "{}: adjoint {:.9e}, central difference {fd:.9e} (h = {h:e}), relative difference \
             {rel:.1e}",
            p.path, p.gradient
        );
        assert!(
            rel <= tol,
            "{}: adjoint {:e}, central difference {:e} (h = {h:e}): relative difference {rel:e}",
            p.path,
            p.gradient,
            fd
        );
        assert!(
            p.gradient != 0.0,
            "{}: a zero derivative checks nothing",
            p.path
        );
    }
    let t = r.taylor.as_ref().expect("checked");
    println!("Taylor orders {:?}", t.orders);
    for o in &t.orders[..2] {
        assert!((o - 2.0).abs() <= 0.1, "Taylor orders {:?}", t.orders);
    }
}

/// The checked gradient (`--check`) of a film scenario `text` (its data files in `dir`) on
/// 2 × 2 × 1 cells whose dynamic stage `stage` lasts `duration` s in steps of 0.2 ms with
/// `integrator`, Kelvin–Voigt η = 50 Pa·s and Newton to 10⁻¹³ of the first residual; `more`:
/// further overrides.
pub fn checked_film_vibration(
    text: &str,
    dir: &std::path::Path,
    stage: usize,
    duration: f64,
    integrator: &str,
    more: &[String],
) -> GradientReport {
    let mut overrides = vec![
        "mesh.divisions=[2, 2, 1]".to_string(),
        format!("stages.{stage}.duration={duration:e}"),
        format!("stages.{stage}.dt=2e-4"),
        format!("stages.{stage}.integrator=\"{integrator}\""),
        "materials.elastomer.viscosity=50.0".into(),
        "solver.newton_rtol=1e-13".into(),
    ];
    overrides.extend_from_slice(more);
    deasim::api::Simulation::from_toml(text, Some(dir))
        .with_overrides(&overrides)
        .gradient(&deasim::api::GradientOptions {
            check: true,
            ..Default::default()
        })
        .unwrap()
}
