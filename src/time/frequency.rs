//! Steady-state response to a small harmonic voltage about a biased equilibrium.
//!
//! About an equilibrium q₀ with the electrodes at their DC voltages, a small voltage
//! ṽ e^{iωt} on one electrode drives the linearised system
//!
//! ```text
//! (K − ω² M + iω C) x = −(∂r/∂V) ṽ,
//! ```
//!
//! with K the coupled tangent (the potential rows carry no mass and no damping, so the potential
//! is condensed by the solve itself), M the mass, C the Kelvin–Voigt tangent ∂f_vis/∂v and the
//! dashpots, and ∂r/∂V the change of the residual with the driven electrode's voltage at fixed
//! free unknowns. The residual is quadratic in the potential (the electric energy is quadratic in
//! the field), so its central difference in V is exact up to round-off; the force is ∝ 2V_dc ṽ for
//! the mechanical rows and vanishes at V_dc = 0 (a first-order response needs a bias).
//!
//! The complex symmetric system is factored by faer's sparse LU with partial pivoting (the
//! symbolic analysis once, the numeric factorisation per frequency): a symmetric indefinite LDLᵀ
//! without pivoting meets zero pivots where a diagonal entry of K − ω²M crosses zero, and an LU
//! does not. A sweep keeps each LU's storage from one frequency to the next and, for systems
//! small enough that one factorisation cannot use the threads well, takes the frequencies in
//! parallel (each thread factoring its frequencies alone, so the bits are the same on any
//! number of threads). A distributed run (processes that share the cells) instead hands each
//! process's part of the equivalent real symmetric system of twice the size ([`RealForm`]) to
//! its distributed solver (MUMPS's LDLᵀ with pivoting), so that no process holds the whole
//! matrices or a whole factor.

use crate::algebra::csr::CsrMatrix;
use crate::algebra::system::{DofLayout, NonlinearSystem};
use crate::element::{KelvinVoigtKernel, MAX_LOCAL};
use crate::problem::assembly::CellShare;
use crate::problem::dofs::{DofMap, CONSTRAINED, FIELDS, PHI};
use crate::problem::model::Model;
use crate::problem::statics::StaticProblem;
use crate::solve::linear::{LinearSolver, SolverSettings, PARALLEL_MIN_UNKNOWNS};
use crate::time::mass::NodalMass;
use crate::time::modal::EquationMass;
use faer::c64;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, NumericLu, SymbolicLu};
use faer::sparse::linalg::LuError;
use faer::sparse::FaerError;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Par};
use rayon::prelude::*;
use std::sync::Arc;

/// The linearised system about a biased state, in the equation space of its dof map. `k`, `m`,
/// `c` and the branch tangents are whole, or this process's part when [`linearise`] was given a
/// solver that sums the parts of processes sharing the cells ([`Linearisation::is_part`]; then
/// products with them are summed by [`Linearisation::sum_parts`] and they are solved by the
/// solvers of [`Linearisation::new_solver`]).
pub struct Linearisation {
    pub dofs: DofMap,
    /// The coupled tangent K.
    pub k: CsrMatrix,
    /// The mass M (zero on the potential rows).
    pub m: CsrMatrix,
    /// The damping C: the Kelvin–Voigt tangent ∂f_vis/∂v and the dashpots.
    pub c: CsrMatrix,
    /// −∂r/∂V of the driven electrode, per volt (equation space, scaled rows).
    pub force: Vec<f64>,
    /// The driven electrode's nodes.
    pub driven: Vec<usize>,
    /// Maxwell branches: relaxation time τ (s) and the branch's instantaneous tangent about the
    /// relaxed state (pattern of `k`); the stiffness at ω is K + Σ iωτ/(1 + iωτ) K_b.
    pub branches: Vec<(f64, CsrMatrix)>,
    /// The symbolic LU of the pattern and its 32-bit column pointers, computed at the first
    /// frequency.
    symbolic: Option<(SymbolicLu<u32>, Vec<u32>)>,
    /// The numeric LU and its workspace of [`Linearisation::response`], kept between
    /// frequencies (allocated afresh per frequency, they cost page faults: docs/validation.md).
    work: Option<LuWork>,
    /// The real form and its solver, when the linearisation was given a solver.
    real: Option<RealForm>,
    /// When `k`, `m`, `c` and the branch tangents are this process's parts: how they meet.
    parts: Option<Parts>,
}

