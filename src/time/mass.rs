//! The mass matrix M = ∫ρ₀ N_a N_b dV of the displacements (the potential has no mass), stored at
//! node level (m_ab, the same for the three components), consistent or lumped.
//!
//! Lumping: row sums for hex8 and tet4. The row sums of the quadratic tetrahedron are negative at
//! its corners (−ρV/20), so tet10 is lumped by HRZ diagonal scaling (Hinton, Rock & Zienkiewicz
//! 1976): m_aa = M_aa · ρV / Σ_b M_bb, positive, with the cell's total mass. Tet10 masses are
//! integrated with a degree-5 rule: the element's 4-point rule is not exact for N_aN_b (degree 4)
//! and would give a singular matrix.

use crate::algebra::exchange::{Exchange, LocalEquations};
use crate::mesh::Mesh;
use crate::problem::dofs::{DofMap, CONSTRAINED};
use crate::problem::model::Model;

/// Node-level mass matrix in CSR form (kg).
#[derive(Debug, Clone)]
pub struct NodalMass {
    pub row_ptr: Vec<usize>,
    pub col_idx: Vec<usize>,
    pub values: Vec<f64>,
}

/// How the mass is distributed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum MassKind {
    Consistent,
    /// Diagonal: row sums (hex8, tet4) or HRZ scaling (tet10).
    Lumped,
}

fn node_pattern(mesh: &Mesh) -> (Vec<usize>, Vec<usize>) {
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); mesh.n_nodes()];
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        for &a in cell {
            adj[a].extend_from_slice(cell);
        }
    }
    let mut row_ptr = vec![0];
    let mut col_idx = Vec::new();
    for mut a in adj {
        a.sort_unstable();
        a.dedup();
        col_idx.extend(a);
        row_ptr.push(col_idx.len());
    }
    (row_ptr, col_idx)
}

/// Consistent mass ∫ρ N_a N_b dV (kg) of a tet10 cell with node coordinates `x`, by the degree-5
/// rule (exact for straight-sided cells).
fn tet10_cell_mass(x: &[[f64; 3]], rho: f64) -> [[f64; 10]; 10] {
    use crate::fem::{shape_functions, tet_rule_degree5};
    let mut m = [[0.0; 10]; 10];
    for (xi, w) in tet_rule_degree5() {
        let (n, dn) = shape_functions(crate::mesh::ElementKind::Tet10, xi);
        let mut jac = crate::material::Mat3::zeros();
        for a in 0..10 {
            for i in 0..3 {
                for j in 0..3 {
                    jac[(i, j)] += x[a][i] * dn[a][j];
                }
            }
        }
        let dv = rho * w * jac.determinant().abs();
        for a in 0..10 {
            for b in 0..10 {
                m[a][b] += dv * n[a] * n[b];
            }
        }
    }
    m
}

/// Consistent mass ∫ρ N_a N_b 2πR dA (kg, whole ring) of a meridian cell with nodes `x` =
/// (R, Z, ·): Gauss rules of 3 × 3 (quad4) and 4 × 4 points (quad8, quad9), exact for
/// N_a N_b R on parallelograms, and Dunavant's degree-4 rule on triangles (exact for tri3, an
/// approximation of degree 4 of the degree-6 integrand of tri6).
fn meridian_cell_mass(kind: crate::mesh::MeridianKind, x: &[[f64; 3]], rho: f64) -> Vec<Vec<f64>> {
    use crate::fem::axisymmetric::meridian_shape_functions;
    use crate::mesh::MeridianKind as K;
    let n = kind.nodes_per_cell();
    let line = |k: usize| -> Vec<(f64, f64)> {
        match k {
            3 => {
                let g = 0.6f64.sqrt();
                vec![(-g, 5.0 / 9.0), (0.0, 8.0 / 9.0), (g, 5.0 / 9.0)]
            }
            _ => crate::problem::faces::side_points(3),
        }
    };
    let rule: Vec<([f64; 2], f64)> = match kind {
        K::Quad4 | K::Quad8 | K::Quad9 => {
            let l = line(if kind == K::Quad4 { 3 } else { 4 });
            l.iter()
                .flat_map(|&(a, wa)| l.iter().map(move |&(b, wb)| ([b, a], wa * wb)))
                .collect()
        }
        K::Tri3 | K::Tri6 => crate::problem::faces::points(6)
            .into_iter()
            .map(|(a, b, w)| ([a, b], w))
            .collect(),
    };
    let mut m = vec![vec![0.0; n]; n];
    for (xi, w) in rule {
        let (nv, dn) = meridian_shape_functions(kind, xi);
        let (mut r, mut j) = (0.0, [[0.0; 2]; 2]);
        for a in 0..n {
            r += nv[a] * x[a][0];
            for i in 0..2 {
                for k in 0..2 {
                    j[i][k] += x[a][i] * dn[a][k];
                }
            }
        }
        let dv = rho
            * w
            * 2.0
            * std::f64::consts::PI
            * r
            * (j[0][0] * j[1][1] - j[0][1] * j[1][0]).abs();
        for a in 0..n {
            for b in 0..n {
                m[a][b] += dv * nv[a] * nv[b];
            }
        }
    }
    m
}

