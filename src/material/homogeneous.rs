//! Homogeneous stress-free-lateral deformation paths (uniaxial,
//! equibiaxial, pure shear) of a compressible [`Material`], used by the
//! Drucker stability check of the [`registry`](super::registry) and by the
//! tests.
//!
//! For a prescribed stretch λ along axis 1 the lateral stretch t is found
//! by a scalar Newton iteration so that P₃₃ = 0 (and, for uniaxial tension,
//! P₂₂ = P₃₃ = 0 by symmetry), with E0 = 0:
//!
//! * uniaxial:     F = diag(λ, t, t),
//! * equibiaxial:  F = diag(λ, λ, t),
//! * pure shear:   F = diag(λ, 1, t).

use super::{Mat3, Material, MaterialError, Vec3};

/// Homogeneous loading mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// F = diag(λ, t, t), P₂₂ = P₃₃ = 0.
    Uniaxial,
    /// F = diag(λ, λ, t), P₃₃ = 0.
    Equibiaxial,
    /// F = diag(λ, 1, t), P₃₃ = 0 (planar tension).
    PureShear,
}

impl Mode {
    /// The three modes.
    pub const ALL: [Mode; 3] = [Mode::Uniaxial, Mode::Equibiaxial, Mode::PureShear];

    /// Human-readable name.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Uniaxial => "uniaxial",
            Mode::Equibiaxial => "equibiaxial",
            Mode::PureShear => "pure shear",
        }
    }

    /// F for stretch λ and lateral stretch t.
    pub fn deformation(self, stretch: f64, lateral: f64) -> Mat3 {
        let d = match self {
            Mode::Uniaxial => Vec3::new(stretch, lateral, lateral),
            Mode::Equibiaxial => Vec3::new(stretch, stretch, lateral),
            Mode::PureShear => Vec3::new(stretch, 1.0, lateral),
        };
        Mat3::from_diagonal(&d)
    }

    /// Lateral stretch of the incompressible material (initial guess).
    pub fn incompressible_lateral(self, stretch: f64) -> f64 {
        match self {
            Mode::Uniaxial => 1.0 / stretch.sqrt(),
            Mode::Equibiaxial => 1.0 / (stretch * stretch),
            Mode::PureShear => 1.0 / stretch,
        }
    }

    /// (∂P₃₃/∂t, ∂P₃₃/∂λ, ∂P₁₁/∂t, ∂P₁₁/∂λ) at fixed other stretch, from A.
    fn partials(self, a: &super::Mat9) -> (f64, f64, f64, f64) {
        // Flattened indices of F₁₁, F₂₂, F₃₃.
        let (x, y, z) = (0, 4, 8);
        match self {
            Mode::Uniaxial => (
                a[(z, y)] + a[(z, z)],
                a[(z, x)],
                a[(x, y)] + a[(x, z)],
                a[(x, x)],
            ),
            Mode::Equibiaxial => (
                a[(z, z)],
                a[(z, x)] + a[(z, y)],
                a[(x, z)],
                a[(x, x)] + a[(x, y)],
            ),
            Mode::PureShear => (a[(z, z)], a[(z, x)], a[(x, z)], a[(x, x)]),
        }
    }
}

/// Equilibrium state on a homogeneous path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HomogeneousState {
    /// Deformation gradient (diagonal).
    pub f: Mat3,
    /// Lateral stretch t.
    pub lateral: f64,
    /// Nominal stress P₁₁ (Pa).
    pub p11: f64,
    /// Total derivative dP₁₁/dλ along the path (Pa).
    pub dp11: f64,
    /// Drucker rate dτ₁₁/d(ln λ) = λ(P₁₁ + λ dP₁₁/dλ) (Pa), τ = Kirchhoff
    /// stress. Since the lateral Kirchhoff stresses vanish (and in pure shear
    /// dε₂₂ = 0), dτ:dε > 0 on the path is equivalent to this being > 0.
    pub drucker: f64,
}

/// The thickness stretch of `mat` stretched equibiaxially by λ in its plane (E₀ = 0, free
/// faces); the incompressible 1/λ² where the homogeneous solve fails.
pub fn equibiaxial_thickness(mat: &dyn Material, stretch: f64) -> f64 {
    solve(mat, Mode::Equibiaxial, stretch)
        .map(|h| h.lateral)
        .unwrap_or(1.0 / (stretch * stretch))
}

/// Solve for the lateral stretch at stretch λ (E0 = 0).
pub fn solve(
    mat: &dyn Material,
    mode: Mode,
    stretch: f64,
) -> Result<HomogeneousState, MaterialError> {
    if !(stretch.is_finite() && stretch > 0.0) {
        return Err(MaterialError::OutOfDomain(format!(
            "homogeneous path: invalid stretch {stretch}"
        )));
    }
    let e0 = Vec3::zeros();
    let scale = mat.shear_modulus().abs().max(f64::MIN_POSITIVE);
    let mut t = mode.incompressible_lateral(stretch);
    let mut tan = mat.tangent(&mode.deformation(stretch, t), &e0)?;
    let mut converged = false;
    for _ in 0..200 {
        let r = tan.p[(2, 2)];
        let (drdt, ..) = mode.partials(&tan.a);
        if r.abs() <= 1e-13 * scale {
            converged = true;
            break;
        }
        let newton = drdt > 0.0 && drdt.is_finite();
        let mut dt = if newton {
            -r / drdt
        } else {
            // Not monotone here: step in the direction that lowers the
            // residual of a stable material.
            -r.signum() * 0.1 * t
        };
        // The Newton correction is at round-off level: converged.
        if newton && dt.abs() <= 1e-13 * t {
            converged = true;
            break;
        }
        let full = dt;
        // Keep t positive and reduce |r| (backtracking).
        let mut accepted = false;
        for _ in 0..60 {
            let tn = t + dt;
            if tn > 0.0 {
                if let Ok(tn_tan) = mat.tangent(&mode.deformation(stretch, tn), &e0) {
                    if tn_tan.p[(2, 2)].abs() < r.abs() {
                        t = tn;
                        tan = tn_tan;
                        accepted = true;
                        break;
                    }
                }
            }
            dt *= 0.5;
        }
        if !accepted {
            // Residual cannot be lowered any more: accept if that is
            // round-off (negligible Newton correction).
            converged = newton && full.abs() <= 1e-10 * t;
            break;
        }
    }
    if !converged {
        return Err(MaterialError::OutOfDomain(format!(
            "{} path: no stress-free lateral stretch found at stretch {stretch}",
            mode.name()
        )));
    }
    let (drdt, drdl, dpdt, dpdl) = mode.partials(&tan.a);
    let dt_dl = -drdl / drdt;
    let p11 = tan.p[(0, 0)];
    let dp11 = dpdl + dpdt * dt_dl;
    Ok(HomogeneousState {
        f: mode.deformation(stretch, t),
        lateral: t,
        p11,
        dp11,
        drucker: stretch * (p11 + stretch * dp11),
    })
}
