//! The cells' tangents of the last evaluation with a matrix, kept for the transposed products
//! of a discrete adjoint at the same point: the adjoint solves with the step's Jacobian and then
//! needs wᵀ∂R/∂· of the same cell matrices, which would otherwise cost a second pass of cell
//! tangents (the dearest part of an adjoint step). They take nl²·8 bytes a cell (8 kB for a
//! hex8; a quarter for a projection's, which keeps its potential rows alone), so they are kept
//! up to [`MAX_BYTES`] only.

use super::model::Model;
use crate::element::MAX_LOCAL;
use crate::fem::{FIELDS, MAX_NODES, PHI};
use std::sync::{Mutex, MutexGuard};

/// Per cell, a row-major nl × nl matrix (or its potential rows, [`Rows::Potential`]), and the
/// point (a stamp of the evaluation's inputs) they were evaluated at.
#[derive(Debug, Default)]
pub struct KeptTangents {
    cells: Vec<Mutex<Vec<f64>>>,
    at: Option<Vec<f64>>,
    rows: Rows,
}

/// Which rows of its matrix a cell keeps.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub enum Rows {
    /// Every row.
    #[default]
    All,
    /// The potential rows alone, the node's Gauss's law (n × nl): a system whose displacement
    /// rows are held (the projection of the potential), a quarter of the whole.
    Potential,
}

/// The most bytes the kept tangents of a model may take: beyond it the products take their own
/// pass, as memory matters more than the pass on such meshes.
pub const MAX_BYTES: usize = 256 << 20;

impl KeptTangents {
    /// Whether the tangents of `model`'s cells fit [`MAX_BYTES`].
    pub fn affordable(model: &Model) -> bool {
        let nl = model.mesh.kind.nodes_per_cell() * FIELDS;
        model.mesh.n_cells().saturating_mul(nl * nl * 8) <= MAX_BYTES
    }

    /// Starts an evaluation of `model`: forgets what was kept, and gives the cells' slots to
    /// fill when the tangents are `wanted` and can be kept (a whole model within
    /// [`MAX_BYTES`]). The stamp of [`KeptTangents::filled_at`] holds every input of the
    /// tangents, the committed internal variables included; their own products
    /// ([`crate::problem::step::points_products`]) need no tangent.
    pub fn begin(&mut self, model: &Model, wanted: bool, rows: Rows) -> Option<&[Mutex<Vec<f64>>]> {
        self.at = None;
        self.rows = rows;
        let keep = wanted && model.share.is_none() && Self::affordable(model);
        keep.then(|| self.slots(model.mesh.n_cells()))
    }

    /// The slots of the `n_cells` cells for an evaluation about to fill them (each cell its own,
    /// from any thread); what was kept before is forgotten.
    fn slots(&mut self, n_cells: usize) -> &[Mutex<Vec<f64>>] {
        if self.cells.len() != n_cells {
            self.cells = (0..n_cells).map(|_| Mutex::new(Vec::new())).collect();
        }
        self.at = None;
        &self.cells
    }

    /// The slot of cell `c`, cleared.
    fn slot(slots: &[Mutex<Vec<f64>>], c: usize) -> MutexGuard<'_, Vec<f64>> {
        let mut s = slots[c].lock().unwrap_or_else(|e| e.into_inner());
        s.clear();
        s
    }

    /// Keeps the `rows` of cell `c`'s row-major nl × nl matrix `k` (nl = FIELDS × its nodes)
    /// in its slot, as [`KeptTangents::begin`] was told.
    pub fn keep(slots: &[Mutex<Vec<f64>>], c: usize, k: &[f64], nl: usize, rows: Rows) {
        let mut slot = Self::slot(slots, c);
        match rows {
            Rows::All => slot.extend_from_slice(&k[..nl * nl]),
            Rows::Potential => {
                for row in k[..nl * nl].chunks_exact(nl).skip(PHI).step_by(FIELDS) {
                    slot.extend_from_slice(row);
                }
            }
        }
    }

    /// The slots hold the evaluation at `stamp`.
    pub fn filled_at(&mut self, stamp: Vec<f64>) {
        self.at = Some(stamp);
    }

    /// The products kᵀw of the kept matrices with the weight `w` over every dof, summed over
    /// the cells of `model` in cell order, when the tangents were kept at `stamp`; `None`
    /// otherwise.
    pub fn products(&self, model: &Model, stamp: &[f64], w: &[f64]) -> Option<Vec<f64>> {
        if self.at.as_deref() != Some(stamp) || self.cells.len() != model.mesh.n_cells() {
            return None;
        }
        let nl = model.mesh.kind.nodes_per_cell() * FIELDS;
        // a cell's kᵀw at its local dofs (each cell alone, so that they may run on the pool),
        // added in cell order on either path: the same sums, bit for bit
        let cell = |c: usize| {
            let k = self.cells[c].lock().unwrap_or_else(|e| e.into_inner());
            let mut wl = [0.0; MAX_LOCAL];
            for (a, &node) in model.mesh.cell(c).iter().enumerate() {
                wl[a * FIELDS..(a + 1) * FIELDS]
                    .copy_from_slice(&w[node * FIELDS..(node + 1) * FIELDS]);
            }
            let mut local = [0.0; MAX_LOCAL];
            match self.rows {
                Rows::All => transposed_product(&k[..nl * nl], &wl[..nl], &mut local[..nl]),
                Rows::Potential => {
                    let n = nl / FIELDS;
                    let mut w = [0.0; MAX_NODES];
                    for (a, wa) in w[..n].iter_mut().enumerate() {
                        *wa = wl[a * FIELDS + PHI];
                    }
                    transposed_product(&k[..n * nl], &w[..n], &mut local[..nl]);
                }
            }
            local
        };
        let all: Vec<usize> = (0..self.cells.len()).collect();
        let locals = crate::problem::assembly::map_cells(&all, cell);
        let mut out = vec![0.0; w.len()];
        for (c, local) in locals.iter().enumerate() {
            let nodes = model.mesh.cell(c);
            for j in 0..nl {
                out[nodes[j / FIELDS] * FIELDS + j % FIELDS] += local[j];
            }
        }
        Some(out)
    }
}

