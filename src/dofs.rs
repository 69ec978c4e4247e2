//! The map (node, field) → equation number, Dirichlet conditions, and the scaling of the unknowns.
//!
//! Every node carries four fields, interleaved node-major: ux, uy, uz (m) and Φ (V). Constrained
//! dofs are eliminated: they get no equation. The solver sees *scaled* unknowns x̂ = x / s, with
//! s = 1 for displacements and s = `phi_scale` (V/m) for the potential, and the scaled residual
//! r̂ = s·r. Choosing `phi_scale` = √(μ/ε) makes the potential block of the Jacobian the same size as
//! the displacement block, and the system stays symmetric.

/// Number of fields per node.
pub const FIELDS: usize = 4;
/// Index of the potential among a node's fields.
pub const PHI: usize = 3;
/// Marker of a constrained dof in [`DofMap::eq`].
pub const CONSTRAINED: usize = usize::MAX;

/// A field of a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    Ux,
    Uy,
    Uz,
    Phi,
}

impl Field {
    /// The field's index among a node's dofs.
    pub fn index(self) -> usize {
        match self {
            Field::Ux => 0,
            Field::Uy => 1,
            Field::Uz => 2,
            Field::Phi => PHI,
        }
    }
}

/// Equation numbering of the free dofs.
#[derive(Debug, Clone)]
pub struct DofMap {
    pub n_nodes: usize,
    /// Equation number of each dof (`node * FIELDS + field`), or [`CONSTRAINED`].
    pub eq: Vec<usize>,
    /// Number of equations.
    pub n_free: usize,
    /// Number of free potential dofs (the expected count of negative pivots of a stable state).
    pub n_free_phi: usize,
    /// Scale of each field's unknowns (m for u, V/m for Φ: x̂ = x / scale).
    pub scale: [f64; FIELDS],
}

impl DofMap {
    /// Numbers the dofs not marked in `constrained` (one flag per dof), in node-major order.
    pub fn new(n_nodes: usize, constrained: &[bool], phi_scale: f64) -> Self {
        assert_eq!(constrained.len(), n_nodes * FIELDS);
        let mut eq = vec![CONSTRAINED; n_nodes * FIELDS];
        let mut n = 0;
        let mut n_phi = 0;
        for (d, &c) in constrained.iter().enumerate() {
            if !c {
                eq[d] = n;
                n += 1;
                if d % FIELDS == PHI {
                    n_phi += 1;
                }
            }
        }
        DofMap {
            n_nodes,
            eq,
            n_free: n,
            n_free_phi: n_phi,
            scale: [1.0, 1.0, 1.0, phi_scale],
        }
    }

    /// Global dof index of a node's field.
    pub fn dof(node: usize, field: usize) -> usize {
        node * FIELDS + field
    }

    /// Adds `alpha · dx̂` (scaled free unknowns) to the full physical state.
    pub fn add_scaled(&self, state: &mut [f64], dx: &[f64], alpha: f64) {
        for (d, &e) in self.eq.iter().enumerate() {
            if e != CONSTRAINED {
                state[d] += alpha * dx[e] * self.scale[d % FIELDS];
            }
        }
    }

    /// Physical value of a scaled free unknown vector entry for dof `d`.
    pub fn field_of_equation(&self) -> Vec<usize> {
        let mut f = vec![0; self.n_free];
        for (d, &e) in self.eq.iter().enumerate() {
            if e != CONSTRAINED {
                f[e] = d % FIELDS;
            }
        }
        f
    }
}

/// A Dirichlet condition: `field` of every node in `nodes` equals `value` (m or V).
#[derive(Debug, Clone)]
pub struct Dirichlet {
    pub nodes: Vec<usize>,
    pub field: Field,
    pub value: f64,
}

/// Flags the dofs constrained by a list of conditions.
pub fn constrained_flags(n_nodes: usize, conditions: &[Dirichlet]) -> Vec<bool> {
    let mut flags = vec![false; n_nodes * FIELDS];
    for c in conditions {
        for &n in &c.nodes {
            flags[DofMap::dof(n, c.field.index())] = true;
        }
    }
    flags
}

/// Writes the prescribed values into the state; a later condition overrides an earlier one.
pub fn apply_dirichlet(state: &mut [f64], conditions: &[Dirichlet]) {
    for c in conditions {
        for &n in &c.nodes {
            state[DofMap::dof(n, c.field.index())] = c.value;
        }
    }
}
