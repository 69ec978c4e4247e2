//! The electro-elastic element kernel: turns a material and a cell's shape-function gradients into
//! the local residual and tangent of Π = ∫ Ψ(F, E₀) dV with E₀ = −∇₀Φ.
//!
//! Local dofs are node-major (ux, uy, uz, Φ). Residual rows:
//! r_{a,i} = ∫ P_iJ ∂N_a/∂X_J dV and r_{a,Φ} = ∂Π/∂Φ_a = ∫ D₀_J ∂N_a/∂X_J dV.
//! The tangent is their exact derivative, symmetric, with a negative-definite Φ–Φ block.

use super::CellHistory;
use crate::algebra::lanes::{with_wide_vectors, Wide, F4};
use crate::fem::FIELDS;
use crate::fem::{kinematics, CellGeometry, MAX_NODES};
use crate::material::{Material, MaterialError};

/// Largest number of local dofs.
pub const MAX_LOCAL: usize = MAX_NODES * FIELDS;

/// Local tangent storage (row-major, `n_local × n_local`).
pub type LocalMatrix = [f64; MAX_LOCAL * MAX_LOCAL];

/// Failure at a quadrature point.
#[derive(Debug, Clone, PartialEq)]
pub struct PointFailure {
    pub qp: usize,
    pub error: MaterialError,
}

/// Splits the local values (node-major, 4 per node) into displacements and potentials.
#[inline(always)]
pub(crate) fn split_local(n: usize, local: &[f64]) -> ([[f64; 3]; MAX_NODES], [f64; MAX_NODES]) {
    let mut u = [[0.0; 3]; MAX_NODES];
    let mut phi = [0.0; MAX_NODES];
    for a in 0..n {
        u[a] = [local[a * 4], local[a * 4 + 1], local[a * 4 + 2]];
        phi[a] = local[a * 4 + 3];
    }
    (u, phi)
}

/// Energy ∫Ψ dV of the cell (J).
pub fn cell_energy(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
) -> Result<f64, PointFailure> {
    let n = geom.n_nodes;
    let (u, phi) = split_local(n, local);
    let mut e = 0.0;
    for q in 0..geom.n_qp {
        let (f, e0) = kinematics(&geom.grad[q][..n], &u[..n], &phi[..n]);
        e += geom.weights[q]
            * mat
                .energy_at(&f, &e0, hist.at(q))
                .map_err(|error| PointFailure { qp: q, error })?;
    }
    Ok(e)
}

/// Mechanical and electric parts of the cell energy, `(∫W dV, ∫w_e dV)` (J), as the material splits it.
pub fn cell_energy_split(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
) -> Result<(f64, f64), PointFailure> {
    let n = geom.n_nodes;
    let (u, phi) = split_local(n, local);
    let (mut m, mut el) = (0.0, 0.0);
    for q in 0..geom.n_qp {
        let (f, e0) = kinematics(&geom.grad[q][..n], &u[..n], &phi[..n]);
        let (a, b) = mat
            .energy_split_at(&f, &e0, hist.at(q).state)
            .map_err(|error| PointFailure { qp: q, error })?;
        m += geom.weights[q] * a;
        el += geom.weights[q] * b;
    }
    Ok((m, el))
}

/// Local residual (and tangent when `k` is given) of the cell. Returns the cell energy (J).
/// `r` has `4·n_nodes` entries; `k` is row-major with leading dimension `4·n_nodes`.
pub fn cell_residual_tangent(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
    r: &mut [f64],
    k: Option<&mut [f64]>,
) -> Result<f64, PointFailure> {
    cell_residual_viscous_tangent(geom, mat, hist, local, None, r, k)
}

/// [`cell_residual_tangent`] whose tangent also holds the Kelvin–Voigt derivatives of
/// `viscous` ([`viscous_point_block`] added to each point's A): the residual is the elastic one.
pub fn cell_residual_viscous_tangent(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
    viscous: Option<&ViscousTangent>,
    r: &mut [f64],
    mut k: Option<&mut [f64]>,
) -> Result<f64, PointFailure> {
    let n = geom.n_nodes;
    let nl = n * FIELDS;
    let (u, phi) = split_local(n, local);
    r[..nl].iter_mut().for_each(|v| *v = 0.0);
    if let Some(k) = k.as_deref_mut() {
        k[..nl * nl].iter_mut().for_each(|v| *v = 0.0);
    }
    let mut energy = 0.0;
    for q in 0..geom.n_qp {
        let g = &geom.grad[q];
        let w = geom.weights[q];
        let (f, e0) = kinematics(&g[..n], &u[..n], &phi[..n]);
        let fail = |error| PointFailure { qp: q, error };
        match k.as_deref_mut() {
            None => {
                let s = mat.stress_at(&f, &e0, hist.at(q)).map_err(fail)?;
                energy += w * s.energy;
                add_residual(g, n, w, &s.p, &s.d0, r);
            }
            Some(k) => {
                let t = mat.tangent_at(&f, &e0, hist.at(q)).map_err(fail)?;
                energy += w * t.energy;
                add_residual(g, n, w, &t.p, &t.d0, r);
                match viscous {
                    None => add_point_tangent(g, n, w, &t.a, &t.b, &t.g, k),
                    Some(v) => {
                        let j = f.determinant();
                        if j.is_nan() || j <= 0.0 {
                            return Err(fail(MaterialError::NonPositiveJ(j)));
                        }
                        let fit = f
                            .try_inverse()
                            .ok_or(fail(MaterialError::NonPositiveJ(j)))?
                            .transpose();
                        let a = t.a + viscous_point_block(&fit, j, g, n, v);
                        add_point_tangent(g, n, w, &a, &t.b, &t.g, k)
                    }
                }
            }
        }
    }
    Ok(energy)
}

