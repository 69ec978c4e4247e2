//! Linear solvers for the symmetric (indefinite) Newton systems.
//!
//! The coupled tangent is a saddle point: positive definite in u at a stable state, negative
//! definite in Φ. Such a quasi-definite matrix has an LDLᵀ factorisation without pivoting for every
//! symmetric ordering, and the signs of D give its inertia (Sylvester's law): a stable equilibrium
//! has exactly as many negative pivots as free potential dofs. One more negative pivot means the
//! mechanical part has lost stability (a limit point such as pull-in was passed).

use super::supernodal;
use crate::algebra::csr::CsrMatrix;
use crate::algebra::system::DofLayout;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::ldlt::factor::{LdltParams, LdltRegularization};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LdltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side, Spec};

/// Counts of positive, negative and zero pivots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Inertia {
    pub positive: usize,
    pub negative: usize,
    pub zero: usize,
}

/// Why a linear solve failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinearSolverError {
    #[error("singular matrix (zero pivot at {0})")]
    Singular(usize),
    #[error("symbolic analysis failed: {0}")]
    Symbolic(String),
    #[error("solve called before a successful factorisation")]
    NotFactored,
    #[error("the iterative solve did not converge: {0}")]
    NotConverged(String),
    /// A solver library failed, or an iterative solve did not converge (the message says which).
    #[error("{0}")]
    Failed(String),
    /// The factor would not fit in the memory allowed for it.
    #[error(
        "the sparse factor would need {:.2} GB, more than the {:.2} GB allowed \
         ([solver] memory_limit, or 80 % of the memory available); \
         kind = \"iterative\" needs memory linear in the unknowns",
        *needed as f64 / 1e9, *limit as f64 / 1e9
    )]
    OutOfMemory { needed: usize, limit: usize },
    /// The matrix or its factor has more entries than the direct solver's 32-bit indices count
    /// (2³², a factor of 34 GB and more).
    #[error(
        "the sparse factor would have more than 2^32 entries (34 GB and more), more than the \
         direct solver indexes; kind = \"iterative\" needs memory linear in the unknowns"
    )]
    TooLarge,
}

/// Memory the system can still give (bytes; Linux's `MemAvailable`), `None` where unknown.
pub fn available_memory() -> Option<usize> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: usize = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The memory a factor may take when no limit is set: 80 % of what is available.
fn default_memory_limit() -> usize {
    available_memory().map_or(usize::MAX, |m| m / 5 * 4)
}

/// A direct solver: factor once, solve many right-hand sides.
pub trait LinearSolver: Send {
    /// Factors `a` (symmetric, full storage). The pattern must stay the same between calls.
    /// Returns the inertia when the solver can tell it (a direct LDLᵀ); `None` otherwise, and
    /// Newton then reports the stability as not checked.
    fn factor(&mut self, a: &CsrMatrix) -> Result<Option<Inertia>, LinearSolverError>;
    /// Overwrites `b` with the solution of A x = b.
    fn solve_in_place(&mut self, b: &mut [f64]) -> Result<(), LinearSolverError>;
    /// Short name for reports.
    fn name(&self) -> &'static str;
    /// True when a factorisation is held (for modified Newton).
    fn is_factored(&self) -> bool {
        false
    }
    /// Drops the held factorisation (the matrix changed, e.g. a new time step size).
    fn invalidate(&mut self) {}
    /// Stored entries of the factor, for a direct solver (benchmarks).
    fn factor_nnz(&self) -> Option<usize> {
        None
    }
    /// Sets the matrix of the next solves (a Newton iteration's tangent). A solver that can
    /// solve with a matrix it has not factored (a held factorisation as the preconditioner of a
    /// Krylov method) may defer or skip the factorisation; the others factor it here. The
    /// inertia, when it matters, is asked for with [`LinearSolver::factor`].
    fn set_operator(&mut self, a: &CsrMatrix) -> Result<(), LinearSolverError> {
        self.factor(a).map(|_| ())
    }
    /// The method in use, where the solver's options choose it (e.g. PETSc's KSP and PC, known
    /// after the first factorisation), for reports.
    fn method(&self) -> Option<String> {
        None
    }
    /// Counts of the work done so far, for reports and benchmarks.
    fn stats(&self) -> SolverStats {
        SolverStats::default()
    }
    /// Whether the solver sums the tangents of processes that share the cells (over the entries
    /// [`DofLayout::entries`] names), rather than taking the matrix as the whole tangent.
    fn sums_shared_entries(&self) -> bool {
        false
    }
    /// Whether the solver wants the layout of a system of `n` unknowns ([`LinearSolver::set_layout`]).
    fn needs_layout(&self, _n: usize) -> bool {
        false
    }
    /// Where the unknowns sit, for a solver that splits the tangent into its fields.
    fn set_layout(&mut self, _layout: DofLayout) {}
    /// The relative residual the next solves need (Newton's forcing term), or `None` for the
    /// solver's own tolerance. An iterative solver may stop there instead of its own, tighter
    /// tolerance; the others solve exactly and ignore it.
    fn set_forcing(&mut self, _rtol: Option<f64>) {}
    /// Whether the solver keeps a factorisation of an earlier matrix across
    /// [`LinearSolver::set_operator`] calls and says so by its count of factorisations: Newton
    /// then marks the system as factored only when that count grows (where the held factor was
    /// made), so that a resumed run re-factors at the same point.
    fn reports_factor_points(&self) -> bool {
        false
    }
    /// Whether [`LinearSolver::solve_with_products`] may solve systems of `n` unknowns (it
    /// preconditions with a held factorisation and follows Newton's forcing term); Newton
    /// then takes its steps from products and makes no chord steps.
    fn accepts_products(&self, _n: usize) -> bool {
        false
    }
    /// Solves A x = b in place with A given by its products alone, `apply(v, y)` setting
    /// y = A v (false: the product could not be evaluated), to Newton's forcing term, where the
    /// solver holds a factorisation of a nearby matrix to precondition a Krylov method with.
    /// `Ok(false)` leaves `b` as it was: the solver holds no such factorisation, would renew
    /// it, or its Krylov method did not converge; the caller then gives it the matrix
    /// ([`LinearSolver::set_operator`]) and solves as usual.
    fn solve_with_products(
        &mut self,
        _apply: &mut dyn FnMut(&[f64], &mut [f64]) -> bool,
        _b: &mut [f64],
    ) -> Result<bool, LinearSolverError> {
        Ok(false)
    }
}

