//! Near-incompressibility: the **mean-dilatation F̄** (Q1–P0 Hu–Washizu) element kernel and the
//! formulation switch of the model.
//!
//! # Formulation
//!
//! The cell energy is
//!
//! ```text
//! Π_cell(u, Φ) = Σ_q w_q Ψ(F̄_q, E₀_q),   F̄_q = (θ̄/J_q)^{1/3} F_q,   θ̄ = v/V = (Σ_q w_q J_q)/(Σ_q w_q),
//! ```
//!
//! i.e. every quadrature point keeps its own isochoric deformation J^{-1/3}F but takes the cell's
//! volume ratio θ̄ (current over reference volume, exact for hex8 with 2×2×2 Gauss points since
//! det ∂x/∂ξ is quadratic in each coordinate). The electric field E₀ = −∇₀Φ keeps the standard
//! interpolation. Residual and tangent are the exact first and second derivatives of Π_cell
//! (the chain rule runs through θ̄, which depends on every nodal displacement of the cell), so the
//! tangent is **symmetric** and the global solver (a symmetric LDLᵀ) can be used as is.
//!
//! This is the mean-dilatation method of Nagtegaal, Parks & Rice (1974) in the finite-strain form
//! of Simo, Taylor & Pister (1985, CMAME 51, "Variational and projection methods for the volume
//! constraint in finite deformation elasto-plasticity"): the three-field Hu–Washizu functional
//! ∫ Ψ(θ^{1/3}J^{-1/3}F, E₀) + p (J − θ) dV with θ and p constant per cell (Q1–P0) gives, on
//! statically condensing p and θ, θ = v/V, and the p-term vanishes at that value, so the condensed
//! functional is exactly Π_cell above, for any energy Ψ(F, E₀) (no additive volumetric/isochoric
//! split of the material is needed). The F-bar element of de Souza Neto, Perić, Dutko & Owen (1996,
//! IJSS 33) would use F̄ = (J₀/J)^{1/3}F with J₀ at the cell centre in a virtual-work statement that
//! is not the variation of an energy; its tangent is unsymmetric, which our symmetric LDLᵀ solver
//! cannot factor — hence the energy-based mean-dilatation choice. (Textbook background: Bonet &
//! Wood, *Nonlinear Continuum Mechanics for Finite Element Analysis*, on the mean-dilatation
//! technique.)
//!
//! # Derivatives
//!
//! With ψ_q(F, θ̄, E) = Ψ(F̄, E), α = (θ̄/J)^{1/3}, f = F⁻ᵀ, P̄ = ∂Ψ/∂F̄ at F̄, s = P̄ : F̄, the map
//! δF ↦ δF̄ at fixed θ̄ is Q = α(𝕀 − ⅓ F ⊗ f), and
//!
//! ```text
//! ∂ψ/∂F      = αP̄ − (s/3) f                            ∂ψ/∂θ̄   = s/(3θ̄)
//! ∂²ψ/∂F²    = Qᵀ Ā Q − (α/3)(P̄⊗f + f⊗P̄) + (s/9) f⊗f + (s/3) f_kN f_mL
//! ∂²ψ/∂F∂θ̄  = [Qᵀ(Ā:F̄) + ∂ψ/∂F]/(3θ̄)                 ∂²ψ/∂θ̄² = (F̄:Ā:F̄ − 2s)/(9θ̄²)
//! ∂²ψ/∂F∂E   = Qᵀ B̄                                      ∂²ψ/∂θ̄∂E = B̄ᵀ:F̄/(3θ̄)
//! ```
//!
//! (Ā, B̄, Ḡ the material tangents at F̄). With ∂θ̄/∂F_q = (w_q/V) cof F_q and H = Σ_q w_q s_q/(3θ̄)
//! the effective first Piola stress at a point is P_q = αP̄ − (s/3)f + (H/V) cof F, whose Cauchy
//! stress is (θ̄/J) dev σ̄ + p̄ I with p̄ = H/V the cell's mean pressure. The cell tangent is the
//! per-point part (∂²ψ/∂F² + (H/V) ∂cof F/∂F) plus rank-one couplings between all points of the
//! cell through θ̄.
//!
//! For a one-point cell (tet4) θ̄ = J and the formulation coincides with the standard one.

use crate::element::axisymmetric::{
    add_point_potential_tangent_meridian, add_point_tangent_meridian, add_residual_meridian,
    delta_f,
};
use crate::element::md_lanes::LaneResidual;
use crate::element::md_point::{cbrt_near_one, cofactor, viscous_stress};
use crate::element::standard::{add_residual, split_local};
use crate::element::{CellFields, PointFailure};
use crate::element::{CellHistory, CellKernel, MeanDilatationKernel, StandardKernel};
use crate::fem::axisymmetric::meridian_kinematics;
use crate::fem::FIELDS;
use crate::fem::{kinematics, CellGeometry, MAX_NODES, MAX_QP};
use crate::material::{
    KnownDeformation, Mat3, Mat9, Mat93, Material, MaterialError, Tangent, Vec3,
};

type Vec9 = nalgebra::SVector<f64, 9>;

/// The element formulation of the displacement field.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Formulation {
    /// Pure displacement (standard Galerkin, full integration). Locks for κ ≫ μ.
    #[default]
    Standard,
    /// Mean-dilatation F̄ (Q1–P0 with the pressure and dilatation condensed per cell): for nearly
    /// incompressible materials.
    MeanDilatation,
}

impl Formulation {
    /// Name in scenario files and messages: `standard` or `mean-dilatation`.
    pub fn name(self) -> &'static str {
        match self {
            Formulation::Standard => "standard",
            Formulation::MeanDilatation => "mean-dilatation",
        }
    }

    /// Parses a name of [`Formulation::name`] (also accepts `q1p0` and `mean_dilatation`).
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "standard" | "displacement" => Some(Formulation::Standard),
            "mean-dilatation" | "mean_dilatation" | "q1p0" | "q1-p0" => {
                Some(Formulation::MeanDilatation)
            }
            _ => None,
        }
    }

    /// The names [`Formulation::from_name`] documents, for messages.
    pub const NAMES: [&'static str; 2] = ["standard", "mean-dilatation"];

    /// The cell kernel of this formulation for 3-D cells, or for meridian cells when
    /// `axisymmetric` (the mean-dilatation kernel serves both: its θ̄ includes the hoop stretch).
    pub fn kernel(self, axisymmetric: bool) -> &'static dyn CellKernel {
        match (self, axisymmetric) {
            (Formulation::Standard, false) => &StandardKernel,
            (Formulation::Standard, true) => &crate::element::AxisymmetricKernel,
            (Formulation::MeanDilatation, _) => &MeanDilatationKernel,
        }
    }
}

/// The F̄ and E₀ a material sees at each quadrature point of a mean-dilatation cell.
pub fn point_deformations_md(
    geom: &CellGeometry,
    local: &[f64],
    out: &mut [(Mat3, Vec3)],
) -> Result<(), PointFailure> {
    let mut k = MdKinematics::identity();
    k.compute(geom, local)?;
    for q in 0..geom.n_qp {
        out[q] = (k.fbar(q), k.e0[q]);
    }
    Ok(())
}

/// ∂(wᵀr)/∂P̄ at each quadrature point of a mean-dilatation cell at `local` (P̄ the stress the
/// material gives at F̄): with δF_q = F(w) − I and the effective stresses of
/// [`effective_stresses`], w_p [α_p δF_p − ⅓(F⁻ᵀ_p : δF_p) F̄_p + c F̄_p / (3θ̄V)], where
/// c = Σ_q w_q J_q F⁻ᵀ_q : δF_q.
pub fn stress_weights_md(
    geom: &CellGeometry,
    local: &[f64],
    w: &[f64],
    out: &mut [Mat3],
) -> Result<(), PointFailure> {
    let mut k = MdKinematics::identity();
    k.compute(geom, local)?;
    let n = geom.n_nodes;
    let (u, phi) = split_local(n, w);
    let mut df = [Mat3::zeros(); MAX_QP];
    let mut c = 0.0;
    for q in 0..geom.n_qp {
        let (f, _) = point_kinematics(geom, q, &u[..n], &phi[..n]);
        df[q] = f - Mat3::identity();
        c += geom.weights[q] * k.j[q] * k.finv_t[q].dot(&df[q]);
    }
    let mean = c / (3.0 * k.theta * k.volume);
    for q in 0..geom.n_qp {
        let fbar = k.fbar(q);
        let trace = k.finv_t[q].dot(&df[q]) / 3.0;
        out[q] = (df[q] * k.alpha[q] + fbar * (mean - trace)) * geom.weights[q];
    }
    Ok(())
}

