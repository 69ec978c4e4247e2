//! The internal variables of the material points: for every cell, `n_qp × size` values of its
//! material (none for elastic materials). The run commits them after an accepted step; a step
//! that is cut back never touches them. When processes share the cells ([`Model::share`]), each
//! holds and updates its own cells' values only, so that the internal variables of a large
//! viscoelastic model divide among the processes; [`PointStates::merged`] collects every cell's
//! values from its owner (for a checkpoint), [`PointStates::with_data`] takes a process's own
//! part of them back.

use super::model::Model;
use crate::element::{CellHistory, CellInput};
use crate::fem::{CellGeometry, MAX_QP};
use crate::material::{Mat3, PointHistory, Vec3};

/// Committed internal variables of every quadrature point of this process's cells.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointStates {
    /// Start of each cell's values in `data` (length `n_cells + 1`; a cell another process owns
    /// has none); empty when no material has internal variables.
    offsets: Vec<usize>,
    /// Values per point of each material.
    sizes: Vec<usize>,
    /// Each material's initial values at every point of a cell: what a cell without values of
    /// its own (another process's) is evaluated with.
    virgin: Vec<Vec<f64>>,
    pub data: Vec<f64>,
}

impl PointStates {
    /// The points of `model` holding the committed values `data` (laid out as
    /// [`PointStates::data`]; empty: a model without internal variables).
    pub fn from_data(model: &Model, data: &[f64]) -> Self {
        if data.is_empty() {
            return PointStates::default();
        }
        let mut p = PointStates::new(model);
        p.data.copy_from_slice(data);
        p
    }

    /// The virgin state of a model's materials, for this process's own cells.
    pub fn new(model: &Model) -> Self {
        let sizes: Vec<usize> = model.materials.iter().map(|m| m.state_size()).collect();
        if sizes.iter().all(|&s| s == 0) {
            return PointStates::default();
        }
        let n_qp = model.reference.n_qp;
        let virgin: Vec<Vec<f64>> = model
            .materials
            .iter()
            .zip(&sizes)
            .map(|(m, &s)| {
                let mut v = vec![0.0; n_qp * s];
                for q in 0..n_qp {
                    m.initial_state(&mut v[q * s..(q + 1) * s]);
                }
                v
            })
            .collect();
        let offsets = cell_offsets(model, &sizes, |c| model.owns(c));
        let mut data = vec![0.0; *offsets.last().expect("non-empty")];
        for c in 0..model.mesh.n_cells() {
            let range = offsets[c]..offsets[c + 1];
            if !range.is_empty() {
                data[range].copy_from_slice(&virgin[model.cell_material[c]]);
            }
        }
        PointStates {
            offsets,
            sizes,
            virgin,
            data,
        }
    }

    /// A store with this process's part of `whole`, the values of every cell (as
    /// [`PointStates::merged`] gives them: a resumed run's); `None` when the length does not fit
    /// the model.
    pub fn with_data(model: &Model, whole: Vec<f64>) -> Option<Self> {
        let mut s = PointStates::new(model);
        let own = s.own_part(model, &whole)?;
        s.data = own;
        Some(s)
    }

    /// This process's part, in this store's layout, of `whole` (every cell's values); `None`
    /// when `whole` is not of the model's length.
    pub fn own_part(&self, model: &Model, whole: &[f64]) -> Option<Vec<f64>> {
        if self.is_empty() {
            return whole.is_empty().then(Vec::new);
        }
        let every = cell_offsets(model, &self.sizes, |_| true);
        if whole.len() != every.last().copied().unwrap_or(0) {
            return None;
        }
        if model.share.is_none() {
            return Some(whole.to_vec());
        }
        let mut own = vec![0.0; self.data.len()];
        for c in (0..model.mesh.n_cells()).filter(|&c| model.owns(c)) {
            own[self.offsets[c]..self.offsets[c + 1]]
                .copy_from_slice(&whole[every[c]..every[c + 1]]);
        }
        Some(own)
    }

    /// True when no material has internal variables.
    pub fn is_empty(&self) -> bool {
        self.offsets.is_empty()
    }

    /// Where cell `c`'s values lie in `data` (empty for a cell without them here).
    pub fn cell_range(&self, c: usize) -> std::ops::Range<usize> {
        if self.offsets.is_empty() {
            return 0..0;
        }
        self.offsets[c]..self.offsets[c + 1]
    }