/// The relative residual a Krylov solve stops at: its own tolerance `own`, or Newton's forcing
/// term ([`LinearSolver::set_forcing`]) when the solver is adaptive and that is looser.
pub(crate) fn forced_tolerance(own: f64, adaptive: bool, forcing: Option<f64>) -> f64 {
    match (adaptive, forcing) {
        (true, Some(eta)) => eta.max(own),
        _ => own,
    }
}

/// Work counts of a linear solver.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct SolverStats {
    /// Numeric factorisations.
    pub factorizations: usize,
    /// Solves (right-hand sides).
    pub solves: usize,
    /// Krylov iterations in all.
    pub krylov_iterations: usize,
    /// Decades of residual reduction over all Krylov solves (the sum of −log₁₀ of each solve's
    /// final relative residual): iterations per decade compare preconditioners across solves
    /// to different tolerances.
    #[serde(default)]
    pub krylov_decades: f64,
}

impl std::ops::Add for SolverStats {
    type Output = SolverStats;

    /// The work of two solvers together (e.g. a time step's and its projection's).
    fn add(self, other: SolverStats) -> SolverStats {
        SolverStats {
            factorizations: self.factorizations + other.factorizations,
            solves: self.solves + other.solves,
            krylov_iterations: self.krylov_iterations + other.krylov_iterations,
            krylov_decades: self.krylov_decades + other.krylov_decades,
        }
    }
}

/// Fill-reducing ordering of [`FaerLdlt`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Ordering {
    /// METIS nested dissection (default; falls back to AMD if METIS fails).
    #[default]
    NestedDissection,
    /// faer's approximate minimum degree.
    Amd,
}

impl Ordering {
    /// Names in scenario files (`[solver] ordering`).
    pub const NAMES: [&'static str; 2] = ["nested-dissection", "amd"];

    /// Parses a name of [`Ordering::NAMES`].
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "nested-dissection" | "metis" => Some(Ordering::NestedDissection),
            "amd" => Some(Ordering::Amd),
            _ => None,
        }
    }
}

/// The kind of linear solver of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum SolverKind {
    /// By size: a fresh sparse LDLᵀ at every Newton iteration below [`REUSE_MIN_UNKNOWNS`]
    /// unknowns, above it the factorisation reused as the preconditioner of FGMRES
    /// ([`ReusedLdlt`](super::reused::ReusedLdlt)). Both give the inertia (the stability test).
    #[default]
    Auto,
    /// Sparse LDLᵀ ([`FaerLdlt`]) of every Newton tangent: exact, gives the inertia.
    Direct,
    /// FGMRES with AMG of the coupled tangent ([`AmgGmres`](super::iterative::AmgGmres)): memory
    /// linear in the unknowns, no inertia.
    Iterative,
    /// PETSc ([`super::petsc::PetscSolver`]): MUMPS LDLᵀ by default, any KSP/PC by options, on
    /// one or more MPI ranks.
    #[cfg(feature = "petsc")]
    Petsc,
}

/// From this many unknowns on, `auto` keeps factorisations across Newton iterations and steps
/// (below it a factorisation costs about as much as the Krylov iterations it would save).
pub const REUSE_MIN_UNKNOWNS: usize = 20_000;

impl SolverKind {
    /// Names in scenario files (`[solver] kind`) that this build accepts.
    #[cfg(not(feature = "petsc"))]
    pub const NAMES: &'static [&'static str] = &["auto", "direct", "iterative"];
    /// Names in scenario files (`[solver] kind`) that this build accepts.
    #[cfg(feature = "petsc")]
    pub const NAMES: &'static [&'static str] = &["auto", "direct", "iterative", "petsc"];
    /// Names of kinds that need a build with a Cargo feature, with that feature.
    pub const OPTIONAL: &'static [(&'static str, &'static str)] = &[("petsc", "petsc")];

    /// Parses a name of [`SolverKind::NAMES`].
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "auto" => Some(SolverKind::Auto),
            "direct" => Some(SolverKind::Direct),
            "iterative" => Some(SolverKind::Iterative),
            #[cfg(feature = "petsc")]
            "petsc" => Some(SolverKind::Petsc),
            _ => None,
        }
    }

    /// Name for messages and `summary.json`.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Auto => "auto",
            SolverKind::Direct => "direct",
            SolverKind::Iterative => "iterative",
            #[cfg(feature = "petsc")]
            SolverKind::Petsc => "petsc",
        }
    }
}

