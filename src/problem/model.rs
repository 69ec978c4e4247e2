//! A model: mesh, materials of the cells, element formulation, Dirichlet conditions (supports and
//! electrodes) and surface tractions.

pub use crate::element::mean_dilatation::Formulation;
use crate::fem::{CellGeometry, ReferenceElement};
use crate::material::Material;
use crate::mesh::Mesh;
use crate::problem::dofs::FIELDS;
use crate::problem::dofs::{Dirichlet, Tie};
pub use crate::problem::loads::Traction;
use std::sync::Arc;

/// Everything that defines the boundary value problem except the loading path.
#[derive(Debug, Clone)]
pub struct Model {
    /// The mesh, shared (never copied) by the models of every stage.
    pub mesh: Arc<Mesh>,
    pub reference: ReferenceElement,
    /// Shape-function gradients and integration weights of the cells in the reference
    /// configuration, computed once per mesh and shared (see [`Model::geometry`]).
    pub geometries: Arc<Geometries>,
    /// The distinct materials.
    pub materials: Vec<Arc<dyn Material>>,
    /// Material index of each cell.
    pub cell_material: Vec<usize>,
    /// Prescribed displacements (m) and potentials (V) at the end of the current stage.
    pub dirichlet: Vec<Dirichlet>,
    /// Element formulation (standard displacement, or mean-dilatation for near incompressibility).
    pub formulation: Formulation,
    /// Dead nominal tractions (N/m² of reference area) at the end of the current stage; statics
    /// scales them by the load factor, dynamics applies them at full value.
    pub tractions: Vec<Traction>,
    /// Body force per reference volume of each material (N/m³, e.g. ρ₀g), a dead load like the
    /// tractions.
    pub body_force: Vec<[f64; 3]>,
    /// Dead point forces (node, N), e.g. the weight of an attached mass.
    pub point_forces: Vec<(usize, [f64; 3])>,
    /// Groups of dofs that move together (a rigid region's translations).
    pub ties: Vec<Tie>,
    /// Linear dashpots (node, N·s/m) on the translations of a node (of a rigid region: the
    /// damping of the attached mass by air and fixture); dynamics only.
    pub point_dampers: Vec<(usize, f64)>,
    /// Follower pressures on face sets; a static stage's drive ramps each one's fraction of its
    /// value over the load factor.
    pub pressures: Vec<crate::problem::pressure::Pressure>,
    /// Free charges (node, C) on the potential of tied (charge-controlled) electrodes: dead
    /// loads −Q on the potential equations, ramped like the forces.
    pub point_charges: Vec<(usize, f64)>,
    /// Electrodes driven through a series resistance (dynamic stages).
    pub circuits: Vec<crate::problem::circuit::Circuit>,
    /// The cells this process assembles when several processes share them (a distributed run;
    /// set by the run set-up). `None`: this process assembles every cell.
    pub share: Option<Arc<crate::problem::assembly::CellShare>>,
}

/// Problems found while building a model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    #[error("cell {cell} is degenerate or inverted (Jacobian {det:e} at quadrature point {qp})")]
    DegenerateCell { cell: usize, qp: usize, det: f64 },
    #[error("unknown set '{name}' (known sets: {known})")]
    UnknownSet { name: String, known: String },
    #[error("{0}")]
    Invalid(String),
}

impl Model {
    /// A model of one material on every cell, without conditions.
    pub fn new(mesh: Mesh, material: Arc<dyn Material>) -> Result<Self, ModelError> {
        Self::with_geometry(mesh, material, true)
    }

    /// As [`Model::new`]; `hold`: whether the model holds every cell's reference geometry, or
    /// computes it when asked (each cell checked here either way). A plan that is only cut into
    /// MPI ranks' parts need not hold it: at 10⁶ unknowns a hex8 mesh's geometry takes about
    /// 0.5 GB.
    pub fn with_geometry(
        mesh: Mesh,
        material: Arc<dyn Material>,
        hold: bool,
    ) -> Result<Self, ModelError> {
        let n = mesh.n_cells();
        let reference = ReferenceElement::new(mesh.kind);
        let geometries = Arc::new(if hold {
            Geometries::new(Self::cell_geometries(&mesh, &reference)?)
        } else {
            Geometries::none(n, Self::checked_volume(&mesh, &reference)?)
        });
        let model = Model {
            reference,
            geometries,
            mesh: Arc::new(mesh),
            materials: vec![material],
            cell_material: vec![0; n],
            dirichlet: Vec::new(),
            formulation: Formulation::Standard,
            tractions: Vec::new(),
            body_force: Vec::new(),
            point_forces: Vec::new(),
            ties: Vec::new(),
            point_dampers: Vec::new(),
            pressures: Vec::new(),
            point_charges: Vec::new(),
            circuits: Vec::new(),
            share: None,
        };
        model.check_cells()?;
        let mut model = model;
        model.dirichlet = model.axisymmetric_supports();
        Ok(model)
    }