/// [`CellKernel::potential_residual_tangent`] of a standard cell: D₀ and its derivatives per
/// point, no stress.
pub fn cell_potential_tangent(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
    r: &mut [f64],
    k: &mut [f64],
) -> Result<(), PointFailure> {
    let n = geom.n_nodes;
    let nl = n * FIELDS;
    let (u, phi) = split_local(n, local);
    r[..nl].iter_mut().for_each(|v| *v = 0.0);
    k[..nl * nl].iter_mut().for_each(|v| *v = 0.0);
    let no_stress = crate::material::Mat3::zeros();
    for q in 0..geom.n_qp {
        let g = &geom.grad[q];
        let w = geom.weights[q];
        let (f, e0) = kinematics(&g[..n], &u[..n], &phi[..n]);
        let t = mat
            .electric_tangent_at(&f, &e0, hist.at(q))
            .map_err(|error| PointFailure { qp: q, error })?;
        add_residual(g, n, w, &no_stress, &t.d0, r);
        add_point_potential_tangent(g, n, w, &t.b, &t.g, k);
    }
    Ok(())
}

/// The Φ rows of [`add_point_tangent`]: −w ∇₀N_a · (∇₀N_b ⋅ B)ᵀ in the displacement columns
/// and w ∇₀N_a · G ∇₀N_b in the potential's.
pub(crate) fn add_point_potential_tangent(
    g: &[[f64; 3]; MAX_NODES],
    n: usize,
    w: f64,
    b_blk: &crate::material::Mat93,
    g_blk: &crate::material::Mat3,
    k: &mut [f64],
) {
    with_wide_vectors(PointTangent {
        g,
        n,
        w,
        a_blk: None,
        b_blk,
        g_blk,
        k,
    })
}

/// Adds w·(P : ∇₀N_a, D₀ · ∇₀N_a) of one point to the residual rows of every node.
pub(crate) fn add_residual(
    g: &[[f64; 3]; MAX_NODES],
    n: usize,
    w: f64,
    p: &crate::material::Mat3,
    d0: &crate::material::Vec3,
    r: &mut [f64],
) {
    for (ga, ra) in g[..n].iter().zip(r.chunks_exact_mut(FIELDS)) {
        for i in 0..3 {
            ra[i] += w * (p[(i, 0)] * ga[0] + p[(i, 1)] * ga[1] + p[(i, 2)] * ga[2]);
        }
        ra[3] += w * (d0[0] * ga[0] + d0[1] * ga[1] + d0[2] * ga[2]);
    }
}

/// Cell averages of the spatial electric field e = F⁻ᵀE₀ (V/m), the Cauchy stress (Pa, row-major)
/// and J, and the largest |e| at a quadrature point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellFields {
    pub e: [f64; 3],
    /// Total Cauchy stress (Pa), row-major: the mechanical stress plus the Maxwell stress.
    pub sigma: [f64; 9],
    /// Mechanical Cauchy stress (Pa): that of the energy at zero field, Ψ(F, 0). The Maxwell
    /// stress is `sigma − sigma_mech` (zero total stress in a free film hides both).
    pub sigma_mech: [f64; 9],
    pub j: f64,
    pub e_max: f64,
}

impl CellFields {
    /// No fields (zero), to accumulate the quadrature points' contributions into.
    pub fn zero() -> Self {
        CellFields {
            e: [0.0; 3],
            sigma: [0.0; 9],
            sigma_mech: [0.0; 9],
            j: 0.0,
            e_max: 0.0,
        }
    }

    /// Number of values of [`CellFields::to_array`].
    pub const VALUES: usize = 23;

    /// The fields as one array (e, σ, σ_mech, J, |e|max), to sum over processes.
    pub fn to_array(&self) -> [f64; Self::VALUES] {
        let mut a = [0.0; Self::VALUES];
        a[..3].copy_from_slice(&self.e);
        a[3..12].copy_from_slice(&self.sigma);
        a[12..21].copy_from_slice(&self.sigma_mech);
        a[21] = self.j;
        a[22] = self.e_max;
        a
    }

    /// The fields from the first [`CellFields::VALUES`] entries of `a` ([`CellFields::to_array`]).
    pub fn from_array(a: &[f64]) -> Self {
        let mut f = Self::zero();
        f.e.copy_from_slice(&a[..3]);
        f.sigma.copy_from_slice(&a[3..12]);
        f.sigma_mech.copy_from_slice(&a[12..21]);
        f.j = a[21];
        f.e_max = a[22];
        f
    }

    /// Adds the weight-`w` contribution of a material point at (F, E₀) with history `h`: its
    /// total stress, the mechanical one (the same point at zero field), its true field and J.
    pub fn add_material_point(
        &mut self,
        w: f64,
        mat: &dyn Material,
        f: &crate::material::Mat3,
        e0: &crate::material::Vec3,
        h: crate::material::PointHistory,
    ) -> Result<(), crate::material::MaterialError> {
        let s = mat.stress_at(f, e0, h)?;
        let s_mech = mat.stress_at(f, &crate::material::Vec3::zeros(), h)?;
        let sigma = crate::material::cauchy_stress(&s.p, f);
        let sigma_mech = crate::material::cauchy_stress(&s_mech.p, f);
        let e = crate::material::spatial_field(f, e0).unwrap_or_default();
        self.add_point(w, &e, &sigma, &sigma_mech, f.determinant());
        Ok(())
    }