/// The compatible F and E₀ at point q of a 3-D or meridian cell from its nodal values.
#[inline(always)]
fn point_kinematics(geom: &CellGeometry, q: usize, u: &[[f64; 3]], phi: &[f64]) -> (Mat3, Vec3) {
    let n = geom.n_nodes;
    if geom.axisymmetric {
        meridian_kinematics(&geom.grad[q][..n], &geom.hoop(q)[..n], u, phi)
    } else {
        kinematics(&geom.grad[q][..n], u, phi)
    }
}

/// Kinematics of a cell under the mean-dilatation formulation.
struct MdKinematics {
    f: [Mat3; MAX_QP],
    e0: [Vec3; MAX_QP],
    j: [f64; MAX_QP],
    /// F⁻ᵀ.
    finv_t: [Mat3; MAX_QP],
    /// (θ̄/J)^{1/3}.
    alpha: [f64; MAX_QP],
    theta: f64,
    /// θ̄^(−2/3), the J̄^(−2/3) of every point's F̄ (det F̄ = θ̄).
    theta_m23: f64,
    volume: f64,
}

fn fail(qp: usize) -> impl Fn(MaterialError) -> PointFailure {
    move |error| PointFailure { qp, error }
}

impl MdKinematics {
    /// The kinematics of the undeformed cell, to be filled by [`MdKinematics::compute`].
    #[inline(always)]
    fn identity() -> Self {
        MdKinematics {
            f: [Mat3::identity(); MAX_QP],
            e0: [Vec3::zeros(); MAX_QP],
            j: [1.0; MAX_QP],
            finv_t: [Mat3::identity(); MAX_QP],
            alpha: [1.0; MAX_QP],
            theta: 1.0,
            theta_m23: 1.0,
            volume: 0.0,
        }
    }

    /// The kinematics of the cell at its local values, written in place: the struct (about
    /// 2 kB) returned inside a `Result` was copied out of it in every cell of every pass.
    #[inline(always)]
    fn compute(&mut self, geom: &CellGeometry, local: &[f64]) -> Result<(), PointFailure> {
        let k = self;
        let n = geom.n_nodes;
        let (u, phi) = split_local(n, local);
        let mut v = 0.0;
        for q in 0..geom.n_qp {
            let (f, e0) = point_kinematics(geom, q, &u[..n], &phi[..n]);
            // F⁻ᵀ = cof F / J, J from the cofactors (one division instead of nine)
            let cof = cofactor(&f);
            let j = f[(0, 0)] * cof[(0, 0)] + f[(0, 1)] * cof[(0, 1)] + f[(0, 2)] * cof[(0, 2)];
            if !(j > 0.0 && j.is_finite()) {
                return Err(fail(q)(MaterialError::NonPositiveJ(j)));
            }
            k.f[q] = f;
            k.e0[q] = e0;
            k.j[q] = j;
            k.finv_t[q] = cof * (1.0 / j);
            v += geom.weights[q] * j;
            k.volume += geom.weights[q];
        }
        k.theta = v / k.volume;
        if !(k.theta > 0.0 && k.theta.is_finite()) {
            return Err(fail(0)(MaterialError::NonPositiveJ(k.theta)));
        }
        for q in 0..geom.n_qp {
            k.alpha[q] = cbrt_near_one(k.theta / k.j[q]);
        }
        let r = k.theta.cbrt();
        k.theta_m23 = 1.0 / (r * r);
        Ok(())
    }

    /// F̄ = (θ̄/J)^{1/3} F at point q.
    #[inline]
    fn fbar(&self, q: usize) -> Mat3 {
        self.f[q] * self.alpha[q]
    }

    /// F̄ at point q with what the material's fast paths need of it: F̄⁻ᵀ = F⁻ᵀ/α, det F̄ = θ̄
    /// and θ̄^(−2/3).
    #[inline]
    fn known(&self, q: usize) -> KnownDeformation {
        KnownDeformation {
            f: self.fbar(q),
            f_inv_t: self.finv_t[q] * (1.0 / self.alpha[q]),
            j: self.theta,
            jm23: self.theta_m23,
        }
    }
}

/// The effective 9 × 9 tangent of a mean-dilatation point in the compatible F: ∂²ψ/∂F² through
/// the projection Q = α(𝕀 − ⅓ F ⊗ f) (f = F⁻ᵀ), with Ā the material tangent at F̄, a_F = Ā:F,
/// `faf` = F:Ā:F, P̄ : ∂²F̄/∂F∂F (s = P̄:F̄), and `pj` = (H/V)J for (H/V) ∂cof F/∂F =
/// (H/V)J(f_mN f_kL − f_mL f_kN). The terms are gathered by the products of f they multiply,
/// so that an entry costs no division:
/// α²Ā − f⊗u − u⊗f + (α² F:Ā:F/9 + s/9 + pJ) f⊗f + (s/3 − pJ) f_kN f_mL, u = (α²/3)a_F + (α/3)P̄.
#[allow(clippy::too_many_arguments)]
fn effective_a(
    a: &Mat9,
    fi: &Vec9,
    a_f: &Vec9,
    pb9: &Vec9,
    faf: f64,
    alpha: f64,
    sq: f64,
    pj: f64,
) -> Mat9 {
    let a2 = alpha * alpha;
    let u9: Vec9 = a_f * (a2 / 3.0) + pb9 * (alpha / 3.0);
    let ff = (a2 * faf + sq) / 9.0 + pj;
    let swap = sq / 3.0 - pj;
    let mut a_eff: Mat9 = a * a2;
    for c9 in 0..9 {
        let (m, nn) = (c9 / 3, c9 % 3);
        for r9 in 0..9 {
            let (kk, ll) = (r9 / 3, r9 % 3);
            a_eff[(r9, c9)] += fi[r9] * (ff * fi[c9] - u9[c9]) - u9[r9] * fi[c9]
                + swap * fi[kk * 3 + nn] * fi[m * 3 + ll];
        }
    }
    a_eff
}

fn to9(m: &Mat3) -> Vec9 {
    Vec9::from_fn(|r, _| m[(r / 3, r % 3)])
}

/// Energy Σ w Ψ(F̄, E₀) of the cell (J).
pub fn cell_energy_md(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
) -> Result<f64, PointFailure> {
    let mut k = MdKinematics::identity();
    k.compute(geom, local)?;
    let mut e = 0.0;
    for q in 0..geom.n_qp {
        e += geom.weights[q]
            * mat
                .energy_at(&k.fbar(q), &k.e0[q], hist.at(q))
                .map_err(fail(q))?;
    }
    Ok(e)
}

/// `(mechanical, electric)` parts of the mean-dilatation cell energy (J), as the material splits
/// Ψ(F̄, E₀).
pub fn cell_energy_split_md(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
) -> Result<(f64, f64), PointFailure> {
    let mut k = MdKinematics::identity();
    k.compute(geom, local)?;
    energy_split_md(geom, mat, hist, &k)
}

/// [`cell_energy_split_md`] at given kinematics.
fn energy_split_md(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    k: &MdKinematics,
) -> Result<(f64, f64), PointFailure> {
    let (mut m, mut el) = (0.0, 0.0);
    for q in 0..geom.n_qp {
        let (a, b) = mat
            .energy_split_at(&k.fbar(q), &k.e0[q], hist.at(q).state)
            .map_err(fail(q))?;
        m += geom.weights[q] * a;
        el += geom.weights[q] * b;
    }
    Ok((m, el))
}

