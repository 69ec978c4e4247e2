//! The static problem: equilibrium of Π(u, Φ) = ∫Ψ dV − W_ext under prescribed displacements and
//! electrode potentials, ramped from their values at the start of the stage to the model's targets,
//! and dead loads (tractions, body and point forces) scaled by the load factor. The cell kernel is the model's
//! [`Formulation`](crate::problem::model::Formulation) (standard or mean-dilatation).

use crate::algebra::csr::CsrMatrix;
use crate::algebra::system::{DofLayout, LoadedSystem, NonlinearSystem};
use crate::element::{CellFields, CellInput, MAX_LOCAL};
use crate::material::{Material, ParameterDerivative};
use crate::problem::assembly::{Assembler, GlobalTerms};
use crate::problem::dofs::{constrained_flags, DofMap, CONSTRAINED, FIELDS, PHI};
use crate::problem::drive::Drive;
use crate::problem::kept_tangents::{KeptTangents, Rows};
use crate::problem::model::Model;
use crate::problem::points::PointStates;
use crate::problem::step::{cell_products, points_products, LevelVjp, StepOperator};

/// Residual floor relative to the characteristic nodal force μ·h² (h the mean cell size).
const RESIDUAL_FLOOR: f64 = 1e-11;
/// Round-off level of the residual norm of a nearly incompressible body, in units of ε·K·h²·√n
/// (ε the machine epsilon, K the bulk modulus, n the number of unknowns): J = det F carries an
/// absolute rounding error ≈ ε, hence the pressure ≈ εK and each nodal force ≈ εK·h², and the
/// norm sums n such errors. With K/μ ≳ 10³ on fine meshes this exceeds the μ-based floor and
/// Newton would stall just above it (measured: ≈ 0.3 ε·K·h²·√n on Cook's membrane, ν = 0.4999).
const ROUNDOFF_FLOOR: f64 = 4.0 * f64::EPSILON;

/// The discrete static problem of a model.
pub struct StaticProblem<'m> {
    pub model: &'m Model,
    pub dofs: DofMap,
    assembler: Assembler,
    /// Physical state, `FIELDS` values per node: u (m), Φ (V).
    pub state: Vec<f64>,
    /// The state at load factor 0 (the supports' start values).
    start: Vec<f64>,
    cell_energy: Vec<f64>,
    floor: f64,
    /// Fraction of the dead loads at the current load factor (from [`StaticProblem::drive`]).
    load: f64,
    /// Nodal forces of the model's dead loads at full value (N, `FIELDS` per node); empty without
    /// dead loads.
    dead_load: Vec<f64>,
    /// The state at which the solver last factored this problem's tangent (for a resumed run to
    /// factor the same matrix again).
    pub factored_at: Option<Vec<f64>>,
    /// Committed internal variables of the material points.
    pub points: PointStates,
    /// Time (s) per unit of load factor: a load step Δs lasts Δs·`duration` for materials with
    /// internal variables (0: the instantaneous response).
    pub duration: f64,
    /// Load factor of the committed state, and of the current one.
    committed_load: f64,
    s: f64,
    /// The stage's drive ([`StaticProblem::set_drive`]): at load factor s, the supports and
    /// loads at s, the electrodes that follow waveforms at stage time s·`duration` (a
    /// quasi-static stage).
    drive: Drive,
    /// Energy dissipated by the material points over the accepted steps (J), and over the last
    /// one.
    pub dissipated: f64,
    pub dissipated_step: f64,
    /// Free charges (node of an electrode's potential unknown, C) held on potential equations
    /// whatever the load factor: the circuits' charges in the electrostatic projection of a
    /// dynamic step.
    pub extra_charges: Vec<(usize, f64)>,
    /// Keep each cell's tangent of the last evaluation with a matrix for
    /// [`StepOperator::level_vjp`] at the same state (an adjoint's load step or projection:
    /// its transposed products then cost no second pass of cell tangents). Elastic materials
    /// on a whole model only.
    pub keep_cell_tangents: bool,
    kept: KeptTangents,
    /// The pressure under volume control, if any (the bordering unknown of the Newton solve).
    pub volume_control: Option<VolumeControl>,
}

/// A pressure whose fraction is the unknown that makes its faces enclose a prescribed volume.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeControl {
    /// Index in `model.pressures`.
    pub pressure: usize,
    /// Enclosed volume (m³, meshed part) at load factor 0 and 1 of the stage (`start`: on a
    /// rank's part, the share of the rank's faces).
    pub start: f64,
    pub target: f64,
    /// The pressure's current fraction of its `value` (the unknown).
    pub level: f64,
}

/// The layout of the free unknowns of `model` numbered by `dofs`, with the share of the cells
/// that `assembler` makes (whether the processes share them, and which equations are this
/// process's).
pub fn layout_of(model: &Model, dofs: &DofMap, assembler: &Assembler) -> DofLayout {
    let mut layout = dofs.layout(&model.mesh.nodes, model.is_axisymmetric());
    layout.shared = assembler.is_shared();
    layout.owned = assembler.term_flags();
    layout
}

