//! Ogden solid with the isochoric/volumetric split
//!
//! ```text
//! W = Σₚ (μₚ/αₚ)(λ̄₁^αₚ + λ̄₂^αₚ + λ̄₃^αₚ − 3) + κ/4 (J² − 1 − 2 ln J),
//! λ̄ᵢ = J^(−1/3) λᵢ,   μ₀ = ½ Σₚ μₚαₚ,   K₀ = κ.
//! ```
//!
//! # Evaluation
//!
//! With cᵢ the eigenvalues of C (cᵢ = λᵢ²), β = α/2 and φ = J^(−α/3), each
//! term is (μ/α)(φ T − 3) with T = tr C^β = Σ cᵢ^β. Then
//!
//! ```text
//! ∂T/∂C = G = β C^(β−1),        ∂φ/∂C = −(α/6) φ C⁻¹
//! S_p   = 2(μ/α) φ (G − (α/6) T C⁻¹)   = Σᵢ μ φ (cᵢ^(β−1) − T/(3cᵢ)) Nᵢ⊗Nᵢ
//! 𝕃_p   = 4(μ/α) φ [ 𝔾 − (α/6)(G⊗C⁻¹ + C⁻¹⊗G) + (α/6)² T C⁻¹⊗C⁻¹ + (α/6) T H ]
//! ```
//!
//! where 𝔾 = ∂G/∂C is the derivative of the matrix function C ↦ h(C),
//! h(c) = β c^(β−1), given by the Daleckii–Krein formula in the eigenbasis
//! Nᵢ of C:
//!
//! ```text
//! 𝔾 = Σᵢⱼ Γᵢⱼ (Nᵢ⊗Nⱼ) ⊗ sym(Nᵢ⊗Nⱼ),   Γᵢⱼ = (h(cᵢ) − h(cⱼ))/(cᵢ − cⱼ),  Γᵢᵢ = h′(cᵢ).
//! ```
//!
//! The divided difference is evaluated without cancellation as
//! b^(m−1)·expm1(m·ln1p(δ))/δ with m = β − 1, b = max(cᵢ, cⱼ),
//! δ = (min − max)/max ∈ (−1, 0], which tends smoothly to the derivative
//! m b^(m−1) as δ → 0. No perturbation of coincident eigenvalues is needed:
//! the result is continuous and exact at F = I and for equibiaxial states.
//! H is written in the same eigenbasis (H = Σᵢⱼ (cᵢcⱼ)⁻¹ (Nᵢ⊗Nⱼ) ⊗ sym(Nᵢ⊗Nⱼ)).

use super::electroelastic::Electroelastic;
use super::hyperelastic::{
    add_vol_tangent, named, vol_log, vol_log_unit, vol_stress, HFirst, HSecond, Hyperelastic,
};
use super::isotropic::{CKinematics, Tensor4};
use super::parameters::Parameters;
use super::{Mat3, MaterialError, Vec3};

/// Ogden W = Σ (μₚ/αₚ)(Σᵢ λ̄ᵢ^αₚ − 3) + κ/4 (J² − 1 − 2 ln J).
#[derive(Debug, Clone, PartialEq)]
pub struct Ogden {
    /// Coefficients μₚ (Pa).
    pub mu: Vec<f64>,
    /// Exponents αₚ (dimensionless, non-zero), same length as `mu`.
    pub alpha: Vec<f64>,
    /// Bulk modulus κ (Pa).
    pub kappa: f64,
}

/// [`Ogden`] with a linear dielectric.
pub type ElectroOgden = Electroelastic<Ogden>;

/// (a^m − b^m)/(a − b) for a, b > 0, given `am` = a^m and `bm` = b^m;
/// continuous (→ m a^(m−1)) as a → b.
fn pow_divided_difference(a: f64, am: f64, b: f64, bm: f64, m: f64) -> f64 {
    let (lo, hi, hi_m) = if a < b { (a, b, bm) } else { (b, a, am) };
    let d = (lo - hi) / hi;
    if d == 0.0 {
        m * hi_m / hi
    } else {
        hi_m / hi * (m * d.ln_1p()).exp_m1() / d
    }
}

/// Spectral data of C.
struct Spectral {
    /// Eigenvalues cᵢ of C.
    c: Vec3,
    /// Eigenvectors (columns).
    n: Mat3,
}