    /// The history of cell `c` (of material `m`) for a step of `dt`.
    pub fn cell(&self, c: usize, m: usize, dt: f64) -> CellHistory<'_> {
        if self.offsets.is_empty() {
            return CellHistory {
                dt,
                ..CellHistory::NONE
            };
        }
        let range = self.offsets[c]..self.offsets[c + 1];
        let state = if range.is_empty() {
            // another process's cell: only linear analyses pass over every cell, and they hold
            // a store of their own for every cell
            &self.virgin[m]
        } else {
            &self.data[range]
        };
        CellHistory {
            state,
            size: self.sizes[m],
            dt,
        }
    }

    /// Cell means of every internal variable, by name (the names of all materials, in order of
    /// first appearance; 0 in cells whose material has no such variable): for field output.
    /// Over this process's own cells when processes share the cells (0 in the others'); summed
    /// over the processes for an axisymmetric model, whose revolved view one process writes whole.
    pub fn cell_means(&self, model: &Model) -> Result<Vec<(String, Vec<f64>)>, String> {
        if self.is_empty() {
            return Ok(Vec::new());
        }
        let mut out: Vec<(String, Vec<f64>)> = Vec::new();
        let n_cells = model.mesh.n_cells();
        let mut columns: Vec<Vec<usize>> = Vec::new();
        for mat in &model.materials {
            let mut cols = Vec::new();
            for name in mat.state_names() {
                let i = match out.iter().position(|(n, _)| *n == name) {
                    Some(i) => i,
                    None => {
                        out.push((name, vec![0.0; n_cells]));
                        out.len() - 1
                    }
                };
                cols.push(i);
            }
            columns.push(cols);
        }
        let n_qp = model.reference.n_qp;
        for c in (0..n_cells).filter(|&c| model.owns(c)) {
            let m = model.cell_material[c];
            let s = self.sizes[m];
            let g = model.geometry(c);
            let weights = &g.weights[..n_qp];
            let volume: f64 = weights.iter().sum();
            for (v, &col) in columns[m].iter().enumerate().take(s) {
                let mean: f64 = (0..n_qp)
                    .map(|q| weights[q] * self.data[self.offsets[c] + q * s + v])
                    .sum::<f64>()
                    / volume;
                out[col].1[c] = mean;
            }
        }
        if let Some(share) = model.share.as_deref().filter(|_| model.is_axisymmetric()) {
            let mut all: Vec<f64> = out.iter().flat_map(|(_, v)| v.iter().copied()).collect();
            (share.sum)(&mut all)?;
            for ((_, v), chunk) in out.iter_mut().zip(all.chunks(n_cells)) {
                v.copy_from_slice(chunk);
            }
        }
        Ok(out)
    }

    /// Every cell's values, each from the process that owns the cell (the values themselves
    /// without a share): what a checkpoint holds. Collective when processes share the cells.
    pub fn merged(&self, model: &Model) -> Result<Vec<f64>, String> {
        self.merge(model, &self.data)
    }

    /// [`PointStates::merged`] of values `data` laid out as this store's (a copy kept from
    /// another step); other data is returned as it is.
    pub fn merge(&self, model: &Model, data: &[f64]) -> Result<Vec<f64>, String> {
        let Some(share) = model
            .share
            .as_deref()
            .filter(|_| !self.is_empty() && data.len() == self.data.len())
        else {
            return Ok(data.to_vec());
        };
        // the owner's values plus zeros from the others: the sum is the owner's bits
        let every = cell_offsets(model, &self.sizes, |_| true);
        let mut all = vec![0.0; *every.last().expect("non-empty")];
        for c in (0..model.mesh.n_cells()).filter(|&c| model.owns(c)) {
            all[every[c]..every[c + 1]]
                .copy_from_slice(&data[self.offsets[c]..self.offsets[c + 1]]);
        }
        (share.sum)(&mut all)?;
        Ok(all)
    }

    /// Commits the state of an accepted step to `state` (u, Φ; `FIELDS` per node) over `dt`:
    /// every point's variables are updated from its deformation (this process's own cells'
    /// points when processes share the cells). Returns the energy dissipated (J), summed over
    /// the processes; a cell failing on any process fails the commit on all.
    pub fn commit(&mut self, model: &Model, state: &[f64], dt: f64) -> Result<f64, String> {
        if self.is_empty() {
            return Ok(0.0);
        }
        let mut new = self.data.clone();
        let mut dissipated = [0.0];
        let mut points = [(Mat3::identity(), Vec3::zeros()); MAX_QP];
        let keep = |c: usize| model.owns(c) && self.sizes[model.cell_material[c]] != 0;
        let outcome = model.for_each_cell_where(state, keep, |c, g: &CellGeometry, mat, local| {
            let s = self.sizes[model.cell_material[c]];
            model
                .kernel()
                .point_deformations(
                    &CellInput {
                        geom: g,
                        mat,
                        hist: CellHistory::NONE,
                        local,
                    },
                    &mut points,
                )
                .map_err(|e| (c, format!("cell {c}: {}", e.error)))?;
            for (q, (f, e0)) in points[..g.n_qp].iter().enumerate() {
                let at = self.offsets[c] + q * s;
                let h = PointHistory {
                    state: &self.data[at..at + s],
                    dt,
                };
                dissipated[0] += g.weights[q]
                    * mat
                        .update_state(f, e0, h, &mut new[at..at + s])
                        .map_err(|e| (c, format!("cell {c}, quadrature point {q}: {e}")))?;
            }
            Ok::<(), (usize, String)>(())
        });
        model.sum_over_processes(&mut dissipated, outcome.err())?;
        self.data = new;
        Ok(dissipated[0])
    }
}

