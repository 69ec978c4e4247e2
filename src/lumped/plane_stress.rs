//! Plane-stress response of a material under F = diag(λ_r, λ_θ, λ_z) with no electric field:
//! λ_z such that P_zz = 0, and the reduced energy, stress and tangent in λ_r at fixed λ_θ.
//!
//! The deasim materials are slightly compressible, so λ_z is found by Newton's method on
//! P_zz(λ_z) = 0 (a nearly incompressible material converges in one or two steps from the guess
//! J₀/(λ_r λ_θ)). By the implicit function theorem, with A = ∂²W/∂F∂F:
//! dλ_z/dλ_r = −A_zz,rr/A_zz,zz and dP_rr/dλ_r = A_rr,rr − A_rr,zz A_zz,rr/A_zz,zz, and since
//! P_zz = 0 the derivative of the reduced energy is dW/dλ_r = P_rr.

use crate::material::{Mat3, Material, MaterialError, Vec3};

/// Plane-stress state at (λ_r, λ_θ).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneStress {
    /// Thickness stretch λ_z with P_zz = 0.
    pub lz: f64,
    /// Energy W per reference volume (J/m³).
    pub w: f64,
    /// Nominal radial stress P_rr = dW/dλ_r (Pa).
    pub p: f64,
    /// Plane-stress tangent dP_rr/dλ_r at fixed λ_θ (Pa).
    pub dp: f64,
    /// dλ_z/dλ_r at fixed λ_θ.
    pub dlz: f64,
}

// Flattened indices of F_rr and F_zz in the 9×9 tangent.
const R: usize = 0;
const Z: usize = 8;

/// Solves P_zz = 0 for λ_z starting from `guess` and returns the plane-stress state.
///
/// The iteration stops when the Newton correction is below 1e-9 λ_z; the returned λ_z, W and
/// P_rr include that last correction to first order (W to second order, since P_zz ≈ 0), so they
/// are exact to O(1e-18).
pub fn plane_stress(
    mat: &dyn Material,
    lr: f64,
    lt: f64,
    guess: f64,
) -> Result<PlaneStress, MaterialError> {
    if !(lr > 0.0 && lt > 0.0 && lr.is_finite() && lt.is_finite()) {
        return Err(MaterialError::OutOfDomain(format!(
            "plane stress: invalid stretches λ_r = {lr}, λ_θ = {lt}"
        )));
    }
    let e0 = Vec3::zeros();
    let mut lz = if guess > 0.0 && guess.is_finite() {
        guess
    } else {
        1.0 / (lr * lt)
    };
    for _ in 0..60 {
        let t = mat.tangent(&Mat3::from_diagonal(&Vec3::new(lr, lt, lz)), &e0)?;
        let r = t.p[(2, 2)];
        let d = t.a[(Z, Z)];
        if !(d > 0.0 && d.is_finite() && r.is_finite()) {
            return Err(MaterialError::OutOfDomain(format!(
                "plane stress: dP_zz/dλ_z = {d:e} is not positive at λ_r = {lr}, λ_θ = {lt}, λ_z = {lz}"
            )));
        }
        let dl = -r / d;
        if dl.abs() <= 1e-9 * lz {
            return Ok(PlaneStress {
                lz: lz + dl,
                w: t.energy + 0.5 * r * dl,
                p: t.p[(0, 0)] + t.a[(R, Z)] * dl,
                dp: t.a[(R, R)] - t.a[(R, Z)] * t.a[(Z, R)] / d,
                dlz: -t.a[(Z, R)] / d,
            });
        }
        // keep λ_z positive
        let mut step = dl;
        while lz + step <= 0.0 {
            step *= 0.5;
        }
        lz += step;
    }
    Err(MaterialError::OutOfDomain(format!(
        "plane stress: no λ_z with P_zz = 0 found at λ_r = {lr}, λ_θ = {lt}"
    )))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::registry;

    fn yeoh() -> std::sync::Arc<dyn Material> {
        let (m, p) = registry::preset("vhb4910-yeoh").unwrap();
        registry::build(m, &p).unwrap().0
    }

    /// P_zz vanishes, and dλ_z/dλ_r, P_rr = dW/dλ_r and dP_rr/dλ_r match central differences of
    /// the plane-stress state (step 1e-5: truncation ~1e-10, round-off ~1e-11 relative).
    #[test]
    fn lumped_plane_stress_derivatives_match_finite_differences() {
        let mat = yeoh();
        for (lr, lt) in [(2.0, 2.0), (2.3, 2.0), (1.2, 0.9), (3.0, 1.5)] {
            let s = plane_stress(mat.as_ref(), lr, lt, 0.0).unwrap();
            let f = Mat3::from_diagonal(&Vec3::new(lr, lt, s.lz));
            let pzz = mat.stress(&f, &Vec3::zeros()).unwrap().p[(2, 2)];
            assert!(pzz.abs() < 1e-6, "P_zz = {pzz}");
            let h = 1e-5 * lr;
            let sp = plane_stress(mat.as_ref(), lr + h, lt, s.lz).unwrap();
            let sm = plane_stress(mat.as_ref(), lr - h, lt, s.lz).unwrap();
            let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1e-300);
            let fd_w = (sp.w - sm.w) / (2.0 * h);
            let fd_p = (sp.p - sm.p) / (2.0 * h);
            let fd_lz = (sp.lz - sm.lz) / (2.0 * h);
            assert!(rel(fd_w, s.p) < 1e-8, "{lr} {lt}: P {} fd {fd_w}", s.p);
            assert!(rel(fd_p, s.dp) < 1e-6, "{lr} {lt}: dP {} fd {fd_p}", s.dp);
            assert!(
                rel(fd_lz, s.dlz) < 1e-6,
                "{lr} {lt}: dλz {} fd {fd_lz}",
                s.dlz
            );
        }
    }
}