/// Effective first Piola stresses P_q = αP̄ − (s/3)F⁻ᵀ + p̄ cof F (Pa) into `p`, the referential
/// electric displacements D₀(F̄, E₀) into `d0`; returns the energy of the cell. The outputs are
/// the caller's buffers: returning them would copy about 1 kB per cell.
fn md_stresses(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    k: &MdKinematics,
    p: &mut [Mat3; MAX_QP],
    d0: &mut [Vec3; MAX_QP],
) -> Result<f64, PointFailure> {
    let mut s = [0.0; MAX_QP];
    let mut energy = 0.0;
    for q in 0..geom.n_qp {
        let kd = k.known(q);
        let st = mat
            .stress_known(&kd, &k.e0[q], hist.at(q))
            .map_err(fail(q))?;
        energy += geom.weights[q] * st.energy;
        s[q] = st.p.dot(&kd.f);
        p[q] = st.p;
        d0[q] = st.d0;
    }
    effective_stresses(geom, k, &s, p);
    Ok(energy)
}

/// Turns the stresses P̄ at F̄ in `p` into the effective stresses αP̄ − (s/3)F⁻ᵀ + p̄ cof F, given
/// s = P̄ : F̄ of every point (p̄ = Σ w s / (3θ̄V), the cell's mean pressure).
#[inline]
fn effective_stresses(
    geom: &CellGeometry,
    k: &MdKinematics,
    s: &[f64; MAX_QP],
    p: &mut [Mat3; MAX_QP],
) {
    let mut h = 0.0;
    for q in 0..geom.n_qp {
        h += geom.weights[q] * s[q] / (3.0 * k.theta);
    }
    let pm = h / k.volume;
    for q in 0..geom.n_qp {
        p[q] = p[q] * k.alpha[q] + k.finv_t[q] * (pm * k.j[q] - s[q] / 3.0);
    }
}

/// What the record and the output fields need of a cell, from one material evaluation per
/// point: the effective stresses of the state into `p` and of the same kinematics at zero field
/// into `p_mech`, the electric displacements into `d0`; returns the energy split.
fn md_record_points(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    k: &MdKinematics,
    p: &mut [Mat3; MAX_QP],
    p_mech: &mut [Mat3; MAX_QP],
    d0: &mut [Vec3; MAX_QP],
) -> Result<(f64, f64), PointFailure> {
    let (mut s, mut s_mech) = ([0.0; MAX_QP], [0.0; MAX_QP]);
    let (mut m, mut el) = (0.0, 0.0);
    for q in 0..geom.n_qp {
        let kd = k.known(q);
        let rec = mat
            .record_known(&kd, &k.e0[q], hist.at(q))
            .map_err(fail(q))?;
        m += geom.weights[q] * rec.split.0;
        el += geom.weights[q] * rec.split.1;
        s[q] = rec.stress.p.dot(&kd.f);
        s_mech[q] = rec.p_mech.dot(&kd.f);
        p[q] = rec.stress.p;
        p_mech[q] = rec.p_mech;
        d0[q] = rec.stress.d0;
    }
    effective_stresses(geom, k, &s, p);
    effective_stresses(geom, k, &s_mech, p_mech);
    Ok((m, el))
}

/// The residual of point q of a 3-D or meridian cell.
fn add_residual_any(geom: &CellGeometry, q: usize, p: &Mat3, d0: &Vec3, r: &mut [f64]) {
    let w = geom.weights[q];
    if geom.axisymmetric {
        add_residual_meridian(geom, q, w, p, d0, r);
    } else {
        add_residual(&geom.grad[q], geom.n_nodes, w, p, d0, r);
    }
}

/// The residual of the cell at given kinematics into `r` (zeroed first), its effective
/// stresses into `p`; returns the energy.
fn md_residual(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    kin: &MdKinematics,
    r: &mut [f64],
    p: &mut [Mat3; MAX_QP],
) -> Result<f64, PointFailure> {
    r[..geom.n_nodes * FIELDS].iter_mut().for_each(|v| *v = 0.0);
    let mut d0 = [Vec3::zeros(); MAX_QP];
    let energy = md_stresses(geom, mat, hist, kin, p, &mut d0)?;
    for q in 0..geom.n_qp {
        add_residual_any(geom, q, &p[q], &d0[q], r);
    }
    Ok(energy)
}

/// Local residual (and tangent when `k` is given) of the mean-dilatation cell; same contract as
/// [`crate::element::cell_residual_tangent`] (node-major dofs ux, uy, uz, Φ; `r` has `4·n_nodes`
/// entries, `k` is row-major with leading dimension `4·n_nodes`). Returns the cell energy (J).
/// The tangent is the exact Hessian of the cell energy, hence symmetric.
pub fn cell_residual_tangent_md(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
    r: &mut [f64],
    k: Option<&mut [f64]>,
) -> Result<f64, PointFailure> {
    cell_residual_viscous_tangent_md(geom, mat, hist, local, None, r, k)
}

/// [`cell_residual_tangent_md`] whose tangent also holds the Kelvin–Voigt derivatives of
/// `viscous` (3-D cells: the viscous forces see the compatible F, so
/// [`crate::element::viscous_point_block`] at each point's F is added to its effective A); the
/// residual is the elastic one.
pub fn cell_residual_viscous_tangent_md(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
    viscous: Option<&crate::element::ViscousTangent>,
    r: &mut [f64],
    k: Option<&mut [f64]>,
) -> Result<f64, PointFailure> {
    debug_assert!(viscous.is_none() || !geom.axisymmetric);
    let n = geom.n_nodes;
    let nl = n * FIELDS;
    let nq = geom.n_qp;
    if k.is_none() && !geom.axisymmetric {
        let lanes = LaneResidual {
            geom,
            mat,
            hist,
            local,
            viscous: None,
            f_r: 1.0,
            r: &mut *r,
        };
        if let Some(out) = lanes.evaluate() {
            return out.map(|(energy, _)| energy);
        }
    }
    let mut kin = MdKinematics::identity();
    kin.compute(geom, local)?;
    let Some(k) = k else {
        return md_residual(geom, mat, hist, &kin, r, &mut [Mat3::zeros(); MAX_QP]);
    };
    r[..nl].iter_mut().for_each(|v| *v = 0.0);
    k[..nl * nl].iter_mut().for_each(|v| *v = 0.0);
    let theta = kin.theta;
    let vol = kin.volume;

    // pass 1: material tangents at F̄ and the cell's θ̄-derivative H = Σ w s/(3θ̄)
    // on the stack: no allocation per cell
    let mut tans: [Option<Tangent>; MAX_QP] = Default::default();
    let mut s = [0.0; MAX_QP];
    let mut energy = 0.0;
    let mut h = 0.0;
    for q in 0..nq {
        let fbar = kin.fbar(q);
        let t = mat
            .tangent_at(&fbar, &kin.e0[q], hist.at(q))
            .map_err(fail(q))?;
        energy += geom.weights[q] * t.energy;
        s[q] = t.p.dot(&fbar);
        h += geom.weights[q] * s[q] / (3.0 * theta);
        tans[q] = Some(t);
    }
    let pm = h / vol;

    // rank-one couplings through θ̄: M = ∂θ̄/∂u, Bv = Σ w ∂²ψ/∂F∂θ̄ : ∇N, Ev = ∂H/∂Φ, D = ∂H/∂θ̄
    let mut mv = [[0.0; 3]; MAX_NODES];
    let mut bv = [[0.0; 3]; MAX_NODES];
    let mut ev = [0.0; MAX_NODES];
    let mut dd = 0.0;

    for (q, t) in tans[..nq].iter().enumerate() {
        let t = t.as_ref().expect("set in pass 1");
        let g = &geom.grad[q];
        let w = geom.weights[q];
        let (alpha, j) = (kin.alpha[q], kin.j[q]);
        let fi = to9(&kin.finv_t[q]);
        let f9 = to9(&kin.f[q]);
        let pb9 = to9(&t.p);
        let cof9 = fi * j;
        let sq = s[q];

        // With Q = α(𝕀 − ⅓ F ⊗ f) and Ā symmetric, a_F = Ā:F, F:Ā:F:
        //   QᵀĀQ = α²(Ā − ⅓ f⊗a_F − ⅓ a_F⊗f + (F:Ā:F)/9 f⊗f),  Qᵀ(Ā:F̄) = α²(a_F − ⅓(F:Ā:F) f)
        let a_f: Vec9 = t.a * f9;
        let faf = f9.dot(&a_f);
        let a2 = alpha * alpha;
        let psi_f: Vec9 = pb9 * alpha - fi * (sq / 3.0);
        let mut a_eff = effective_a(&t.a, &fi, &a_f, &pb9, faf, alpha, sq, pm * j);
        if let Some(v) = viscous {
            a_eff += crate::element::viscous_point_block(&kin.finv_t[q], j, g, n, v);
        }
        // QᵀB̄ = α(B̄ − ⅓ f ⊗ (F:B̄)),  B̄ᵀ:F̄ = α F:B̄
        let f_b: Vec3 = t.b.transpose() * f9;
        let b_eff: Mat93 = (t.b - fi * f_b.transpose() / 3.0) * alpha;
        let bq: Vec9 = ((a_f - fi * (faf / 3.0)) * a2 + psi_f) / (3.0 * theta);
        dd += w * (a2 * faf - 2.0 * sq) / (9.0 * theta * theta);
        let eq: Vec3 = f_b * (alpha / (3.0 * theta));

        // residual with the effective stress
        let p_eff = t.p * alpha + kin.finv_t[q] * (pm * j - sq / 3.0);
        add_residual_any(geom, q, &p_eff, &t.d0, r);

        for a in 0..n {
            for i in 0..3 {
                let mut m_ai = 0.0;
                let mut b_ai = 0.0;
                for (m, v) in delta_f(geom, q, a, i) {
                    m_ai += cof9[m] * v;
                    b_ai += bq[m] * v;
                }
                mv[a][i] += w / vol * m_ai;
                bv[a][i] += w * b_ai;
            }
            ev[a] -= w * (eq[0] * g[a][0] + eq[1] * g[a][1] + eq[2] * g[a][2]);
        }

        // per-point blocks, as in the standard kernel
        if geom.axisymmetric {
            add_point_tangent_meridian(geom, q, w, &a_eff, &b_eff, &t.g, k);
        } else {
            crate::element::add_point_tangent(g, n, w, &a_eff, &b_eff, &t.g, k);
        }
    }

    // couplings of all points through θ̄
    for a in 0..n {
        for b in 0..n {
            for i in 0..3 {
                let row = (a * 4 + i) * nl + b * 4;
                for kk in 0..3 {
                    k[row + kk] +=
                        bv[a][i] * mv[b][kk] + mv[a][i] * bv[b][kk] + dd * mv[a][i] * mv[b][kk];
                }
                k[row + 3] += mv[a][i] * ev[b];
            }
            let row = (a * 4 + 3) * nl + b * 4;
            for kk in 0..3 {
                k[row + kk] += ev[a] * mv[b][kk];
            }
        }
    }
    Ok(energy)
}