/// The dof map (constraints of `model.dirichlet`), the assembler with its CSR pattern, and the
/// absolute residual floor (N) of a model: h²·max(10⁻¹¹ μ, 4ε·K·√n) with the largest shear and
/// bulk moduli of the materials.
pub fn discretize(model: &Model) -> (DofMap, Assembler, f64) {
    let n_nodes = model.mesh.n_nodes();
    let flags = constrained_flags(n_nodes, &model.dirichlet);
    let dofs = DofMap::with_ties(n_nodes, &flags, model.potential_scale(), &model.ties);
    // shared cells of another mesh (never the case: the stages share the mesh) would leave
    // cells out; every process then assembles everything, as without a share
    let assembler = match &model.share {
        Some(share) if share.part.len() == model.mesh.n_cells() => {
            Assembler::shared(&model.mesh, &dofs, share.clone())
        }
        _ => Assembler::new(&model.mesh, &dofs),
    };
    let floor = residual_floor(model, dofs.n_free);
    (dofs, assembler, floor)
}

/// The strains of a difference of residuals that stands for the tangent's product
/// ([`NonlinearSystem::difference_step`]): the residual's round-off, relative to its forces,
/// is far above ε (the stresses of a nearly incompressible, electrically loaded body cancel in
/// the nodal forces), so the balance of round-off and truncation lies above √ε: on the film
/// 40 × 40 × 8 a step of √ε of the cell size left the products about 10⁻⁴ off, 10⁻⁶ of it a few
/// 10⁻⁶ (the Krylov solves on them then reach 10⁻⁴ without stalling).
const DIFFERENCE_STRAIN: f64 = 1e-6;

/// The absolute residual floor (N) of `model` with `n_free` unknowns: h²·max(10⁻¹¹ μ, 4ε·K·√n)
/// with the largest shear and bulk moduli of the materials and the mean cell size h.
pub fn residual_floor(model: &Model, n_free: usize) -> f64 {
    let mu = model
        .materials
        .iter()
        .map(|m| m.shear_modulus())
        .fold(0.0, f64::max);
    let kappa = model
        .materials
        .iter()
        .map(|m| m.bulk_modulus())
        .fold(0.0, f64::max);
    let h = model.cell_size();
    let floor = (RESIDUAL_FLOOR * mu).max(ROUNDOFF_FLOOR * kappa * (n_free as f64).sqrt());
    floor * h * h
}

impl<'m> StaticProblem<'m> {
    /// Sets up the problem starting from `state` (zero when `None`).
    pub fn new(model: &'m Model, state: Option<Vec<f64>>) -> Self {
        let (dofs, assembler, floor) = discretize(model);
        let state = state.unwrap_or_else(|| vec![0.0; model.mesh.n_nodes() * FIELDS]);
        let dead_load = if model.has_dead_loads() {
            model.dead_load_forces()
        } else {
            Vec::new()
        };
        let volume_control = model.pressures.iter().enumerate().find_map(|(i, p)| {
            p.volume.map(|target| VolumeControl {
                pressure: i,
                start: crate::problem::pressure::enclosed_volume(&p.faces, &state),
                target,
                level: 0.0,
            })
        });
        let mut problem = StaticProblem {
            model,
            dofs,
            assembler,
            start: state.clone(),
            state,
            cell_energy: Vec::new(),
            floor,
            load: 0.0,
            dead_load,
            factored_at: None,
            points: PointStates::new(model),
            duration: 0.0,
            committed_load: 0.0,
            s: 0.0,
            drive: Drive::ramped(model),
            dissipated: 0.0,
            dissipated_step: 0.0,
            extra_charges: Vec::new(),
            keep_cell_tangents: false,
            kept: KeptTangents::default(),
            volume_control,
        };
        problem.set_drive(Drive::ramped(model));
        problem
    }

    /// Takes the stage's drive: the supports go from the problem's start state to the model's
    /// targets, the loads and the volume-controlled pressure's level start from the drive's
    /// values at load factor 0 (the current load factor is kept).
    pub fn set_drive(&mut self, mut drive: Drive) {
        drive.support_from(&self.start, &self.model.dirichlet);
        self.load = drive.dead_loads.at(self.s);
        if let Some(c) = self.volume_control.as_mut() {
            c.level = drive.pressures[c.pressure].from;
        }
        self.drive = drive;
    }

    /// The stage's drive.
    pub fn drive(&self) -> &Drive {
        &self.drive
    }

    /// The state at load factor 0 (where the supports start).
    pub fn start(&self) -> &[f64] {
        &self.start
    }

    /// The load factor of the current state.
    pub fn load_factor(&self) -> f64 {
        self.s
    }

    /// The fraction of each pressure's value acting at the current state: its ramp at the load
    /// factor, or the unknown level of the volume-controlled one.
    pub fn pressure_fractions(&self) -> Vec<f64> {
        let mut f: Vec<f64> = self
            .model
            .pressures
            .iter()
            .zip(&self.drive.pressures)
            .map(|(_, r)| r.at(self.s))
            .collect();
        if let Some(c) = &self.volume_control {
            f[c.pressure] = c.level;
        }
        f
    }

    /// ∂r/∂p of pressure `i`'s value p at the current state and load factor, per dof (unscaled,
    /// zero where the pressure does not act): its residual terms at 1 Pa, since they are linear
    /// in p.
    pub fn pressure_forces(&self, i: usize) -> Vec<f64> {
        let mut out = vec![0.0; self.state.len()];
        let fraction = self.pressure_fractions()[i];
        if fraction != 0.0 {
            let unit = crate::problem::pressure::Pressure {
                value: 1.0,
                ..self.model.pressures[i].clone()
            };
            crate::problem::pressure::add_pressure(&unit, fraction, &self.state, &mut out, None);
        }
        out
    }