/// The linear solver settings of a run (`[solver]` in a scenario).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SolverSettings {
    pub kind: SolverKind,
    /// Fill-reducing ordering of the direct solver.
    pub ordering: Ordering,
    /// `auto` reuses factorisations from this many unknowns on ([`REUSE_MIN_UNKNOWNS`]).
    pub reuse_from: usize,
    /// `auto`: the precision of reused factorisations.
    #[serde(default)]
    pub precision: FactorPrecision,
    /// PETSc options (`-ksp_type minres -pc_type jacobi ...`) of the PETSc solver; empty for
    /// PETSc's defaults as deasim sets them (a direct MUMPS LDLᵀ).
    #[serde(default)]
    pub petsc_options: String,
    /// `iterative`, and `auto` once it has switched to it: relative residual of each solve.
    #[serde(default = "default_rtol")]
    pub rtol: f64,
    /// `iterative`, `auto` wherever it runs FGMRES, and `petsc` with an iterating KSP: stop each
    /// solve at Newton's forcing term when that is looser than the solver's own tolerance
    /// (Eisenstat–Walker); false: every solve to that tolerance. A scenario's default is true,
    /// and false for `petsc` (loose first directions can stall Newton on a large step).
    #[serde(default = "default_adaptive")]
    pub adaptive: bool,
    /// `auto` and `direct`: the largest factor (bytes) to hold; `None`: 80 % of the memory
    /// available when the factorisation starts. `auto` switches to `iterative` above it.
    #[serde(default)]
    pub memory_limit: Option<usize>,
    /// `petsc` with an iterating KSP: keep the preconditioner across Newton iterations and
    /// steps, set up anew only when it has grown stale or a solve fails; false: set up with
    /// every tangent.
    #[serde(default)]
    pub keep_preconditioner: bool,
    /// The matrix of the Newton iterations of implicit dynamic steps.
    #[serde(default)]
    pub jacobian: StepJacobian,
}

/// The precision in which `auto` holds the factorisations it reuses as preconditioners (from
/// [`SolverSettings::reuse_from`] unknowns on; smaller systems are factored in double precision
/// at every tangent either way).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum FactorPrecision {
    /// Single precision for the load steps of static stages with adaptive solves, where
    /// Newton's steps come from FGMRES on the tangent's products (the factor only
    /// preconditions them); double precision for the other analyses, which solve many systems
    /// with one factor.
    #[default]
    Auto,
    /// Double precision everywhere.
    Double,
    /// Single precision everywhere: half the factor's memory; FGMRES restores the accuracy.
    Single,
}

/// The matrix Newton iterates with in an implicit dynamic step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum StepJacobian {
    /// The exact, unsymmetric Jacobian of the step residual (with the configuration derivative
    /// of the Kelvin–Voigt forces), solved by FGMRES preconditioned by a held LDLᵀ factor of its
    /// symmetric part; a new tangent at every iteration. Kinds `auto` and `direct`; the others
    /// iterate with the symmetric matrix.
    Exact,
    /// The symmetric iteration matrix (without ∂f_vis/∂q), factored and reused across
    /// iterations and steps (modified Newton): the default, as a tangent costs many residuals
    /// and the examples run faster so (docs/validation.md).
    #[default]
    Symmetric,
}

impl StepJacobian {
    /// Names in scenario files (`[solver] jacobian`).
    pub const NAMES: &'static [&'static str] = &["exact", "symmetric"];

    /// The setting of a name of [`StepJacobian::NAMES`].
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "exact" => Some(StepJacobian::Exact),
            "symmetric" => Some(StepJacobian::Symmetric),
            _ => None,
        }
    }
}

/// Default relative residual of each iterative solve. Newton's tolerance is 1e-10 of its first
/// residual; steps accurate to 1e-8 of the current residual cost it at most one more iteration.
pub const DEFAULT_RTOL: f64 = 1e-8;

fn default_rtol() -> f64 {
    DEFAULT_RTOL
}

fn default_adaptive() -> bool {
    true
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            kind: SolverKind::default(),
            ordering: Ordering::default(),
            reuse_from: REUSE_MIN_UNKNOWNS,
            precision: FactorPrecision::default(),
            petsc_options: String::new(),
            rtol: default_rtol(),
            adaptive: default_adaptive(),
            memory_limit: None,
            keep_preconditioner: false,
            jacobian: StepJacobian::default(),
        }
    }
}

impl SolverSettings {
    /// Whether the solver gives the inertia of the tangent (the stability test of static stages:
    /// without it, limit points show only as Newton failures).
    pub fn gives_inertia(&self) -> bool {
        match self.kind {
            SolverKind::Direct | SolverKind::Auto => true,
            SolverKind::Iterative => false,
            // MUMPS's LDLᵀ counts the negative pivots unless options choose another method
            #[cfg(feature = "petsc")]
            SolverKind::Petsc => {
                let env = std::env::var("PETSC_OPTIONS").unwrap_or_default();
                let options = format!("{} {env}", self.petsc_options);
                let is = |name: &str, default: &str| {
                    last_option_value(&options, name).is_none_or(|v| v == default)
                };
                is("-ksp_type", "preonly")
                    && is("-pc_type", "cholesky")
                    && is("-pc_factor_mat_solver_type", "mumps")
            }
        }
    }

