//! Linear dielectric part of the energy, shared by every electro-elastic
//! model:
//!
//! ```text
//! Ω_e(C, E0) = c₁ E0·E0 + c₂ E0·(C E0) − ε/2 J E0·(C⁻¹E0)
//! ```
//!
//! With c₁ = c₂ = 0 this is the ideal dielectric (ε = εᵣε₀); the "Vu" form
//! uses ε = ε₀ and electrostrictive coefficients c₁, c₂. The small-strain
//! permittivity is ε − 2c₁ − 2c₂.
//!
//! Derivatives (g = C⁻¹E0, a = E0·g, H_IJKL = ½(C⁻¹_IK C⁻¹_JL + C⁻¹_IL C⁻¹_JK)):
//!
//! ```text
//! S_e  = 2c₂ E0⊗E0 + εJ (g⊗g − ½ a C⁻¹)
//! D0   = −2c₁E0 − 2c₂ C E0 + εJ g
//! 𝕃_e  = εJ a H − ½ εJ a C⁻¹⊗C⁻¹
//!        + εJ [ (g⊗g)⊗C⁻¹ + C⁻¹⊗(g⊗g)
//!               − (C⁻¹_IK g_J g_L + C⁻¹_IL g_J g_K + C⁻¹_JK g_I g_L + C⁻¹_JL g_I g_K) ]
//! ∂S_IJ/∂E0_K = 2c₂(δ_IK E0_J + E0_I δ_JK) + εJ (C⁻¹_IK g_J + g_I C⁻¹_JK − g_K C⁻¹_IJ)
//! ∂D0/∂E0     = −2c₁ I − 2c₂ C + εJ C⁻¹
//! ```

use super::isotropic::{CKinematics, Tensor3, Tensor4};
use super::{ElectricTangent, Known, KnownDeformation, Mat3, Mat9, Mat93, Vec3, EPSILON_0};
use crate::algebra::lanes::Lane;
use nalgebra::{Matrix3, Vector3};

/// Dielectric part of the energy (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElectricPart {
    /// Permittivity ε (F/m).
    pub eps: f64,
    /// Electrostrictive coefficient c₁ (F/m = N/V²).
    pub c1: f64,
    /// Electrostrictive coefficient c₂ (F/m = N/V²).
    pub c2: f64,
}

/// The field's terms of the first Piola forms: e = F⁻ᵀE0, g = C⁻¹E0 = F⁻¹e and C⁻¹ = F⁻¹F⁻ᵀ.
struct FieldTerms {
    e: Vec3,
    g: Vec3,
    ci: Mat3,
}

impl FieldTerms {
    #[inline]
    fn new(f_inv_t: &Mat3, e0: &Vec3) -> Self {
        let e = f_inv_t * e0;
        FieldTerms {
            e,
            g: f_inv_t.tr_mul(&e),
            ci: f_inv_t.tr_mul(f_inv_t),
        }
    }
}

impl ElectricPart {
    /// Ideal dielectric with relative permittivity εᵣ: ε = εᵣε₀, c₁ = c₂ = 0.
    pub fn ideal(eps_r: f64) -> Self {
        Self {
            eps: eps_r * EPSILON_0,
            c1: 0.0,
            c2: 0.0,
        }
    }

    /// Same part with the electrostrictive coefficients set to (c₁, c₂).
    pub fn with_coupling(self, c1: f64, c2: f64) -> Self {
        Self { c1, c2, ..self }
    }

    /// Small-strain permittivity ε − 2c₁ − 2c₂ (F/m).
    pub fn small_strain_permittivity(&self) -> f64 {
        self.eps - 2.0 * self.c1 - 2.0 * self.c2
    }

    /// Ω_e = c₁ E0·E0 + c₂ E0·CE0 − ε/2 J E0·C⁻¹E0 (the E0-dependent part of
    /// the energy; the bookkeeping "electric energy" is −Ω_e).
    #[inline]
    pub fn energy(&self, k: &CKinematics, e0: &Vec3) -> f64 {
        let ee = e0.dot(e0);
        let ece = e0.dot(&(k.c * e0));
        let a = e0.dot(&(k.c_inv * e0));
        self.c1 * ee + self.c2 * ece - 0.5 * self.eps * k.j * a
    }