    /// Current load factor of the dead loads.
    pub fn load(&self) -> f64 {
        self.load
    }

    /// Assembles every cell on this process even when the model's cells are shared between
    /// processes: for analyses that use the tangent itself (modes, frequency response) rather
    /// than hand it to a distributed solver.
    pub fn assemble_every_cell(&mut self) {
        if self.assembler.is_shared() {
            self.assembler = Assembler::new(&self.model.mesh, &self.dofs);
        }
    }

    /// The assembler (for benchmarks).
    pub fn assembler(&self) -> &Assembler {
        &self.assembler
    }

    /// Total stored energy split `(mechanical, electric)` (J) at the current state.
    pub fn energies(&self) -> Result<(f64, f64), String> {
        energies_with(self.model, &self.state, &self.points)
    }

    /// Marks the current state (a resumed run's, at load factor `s`) as the committed one, with the
    /// point states already set.
    pub fn accept_resumed(&mut self, s: f64) {
        self.s = s;
        self.committed_load = s;
    }

    /// Time step (s) from the committed state to the current one.
    fn dt(&self) -> f64 {
        (self.s - self.committed_load) * self.duration
    }

    /// The inputs of the cells' tangents as a stamp of [`KeptTangents`]: the state, the step
    /// of the internal variables' update and the committed internal variables.
    fn tangent_stamp(&self) -> Vec<f64> {
        let mut stamp = Vec::with_capacity(self.state.len() + 1 + self.points.data.len());
        stamp.extend_from_slice(&self.state);
        stamp.push(self.dt());
        stamp.extend_from_slice(&self.points.data);
        stamp
    }

    /// The free charges on potential equations besides the model's dead loads (node of an
    /// electrode's potential unknown, C): `extra_charges`, and the drive's charges at the load
    /// factor and its stage time.
    pub fn free_charges(&self) -> Vec<(usize, f64)> {
        let mut charges = self.extra_charges.clone();
        charges.extend(self.drive.charges_at(self.s * self.duration, self.s));
        charges
    }

    /// Unscaled nodal reactions ∂Π/∂x of every dof (N for u, C for Φ): internal forces minus the
    /// dead loads at the current load factor; zero at the free dofs of an equilibrium.
    pub fn nodal_reactions(&self) -> Result<Vec<f64>, String> {
        let mut r = nodal_reactions_with(self.model, &self.state, &self.points, self.dt())?;
        for (v, t) in r.iter_mut().zip(&self.dead_load) {
            *v -= self.load * t;
        }
        for (node, q) in self.free_charges() {
            r[node * FIELDS + PHI] += q;
        }
        for (p, f) in self.model.pressures.iter().zip(self.pressure_fractions()) {
            crate::problem::pressure::add_pressure(p, f, &self.state, &mut r, None);
        }
        Ok(r)
    }
}

/// Adds the pressures at their `fractions` of their values to the scaled residual of the free
/// equations and, with `k`, their stiffness (scaled like the cells' entries).
fn add_pressures(
    m: &Model,
    fractions: &[f64],
    state: &[f64],
    dofs: &crate::problem::dofs::DofMap,
    r: &mut [f64],
    mut k: Option<GlobalTerms<'_>>,
) {
    let mut full = vec![0.0; state.len()];
    for (p, &load) in m.pressures.iter().zip(fractions) {
        if load == 0.0 {
            continue;
        }
        match k.as_mut() {
            Some(k) => {
                let mut put = |i: usize, j: usize, v: f64| {
                    let (ei, ej) = (dofs.eq[i], dofs.eq[j]);
                    if ei == CONSTRAINED || ej == CONSTRAINED {
                        return;
                    }
                    k.add(ei, ej, dofs.scale[i % FIELDS] * dofs.scale[j % FIELDS] * v);
                };
                crate::problem::pressure::add_pressure(p, load, state, &mut full, Some(&mut put));
            }
            None => crate::problem::pressure::add_pressure(p, load, state, &mut full, None),
        }
    }
    for (d, v) in full.iter().enumerate() {
        let e = dofs.eq[d];
        if e != CONSTRAINED && *v != 0.0 {
            r[e] += dofs.scale[d % FIELDS] * v;
        }
    }
}

/// Mechanical strain energy and electric field energy (J) of a state (of elastic materials, or
/// of the virgin point states).
pub fn energies(model: &Model, state: &[f64]) -> Result<(f64, f64), String> {
    energies_with(model, state, &PointStates::default())
}

/// [`energies`] with the committed point states (the branches' stored energy included).
/// Every cell is evaluated: for a model whose cells no processes share ([`record_with`] is the
/// pass of a shared one).
pub fn energies_with(
    model: &Model,
    state: &[f64],
    points: &PointStates,
) -> Result<(f64, f64), String> {
    let (mut mech, mut elec) = (0.0, 0.0);
    model.for_each_cell(state, |c, g, mat, local| {
        let (a, b) = model
            .kernel()
            .energy_split(&CellInput {
                geom: g,
                mat,
                hist: points.cell(c, model.cell_material[c], 0.0),
                local,
            })
            .map_err(|e| format!("cell {c}: {}", e.error))?;
        mech += a;
        elec += b;
        Ok::<(), String>(())
    })?;
    Ok((mech, elec))
}