impl Ogden {
    /// Ogden model; `mu` and `alpha` must have the same length.
    pub fn new(mu: Vec<f64>, alpha: Vec<f64>, kappa: f64) -> Self {
        Self { mu, alpha, kappa }
    }

    fn spectral(k: &CKinematics) -> Result<Spectral, MaterialError> {
        let eig = nalgebra::SymmetricEigen::new(k.c);
        let c = eig.eigenvalues;
        if !c.iter().all(|&x| x.is_finite() && x > 0.0) {
            return Err(MaterialError::OutOfDomain(format!(
                "Ogden: eigenvalues of C not positive: [{}, {}, {}]",
                c[0], c[1], c[2]
            )));
        }
        Ok(Spectral {
            c,
            n: eig.eigenvectors,
        })
    }

    /// Isochoric energy, plus the principal values of S_iso.
    fn iso(&self, k: &CKinematics, sp: &Spectral) -> (f64, Vec3) {
        let mut w = 0.0;
        let mut s = Vec3::zeros();
        for (&mu, &alpha) in self.mu.iter().zip(&self.alpha) {
            let beta = 0.5 * alpha;
            let phi = k.j.powf(-alpha / 3.0);
            let pw = sp.c.map(|c| c.powf(beta));
            let t = pw.sum();
            w += mu / alpha * (phi * t - 3.0);
            for i in 0..3 {
                s[i] += mu * phi * (pw[i] / sp.c[i] - t / (3.0 * sp.c[i]));
            }
        }
        (w, s)
    }
}

impl Hyperelastic for Ogden {
    fn w(&self, k: &CKinematics) -> Result<f64, MaterialError> {
        let sp = Self::spectral(k)?;
        Ok(self.iso(k, &sp).0 + vol_log(self.kappa, k.j).u)
    }

    fn s(&self, k: &CKinematics) -> Result<HFirst, MaterialError> {
        let sp = Self::spectral(k)?;
        let (w, s_p) = self.iso(k, &sp);
        let v = vol_log(self.kappa, k.j);
        let s_iso = sp.n * Mat3::from_diagonal(&s_p) * sp.n.transpose();
        Ok(HFirst {
            w: w + v.u,
            s: s_iso + vol_stress(k, &v),
        })
    }