/// y = M x in the equation space ([`Linearisation::mass_product`]).
pub type MassProduct<'a> = Box<dyn FnMut(&[f64], &mut [f64]) + 'a>;

/// What a process needs to use its parts of the linearised matrices in a distributed run.
struct Parts {
    /// The share of the cells, whose sum adds a vector over the processes.
    share: Arc<CellShare>,
    /// The layout of the equations, for new distributed solvers; its `owned` flags are the rows
    /// of this process's non-cell terms.
    layout: DofLayout,
    /// The nodal mass, whole on every process (products with M without a sum).
    mass: NodalMass,
}

/// A complex LU's numeric factor, values and workspace, reused from one frequency to the next.
#[derive(Default)]
struct LuWork {
    numeric: NumericLu<u32, c64>,
    values: Vec<c64>,
    /// The workspace and the size it was made for.
    mem: Option<(faer::dyn_stack::StackReq, MemBuffer)>,
}

/// (A + iB) x = f in real form for a solver of real symmetric matrices: with y = −Im x,
///
/// ```text
/// [ A   B ] [Re x]   [f]
/// [ B  −A ] [  y ] = [0],
/// ```
///
/// symmetric (indefinite) as A and B are. The unknowns are interleaved (2e: Re x_e, 2e + 1: y_e),
/// so each node's unknowns stay together; a process that holds part of A and B (its own cells)
/// holds the same part of this matrix, and a solver that sums the processes' parts gets it whole.
struct RealForm {
    solver: Box<dyn LinearSolver>,
    /// The pattern of K doubled, built at the first frequency.
    matrix: Option<CsrMatrix>,
}

impl RealForm {
    /// The real form's pattern from the pattern of `k` (zero values).
    fn pattern(k: &CsrMatrix) -> CsrMatrix {
        let nnz = k.nnz();
        let mut row_ptr = Vec::with_capacity(2 * k.n + 1);
        let mut col_idx = Vec::with_capacity(4 * nnz);
        row_ptr.push(0);
        for i in 0..k.n {
            let cols = &k.col_idx[k.row_ptr[i]..k.row_ptr[i + 1]];
            for _ in 0..2 {
                col_idx.extend(cols.iter().flat_map(|&j| [2 * j, 2 * j + 1]));
                row_ptr.push(col_idx.len());
            }
        }
        CsrMatrix::new(2 * k.n, row_ptr, col_idx, vec![0.0; 4 * nnz])
    }

    /// The layout of the real form's unknowns from that of the equations: the two copies of a
    /// node's unknowns are two nodes at its place (2N, 2N + 1), each with the node's fields, and
    /// each copy's rows go to the process that takes the node's terms.
    fn layout(layout: DofLayout) -> DofLayout {
        let twice =
            |v: &[usize]| -> Vec<usize> { v.iter().flat_map(|&n| [2 * n, 2 * n + 1]).collect() };
        DofLayout {
            node: twice(&layout.node),
            field: layout.field.iter().flat_map(|&f| [f, f]).collect(),
            coords: layout.coords.iter().flat_map(|&c| [c, c]).collect(),
            axisymmetric: layout.axisymmetric,
            shared: layout.shared,
            owned: layout
                .owned
                .map(|o| std::sync::Arc::new(o.iter().flat_map(|&own| [own, own]).collect())),
            // the frequency response runs on a replicated state
            equations: None,
        }
    }

