//! The map (node, field) → equation number, Dirichlet conditions, and the scaling of the unknowns.
//!
//! Every node carries four fields, interleaved node-major: ux, uy, uz (m) and Φ (V). Constrained
//! dofs are eliminated: they get no equation. The solver sees *scaled* unknowns x̂ = x / s, with
//! s = 1 for displacements and s = `phi_scale` (V/m) for the potential, and the scaled residual
//! r̂ = s·r. Choosing `phi_scale` = √(μ/ε) makes the potential block of the Jacobian the same size as
//! the displacement block, and the system stays symmetric.

use crate::algebra::system::DofLayout;
pub use crate::fem::{FIELDS, PHI};
/// Marker of a constrained dof in [`DofMap::eq`].
pub const CONSTRAINED: usize = usize::MAX;

/// A field of a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
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
        Self::with_ties(n_nodes, constrained, phi_scale, &[])
    }

    /// As [`DofMap::new`], and every tie's dofs share one equation (they move together by the
    /// same increments). A tie with a constrained member is constrained as a whole: its dofs keep
    /// their current values.
    pub fn with_ties(n_nodes: usize, constrained: &[bool], phi_scale: f64, ties: &[Tie]) -> Self {
        assert_eq!(constrained.len(), n_nodes * FIELDS);
        let mut flags = constrained.to_vec();
        // leader[d]: the first dof of d's tie (d itself when untied)
        let mut leader: Vec<usize> = (0..n_nodes * FIELDS).collect();
        for t in ties {
            let dofs: Vec<usize> = t
                .nodes
                .iter()
                .map(|&n| Self::dof(n, t.field.index()))
                .collect();
            let Some(&first) = dofs.iter().min() else {
                continue;
            };
            let held = t.held || dofs.iter().any(|&d| flags[d]);
            for &d in &dofs {
                leader[d] = first;
                flags[d] |= held;
            }
        }
        let mut eq = vec![CONSTRAINED; n_nodes * FIELDS];
        let mut n = 0;
        let mut n_phi = 0;
        for d in 0..n_nodes * FIELDS {
            if flags[d] {
                continue;
            }
            if leader[d] != d {
                eq[d] = eq[leader[d]];
                continue;
            }
            eq[d] = n;
            n += 1;
            if d % FIELDS == PHI {
                n_phi += 1;
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

    /// For every node, a representative node of its class under "shares an equation" (through
    /// ties, transitively; the node itself when it has no tied dof): cells whose nodes have a
    /// common representative may write the same rows, so they must not be assembled concurrently.
    pub fn node_representatives(&self) -> Vec<usize> {
        fn find(parent: &mut [usize], mut a: usize) -> usize {
            while parent[a] != a {
                parent[a] = parent[parent[a]];
                a = parent[a];
            }
            a
        }
        let mut parent: Vec<usize> = (0..self.n_nodes).collect();
        let mut first_node_of_eq = vec![usize::MAX; self.n_free];
        for (d, &e) in self.eq.iter().enumerate() {
            if e == CONSTRAINED {
                continue;
            }
            let node = d / FIELDS;
            if first_node_of_eq[e] == usize::MAX {
                first_node_of_eq[e] = node;
            } else {
                let (a, b) = (
                    find(&mut parent, node),
                    find(&mut parent, first_node_of_eq[e]),
                );
                parent[a.max(b)] = a.min(b);
            }
        }
        (0..self.n_nodes).map(|n| find(&mut parent, n)).collect()
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

    /// The layout of the free unknowns over the mesh nodes at `coords` (a tied equation sits at
    /// the tie's first node).
    pub fn layout(&self, coords: &[[f64; 3]], axisymmetric: bool) -> DofLayout {
        let mut node = vec![usize::MAX; self.n_free];
        let mut field = vec![0u8; self.n_free];
        for (d, &e) in self.eq.iter().enumerate() {
            if e != CONSTRAINED && node[e] == usize::MAX {
                node[e] = d / FIELDS;
                field[e] = (d % FIELDS) as u8;
            }
        }
        DofLayout {
            node,
            field,
            coords: coords.to_vec(),
            axisymmetric,
            shared: false,
            owned: None,
            equations: None,
        }
    }

    /// The field (0..`FIELDS`) of every free unknown.
    pub fn field_of_equation(&self) -> Vec<usize> {
        let mut f = vec![0; self.n_free];
        for (d, &e) in self.eq.iter().enumerate() {
            if e != CONSTRAINED {
                f[e] = d % FIELDS;
            }
        }
        f
    }

    /// Each equation's field group for Newton's table: 0 displacement, 1 potential.
    pub fn groups(&self) -> Vec<u8> {
        self.field_of_equation()
            .into_iter()
            .map(|f| u8::from(f == PHI))
            .collect()
    }
}

/// A tie: `field` of every node in `nodes` takes one common increment (a rigid translation of a
/// region along one axis).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Tie {
    pub nodes: Vec<usize>,
    pub field: Field,
    /// Constrained as a whole whatever its members' conditions: it is a rank's part of a tie
    /// that has a held member on another rank (see [`DofMap::with_ties`]).
    pub held: bool,
}

/// A Dirichlet condition: `field` of every node in `nodes` equals `value` (m or V).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
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
/// A vector `w` over the free unknowns of `dofs` seen over every dof: w_e s_d at each dof d of
/// equation e (s_d its field's scale), 0 at held dofs. For the weighted sums wᵀ∂R/∂y of a scaled
/// residual R through unscaled nodal forces f: wᵀ∂R/∂y = (free_weights(w))ᵀ ∂f/∂y.
pub fn free_weights(dofs: &DofMap, w: &[f64]) -> Vec<f64> {
    dofs.eq
        .iter()
        .enumerate()
        .map(|(d, &e)| {
            if e == CONSTRAINED {
                0.0
            } else {
                w[e] * dofs.scale[d % FIELDS]
            }
        })
        .collect()
}
