//! Purely mechanical isotropic hyperelastic energies W(C) and the shared
//! building blocks (isochoric invariants, volumetric functions) used by the
//! models in this directory.
//!
//! A model implements [`Hyperelastic`], returning
//!
//! * `W(C)`,
//! * `S = 2 ∂W/∂C`,
//! * `𝕃 = 4 ∂²W/∂C∂C` (minor and major symmetry),
//!
//! and is combined with an [`ElectricPart`](super::electric::ElectricPart) by
//! [`Electroelastic`](super::electroelastic::Electroelastic).
//!
//! # Invariant-based models
//!
//! With I₁ = tr C, I₂ = ½(I₁² − tr C²), J = √det C and the isochoric
//! invariants Ī₁ = J^(−2/3) I₁, Ī₂ = J^(−4/3) I₂ one has (Ci = C⁻¹)
//!
//! ```text
//! ∂Ī₁/∂C = J^(−2/3) (I − I₁/3 Ci)
//! ∂Ī₂/∂C = J^(−4/3) (I₁ I − C − 2I₂/3 Ci)
//! ∂²Ī₁/∂C² = J^(−2/3) [ −⅓(I⊗Ci + Ci⊗I) + I₁/9 Ci⊗Ci + I₁/3 H ]
//! ∂²Ī₂/∂C² = J^(−4/3) [ I⊗I − 𝕀 − ⅔I₁(I⊗Ci + Ci⊗I) + ⅔(C⊗Ci + Ci⊗C)
//!                        + 4I₂/9 Ci⊗Ci + 2I₂/3 H ]
//! ```
//!
//! with H_IJKL = ½(Ci_IK Ci_JL + Ci_IL Ci_JK) = −∂Ci_IJ/∂C_KL and
//! 𝕀_IJKL = ½(δ_IK δ_JL + δ_IL δ_JK). For W = Ŵ(Ī₁, Ī₂) + U(J):
//!
//! ```text
//! S = 2(W₁ ∂Ī₁/∂C + W₂ ∂Ī₂/∂C) + J U′ Ci
//! 𝕃 = 4[ W₁₁ A⊗A + W₁₂(A⊗B + B⊗A) + W₂₂ B⊗B + W₁ ∂²Ī₁/∂C² + W₂ ∂²Ī₂/∂C² ]
//!     + J(U′ + J U″) Ci⊗Ci − 2J U′ H          (A = ∂Ī₁/∂C, B = ∂Ī₂/∂C)
//! ```
//!
//! # The first Piola form of the Ī₁ models
//!
//! For W = Ŵ(Ī₁) + U(J) the stress and its derivative follow from F, f = F⁻ᵀ and I₁ = F:F
//! without C, C⁻¹ or 𝕃 (dJ = J f:dF, df_iJ = −f_iL f_kJ dF_kL, dĪ₁ = 2J^(−2/3) g:dF):
//!
//! ```text
//! P = a F + β f,      a = 2W₁J^(−2/3),  β = J U′ − a I₁/3,  g = F − I₁/3 f
//! A_iJkL = a δ_ik δ_JL + c g_iJ g_kL − (2a/3)(F_iJ f_kL + f_iJ F_kL)
//!          + (J(U′ + J U″) + 2a I₁/9) f_iJ f_kL − β f_iL f_kJ,     c = 4W₁₁J^(−4/3)
//! ```
//!
//! (the same A as the conversion of 𝕃 gives, without forming 𝕃).
//!
//! # Volumetric functions
//!
//! The split models (neo-Hooke split, Gent, Ogden, both Arruda–Boyce forms) all use
//! [`vol_log`], U(J) = κ/4 (J² − 1 − 2 ln J), the function of the deal.II
//! Cook's membrane benchmark (U″(1) = κ, so the small-strain bulk modulus
//! is κ; U grows without bound for J → 0 and J → ∞). Yeoh and Mooney–Rivlin
//! use the Abaqus polynomial form [`vol_poly`], U = Σᵢ (1/Dᵢ)(J − 1)^(2i),
//! with K₀ = 2/D₁.