    /// Fills the values from those of A and B (entry by entry on K's pattern), factors, and
    /// solves for the right-hand side `f`: (Re x, Im x).
    fn solve(
        &mut self,
        k: &CsrMatrix,
        a: &[f64],
        b: &[f64],
        f: &[f64],
    ) -> Result<(Vec<f64>, Vec<f64>), String> {
        let matrix = self.matrix.get_or_insert_with(|| Self::pattern(k));
        for i in 0..k.n {
            let (start, end) = (k.row_ptr[i], k.row_ptr[i + 1]);
            let width = 2 * (end - start);
            // rows 2i and 2i + 1 start at 4·start (each earlier row of K gave two rows twice as
            // long)
            let (upper, lower) =
                matrix.values[4 * start..4 * start + 2 * width].split_at_mut(width);
            for p in start..end {
                let q = 2 * (p - start);
                upper[q] = a[p];
                upper[q + 1] = b[p];
                lower[q] = b[p];
                lower[q + 1] = -a[p];
            }
        }
        self.solver.factor(matrix).map_err(|e| e.to_string())?;
        let mut rhs: Vec<f64> = f.iter().flat_map(|&v| [v, 0.0]).collect();
        self.solver
            .solve_in_place(&mut rhs)
            .map_err(|e| e.to_string())?;
        Ok((
            rhs.iter().step_by(2).copied().collect(),
            rhs.iter().skip(1).step_by(2).map(|&y| -y).collect(),
        ))
    }
}

/// `model` with every material replaced by the elastic material it relaxes to (the same model
/// when no material has internal variables).
pub fn relaxed_model(model: &Model) -> Model {
    let mut relaxed = model.clone();
    for m in relaxed.materials.iter_mut() {
        if let Some(r) = m.relaxed() {
            *m = r;
        }
    }
    relaxed
}