impl NodalMass {
    /// Assembles the mass of a model with the density of each material (kg/m³).
    pub fn new(model: &Model, densities: &[f64], kind: MassKind) -> Self {
        let mesh = &model.mesh;
        let (row_ptr, col_idx) = match kind {
            MassKind::Consistent => node_pattern(mesh),
            MassKind::Lumped => (
                (0..=mesh.n_nodes()).collect(),
                (0..mesh.n_nodes()).collect(),
            ),
        };
        let mut m = NodalMass {
            values: vec![0.0; col_idx.len()],
            row_ptr,
            col_idx,
        };
        let re = &model.reference;
        let npc = mesh.kind.nodes_per_cell();
        let mut x = vec![[0.0; 3]; npc];
        for c in 0..mesh.n_cells() {
            let rho = densities[model.cell_material[c]];
            if rho == 0.0 {
                continue;
            }
            mesh.cell_coords_into(c, &mut x);
            let Ok(g) = re.geometry(&x) else { continue };
            let cell = mesh.cell(c);
            if mesh.kind == crate::mesh::ElementKind::Tet4 {
                // exact consistent mass of the linear tetrahedron, ρV/20 (1 + δ_ab) (its one-point
                // stiffness quadrature would give a singular mass matrix)
                let vol = g.weights[..g.n_qp].iter().sum::<f64>();
                for a in 0..npc {
                    for b in 0..npc {
                        let v = rho * vol / 20.0 * if a == b { 2.0 } else { 1.0 };
                        match kind {
                            MassKind::Consistent => m.add(cell[a], cell[b], v),
                            MassKind::Lumped => m.add(cell[a], cell[a], v),
                        }
                    }
                }
                continue;
            }
            if mesh.kind == crate::mesh::ElementKind::Tet10 {
                let mc = tet10_cell_mass(&x, rho);
                let diag: f64 = (0..10).map(|a| mc[a][a]).sum();
                let total: f64 = mc.iter().flatten().sum();
                for a in 0..10 {
                    match kind {
                        MassKind::Consistent => {
                            for b in 0..10 {
                                m.add(cell[a], cell[b], mc[a][b]);
                            }
                        }
                        MassKind::Lumped => m.add(cell[a], cell[a], mc[a][a] * total / diag),
                    }
                }
                continue;
            }
            if let crate::mesh::ElementKind::Meridian(mk) = mesh.kind {
                let mc = meridian_cell_mass(mk, &x, rho);
                let diag: f64 = (0..npc).map(|a| mc[a][a]).sum();
                let total: f64 = mc.iter().flatten().sum();
                for a in 0..npc {
                    match kind {
                        MassKind::Consistent => {
                            for b in 0..npc {
                                m.add(cell[a], cell[b], mc[a][b]);
                            }
                        }
                        // HRZ: row sums vanish at the corners of tri6 and are negative at
                        // those of quad8
                        MassKind::Lumped => m.add(cell[a], cell[a], mc[a][a] * total / diag),
                    }
                }
                continue;
            }
            for q in 0..g.n_qp {
                let w = rho * g.weights[q];
                for a in 0..npc {
                    for b in 0..npc {
                        let v = w * re.n[q][a] * re.n[q][b];
                        match kind {
                            MassKind::Consistent => m.add(cell[a], cell[b], v),
                            MassKind::Lumped => m.add(cell[a], cell[a], v),
                        }
                    }
                }
            }
        }
        m
    }

    fn add(&mut self, a: usize, b: usize, v: f64) {
        let cols = &self.col_idx[self.row_ptr[a]..self.row_ptr[a + 1]];
        let p = cols
            .binary_search(&b)
            .expect("pattern holds every cell coupling");
        self.values[self.row_ptr[a] + p] += v;
    }