/// Σᵢ wᵢ kᵢ of the rows kᵢ of `k` (row-major, each `out.len()` long) into `out`: kᵀw of a
/// cell's nl × nl matrix, or of its potential rows alone. Row by row (contiguous, so the loop
/// over a row vectorises), rows of zero weight skipped (the displacement rows of a projection's
/// weight).
pub fn transposed_product(k: &[f64], w: &[f64], out: &mut [f64]) {
    let nl = out.len();
    out.fill(0.0);
    for (row, &wi) in k.chunks_exact(nl).zip(w) {
        if wi != 0.0 {
            for (o, &kij) in out.iter_mut().zip(row) {
                *o += wi * kij;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hex8 cell's matrix takes 8 kB: 4 cells fit, 39 200 (321 MB) do not.
    #[test]
    fn tangents_are_kept_up_to_the_limit() {
        let film = |d| crate::problem::examples::film(d, crate::mesh::ElementKind::Hex8, 2e4);
        assert!(KeptTangents::affordable(&film([2, 2, 1]).unwrap()));
        assert!(!KeptTangents::affordable(&film([70, 70, 8]).unwrap()));
    }

    /// A cell's potential rows alone give the products of its whole matrix for a weight on the
    /// potential rows (a projection's), the same bits, from a quarter of the entries.
    #[test]
    fn potential_rows_give_the_whole_matrix_products() {
        let model =
            crate::problem::examples::film([2, 1, 1], crate::mesh::ElementKind::Hex8, 2e4).unwrap();
        let nl = model.mesh.kind.nodes_per_cell() * FIELDS;
        let kept = |rows: Rows| {
            let mut kept = KeptTangents::default();
            let slots = kept.begin(&model, true, rows).unwrap();
            for c in 0..model.mesh.n_cells() {
                let k: Vec<f64> = (0..nl * nl)
                    .map(|i| ((i * 37 + c * 11) % 101) as f64 - 50.0)
                    .collect();
                KeptTangents::keep(slots, c, &k, nl, rows);
            }
            kept.filled_at(vec![1.0]);
            kept
        };
        let (whole, potential) = (kept(Rows::All), kept(Rows::Potential));
        let n_dofs = model.mesh.n_nodes() * FIELDS;
        let w: Vec<f64> = (0..n_dofs)
            .map(|d| match d % FIELDS {
                PHI => ((d * 13) % 7) as f64 - 3.0,
                _ => 0.0,
            })
            .collect();
        let a = whole.products(&model, &[1.0], &w).unwrap();
        assert!(a.iter().any(|&x| x != 0.0));
        assert_eq!(a, potential.products(&model, &[1.0], &w).unwrap());
        let n = model.mesh.kind.nodes_per_cell();
        for (cw, cp) in whole.cells.iter().zip(&potential.cells) {
            assert_eq!(cw.lock().unwrap().len(), nl * nl);
            assert_eq!(cp.lock().unwrap().len(), n * nl);
        }
        // kept at another point: nothing served
        assert!(potential.products(&model, &[2.0], &w).is_none());
    }
}