/// Linearises `model` (its Dirichlet conditions hold the supports and every electrode at its DC
/// voltage) about the equilibrium `state`; `driven` are the nodes of the electrode that carries
/// the small voltage, `viscosity` the Kelvin–Voigt viscosity of each material (Pa·s).
///
/// Materials with Maxwell branches are linearised about their relaxed state: `state` must be the
/// equilibrium of [`relaxed_model`]. With the viscous variable A at C̄⁻¹ the branch stress
/// vanishes for every F, so a small harmonic δF moves A by δA = (∂C̄⁻¹/∂F δF)/(1 + iωτ) and the
/// branch stress by ∂S/∂F|_A (1 − 1/(1 + iωτ)) δF: the instantaneous branch tangent times
/// iωτ/(1 + iωτ) (a standard linear solid per branch), exact to first order.
///
/// With a `solver`, each frequency is solved in real form by it ([`RealForm`]); a solver that
/// sums the shared entries of processes that share the cells then gets each process's part of
/// the matrices (its own cells, the mass and dashpots on the rows of its non-cell terms), and
/// `k`, `m`, `c` and the branch tangents are parts too. Without one, or for a solver of whole
/// matrices, they are whole on every process (the modal method needs them whole).
pub fn linearise(
    model: &Model,
    state: &[f64],
    mass: &NodalMass,
    viscosity: &[f64],
    driven: &[usize],
    solver: Option<Box<dyn LinearSolver>>,
) -> Result<Linearisation, String> {
    let relaxed = relaxed_model(model);
    let mut problem = StaticProblem::new(&relaxed, Some(state.to_vec()));
    problem.set_drive(crate::problem::drive::Drive::held(&relaxed));
    if solver.as_ref().is_none_or(|s| !s.sums_shared_entries()) {
        // the tangent itself is used here, not only handed to a solver that sums the parts
        problem.assemble_every_cell();
    }
    let n = problem.n();
    let mut k = problem.new_matrix();
    let mut r = vec![0.0; n];
    problem.evaluate(&mut r, Some(&mut k))?;
    let dofs = problem.dofs.clone();
    // the mass once between the processes: on the rows of this process's non-cell terms (every
    // row without a share)
    let mut m = k.zeros_like();
    super::modal::add_mass_on_term_rows(&problem, mass, 1.0, &mut m);
    // Kelvin–Voigt tangent ∂f_vis/∂v at the state, and the dashpots
    let mut c = k.clone();
    let npc = model.mesh.kind.nodes_per_cell();
    let nl = npc * FIELDS;
    let kernel = |cell: usize, local: &[f64], rl: &mut [f64], kl: Option<&mut [f64]>| {
        rl[..nl].iter_mut().for_each(|v| *v = 0.0);
        let eta = viscosity
            .get(model.cell_material[cell])
            .copied()
            .unwrap_or(0.0);
        if let Some(kl) = kl {
            kl[..nl * nl].iter_mut().for_each(|v| *v = 0.0);
            if eta > 0.0 {
                let zero = [0.0; MAX_LOCAL];
                let mut rv = [0.0; MAX_LOCAL];
                KelvinVoigtKernel { eta }
                    .forces(&model.geometry(cell), local, &zero[..nl], &mut rv, Some(kl))
                    .map_err(|e| format!("{} at quadrature point {}", e.error, e.qp))?;
            }
        }
        Ok::<f64, String>(0.0)
    };
    let mut energy = Vec::new();
    problem
        .assembler()
        .assemble(
            &model.mesh,
            &dofs,
            state,
            kernel,
            &mut r,
            Some(&mut c),
            &mut energy,
        )
        .map_err(|f| format!("cell {}: {}", f.cell, f.error))?;
    {
        let mut terms = problem
            .assembler()
            .global_terms(Some(&mut c))
            .expect("a matrix was given");
        for &(node, damping) in &model.point_dampers {
            for i in 0..3 {
                let e = dofs.eq[node * FIELDS + i];
                if e != CONSTRAINED {
                    // once: by the process that takes the row's terms
                    terms.add(e, e, damping);
                }
            }
        }
    }
    // −∂r/∂V by a central difference (exact: r is quadratic in the potential)
    let h = 1.0;
    let mut plus = vec![0.0; n];
    let mut minus = vec![0.0; n];
    for (sign, out) in [(1.0, &mut plus), (-1.0, &mut minus)] {
        let mut s = state.to_vec();
        for &node in driven {
            s[node * FIELDS + PHI] += sign * h;
        }
        problem.state.copy_from_slice(&s);
        problem.evaluate(out, None)?;
    }
    let force: Vec<f64> = plus
        .iter()
        .zip(&minus)
        .map(|(p, q)| -(p - q) / (2.0 * h))
        .collect();
    let branches = branch_tangents(model, &relaxed, state, &problem, &k)?;
    let parts = match (&model.share, problem.shares_cells(), problem.layout()) {
        (Some(share), true, Some(layout)) => Some(Parts {
            share: share.clone(),
            layout,
            mass: mass.clone(),
        }),
        _ => None,
    };
    let real = solver.map(|mut solver| {
        if solver.needs_layout(2 * n) {
            if let Some(layout) = problem.layout() {
                solver.set_layout(RealForm::layout(layout));
            }
        }
        RealForm {
            solver,
            matrix: None,
        }
    });
    Ok(Linearisation {
        dofs,
        k,
        m,
        c,
        force,
        driven: driven.to_vec(),
        branches,
        symbolic: None,
        work: None,
        real,
        parts,
    })
}