    /// One line for the start of a run: the solver chosen for `unknowns` unknowns, and why.
    pub fn describe(&self, unknowns: usize) -> String {
        let ordering = match self.ordering {
            Ordering::NestedDissection => "METIS nested-dissection",
            Ordering::Amd => "AMD",
        };
        let exact = format!(
            "direct sparse LDLT, {ordering} ordering (exact solves and the inertia for the stability test)"
        );
        match self.kind {
            SolverKind::Direct => exact,
            SolverKind::Auto if unknowns < self.reuse_from => {
                format!("{exact}; auto: {unknowns} unknowns, a fresh factorisation per Newton iteration")
            }
            SolverKind::Iterative => format!(
                "FGMRES to {:.0e}{} preconditioned by smoothed-aggregation AMG of the whole \
                 coupled tangent (aggregates of nodes with u and Φ; rigid-body modes and the \
                 constant potential; memory linear in the unknowns; no inertia, so a limit point \
                 shows as a Newton failure)",
                self.rtol,
                if self.adaptive {
                    " or Newton's looser forcing term"
                } else {
                    ""
                }
            ),
            SolverKind::Auto => format!(
                "direct sparse LDLT, {ordering} ordering, reused as the preconditioner of FGMRES \
                 (auto: {unknowns} unknowns ≥ {}; refactored when the Krylov work \
                 exceeds a factorisation, and at every stability test, whose inertia stays exact; \
                 factors held in {})",
                self.reuse_from,
                match self.precision {
                    FactorPrecision::Auto if self.adaptive => {
                        "single precision in static load steps (Newton on the tangent's \
                         products), double elsewhere"
                    }
                    FactorPrecision::Auto | FactorPrecision::Double => "double precision",
                    FactorPrecision::Single => "single precision",
                }
            ),
            #[cfg(feature = "petsc")]
            SolverKind::Petsc => {
                let env = std::env::var("PETSC_OPTIONS").unwrap_or_default();
                let mut s = String::from("PETSc");
                if self.petsc_options.trim().is_empty() && env.trim().is_empty() {
                    s.push_str(
                        " (MUMPS LDLT: exact solves and the inertia for the stability test)",
                    );
                }
                if !self.petsc_options.trim().is_empty() {
                    s.push_str(&format!(", options \"{}\"", self.petsc_options.trim()));
                }
                if !env.trim().is_empty() {
                    s.push_str(&format!(", PETSC_OPTIONS \"{}\"", env.trim()));
                }
                // PETSc uses the last -ksp_type given; PETSC_OPTIONS comes after the scenario's
                let krylov = [env.as_str(), self.petsc_options.as_str()]
                    .iter()
                    .find_map(|o| last_option_value(o, "-ksp_type"))
                    .is_some_and(|t| t != "preonly");
                // both only act on a Krylov method, so a direct solve does not mention them
                if self.adaptive && krylov {
                    s.push_str("; a Krylov method stops at Newton's forcing term when looser");
                }
                if self.keep_preconditioner && krylov {
                    s.push_str(
                        "; a Krylov method keeps its preconditioner until its iterations per \
                         decade of residual reduction double or a solve fails",
                    );
                }
                s
            }
        }
    }
}

/// The value of the last occurrence of option `name` in a PETSc options string (the one PETSc
/// uses), `Some("")` for a flag without value.
#[cfg(feature = "petsc")]
fn last_option_value<'a>(options: &'a str, name: &str) -> Option<&'a str> {
    let words: Vec<&str> = options.split_whitespace().collect();
    let i = words.iter().rposition(|w| *w == name)?;
    Some(
        words
            .get(i + 1)
            .filter(|v| !v.starts_with('-') || v.parse::<f64>().is_ok())
            .copied()
            .unwrap_or(""),
    )
}

/// Sparse supernodal LDLᵀ (faer) with a nested-dissection (METIS) or AMD ordering; the symbolic
/// analysis is computed at the first factorisation and reused for every later one.
pub struct FaerLdlt {
    ordering: Ordering,
    symbolic: Option<SymbolicCholesky<u32>>,
    /// The matrix's row pointers in the 32 bits of its columns (faer takes one index type).
    row_ptr: Vec<u32>,
    l_values: Vec<f64>,
    factored: bool,
    par: Par,
    mem: Option<MemBuffer>,
    stats: SolverStats,
    /// Single precision: the factor, and work copies of the matrix and a right-hand side.
    single: Option<Single>,
    /// Largest factor (bytes) allowed; `None`: 80 % of the memory available.
    memory_limit: Option<usize>,
    /// Work vector of the supernodal solve.
    work: Vec<f64>,
    /// The two parts of the elimination tree the supernodal solve does side by side on two
    /// threads (planned at the first solve after a symbolic analysis; `None` inside: none
    /// worth it).
    split: Option<Option<supernodal::Split>>,
}