    fn ll(&self, k: &CKinematics) -> Result<HSecond, MaterialError> {
        let sp = Self::spectral(k)?;
        let v = vol_log(self.kappa, k.j);
        let c = &sp.c;
        // Eigenbasis coefficients: 𝕃_iso = Σᵢⱼ mᵢⱼ (Nᵢ⊗Nᵢ)⊗(Nⱼ⊗Nⱼ)
        //                                 + Σᵢⱼ kᵢⱼ (Nᵢ⊗Nⱼ)⊗sym(Nᵢ⊗Nⱼ).
        let mut m = [[0.0; 3]; 3];
        let mut kk = [[0.0; 3]; 3];
        let mut w = 0.0;
        let mut s_p = Vec3::zeros();
        for (&mu, &alpha) in self.mu.iter().zip(&self.alpha) {
            let beta = 0.5 * alpha;
            let a6 = alpha / 6.0;
            let phi = k.j.powf(-alpha / 3.0);
            let pw = c.map(|x| x.powf(beta));
            let t = pw.sum();
            w += mu / alpha * (phi * t - 3.0);
            let q = pw.component_div(c); // cᵢ^(β−1)
            let g = q * beta; // h(cᵢ) = β cᵢ^(β−1)
            let f = 4.0 * mu / alpha * phi;
            for i in 0..3 {
                s_p[i] += mu * phi * (q[i] - t / (3.0 * c[i]));
                for j in i..3 {
                    let cij = 1.0 / (c[i] * c[j]);
                    let mij = f * (-a6 * (g[i] / c[j] + g[j] / c[i]) + a6 * a6 * t * cij);
                    let gamma = beta * pow_divided_difference(c[i], q[i], c[j], q[j], beta - 1.0);
                    let kij = f * (gamma + a6 * t * cij);
                    m[i][j] += mij;
                    kk[i][j] += kij;
                    if j != i {
                        m[j][i] += mij;
                        kk[j][i] += kij;
                    }
                }
            }
        }
        let n = &sp.n;
        // Dyads Nᵢ⊗Nⱼ; only the 21 independent entries of 𝕃 (minor and
        // major symmetry) are computed, then copied.
        let dyad: [[Mat3; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|j| n.column(i) * n.column(j).transpose()));
        const VOIGT: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)];
        let mut ll: Tensor4 = [[[[0.0; 3]; 3]; 3]; 3];
        for (a, &(ii, jj)) in VOIGT.iter().enumerate() {
            for &(k2, l2) in &VOIGT[a..] {
                let mut val = 0.0;
                for i in 0..3 {
                    for j in 0..3 {
                        let dij = &dyad[i][j];
                        val += m[i][j] * dyad[i][i][(ii, jj)] * dyad[j][j][(k2, l2)]
                            + kk[i][j] * dij[(ii, jj)] * 0.5 * (dij[(k2, l2)] + dij[(l2, k2)]);
                    }
                }
                for (p, q) in [(ii, jj), (jj, ii)] {
                    for (r, t) in [(k2, l2), (l2, k2)] {
                        ll[p][q][r][t] = val;
                        ll[r][t][p][q] = val;
                    }
                }
            }
        }
        add_vol_tangent(k, &v, &mut ll);
        let s_iso = n * Mat3::from_diagonal(&s_p) * n.transpose();
        Ok(HSecond {
            w: w + v.u,
            s: s_iso + vol_stress(k, &v),
            ll,
        })
    }

    fn shear_modulus(&self) -> f64 {
        0.5 * self
            .mu
            .iter()
            .zip(&self.alpha)
            .map(|(m, a)| m * a)
            .sum::<f64>()
    }

    fn bulk_modulus(&self) -> f64 {
        self.kappa
    }

    /// `mu.0`, `mu.1`, …, `alpha.0`, `alpha.1`, …, `kappa` (the scenario's lists by index).
    fn parameters(&self) -> Option<Parameters> {
        let mut p = named("ogden", &[], &[]);
        for (i, &m) in self.mu.iter().enumerate() {
            p.push(format!("mu.{i}"), m);
        }
        for (i, &a) in self.alpha.iter().enumerate() {
            p.push(format!("alpha.{i}"), a);
        }
        p.push("kappa", self.kappa);
        Some(p)
    }

    /// W is linear in the μₚ and κ. In αₚ, with φ = J^(−α/3), T = Σ cᵢ^(α/2):
    /// ∂φ/∂α = −(ln J/3)φ, ∂T/∂α = ½ Σ ln cᵢ cᵢ^(α/2), and the term (μ/α)(φT − 3) with its
    /// principal stresses μφ(cᵢ^(α/2) − T/3)/cᵢ are differentiated by the product rule.
    fn parameter_derivatives(&self, k: &CKinematics) -> Result<Vec<HFirst>, MaterialError> {
        let sp = Self::spectral(k)?;
        let n = &sp.n;
        let principal = |s: Vec3| n * Mat3::from_diagonal(&s) * n.transpose();
        let mut out = Vec::with_capacity(2 * self.mu.len() + 1);
        for &alpha in &self.alpha {
            let unit = Ogden::new(vec![1.0], vec![alpha], 0.0);
            let (w, s) = unit.iso(k, &sp);
            out.push(HFirst { w, s: principal(s) });
        }
        for (&mu, &alpha) in self.mu.iter().zip(&self.alpha) {
            let beta = 0.5 * alpha;
            let phi = k.j.powf(-alpha / 3.0);
            let dphi = -k.j.ln() / 3.0 * phi;
            let pw = sp.c.map(|c| c.powf(beta));
            let dpw = Vec3::from_fn(|i, _| 0.5 * sp.c[i].ln() * pw[i]);
            let (t, dt) = (pw.sum(), dpw.sum());
            let w = -mu / (alpha * alpha) * (phi * t - 3.0) + mu / alpha * (dphi * t + phi * dt);
            let s = Vec3::from_fn(|i, _| {
                mu * (dphi * (pw[i] - t / 3.0) + phi * (dpw[i] - dt / 3.0)) / sp.c[i]
            });
            out.push(HFirst { w, s: principal(s) });
        }
        out.push(vol_log_unit(k));
        Ok(out)
    }
}