/// Internal forces ∂(∫Ψ dV)/∂x for every dof of a state (N for u, C for Φ). Dead loads are not
/// included: where one acts on a constrained node, subtract
/// [`Model::dead_load_forces`] for its reaction.
pub fn nodal_reactions(model: &Model, state: &[f64]) -> Result<Vec<f64>, String> {
    nodal_reactions_with(model, state, &PointStates::default(), 0.0)
}

/// [`nodal_reactions`] of a step of `dt` from committed point states.
/// Every cell is evaluated: for a model whose cells no processes share ([`record_with`] is the
/// pass of a shared one).
pub fn nodal_reactions_with(
    model: &Model,
    state: &[f64],
    points: &PointStates,
    dt: f64,
) -> Result<Vec<f64>, String> {
    internal_forces(model, state, points, dt, None)
}

/// The internal forces of [`nodal_reactions_with`], from every cell, or with `only = (m, mat)`
/// from the cells of material `m` alone, evaluated with `mat` in its place.
fn internal_forces(
    model: &Model,
    state: &[f64],
    points: &PointStates,
    dt: f64,
    only: Option<(usize, &dyn Material)>,
) -> Result<Vec<f64>, String> {
    let nl = model.mesh.kind.nodes_per_cell() * FIELDS;
    let kernel = model.kernel();
    let eval = |c: usize| -> Result<[f64; MAX_LOCAL], String> {
        let mut local = [0.0; MAX_LOCAL];
        for (a, &node) in model.mesh.cell(c).iter().enumerate() {
            local[a * FIELDS..(a + 1) * FIELDS]
                .copy_from_slice(&state[node * FIELDS..(node + 1) * FIELDS]);
        }
        let m = model.cell_material[c];
        let input = CellInput {
            geom: &model.geometry(c),
            mat: only.map_or(model.materials[m].as_ref(), |(_, instead)| instead),
            hist: points.cell(c, m, dt),
            local: &local[..nl],
        };
        let mut r = [0.0; MAX_LOCAL];
        kernel
            .residual_tangent(&input, &mut r[..nl], None)
            .map_err(|e| format!("cell {c}: {} at quadrature point {}", e.error, e.qp))?;
        Ok(r)
    };
    let cells: Vec<usize> = (0..model.mesh.n_cells())
        .filter(|&c| only.is_none_or(|(m, _)| model.cell_material[c] == m))
        .collect();
    // their forces added in cell order (the same sums on any number of threads)
    let done = crate::problem::assembly::map_cells(&cells, eval);
    let mut out = vec![0.0; state.len()];
    for (&c, r) in cells.iter().zip(done) {
        let r = r?;
        for (a, &node) in model.mesh.cell(c).iter().enumerate() {
            for f in 0..FIELDS {
                out[node * FIELDS + f] += r[a * FIELDS + f];
            }
        }
    }
    Ok(out)
}

/// ∂f/∂θₖ for every parameter θₖ of material `material` ([`Material::parameters`]): the
/// derivatives of the internal forces of [`nodal_reactions_with`] (every dof; N for u, C for Φ
/// per unit of the parameter), from the cells of that material, each computed by the model's own
/// kernel with the material's [`ParameterDerivative`] (exact). Empty for a material without a
/// parameter vector.
pub fn parameter_forces(
    model: &Model,
    state: &[f64],
    points: &PointStates,
    dt: f64,
    material: usize,
    entries: Option<&[usize]>,
) -> Result<Vec<Vec<f64>>, String> {
    let base = model
        .materials
        .get(material)
        .ok_or_else(|| format!("no material {material}"))?;
    let n = base.parameters().map_or(0, |p| p.values.len());
    (0..n)
        .map(|index| {
            if entries.is_some_and(|e| !e.contains(&index)) {
                return Ok(Vec::new());
            }
            let derivative = ParameterDerivative {
                base: base.clone(),
                index,
            };
            internal_forces(model, state, points, dt, Some((material, &derivative)))
        })
        .collect()
}

/// wᵀ ∂f/∂θ of material `material` for `w` over every dof: the parameter vector–Jacobian product
/// of the internal forces, one entry per parameter ([`parameter_forces`]; 0 at the entries
/// `entries` leaves out).
pub fn parameter_vjp(
    model: &Model,
    state: &[f64],
    points: &PointStates,
    dt: f64,
    material: usize,
    entries: Option<&[usize]>,
    w: &[f64],
) -> Result<Vec<f64>, String> {
    Ok(
        parameter_forces(model, state, points, dt, material, entries)?
            .iter()
            .map(|f| f.iter().zip(w).map(|(a, b)| a * b).sum())
            .collect(),
    )
}

/// What the record of a state needs of the cells (see [`record_with`]).
#[derive(Debug)]
pub struct CellsRecord {
    /// The nodal reactions of [`nodal_reactions_with`] (at Δt = 0).
    pub reactions: Vec<f64>,
    /// The energies of [`energies_with`].
    pub energies: (f64, f64),
    /// The fields of [`cell_fields_with`].
    pub fields: Vec<CellFields>,
}