/// The single-precision factor of [`FaerLdlt::single_precision`].
#[derive(Default)]
struct Single {
    l: Vec<f32>,
    a: Vec<f32>,
    rhs: Vec<f32>,
}

impl std::fmt::Debug for FaerLdlt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FaerLdlt")
            .field("factored", &self.factored)
            .field("l_nnz", &self.l_values.len())
            .finish()
    }
}

/// Below this many unknowns the factorisation and the solves run on the calling thread (and a
/// frequency sweep factors its frequencies in parallel, each on one thread).
pub(crate) const PARALLEL_MIN_UNKNOWNS: usize = 20_000;

impl Default for FaerLdlt {
    fn default() -> Self {
        Self::new()
    }
}

impl FaerLdlt {
    /// Nested dissection, using the threads of the current rayon pool.
    pub fn new() -> Self {
        Self::with_ordering(Ordering::NestedDissection)
    }

    /// A solver with the given ordering.
    pub fn with_ordering(ordering: Ordering) -> Self {
        let threads = rayon::current_num_threads();
        FaerLdlt {
            ordering,
            symbolic: None,
            row_ptr: Vec::new(),
            l_values: Vec::new(),
            factored: false,
            par: if threads > 1 {
                Par::rayon(threads)
            } else {
                Par::Seq
            },
            mem: None,
            stats: SolverStats::default(),
            single: None,
            memory_limit: None,
            work: Vec::new(),
            split: None,
        }
    }

    /// Refuses factors of more than `bytes` ([`LinearSolverError::OutOfMemory`]) instead of 80 %
    /// of the memory available.
    pub fn memory_limit(mut self, bytes: usize) -> Self {
        self.memory_limit = Some(bytes);
        self
    }

    /// `a` in faer's form, its row pointers from `row_ptr` (32 bits). A symmetric matrix in CSR
    /// is the same matrix in CSC.
    fn matrix<'a, T>(
        a: &'a CsrMatrix,
        row_ptr: &'a [u32],
        values: &'a [T],
    ) -> SparseColMatRef<'a, u32, T> {
        let sym = SymbolicSparseColMatRef::new_checked(a.n, a.n, row_ptr, None, &a.col_idx);
        SparseColMatRef::new(sym, values)
    }

    /// Factors and solves in single precision: half the memory of the factor and of every
    /// triangular sweep, and twice the arithmetic rate of the dense kernels. The solves are then
    /// accurate to about 1e-6 only, so such a factor serves as a preconditioner (see
    /// [`super::reused::ReusedLdlt`]); its inertia is that of the matrix unless a pivot is within
    /// single-precision round-off of zero.
    pub fn single_precision(mut self) -> Self {
        self.single = Some(Single::default());
        self
    }

    /// Factors in single precision from the next factorisation on, or in double precision; a
    /// change drops the factor and its symbolic analysis (which sizes the factor's storage).
    pub fn set_single(&mut self, on: bool) {
        if on != self.is_single() {
            self.single = on.then(Single::default);
            self.symbolic = None;
            self.mem = None;
            self.split = None;
            self.factored = false;
        }
    }

    /// Whether the factor is held in single precision.
    pub fn is_single(&self) -> bool {
        self.single.is_some()
    }

    /// Multiply–adds of one numeric factorisation, from the symbolic analysis (per supernode of c
    /// columns over m rows below it: c³/3 + m c² + m² c); `None` before the first factorisation.
    pub fn factor_flops(&self) -> Option<f64> {
        let symbolic = self.symbolic.as_ref()?;
        Some(match symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => {
                let cp = s.col_ptr();
                (0..s.nrows())
                    .map(|j| ((cp[j + 1] - cp[j]) as f64).powi(2))
                    .sum()
            }
            SymbolicCholeskyRaw::Supernodal(s) => {
                let (begin, end, nnz) = (s.supernode_begin(), s.supernode_end(), s.nnz_per_super());
                (0..s.n_supernodes())
                    .map(|sn| {
                        // the diagonal block, the panel below it and the update of the ancestors
                        let (c, m) = ((end[sn] - begin[sn]) as f64, nnz[sn] as f64);
                        c * c * c / 3.0 + m * c * c + m * m * c
                    })
                    .sum()
            }
        })
    }

    /// Entry `i` of the stored factor, in either precision.
    fn l_value(&self, i: usize) -> f64 {
        match &self.single {
            Some(s) => f64::from(s.l[i]),
            None => self.l_values[i],
        }
    }

    /// The pivots D of the last factorisation.
    fn pivots(&self) -> Vec<f64> {
        let Some(symbolic) = &self.symbolic else {
            return Vec::new();
        };
        let mut d = Vec::with_capacity(symbolic.nrows());
        match symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => {
                let cp = s.col_ptr();
                for j in 0..s.nrows() {
                    d.push(self.l_value(cp[j] as usize));
                }
            }
            SymbolicCholeskyRaw::Supernodal(s) => {
                let cp = s.col_ptr_for_val();
                let begin = s.supernode_begin();
                let end = s.supernode_end();
                let nnz = s.nnz_per_super();
                for sn in 0..s.n_supernodes() {
                    let ncols = (end[sn] - begin[sn]) as usize;
                    let nrows = nnz[sn] as usize + ncols;
                    let base = cp[sn] as usize;
                    for j in 0..ncols {
                        d.push(self.l_value(base + j * nrows + j));
                    }
                }
            }
        }
        d
    }
}