    /// Adds a point mass (kg) to a node.
    pub fn add_point_mass(&mut self, node: usize, mass: f64) {
        self.add(node, node, mass);
    }

    /// y_u = M x_u for a state vector with 4 values per node (the potential entries of y are 0).
    pub fn mul(&self, x: &[f64], y: &mut [f64]) {
        for a in 0..self.row_ptr.len() - 1 {
            let mut s = [0.0; 3];
            for p in self.row_ptr[a]..self.row_ptr[a + 1] {
                let b = self.col_idx[p];
                let m = self.values[p];
                for i in 0..3 {
                    s[i] += m * x[b * 4 + i];
                }
            }
            y[a * 4..a * 4 + 3].copy_from_slice(&s);
            y[a * 4 + 3] = 0.0;
        }
    }

    /// Total mass (kg).
    pub fn total(&self) -> f64 {
        self.values.iter().sum()
    }
}

impl NodalMass {
    /// Solves the reduced system (PᵀMP) y = Pᵀb over the free displacement equations of `dofs`
    /// (P maps equations to dofs; tied dofs share an equation) and returns x = P y, 4 values per
    /// node (constrained and potential entries 0). Conjugate gradients with the diagonal as
    /// preconditioner: the consistent mass matrix is well conditioned, so a few dozen iterations
    /// reach `rtol`.
    pub fn solve(&self, b: &[f64], dofs: &DofMap, rtol: f64) -> Vec<f64> {
        match self.solve_on(b, dofs, rtol, None) {
            Ok(x) => x,
            Err(e) => unreachable!("a solve without exchanges cannot fail: {e}"),
        }
    }

    /// [`NodalMass::solve`], on a rank's part of the mesh when `part` gives the rank's equations
    /// and the exchange between the ranks (collective): this mass and `b` are the part's shares
    /// (its cells' masses, its forces), the equations' sums are taken by their owners, the dot
    /// products over the owned equations summed over the ranks, and every rank returns the
    /// solution at its own nodes.
    pub fn solve_on(
        &self,
        b: &[f64],
        dofs: &DofMap,
        rtol: f64,
        part: Option<(&LocalEquations, &dyn Exchange)>,
    ) -> Result<Vec<f64>, String> {
        let n = b.len();
        let ne = dofs.n_free;
        let is_u = |d: usize| d % 4 != 3 && dofs.eq[d] != CONSTRAINED;
        let owned: Vec<bool> = part.map_or_else(|| vec![true; ne], |(eq, _)| eq.owned.clone());
        // the owners' sums of the ranks' shares, the owners' values at the ghosts, a sum
        let combine = |v: &mut [f64]| part.map_or(Ok(()), |(_, x)| x.add_to_owners(v));
        let spread = |v: &mut [f64]| part.map_or(Ok(()), |(_, x)| x.to_ghosts(v));
        let dot = |a: &[f64], b: &[f64]| -> Result<f64, String> {
            let mut s = [(0..ne)
                .filter(|&e| owned[e])
                .map(|e| a[e] * b[e])
                .sum::<f64>()];
            part.map_or(Ok(()), |(_, x)| x.sum(&mut s))?;
            Ok(s[0])
        };
        // Pᵀ v (equation space, the owners' sums) and P y (dof space)
        let restrict = |v: &[f64], out: &mut [f64]| {
            out.iter_mut().for_each(|x| *x = 0.0);
            for d in 0..n {
                if is_u(d) {
                    out[dofs.eq[d]] += v[d];
                }
            }
            combine(out)
        };
        let prolong = |y: &[f64], out: &mut [f64]| {
            for d in 0..n {
                out[d] = if is_u(d) { y[dofs.eq[d]] } else { 0.0 };
            }
        };
        let mut diag_dof = vec![0.0; n];
        for a in 0..n / 4 {
            for p in self.row_ptr[a]..self.row_ptr[a + 1] {
                if self.col_idx[p] == a {
                    diag_dof[a * 4..a * 4 + 3]
                        .iter_mut()
                        .for_each(|m| *m = self.values[p]);
                }
            }
        }
        let mut diag = vec![0.0; ne];
        restrict(&diag_dof, &mut diag)?;
        let precond = |r: &[f64], z: &mut [f64]| {
            for e in 0..ne {
                z[e] = if diag[e] > 0.0 { r[e] / diag[e] } else { 0.0 };
            }
        };
        let (mut full, mut mfull, mut spread_y) = (vec![0.0; n], vec![0.0; n], vec![0.0; ne]);
        let mut apply = |y: &[f64], out: &mut [f64]| {
            spread_y.copy_from_slice(y);
            spread(&mut spread_y)?;
            prolong(&spread_y, &mut full);
            self.mul(&full, &mut mfull);
            restrict(&mfull, out)
        };
        let mut y = vec![0.0; ne];
        let mut r = vec![0.0; ne];
        restrict(b, &mut r)?;
        let norm0 = dot(&r, &r)?.sqrt();
        let mut x = vec![0.0; n];
        if norm0 == 0.0 {
            return Ok(x);
        }
        let mut z = vec![0.0; ne];
        precond(&r, &mut z);
        let mut p = z.clone();
        let mut rz = dot(&r, &z)?;
        let mut ap = vec![0.0; ne];
        let n_all = part.map_or(ne, |(eq, _)| eq.n_global());
        for _ in 0..10 * n_all.max(10) {
            apply(&p, &mut ap)?;
            let pap = dot(&p, &ap)?;
            if pap <= 0.0 {
                break;
            }
            let alpha = rz / pap;
            for e in 0..ne {
                y[e] += alpha * p[e];
                r[e] -= alpha * ap[e];
            }
            if dot(&r, &r)?.sqrt() <= rtol * norm0 {
                break;
            }
            precond(&r, &mut z);
            let rz_new = dot(&r, &z)?;
            let beta = rz_new / rz;
            rz = rz_new;
            for e in 0..ne {
                p[e] = z[e] + beta * p[e];
            }
        }
        spread(&mut y)?;
        prolong(&y, &mut x);
        Ok(x)
    }
}

