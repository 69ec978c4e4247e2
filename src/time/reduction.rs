//! Modal problems on combinations of a model's dofs (the harmonic unknowns of a meridian model,
//! the rigid motions of rotating regions): the rows of the projected (K, M) pair, the projected
//! node mass, their CSR matrices on a common pattern and the map of their equations.

use crate::algebra::csr::{to_cols, CsrMatrix};
use crate::problem::dofs::{DofMap, CONSTRAINED, FIELDS, PHI};
use crate::time::mass::NodalMass;
use std::collections::BTreeMap;

/// The direct LDLᵀ solver of these problems (it gives the inertia).
pub fn direct_solver() -> Box<dyn crate::solve::linear::LinearSolver> {
    crate::solve::linear::SolverSettings {
        kind: crate::solve::linear::SolverKind::Direct,
        ..Default::default()
    }
    .build()
}

/// The (K, M) entries of each row by column.
pub type PairedRows = Vec<BTreeMap<usize, (f64, f64)>>;

/// Adds `factor` · Tᵀ M T to the mass entries of `rows`: M the node mass `mass` on the three
/// displacement slots, T each dof's combination `of_dof` of the unknowns.
pub fn add_projected_mass(
    rows: &mut PairedRows,
    mass: &NodalMass,
    of_dof: &[Vec<(usize, f64)>],
    factor: f64,
) {
    for a in 0..mass.row_ptr.len() - 1 {
        for p in mass.row_ptr[a]..mass.row_ptr[a + 1] {
            let b = mass.col_idx[p];
            for s in 0..3 {
                for &(ei, ci) in &of_dof[a * FIELDS + s] {
                    for &(ej, cj) in &of_dof[b * FIELDS + s] {
                        rows[ei].entry(ej).or_insert((0.0, 0.0)).1 +=
                            factor * ci * cj * mass.values[p];
                    }
                }
            }
        }
    }
}

/// K and M of `rows` as CSR matrices on their common pattern.
pub fn paired_csr(rows: &PairedRows) -> (CsrMatrix, CsrMatrix) {
    let mut row_ptr = vec![0];
    let (mut cols, mut kv, mut mv) = (Vec::new(), Vec::new(), Vec::new());
    for row in rows {
        for (&j, &(a, b)) in row {
            cols.push(j);
            kv.push(a);
            mv.push(b);
        }
        row_ptr.push(cols.len());
    }
    let k = CsrMatrix::new(rows.len(), row_ptr, to_cols(cols), kv);
    let m = CsrMatrix {
        values: mv,
        ..k.clone()
    };
    (k, m)
}

/// The equations as the nodes of a map of their own: equation e is the dof (e, `field[e]`),
/// unit scales.
pub fn equation_map(field: &[usize]) -> DofMap {
    let n = field.len();
    let mut eq = vec![CONSTRAINED; n * FIELDS];
    for (e, &f) in field.iter().enumerate() {
        eq[e * FIELDS + f] = e;
    }
    DofMap {
        n_nodes: n,
        eq,
        n_free: n,
        n_free_phi: field.iter().filter(|&&f| f == PHI).count(),
        scale: [1.0; FIELDS],
    }
}