use super::isotropic::{CKinematics, Tensor4};
use super::parameters::Parameters;
use super::{Known, KnownDeformation, KnownLanes, Mat3, Mat9, MaterialError};
use crate::algebra::lanes::{norm_squared, Lane, F4, LANES};
use nalgebra::Matrix3;
use num_traits::Zero;

/// W and S = 2∂W/∂C.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HFirst {
    /// Energy per reference volume W (J/m³).
    pub w: f64,
    /// S = 2 ∂W/∂C (Pa).
    pub s: Mat3,
}

/// W, S and 𝕃 = 4∂²W/∂C².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HSecond {
    /// Energy per reference volume W (J/m³).
    pub w: f64,
    /// S = 2 ∂W/∂C (Pa).
    pub s: Mat3,
    /// 𝕃 = 4 ∂²W/∂C∂C (Pa), minor and major symmetry.
    pub ll: Tensor4,
}

/// A purely mechanical isotropic strain energy W(C) per unit reference
/// volume.
pub trait Hyperelastic: Send + Sync + std::fmt::Debug {
    /// W(C).
    fn w(&self, k: &CKinematics) -> Result<f64, MaterialError>;
    /// W and S = 2∂W/∂C.
    fn s(&self, k: &CKinematics) -> Result<HFirst, MaterialError>;
    /// W, S and 𝕃 = 4∂²W/∂C².
    fn ll(&self, k: &CKinematics) -> Result<HSecond, MaterialError>;
    /// W and the first Piola stress P = ∂W/∂F = F S straight from a known deformation (no C,
    /// C⁻¹ or F·S product); `None` when the model has no such form and the caller forms S.
    fn first_piola(&self, _k: &KnownDeformation) -> Option<Result<(f64, Mat3), MaterialError>> {
        None
    }
    /// [`Hyperelastic::first_piola`] of [`LANES`](crate::algebra::lanes::LANES) points, one a
    /// lane, each the same bits as `first_piola` of its point; `None` when the model has no
    /// such form or a lane is outside its domain.
    fn first_piola_lanes(&self, _k: &KnownLanes) -> Option<(F4, Matrix3<F4>)> {
        None
    }
    /// W, P and A = ∂P/∂F straight from a known deformation (no 𝕃 and no conversion of it),
    /// P the same bits as [`Hyperelastic::first_piola`]; `None` when the model has no such
    /// form and the caller converts 𝕃.
    fn first_piola_tangent(&self, _k: &KnownDeformation) -> Option<PiolaTangent> {
        None
    }
    /// Small-strain shear modulus μ₀ (Pa).
    fn shear_modulus(&self) -> f64;
    /// Small-strain bulk modulus K₀ (Pa).
    fn bulk_modulus(&self) -> f64;
    /// How far the chains are towards the model's locking limit (1 = locked) and the key of the
    /// parameter that sets it; `None` for a model without one.
    fn locking(&self, _k: &CKinematics) -> Option<(f64, &'static str)> {
        None
    }
    /// The registry model this is and its mechanical parameters as named entries of θ (see
    /// [`super::parameters`]); `None` for a model the registry does not build.
    fn parameters(&self) -> Option<Parameters> {
        None
    }
    /// ∂W/∂θ and ∂S/∂θ for every entry of [`Hyperelastic::parameters`], in its order.
    fn parameter_derivatives(&self, _k: &CKinematics) -> Result<Vec<HFirst>, MaterialError> {
        Ok(Vec::new())
    }
}

/// The entries `names` with `values` of model `model`.
pub(crate) fn named(model: &'static str, names: &[&str], values: &[f64]) -> Parameters {
    Parameters {
        model,
        names: names.iter().map(|n| n.to_string()).collect(),
        values: values.to_vec(),
    }
}

/// W and S of κ/4 (J² − 1 − 2 ln J) with κ = 1: the derivative of every split model in κ.
pub(crate) fn vol_log_unit(k: &CKinematics) -> HFirst {
    let v = vol_log(1.0, k.j);
    HFirst {
        w: v.u,
        s: vol_stress(k, &v),
    }
}

