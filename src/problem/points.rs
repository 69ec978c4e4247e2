//! The internal variables of the material points: for every cell, `n_qp × size` values of its
//! material (none for elastic materials). The run commits them after an accepted step; a step
//! that is cut back never touches them.

use super::model::Model;
use crate::element::{CellHistory, CellInput};
use crate::fem::{CellGeometry, MAX_QP};
use crate::material::{Mat3, PointHistory, Vec3};

/// Committed internal variables of every quadrature point.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointStates {
    /// Start of each cell's values in `data` (length `n_cells + 1`); empty when no material has
    /// internal variables.
    offsets: Vec<usize>,
    /// Values per point of each material.
    sizes: Vec<usize>,
    pub data: Vec<f64>,
}

impl PointStates {
    /// The virgin state of a model's materials.
    pub fn new(model: &Model) -> Self {
        let sizes: Vec<usize> = model.materials.iter().map(|m| m.state_size()).collect();
        if sizes.iter().all(|&s| s == 0) {
            return PointStates::default();
        }
        let n_qp = model.reference.n_qp;
        let mut offsets = Vec::with_capacity(model.mesh.n_cells() + 1);
        offsets.push(0);
        for c in 0..model.mesh.n_cells() {
            let last = *offsets.last().expect("starts with 0");
            offsets.push(last + n_qp * sizes[model.cell_material[c]]);
        }
        let mut data = vec![0.0; *offsets.last().expect("non-empty")];
        for c in 0..model.mesh.n_cells() {
            let m = model.cell_material[c];
            let s = sizes[m];
            for q in 0..n_qp {
                let at = offsets[c] + q * s;
                model.materials[m].initial_state(&mut data[at..at + s]);
            }
        }
        PointStates {
            offsets,
            sizes,
            data,
        }
    }

    /// A store with these values (a resumed run); `None` when the length does not fit the model.
    pub fn with_data(model: &Model, data: Vec<f64>) -> Option<Self> {
        let mut s = PointStates::new(model);
        (s.data.len() == data.len()).then(|| {
            s.data = data;
            s
        })
    }

    /// True when no material has internal variables.
    pub fn is_empty(&self) -> bool {
        self.offsets.is_empty()
    }

    /// The history of cell `c` (of material `m`) for a step of `dt`.
    pub fn cell(&self, c: usize, m: usize, dt: f64) -> CellHistory<'_> {
        if self.offsets.is_empty() {
            return CellHistory {
                dt,
                ..CellHistory::NONE
            };
        }
        CellHistory {
            state: &self.data[self.offsets[c]..self.offsets[c + 1]],
            size: self.sizes[m],
            dt,
        }
    }

    /// Cell means of every internal variable, by name (the names of all materials, in order of
    /// first appearance; 0 in cells whose material has no such variable): for field output.
    pub fn cell_means(&self, model: &Model) -> Vec<(String, Vec<f64>)> {
        if self.is_empty() {
            return Vec::new();
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
        for c in 0..n_cells {
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
        out
    }

    /// Commits the state of an accepted step to `state` (u, Φ; `FIELDS` per node) over `dt`:
    /// every point's variables are updated from its deformation. Returns the energy dissipated
    /// (J).
    pub fn commit(&mut self, model: &Model, state: &[f64], dt: f64) -> Result<f64, String> {
        if self.is_empty() {
            return Ok(0.0);
        }
        let mut new = self.data.clone();
        let mut dissipated = 0.0;
        let mut points = [(Mat3::identity(), Vec3::zeros()); MAX_QP];
        model.for_each_cell(state, |c, g: &CellGeometry, mat, local| {
            let m = model.cell_material[c];
            let s = self.sizes[m];
            if s == 0 {
                return Ok(());
            }
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
                .map_err(|e| format!("cell {c}: {}", e.error))?;
            for (q, (f, e0)) in points[..g.n_qp].iter().enumerate() {
                let at = self.offsets[c] + q * s;
                let h = PointHistory {
                    state: &self.data[at..at + s],
                    dt,
                };
                dissipated += g.weights[q]
                    * mat
                        .update_state(f, e0, h, &mut new[at..at + s])
                        .map_err(|e| format!("cell {c}, quadrature point {q}: {e}"))?;
            }
            Ok::<(), String>(())
        })?;
        self.data = new;
        Ok(dissipated)
    }
}