/// What the record of a state needs, in one pass over the cells (see
/// [`CellKernel::record`](crate::element::CellKernel::record)), at committed point states.
///
/// When processes share the cells ([`Model::share`]), each evaluates its own cells only: the
/// reactions and energies are summed over the processes (every process receiving the same
/// bits), and the fields of the other processes' cells are zero, except in an axisymmetric
/// model, whose fields are summed too (its revolved view is written whole by one process; its
/// meshes are small). A cell failing on any process fails the record on every process.
pub fn record_with(
    model: &Model,
    state: &[f64],
    points: &PointStates,
) -> Result<CellsRecord, String> {
    use crate::element::MAX_LOCAL;
    let n_cells = model.mesh.n_cells();
    let share = model.share.as_deref();
    let owned = |c: usize| model.owns(c);
    let nl = model.mesh.kind.nodes_per_cell() * FIELDS;
    // one cell's residual, energy split and fields
    let eval = |c: usize| {
        let mut local = [0.0; MAX_LOCAL];
        for (a, &node) in model.mesh.cell(c).iter().enumerate() {
            local[a * FIELDS..(a + 1) * FIELDS]
                .copy_from_slice(&state[node * FIELDS..(node + 1) * FIELDS]);
        }
        let mut r = [0.0; MAX_LOCAL];
        let m = model.cell_material[c];
        let input = CellInput {
            geom: &model.geometry(c),
            mat: model.materials[m].as_ref(),
            hist: points.cell(c, m, 0.0),
            local: &local[..nl],
        };
        let out = model.kernel().record(&input, &mut r);
        out.map(|(split, f)| (r, split, f))
            .map_err(|e| (c, format!("cell {c}: {}", e.error)))
    };
    let mut out = CellsRecord {
        reactions: vec![0.0; state.len()],
        energies: (0.0, 0.0),
        fields: Vec::with_capacity(n_cells),
    };
    // one cell's contributions, added in cell order on either path
    let mut add = |c: usize, r: &[f64], (a, b): (f64, f64), f: CellFields| {
        for (a, &node) in model.mesh.cell(c).iter().enumerate() {
            for f in 0..FIELDS {
                out.reactions[node * FIELDS + f] += r[a * FIELDS + f];
            }
        }
        out.energies.0 += a;
        out.energies.1 += b;
        out.fields.push(f);
    };
    // a cell's outcome (`None`: another process's cell), added in cell order on either path;
    // false after a failure, which ends the pass
    let mut failure = None;
    type Outcome = Result<([f64; MAX_LOCAL], (f64, f64), CellFields), (usize, String)>;
    let mut take = |c: usize, cell: Option<Outcome>| match cell {
        None => {
            add(c, &[0.0; MAX_LOCAL], (0.0, 0.0), CellFields::zero());
            true
        }
        Some(Ok((r, split, f))) => {
            add(c, &r, split, f);
            true
        }
        Some(Err(e)) => {
            failure = Some(e);
            false
        }
    };
    let all: Vec<usize> = (0..n_cells).collect();
    let cells = crate::problem::assembly::map_cells(&all, |c| owned(c).then(|| eval(c)));
    for (c, cell) in cells.into_iter().enumerate() {
        if !take(c, cell) {
            break;
        }
    }
    let Some(share) = share else {
        return match failure {
            Some((_, message)) => Err(message),
            None => Ok(out),
        };
    };
    // the processes' sums: reactions, the two energies and, in an axisymmetric model, the
    // fields
    let whole_fields = model.is_axisymmetric() && failure.is_none();
    let mut v = std::mem::take(&mut out.reactions);
    v.extend_from_slice(&[out.energies.0, out.energies.1]);
    if model.is_axisymmetric() {
        let zero = CellFields::zero();
        for c in 0..n_cells {
            v.extend_from_slice(&out.fields.get(c).unwrap_or(&zero).to_array());
        }
    }
    share.sum_unless_failed(&mut v, failure.as_ref().map(|f| f.0))?;
    if let Some((_, message)) = failure {
        return Err(message);
    }
    let n = state.len();
    if whole_fields {
        for (f, values) in out
            .fields
            .iter_mut()
            .zip(v[n + 2..].chunks(CellFields::VALUES))
        {
            *f = CellFields::from_array(values);
        }
    }
    out.energies = (v[n], v[n + 1]);
    v.truncate(n);
    out.reactions = v;
    Ok(out)
}

/// Per-cell output fields of a state.
pub fn cell_fields(model: &Model, state: &[f64]) -> Result<Vec<CellFields>, String> {
    cell_fields_with(model, state, &PointStates::default())
}