/// [`CellKernel::dynamic_residual`] of a 3-D mean-dilatation cell: the elastic residual and the
/// Kelvin–Voigt forces from one evaluation of the kinematics. The viscous forces see the
/// compatible F, as [`crate::element::cell_viscous`] does: their stress Jη d F⁻ᵀ, with
/// d = sym(Ḟ F⁻¹) and Ḟ = Σ v_a ⊗ ∇₀N_a, is added to each point's effective stress, so that one
/// pass over the nodes gives both forces (equal to the separate calls up to round-off).
pub fn cell_dynamic_residual_md(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
    viscous: Option<(crate::element::KelvinVoigtKernel, &[f64])>,
    f_r: f64,
    r: &mut [f64],
) -> Result<(f64, f64), PointFailure> {
    debug_assert!(!geom.axisymmetric);
    let lanes = LaneResidual {
        geom,
        mat,
        hist,
        local,
        viscous,
        f_r,
        r: &mut *r,
    };
    if let Some(out) = lanes.evaluate() {
        return out;
    }
    dynamic_residual_points(geom, mat, hist, local, viscous, f_r, r)
}

/// [`cell_dynamic_residual_md`] point by point: the path of a cell whose lanes fail, which
/// then reports the failure, and the reference of the lanes' tests.
pub(crate) fn dynamic_residual_points(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
    viscous: Option<(crate::element::KelvinVoigtKernel, &[f64])>,
    f_r: f64,
    r: &mut [f64],
) -> Result<(f64, f64), PointFailure> {
    let n = geom.n_nodes;
    let mut kin = MdKinematics::identity();
    kin.compute(geom, local)?;
    let mut p = [Mat3::zeros(); MAX_QP];
    let mut d0 = [Vec3::zeros(); MAX_QP];
    let energy = md_stresses(geom, mat, hist, &kin, &mut p, &mut d0)?;
    let mut power = 0.0;
    if let Some((kv, vel)) = viscous {
        let (v, _) = split_local(n, vel);
        for q in 0..geom.n_qp {
            let g = &geom.grad[q];
            let mut fd = [[0.0; 3]; 3];
            for (va, ga) in v[..n].iter().zip(&g[..n]) {
                for i in 0..3 {
                    for m in 0..3 {
                        fd[i][m] += va[i] * ga[m];
                    }
                }
            }
            let (pv, dd) = viscous_stress(&fd, &kin.finv_t[q], kin.j[q] * kv.eta);
            power += geom.weights[q] * dd;
            p[q] += pv;
        }
    }
    r[..n * FIELDS].iter_mut().for_each(|v| *v = 0.0);
    for q in 0..geom.n_qp {
        add_residual(&geom.grad[q], n, f_r * geom.weights[q], &p[q], &d0[q], r);
    }
    Ok((energy, power))
}

/// Output fields of a mean-dilatation cell: the Cauchy stress is that of the effective stress,
/// P_q Fᵀ/J = (θ̄/J) dev σ̄ + p̄ I, averaged over the cell; e = F⁻ᵀE₀ with the compatible F.
pub fn cell_fields_md(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
) -> Result<CellFields, PointFailure> {
    let mut k = MdKinematics::identity();
    k.compute(geom, local)?;
    let (mut p, mut p_mech) = ([Mat3::zeros(); MAX_QP], [Mat3::zeros(); MAX_QP]);
    let mut d0 = [Vec3::zeros(); MAX_QP];
    md_record_points(geom, mat, hist, &k, &mut p, &mut p_mech, &mut d0)?;
    Ok(fields_md(geom, &k, &p, &p_mech))
}

/// [`CellKernel::potential_residual`] of a mean-dilatation cell: D₀(F̄, E₀) only.
pub fn cell_potential_residual_md(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
    r: &mut [f64],
) -> Result<(), PointFailure> {
    let mut k = MdKinematics::identity();
    k.compute(geom, local)?;
    r[..geom.n_nodes * FIELDS].iter_mut().for_each(|v| *v = 0.0);
    let no_stress = Mat3::zeros();
    for q in 0..geom.n_qp {
        let d0 = mat
            .electric_displacement_known(&k.known(q), &k.e0[q], hist.at(q))
            .map_err(fail(q))?;
        add_residual_any(geom, q, &no_stress, &d0, r);
    }
    Ok(())
}