    /// Calls `f` with every cell's reference geometry, in cell order; fails on the first cell
    /// with a non-positive Jacobian.
    fn for_each_geometry(
        mesh: &Mesh,
        reference: &ReferenceElement,
        mut f: impl FnMut(CellGeometry),
    ) -> Result<(), ModelError> {
        let mut x = vec![[0.0; 3]; mesh.kind.nodes_per_cell()];
        for c in 0..mesh.n_cells() {
            mesh.cell_coords_into(c, &mut x);
            f(reference
                .geometry(&x)
                .map_err(|e| ModelError::DegenerateCell {
                    cell: c,
                    qp: e.qp,
                    det: e.det,
                })?);
        }
        Ok(())
    }

    /// The reference geometry of every cell; fails on the first cell with a non-positive Jacobian.
    fn cell_geometries(
        mesh: &Mesh,
        reference: &ReferenceElement,
    ) -> Result<Vec<CellGeometry>, ModelError> {
        let mut all = Vec::with_capacity(mesh.n_cells());
        Self::for_each_geometry(mesh, reference, |g| all.push(g))?;
        Ok(all)
    }

    /// The reference volume of every cell together (in cell order, as [`Geometries::new`]
    /// sums it); fails on the first cell with a non-positive Jacobian.
    fn checked_volume(mesh: &Mesh, reference: &ReferenceElement) -> Result<f64, ModelError> {
        let mut volume = 0.0;
        Self::for_each_geometry(mesh, reference, |g| {
            volume += g.weights[..g.n_qp].iter().sum::<f64>()
        })?;
        Ok(volume)
    }

    /// Holds every cell's reference geometry (a model built without: [`Model::with_geometry`]).
    pub fn hold_every_geometry(&mut self) -> Result<(), ModelError> {
        let all = Self::cell_geometries(&self.mesh, &self.reference)?;
        self.geometries = Arc::new(Geometries::new(all));
        Ok(())
    }

    /// Fails on the first cell with a non-positive Jacobian.
    pub fn check_cells(&self) -> Result<(), ModelError> {
        Self::for_each_geometry(&self.mesh, &self.reference, |_| {})
    }

    /// Nodes of a named set, or an error naming the known sets.
    pub fn set_nodes(&self, name: &str) -> Result<Vec<usize>, ModelError> {
        self.mesh
            .set_nodes(name)
            .ok_or_else(|| ModelError::UnknownSet {
                name: name.to_string(),
                known: self.mesh.set_names().join(", "),
            })
    }

    /// Adds a Dirichlet condition on a named set.
    pub fn fix(
        &mut self,
        set: &str,
        field: crate::problem::dofs::Field,
        value: f64,
    ) -> Result<(), ModelError> {
        let nodes = self.set_nodes(set)?;
        self.dirichlet.push(Dirichlet {
            nodes,
            field,
            value,
        });
        Ok(())
    }