    /// (S_e, D0).
    #[inline]
    pub fn first(&self, k: &CKinematics, e0: &Vec3) -> (Mat3, Vec3) {
        let ci = &k.c_inv;
        let g = ci * e0;
        let a = e0.dot(&g);
        let ej = self.eps * k.j;
        let s = e0 * e0.transpose() * (2.0 * self.c2) + (g * g.transpose() - ci * (0.5 * a)) * ej;
        (s, self.d0(k, e0))
    }

    /// D0 alone (as in [`ElectricPart::first`]).
    #[inline]
    pub fn d0(&self, k: &CKinematics, e0: &Vec3) -> Vec3 {
        let g = k.c_inv * e0;
        let ej = self.eps * k.j;
        e0 * (-2.0 * self.c1) - (k.c * e0) * (2.0 * self.c2) + g * ej
    }

    /// (Ω_e, P_e = F S_e, D0) at a known deformation, with the spatial field e = F⁻ᵀE0,
    /// g = C⁻¹E0 = F⁻¹e and a = E0·g = e·e (F g = e, F C⁻¹ = F⁻ᵀ):
    /// P_e = 2c₂ (F E0)⊗E0 + εJ (e⊗g − ½ a F⁻ᵀ), D0 = −2c₁E0 − 2c₂ Fᵀ(F E0) + εJ g,
    /// Ω_e = c₁ E0·E0 + c₂ |F E0|² − ½ εJ a. No C or C⁻¹ is formed.
    #[inline(always)]
    pub fn first_known<T: Lane>(
        &self,
        k: &Known<T>,
        e0: &Vector3<T>,
    ) -> (T, Matrix3<T>, Vector3<T>) {
        let e = k.f_inv_t * e0;
        let g = k.f_inv_t.tr_mul(&e);
        let a = e.dot(&e);
        let ej = T::splat(self.eps) * k.j;
        let mut energy = T::splat(-0.5) * ej * a;
        let mut p = e * g.transpose() * ej - k.f_inv_t * (T::splat(0.5) * a * ej);
        let mut d0 = g * ej;
        if self.c1 != 0.0 {
            energy += T::splat(self.c1) * e0.dot(e0);
            d0 -= e0 * T::splat(2.0 * self.c1);
        }
        if self.c2 != 0.0 {
            let fe = k.f * e0;
            energy += T::splat(self.c2) * fe.dot(&fe);
            p += fe * e0.transpose() * T::splat(2.0 * self.c2);
            d0 -= k.f.tr_mul(&fe) * T::splat(2.0 * self.c2);
        }
        (energy, p, d0)
    }

    /// D0 alone at a known deformation (as in [`ElectricPart::first_known`]).
    #[inline]
    pub fn d0_known(&self, k: &KnownDeformation, e0: &Vec3) -> Vec3 {
        self.d0_from(&k.f, &k.f_inv_t, k.j, e0)
    }

    /// [`ElectricPart::d0_known`] from F, F⁻ᵀ and J.
    #[inline]
    fn d0_from(&self, f: &Mat3, f_inv_t: &Mat3, j: f64, e0: &Vec3) -> Vec3 {
        let g = f_inv_t.tr_mul(&(f_inv_t * e0));
        let mut d0 = g * (self.eps * j);
        if self.c1 != 0.0 {
            d0 -= e0 * (2.0 * self.c1);
        }
        if self.c2 != 0.0 {
            d0 -= f.tr_mul(&(f * e0)) * (2.0 * self.c2);
        }
        d0
    }