/// W and S of (J − 1)^(2i)/Dᵢ differentiated in Dᵢ (i = `term` + 1): −1/Dᵢ² times the term with
/// 1/Dᵢ = 1.
pub(crate) fn vol_poly_d(k: &CKinematics, term: usize, d: f64) -> HFirst {
    let mut inv = [0.0; 3];
    inv[term] = 1.0;
    let v = vol_poly(&inv[..=term], k.j);
    let scale = -1.0 / (d * d);
    HFirst {
        w: v.u * scale,
        s: vol_stress(k, &v) * scale,
    }
}

/// S of Ŵ(Ī₁, Ī₂) for the derivatives `w1`, `w2` with W = `w`: a parameter's derivative in an
/// invariant-based model.
pub(crate) fn iso_first(k: &CKinematics, inv: &IsoInvariants, w: f64, w1: f64, w2: f64) -> HFirst {
    HFirst {
        w,
        s: iso_stress(
            k,
            inv,
            &InvariantDerivs {
                w1,
                w2,
                ..Default::default()
            },
        ),
    }
}

/// Value and first two derivatives of a volumetric function U(J) (of one point, or of a
/// [`Lane`] of points).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VolDerivs<T = f64> {
    /// U(J).
    pub u: T,
    /// U′(J).
    pub du: T,
    /// U″(J).
    pub ddu: T,
}

/// U(J) = κ/4 (J² − 1 − 2 ln J): U′ = κ/2 (J − 1/J), U″ = κ/2 (1 + 1/J²).
#[inline(always)]
pub fn vol_log<T: Lane>(kappa: f64, j: T) -> VolDerivs<T> {
    let one = T::one();
    let two = T::splat(2.0);
    VolDerivs {
        u: T::splat(0.25 * kappa) * (j * j - one - two * j.map(f64::ln)),
        du: T::splat(0.5 * kappa) * (j - one / j),
        ddu: T::splat(0.5 * kappa) * (one + one / (j * j)),
    }
}

/// Abaqus polynomial form U(J) = Σᵢ (1/Dᵢ)(J − 1)^(2i), i = 1, 2, …, given
/// the inverse compressibilities `inv_d[i−1]` = 1/Dᵢ (0 for an absent term).
#[inline(always)]
pub fn vol_poly<T: Lane>(inv_d: &[f64], j: T) -> VolDerivs<T> {
    let x = j - T::one();
    let x2 = x * x;
    let mut v = VolDerivs {
        u: T::zero(),
        du: T::zero(),
        ddu: T::zero(),
    };
    // Term i: (J−1)^(2i)/Dᵢ, derivative 2i (J−1)^(2i−1)/Dᵢ,
    // second derivative 2i(2i−1)(J−1)^(2i−2)/Dᵢ.
    let mut x2im2 = T::one(); // (J−1)^(2i−2)
    for (idx, &c) in inv_d.iter().enumerate() {
        let n = 2.0 * (idx + 1) as f64;
        v.u += T::splat(c) * x2im2 * x2;
        v.du += T::splat(c * n) * x2im2 * x;
        v.ddu += T::splat(c * n * (n - 1.0)) * x2im2;
        x2im2 *= x2;
    }
    v
}

/// Volumetric stress S_vol = J U′ C⁻¹.
#[inline]
pub fn vol_stress(k: &CKinematics, v: &VolDerivs) -> Mat3 {
    k.c_inv * (k.j * v.du)
}

/// Adds 𝕃_vol = J(U′ + J U″) C⁻¹⊗C⁻¹ − 2J U′ H to `ll`.
pub fn add_vol_tangent(k: &CKinematics, v: &VolDerivs, ll: &mut Tensor4) {
    let cc = k.j * (v.du + k.j * v.ddu);
    let hh = -2.0 * k.j * v.du;
    let ci = &k.c_inv;
    for (i, lli) in ll.iter_mut().enumerate() {
        for (j, llij) in lli.iter_mut().enumerate() {
            for (kk, llijk) in llij.iter_mut().enumerate() {
                for (l, x) in llijk.iter_mut().enumerate() {
                    let h = 0.5 * (ci[(i, kk)] * ci[(j, l)] + ci[(i, l)] * ci[(j, kk)]);
                    *x += cc * ci[(i, j)] * ci[(kk, l)] + hh * h;
                }
            }
        }
    }
}