    /// Adds the weight-`w` contribution of one point: its true field `e`, total and mechanical
    /// Cauchy stress, and J.
    pub fn add_point(
        &mut self,
        w: f64,
        e: &crate::material::Vec3,
        sigma: &crate::material::Mat3,
        sigma_mech: &crate::material::Mat3,
        j: f64,
    ) {
        for i in 0..3 {
            self.e[i] += w * e[i];
            for k in 0..3 {
                self.sigma[i * 3 + k] += w * sigma[(i, k)];
                self.sigma_mech[i * 3 + k] += w * sigma_mech[(i, k)];
            }
        }
        self.j += w * j;
        self.e_max = self.e_max.max(e.norm());
    }
}

/// F and E₀ at each quadrature point of a standard cell, into `out[..n_qp]`.
pub fn point_deformations(
    geom: &CellGeometry,
    local: &[f64],
    out: &mut [(crate::material::Mat3, crate::material::Vec3)],
) {
    let n = geom.n_nodes;
    let (u, phi) = split_local(n, local);
    for q in 0..geom.n_qp {
        out[q] = kinematics(&geom.grad[q][..n], &u[..n], &phi[..n]);
    }
}

/// Field values of a cell for output.
pub fn cell_fields(
    geom: &CellGeometry,
    mat: &dyn Material,
    hist: CellHistory,
    local: &[f64],
) -> Result<CellFields, PointFailure> {
    let n = geom.n_nodes;
    let (u, phi) = split_local(n, local);
    let mut out = CellFields::zero();
    let vol: f64 = geom.weights[..geom.n_qp].iter().sum();
    for q in 0..geom.n_qp {
        let (f, e0) = kinematics(&geom.grad[q][..n], &u[..n], &phi[..n]);
        out.add_material_point(geom.weights[q] / vol, mat, &f, &e0, hist.at(q))
            .map_err(|error| PointFailure { qp: q, error })?;
    }
    Ok(out)
}

/// One quadrature point of the Kelvin–Voigt forces: with the spatial gradients `h` and the nodal
/// velocities `v`, d = sym(Σ v_a ⊗ h_a) = sym(Ḟ F⁻¹); adds c·d h_a to the u rows of node a in `r`
/// and returns c d:d (c = w J η, the point's weight in the dissipation power).
pub(crate) fn viscous_point(h: &[[f64; 3]], v: &[[f64; 3]], c: f64, r: &mut [f64]) -> f64 {
    let mut l = [[0.0; 3]; 3];
    for (va, ha) in v.iter().zip(h) {
        for i in 0..3 {
            for m in 0..3 {
                l[i][m] += va[i] * ha[m];
            }
        }
    }
    let mut d = [[0.0; 3]; 3];
    let mut dd = 0.0;
    for i in 0..3 {
        for m in 0..3 {
            d[i][m] = 0.5 * (l[i][m] + l[m][i]);
        }
    }
    for i in 0..3 {
        for m in 0..3 {
            dd += d[i][m] * d[i][m];
        }
    }
    for (ha, ra) in h.iter().zip(r.chunks_exact_mut(FIELDS)) {
        for i in 0..3 {
            ra[i] += c * (d[i][0] * ha[0] + d[i][1] * ha[1] + d[i][2] * ha[2]);
        }
    }
    c * dd
}

/// Kelvin–Voigt viscosity (Wriggers' 3-D form; docs/theory.md, Kelvin–Voigt viscosity): P_vis = Jη d F⁻ᵀ with
/// d = sym(Ḟ F⁻¹), the derivative of the Rayleigh function R = (Jη/2) d:d with respect to Ḟ.
/// With the spatial gradients h_a = F⁻ᵀ∇₀N_a: r_{a,i} = ∫ Jη (d h_a)_i dV and
/// ∂r_{a,i}/∂v_{b,k} = ∫ (Jη/2)(δ_ik h_a·h_b + h_{b,i} h_{a,k}) dV (symmetric, positive semi-definite).
/// Adds the viscous forces to the u rows of `r` and, when given, their derivative with respect to
/// the nodal velocities to `kv`; `local` is the configuration, `vel` the nodal velocities (4 per
/// node, potential entries ignored). Returns the dissipation power ∫ Jη d:d dV (W).
pub fn cell_viscous(
    geom: &CellGeometry,
    eta: f64,
    local: &[f64],
    vel: &[f64],
    r: &mut [f64],
    mut kv: Option<&mut [f64]>,
) -> Result<f64, PointFailure> {
    let n = geom.n_nodes;
    let nl = n * FIELDS;
    let (u, phi) = split_local(n, local);
    let (v, _) = split_local(n, vel);
    let mut power = 0.0;
    for q in 0..geom.n_qp {
        let g = &geom.grad[q];
        let w = geom.weights[q];
        let (f, _) = kinematics(&g[..n], &u[..n], &phi[..n]);
        let j = f.determinant();
        let fail = |error| PointFailure { qp: q, error };
        if j.is_nan() || j <= 0.0 {
            return Err(fail(MaterialError::NonPositiveJ(j)));
        }
        let finv = f
            .try_inverse()
            .ok_or(fail(MaterialError::NonPositiveJ(j)))?;
        let mut h = [[0.0; 3]; MAX_NODES];
        for (ha, ga) in h[..n].iter_mut().zip(&g[..n]) {
            for i in 0..3 {
                ha[i] = finv[(0, i)] * ga[0] + finv[(1, i)] * ga[1] + finv[(2, i)] * ga[2];
            }
        }
        let c = w * j * eta;
        power += viscous_point(&h[..n], &v[..n], c, r);
        if let Some(kv) = kv.as_deref_mut() {
            for a in 0..n {
                for b in 0..n {
                    let hab = h[a][0] * h[b][0] + h[a][1] * h[b][1] + h[a][2] * h[b][2];
                    for i in 0..3 {
                        let row = (a * 4 + i) * nl + b * 4;
                        for k in 0..3 {
                            let delta = if i == k { hab } else { 0.0 };
                            kv[row + k] += 0.5 * c * (delta + h[b][i] * h[a][k]);
                        }
                    }
                }
            }
        }
    }
    Ok(power)
}