/// Per Maxwell branch of each material: its relaxation time and its instantaneous tangent about
/// the relaxed state — the tangent of the material with every viscous variable at C̄⁻¹ (relaxed
/// by one backward-Euler update of a step much longer than every τ) at Δt = 0, minus the relaxed
/// material's, over the material's cells, shared among its branches by their moduli (each
/// neo-Hookean branch's tangent is its modulus times the same tensor when A = C̄⁻¹).
fn branch_tangents(
    model: &Model,
    relaxed: &Model,
    state: &[f64],
    problem: &StaticProblem,
    k: &CsrMatrix,
) -> Result<Vec<(f64, CsrMatrix)>, String> {
    let mut out = Vec::new();
    let longest = model
        .materials
        .iter()
        .flat_map(|m| m.maxwell_branches())
        .map(|b| b.1)
        .fold(0.0, f64::max);
    if longest <= 0.0 {
        return Ok(out);
    }
    // the relaxed variables of every cell: the tangent below is assembled over every cell, also
    // where processes share the cells (each would otherwise update its own cells only)
    let every_cell = Model {
        share: None,
        ..model.clone()
    };
    let mut points = crate::problem::points::PointStates::new(&every_cell);
    points.commit(&every_cell, state, 1e30 * longest)?;
    let n = k.n;
    let nl = model.mesh.kind.nodes_per_cell() * FIELDS;
    for (mi, material) in model.materials.iter().enumerate() {
        let branches = material.maxwell_branches();
        let total: f64 = branches.iter().map(|b| b.0).sum();
        if branches.is_empty() || total <= 0.0 {
            continue;
        }
        let kernel = model.kernel();
        let cell_kernel = |cell: usize, local: &[f64], rl: &mut [f64], kl: Option<&mut [f64]>| {
            rl[..nl].iter_mut().for_each(|v| *v = 0.0);
            let Some(kl) = kl else {
                return Ok(0.0);
            };
            kl[..nl * nl].iter_mut().for_each(|v| *v = 0.0);
            if model.cell_material[cell] != mi {
                return Ok(0.0);
            }
            let fail = |e: crate::element::PointFailure| {
                format!("{} at quadrature point {}", e.error, e.qp)
            };
            let mut r_tmp = [0.0; MAX_LOCAL];
            let mut k_eq = vec![0.0; nl * nl];
            let full = crate::element::CellInput {
                geom: &model.geometry(cell),
                mat: material.as_ref(),
                hist: points.cell(cell, mi, 0.0),
                local,
            };
            kernel
                .residual_tangent(&full, &mut r_tmp, Some(&mut *kl))
                .map_err(fail)?;
            let eq = crate::element::CellInput {
                geom: &model.geometry(cell),
                mat: relaxed.materials[mi].as_ref(),
                hist: crate::element::CellHistory::NONE,
                local,
            };
            kernel
                .residual_tangent(&eq, &mut r_tmp, Some(&mut k_eq))
                .map_err(fail)?;
            for (a, b) in kl[..nl * nl].iter_mut().zip(&k_eq) {
                *a -= b;
            }
            Ok::<f64, String>(0.0)
        };
        let mut d = k.clone();
        let mut r = vec![0.0; n];
        let mut energy = Vec::new();
        problem
            .assembler()
            .assemble(
                &model.mesh,
                &problem.dofs,
                state,
                cell_kernel,
                &mut r,
                Some(&mut d),
                &mut energy,
            )
            .map_err(|f| format!("cell {}: {}", f.cell, f.error))?;
        for &(g, tau) in &branches {
            let mut kb = d.clone();
            kb.values.iter_mut().for_each(|v| *v *= g / total);
            out.push((tau, kb));
        }
    }
    Ok(out)
}

impl Linearisation {
    /// Whether the drive reaches the mechanics to first order (false at zero DC bias).
    pub fn drives_motion(&self) -> bool {
        let fields = self.dofs.field_of_equation();
        let scale = self
            .force
            .iter()
            .zip(&fields)
            .filter(|(_, &f)| f == PHI)
            .map(|(v, _)| v.abs())
            .fold(0.0, f64::max);
        self.force
            .iter()
            .zip(&fields)
            .filter(|(_, &f)| f != PHI)
            .any(|(v, _)| v.abs() > 1e-12 * scale.max(f64::MIN_POSITIVE))
    }