    /// Adds a dead nominal traction `value` (N/m² of reference area) on a named face set.
    pub fn add_traction(&mut self, face_set: &str, value: [f64; 3]) -> Result<(), ModelError> {
        let faces = self
            .mesh
            .face_sets
            .get(face_set)
            .ok_or_else(|| ModelError::UnknownSet {
                name: face_set.to_string(),
                known: self
                    .mesh
                    .face_sets
                    .keys()
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", "),
            })?
            .clone();
        if value.iter().any(|v| !v.is_finite()) {
            return Err(ModelError::Invalid(format!(
                "traction on '{face_set}' must be finite; got {value:?}"
            )));
        }
        self.tractions.push(Traction { faces, value });
        Ok(())
    }

    /// Whether the model carries any dead load (traction, body force, point force).
    pub fn has_dead_loads(&self) -> bool {
        !self.tractions.is_empty()
            || !self.point_forces.is_empty()
            || !self.point_charges.is_empty()
            || self.body_force.iter().any(|b| *b != [0.0; 3])
    }

    /// Potential scale √(μ/ε) (V/m) from the stiffest and most permittive materials, so that the
    /// potential block of the tangent has the size of the displacement block.
    pub fn potential_scale(&self) -> f64 {
        let mu = self
            .materials
            .iter()
            .map(|m| m.shear_modulus())
            .fold(0.0, f64::max);
        let eps = self
            .materials
            .iter()
            .map(|m| m.permittivity())
            .fold(0.0, f64::max);
        if mu > 0.0 && eps > 0.0 {
            (mu / eps).sqrt()
        } else {
            1.0
        }
    }

    /// Calls `f(cell, geometry, material, local values)` for every cell, in order, with the cell's
    /// local values (4 per node) gathered from the full physical `state`.
    pub fn for_each_cell<E>(
        &self,
        state: &[f64],
        f: impl FnMut(usize, &CellGeometry, &dyn Material, &[f64]) -> Result<(), E>,
    ) -> Result<(), E> {
        self.for_each_cell_where(state, |_| true, f)
    }

    /// [`Model::for_each_cell`] over the cells `keep` accepts only.
    pub fn for_each_cell_where<E>(
        &self,
        state: &[f64],
        keep: impl Fn(usize) -> bool,
        mut f: impl FnMut(usize, &CellGeometry, &dyn Material, &[f64]) -> Result<(), E>,
    ) -> Result<(), E> {
        let npc = self.mesh.kind.nodes_per_cell();
        let mut local = vec![0.0; npc * FIELDS];
        for c in (0..self.mesh.n_cells()).filter(|&c| keep(c)) {
            for (a, &node) in self.mesh.cell(c).iter().enumerate() {
                local[a * FIELDS..(a + 1) * FIELDS]
                    .copy_from_slice(&state[node * FIELDS..(node + 1) * FIELDS]);
            }
            f(
                c,
                &self.geometry(c),
                self.materials[self.cell_material[c]].as_ref(),
                &local,
            )?;
        }
        Ok(())
    }

    /// Finishes a pass over this process's cells whose sums are `v` and which stopped at
    /// `failure` (the cell and its message), if any: sums `v` over the processes that share the
    /// cells (nothing without a share), and fails on every process when a cell failed on any,
    /// with this process's own message for its own cell ([`CellShare::sum_unless_failed`]).
    pub fn sum_over_processes(
        &self,
        v: &mut [f64],
        failure: Option<(usize, String)>,
    ) -> Result<(), String> {
        if let Some(share) = self.share.as_deref() {
            share.sum_unless_failed(v, failure.as_ref().map(|f| f.0))?;
        }
        match failure {
            Some((_, message)) => Err(message),
            None => Ok(()),
        }
    }

    /// Whether this process evaluates cell `c`: every cell, unless processes share the cells
    /// ([`Model::share`]).
    pub fn owns(&self, c: usize) -> bool {
        self.share.as_ref().is_none_or(|s| s.owns(c))
    }

    /// The conditions every axisymmetric model carries: the unused third displacement slot held
    /// at 0 at every node, and u_r = 0 on the axis (nodes with R = 0). Empty for a 3-D model.
    pub fn axisymmetric_supports(&self) -> Vec<Dirichlet> {
        if !self.is_axisymmetric() {
            return Vec::new();
        }
        let axis: Vec<usize> = (0..self.mesh.n_nodes())
            .filter(|&n| self.mesh.nodes[n][0] == 0.0)
            .collect();
        vec![
            Dirichlet {
                nodes: (0..self.mesh.n_nodes()).collect(),
                field: crate::problem::dofs::Field::Uz,
                value: 0.0,
            },
            Dirichlet {
                nodes: axis,
                field: crate::problem::dofs::Field::Ux,
                value: 0.0,
            },
        ]
    }

    /// Whether the model is axisymmetric (its cells are meridian cells).
    pub fn is_axisymmetric(&self) -> bool {
        self.mesh.kind.meridian().is_some()
    }

    /// The cell kernel of the model's formulation and kinematics.
    pub fn kernel(&self) -> &'static dyn crate::element::CellKernel {
        self.formulation.kernel(self.is_axisymmetric())
    }

    /// Mean cell size (m): the cube root of the mean cell volume.
    pub fn cell_size(&self) -> f64 {
        (self.geometries.volume / self.mesh.n_cells().max(1) as f64).cbrt()
    }

    /// The reference geometry of cell `c`: the held one, or (for a cell that a distributed run
    /// gives to another process, which only outputs visit here) computed again.
    pub fn geometry(&self, c: usize) -> std::borrow::Cow<'_, CellGeometry> {
        match self.geometries.held(c) {
            Some(g) => std::borrow::Cow::Borrowed(g),
            None => {
                let mut x = vec![[0.0; 3]; self.mesh.kind.nodes_per_cell()];
                self.mesh.cell_coords_into(c, &mut x);
                // every cell's geometry was computed once when the model was built
                std::borrow::Cow::Owned(
                    self.reference
                        .geometry(&x)
                        .expect("a cell checked when the model was built"),
                )
            }
        }
    }

    /// This model's part on one rank's part of its mesh (`local`, cut from this model's mesh):
    /// the rank's cells with their materials, the supports, ties and tractions restricted to
    /// them, and the loads that are not cell terms (point forces and charges, dashpots) at the
    /// nodes the rank owns only, so that the ranks' parts add up to the whole model with each
    /// such load once, each face of a traction or pressure on the rank of its cell (a
    /// volume-controlled pressure's volume is then a sum of the ranks' shares). Circuits are
    /// refused: they are not divided between the ranks yet.
    pub fn part(&self, local: &crate::mesh::distribute::LocalMesh) -> Result<Model, ModelError> {
        if !self.circuits.is_empty() {
            return Err(ModelError::Invalid(
                "circuit-driven electrodes are not divided between the ranks yet".into(),
            ));
        }
        let mut at = vec![usize::MAX; self.mesh.n_nodes()];
        for (l, &n) in local.nodes.iter().enumerate() {
            at[n] = l;
        }
        let mut cell_at = vec![usize::MAX; self.mesh.n_cells()];
        for (l, &c) in local.cells.iter().enumerate() {
            cell_at[c] = l;
        }
        let nodes = |list: &[usize]| -> Vec<usize> {
            list.iter()
                .filter(|&&n| at[n] != usize::MAX)
                .map(|&n| at[n])
                .collect()
        };
        let owned = |n: usize| at[n] < local.owned;
        // a tie with a held member is held as a whole, also on ranks without that member
        let flags = crate::problem::dofs::constrained_flags(self.mesh.n_nodes(), &self.dirichlet);
        let mut part = Model::new(local.mesh.clone(), self.materials[0].clone())?;
        part.materials = self.materials.clone();
        part.cell_material = local.cells.iter().map(|&c| self.cell_material[c]).collect();
        part.formulation = self.formulation;
        part.dirichlet = self
            .dirichlet
            .iter()
            .map(|d| Dirichlet {
                nodes: nodes(&d.nodes),
                ..d.clone()
            })
            .filter(|d| !d.nodes.is_empty())
            .collect();
        part.ties = self
            .ties
            .iter()
            .map(|t| Tie {
                nodes: nodes(&t.nodes),
                field: t.field,
                held: t.held || t.nodes.iter().any(|&n| flags[n * FIELDS + t.field.index()]),
            })
            .filter(|t| !t.nodes.is_empty())
            .collect();
        part.tractions = self
            .tractions
            .iter()
            .map(|t| Traction {
                faces: t
                    .faces
                    .iter()
                    .filter(|f| cell_at[f.cell] != usize::MAX)
                    .map(|f| crate::mesh::FaceRef {
                        cell: cell_at[f.cell],
                        face: f.face,
                    })
                    .collect(),
                value: t.value,
            })
            .collect();
        // each face on the rank of its cell, so that it acts once
        part.pressures = self
            .pressures
            .iter()
            .map(|p| crate::problem::pressure::Pressure {
                faces: crate::problem::pressure::faces_on_part(&p.faces, &cell_at, &at),
                ..p.clone()
            })
            .collect();
        part.body_force = self.body_force.clone();
        let on_owned = |list: &[(usize, f64)]| -> Vec<(usize, f64)> {
            list.iter()
                .filter(|(n, _)| owned(*n))
                .map(|&(n, v)| (at[n], v))
                .collect()
        };
        part.point_forces = self
            .point_forces
            .iter()
            .filter(|(n, _)| owned(*n))
            .map(|&(n, f)| (at[n], f))
            .collect();
        part.point_dampers = on_owned(&self.point_dampers);
        part.point_charges = on_owned(&self.point_charges);
        Ok(part)
    }

    /// Keeps the reference geometry of the cells `keep` names only (the others are computed
    /// when asked for): a distributed run's process holds its own cells'.
    pub fn hold_geometry_of(&mut self, keep: impl Fn(usize) -> bool) {
        self.geometries = Arc::new(self.geometries.restricted(keep));
    }
}