/// What a dynamic step's tangent needs of the Kelvin–Voigt forces in a cell whose kernel
/// forms them with its own tangent: the viscosity, the nodal velocities (4 per node) and the
/// weight `cv` of the velocity derivative against the configuration derivatives.
#[derive(Debug, Clone, Copy)]
pub struct ViscousTangent<'a> {
    pub eta: f64,
    pub vel: &'a [f64],
    pub cv: f64,
}

/// One point's Kelvin–Voigt derivatives as a 9 × 9 block on the reference gradients, the form
/// of [`add_point_tangent`]'s A (K_{ai,bk} = Σ ∂N_a/∂X_J A_{iJ,kL} ∂N_b/∂X_L, the point's weight
/// applied there): the configuration derivative of [`cell_viscous_configuration`] plus `cv`
/// times the velocity derivative of [`cell_viscous`]. With f = F⁻ᵀ (`fit`), h_a = f∇₀N_a,
/// l = Σ v_a ⊗ h_a, d = sym l and c = Jη:
/// Q_{iJ,kL} = c[(d f)_{iJ} f_{kL} − f_{kJ}(d f)_{iL} − ½ l_ik (fᵀf)_{JL} − ½ f_{iL}(lᵀf)_{kJ}],
/// V_{iJ,kL} = ½c(δ_ik (fᵀf)_{JL} + f_{iL} f_{kJ}).
pub(crate) fn viscous_point_block(
    fit: &crate::material::Mat3,
    j: f64,
    g: &[[f64; 3]; MAX_NODES],
    n: usize,
    viscous: &ViscousTangent,
) -> crate::material::Mat9 {
    use crate::material::Mat3;
    let mut l = Mat3::zeros();
    for (a, ga) in g[..n].iter().enumerate() {
        let v = &viscous.vel[a * FIELDS..a * FIELDS + 3];
        for m in 0..3 {
            let ham = fit[(m, 0)] * ga[0] + fit[(m, 1)] * ga[1] + fit[(m, 2)] * ga[2];
            for i in 0..3 {
                l[(i, m)] += v[i] * ham;
            }
        }
    }
    let d = (l + l.transpose()) * 0.5;
    let df = d * fit;
    let ftf = fit.transpose() * fit;
    let ltf = l.transpose() * fit;
    let c = j * viscous.eta;
    let cv = viscous.cv;
    crate::material::Mat9::from_fn(|r9, c9| {
        let (i, jj) = (r9 / 3, r9 % 3);
        let (k, ll) = (c9 / 3, c9 % 3);
        let q = df[(i, jj)] * fit[(k, ll)]
            - fit[(k, jj)] * df[(i, ll)]
            - 0.5 * l[(i, k)] * ftf[(jj, ll)]
            - 0.5 * fit[(i, ll)] * ltf[(k, jj)];
        let delta = if i == k { ftf[(jj, ll)] } else { 0.0 };
        let v = 0.5 * (delta + fit[(i, ll)] * fit[(k, jj)]);
        c * (q + cv * v)
    })
}

/// The derivative of the Kelvin–Voigt forces of [`cell_viscous`] with respect to the
/// configuration at fixed nodal velocities, added to `kq` (row-major 4n × 4n; u rows and columns
/// only: the forces do not depend on Φ). With δF = e_k ⊗ ∇₀N_b: δJ = J h_{b,k},
/// δh_a = −h_b h_{a,k} and δl = −(l e_k) ⊗ h_b, so that
/// ∂r_{a,i}/∂u_{b,k} = ∫ Jη [h_{b,k}(d h_a)_i − h_{a,k}(d h_b)_i − ½ l_ik h_a·h_b − ½ h_{b,i}(lᵀh_a)_k] dV.
/// Unsymmetric: the step Jacobian of a viscous dynamic step needs it, its symmetric iteration
/// matrix omits it.
pub fn cell_viscous_configuration(
    geom: &CellGeometry,
    eta: f64,
    local: &[f64],
    vel: &[f64],
    kq: &mut [f64],
) -> Result<(), PointFailure> {
    let n = geom.n_nodes;
    let nl = n * FIELDS;
    let (u, phi) = split_local(n, local);
    let (v, _) = split_local(n, vel);
    for q in 0..geom.n_qp {
        let g = &geom.grad[q];
        let (f, _) = kinematics(&g[..n], &u[..n], &phi[..n]);
        let j = f.determinant();
        let fail = |error| PointFailure { qp: q, error };
        if j.is_nan() || j <= 0.0 {
            return Err(fail(MaterialError::NonPositiveJ(j)));
        }
        let finv = f
            .try_inverse()
            .ok_or(fail(MaterialError::NonPositiveJ(j)))?;
        let mut h = [[0.0; 3]; MAX_NODES];
        for (ha, ga) in h[..n].iter_mut().zip(&g[..n]) {
            for i in 0..3 {
                ha[i] = finv[(0, i)] * ga[0] + finv[(1, i)] * ga[1] + finv[(2, i)] * ga[2];
            }
        }
        let mut l = [[0.0; 3]; 3];
        for (va, ha) in v[..n].iter().zip(&h[..n]) {
            for i in 0..3 {
                for m in 0..3 {
                    l[i][m] += va[i] * ha[m];
                }
            }
        }
        let d: [[f64; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|m| 0.5 * (l[i][m] + l[m][i])));
        // d h_a and lᵀ h_a of every node
        let mut dh = [[0.0; 3]; MAX_NODES];
        let mut lth = [[0.0; 3]; MAX_NODES];
        for a in 0..n {
            for i in 0..3 {
                dh[a][i] = d[i][0] * h[a][0] + d[i][1] * h[a][1] + d[i][2] * h[a][2];
                lth[a][i] = l[0][i] * h[a][0] + l[1][i] * h[a][1] + l[2][i] * h[a][2];
            }
        }
        let c = geom.weights[q] * j * eta;
        let p = ViscousPoint {
            c,
            h: &h,
            dh: &dh,
            lth: &lth,
            l: &l,
        };
        p.add_cell(n, &mut kq[..nl * nl]);
    }
    Ok(())
}