    /// The complex response per volt at angular frequency `omega` (rad/s): (real, imaginary) parts
    /// of the state perturbation, `FIELDS` values per node (u in m/V, Φ in V/V; the driven
    /// electrode's nodes carry the applied 1 V in the real part).
    pub fn response(&mut self, omega: f64) -> Result<(Vec<f64>, Vec<f64>), String> {
        let hz = omega / (2.0 * std::f64::consts::PI);
        if let Some(mut real) = self.real.take() {
            let (a, b): (Vec<f64>, Vec<f64>) = (0..self.k.values.len())
                .map(self.view().entries(omega))
                .unzip();
            let x = real.solve(&self.k, &a, &b, &self.force);
            self.real = Some(real);
            let (xr, xi) =
                x.map_err(|e| format!("solving K − ω²M + iωC at {hz} Hz in real form: {e}"))?;
            return self.view().finish(hz, xr, xi);
        }
        self.analyse()?;
        let mut work = self.work.take().unwrap_or_default();
        let x = self
            .view()
            .complex_solve(omega, &mut work, faer::get_global_parallelism());
        self.work = Some(work);
        x
    }

    /// [`Linearisation::response`] at each of `omegas`, each response handed to `then` (which may
    /// run on any thread); the results in the order of `omegas`, or the error of the first
    /// frequency that failed. Small systems solved by the complex LU take the frequencies in
    /// parallel, each piece of the sweep reusing one LU's storage (each factorisation on its
    /// thread alone, so the results are the same bits on any number of threads); large ones, and
    /// the real form of a distributed run (whose processes must meet in the same order), one
    /// after the other.
    pub fn responses<T: Send>(
        &mut self,
        omegas: &[f64],
        then: impl Fn(&[f64], &[f64]) -> Result<T, String> + Sync,
    ) -> Result<Vec<T>, String> {
        // one frequency at a time for the real form and where one factorisation uses the threads
        if self.real.is_some() || self.k.n >= PARALLEL_MIN_UNKNOWNS {
            return omegas
                .iter()
                .map(|&omega| {
                    let (xr, xi) = self.response(omega)?;
                    then(&xr, &xi)
                })
                .collect();
        }
        self.analyse()?;
        let this = self.view();
        let results: Vec<Result<T, String>> = omegas
            .par_iter()
            .map_init(LuWork::default, |work, &omega| {
                let (xr, xi) = this.complex_solve(omega, work, Par::Seq)?;
                then(&xr, &xi)
            })
            .collect();
        results.into_iter().collect()
    }

    /// The symbolic analysis of the complex LU, once.
    fn analyse(&mut self) -> Result<(), String> {
        if self.symbolic.is_none() {
            // K, M, C are symmetric with one pattern: their CSR arrays are also the CSC arrays
            let row_ptr = self
                .k
                .row_ptr_u32()
                .ok_or("the tangent has more than 2^32 entries: too many for the complex LU")?;
            let pattern = SymbolicSparseColMatRef::new_checked(
                self.k.n,
                self.k.n,
                &row_ptr,
                None,
                &self.k.col_idx,
            );
            let symbolic = factorize_symbolic_lu(pattern, Default::default())
                .map_err(|e| format!("analysing the complex LU: {}", lu_failure(e)))?;
            self.symbolic = Some((symbolic, row_ptr));
        }
        Ok(())
    }

    /// Whether `k`, `m`, `c` and the branch tangents are this process's parts of a distributed
    /// run's matrices (the processes' parts add up to them).
    pub fn is_part(&self) -> bool {
        self.parts.is_some()
    }

    /// Sums `v` over the processes whose parts the matrices are; nothing when they are whole.
    pub fn sum_parts(&self, v: &mut [f64]) -> Result<(), String> {
        match &self.parts {
            Some(p) => (p.share.sum)(v),
            None => Ok(()),
        }
    }