/// The material point of `state` nearest its material's locking limit: how far towards it (1 =
/// locked), the material's index and the key of the limit's parameter; `None` when no material
/// has such a limit. Names a failure at a material limit (a Gent network locking) as such.
pub fn nearest_locking(model: &Model, state: &[f64]) -> Option<(f64, usize, &'static str)> {
    use crate::material::{Mat3, Vec3};
    let kernel = model.kernel();
    let points = PointStates::default();
    let mut at = vec![(Mat3::zeros(), Vec3::zeros()); crate::fem::MAX_QP];
    let mut best: Option<(f64, usize, &'static str)> = None;
    let _ = model.for_each_cell(state, |c, g, mat, local| {
        let input = CellInput {
            geom: g,
            mat,
            hist: points.cell(c, model.cell_material[c], 0.0),
            local,
        };
        if kernel.point_deformations(&input, &mut at).is_ok() {
            for (f, _) in &at[..g.n_qp] {
                if let Some((x, key)) = mat.locking(f) {
                    if x.is_finite() && best.is_none_or(|b| x > b.0) {
                        best = Some((x, model.cell_material[c], key));
                    }
                }
            }
        }
        Ok::<(), ()>(())
    });
    best
}

/// [`cell_fields`] at committed point states.
/// Every cell is evaluated: for a model whose cells no processes share ([`record_with`] is the
/// pass of a shared one).
pub fn cell_fields_with(
    model: &Model,
    state: &[f64],
    points: &PointStates,
) -> Result<Vec<CellFields>, String> {
    let mut out = Vec::with_capacity(model.mesh.n_cells());
    model.for_each_cell(state, |c, g, mat, local| {
        out.push(
            model
                .kernel()
                .fields(&CellInput {
                    geom: g,
                    mat,
                    hist: points.cell(c, model.cell_material[c], 0.0),
                    local,
                })
                .map_err(|e| format!("cell {c}: {}", e.error))?,
        );
        Ok::<(), String>(())
    })?;
    Ok(out)
}

impl NonlinearSystem for StaticProblem<'_> {
    fn n(&self) -> usize {
        self.dofs.n_free
    }

    fn evaluate(&mut self, r: &mut [f64], mut k: Option<&mut CsrMatrix>) -> Result<(), String> {
        let m = self.model;
        let (points, dt) = (&self.points, self.dt());
        let cell_kernel = m.kernel();
        // every displacement held (the electrostatic projection of a dynamic step): the residual
        // and tangent have Φ rows only (the cell energies are then not evaluated)
        let potential_only = self.dofs.n_free == self.dofs.n_free_phi;
        let rows = if potential_only {
            Rows::Potential
        } else {
            Rows::All
        };
        let slots = self
            .kept
            .begin(m, self.keep_cell_tangents && k.is_some(), rows);
        let keep = slots.is_some();
        let kernel = |c: usize, local: &[f64], rl: &mut [f64], kl: Option<&mut [f64]>| {
            let input = CellInput {
                geom: &m.geometry(c),
                mat: m.materials[m.cell_material[c]].as_ref(),
                hist: points.cell(c, m.cell_material[c], dt),
                local,
            };
            let fail = |e: crate::element::PointFailure| {
                format!("{} at quadrature point {}", e.error, e.qp)
            };
            let nl = local.len();
            match (potential_only, kl, slots) {
                (true, None, _) => cell_kernel
                    .potential_residual(&input, rl)
                    .map(|()| 0.0)
                    .map_err(fail),
                (true, Some(kl), slots) => {
                    cell_kernel
                        .potential_residual_tangent(&input, rl, &mut *kl)
                        .map_err(fail)?;
                    if let Some(slots) = slots {
                        KeptTangents::keep(slots, c, kl, nl, rows);
                    }
                    Ok(0.0)
                }
                (false, Some(kl), Some(slots)) => {
                    let energy = cell_kernel
                        .residual_tangent(&input, rl, Some(&mut *kl))
                        .map_err(fail)?;
                    KeptTangents::keep(slots, c, kl, nl, rows);
                    Ok(energy)
                }
                (false, kl, _) => cell_kernel.residual_tangent(&input, rl, kl).map_err(fail),
            }
        };
        let cells = self.assembler.assemble(
            &m.mesh,
            &self.dofs,
            &self.state,
            kernel,
            r,
            k.as_deref_mut(),
            &mut self.cell_energy,
        );
        self.assembler.combine(r, cells)?;
        if keep {
            let stamp = self.tangent_stamp();
            self.kept.filled_at(stamp);
        }
        // the terms below are no cell terms: in the residual everywhere, in the tangent once
        let k = self.assembler.global_terms(k);
        // dead loads: −s·f on the free displacement rows (scaled residual s_f·r)
        if self.load != 0.0 {
            for (d, &t) in self.dead_load.iter().enumerate() {
                let e = self.dofs.eq[d];
                if e != CONSTRAINED && t != 0.0 {
                    r[e] -= self.dofs.scale[d % FIELDS] * self.load * t;
                }
            }
        }
        for (node, q) in self.free_charges() {
            let e = self.dofs.eq[node * FIELDS + PHI];
            if e != CONSTRAINED {
                r[e] += self.dofs.scale[PHI] * q;
            }
        }
        if !m.pressures.is_empty() {
            let fractions = self.pressure_fractions();
            add_pressures(m, &fractions, &self.state, &self.dofs, r, k);
        }
        Ok(())
    }

    fn increment(&mut self, dx: &[f64], alpha: f64) {
        self.dofs.add_scaled(&mut self.state, dx, alpha);
    }

    /// The state followed by the dead-load factor (which the state does not carry, unlike
    /// the prescribed values).
    fn snapshot(&self) -> Vec<f64> {
        let mut s = Vec::with_capacity(self.state.len() + 3);
        s.extend_from_slice(&self.state);
        s.push(self.load);
        s.push(self.s);
        if let Some(c) = &self.volume_control {
            s.push(c.level);
        }
        s
    }

    /// Accepts a snapshot, or a bare state (the load factor is then kept).
    fn restore(&mut self, s: &[f64]) {
        let n = self.state.len();
        self.state.copy_from_slice(&s[..n]);
        if let Some(&load) = s.get(n) {
            self.load = load;
        }
        if let Some(&factor) = s.get(n + 1) {
            self.s = factor;
        }
        if let (Some(&level), Some(c)) = (s.get(n + 2), self.volume_control.as_mut()) {
            c.level = level;
        }
    }

    /// Volume control: μ the pressure's fraction, g = V(x) − V̄(s) with V̄ linear in the load
    /// factor from the stage's start volume to the target; b = ∂r/∂μ is the pressure's load
    /// vector per unit fraction, −∂V/∂x scaled by its value, so c = ∂V/∂x = −b / value.
    fn border(&self) -> Result<Option<crate::algebra::system::Border>, String> {
        let Some(c) = self.volume_control.as_ref() else {
            return Ok(None);
        };
        let p = &self.model.pressures[c.pressure];
        let mut full = vec![0.0; self.state.len()];
        crate::problem::pressure::add_pressure(p, 1.0, &self.state, &mut full, None);
        let mut b = vec![0.0; self.dofs.n_free];
        for (d, v) in full.iter().enumerate() {
            let e = self.dofs.eq[d];
            if e != CONSTRAINED && *v != 0.0 {
                b[e] += self.dofs.scale[d % FIELDS] * v;
            }
        }
        let cvec = b.iter().map(|v| -v / p.value).collect();
        Ok(Some(crate::algebra::system::Border {
            b,
            c: cvec,
            measure: crate::problem::pressure::enclosed_volume(&p.faces, &self.state),
            start: c.start,
            end: c.target,
            load: self.s,
            rtol: 1e-11,
        }))
    }

    fn increment_border(&mut self, delta: f64) {
        if let Some(c) = self.volume_control.as_mut() {
            c.level += delta;
        }
    }

    fn new_matrix(&self) -> CsrMatrix {
        self.assembler.new_matrix()
    }

    fn expected_negative_pivots(&self) -> usize {
        self.dofs.n_free_phi
    }

    fn residual_floor(&self) -> f64 {
        self.floor
    }

    fn factored(&mut self) {
        match &mut self.factored_at {
            Some(s) => s.copy_from_slice(&self.state),
            None => self.factored_at = Some(self.state.clone()),
        }
    }

    fn groups(&self) -> Vec<u8> {
        self.dofs.groups()
    }

    fn shares_cells(&self) -> bool {
        self.assembler.is_shared()
    }

    /// [`DIFFERENCE_STRAIN`] of the mean cell size.
    fn difference_step(&self) -> Option<f64> {
        let h = self.model.cell_size();
        (h > 0.0 && h.is_finite()).then_some(DIFFERENCE_STRAIN * h)
    }

    fn layout(&self) -> Option<DofLayout> {
        Some(layout_of(self.model, &self.dofs, &self.assembler))
    }
}