/// One quadrature point's share of [`cell_viscous_configuration`]: c = w J η, the gradients
/// h_a = F⁻ᵀ∇₀N_a, d h_a, lᵀ h_a and l = Σ v_a ⊗ h_a.
struct ViscousPoint<'a> {
    c: f64,
    h: &'a [[f64; 3]; MAX_NODES],
    dh: &'a [[f64; 3]; MAX_NODES],
    lth: &'a [[f64; 3]; MAX_NODES],
    l: &'a [[f64; 3]; 3],
}

impl ViscousPoint<'_> {
    /// [`ViscousPoint::add`] for a cell of `n` nodes, the node count a constant for the common
    /// cells (so that the loops over b unroll).
    fn add_cell(&self, n: usize, kq: &mut [f64]) {
        match n {
            8 => self.add::<8>(n, kq),
            4 => self.add::<4>(n, kq),
            10 => self.add::<10>(n, kq),
            _ => self.add::<MAX_NODES>(n, kq),
        }
    }

    /// Adds the entries K_{ai,bk} = c (h_b,k (d h_a)_i − h_a,k (d h_b)_i − ½ l_ik h_a·h_b
    /// − ½ h_b,i (lᵀh_a)_k) for cells of `n ≤ N` nodes, a row segment's nodes b at once from
    /// values held contiguous over b (so the loop over b vectorises); each entry is the same
    /// expression as formed one by one, so the sums are the same bits.
    #[inline(always)]
    fn add<const N: usize>(&self, n: usize, kq: &mut [f64]) {
        let (c, h, dh, lth, l) = (self.c, self.h, self.dh, self.lth, self.l);
        let nl = n * FIELDS;
        let mut ht = [[0.0; N]; 3];
        let mut dht = [[0.0; N]; 3];
        for b in 0..n {
            for m in 0..3 {
                ht[m][b] = h[b][m];
                dht[m][b] = dh[b][m];
            }
        }
        let mut hab = [0.0; N];
        let mut seg = [[0.0; N]; 3];
        for a in 0..n {
            for b in 0..n {
                hab[b] = h[a][0] * ht[0][b] + h[a][1] * ht[1][b] + h[a][2] * ht[2][b];
            }
            for i in 0..3 {
                let dai = dh[a][i];
                for (k, out) in seg.iter_mut().enumerate() {
                    let (hak, lik, lak) = (h[a][k], l[i][k], lth[a][k]);
                    for b in 0..n {
                        out[b] = c
                            * (ht[k][b] * dai
                                - hak * dht[i][b]
                                - 0.5 * lik * hab[b]
                                - 0.5 * ht[i][b] * lak);
                    }
                }
                let row = &mut kq[(a * 4 + i) * nl..(a * 4 + i) * nl + nl];
                for (b, kb) in row.chunks_exact_mut(FIELDS).enumerate() {
                    kb[0] += seg[0][b];
                    kb[1] += seg[1][b];
                    kb[2] += seg[2][b];
                }
            }
        }
    }
}

/// Adds w·(∂r/∂x) of one quadrature point to the local tangent `k` (leading dimension 4n), given
/// the point's blocks A = ∂P/∂F (9×9), B = ∂P/∂E₀ (9×3) and G = ∂²Ψ/∂E₀² (3×3):
/// K_{ai,bk} = Σ ∂N_a/∂X_J A_{iJ,kL} ∂N_b/∂X_L, K_{ai,bΦ} = −Σ ∂N_a/∂X_J B_{iJ,K} ∂N_b/∂X_K,
/// K_{aΦ,bk} its symmetric partner and K_{aΦ,bΦ} = Σ ∂N_a/∂X_J G_JK ∂N_b/∂X_K.
///
/// The four entries (b, ux), (b, uy), (b, uz), (b, Φ) of a row are formed together as the four
/// lanes of an [`F4`] and added to the row's four contiguous entries at once, compiled for AVX2
/// where the processor has it; each entry is the same expression as when formed one by one, so
/// the sums are the same bits on any processor.
pub(crate) fn add_point_tangent(
    g: &[[f64; 3]; MAX_NODES],
    n: usize,
    w: f64,
    a_blk: &crate::material::Mat9,
    b_blk: &crate::material::Mat93,
    g_blk: &crate::material::Mat3,
    k: &mut [f64],
) {
    with_wide_vectors(PointTangent {
        g,
        n,
        w,
        a_blk: Some(a_blk),
        b_blk,
        g_blk,
        k,
    })
}