/// Invariants of C needed by the invariant-based models.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IsoInvariants {
    /// I₁ = tr C.
    pub i1: f64,
    /// I₂ = ½(I₁² − tr C²).
    pub i2: f64,
    /// J^(−2/3).
    pub jm23: f64,
    /// Ī₁ = J^(−2/3) I₁.
    pub i1b: f64,
    /// Ī₂ = J^(−4/3) I₂.
    pub i2b: f64,
}

impl IsoInvariants {
    /// Invariants from the kinematics.
    #[inline]
    pub fn new(k: &CKinematics) -> Self {
        let i1 = k.c.trace();
        let i2 = 0.5 * (i1 * i1 - (k.c * k.c).trace());
        let jm23 = k.j.powf(-2.0 / 3.0);
        Self {
            i1,
            i2,
            jm23,
            i1b: jm23 * i1,
            i2b: jm23 * jm23 * i2,
        }
    }

    /// ∂Ī₁/∂C = J^(−2/3)(I − I₁/3 C⁻¹).
    pub fn d_i1b(&self, k: &CKinematics) -> Mat3 {
        (Mat3::identity() - k.c_inv * (self.i1 / 3.0)) * self.jm23
    }

    /// ∂Ī₂/∂C = J^(−4/3)(I₁ I − C − 2I₂/3 C⁻¹).
    pub fn d_i2b(&self, k: &CKinematics) -> Mat3 {
        (Mat3::identity() * self.i1 - k.c - k.c_inv * (2.0 * self.i2 / 3.0))
            * (self.jm23 * self.jm23)
    }
}

/// P = F S of W = Ŵ(Ī₁) + U(J) at a known deformation: with F C⁻¹ = F⁻ᵀ,
/// P = 2W₁ J^(−2/3)(F − I₁/3 F⁻ᵀ) + J U′ F⁻ᵀ (`i1` = I₁ = F:F, `w1` = ∂Ŵ/∂Ī₁, `du` = U′).
#[inline(always)]
pub fn i1_model_piola<T: Lane>(k: &Known<T>, i1: T, w1: T, du: T) -> Matrix3<T> {
    let a = T::splat(2.0) * w1 * k.jm23;
    k.f * a + k.f_inv_t * (k.j * du - a * i1 / T::splat(3.0))
}

/// W, P and A = ∂P/∂F of a point ([`Hyperelastic::first_piola_tangent`]).
pub type PiolaTangent = Result<(f64, Mat3, Mat9), MaterialError>;

/// A = ∂P/∂F of W = Ŵ(Ī₁) + U(J) at a known deformation (the module documentation's first
/// Piola form): `i1` = F:F, `d` the derivatives of Ŵ (W₂ and beyond unused), `v` those of U.
pub fn i1_model_tangent(k: &KnownDeformation, i1: f64, d: &InvariantDerivs, v: &VolDerivs) -> Mat9 {
    let a = 2.0 * d.w1 * k.jm23;
    let c = 4.0 * d.w11 * k.jm23 * k.jm23;
    let beta = k.j * v.du - a * i1 / 3.0;
    let ff = k.j * (v.du + k.j * v.ddu) + 2.0 * a * i1 / 9.0;
    let cross = 2.0 * a / 3.0;
    let nine = |m: &Mat3| -> [f64; 9] { std::array::from_fn(|r| m[(r / 3, r % 3)]) };
    let f = nine(&k.f);
    let fi = nine(&k.f_inv_t);
    let g: [f64; 9] = std::array::from_fn(|r| f[r] - fi[r] * (i1 / 3.0));
    let mut out = Mat9::zeros();
    for col in 0..9 {
        let (kk, l) = (col / 3, col % 3);
        let (gc, fc, fic) = (c * g[col], cross * f[col], fi[col]);
        for row in 0..9 {
            let (i, jj) = (row / 3, row % 3);
            out[(row, col)] = gc * g[row] - cross * f[row] * fic - fi[row] * fc
                + ff * fi[row] * fic
                - beta * fi[i * 3 + l] * fi[kk * 3 + jj];
        }
        out[(col, col)] += a;
    }
    out
}