impl LinearSolver for FaerLdlt {
    fn factor(&mut self, a: &CsrMatrix) -> Result<Option<Inertia>, LinearSolverError> {
        self.factored = false;
        // O(n), against the factorisation's O(entries of the factor)
        self.row_ptr = a.row_ptr_u32().ok_or(LinearSolverError::TooLarge)?;
        let mat = Self::matrix(a, &self.row_ptr, &a.values);
        if self.symbolic.is_none() {
            let nd = match self.ordering {
                Ordering::NestedDissection => {
                    super::ordering::nested_dissection(a.n, &a.row_ptr, &a.col_idx)
                }
                Ordering::Amd => None,
            };
            let nd: Option<Vec<u32>> = nd.map(|p| p.into_iter().map(|i| i as u32).collect());
            let inverse = nd.as_ref().map(|p| {
                let mut inv = vec![0u32; p.len()];
                for (new, &old) in p.iter().enumerate() {
                    inv[old as usize] = new as u32;
                }
                inv
            });
            let ord = match (&nd, &inverse) {
                (Some(fwd), Some(inv)) => {
                    SymmetricOrdering::Custom(PermRef::new_checked(fwd, inv, a.n))
                }
                _ => SymmetricOrdering::Amd,
            };
            let symbolic = factorize_symbolic_cholesky(
                mat.symbolic(),
                Side::Lower,
                ord,
                CholeskySymbolicParams::default(),
            )
            .map_err(|e| match e {
                faer::sparse::FaerError::IndexOverflow => LinearSolverError::TooLarge,
                e => LinearSolverError::Symbolic(format!("{e:?}")),
            })?;
            let bytes = symbolic.len_val() * if self.single.is_some() { 4 } else { 8 };
            let limit = self.memory_limit.unwrap_or_else(default_memory_limit);
            if bytes > limit {
                return Err(LinearSolverError::OutOfMemory {
                    needed: bytes,
                    limit,
                });
            }
            match &mut self.single {
                Some(s) => s.l = vec![0.0; symbolic.len_val()],
                None => self.l_values = vec![0.0; symbolic.len_val()],
            }
            if a.n < PARALLEL_MIN_UNKNOWNS {
                // the pool's hand-offs cost more than a small factorisation
                self.par = Par::Seq;
            }
            let req = symbolic
                .factorize_numeric_ldlt_scratch::<f64>(self.par, Spec::<LdltParams, f64>::default())
                .or(symbolic.solve_in_place_scratch::<f64>(1, self.par));
            self.mem = Some(MemBuffer::new(req));
            self.symbolic = Some(symbolic);
            self.split = None;
        }
        let symbolic = self.symbolic.as_ref().expect("set above");
        let mem = self.mem.as_mut().expect("set above");
        let stack = MemStack::new(mem);
        let zero_pivot = |e| match e {
            faer::linalg::cholesky::ldlt::factor::LdltError::ZeroPivot { index } => {
                LinearSolverError::Singular(index)
            }
        };
        let numeric = match &mut self.single {
            None => symbolic
                .factorize_numeric_ldlt(
                    &mut self.l_values,
                    mat,
                    Side::Lower,
                    LdltRegularization::default(),
                    self.par,
                    stack,
                    Spec::<LdltParams, f64>::default(),
                )
                .map(|_| ()),
            Some(s) => {
                s.a.clear();
                s.a.extend(a.values.iter().map(|&v| v as f32));
                symbolic
                    .factorize_numeric_ldlt(
                        &mut s.l,
                        Self::matrix(a, &self.row_ptr, &s.a),
                        Side::Lower,
                        LdltRegularization::default(),
                        self.par,
                        stack,
                        Spec::<LdltParams, f32>::default(),
                    )
                    .map(|_| ())
            }
        };
        super::vector_state::clear_after(self.par, a.n);
        numeric.map_err(zero_pivot)?;
        let mut inertia = Inertia::default();
        let d = self.pivots();
        let dmax = d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        // pivots within round-off of zero (relative to the largest) count as zero
        let small = if self.single.is_some() { 1e-7 } else { 1e-14 };
        for v in d {
            if !v.is_finite() || v.abs() <= small * dmax {
                inertia.zero += 1;
            } else if v > 0.0 {
                inertia.positive += 1;
            } else {
                inertia.negative += 1;
            }
        }
        self.stats.factorizations += 1;
        if inertia.zero > 0 {
            return Err(LinearSolverError::Singular(0));
        }
        self.factored = true;
        Ok(Some(inertia))
    }