impl NodalMass {
    /// (position in a tangent, index into `values`) of every coupling between free displacement
    /// dofs that `position` (equations → position) places, to add the mass to the tangent
    /// without searching.
    pub fn positions_in(
        &self,
        dofs: &crate::problem::dofs::DofMap,
        position: impl Fn(usize, usize) -> Option<usize>,
    ) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        for a in 0..self.row_ptr.len() - 1 {
            for p in self.row_ptr[a]..self.row_ptr[a + 1] {
                let b = self.col_idx[p];
                for i in 0..3 {
                    let (ea, eb) = (dofs.eq[a * 4 + i], dofs.eq[b * 4 + i]);
                    if ea != crate::problem::dofs::CONSTRAINED
                        && eb != crate::problem::dofs::CONSTRAINED
                    {
                        if let Some(pos) = position(ea, eb) {
                            out.push((pos, p));
                        }
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::ElectroNeoHooke;
    use crate::mesh::{generate::box_mesh, ElementKind};
    use std::sync::Arc;

    /// An exchange whose sums reach the owners only: the ghosts' entries become NaN, as no
    /// distributed vector promises them (a solve must send the owners' values to the ghosts).
    struct OwnersOnly(crate::algebra::exchange::SumExchange, Vec<bool>);

    impl Exchange for OwnersOnly {
        fn add_to_owners(&self, local: &mut [f64]) -> Result<(), String> {
            self.0.add_to_owners(local)?;
            for (x, &owned) in local.iter_mut().zip(&self.1) {
                if !owned {
                    *x = f64::NAN;
                }
            }
            Ok(())
        }
        fn to_ghosts(&self, local: &mut [f64]) -> Result<(), String> {
            self.0.to_ghosts(local)
        }
        fn sum(&self, values: &mut [f64]) -> Result<(), String> {
            self.0.sum(values)
        }
    }

    /// On 2 and 3 ranks simulated by threads, each holding its part of the mesh (its cells'
    /// mass, its owned nodes' share of the right-hand side), the solve over the ranks gives the
    /// whole solve at every node of every part, with a tie across the partition's cut.
    #[test]
    fn the_solve_over_the_ranks_parts_is_the_whole_solve() {
        use crate::algebra::exchange::{LocalEquations, SumExchange};
        use crate::mesh::distribute::{LocalMesh, Numbering};
        use crate::problem::assembly::{node_processes, on_threads};
        use crate::problem::distributed::equation_owners;
        use crate::problem::dofs::{Field, Tie};
        let material = Arc::new(ElectroNeoHooke::new(1.0, 1.0, 1.0));
        for mk in [MassKind::Consistent, MassKind::Lumped] {
            let mesh = box_mesh([2.0, 1.0, 0.5], [6, 4, 2], ElementKind::Hex8);
            let n = mesh.n_nodes() * 4;
            let tie = |nodes: Vec<usize>| Tie {
                nodes,
                field: Field::Uz,
                held: false,
            };
            let face = mesh.set_nodes("x1").unwrap();
            // the x = 0 face's x displacement held
            let mut held = vec![false; n];
            for &node in &mesh.set_nodes("x0").unwrap() {
                held[node * 4] = true;
            }
            let whole_dofs = DofMap::with_ties(n / 4, &held, 1.0, &[tie(face.clone())]);
            let model = Model::new(mesh.clone(), material.clone()).unwrap();
            let whole_mass = NodalMass::new(&model, &[7.0], mk);
            let b: Vec<f64> = (0..n).map(|d| ((d * 7) % 13) as f64 - 6.0).collect();
            let whole = whole_mass.solve(&b, &whole_dofs, 1e-13);
            let scale = whole.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for ranks in [2, 3] {
                let cells = crate::mesh::partition::partition_cells(&mesh, ranks, None);
                let owner = node_processes(&mesh, &whole_dofs, &cells, ranks);
                let numbering = Numbering::contiguous(&equation_owners(&whole_dofs, &owner), ranks);
                let parts = on_threads(ranks, |rank, sum| {
                    let local = LocalMesh::of_rank(&mesh, &cells, &owner, rank, ranks).unwrap();
                    let nl = local.nodes.len();
                    let at = |g: usize| local.nodes.iter().position(|&l| l == g);
                    let local_face: Vec<usize> = face.iter().filter_map(|&g| at(g)).collect();
                    let local_held: Vec<bool> = local
                        .nodes
                        .iter()
                        .flat_map(|&g| held[g * 4..(g + 1) * 4].to_vec())
                        .collect();
                    let dofs = DofMap::with_ties(nl, &local_held, 1.0, &[tie(local_face)]);
                    let equations = Arc::new(
                        LocalEquations::new(&whole_dofs, &numbering, &local, &dofs).unwrap(),
                    );
                    let exchange = OwnersOnly(
                        SumExchange::new(Arc::clone(&equations), sum),
                        equations.owned.clone(),
                    );
                    let part_model = Model::new(local.mesh.clone(), material.clone()).unwrap();
                    let mass = NodalMass::new(&part_model, &[7.0], mk);
                    // the owned nodes' forces: each acts once over the ranks
                    let share: Vec<f64> = (0..nl * 4)
                        .map(|d| {
                            if d / 4 < local.owned {
                                b[local.nodes[d / 4] * 4 + d % 4]
                            } else {
                                0.0
                            }
                        })
                        .collect();
                    let x = mass
                        .solve_on(&share, &dofs, 1e-13, Some((&equations, &exchange)))
                        .unwrap();
                    (local.nodes.clone(), x)
                });
                for (rank, (nodes, x)) in parts.iter().enumerate() {
                    for (l, &g) in nodes.iter().enumerate() {
                        for f in 0..4 {
                            let (a, e) = (x[l * 4 + f], whole[g * 4 + f]);
                            assert!(
                                (a - e).abs() <= 1e-10 * scale,
                                "{mk:?}, {ranks} ranks, rank {rank}, node {g}, field {f}: \
                                 {a:e} against {e:e}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn mass_totals_and_solve() {
        for kind in [ElementKind::Hex8, ElementKind::Tet4, ElementKind::Tet10] {
            let mesh = box_mesh([2.0, 1.0, 0.5], [3, 2, 2], kind);
            let model = Model::new(mesh, Arc::new(ElectroNeoHooke::new(1.0, 1.0, 1.0))).unwrap();
            for mk in [MassKind::Consistent, MassKind::Lumped] {
                let m = NodalMass::new(&model, &[7.0], mk);
                // a rigid translation: Σ (M v) = total mass × v
                assert!((m.total() - 7.0).abs() < 1e-12, "{kind:?} {mk:?}");
                let n = model.mesh.n_nodes() * 4;
                let b: Vec<f64> = (0..n)
                    .map(|d| {
                        if d % 4 == 3 {
                            0.0
                        } else {
                            ((d * 7) % 13) as f64 - 6.0
                        }
                    })
                    .collect();
                let dofs = DofMap::new(n / 4, &vec![false; n], 1.0);
                let x = m.solve(&b, &dofs, 1e-13);
                let mut mx = vec![0.0; n];
                m.mul(&x, &mut mx);
                for d in 0..n {
                    assert!((mx[d] - b[d]).abs() < 1e-9, "{kind:?} {mk:?}");
                }
                // tied uz of the x = 0 face: one common value, and the summed equation holds
                let face = model.mesh.set_nodes("x0").unwrap();
                let tie = crate::problem::dofs::Tie {
                    nodes: face.clone(),
                    field: crate::problem::dofs::Field::Uz,
                    held: false,
                };
                let mut flags = vec![false; n];
                flags[0] = true; // node 0 (on x0) holds ux: the tie on uz is unaffected
                let tied = DofMap::with_ties(n / 4, &flags, 1.0, &[tie]);
                assert_eq!(tied.n_free, n - 1 - (face.len() - 1));
                let x = m.solve(&b, &tied, 1e-13);
                m.mul(&x, &mut mx);
                let uz = x[face[0] * 4 + 2];
                let mut sum = 0.0;
                for &node in &face {
                    assert_eq!(x[node * 4 + 2], uz);
                    sum += mx[node * 4 + 2] - b[node * 4 + 2];
                }
                assert!(sum.abs() < 1e-9, "{kind:?} {mk:?}: {sum}");
                assert_eq!(x[0], 0.0);
                for d in 1..n {
                    let in_tie = d % 4 == 2 && face.contains(&(d / 4));
                    if d % 4 != 3 && !in_tie {
                        assert!((mx[d] - b[d]).abs() < 1e-9, "{kind:?} {mk:?} dof {d}");
                    }
                }
            }
        }
    }

    /// The tet10 consistent mass of a straight-sided cell against its closed form ρV/420 ×
    /// (6 corner diagonal, 1 corner–corner, −4 corner–adjacent edge, −6 corner–opposite edge,
    /// 32 edge diagonal, 16 edges sharing a corner, 8 opposite edges); the HRZ lumped masses are
    /// positive and sum to ρV.
    #[test]
    fn tet10_mass_closed_form_and_hrz() {
        use crate::fem::TET10_EDGES;
        let c = [
            [0.1, 0.0, 0.2],
            [1.3, 0.1, 0.0],
            [0.2, 1.1, 0.1],
            [0.0, 0.3, 0.9],
        ];
        let mut x = c.to_vec();
        for [i, j] in TET10_EDGES {
            x.push([0, 1, 2].map(|k| 0.5 * (c[i][k] + c[j][k])));
        }
        let e = |a: usize, b: usize| [0, 1, 2].map(|k| c[b][k] - c[a][k]);
        let (a, b, d) = (e(0, 1), e(0, 2), e(0, 3));
        let vol = (a[0] * (b[1] * d[2] - b[2] * d[1]) - a[1] * (b[0] * d[2] - b[2] * d[0])
            + a[2] * (b[0] * d[1] - b[1] * d[0]))
            / 6.0;
        let rho = 3.0;
        let m = tet10_cell_mass(&x, rho);
        let ends = |n: usize| TET10_EDGES[n - 4];
        for p in 0..10 {
            for q in 0..10 {
                let k = match (p < 4, q < 4) {
                    (true, true) => {
                        if p == q {
                            6.0
                        } else {
                            1.0
                        }
                    }
                    (true, false) | (false, true) => {
                        let (v, ed) = if p < 4 { (p, ends(q)) } else { (q, ends(p)) };
                        if ed.contains(&v) {
                            -4.0
                        } else {
                            -6.0
                        }
                    }
                    (false, false) => {
                        let (e1, e2) = (ends(p), ends(q));
                        if p == q {
                            32.0
                        } else if e1.iter().any(|v| e2.contains(v)) {
                            16.0
                        } else {
                            8.0
                        }
                    }
                };
                let expect = rho * vol * k / 420.0;
                assert!((m[p][q] - expect).abs() < 1e-13 * rho * vol, "({p},{q})");
            }
        }
        let mesh = box_mesh([2.0, 1.0, 0.5], [2, 1, 1], ElementKind::Tet10);
        let model = Model::new(mesh, Arc::new(ElectroNeoHooke::new(1.0, 1.0, 1.0))).unwrap();
        let lumped = NodalMass::new(&model, &[7.0], MassKind::Lumped);
        assert!(lumped.values.iter().all(|&v| v > 0.0));
        assert!((lumped.total() - 7.0).abs() < 1e-12);
    }
}