/// The reference geometry of the cells, held for all of them or (in a distributed run) for the
/// cells of this process only: at 10⁶ unknowns a hex8 mesh's geometry takes about 0.7 GB.
#[derive(Debug, Clone)]
pub struct Geometries {
    held: Vec<CellGeometry>,
    /// Per cell: its index in `held`, or `NOT_HELD`.
    slot: Vec<u32>,
    /// The reference volume of all cells (m³, the sum of their weights, in cell order).
    volume: f64,
}

const NOT_HELD: u32 = u32::MAX;

impl Geometries {
    /// Holds every cell's geometry.
    pub fn new(all: Vec<CellGeometry>) -> Self {
        let volume = all
            .iter()
            .map(|g| g.weights[..g.n_qp].iter().sum::<f64>())
            .sum();
        let slot = (0..all.len())
            .map(|c| u32::try_from(c).unwrap_or(NOT_HELD))
            .collect();
        Geometries {
            held: all,
            slot,
            volume,
        }
    }

    /// Holds no cell's geometry; `volume`: the reference volume of all cells (m³).
    fn none(cells: usize, volume: f64) -> Self {
        Geometries {
            held: Vec::new(),
            slot: vec![NOT_HELD; cells],
            volume,
        }
    }

    /// The held geometry of cell `c`, if held.
    pub fn held(&self, c: usize) -> Option<&CellGeometry> {
        match self.slot.get(c) {
            Some(&s) if s != NOT_HELD => self.held.get(s as usize),
            _ => None,
        }
    }