/// [`CellKernel::potential_residual_tangent`] of a mean-dilatation cell (3-D or meridian):
/// D₀(F̄, E₀) and its derivatives per point, with the coupling of every point through θ̄ (the
/// Φ rows of [`cell_residual_tangent_md`]; no stress, no derivative in F̄ twice).
pub fn cell_potential_tangent_md(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
    r: &mut [f64],
    k: &mut [f64],
) -> Result<(), PointFailure> {
    let n = geom.n_nodes;
    let nl = n * FIELDS;
    let mut kin = MdKinematics::identity();
    kin.compute(geom, local)?;
    r[..nl].iter_mut().for_each(|v| *v = 0.0);
    k[..nl * nl].iter_mut().for_each(|v| *v = 0.0);
    let (theta, vol) = (kin.theta, kin.volume);
    // M = ∂θ̄/∂u and Ev = ∂H/∂Φ, as in the full tangent
    let mut mv = [[0.0; 3]; MAX_NODES];
    let mut ev = [0.0; MAX_NODES];
    let no_stress = Mat3::zeros();
    for q in 0..geom.n_qp {
        let fbar = kin.fbar(q);
        let t = mat
            .electric_tangent_at(&fbar, &kin.e0[q], hist.at(q))
            .map_err(fail(q))?;
        let g = &geom.grad[q];
        let w = geom.weights[q];
        let alpha = kin.alpha[q];
        let fi = to9(&kin.finv_t[q]);
        let cof9 = fi * kin.j[q];
        let f_b: Vec3 = t.b.transpose() * to9(&kin.f[q]);
        let b_eff: Mat93 = (t.b - fi * f_b.transpose() / 3.0) * alpha;
        let eq: Vec3 = f_b * (alpha / (3.0 * theta));
        add_residual_any(geom, q, &no_stress, &t.d0, r);
        for a in 0..n {
            for (i, m_a) in mv[a].iter_mut().enumerate() {
                let m_ai: f64 = delta_f(geom, q, a, i)
                    .iter()
                    .map(|&(m, v)| cof9[m] * v)
                    .sum();
                *m_a += w / vol * m_ai;
            }
            ev[a] -= w * (eq[0] * g[a][0] + eq[1] * g[a][1] + eq[2] * g[a][2]);
        }
        if geom.axisymmetric {
            add_point_potential_tangent_meridian(geom, q, w, &b_eff, &t.g, k);
        } else {
            crate::element::standard::add_point_potential_tangent(g, n, w, &b_eff, &t.g, k);
        }
    }
    for a in 0..n {
        let row = (a * 4 + 3) * nl;
        for b in 0..n {
            for kk in 0..3 {
                k[row + b * 4 + kk] += ev[a] * mv[b][kk];
            }
        }
    }
    Ok(())
}

/// [`CellKernel::record`] of a mean-dilatation cell: the kinematics and one material evaluation
/// per point for the residual, the energy split and the fields.
pub fn cell_record_md(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
    r: &mut [f64],
) -> Result<((f64, f64), CellFields), PointFailure> {
    let mut k = MdKinematics::identity();
    k.compute(geom, local)?;
    let (mut p, mut p_mech) = ([Mat3::zeros(); MAX_QP], [Mat3::zeros(); MAX_QP]);
    let mut d0 = [Vec3::zeros(); MAX_QP];
    let split = md_record_points(geom, mat, hist, &k, &mut p, &mut p_mech, &mut d0)?;
    r[..geom.n_nodes * FIELDS].iter_mut().for_each(|v| *v = 0.0);
    for q in 0..geom.n_qp {
        add_residual_any(geom, q, &p[q], &d0[q], r);
    }
    Ok((split, fields_md(geom, &k, &p, &p_mech)))
}

/// The output fields of a cell from the effective stresses of the state (`p`) and at zero field
/// (`p_mech`): the Cauchy stresses P Fᵀ/J and the true field e = F⁻ᵀE₀ averaged over the cell.
fn fields_md(
    geom: &CellGeometry,
    k: &MdKinematics,
    p: &[Mat3; MAX_QP],
    p_mech: &[Mat3; MAX_QP],
) -> CellFields {
    let mut out = CellFields::zero();
    for q in 0..geom.n_qp {
        let sigma = p[q] * k.f[q].transpose() / k.j[q];
        let sigma_mech = p_mech[q] * k.f[q].transpose() / k.j[q];
        let e = k.finv_t[q] * k.e0[q];
        out.add_point(geom.weights[q] / k.volume, &e, &sigma, &sigma_mech, k.j[q]);
    }
    out
}

/// The second derivatives of a mean-dilatation cell's energy as bilinear forms in the point
/// variations (δF_q, δE₀_q): per point q the weighted blocks (w_q, A_q, B_q, G_q) of
/// ∂²ψ/∂F² + (H/V) ∂cof F/∂F, QᵀB̄ and Ḡ (the per-point part of
/// [`cell_residual_tangent_md`]), and the couplings through θ̄ as linear forms:
/// δθ̄ = Σ_q m_q : δF_q, b = Σ_q w_q b_q : δF_q, e = Σ_q w_q e_q · δE₀_q, with the Hessian part
/// b ⊗ δθ̄ + δθ̄ ⊗ b + d δθ̄ ⊗ δθ̄ + δθ̄ ⊗ e + e ⊗ δθ̄. The same numbers as the tangent, for a
/// kinematics other than the cell's own (the circumferential harmonics of a meridian cell).
pub(crate) struct MdHessian {
    pub points: Vec<(f64, Mat9, Mat93, Mat3)>,
    /// m_q (cof F_q w_q / V), b_q, e_q per point.
    pub m: Vec<[f64; 9]>,
    pub b: Vec<[f64; 9]>,
    pub e: Vec<[f64; 3]>,
    pub d: f64,
}

