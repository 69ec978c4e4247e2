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