/// The transposed derivatives of a commit ξ_{n+1} = U(x, ξ_n, θ, Δt) ([`PointStates::commit`])
/// with a cotangent w of ξ_{n+1}: what the adjoint of a run with internal variables carries
/// back from each accepted step.
#[derive(Debug, Clone, PartialEq)]
pub struct CommitVjp {
    /// wᵀ∂U/∂x over every dof (4 per node), summed over the processes that share the cells.
    pub state: Vec<f64>,
    /// wᵀ∂U/∂ξ_n, laid out as [`PointStates::data`] (this process's cells).
    pub points: Vec<f64>,
    /// wᵀ∂U/∂θ of each material (in the order of its parameter vector; empty for a material
    /// without internal variables), summed over the processes.
    pub theta: Vec<Vec<f64>>,
}

impl PointStates {
    /// [`CommitVjp`] of the commit from these (committed) values to `state` over `dt`, for the
    /// cotangent `w` of the values it gives (laid out as `data`).
    pub fn commit_vjp(
        &self,
        model: &Model,
        state: &[f64],
        dt: f64,
        w: &[f64],
    ) -> Result<CommitVjp, String> {
        let n_mat = model.materials.len();
        let mut out = CommitVjp {
            state: vec![0.0; state.len()],
            points: vec![0.0; self.data.len()],
            theta: vec![Vec::new(); n_mat],
        };
        if self.is_empty() {
            return Ok(out);
        }
        for (m, t) in model.materials.iter().zip(&mut out.theta) {
            if m.state_size() > 0 {
                *t = vec![0.0; m.parameters().map_or(0, |p| p.values.len())];
            }
        }
        let kernel = model.kernel();
        let nl = model.mesh.kind.nodes_per_cell() * crate::fem::FIELDS;
        let mut local_bar = vec![0.0; nl];
        let mut points = [(Mat3::identity(), Vec3::zeros()); MAX_QP];
        let (mut f_bar, mut e_bar) = ([Mat3::zeros(); MAX_QP], [Vec3::zeros(); MAX_QP]);
        let keep = |c: usize| model.owns(c) && self.sizes[model.cell_material[c]] != 0;
        let outcome = model.for_each_cell_where(state, keep, |c, g: &CellGeometry, mat, local| {
            let m = model.cell_material[c];
            let s = self.sizes[m];
            let input = CellInput {
                geom: g,
                mat,
                hist: CellHistory::NONE,
                local,
            };
            kernel
                .point_deformations(&input, &mut points)
                .map_err(|e| (c, format!("cell {c}: {}", e.error)))?;
            for (q, (f, e0)) in points[..g.n_qp].iter().enumerate() {
                let at = self.offsets[c] + q * s;
                let h = PointHistory {
                    state: &self.data[at..at + s],
                    dt,
                };
                let d = mat
                    .update_state_vjp(f, e0, h, &w[at..at + s])
                    .map_err(|e| (c, format!("cell {c}, quadrature point {q}: {e}")))?;
                out.points[at..at + s].copy_from_slice(&d.state);
                out.theta[m]
                    .iter_mut()
                    .zip(&d.theta)
                    .for_each(|(a, b)| *a += b);
                f_bar[q] = d.f;
                e_bar[q] = d.e0;
            }
            crate::element::deformation_vjp::deformation_vjp(
                kernel,
                &input,
                &f_bar[..g.n_qp],
                &e_bar[..g.n_qp],
                &mut local_bar,
            )
            .map_err(|e| {
                (
                    c,
                    format!("cell {c}: {} at quadrature point {}", e.error, e.qp),
                )
            })?;
            for (a, &node) in model.mesh.cell(c).iter().enumerate() {
                for k in 0..crate::fem::FIELDS {
                    out.state[node * crate::fem::FIELDS + k] +=
                        local_bar[a * crate::fem::FIELDS + k];
                }
            }
            Ok::<(), (usize, String)>(())
        });
        let n = out.state.len();
        let mut sums: Vec<f64> = out.state.clone();
        for t in &out.theta {
            sums.extend_from_slice(t);
        }
        model.sum_over_processes(&mut sums, outcome.err())?;
        out.state.copy_from_slice(&sums[..n]);
        let mut at = n;
        for t in &mut out.theta {
            let len = t.len();
            t.copy_from_slice(&sums[at..at + len]);
            at += len;
        }
        Ok(out)
    }
}