/// [`MdHessian`] of a cell at `local`.
pub(crate) fn md_hessian(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
) -> Result<MdHessian, PointFailure> {
    let nq = geom.n_qp;
    let mut kin = MdKinematics::identity();
    kin.compute(geom, local)?;
    let theta = kin.theta;
    let vol = kin.volume;
    let mut tans = Vec::with_capacity(nq);
    let mut s = [0.0; MAX_QP];
    let mut h = 0.0;
    for q in 0..nq {
        let fbar = kin.fbar(q);
        let t = mat
            .tangent_at(&fbar, &kin.e0[q], hist.at(q))
            .map_err(fail(q))?;
        s[q] = t.p.dot(&fbar);
        h += geom.weights[q] * s[q] / (3.0 * theta);
        tans.push(t);
    }
    let pm = h / vol;
    let mut out = MdHessian {
        points: Vec::with_capacity(nq),
        m: Vec::with_capacity(nq),
        b: Vec::with_capacity(nq),
        e: Vec::with_capacity(nq),
        d: 0.0,
    };
    for (q, t) in tans.iter().enumerate() {
        let w = geom.weights[q];
        let (alpha, j) = (kin.alpha[q], kin.j[q]);
        let fi = to9(&kin.finv_t[q]);
        let f9 = to9(&kin.f[q]);
        let pb9 = to9(&t.p);
        let cof9 = fi * j;
        let sq = s[q];
        let a_f: Vec9 = t.a * f9;
        let faf = f9.dot(&a_f);
        let a2 = alpha * alpha;
        let psi_f: Vec9 = pb9 * alpha - fi * (sq / 3.0);
        let a_eff = effective_a(&t.a, &fi, &a_f, &pb9, faf, alpha, sq, pm * j);
        let f_b: Vec3 = t.b.transpose() * f9;
        let b_eff: Mat93 = (t.b - fi * f_b.transpose() / 3.0) * alpha;
        let bq: Vec9 = ((a_f - fi * (faf / 3.0)) * a2 + psi_f) / (3.0 * theta);
        out.d += w * (a2 * faf - 2.0 * sq) / (9.0 * theta * theta);
        let eq: Vec3 = f_b * (alpha / (3.0 * theta));
        out.points.push((w, a_eff, b_eff, t.g));
        out.m.push(std::array::from_fn(|i| cof9[i] * w / vol));
        out.b.push(std::array::from_fn(|i| bq[i]));
        out.e.push([eq[0], eq[1], eq[2]]);
    }
    Ok(out)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::fem::ReferenceElement;
    use crate::material::{ElectroNeoHooke, Electroelastic, NeoHookeSplit, EPSILON_0};
    use crate::mesh::ElementKind;

    /// Nodes of a distorted hex8 about 1 mm in size (m).
    pub(crate) fn cell_coords() -> [[f64; 3]; 8] {
        [
            [0.0, 0.0, 0.0],
            [1.2, 0.1, 0.0],
            [1.3, 0.9, 0.1],
            [-0.1, 1.0, 0.0],
            [0.1, 0.0, 1.0],
            [1.0, 0.2, 1.1],
            [1.1, 1.2, 0.9],
            [0.0, 1.1, 1.2],
        ]
        .map(|p| p.map(|c| c * 1e-3))
    }

    /// The hex8 of [`cell_coords`] and a random-looking state with displacement gradients of
    /// order 0.1 and a field of order 0.3√(μ/ε).
    fn cell() -> (CellGeometry, Vec<f64>) {
        let h = 1e-3;
        let x = cell_coords();
        let g = ReferenceElement::new(ElementKind::Hex8)
            .geometry(&x)
            .unwrap();
        let e_scale = (1e5f64 / (4.7 * EPSILON_0)).sqrt();
        let mut local = vec![0.0; 32];
        for (i, v) in local.iter_mut().enumerate() {
            let r = ((i as f64 * 12.9898).sin() * 43758.5453).fract();
            *v = if i % 4 == 3 {
                0.3 * e_scale * h * r
            } else {
                0.1 * h * r
            };
        }
        (g, local)
    }

    fn materials() -> Vec<Box<dyn Material>> {
        let eps = 4.7 * EPSILON_0;
        vec![
            Box::new(ElectroNeoHooke::new(1e5, 4e5, 4.7).with_coupling(0.3 * eps, 0.2 * eps)),
            Box::new(Electroelastic::ideal(
                NeoHookeSplit {
                    mu: 1e5,
                    kappa: 5e7,
                },
                4.7,
            )),
        ]
    }

    /// The residual is the gradient of the energy and the tangent the derivative of the residual
    /// (central differences, step 1e-7 of the cell size; tolerance 1e-6 of the largest entry),
    /// for every material, on the cell `g` at the state `local` (4 values per node).
    fn check_consistency(g: &CellGeometry, local: &[f64]) {
        let nl = g.n_nodes * 4;
        for mat in materials() {
            let mat = mat.as_ref();
            let mut r = vec![0.0; nl];
            let mut k = vec![0.0; nl * nl];
            let e =
                cell_residual_tangent_md(g, mat, CellHistory::NONE, local, &mut r, Some(&mut k))
                    .unwrap();
            let mut r2 = vec![0.0; nl];
            let e2 =
                cell_residual_tangent_md(g, mat, CellHistory::NONE, local, &mut r2, None).unwrap();
            // the residual alone takes the materials' fast paths: equal up to round-off
            assert!((e - e2).abs() <= 1e-14 * e.abs());
            assert!(
                (cell_energy_md(g, mat, CellHistory::NONE, local).unwrap() - e).abs()
                    <= 1e-14 * e.abs()
            );
            for i in 0..nl {
                assert!(
                    (r[i] - r2[i]).abs() <= 1e-12 * r.iter().fold(0.0f64, |m, v| m.max(v.abs()))
                );
            }
            // compare in the solver's scaled unknowns (Φ/√(μ/ε) is a length, s·r_Φ a force)
            let e_scale = (1e5f64 / (4.7 * EPSILON_0)).sqrt();
            let sc = |i: usize| if i % 4 == 3 { e_scale } else { 1.0 };
            let rmax = (0..nl).fold(0.0f64, |m, i| m.max((r[i] * sc(i)).abs()));
            let kmax =
                (0..nl * nl).fold(0.0f64, |m, p| m.max((k[p] * sc(p / nl) * sc(p % nl)).abs()));
            let (mut worst_r, mut worst_k) = (0.0f64, 0.0f64);
            for j in 0..nl {
                let h = 1e-10 * sc(j);
                let mut lp = local.to_vec();
                let mut lm = local.to_vec();
                lp[j] += h;
                lm[j] -= h;
                let (mut rp, mut rm) = (vec![0.0; nl], vec![0.0; nl]);
                let ep = cell_residual_tangent_md(g, mat, CellHistory::NONE, &lp, &mut rp, None)
                    .unwrap();
                let em = cell_residual_tangent_md(g, mat, CellHistory::NONE, &lm, &mut rm, None)
                    .unwrap();
                worst_r = worst_r.max(((ep - em) / (2.0 * h) - r[j]).abs() * sc(j) / rmax);
                for i in 0..nl {
                    let fd = (rp[i] - rm[i]) / (2.0 * h);
                    worst_k = worst_k.max((fd - k[i * nl + j]).abs() * sc(i) * sc(j) / kmax);
                }
            }
            eprintln!("{mat:?}: residual {worst_r:.2e}, tangent {worst_k:.2e}");
            assert!(worst_r < 1e-6, "residual vs energy: {worst_r:e}");
            assert!(worst_k < 1e-6, "tangent vs residual: {worst_k:e}");
            for i in 0..nl {
                for j in 0..nl {
                    assert!((k[i * nl + j] - k[j * nl + i]).abs() <= 1e-12 * kmax);
                }
            }
        }
    }

    /// The potential's rows of a cell alone ([`CellKernel::potential_residual_tangent`]) are
    /// those of the whole cell's residual and tangent, and its displacement rows zero: the
    /// mean-dilatation and standard hex8 and a meridian quad4 (which takes the whole cell's),
    /// for a material with its electric part apart (the ideal dielectric with electrostriction)
    /// and one without (the compressible neo-Hooke, the default from the whole tangent).
    #[test]
    fn potential_rows_alone_are_the_whole_cells() {
        use crate::fem::axisymmetric::{meridian_geometry, MeridianKind};
        let eps = 4.7 * EPSILON_0;
        let mats: Vec<Box<dyn Material>> = vec![
            Box::new(ElectroNeoHooke::new(1e5, 4e5, 4.7).with_coupling(0.3 * eps, 0.2 * eps)),
            Box::new(Electroelastic::new(
                NeoHookeSplit {
                    mu: 1e5,
                    kappa: 5e7,
                },
                crate::material::ElectricPart::ideal(4.7).with_coupling(0.3 * eps, 0.2 * eps),
            )),
        ];
        let (hex, local) = cell();
        let x: Vec<[f64; 2]> = MeridianKind::Quad4
            .reference_nodes()
            .iter()
            .map(|p| [0.4e-3 + 0.5e-3 * (p[0] + 1.0), 0.5e-3 * (p[1] + 1.1)])
            .collect();
        let quad = meridian_geometry(MeridianKind::Quad4, &x).unwrap();
        let kernels: [(&dyn CellKernel, &CellGeometry); 3] = [
            (&MeanDilatationKernel, &hex),
            (&StandardKernel, &hex),
            (&MeanDilatationKernel, &quad),
        ];
        for (kernel, g) in kernels {
            let nl = g.n_nodes * FIELDS;
            for mat in &mats {
                let c = crate::element::CellInput {
                    geom: g,
                    mat: mat.as_ref(),
                    hist: CellHistory::NONE,
                    local: &local[..nl],
                };
                let (mut r, mut k) = (vec![0.0; nl], vec![0.0; nl * nl]);
                kernel.residual_tangent(&c, &mut r, Some(&mut k)).unwrap();
                let (mut rp, mut kp) = (vec![1.0; nl], vec![1.0; nl * nl]);
                kernel
                    .potential_residual_tangent(&c, &mut rp, &mut kp)
                    .unwrap();
                // in the solver's scaled unknowns, as above
                let e_scale = (1e5f64 / eps).sqrt();
                let sc = |i: usize| if i % 4 == 3 { e_scale } else { 1.0 };
                let rmax = (0..nl).fold(0.0f64, |m, i| m.max((r[i] * sc(i)).abs()));
                let kmax = (0..nl * nl)
                    .filter(|p| (p / nl) % 4 == 3)
                    .fold(0.0f64, |m, p| m.max((k[p] * sc(p / nl) * sc(p % nl)).abs()));
                assert!(rmax > 0.0 && kmax > 0.0);
                for i in 0..nl {
                    if i % 4 != 3 {
                        assert_eq!(rp[i], 0.0);
                        assert!(kp[i * nl..(i + 1) * nl].iter().all(|v| *v == 0.0));
                        continue;
                    }
                    assert!(
                        (rp[i] - r[i]).abs() * sc(i) <= 1e-13 * rmax,
                        "{mat:?} r[{i}]"
                    );
                    for j in 0..nl {
                        let p = i * nl + j;
                        assert!(
                            (kp[p] - k[p]).abs() * sc(i) * sc(j) <= 1e-13 * kmax,
                            "{mat:?} k[{i}][{j}]: {} against {}",
                            kp[p],
                            k[p]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn residual_and_tangent_are_consistent() {
        let (g, local) = cell();
        check_consistency(&g, &local);
    }

    /// The same on meridian cells (quad4 and quad9 touching the axis and off it), whose θ̄ and
    /// forces carry the hoop stretch; the held third slot has no residual.
    #[test]
    fn meridian_residual_and_tangent_are_consistent() {
        use crate::fem::axisymmetric::{meridian_geometry, MeridianKind};
        for kind in [MeridianKind::Quad4, MeridianKind::Quad9] {
            for r0 in [0.0, 0.8e-3] {
                let x: Vec<[f64; 2]> = kind
                    .reference_nodes()
                    .iter()
                    .map(|p| {
                        let (s, t) = (0.5 * (p[0] + 1.0), 0.5 * (p[1] + 1.0));
                        [r0 + 1e-3 * s * (1.0 + 0.1 * t), 1e-3 * (t + 0.05 * s)]
                    })
                    .collect();
                let g = meridian_geometry(kind, &x).unwrap();
                let e_scale = (1e5f64 / (4.7 * EPSILON_0)).sqrt();
                let mut local = vec![0.0; 4 * x.len()];
                for (i, v) in local.iter_mut().enumerate() {
                    let r = ((i as f64 * 12.9898).sin() * 43758.5453).fract();
                    *v = match i % 4 {
                        3 => 0.3 * e_scale * 1e-3 * r,
                        2 => 0.0,
                        // u_r = 0 on the axis
                        0 if x[i / 4][0] == 0.0 => 0.0,
                        _ => 0.1 * 1e-3 * r,
                    };
                }
                check_consistency(&g, &local);
                let mut r = vec![0.0; local.len()];
                cell_residual_tangent_md(
                    &g,
                    materials()[0].as_ref(),
                    CellHistory::NONE,
                    &local,
                    &mut r,
                    None,
                )
                .unwrap();
                assert!(r.iter().skip(2).step_by(4).all(|&v| v == 0.0));
            }
        }
    }

    /// A homogeneous deformation gives the standard element's residual, tangent and fields.
    #[test]
    fn homogeneous_state_matches_standard() {
        let (g, _) = cell();
        let x = cell_coords();
        let grad = [[0.05, 0.02, -0.01], [0.01, -0.03, 0.02], [0.0, 0.04, 0.06]];
        let ef = [2e6, -1e6, 5e6];
        let mut local = vec![0.0; 32];
        for a in 0..8 {
            for i in 0..3 {
                local[a * 4 + i] = (0..3).map(|j| grad[i][j] * x[a][j]).sum();
            }
            local[a * 4 + 3] = -(0..3).map(|j| ef[j] * x[a][j]).sum::<f64>();
        }
        for mat in materials() {
            let mat = mat.as_ref();
            let (mut r1, mut r2) = (vec![0.0; 32], vec![0.0; 32]);
            let e1 = crate::element::cell_residual_tangent(
                &g,
                mat,
                CellHistory::NONE,
                &local,
                &mut r1,
                None,
            )
            .unwrap();
            let e2 = cell_residual_tangent_md(&g, mat, CellHistory::NONE, &local, &mut r2, None)
                .unwrap();
            assert!((e1 - e2).abs() <= 1e-12 * e1.abs());
            let rmax = r1.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for i in 0..32 {
                assert!(
                    (r1[i] - r2[i]).abs() <= 1e-10 * rmax,
                    "{i}: {} {}",
                    r1[i],
                    r2[i]
                );
            }
            let f1 = crate::element::cell_fields(&g, mat, CellHistory::NONE, &local).unwrap();
            let f2 = cell_fields_md(&g, mat, CellHistory::NONE, &local).unwrap();
            for i in 0..9 {
                assert!((f1.sigma[i] - f2.sigma[i]).abs() <= 1e-9 * 1e5);
            }
            assert!((f1.j - f2.j).abs() < 1e-13);
        }
    }

    /// The fused residual of a dynamic step (elastic and Kelvin–Voigt forces from one set of
    /// kinematics) equals the separate calls up to round-off, with and without viscosity.
    #[test]
    fn dynamic_residual_matches_separate_calls() {
        use crate::element::{dynamic_residual_separate, CellInput, KelvinVoigtKernel};
        let (g, local) = cell();
        let vel: Vec<f64> = (0..32)
            .map(|i| ((i as f64 * 7.31).sin() * 911.7).fract() * 1e-2)
            .collect();
        for mat in materials() {
            let input = CellInput {
                geom: &g,
                mat: mat.as_ref(),
                hist: CellHistory::NONE,
                local: &local,
            };
            for viscous in [None, Some((KelvinVoigtKernel { eta: 2000.0 }, &vel[..]))] {
                let (mut r1, mut r2) = (vec![0.0; 32], vec![0.0; 32]);
                let a = MeanDilatationKernel
                    .dynamic_residual(&input, viscous, 0.37e-3, &mut r1)
                    .unwrap();
                let b = dynamic_residual_separate(
                    &MeanDilatationKernel,
                    &input,
                    viscous,
                    0.37e-3,
                    &mut r2,
                )
                .unwrap();
                assert!((a.0 - b.0).abs() <= 1e-14 * b.0.abs());
                assert!((a.1 - b.1).abs() <= 1e-13 * b.1.abs());
                // displacement and potential rows each against their own scale
                let rmax = |phi: bool| {
                    (0..32)
                        .filter(|i| (i % 4 == 3) == phi)
                        .fold(0.0f64, |m, i| m.max(r2[i].abs()))
                };
                for (i, (x, y)) in r1.iter().zip(&r2).enumerate() {
                    assert!((x - y).abs() <= 1e-13 * rmax(i % 4 == 3), "{i}: {x} {y}");
                }
                assert!(r1.iter().any(|&v| v != 0.0));
                if viscous.is_some() {
                    assert!(a.1 > 0.0);
                }
            }
        }
    }

    /// The configuration derivative of the Kelvin–Voigt kernel is that of the viscous part of the
    /// mean-dilatation kernel's fused dynamic residual (central differences).
    #[test]
    fn viscous_configuration_tangent_matches_the_fused_residual() {
        use crate::element::{CellInput, KelvinVoigtKernel};
        let (g, local) = cell();
        let vel: Vec<f64> = (0..32)
            .map(|i| ((i as f64 * 7.31).sin() * 911.7).fract() * 1e-2)
            .collect();
        let mat = &materials()[0];
        let kv = KelvinVoigtKernel { eta: 2000.0 };
        let f_r = 0.37e-3;
        let mut kq = vec![0.0; 32 * 32];
        kv.configuration_tangent(&g, &local, &vel, &mut kq).unwrap();
        crate::element::standard::tests::check_configuration_tangent(
            &local,
            &kq,
            |j| j % 4 != 3,
            |q| {
                let input = CellInput {
                    geom: &g,
                    mat: mat.as_ref(),
                    hist: CellHistory::NONE,
                    local: q,
                };
                let (mut with, mut without) = (vec![0.0; 32], vec![0.0; 32]);
                cell_dynamic_residual_md(
                    &g,
                    input.mat,
                    input.hist,
                    q,
                    Some((kv, &vel)),
                    f_r,
                    &mut with,
                )
                .unwrap();
                cell_dynamic_residual_md(&g, input.mat, input.hist, q, None, f_r, &mut without)
                    .unwrap();
                with.iter()
                    .zip(&without)
                    .map(|(a, b)| (a - b) / f_r)
                    .collect()
            },
        );
    }

    /// The tangents with the Kelvin–Voigt derivatives formed in the point blocks equal the
    /// elastic tangent plus the viscous configuration tangent plus `cv` times the velocity
    /// tangent, each from its own pass: mean-dilatation and standard hex8, every material of
    /// the tests (10⁻¹³ of the largest entry).
    #[test]
    fn viscous_point_blocks_give_the_separate_tangents() {
        use crate::element::{
            CellInput, CellKernel, KelvinVoigtKernel, MeanDilatationKernel, StandardKernel,
            ViscousTangent,
        };
        let (g, local) = cell();
        let vel: Vec<f64> = (0..32)
            .map(|i| ((i as f64 * 7.31).sin() * 911.7).fract() * 1.0)
            .collect();
        let kv = KelvinVoigtKernel { eta: 2000.0 };
        let kernels: [&dyn CellKernel; 2] = [&MeanDilatationKernel, &StandardKernel];
        // cv = 0: the configuration derivative alone; then with a step's 2/Δt
        for cv in [0.0, 2.0 / 0.37e-3] {
            let viscous = ViscousTangent {
                eta: kv.eta,
                vel: &vel,
                cv,
            };
            for mat in materials() {
                for kernel in kernels {
                    let input = CellInput {
                        geom: &g,
                        mat: mat.as_ref(),
                        hist: CellHistory::NONE,
                        local: &local,
                    };
                    let (mut r, mut k) = (vec![0.0; 32], vec![0.0; 32 * 32]);
                    kernel
                        .residual_tangent(&input, &mut r, Some(&mut k))
                        .unwrap();
                    let (mut kvel, mut kq) = (vec![0.0; 32 * 32], vec![0.0; 32 * 32]);
                    kv.forces(&g, &local, &vel, &mut vec![0.0; 32], Some(&mut kvel))
                        .unwrap();
                    kv.configuration_tangent(&g, &local, &vel, &mut kq).unwrap();
                    let (mut r2, mut fused) = (vec![0.0; 32], vec![0.0; 32 * 32]);
                    kernel
                        .residual_viscous_tangent(&input, &viscous, &mut r2, &mut fused)
                        .expect("a 3-D kernel forms them")
                        .unwrap();
                    assert_eq!(r, r2, "the elastic residual");
                    let apart: Vec<f64> =
                        (0..32 * 32).map(|i| k[i] + kq[i] + cv * kvel[i]).collect();
                    let big = apart.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    let part = (0..32 * 32)
                        .map(|i| if cv == 0.0 { kq[i] } else { cv * kvel[i] })
                        .fold(0.0f64, |m, v| m.max(v.abs()));
                    assert!(part > 1e-2 * big, "the viscous part shows: {part} of {big}");
                    for (a, b) in fused.iter().zip(&apart) {
                        assert!((a - b).abs() <= 1e-13 * big, "{a} against {b}");
                    }
                }
            }
        }
    }

    /// A material without the fast paths: every `*_known` method falls back to the generic
    /// evaluation at F.
    #[derive(Debug)]
    struct Generic<'a>(&'a dyn Material);

    impl Material for Generic<'_> {
        fn energy(&self, f: &Mat3, e0: &Vec3) -> Result<f64, MaterialError> {
            self.0.energy(f, e0)
        }
        fn stress(&self, f: &Mat3, e0: &Vec3) -> Result<crate::material::Stress, MaterialError> {
            self.0.stress(f, e0)
        }
        fn tangent(&self, f: &Mat3, e0: &Vec3) -> Result<Tangent, MaterialError> {
            self.0.tangent(f, e0)
        }
        fn shear_modulus(&self) -> f64 {
            self.0.shear_modulus()
        }
        fn bulk_modulus(&self) -> f64 {
            self.0.bulk_modulus()
        }
        fn permittivity(&self) -> f64 {
            self.0.permittivity()
        }
        fn energy_split(&self, f: &Mat3, e0: &Vec3) -> Result<(f64, f64), MaterialError> {
            self.0.energy_split(f, e0)
        }
    }

    /// The kernel's results with the materials' fast paths (stress, D₀ and record at a known
    /// F̄) equal those of the generic evaluations up to round-off: residual, dynamic residual,
    /// record (residual, energy split, fields) and the potential residual.
    #[test]
    fn fast_material_paths_match_generic_ones() {
        use crate::element::{CellInput, KelvinVoigtKernel};
        let (g, local) = cell();
        let vel: Vec<f64> = (0..32)
            .map(|i| ((i as f64 * 7.31).sin() * 911.7).fract() * 1e-2)
            .collect();
        let mut mats = materials();
        mats.push(Box::new(crate::material::ElectroYeoh::ideal(
            crate::material::Yeoh::new(2e5, 4e1, 1.3e2, 2.2e-9, 8.7e-11, -1.8e-11),
            4.7,
        )));
        // each row family against its own scale
        let same = |a: &[f64], b: &[f64], tol: f64| {
            for phi in [false, true] {
                let rows = || (0..a.len()).filter(move |i| (i % 4 == 3) == phi);
                let m = rows().fold(0.0f64, |m, i| m.max(b[i].abs()));
                for i in rows() {
                    assert!((a[i] - b[i]).abs() <= tol * m, "{i}: {} {}", a[i], b[i]);
                }
            }
        };
        let near = |a: f64, b: f64| assert!((a - b).abs() <= 1e-13 * b.abs(), "{a} {b}");
        for mat in &mats {
            let generic = Generic(mat.as_ref());
            let cells = [mat.as_ref(), &generic as &dyn Material].map(|m| CellInput {
                geom: &g,
                mat: m,
                hist: CellHistory::NONE,
                local: &local,
            });
            let (mut r1, mut r2) = (vec![0.0; 32], vec![0.0; 32]);
            let k = MeanDilatationKernel;
            near(
                k.residual_tangent(&cells[0], &mut r1, None).unwrap(),
                k.residual_tangent(&cells[1], &mut r2, None).unwrap(),
            );
            same(&r1, &r2, 1e-13);
            let viscous = Some((KelvinVoigtKernel { eta: 2000.0 }, &vel[..]));
            let a = k
                .dynamic_residual(&cells[0], viscous, 0.37e-3, &mut r1)
                .unwrap();
            let b = k
                .dynamic_residual(&cells[1], viscous, 0.37e-3, &mut r2)
                .unwrap();
            near(a.0, b.0);
            near(a.1, b.1);
            same(&r1, &r2, 1e-13);
            let (a, fa) = k.record(&cells[0], &mut r1).unwrap();
            let (b, fb) = k.record(&cells[1], &mut r2).unwrap();
            near(a.0, b.0);
            near(a.1, b.1);
            same(&r1, &r2, 1e-13);
            let smax = fb.sigma.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for i in 0..9 {
                assert!((fa.sigma[i] - fb.sigma[i]).abs() <= 1e-12 * smax);
                assert!((fa.sigma_mech[i] - fb.sigma_mech[i]).abs() <= 1e-12 * smax);
            }
            near(fa.e_max, fb.e_max);
            // and the record is the three separate calls
            assert_eq!(fa, k.fields(&cells[0]).unwrap());
            let split = k.energy_split(&cells[1]).unwrap();
            near(a.0, split.0);
            near(a.1, split.1);
            k.potential_residual(&cells[0], &mut r1).unwrap();
            k.potential_residual(&cells[1], &mut r2).unwrap();
            same(&r1, &r2, 1e-13);
        }
    }

    /// The cube root near 1 is the library's to a few ulps on both sides of its switch.
    #[test]
    fn cube_root_near_one() {
        let mut worst = 0.0f64;
        for i in -20000..=20000 {
            let x = 1.0 + 0.07 * i as f64 / 20000.0 + 1e-9 * (i as f64).sin();
            let (a, b) = (cbrt_near_one(x), x.cbrt());
            worst = worst.max((a - b).abs() / b);
        }
        assert!(worst <= 4.0 * f64::EPSILON, "{worst:e}");
        for x in [1e-3, 0.5, 2.0, 8.0, 1e3] {
            assert_eq!(cbrt_near_one(x), x.cbrt());
        }
    }

    #[test]
    fn names_round_trip() {
        for f in [Formulation::Standard, Formulation::MeanDilatation] {
            assert_eq!(Formulation::from_name(f.name()), Some(f));
        }
        assert_eq!(Formulation::from_name("bbar"), None);
        assert_eq!(Formulation::default(), Formulation::Standard);
    }
}