/// A load step (static, quasi-static, continuation, or the potential's projection): the new state
/// is the only state in its equations; the committed internal variables and the load factor's
/// prescribed values are its other inputs.
impl StepOperator for StaticProblem<'_> {
    fn level_vjp(&mut self, w: &[f64]) -> Result<LevelVjp, String> {
        let m = self.model;
        let weights = crate::problem::dofs::free_weights(&self.dofs, w);
        // the cells' tangents the last evaluation kept at this state, or a pass of their own
        let kept = self.kept.products(m, &self.tangent_stamp(), &weights);
        let (mut q_new, points) = match kept {
            Some(k) => {
                let points = points_products(m, &self.state, &self.points, self.dt(), &weights)?;
                (k, points)
            }
            None => {
                let p =
                    cell_products(m, &self.state, None, &[], &self.points, self.dt(), &weights)?;
                (p.stiffness, p.points)
            }
        };
        let fractions = self.pressure_fractions();
        for (pressure, &load) in m.pressures.iter().zip(&fractions) {
            if load != 0.0 {
                let mut put = |i: usize, j: usize, v: f64| q_new[j] += weights[i] * v;
                let mut unused = vec![0.0; self.state.len()];
                crate::problem::pressure::add_pressure(
                    pressure,
                    load,
                    &self.state,
                    &mut unused,
                    Some(&mut put),
                );
            }
        }
        Ok(LevelVjp {
            q_new,
            points,
            ..LevelVjp::default()
        })
    }

    /// Only the internal forces depend on a material's parameters. The scaling of the unknowns
    /// (from the moduli) is held: a numerical choice, not part of the equations. With every
    /// displacement held (the potential's projection) the weights have no displacement entries,
    /// so only the parameters that enter D0 take a pass over the cells; the others' entries are
    /// exactly zero.
    fn parameter_vjp(
        &mut self,
        w: &[f64],
        material: usize,
        entries: Option<&[usize]>,
    ) -> Result<Vec<f64>, String> {
        let potential_only = self.dofs.n_free == self.dofs.n_free_phi;
        let kept: Option<Vec<usize>> = match self.model.materials.get(material) {
            Some(mat) if potential_only => {
                let n = mat.parameters().map_or(0, |p| p.values.len());
                Some(
                    (0..n)
                        .filter(|&i| entries.is_none_or(|e| e.contains(&i)))
                        .filter(|&i| mat.parameter_enters_d0(i))
                        .collect(),
                )
            }
            _ => None,
        };
        parameter_vjp(
            self.model,
            &self.state,
            &self.points,
            self.dt(),
            material,
            kept.as_deref().or(entries),
            &crate::problem::dofs::free_weights(&self.dofs, w),
        )
    }
}