    /// These geometries restricted to the held cells that `keep` names.
    fn restricted(&self, keep: impl Fn(usize) -> bool) -> Self {
        // the exact size: grown by doubling, the vector would hold up to twice the geometry
        let count = (0..self.slot.len())
            .filter(|&c| keep(c) && self.held(c).is_some())
            .count();
        let mut held = Vec::with_capacity(count);
        let slot = (0..self.slot.len())
            .map(|c| match self.held(c) {
                Some(g) if keep(c) => {
                    held.push(g.clone());
                    (held.len() - 1) as u32
                }
                _ => NOT_HELD,
            })
            .collect();
        Geometries {
            held,
            slot,
            volume: self.volume,
        }
    }
}

/// A [`Model`] as data (serde's `with` module): everything but its materials, which are code
/// (trait objects built from a scenario), and what follows from the mesh (the reference element
/// and the cells' geometry, computed again on reading). A model read back has no materials until
/// its reader sets them; a cell share is not data either (a distributed run sets its own).
pub mod data {
    use super::*;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    /// The model's data, borrowed for writing.
    #[derive(Serialize)]
    struct Written<'a> {
        mesh: &'a Mesh,
        cell_material: &'a [usize],
        dirichlet: &'a [Dirichlet],
        formulation: Formulation,
        tractions: &'a [Traction],
        body_force: &'a [[f64; 3]],
        point_forces: &'a [(usize, [f64; 3])],
        ties: &'a [Tie],
        point_dampers: &'a [(usize, f64)],
        pressures: &'a [crate::problem::pressure::Pressure],
        point_charges: &'a [(usize, f64)],
        circuits: &'a [crate::problem::circuit::Circuit],
    }

    /// The model's data, read.
    #[derive(Deserialize)]
    struct Read {
        mesh: Mesh,
        cell_material: Vec<usize>,
        dirichlet: Vec<Dirichlet>,
        formulation: Formulation,
        tractions: Vec<Traction>,
        body_force: Vec<[f64; 3]>,
        point_forces: Vec<(usize, [f64; 3])>,
        ties: Vec<Tie>,
        point_dampers: Vec<(usize, f64)>,
        pressures: Vec<crate::problem::pressure::Pressure>,
        point_charges: Vec<(usize, f64)>,
        circuits: Vec<crate::problem::circuit::Circuit>,
    }

    pub fn serialize<S: Serializer>(model: &Model, s: S) -> Result<S::Ok, S::Error> {
        // every field named, so that a field added to the model is added here too
        let Model {
            mesh,
            reference: _,
            geometries: _,
            materials: _,
            cell_material,
            dirichlet,
            formulation,
            tractions,
            body_force,
            point_forces,
            ties,
            point_dampers,
            pressures,
            point_charges,
            circuits,
            share: _,
        } = model;
        Written {
            mesh,
            cell_material,
            dirichlet,
            formulation: *formulation,
            tractions,
            body_force,
            point_forces,
            ties,
            point_dampers,
            pressures,
            point_charges,
            circuits,
        }
        .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Model, D::Error> {
        let r = Read::deserialize(d)?;
        if r.cell_material.len() != r.mesh.n_cells() {
            return Err(serde::de::Error::custom(format!(
                "{} cell materials for {} cells",
                r.cell_material.len(),
                r.mesh.n_cells()
            )));
        }
        let reference = ReferenceElement::new(r.mesh.kind);
        let geometries = Model::cell_geometries(&r.mesh, &reference)
            .map_err(|e| serde::de::Error::custom(e.to_string()))?;
        Ok(Model {
            reference,
            geometries: Arc::new(Geometries::new(geometries)),
            mesh: Arc::new(r.mesh),
            materials: Vec::new(),
            cell_material: r.cell_material,
            dirichlet: r.dirichlet,
            formulation: r.formulation,
            tractions: r.tractions,
            body_force: r.body_force,
            point_forces: r.point_forces,
            ties: r.ties,
            point_dampers: r.point_dampers,
            pressures: r.pressures,
            point_charges: r.point_charges,
            circuits: r.circuits,
            share: None,
        })
    }
}