    /// The product y = M x (equation space), whole on every process: with parts from the
    /// nodal mass itself, else with `m`.
    pub fn mass_product(&self) -> MassProduct<'_> {
        match &self.parts {
            Some(p) => {
                let mut m = EquationMass::new(&p.mass, &self.dofs);
                Box::new(move |x, y| m.mul(x, y))
            }
            None => Box::new(|x, y| self.m.mul_vec(x, y)),
        }
    }

    /// A new solver for matrices of the linearisation's pattern: the run's (`settings`), or for
    /// parts the distributed direct solver ([`SolverSettings::distributed_direct`]) with the
    /// equations' layout.
    pub fn new_solver(&self, settings: &SolverSettings) -> Result<Box<dyn LinearSolver>, String> {
        let Some(parts) = &self.parts else {
            return Ok(settings.build());
        };
        let mut solver = settings.distributed_direct().ok_or_else(|| {
            format!(
                "the matrices are parts of a distributed run, which the `{}` solver cannot sum",
                settings.kind.name()
            )
        })?;
        if solver.needs_layout(self.k.n) {
            solver.set_layout(parts.layout.clone());
        }
        Ok(solver)
    }

    /// Whether this process adds the terms of equation `e` that are added once between the
    /// processes (every equation when the matrices are whole).
    pub fn takes_terms_of(&self, e: usize) -> bool {
        self.parts
            .as_ref()
            .and_then(|p| p.layout.owned.as_ref())
            .is_none_or(|owned| owned[e])
    }

    /// How each frequency is solved, for reports.
    pub fn solved_by(&self) -> String {
        match &self.real {
            Some(real) => format!(
                "the real form [[A, B], [B, −A]] of (A + iB) x = f with {}{}{}",
                real.solver.name(),
                real.solver
                    .method()
                    .map(|m| format!(" ({m})"))
                    .unwrap_or_default(),
                if self.parts.is_some() {
                    ", each process holding its own cells' part"
                } else {
                    ""
                }
            ),
            None => "a complex sparse LU (faer) of K − ω²M + iωC".into(),
        }
    }

    /// What a frequency's solve reads, apart from the real form's solver (which is not shared
    /// between threads).
    fn view(&self) -> View<'_> {
        View {
            k: &self.k,
            m: &self.m,
            c: &self.c,
            branches: &self.branches,
            force: &self.force,
            dofs: &self.dofs,
            driven: &self.driven,
            symbolic: self.symbolic.as_ref(),
        }
    }
}

/// The parts of a [`Linearisation`] that a frequency's solve reads.
struct View<'a> {
    k: &'a CsrMatrix,
    m: &'a CsrMatrix,
    c: &'a CsrMatrix,
    branches: &'a [(f64, CsrMatrix)],
    force: &'a [f64],
    dofs: &'a DofMap,
    driven: &'a [usize],
    symbolic: Option<&'a (SymbolicLu<u32>, Vec<u32>)>,
}