/// The arguments of [`add_point_tangent`] (of [`add_point_potential_tangent`] without A), run
/// compiled for wide vectors.
struct PointTangent<'a> {
    g: &'a [[f64; 3]; MAX_NODES],
    n: usize,
    w: f64,
    a_blk: Option<&'a crate::material::Mat9>,
    b_blk: &'a crate::material::Mat93,
    g_blk: &'a crate::material::Mat3,
    k: &'a mut [f64],
}

impl Wide for PointTangent<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        let PointTangent {
            g,
            n,
            w,
            a_blk,
            b_blk,
            g_blk,
            k,
        } = self;
        // the node count as a constant for the common cells, so that the loops over b unroll
        match n {
            8 => point_tangent::<8>(g, 8, w, a_blk, b_blk, g_blk, k),
            4 => point_tangent::<4>(g, 4, w, a_blk, b_blk, g_blk, k),
            10 => point_tangent::<10>(g, 10, w, a_blk, b_blk, g_blk, k),
            _ => point_tangent::<MAX_NODES>(g, n, w, a_blk, b_blk, g_blk, k),
        }
    }
}

/// [`add_point_tangent`] for cells of `n ≤ N` nodes (`n = N` known where it is inlined); the
/// Φ rows alone without `a_blk`.
#[inline(always)]
fn point_tangent<const N: usize>(
    g: &[[f64; 3]; MAX_NODES],
    n: usize,
    w: f64,
    a_blk: Option<&crate::material::Mat9>,
    b_blk: &crate::material::Mat93,
    g_blk: &crate::material::Mat3,
    k: &mut [f64],
) {
    let nl = n * FIELDS;
    let wl = F4::splat(w);
    let mut gl = [[F4::splat(0.0); 3]; N];
    for a in 0..n {
        for l in 0..3 {
            gl[a][l] = F4::splat(g[a][l]);
        }
    }
    // the Φ row's factors of node b: (gb[b][0][L], gb[b][1][L], gb[b][2][L], ∂N_b/∂X_L) with
    // gb[b][k][L] = Σ_J ∂N_b/∂X_J B_{kJ,L}
    let mut yl = [[F4::splat(0.0); 3]; N];
    // K_{ai,bΦ} enters with the sign −, the Φ row's K_{aΦ,bk} likewise (x − y is x + (−y))
    let (u_sign, phi_sign) = (F4([1.0, 1.0, 1.0, -1.0]), F4([-1.0, -1.0, -1.0, 1.0]));
    let add = |kb: &mut [f64], v: F4| {
        let s = F4([kb[0], kb[1], kb[2], kb[3]]) + v;
        kb.copy_from_slice(&s.0);
    };
    if let Some(a_blk) = a_blk {
        // Row (a, i)'s four entries (b, f) are w·Σ_L c[a][i][L]_f ∂N_b/∂X_L, with the
        // coefficients c_f = ga[a][i][3f + L] (f < 3) and gb[a][i][L] (f = Φ),
        // ga[a][i][kL] = Σ_J ∂N_a/∂X_J A_{iJ,kL}: held as four lanes, one per f, each summed
        // from 0 over J in the order of the entry-by-entry form, so the sums are the same bits
        let cols: [[[F4; 3]; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|jj| {
                let row = i * 3 + jj;
                std::array::from_fn(|l| {
                    F4([
                        a_blk[(row, l)],
                        a_blk[(row, 3 + l)],
                        a_blk[(row, 6 + l)],
                        b_blk[(row, l)],
                    ])
                })
            })
        });
        let mut c = [[[F4::splat(0.0); 3]; 3]; N];
        for a in 0..n {
            for (i, ci) in c[a].iter_mut().enumerate() {
                for (jj, gaj) in gl[a].iter().enumerate() {
                    for (l, cl) in ci.iter_mut().enumerate() {
                        *cl += *gaj * cols[i][jj][l];
                    }
                }
            }
            for (i, c) in c[a].iter().enumerate() {
                let row = &mut k[(a * 4 + i) * nl..(a * 4 + i) * nl + nl];
                for (kb, gb) in row.chunks_exact_mut(FIELDS).zip(&gl[..n]) {
                    add(
                        kb,
                        wl * (c[0] * gb[0] + c[1] * gb[1] + c[2] * gb[2]) * u_sign,
                    );
                }
            }
            for l in 0..3 {
                yl[a][l] = F4([c[a][0][l].0[3], c[a][1][l].0[3], c[a][2][l].0[3], g[a][l]]);
            }
        }
    } else {
        let cols: [[F4; 3]; 3] = std::array::from_fn(|jj| {
            std::array::from_fn(|l| {
                F4([b_blk[(jj, l)], b_blk[(3 + jj, l)], b_blk[(6 + jj, l)], 0.0])
            })
        });
        for b in 0..n {
            for l in 0..3 {
                let mut y = F4::splat(0.0);
                for (jj, gbj) in gl[b].iter().enumerate() {
                    y += *gbj * cols[jj][l];
                }
                y.0[3] = g[b][l];
                yl[b][l] = y;
            }
        }
    }
    // the Φ rows: −w gb[b][k]·∇N_a and w gg[a]·∇N_b, gg[a][K] = Σ_J ∂N_a/∂X_J G_JK
    for a in 0..n {
        let gg: [f64; 3] = std::array::from_fn(|k| {
            g[a][0] * g_blk[(0, k)] + g[a][1] * g_blk[(1, k)] + g[a][2] * g_blk[(2, k)]
        });
        let x: [F4; 3] = std::array::from_fn(|l| F4([g[a][l], g[a][l], g[a][l], gg[l]]));
        let row = &mut k[(a * 4 + 3) * nl..(a * 4 + 3) * nl + nl];
        for (kb, y) in row.chunks_exact_mut(FIELDS).zip(&yl[..n]) {
            add(
                kb,
                wl * (x[0] * y[0] + x[1] * y[1] + x[2] * y[2]) * phi_sign,
            );
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::material::{Mat3, Mat9, Mat93};

    /// The point tangent formed entry by entry, the form `add_point_tangent` reorders.
    fn point_tangent_entrywise(
        g: &[[f64; 3]; MAX_NODES],
        n: usize,
        w: f64,
        a_blk: &Mat9,
        b_blk: &Mat93,
        g_blk: &Mat3,
        k: &mut [f64],
    ) {
        let nl = n * FIELDS;
        for a in 0..n {
            for b in 0..n {
                for i in 0..3 {
                    let row = (a * 4 + i) * nl + b * 4;
                    for kk in 0..3 {
                        let mut c = [0.0; 3];
                        for (l, cl) in c.iter_mut().enumerate() {
                            for jj in 0..3 {
                                *cl += g[a][jj] * a_blk[(i * 3 + jj, kk * 3 + l)];
                            }
                        }
                        k[row + kk] += w * (c[0] * g[b][0] + c[1] * g[b][1] + c[2] * g[b][2]);
                    }
                    let mut c = [0.0; 3];
                    for (l, cl) in c.iter_mut().enumerate() {
                        for jj in 0..3 {
                            *cl += g[a][jj] * b_blk[(i * 3 + jj, l)];
                        }
                    }
                    k[row + 3] -= w * (c[0] * g[b][0] + c[1] * g[b][1] + c[2] * g[b][2]);
                }
                let row = (a * 4 + 3) * nl + b * 4;
                for kk in 0..3 {
                    let mut c = [0.0; 3];
                    for (l, cl) in c.iter_mut().enumerate() {
                        for jj in 0..3 {
                            *cl += g[b][jj] * b_blk[(kk * 3 + jj, l)];
                        }
                    }
                    k[row + kk] -= w * (c[0] * g[a][0] + c[1] * g[a][1] + c[2] * g[a][2]);
                }
                let gg: Vec<f64> = (0..3)
                    .map(|c| {
                        g[a][0] * g_blk[(0, c)] + g[a][1] * g_blk[(1, c)] + g[a][2] * g_blk[(2, c)]
                    })
                    .collect();
                k[row + 3] += w * (gg[0] * g[b][0] + gg[1] * g[b][1] + gg[2] * g[b][2]);
            }
        }
    }

    /// A small deterministic generator of values in (−1, 1).
    fn generator() -> impl FnMut() -> f64 {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        }
    }

    /// Checks `kq` (n × n, row-major) against central differences of `force` over every
    /// displacement column: each entry within 1e-6 of the largest.
    pub(crate) fn check_configuration_tangent(
        local: &[f64],
        kq: &[f64],
        columns: impl Fn(usize) -> bool,
        force: impl Fn(&[f64]) -> Vec<f64>,
    ) {
        let n = local.len();
        let kmax = kq.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(kmax > 0.0);
        let umax = (0..n)
            .filter(|&j| columns(j))
            .fold(0.0f64, |m, j| m.max(local[j].abs()));
        let h = 1e-6 * umax.max(1e-6);
        let mut worst = 0.0f64;
        for j in 0..n {
            if !columns(j) {
                // the forces do not depend on this unknown
                assert!((0..n).all(|i| kq[i * n + j] == 0.0), "column {j}");
                continue;
            }
            let (mut p, mut m) = (local.to_vec(), local.to_vec());
            p[j] += h;
            m[j] -= h;
            let (rp, rm) = (force(&p), force(&m));
            for i in 0..n {
                let fd = (rp[i] - rm[i]) / (2.0 * h);
                worst = worst.max((fd - kq[i * n + j]).abs() / kmax);
            }
        }
        assert!(worst <= 1e-6, "relative difference {worst:e}");
    }

    /// The configuration derivative of the Kelvin–Voigt forces at fixed velocity matches central
    /// differences on distorted hex8 and tet10 cells in a general state and motion, and is
    /// unsymmetric.
    #[test]
    fn viscous_configuration_tangent_matches_finite_differences() {
        use crate::fem::ReferenceElement;
        use crate::mesh::ElementKind;
        let mut next = generator();
        for kind in [ElementKind::Hex8, ElementKind::Tet10] {
            let reference = ReferenceElement::new(kind);
            let corners: Vec<[f64; 3]> = match kind {
                ElementKind::Hex8 => vec![
                    [0.0, 0.0, 0.0],
                    [1.0, 0.0, 0.0],
                    [1.0, 1.0, 0.0],
                    [0.0, 1.0, 0.0],
                    [0.0, 0.0, 1.0],
                    [1.0, 0.0, 1.0],
                    [1.0, 1.0, 1.0],
                    [0.0, 1.0, 1.0],
                ],
                _ => {
                    let c = [
                        [0.0, 0.0, 0.0],
                        [1.0, 0.0, 0.0],
                        [0.0, 1.0, 0.0],
                        [0.0, 0.0, 1.0],
                    ];
                    let mid =
                        |a: usize, b: usize| std::array::from_fn(|i| 0.5 * (c[a][i] + c[b][i]));
                    let mut x = c.to_vec();
                    for (a, b) in [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)] {
                        x.push(mid(a, b));
                    }
                    x
                }
            };
            let x: Vec<[f64; 3]> = corners
                .iter()
                .map(|p| p.map(|c| 1e-3 * (c + 0.08 * next())))
                .collect();
            let g = reference.geometry(&x).unwrap();
            let n = x.len() * FIELDS;
            let local: Vec<f64> = (0..n).map(|_| 1.5e-4 * next()).collect();
            let vel: Vec<f64> = (0..n).map(|_| 1e-2 * next()).collect();
            let eta = 2000.0;
            let mut kq = vec![0.0; n * n];
            cell_viscous_configuration(&g, eta, &local, &vel, &mut kq).unwrap();
            let asym = (0..n)
                .flat_map(|i| (0..n).map(move |j| (i, j)))
                .fold(0.0f64, |m, (i, j)| {
                    m.max((kq[i * n + j] - kq[j * n + i]).abs())
                });
            assert!(asym > 1e-3 * kq.iter().fold(0.0f64, |m, v| m.max(v.abs())));
            check_configuration_tangent(
                &local,
                &kq,
                |j| j % FIELDS != 3,
                |q| {
                    let mut r = vec![0.0; n];
                    cell_viscous(&g, eta, q, &vel, &mut r, None).unwrap();
                    r
                },
            );
            // and the velocity derivative, symmetric
            let mut kv = vec![0.0; n * n];
            cell_viscous(&g, eta, &local, &vel, &mut vec![0.0; n], Some(&mut kv)).unwrap();
            for i in 0..n {
                for j in 0..n {
                    assert_eq!(kv[i * n + j], kv[j * n + i]);
                }
            }
            check_configuration_tangent(
                &vel,
                &kv,
                |j| j % FIELDS != 3,
                |v| {
                    let mut r = vec![0.0; n];
                    cell_viscous(&g, eta, &local, v, &mut r, None).unwrap();
                    r
                },
            );
        }
    }

    /// The viscous configuration tangent of one point formed entry by entry, the form
    /// [`ViscousPoint::add`] reorders: the same bits for every node count.
    #[test]
    fn viscous_point_has_the_bits_of_its_entrywise_form() {
        let mut next = generator();
        for n in [4, 6, 8, 10] {
            let mut h = [[0.0; 3]; MAX_NODES];
            let mut dh = [[0.0; 3]; MAX_NODES];
            let mut lth = [[0.0; 3]; MAX_NODES];
            for a in 0..n {
                for i in 0..3 {
                    (h[a][i], dh[a][i], lth[a][i]) = (1e3 * next(), 1e2 * next(), 1e2 * next());
                }
            }
            let l: [[f64; 3]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| 0.1 * next()));
            let c = 1e-6 * (1.5 + next());
            let nl = n * FIELDS;
            let mut fast = vec![0.0; nl * nl];
            let p = ViscousPoint {
                c,
                h: &h,
                dh: &dh,
                lth: &lth,
                l: &l,
            };
            p.add_cell(n, &mut fast);
            let mut slow = vec![0.0; nl * nl];
            for a in 0..n {
                for b in 0..n {
                    let hab = h[a][0] * h[b][0] + h[a][1] * h[b][1] + h[a][2] * h[b][2];
                    for i in 0..3 {
                        let row = (a * 4 + i) * nl + b * 4;
                        for k in 0..3 {
                            slow[row + k] += c
                                * (h[b][k] * dh[a][i]
                                    - h[a][k] * dh[b][i]
                                    - 0.5 * l[i][k] * hab
                                    - 0.5 * h[b][i] * lth[a][k]);
                        }
                    }
                }
            }
            assert!(slow.iter().any(|v| *v != 0.0));
            assert_eq!(fast, slow, "{n} nodes");
        }
    }

    #[test]
    fn point_tangent_has_the_bits_of_its_entrywise_form() {
        let mut next = generator();
        for n in [4, 6, 8, 10] {
            let mut g = [[0.0; 3]; MAX_NODES];
            g.iter_mut().flatten().for_each(|v| *v = 1e3 * next());
            let a_blk = Mat9::from_fn(|_, _| 1e5 * next());
            let b_blk = Mat93::from_fn(|_, _| 1e-6 * next());
            let g_blk = Mat3::from_fn(|_, _| -1e-11 * next().abs());
            let w = 1e-9 * (1.5 + next());
            let nl = n * FIELDS;
            let start: Vec<f64> = (0..nl * nl).map(|_| next()).collect();
            let (mut fast, mut reference) = (start.clone(), start.clone());
            let (mut potential, mut baseline) = (start.clone(), start.clone());
            for _ in 0..2 {
                add_point_tangent(&g, n, w, &a_blk, &b_blk, &g_blk, &mut fast);
                point_tangent_entrywise(&g, n, w, &a_blk, &b_blk, &g_blk, &mut reference);
                add_point_potential_tangent(&g, n, w, &b_blk, &g_blk, &mut potential);
                // the lanes as compiled for every x86-64 (no AVX2), run directly
                PointTangent {
                    g: &g,
                    n,
                    w,
                    a_blk: Some(&a_blk),
                    b_blk: &b_blk,
                    g_blk: &g_blk,
                    k: &mut baseline,
                }
                .run();
            }
            for (i, ((x, y), z)) in fast.iter().zip(&reference).zip(&baseline).enumerate() {
                assert_eq!(x.to_bits(), y.to_bits(), "n = {n}, entry {i}: {x} vs {y}");
                assert_eq!(x.to_bits(), z.to_bits(), "n = {n}, entry {i} without AVX2");
            }
            // the Φ rows alone: those of the whole, the other rows untouched
            for (i, (x, y)) in potential.iter().zip(&reference).enumerate() {
                let y = if (i / nl) % FIELDS == 3 { y } else { &start[i] };
                assert_eq!(
                    x.to_bits(),
                    y.to_bits(),
                    "n = {n}, Φ rows, entry {i}: {x} vs {y}"
                );
            }
        }
    }
}