/// The model's loads at full value.
impl Model {
    /// Consistent nodal forces (N, `FIELDS` per node, zero potential entries) of all the dead loads of
    /// a model at full value: tractions ∫N t₀ dA, body forces ∫N b₀ dV (with the element's own
    /// quadrature, exact for constant b₀ on affine cells) and point forces.
    pub fn dead_load_forces(&self) -> Vec<f64> {
        let model = self;
        let mut out = crate::problem::loads::traction_forces(&model.mesh, &model.tractions, 1.0);
        for &(node, q) in &model.point_charges {
            out[node * FIELDS + crate::problem::dofs::PHI] -= q;
        }
        for (o, g) in out.iter_mut().zip(model.weight_forces()) {
            *o += g;
        }
        out
    }

    /// Consistent nodal forces (N, `FIELDS` per node) of the body and point forces of a model at
    /// full value: the loads with a potential energy −f·u (gravity on the body and attached masses).
    pub fn weight_forces(&self) -> Vec<f64> {
        let mut out = self.body_forces_of(|_| true);
        for &(node, f) in &self.point_forces {
            for i in 0..3 {
                out[node * FIELDS + i] += f[i];
            }
        }
        out
    }

    /// Consistent nodal forces (N, `FIELDS` per node) of the body force of the cells whose
    /// material `of` accepts, at full value.
    pub fn body_forces_of(&self, of: impl Fn(usize) -> bool) -> Vec<f64> {
        let model = self;
        let mesh = &model.mesh;
        let mut out = vec![0.0; mesh.n_nodes() * FIELDS];
        if model.body_force.iter().any(|b| *b != [0.0; 3]) {
            let npc = mesh.kind.nodes_per_cell();
            let mut x = vec![[0.0; 3]; npc];
            for c in 0..mesh.n_cells() {
                let m = model.cell_material[c];
                let Some(b) = model.body_force.get(m).filter(|_| of(m)) else {
                    continue;
                };
                mesh.cell_coords_into(c, &mut x);
                // a degenerate cell is reported by the solver; it carries no load here
                let Ok(g) = model.reference.geometry(&x) else {
                    continue;
                };
                for (a, &node) in mesh.cell(c).iter().enumerate() {
                    let w: f64 = (0..g.n_qp)
                        .map(|q| g.weights[q] * model.reference.n[q][a])
                        .sum();
                    for i in 0..3 {
                        out[node * FIELDS + i] += w * b[i];
                    }
                }
            }
        }
        out
    }
}