impl View<'_> {
    /// The entries of A + iB = K − ω²M + iωC + Σ (the branches' complex moduli), by position in
    /// the pattern of K.
    fn entries(&self, omega: f64) -> impl Fn(usize) -> (f64, f64) + '_ {
        // iωτ/(1 + iωτ) = (ω²τ² + iωτ)/(1 + ω²τ²) per branch
        let factors: Vec<(f64, f64)> = self
            .branches
            .iter()
            .map(|(tau, _)| {
                let x = omega * tau;
                (x * x / (1.0 + x * x), x / (1.0 + x * x))
            })
            .collect();
        move |p: usize| {
            let (mut re, mut im) = (
                self.k.values[p] - omega * omega * self.m.values[p],
                omega * self.c.values[p],
            );
            for ((_, kb), (fr, fi)) in self.branches.iter().zip(&factors) {
                re += fr * kb.values[p];
                im += fi * kb.values[p];
            }
            (re, im)
        }
    }

    /// One frequency by the complex LU (the view of an analysed linearisation) in `work`, the
    /// factorisation and the solve run with `par`.
    fn complex_solve(
        &self,
        omega: f64,
        work: &mut LuWork,
        par: Par,
    ) -> Result<(Vec<f64>, Vec<f64>), String> {
        let n = self.k.n;
        let hz = omega / (2.0 * std::f64::consts::PI);
        let (symbolic, row_ptr) = self.symbolic.expect("analysed");
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, row_ptr, None, &self.k.col_idx);
        let entry = self.entries(omega);
        work.values.clear();
        work.values.extend((0..self.k.values.len()).map(|p| {
            let (re, im) = entry(p);
            c64::new(re, im)
        }));
        let req = symbolic
            .factorize_numeric_lu_scratch::<c64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<c64>(1, par));
        if work.mem.as_ref().is_none_or(|(r, _)| *r != req) {
            let buffer = MemBuffer::try_new(req).map_err(|_| {
                format!(
                    "factoring K − ω²M + iωC at {hz} Hz: {}",
                    lu_failure(FaerError::OutOfMemory)
                )
            })?;
            work.mem = Some((req, buffer));
        }
        let (_, buffer) = work.mem.as_mut().expect("set above");
        let matrix = SparseColMatRef::new(pattern, &work.values);
        let lu = symbolic
            .factorize_numeric_lu(
                &mut work.numeric,
                matrix,
                par,
                MemStack::new(buffer),
                Default::default(),
            )
            .inspect_err(|_| crate::solve::vector_state::clear_after(par, n))
            .map_err(|e| {
                let why = match e {
                    LuError::Generic(e) => lu_failure(e),
                    LuError::SymbolicSingular { index } => {
                        format!("no pivot in column {index} (a structurally singular matrix)")
                    }
                };
                format!("factoring K − ω²M + iωC at {hz} Hz: {why}")
            })?;
        let mut rhs = faer::Mat::<c64>::from_fn(n, 1, |i, _| c64::new(self.force[i], 0.0));
        lu.solve_in_place_with_conj(Conj::No, rhs.as_mut(), par, MemStack::new(buffer));
        crate::solve::vector_state::clear_after(par, n);
        self.finish(
            hz,
            (0..n).map(|i| rhs[(i, 0)].re).collect(),
            (0..n).map(|i| rhs[(i, 0)].im).collect(),
        )
    }

    /// The response as dof values, or the error of a non-finite solution.
    fn finish(&self, hz: f64, xr: Vec<f64>, xi: Vec<f64>) -> Result<(Vec<f64>, Vec<f64>), String> {
        if xr.iter().chain(&xi).any(|v| !v.is_finite()) {
            return Err(format!(
                "singular system at {hz} Hz (an undamped resonance?)"
            ));
        }
        Ok((self.to_dofs(&xr, 1.0), self.to_dofs(&xi, 0.0)))
    }

    /// A vector of the equation space as dof values, with `volts` on the driven electrode.
    fn to_dofs(&self, x: &[f64], volts: f64) -> Vec<f64> {
        let mut out = vec![0.0; self.dofs.eq.len()];
        for (d, &e) in self.dofs.eq.iter().enumerate() {
            if e != CONSTRAINED {
                out[d] = x[e] * self.dofs.scale[d % FIELDS];
            }
        }
        for &node in self.driven {
            out[node * FIELDS + PHI] = volts;
        }
        out
    }
}

/// A failure of faer's sparse complex LU, in words.
fn lu_failure(e: FaerError) -> String {
    match e {
        FaerError::IndexOverflow => "the factor would have more than 2^32 entries (34 GB and \
             more), more than the direct method indexes; method = \"modal\" needs no complex \
             factor (it projects onto the tangent's modes)"
            .into(),
        FaerError::OutOfMemory => "not enough memory for the factor; method = \"modal\" needs \
             no complex factor (it projects onto the tangent's modes)"
            .into(),
        e => format!("{e:?}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// faer's index overflow and allocation failure reach the user in words, with the way out.
    #[test]
    fn lu_failures_are_worded() {
        let overflow = lu_failure(FaerError::IndexOverflow);
        assert!(overflow.contains("2^32 entries") && overflow.contains("method = \"modal\""));
        let memory = lu_failure(FaerError::OutOfMemory);
        assert!(memory.contains("not enough memory") && memory.contains("method = \"modal\""));
        assert!(!overflow.contains("IndexOverflow") && !memory.contains("OutOfMemory"));
    }
}