    /// (Ω_e, P_e, D0) as [`ElectricPart::first_known`] gives them, with B, G, and A_e = ∂P_e/∂F
    /// added to `a_out`, at a known deformation (its notation, f = F⁻ᵀ, C⁻¹ = fᵀf; no 𝕃_e is
    /// formed):
    /// A_e,iJkL = 2c₂ δ_ik E0_J E0_L − ½εJ [a (f_iJ f_kL − f_iL f_kJ) − 2(e_i g_J f_kL + f_iJ e_k g_L)
    ///            + 2(f_iL e_k g_J + e_i g_L f_kJ) + 2 e_i e_k C⁻¹_JL],
    /// B_iJ,K = 2c₂(F_iK E0_J + (F E0)_i δ_JK) − εJ (f_iJ g_K − f_iK g_J − e_i C⁻¹_JK),
    /// G = 2c₁ I + 2c₂ C − εJ C⁻¹.
    pub fn tangent_known(
        &self,
        k: &KnownDeformation,
        e0: &Vec3,
        a_out: &mut Mat9,
    ) -> (f64, Mat3, ElectricTangent) {
        let (energy, p, d0) = self.first_known(k, e0);
        let fi = &k.f_inv_t;
        let FieldTerms { e, g, ci } = FieldTerms::new(fi, e0);
        let a = e.dot(&e);
        let ej = self.eps * k.j;
        if *e0 != Vec3::zeros() {
            // −½εJ [...] with its rank-one products over the rows and, with u = e⊗g and
            // w = 2u − (a/2) f, the crossed terms f_iL w_kJ + w_iL f_kJ
            let h = -0.5 * ej;
            let nine = |m: &Mat3| -> [f64; 9] { std::array::from_fn(|r| m[(r / 3, r % 3)]) };
            let f9 = nine(fi);
            let u9: [f64; 9] = std::array::from_fn(|r| e[r / 3] * g[r % 3]);
            let w9: [f64; 9] = std::array::from_fn(|r| 2.0 * u9[r] - 0.5 * a * f9[r]);
            for col in 0..9 {
                let (kk, l) = (col / 3, col % 3);
                let p_col = h * (a * f9[col] - 2.0 * u9[col]);
                let q_col = 2.0 * h * f9[col];
                for row in 0..9 {
                    let (i, jj) = (row / 3, row % 3);
                    let (il, kj) = (i * 3 + l, kk * 3 + jj);
                    let mut v = f9[row] * p_col - u9[row] * q_col
                        + h * (f9[il] * w9[kj] + w9[il] * f9[kj])
                        + 2.0 * h * e[i] * e[kk] * ci[(jj, l)];
                    if i == kk {
                        v += 2.0 * self.c2 * e0[jj] * e0[l];
                    }
                    a_out[(row, col)] += v;
                }
            }
        }
        let (b, g_blk) = self.mixed_known(&k.f, fi, k.j, e0, &FieldTerms { e, g, ci });
        (energy, p, ElectricTangent { d0, b, g: g_blk })
    }

    /// D0, B and G of [`ElectricPart::tangent_known`] from F, F⁻ᵀ and J alone: what the rows of
    /// Gauss's law need, without A.
    pub fn electric_tangent_known(
        &self,
        f: &Mat3,
        f_inv_t: &Mat3,
        j: f64,
        e0: &Vec3,
    ) -> ElectricTangent {
        let terms = FieldTerms::new(f_inv_t, e0);
        let (b, g) = self.mixed_known(f, f_inv_t, j, e0, &terms);
        ElectricTangent {
            d0: self.d0_from(f, f_inv_t, j, e0),
            b,
            g,
        }
    }