/// Derivatives of the isochoric energy Ŵ(Ī₁, Ī₂) (of one point, or of a [`Lane`] of points).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InvariantDerivs<T = f64> {
    /// ∂Ŵ/∂Ī₁.
    pub w1: T,
    /// ∂Ŵ/∂Ī₂.
    pub w2: T,
    /// ∂²Ŵ/∂Ī₁².
    pub w11: T,
    /// ∂²Ŵ/∂Ī₁∂Ī₂.
    pub w12: T,
    /// ∂²Ŵ/∂Ī₂².
    pub w22: T,
}

/// S_iso = 2(W₁ ∂Ī₁/∂C + W₂ ∂Ī₂/∂C).
#[inline]
pub fn iso_stress(k: &CKinematics, inv: &IsoInvariants, d: &InvariantDerivs) -> Mat3 {
    let mut s = inv.d_i1b(k) * (2.0 * d.w1);
    if d.w2 != 0.0 {
        s += inv.d_i2b(k) * (2.0 * d.w2);
    }
    s
}

/// 𝕃_iso = 4[W₁₁ A⊗A + W₁₂(A⊗B + B⊗A) + W₂₂ B⊗B + W₁ ∂²Ī₁ + W₂ ∂²Ī₂]
/// (see the module documentation).
pub fn iso_tangent(k: &CKinematics, inv: &IsoInvariants, d: &InvariantDerivs) -> Tensor4 {
    let ci = &k.c_inv;
    let c = &k.c;
    let a = inv.d_i1b(k);
    let b = inv.d_i2b(k);
    let with_i2 = d.w2 != 0.0 || d.w12 != 0.0 || d.w22 != 0.0;
    let del = |p: usize, q: usize| if p == q { 1.0 } else { 0.0 };
    // Coefficients of the second-derivative terms, with the factor 4 and
    // the J powers folded in.
    let f1 = 4.0 * d.w1 * inv.jm23;
    let f2 = 4.0 * d.w2 * inv.jm23 * inv.jm23;
    let (i1, i2) = (inv.i1, inv.i2);
    let mut ll: Tensor4 = [[[[0.0; 3]; 3]; 3]; 3];
    for (i, lli) in ll.iter_mut().enumerate() {
        for (j, llij) in lli.iter_mut().enumerate() {
            let (aij, bij, cij, dij, cmij) =
                (a[(i, j)], b[(i, j)], ci[(i, j)], del(i, j), c[(i, j)]);
            for (kk, llijk) in llij.iter_mut().enumerate() {
                for (l, x) in llijk.iter_mut().enumerate() {
                    let (akl, ckl, dkl) = (a[(kk, l)], ci[(kk, l)], del(kk, l));
                    let h = 0.5 * (ci[(i, kk)] * ci[(j, l)] + ci[(i, l)] * ci[(j, kk)]);
                    let mut v = 4.0 * d.w11 * aij * akl
                        + f1 * (-(dij * ckl + cij * dkl) / 3.0
                            + i1 / 9.0 * cij * ckl
                            + i1 / 3.0 * h);
                    if with_i2 {
                        let bkl = b[(kk, l)];
                        let sym_i = 0.5 * (del(i, kk) * del(j, l) + del(i, l) * del(j, kk));
                        v += 4.0 * d.w12 * (aij * bkl + bij * akl)
                            + 4.0 * d.w22 * bij * bkl
                            + f2 * (dij * dkl - sym_i - 2.0 / 3.0 * i1 * (dij * ckl + cij * dkl)
                                + 2.0 / 3.0 * (cmij * ckl + cij * c[(kk, l)])
                                + 4.0 * i2 / 9.0 * cij * ckl
                                + 2.0 * i2 / 3.0 * h);
                    }
                    *x = v;
                }
            }
        }
    }
    ll
}