impl LoadedSystem for StaticProblem<'_> {
    /// The supports, dead loads and pressures at load factor `s` of the drive, its waveforms
    /// at stage time s·`duration`.
    fn set_load(&mut self, s: f64) {
        self.s = s;
        self.load = self.drive.dead_loads.at(s);
        self.drive.apply_supports(&mut self.state, s);
        self.drive
            .apply_voltages(&mut self.state, s * self.duration);
    }

    /// Commits the material points' internal variables at the accepted state.
    fn accept(&mut self) -> Result<bool, String> {
        let history = !self.points.is_empty();
        if history {
            let dt = self.dt();
            self.dissipated_step = self.points.commit(self.model, &self.state, dt)?;
            self.dissipated += self.dissipated_step;
        }
        self.committed_load = self.s;
        Ok(history)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{ElementKind, MeridianKind, Mesh};
    use crate::problem::assembly::{on_threads, CellShare};
    use std::sync::Arc;

    /// A smooth, small displacement and potential over the model's nodes.
    fn state_of(model: &Model) -> Vec<f64> {
        crate::problem::examples::wavy_state(model, 0.0, 1e-6, 1000.0)
    }

    /// The record of `model` at `state` by `size` processes sharing its cells in contiguous
    /// blocks, one record per process.
    fn shared_records(
        model: &Model,
        state: &[f64],
        size: usize,
    ) -> Vec<Result<CellsRecord, String>> {
        let n = model.mesh.n_cells();
        on_threads(size, |rank, sum| {
            let mut m = model.clone();
            let part: Vec<usize> = (0..n).map(|c| c * size / n).collect();
            m.hold_geometry_of(|c| part[c] == rank);
            m.share = Some(Arc::new(CellShare {
                part,
                rank,
                size,
                sum,
            }));
            record_with(&m, state, &PointStates::default())
        })
    }

    fn largest(v: &[f64]) -> f64 {
        v.iter().fold(0.0_f64, |m, x| m.max(x.abs()))
    }

    #[test]
    fn processes_sharing_the_cells_record_what_one_records() {
        let model = crate::problem::examples::film([4, 4, 3], ElementKind::Hex8, 1000.0).unwrap();
        let state = state_of(&model);
        let whole = record_with(&model, &state, &PointStates::default()).unwrap();
        let n = model.mesh.n_cells();
        for size in [2, 3] {
            let parts = shared_records(&model, &state, size);
            let first = parts[0].as_ref().unwrap();
            for (rank, part) in parts.iter().enumerate() {
                let part = part.as_ref().unwrap();
                // the same bits on every process
                assert_eq!(part.reactions, first.reactions);
                assert_eq!(part.energies, first.energies);
                for c in 0..n {
                    let expected = if c * size / n == rank {
                        whole.fields[c]
                    } else {
                        CellFields::zero()
                    };
                    assert_eq!(part.fields[c], expected, "{size} processes, cell {c}");
                }
            }
            let scale = largest(&whole.reactions);
            for (a, b) in first.reactions.iter().zip(&whole.reactions) {
                assert!((a - b).abs() <= 1e-13 * scale, "{size}: {a} against {b}");
            }
            for (a, b) in [
                (first.energies.0, whole.energies.0),
                (first.energies.1, whole.energies.1),
            ] {
                assert!((a - b).abs() <= 1e-13 * b.abs(), "{size}: {a} against {b}");
            }
        }
    }

    #[test]
    fn a_cell_failing_on_one_process_fails_the_record_on_every_process() {
        let model = crate::problem::examples::film([4, 4, 3], ElementKind::Hex8, 1000.0).unwrap();
        let mut state = state_of(&model);
        // the last cell turned inside out: its top corner pushed far through its bottom
        let c = model.mesh.n_cells() - 1;
        let node = model.mesh.cell(c)[6];
        state[node * FIELDS + 2] = -0.1;
        let own = record_with(&model, &state, &PointStates::default()).unwrap_err();
        let parts = shared_records(&model, &state, 2);
        let messages: Vec<String> = parts.into_iter().map(|p| p.err().unwrap()).collect();
        // the cell's owner reports its own failure, the other the owner's cell
        assert_eq!(messages[1], own);
        assert!(
            messages[0].contains("failed on another MPI rank"),
            "{}",
            messages[0]
        );
    }

    #[test]
    fn an_axisymmetric_record_holds_every_cells_fields_on_every_process() {
        // a 4 × 3 quad4 meridian section, R from 0 to 4 mm, Z from 0 to 0.6 mm
        let (nr, nz) = (4, 3);
        let mut nodes = Vec::new();
        for j in 0..=nz {
            for i in 0..=nr {
                nodes.push([1e-3 * i as f64, 0.2e-3 * j as f64, 0.0]);
            }
        }
        let mut connectivity = Vec::new();
        for j in 0..nz {
            for i in 0..nr {
                let a = j * (nr + 1) + i;
                connectivity.extend([a, a + 1, a + nr + 2, a + nr + 1]);
            }
        }
        let mesh = Mesh {
            kind: ElementKind::Meridian(MeridianKind::Quad4),
            nodes,
            connectivity,
            node_sets: Default::default(),
            face_sets: Default::default(),
            cell_sets: Default::default(),
        };
        let material = Arc::new(crate::material::ElectroNeoHooke::new(1e5, 1e7, 4.7));
        let model = Model::new(mesh, material).unwrap();
        let mut state = state_of(&model);
        // the unused third displacement slot of a meridian node
        (0..model.mesh.n_nodes()).for_each(|n| state[n * FIELDS + 2] = 0.0);
        let whole = record_with(&model, &state, &PointStates::default()).unwrap();
        for part in shared_records(&model, &state, 3) {
            let part = part.unwrap();
            assert_eq!(part.fields, whole.fields);
            let scale = largest(&whole.reactions);
            for (a, b) in part.reactions.iter().zip(&whole.reactions) {
                assert!((a - b).abs() <= 1e-13 * scale, "{a} against {b}");
            }
        }
    }
}