    /// (B, G) of [`ElectricPart::tangent_known`].
    fn mixed_known(
        &self,
        f: &Mat3,
        fi: &Mat3,
        j: f64,
        e0: &Vec3,
        terms: &FieldTerms,
    ) -> (Mat93, Mat3) {
        let FieldTerms { e, g, ci } = terms;
        let ej = self.eps * j;
        let fe = f * e0;
        let mut b = Mat93::zeros();
        for i in 0..3 {
            for jj in 0..3 {
                for kk in 0..3 {
                    let mut v =
                        -ej * (fi[(i, jj)] * g[kk] - fi[(i, kk)] * g[jj] - e[i] * ci[(jj, kk)]);
                    v += 2.0 * self.c2 * f[(i, kk)] * e0[jj];
                    if jj == kk {
                        v += 2.0 * self.c2 * fe[i];
                    }
                    b[(i * 3 + jj, kk)] = v;
                }
            }
        }
        let g_blk = Mat3::identity() * (2.0 * self.c1) + f.tr_mul(f) * (2.0 * self.c2) - ci * ej;
        (b, g_blk)
    }

    /// Adds 𝕃_e to `ll` and returns (∂S/∂E0 indexed `[I][J][K]`, ∂D0/∂E0).
    pub fn second_into(&self, k: &CKinematics, e0: &Vec3, ll: &mut Tensor4) -> (Tensor3, Mat3) {
        let ci = &k.c_inv;
        let g = ci * e0;
        let a = e0.dot(&g);
        let ej = self.eps * k.j;

        // 𝕃_IJKL = εJ [ a H_IJKL − ½ a Ci_IJ Ci_KL + Ci_KL g_I g_J + Ci_IJ g_K g_L
        //               − (Ci_IK g_J g_L + Ci_IL g_J g_K + Ci_JK g_I g_L + Ci_JL g_I g_K) ]
        // (identically zero for E0 = 0).
        if *e0 != Vec3::zeros() {
            for (i, lli) in ll.iter_mut().enumerate() {
                for (j, llij) in lli.iter_mut().enumerate() {
                    let cij = ci[(i, j)];
                    let gij = g[i] * g[j];
                    for (kk, llijk) in llij.iter_mut().enumerate() {
                        for (l, v) in llijk.iter_mut().enumerate() {
                            let ckl = ci[(kk, l)];
                            let h = 0.5 * (ci[(i, kk)] * ci[(j, l)] + ci[(i, l)] * ci[(j, kk)]);
                            let cross = ci[(i, kk)] * g[j] * g[l]
                                + ci[(i, l)] * g[j] * g[kk]
                                + ci[(j, kk)] * g[i] * g[l]
                                + ci[(j, l)] * g[i] * g[kk];
                            *v += ej
                                * (a * h - 0.5 * a * cij * ckl + ckl * gij + cij * g[kk] * g[l]
                                    - cross);
                        }
                    }
                }
            }
        }

        self.mixed_second(k, e0)
    }

    /// (∂S/∂E0 indexed `[I][J][K]`, ∂D0/∂E0): the second derivatives that involve E0, without
    /// 𝕃_e (what the rows of Gauss's law need).
    pub fn mixed_second(&self, k: &CKinematics, e0: &Vec3) -> (Tensor3, Mat3) {
        let ci = &k.c_inv;
        let g = ci * e0;
        let ej = self.eps * k.j;
        // ∂S_IJ/∂E0_K = 2c₂(δ_IK E_J + E_I δ_JK) + εJ(Ci_IK g_J + g_I Ci_JK − g_K Ci_IJ)
        let mut se: Tensor3 = [[[0.0; 3]; 3]; 3];
        for (i, sei) in se.iter_mut().enumerate() {
            for (j, seij) in sei.iter_mut().enumerate() {
                for (kk, v) in seij.iter_mut().enumerate() {
                    let mut w = ej * (ci[(i, kk)] * g[j] + g[i] * ci[(j, kk)] - g[kk] * ci[(i, j)]);
                    if i == kk {
                        w += 2.0 * self.c2 * e0[j];
                    }
                    if j == kk {
                        w += 2.0 * self.c2 * e0[i];
                    }
                    *v = w;
                }
            }
        }

        // ∂D0/∂E0 = −2c₁ I − 2c₂ C + εJ C⁻¹
        let dd = Mat3::identity() * (-2.0 * self.c1) - k.c * (2.0 * self.c2) + ci * ej;
        (se, dd)
    }
}