/// Complete [`HSecond`] for W = Ŵ(Ī₁, Ī₂) + U(J).
pub fn invariant_model_second(
    k: &CKinematics,
    inv: &IsoInvariants,
    w: f64,
    d: &InvariantDerivs,
    v: &VolDerivs,
) -> HSecond {
    let s = iso_stress(k, inv, d) + vol_stress(k, v);
    let mut ll = iso_tangent(k, inv, d);
    add_vol_tangent(k, v, &mut ll);
    HSecond { w, s, ll }
}

/// The [`Hyperelastic`] methods of W = Ŵ(Ī₁) + U(J) with U the logarithmic volumetric part of
/// bulk modulus `kappa` ([`vol_log`]): one body for the Gent and Arruda–Boyce models. `iso`
/// gives Ŵ(Ī₁) and its derivatives, or the error of an Ī₁ outside its domain (a locking limit).
pub struct SplitI1<F> {
    pub iso: F,
    pub kappa: f64,
}

impl<F: Fn(f64) -> Result<(f64, InvariantDerivs), MaterialError>> SplitI1<F> {
    /// W.
    pub fn w(&self, k: &CKinematics) -> Result<f64, MaterialError> {
        let inv = IsoInvariants::new(k);
        Ok((self.iso)(inv.i1b)?.0 + vol_log(self.kappa, k.j).u)
    }

    /// W and S.
    pub fn s(&self, k: &CKinematics) -> Result<HFirst, MaterialError> {
        let inv = IsoInvariants::new(k);
        let (w, d) = (self.iso)(inv.i1b)?;
        let v = vol_log(self.kappa, k.j);
        Ok(HFirst {
            w: w + v.u,
            s: iso_stress(k, &inv, &d) + vol_stress(k, &v),
        })
    }

    /// W, S and the tangent.
    pub fn ll(&self, k: &CKinematics) -> Result<HSecond, MaterialError> {
        let inv = IsoInvariants::new(k);
        let (w, d) = (self.iso)(inv.i1b)?;
        let v = vol_log(self.kappa, k.j);
        Ok(invariant_model_second(k, &inv, w + v.u, &d, &v))
    }

    /// W and P at a known deformation.
    pub fn first_piola(&self, k: &KnownDeformation) -> Result<(f64, Mat3), MaterialError> {
        let i1 = norm_squared(&k.f);
        let v = vol_log(self.kappa, k.j);
        (self.iso)(k.jm23 * i1).map(|(w, d)| (w + v.u, i1_model_piola(k, i1, d.w1, v.du)))
    }

    /// W, P and A at a known deformation.
    pub fn first_piola_tangent(&self, k: &KnownDeformation) -> PiolaTangent {
        let i1 = norm_squared(&k.f);
        let v = vol_log(self.kappa, k.j);
        let (w, d) = (self.iso)(k.jm23 * i1)?;
        Ok((
            w + v.u,
            i1_model_piola(k, i1, d.w1, v.du),
            i1_model_tangent(k, i1, &d, &v),
        ))
    }

    /// [`SplitI1::first_piola`] of a lane of points (Ŵ lane by lane); `None` when a lane is
    /// outside Ŵ's domain.
    #[inline(always)]
    pub fn first_piola_lanes(&self, k: &KnownLanes) -> Option<(F4, Matrix3<F4>)> {
        let i1 = norm_squared(&k.f);
        let v = vol_log(self.kappa, k.j);
        let i1b = k.jm23 * i1;
        let (mut w, mut w1) = (F4::zero(), F4::zero());
        for l in 0..LANES {
            let (wl, d) = (self.iso)(i1b.0[l]).ok()?;
            w.0[l] = wl;
            w1.0[l] = d.w1;
        }
        Some((w + v.u, i1_model_piola(k, i1, w1, v.du)))
    }
}