/// The start of each cell's values (length `n_cells + 1`) when the cells `holds` accepts have
/// `n_qp × size` values of their material and the others none.
fn cell_offsets(model: &Model, sizes: &[usize], holds: impl Fn(usize) -> bool) -> Vec<usize> {
    let n_qp = model.reference.n_qp;
    let mut offsets = Vec::with_capacity(model.mesh.n_cells() + 1);
    offsets.push(0);
    for c in 0..model.mesh.n_cells() {
        let last = *offsets.last().expect("starts with 0");
        let own = if holds(c) {
            n_qp * sizes[model.cell_material[c]]
        } else {
            0
        };
        offsets.push(last + own);
    }
    offsets
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::registry::{build, preset};
    use crate::mesh::ElementKind;
    use crate::problem::assembly::{on_threads, CellShare};
    use std::sync::Arc;

    /// The film of the examples made of viscoelastic VHB 4910 (three Maxwell branches).
    fn viscous_film() -> Model {
        let mut model = crate::problem::examples::film([3, 3, 2], ElementKind::Hex8, 1000.0)
            .expect("the film builds");
        let (name, p) = preset("vhb4910-wang2016").expect("the preset exists");
        let (material, _) = build(name, &p).expect("the preset builds");
        model.materials = vec![material];
        model.cell_material = vec![0; model.mesh.n_cells()];
        model
    }

    /// The transposed derivatives of a commit against central differences of wᵀ U(x, ξ, θ) in
    /// the state, the committed values and every parameter of the material, for the standard
    /// and the mean-dilatation hex8 (the update reads the kernel's point deformations).
    #[test]
    fn the_commit_vjp_matches_central_differences() {
        for md in [false, true] {
            let mut model = viscous_film();
            if md {
                model.formulation = crate::element::Formulation::MeanDilatation;
            }
            let x = crate::problem::examples::wavy_state(&model, 3e-2, 2e-6, 500.0);
            let dt = 0.07;
            // committed values away from the identity: one commit from the virgin state
            let mut start = PointStates::new(&model);
            let half: Vec<f64> = x.iter().map(|v| 0.6 * v).collect();
            start.commit(&model, &half, 0.3).unwrap();
            let w: Vec<f64> = (0..start.data.len())
                .map(|i| ((i * 7919 % 101) as f64 / 101.0) - 0.5)
                .collect();
            let value = |model: &Model, x: &[f64], points: &PointStates| {
                let mut p = points.clone();
                p.commit(model, x, dt).unwrap();
                p.data.iter().zip(&w).map(|(a, b)| a * b).sum::<f64>()
            };
            let vjp = start.commit_vjp(&model, &x, dt, &w).unwrap();
            let scale = vjp.state.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(scale > 0.0);
            for d in (0..x.len()).step_by(7) {
                let h = 1e-9;
                let (mut p, mut m) = (x.clone(), x.clone());
                p[d] += h;
                m[d] -= h;
                let fd = (value(&model, &p, &start) - value(&model, &m, &start)) / (2.0 * h);
                assert!(
                    (vjp.state[d] - fd).abs() <= 1e-6 * scale,
                    "md {md}, dof {d}: {} against {fd}",
                    vjp.state[d]
                );
            }
            for i in (0..start.data.len()).step_by(13) {
                let h = 1e-6;
                let (mut p, mut m) = (start.clone(), start.clone());
                p.data[i] += h;
                m.data[i] -= h;
                let fd = (value(&model, &x, &p) - value(&model, &x, &m)) / (2.0 * h);
                assert!(
                    (vjp.points[i] - fd).abs() <= 1e-8 * (1.0 + fd.abs()),
                    "md {md}, value {i}: {} against {fd}",
                    vjp.points[i]
                );
            }
            let theta = model.materials[0].parameters().unwrap();
            assert_eq!(vjp.theta[0].len(), theta.values.len());
            // (a coefficient that is 0, c₁ or c₂ of the dielectric, has no relative step)
            for (k, name) in theta.names.iter().enumerate() {
                if theta.values[k] == 0.0 {
                    continue;
                }
                // a relative step of 10⁻⁴: the sum's round-off (10⁻¹⁴ of values of order 10)
                // over a smaller step would exceed the tolerance
                let h = 1e-4 * theta.values[k].abs();
                let at = |v: f64| {
                    let mut t = theta.values.clone();
                    t[k] = v;
                    let mut m = model.clone();
                    m.materials = vec![model.materials[0].with_parameters(&t).unwrap()];
                    value(&m, &x, &start)
                };
                let fd = (at(theta.values[k] + h) - at(theta.values[k] - h)) / (2.0 * h);
                let size = vjp.theta[0]
                    .iter()
                    .zip(&theta.values)
                    .fold(0.0f64, |m, (g, v)| m.max((g * v).abs()));
                assert!(
                    ((vjp.theta[0][k] - fd) * theta.values[k]).abs() <= 1e-6 * size,
                    "md {md}, {name}: {} against {fd}",
                    vjp.theta[0][k]
                );
            }
        }
    }

    /// Processes that share the cells each update their own cells' points: the energy they
    /// dissipate is summed to what one process dissipates, and the merged values are one
    /// process's, cell by cell (two steps, so that a stale value would show).
    #[test]
    fn processes_sharing_the_cells_commit_what_one_commits() {
        let model = viscous_film();
        // a stretch of 2 % with a wave that varies from cell to cell, and a potential
        let state = crate::problem::examples::wavy_state(&model, 2e-2, 1e-6, 500.0);
        let half: Vec<f64> = state.iter().map(|v| 0.5 * v).collect();
        let mut whole = PointStates::new(&model);
        assert!(!whole.is_empty());
        let serial = [
            whole.commit(&model, &half, 0.05).unwrap(),
            whole.commit(&model, &state, 0.05).unwrap(),
        ];
        assert!(serial.iter().all(|&w| w > 0.0), "{serial:?}");
        let n = model.mesh.n_cells();
        for size in [2, 3] {
            let parts = on_threads(size, |rank, sum| {
                let mut m = model.clone();
                m.share = Some(Arc::new(CellShare {
                    part: (0..n).map(|c| c * size / n).collect(),
                    rank,
                    size,
                    sum,
                }));
                let mut points = PointStates::new(&m);
                let dissipated = [
                    points.commit(&m, &half, 0.05).unwrap(),
                    points.commit(&m, &state, 0.05).unwrap(),
                ];
                let means = points.cell_means(&m).unwrap();
                let merged = points.merged(&m).unwrap();
                // a resumed store takes its own part of the merged values back
                let resumed = PointStates::with_data(&m, merged.clone()).unwrap();
                assert_eq!(resumed, points, "{size} processes, rank {rank}");
                (dissipated, merged, means, points.data.len())
            });
            let whole_means = whole.cell_means(&model).unwrap();
            // each process holds its own cells' values only
            let own: Vec<usize> = parts.iter().map(|p| p.3).collect();
            assert_eq!(own.iter().sum::<usize>(), whole.data.len(), "{own:?}");
            assert!(own.iter().all(|&l| l < whole.data.len()), "{own:?}");
            for (rank, (dissipated, merged, means, _)) in parts.iter().enumerate() {
                for (a, b) in dissipated.iter().zip(&serial) {
                    assert!((a - b).abs() <= 1e-13 * b, "{size}: {a} against {b}");
                }
                assert_eq!(dissipated, &parts[0].0, "the same bits on every process");
                assert_eq!(merged, &whole.data, "{size} processes, rank {rank}");
                // a 3-D model's means: this process's cells only
                for ((name, v), (_, w)) in means.iter().zip(&whole_means) {
                    for c in 0..n {
                        let expected = if c * size / n == rank { w[c] } else { 0.0 };
                        assert_eq!(v[c], expected, "{name}, cell {c}");
                    }
                }
            }
        }
    }
}