    fn solve_in_place(&mut self, b: &mut [f64]) -> Result<(), LinearSolverError> {
        if !self.factored {
            return Err(LinearSolverError::NotFactored);
        }
        let symbolic = self.symbolic.as_ref().expect("factored");
        let mem = self.mem.as_mut().expect("factored");
        let stack = MemStack::new(mem);
        let n = b.len();
        self.stats.solves += 1;
        match &mut self.single {
            None if matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)) => {
                if let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() {
                    let perm = symbolic.perm().map(|p| p.arrays());
                    let split = self
                        .split
                        .get_or_insert_with(|| supernodal::Split::plan(sn));
                    let split = split.as_mut().filter(|_| rayon::current_num_threads() > 1);
                    supernodal::solve(sn, perm, &self.l_values, b, &mut self.work, split);
                }
            }
            None => {
                let rhs = MatMut::from_column_major_slice_mut(b, n, 1);
                LdltRef::new(symbolic, &self.l_values).solve_in_place_with_conj(
                    Conj::No,
                    rhs,
                    self.par,
                    stack,
                );
                super::vector_state::clear_after(self.par, n);
            }
            Some(s) => {
                // scaled to unit size, so that no entry under- or overflows in single precision
                let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                if scale == 0.0 {
                    return Ok(());
                }
                s.rhs.clear();
                s.rhs.extend(b.iter().map(|&v| (v / scale) as f32));
                let rhs = MatMut::from_column_major_slice_mut(&mut s.rhs, n, 1);
                LdltRef::new(symbolic, &s.l).solve_in_place_with_conj(
                    Conj::No,
                    rhs,
                    self.par,
                    stack,
                );
                super::vector_state::clear_after(self.par, n);
                for (v, &x) in b.iter_mut().zip(&s.rhs) {
                    *v = f64::from(x) * scale;
                }
            }
        }
        Ok(())
    }

    fn is_factored(&self) -> bool {
        self.factored
    }

    fn factor_nnz(&self) -> Option<usize> {
        Some(match &self.single {
            Some(s) => s.l.len(),
            None => self.l_values.len(),
        })
    }

    fn stats(&self) -> SolverStats {
        self.stats
    }

    fn invalidate(&mut self) {
        self.factored = false;
    }

    fn name(&self) -> &'static str {
        match self.ordering {
            Ordering::NestedDissection => "faer sparse LDLT (METIS nested dissection)",
            Ordering::Amd => "faer sparse LDLT (AMD)",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small saddle-point matrix [[K, B], [Bᵀ, −C]] in CSR.
    fn saddle(n: usize, shift: f64) -> CsrMatrix {
        // 1-D Laplacian blocks coupled diagonally
        let m = 2 * n;
        let mut dense = vec![0.0; m * m];
        for i in 0..n {
            dense[i * m + i] = 2.0 - shift;
            dense[(n + i) * m + n + i] = -2.0;
            if i + 1 < n {
                dense[i * m + i + 1] = -1.0;
                dense[(i + 1) * m + i] = -1.0;
                dense[(n + i) * m + n + i + 1] = 1.0;
                dense[(n + i + 1) * m + n + i] = 1.0;
            }
            dense[i * m + n + i] = 0.3;
            dense[(n + i) * m + i] = 0.3;
        }
        let n_rows = m;
        let (mut row_ptr, mut col_idx, mut values) = (vec![0usize], Vec::new(), Vec::<f64>::new());
        for i in 0..m {
            for j in 0..m {
                if dense[i * m + j] != 0.0 {
                    col_idx.push(j);
                    values.push(dense[i * m + j]);
                }
            }
            row_ptr.push(col_idx.len());
        }
        CsrMatrix::from_usize(n_rows, row_ptr, col_idx, values)
    }

    /// A saddle-point matrix with a supernodal factor: the Laplacian of a g × g × g grid
    /// (positive block) coupled to a negative one.
    fn grid_saddle(g: usize) -> CsrMatrix {
        let nodes = g * g * g;
        let n = 2 * nodes;
        let id = |x: usize, y: usize, z: usize| (x * g + y) * g + z;
        let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        for x in 0..g {
            for y in 0..g {
                for z in 0..g {
                    let i = id(x, y, z);
                    rows[i].push((i, 6.5));
                    rows[nodes + i].push((nodes + i, -6.2));
                    rows[i].push((nodes + i, 0.4));
                    rows[nodes + i].push((i, 0.4));
                    let mut link = |j: usize| {
                        rows[i].push((j, -1.0));
                        rows[nodes + i].push((nodes + j, 1.0));
                    };
                    if x > 0 {
                        link(id(x - 1, y, z));
                    }
                    if x + 1 < g {
                        link(id(x + 1, y, z));
                    }
                    if y > 0 {
                        link(id(x, y - 1, z));
                    }
                    if y + 1 < g {
                        link(id(x, y + 1, z));
                    }
                    if z > 0 {
                        link(id(x, y, z - 1));
                    }
                    if z + 1 < g {
                        link(id(x, y, z + 1));
                    }
                }
            }
        }
        let (mut row_ptr, mut col_idx, mut values) = (vec![0usize], Vec::new(), Vec::new());
        for r in &mut rows {
            r.sort_by_key(|e| e.0);
            col_idx.extend(r.iter().map(|e| e.0));
            values.extend(r.iter().map(|e| e.1));
            row_ptr.push(col_idx.len());
        }
        CsrMatrix::from_usize(n, row_ptr, col_idx, values)
    }

    /// The hand-written supernodal solve gives faer's solution with the same factor, up to
    /// round-off.
    #[test]
    fn supernodal_solve_matches_faer() {
        let a = grid_saddle(9);
        let n = a.n;
        let mut s = FaerLdlt::new();
        s.factor(&a).unwrap();
        assert_eq!(s.par, Par::Seq);
        let b: Vec<f64> = (0..n)
            .map(|i| ((i as f64 * 0.37).sin() + 0.1).powi(3))
            .collect();
        let mut x = b.clone();
        s.solve_in_place(&mut x).unwrap();
        let symbolic = s.symbolic.as_ref().unwrap();
        assert!(matches!(symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)));
        let mut y = b.clone();
        let mut mem = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        LdltRef::new(symbolic, &s.l_values).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut y, n, 1),
            Par::Seq,
            MemStack::new(&mut mem),
        );
        let ymax = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (u, v) in x.iter().zip(&y) {
            assert!((u - v).abs() <= 1e-13 * ymax, "{u} {v}");
        }
        // and it solves the system
        let mut ax = vec![0.0; n];
        a.mul_vec(&x, &mut ax);
        let bmax = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (u, v) in ax.iter().zip(&b) {
            assert!((u - v).abs() <= 1e-12 * bmax);
        }
    }

    /// The solve with two parts of the tree side by side is the sequential solve, bit for bit.
    #[test]
    fn a_solve_split_in_two_parts_has_the_bits_of_the_sequential_one() {
        let a = grid_saddle(14);
        let n = a.n;
        let mut s = FaerLdlt::new();
        s.factor(&a).unwrap();
        let symbolic = s.symbolic.as_ref().unwrap();
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            panic!("a supernodal factor expected");
        };
        let perm = symbolic.perm().map(|p| p.arrays());
        let mut split = supernodal::Split::plan(sn).expect("two parts worth solving apart");
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.91).cos() + 0.2).collect();
        let (mut x1, mut x2) = (b.clone(), b.clone());
        let mut work = Vec::new();
        supernodal::solve(sn, perm, &s.l_values, &mut x1, &mut work, None);
        for _ in 0..3 {
            x2.copy_from_slice(&b);
            supernodal::solve(sn, perm, &s.l_values, &mut x2, &mut work, Some(&mut split));
            assert!(x1.iter().zip(&x2).all(|(u, v)| u.to_bits() == v.to_bits()));
        }
        let mut ax = vec![0.0; n];
        a.mul_vec(&x1, &mut ax);
        let bmax = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(ax
            .iter()
            .zip(&b)
            .all(|(u, v)| (u - v).abs() <= 1e-12 * bmax));
        // the solver's own path, whatever the number of threads
        let mut x3 = b.clone();
        s.solve_in_place(&mut x3).unwrap();
        assert!(x1.iter().zip(&x3).all(|(u, v)| u.to_bits() == v.to_bits()));
    }

    #[cfg(feature = "petsc")]
    #[test]
    fn petsc_gives_the_inertia_only_with_the_mumps_cholesky() {
        let with = |o: &str| SolverSettings {
            kind: SolverKind::Petsc,
            petsc_options: o.to_string(),
            ..SolverSettings::default()
        };
        assert!(with("").gives_inertia());
        assert!(with("-pc_type cholesky -mat_mumps_icntl_14 50").gives_inertia());
        assert!(!with("-ksp_type gmres -pc_type jacobi").gives_inertia());
        assert!(!with("-pc_type lu").gives_inertia());
        assert!(with("-pc_type lu -pc_type cholesky").gives_inertia());
        assert_eq!(last_option_value("-a 1 -b -c -2", "-c"), Some("-2"));
        assert_eq!(last_option_value("-a 1 -b -c -2", "-b"), Some(""));
        assert_eq!(last_option_value("-a 1", "-d"), None);
    }

    #[test]
    fn solves_saddle_system_and_counts_inertia() {
        let n = 40;
        let a = saddle(n, 0.0);
        let mut s = FaerLdlt::new();
        let inertia = s.factor(&a).unwrap().unwrap();
        assert_eq!(inertia.negative, n);
        assert_eq!(inertia.positive, n);
        let x: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut b = vec![0.0; 2 * n];
        a.mul_vec(&x, &mut b);
        s.solve_in_place(&mut b).unwrap();
        for (u, v) in b.iter().zip(&x) {
            assert!((u - v).abs() < 1e-10);
        }
        // refactor with the same pattern but a shifted (indefinite) K block: one more negative pivot
        let shifted = saddle(n, 1.0);
        let inertia = s.factor(&shifted).unwrap().unwrap();
        assert!(inertia.negative > n, "{inertia:?}");
    }

    #[test]
    fn single_precision_gives_the_inertia_and_solves_to_single_accuracy() {
        let n = 40;
        let a = saddle(n, 0.0);
        let mut s = FaerLdlt::new().single_precision();
        let inertia = s.factor(&a).unwrap().unwrap();
        assert_eq!((inertia.positive, inertia.negative), (n, n));
        let x: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut b = vec![0.0; 2 * n];
        a.mul_vec(&x, &mut b);
        s.solve_in_place(&mut b).unwrap();
        let err = b
            .iter()
            .zip(&x)
            .map(|(u, v)| (u - v).abs())
            .fold(0.0, f64::max);
        // single precision: far from double round-off, near single round-off
        assert!(err < 1e-5 && err > 1e-13, "{err:e}");
        let shifted = saddle(n, 1.0);
        assert!(s.factor(&shifted).unwrap().unwrap().negative > n);
    }
}
