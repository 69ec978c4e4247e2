//! Linear solves by PETSc (`[solver] kind = "petsc"`, a build with `--features petsc`).
//!
//! A thin safe layer over `petsc-sys`: owning wrappers of PETSc's matrix, vector, scatter and
//! Krylov-solver objects, every error code turned into a [`LinearSolverError`] with PETSc's own
//! message, and [`PetscSolver`], a [`LinearSolver`] whose system is one PETSc AIJ matrix on
//! `PETSC_COMM_WORLD`.
//!
//! **Distribution.** Every MPI rank runs the same program; the PETSc system is one distributed
//! system: each rank owns a contiguous block of rows, and the solution is gathered back to every
//! rank. With the system's layout the rows are whole nodes, four per node (ux, uy, uz, Φ), the
//! held unknowns' rows decoupled padding, so the matrix has a block size of 4 (PETSc's node
//! blocks, which GAMG aggregates whole); without it, 4 only where the pattern allows. A rank whose
//! matrix is the whole tangent passes the entries of its rows; on one rank this is an ordinary
//! sequential solve.
//!
//! **Default method.** Without options the solver is direct: `-ksp_type preonly -pc_type cholesky
//! -pc_factor_mat_solver_type mumps`, a symmetric indefinite LDLᵀ factorisation by MUMPS (Amestoy
//! et al., SIAM J. Matrix Anal. Appl. 23, 2001), so results agree with the serial LDLᵀ to
//! round-off, and MUMPS's count of negative pivots gives the inertia for the stability test
//! (`MatGetInertia`; `-mat_mumps_icntl_13 1` is set so that the count is also right on several
//! ranks, as the PETSc manual page of `MATSOLVERMUMPS` requires).
//!
//! **Options.** Each solver has an options database of its own, holding the scenario's
//! `[solver] petsc_options` string and then the `PETSC_OPTIONS` environment variable (the later
//! wins, as PETSc's command line wins over an options file); it is made PETSc's default database
//! (`PetscOptionsPush`) for every call of that solver, so that solvers with different options
//! in one process do not see each other's. The solver reads them with `KSPSetFromOptions`, so
//! any KSP/PC choice of the PETSc users manual applies, e.g. `-ksp_type minres -pc_type jacobi
//! -ksp_rtol 1e-10`. A Krylov solve that does not converge is an error naming PETSc's reason,
//! never a silently inaccurate answer.
//!
//! **Shared assembly.** When the ranks share the cells (each assembles its own, see
//! [`crate::problem::assembly::CellShare`]), the system's layout says so
//! ([`DofLayout::shared`]): the rank's tangent is then its part, with a pattern of its own, and
//! it passes every entry of it, wherever the rows are (`MatSetValues`, adding); PETSc sends the
//! entries of other ranks' rows to them and sums them at assembly. Each rank owns the rows of the
//! nodes whose equations take its non-cell terms ([`DofLayout::owned`]: nodes of its own cells,
//! those on the partition's boundary dealt out evenly), so only the entries on the partition's
//! boundary travel. Without a layout the
//! block size is agreed between the ranks. [`sum_over_ranks`] sums the residual.
//!
//! **Near-null space.** From the system's [`DofLayout`] the solver builds the rigid-body modes
//! of the free displacements (three translations and three rotations in 3-D, the axial
//! translation in the meridian plane; zero on the potential rows), orthonormal, and attaches
//! them with the constant potential (zero on the displacement rows) to the matrix
//! (`MatSetNearNullSpace`) for algebraic multigrid (`-pc_type gamg`). It also
//! names the two fields for `-pc_type fieldsplit` (`PCFieldSplitSetIS`: split `u`, the
//! displacements, with the modes attached for GAMG on that block, and split `p`, the
//! potentials), so `-fieldsplit_u_pc_type gamg` sees the elasticity modes.
//!
//! **Threads.** PETSc is not thread-safe: every call into it holds one process-wide lock, and
//! PETSc is initialised once per process (on first use) and finalised at process exit.

use super::linear::{Inertia, LinearSolver, LinearSolverError, SolverStats};
use crate::algebra::csr::CsrMatrix;
use crate::algebra::exchange::{Exchange, LocalEquations};
use crate::algebra::system::DofLayout;
use crate::fem::FIELDS;
use petsc_sys as ffi;
use std::cell::Cell;
use std::ffi::{CStr, CString};
use std::ptr;
use std::sync::{Mutex, MutexGuard, OnceLock};

/// Serialises every call into PETSc (and MPI) of this process.
static LOCK: Mutex<()> = Mutex::new(());

/// The outcome of the one initialisation of the process.
static INIT: OnceLock<Result<(), String>> = OnceLock::new();

thread_local! {
    /// Whether this thread holds [`LOCK`] (so that nested calls, e.g. destructors on an error
    /// path, do not wait for themselves).
    static HELD: Cell<bool> = const { Cell::new(false) };
}

/// Holds [`LOCK`] unless this thread already does.
struct Guard(Option<MutexGuard<'static, ()>>);

impl Drop for Guard {
    fn drop(&mut self) {
        if self.0.is_some() {
            HELD.with(|h| h.set(false));
        }
    }
}

fn lock() -> Guard {
    if HELD.with(|h| h.get()) {
        return Guard(None);
    }
    // a panic while holding the lock leaves PETSc as it was: carry on
    let guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    HELD.with(|h| h.set(true));
    Guard(Some(guard))
}

/// PETSc's message for an error code: the generic text and the specific message of the last
/// error raised.
fn message(code: ffi::PetscErrorCode) -> String {
    let mut text: *const std::os::raw::c_char = ptr::null();
    let mut specific: *mut std::os::raw::c_char = ptr::null_mut();
    // SAFETY: PetscErrorMessage writes pointers to static strings owned by PETSc
    unsafe {
        ffi::PetscErrorMessage(code, &mut text, &mut specific);
    }
    let read = |p: *const std::os::raw::c_char| {
        if p.is_null() {
            String::new()
        } else {
            // SAFETY: non-null pointers from PETSc are NUL-terminated strings
            unsafe { CStr::from_ptr(p) }
                .to_string_lossy()
                .trim()
                .to_string()
        }
    };
    let (text, specific) = (read(text), read(specific));
    match (text.is_empty(), specific.is_empty()) {
        (_, true) => format!("PETSc error {code}: {text}"),
        (true, false) => format!("PETSc error {code}: {specific}"),
        (false, false) => format!("PETSc error {code}: {text}: {specific}"),
    }
}

/// A PETSc return code as a `Result`; `what` names the call for the message.
fn check(code: ffi::PetscErrorCode, what: &str) -> Result<(), LinearSolverError> {
    ffi::check(code).map_err(|c| LinearSolverError::Failed(format!("{what}: {}", message(c))))
}

extern "C" fn finalize_at_exit() {
    let _guard = lock();
    // SAFETY: runs once, at exit, after PetscInitialize succeeded; objects still alive are freed
    // by the operating system
    unsafe {
        ffi::PetscFinalize();
    }
}

/// Initialises PETSc (and MPI, unless the program already did) once per process, and registers
/// its finalisation at exit. PETSc's signal handlers stay off (deasim handles Ctrl-C itself), and
/// errors are returned to the caller rather than printed as tracebacks.
pub fn initialize() -> Result<(), LinearSolverError> {
    INIT.get_or_init(|| {
        let _guard = lock();
        // SAFETY: the options database may be written before PetscInitialize; the argument
        // pointers may be null (no command line: deasim's own arguments are not PETSc's)
        unsafe {
            let opt = c"-no_signal_handler";
            ffi::PetscOptionsSetValue(ptr::null_mut(), opt.as_ptr(), ptr::null());
            let code =
                ffi::PetscInitialize(ptr::null_mut(), ptr::null_mut(), ptr::null(), ptr::null());
            if code != 0 {
                return Err(format!("PetscInitialize failed with error code {code}"));
            }
            ffi::PetscPushErrorHandler(Some(ffi::PetscReturnErrorHandler), ptr::null_mut());
            libc::atexit(finalize_at_exit);
        }
        Ok(())
    })
    .clone()
    .map_err(LinearSolverError::Failed)
}

/// This process's rank and the number of ranks of `PETSC_COMM_WORLD` (initialising PETSc).
pub fn world() -> Result<(usize, usize), LinearSolverError> {
    initialize()?;
    let _guard = lock();
    let (mut rank, mut size) = (0, 0);
    // SAFETY: PETSc is initialised
    unsafe {
        let comm = ffi::comm_world();
        ffi::MPI_Comm_rank(comm, &mut rank);
        ffi::MPI_Comm_size(comm, &mut size);
    }
    Ok((rank as usize, size as usize))
}

/// Waits until every rank of `PETSC_COMM_WORLD` arrives here (e.g. the writing rank has
/// finished its files before any rank exits, which would make the launcher abort the others).
pub fn barrier() -> Result<(), LinearSolverError> {
    initialize()?;
    let _guard = lock();
    // SAFETY: PETSc (and so MPI) is initialised
    let code = unsafe { ffi::MPI_Barrier(ffi::comm_world()) };
    if code != 0 {
        return Err(LinearSolverError::Failed(format!(
            "MPI_Barrier failed with code {code}"
        )));
    }
    Ok(())
}

/// The tag of deasim's byte messages.
const BYTES_TAG: i32 = 0x0dea;

/// Sends `bytes` to rank `to` of `PETSC_COMM_WORLD` (which receives them with
/// [`receive_bytes`]); returns when the bytes may be reused.
pub fn send_bytes(bytes: &[u8], to: usize) -> Result<(), LinearSolverError> {
    initialize()?;
    let _guard = lock();
    let to = i32::try_from(to).map_err(|_| LinearSolverError::Failed(format!("no rank {to}")))?;
    // SAFETY: MPI is initialised; `bytes` is valid for its length during the call
    let code = unsafe {
        ffi::deasim_mpi_send_bytes(
            bytes.as_ptr(),
            bytes.len() as u64,
            to,
            BYTES_TAG,
            ffi::comm_world(),
        )
    };
    if code != 0 {
        return Err(LinearSolverError::Failed(format!(
            "sending {} bytes to rank {to} failed with MPI error code {code}",
            bytes.len()
        )));
    }
    Ok(())
}

/// The bytes rank `from` of `PETSC_COMM_WORLD` sends this rank with [`send_bytes`].
pub fn receive_bytes(from: usize) -> Result<Vec<u8>, LinearSolverError> {
    initialize()?;
    let _guard = lock();
    let fail = |what: &str, code: i32| {
        LinearSolverError::Failed(format!(
            "receiving {what} from rank {from} failed with MPI error code {code}"
        ))
    };
    let from = i32::try_from(from).map_err(|_| fail("a message", -1))?;
    let mut length = 0u64;
    // SAFETY: MPI is initialised; the length is written into a local, the bytes into a buffer
    // of that length
    unsafe {
        let code = ffi::deasim_mpi_recv_length(&mut length, from, BYTES_TAG, ffi::comm_world());
        if code != 0 {
            return Err(fail("a message's length", code));
        }
        let mut bytes = vec![0u8; usize::try_from(length).map_err(|_| fail("a message", -1))?];
        let code = ffi::deasim_mpi_recv_bytes(
            bytes.as_mut_ptr(),
            length,
            from,
            BYTES_TAG,
            ffi::comm_world(),
        );
        if code != 0 {
            return Err(fail(&format!("{length} bytes"), code));
        }
        Ok(bytes)
    }
}

/// Inserts an options string into the default options database (call with the lock held).
fn insert_options(options: &str, origin: &str) -> Result<(), LinearSolverError> {
    if options.trim().is_empty() {
        return Ok(());
    }
    let c = CString::new(options).map_err(|_| {
        LinearSolverError::Failed(format!("{origin}: the PETSc options contain a NUL byte"))
    })?;
    // SAFETY: c is a valid C string for the duration of the call
    check(
        unsafe { ffi::PetscOptionsInsertString(ptr::null_mut(), c.as_ptr()) },
        &format!("{origin}: PetscOptionsInsertString(\"{options}\")"),
    )
}

/// Sets up a Krylov solver from the scenario's `options` and then the `PETSC_OPTIONS`
/// environment variable, as the solver does at its first factorisation, and returns PETSc's
/// refusal: a misspelt method or preconditioner is then reported with the scenario, before the
/// first step, instead of failing every attempt of the first load step. Collective: every rank
/// reads the same scenario and calls it. The answer is kept: a second call with the same
/// options (and the same `PETSC_OPTIONS`) returns it without a collective call, so that rank 0
/// may build the whole plan alone after every rank has checked the options.
pub fn check_options(options: &str) -> Result<(), LinearSolverError> {
    type Checked = Option<((String, Option<String>), Result<(), LinearSolverError>)>;
    static CHECKED: Mutex<Checked> = Mutex::new(None);
    let key = (options.to_string(), std::env::var("PETSC_OPTIONS").ok());
    let mut checked = CHECKED.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((k, answer)) = checked.as_ref() {
        if *k == key {
            return answer.clone();
        }
    }
    let answer = check_options_now(options);
    *checked = Some((key, answer.clone()));
    answer
}

/// [`check_options`] without the kept answer (collective).
fn check_options_now(options: &str) -> Result<(), LinearSolverError> {
    initialize()?;
    let _guard = lock();
    // SAFETY: PETSc is initialised; the handles are owned by wrappers that destroy them (the
    // solver first, then the database is popped and destroyed)
    unsafe {
        let mut db = Options(ptr::null_mut());
        check(ffi::PetscOptionsCreate(&mut db.0), "PetscOptionsCreate")?;
        let _scope = Scope::push(&db)?;
        insert_options(options, "[solver] petsc_options")?;
        if let Ok(env) = std::env::var("PETSC_OPTIONS") {
            insert_options(&env, "PETSC_OPTIONS")?;
        }
        let mut ksp = Ksp(ptr::null_mut());
        check(ffi::KSPCreate(ffi::comm_world(), &mut ksp.0), "KSPCreate")?;
        check(ffi::KSPSetFromOptions(ksp.0), "KSPSetFromOptions")
    }
}

fn has_option(name: &CStr) -> Result<bool, LinearSolverError> {
    let mut set = ffi::PETSC_FALSE;
    // SAFETY: valid C string, out-pointer to a local
    check(
        unsafe { ffi::PetscOptionsHasName(ptr::null_mut(), ptr::null(), name.as_ptr(), &mut set) },
        "PetscOptionsHasName",
    )?;
    Ok(set == ffi::PETSC_TRUE)
}

/// A C string of PETSc (a type name) as Rust text.
fn type_name(p: *const std::os::raw::c_char) -> String {
    if p.is_null() {
        String::new()
    } else {
        // SAFETY: PETSc type names are NUL-terminated static strings
        unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
    }
}

/// An owned PETSc options database.
struct Options(ffi::PetscOptions);
/// An owned PETSc matrix.
struct Mat(ffi::Mat);
/// An owned PETSc vector.
struct Vector(ffi::Vec);
/// An owned PETSc Krylov solver (with its preconditioner).
struct Ksp(ffi::KSP);
/// An owned PETSc scatter.
struct Scatter(ffi::VecScatter);

macro_rules! destroy_on_drop {
    ($t:ident, $f:ident) => {
        impl Drop for $t {
            fn drop(&mut self) {
                if !self.0.is_null() {
                    let _guard = lock();
                    // SAFETY: the handle is owned and destroyed once; PETSc is initialised
                    unsafe {
                        ffi::$f(&mut self.0);
                    }
                }
            }
        }
        // SAFETY: every use of the handle holds the process-wide PETSc lock
        unsafe impl Send for $t {}
    };
}
destroy_on_drop!(Options, PetscOptionsDestroy);
destroy_on_drop!(Mat, MatDestroy);
destroy_on_drop!(Vector, VecDestroy);
destroy_on_drop!(Ksp, KSPDestroy);
destroy_on_drop!(Scatter, VecScatterDestroy);
destroy_on_drop!(NullSpace, MatNullSpaceDestroy);
destroy_on_drop!(IndexSet, ISDestroy);

/// An owned PETSc null space.
struct NullSpace(ffi::MatNullSpace);
/// An owned PETSc index set.
struct IndexSet(ffi::IS);

/// The exchanges of [`sum_over_ranks`], one per vector length.
struct Gather {
    n: usize,
    /// This rank's vector as block `rank` of a vector of `size` blocks: no storage of its own,
    /// the caller's vector is placed in it for each sum.
    parts: Vector,
    /// This rank's chunk of every rank's vector, block after block in rank order.
    mine: Vector,
    to_mine: Scatter,
    /// The summed chunk of this rank (a distributed vector of length `n`).
    sum: Vector,
    /// The whole sum, on every rank: no storage of its own either, the caller's vector
    /// receives it.
    all: Vector,
    to_all: Scatter,
}

static GATHERS: Mutex<Vec<Gather>> = Mutex::new(Vec::new());

/// The chunk of a vector of `n` values that rank `r` of `size` sums.
fn chunk(n: usize, r: usize, size: usize) -> std::ops::Range<usize> {
    n * r / size..n * (r + 1) / size
}

/// Sums `v` over the ranks of `PETSC_COMM_WORLD` in place (collective: every rank calls it with
/// a vector of the same length). Each rank receives one chunk of every rank's vector and adds
/// them in rank order, then the summed chunks are gathered on every rank: all ranks receive the
/// same bits, and the same from run to run (a reduction tree may round differently on different
/// ranks, which would let their Newton iterations part). `v` itself is sent and receives the
/// sum (PETSc vectors without storage of their own, `v`'s array placed in them), so the buffers
/// held per vector length are the received chunks (`len` values) and the summed chunk
/// (`len`/ranks), whatever the number of ranks.
pub fn sum_over_ranks(v: &mut [f64]) -> Result<(), LinearSolverError> {
    let (rank, size) = world()?;
    if size == 1 {
        return Ok(());
    }
    let n = v.len();
    let int = |k: usize| {
        ffi::PetscInt::try_from(k).map_err(|_| {
            LinearSolverError::Failed(format!("a vector of {n} values is too long for PETSc"))
        })
    };
    int(n * size)?;
    let own = chunk(n, rank, size);
    let _guard = lock();
    let mut gathers = GATHERS.lock().unwrap_or_else(|e| e.into_inner());
    // SAFETY throughout: PETSc is initialised, handles are created before use and owned by
    // wrappers; arrays from PETSc are restored before return and have the lengths used
    unsafe {
        if !gathers.iter().any(|g| g.n == n) {
            let comm = ffi::comm_world();
            // a distributed vector of `local` values on this rank, with its own storage or
            // without (an array is then placed in it for each sum)
            let mpi_vector = |local: usize, stored: bool| -> Result<Vector, LinearSolverError> {
                let mut x = Vector(ptr::null_mut());
                let (local, all) = (int(local)?, ffi::PETSC_DECIDE as ffi::PetscInt);
                check(
                    if stored {
                        ffi::VecCreateMPI(comm, local, all, &mut x.0)
                    } else {
                        ffi::VecCreateMPIWithArray(comm, 1, local, all, ptr::null(), &mut x.0)
                    },
                    "VecCreateMPI",
                )?;
                Ok(x)
            };
            let parts = mpi_vector(n, false)?;
            let mine = mpi_vector(size * own.len(), true)?;
            let sum = mpi_vector(own.len(), true)?;
            // block q of `mine` on this rank is chunk `own` of rank q's vector
            let before: usize = (0..rank).map(|r| size * chunk(n, r, size).len()).sum();
            let from: Vec<ffi::PetscInt> = (0..size)
                .flat_map(|q| own.clone().map(move |i| (q * n + i) as ffi::PetscInt))
                .collect();
            let to: Vec<ffi::PetscInt> = (0..from.len())
                .map(|k| (before + k) as ffi::PetscInt)
                .collect();
            let (is_from, is_to) = (index_set(comm, &from)?, index_set(comm, &to)?);
            let mut to_mine = Scatter(ptr::null_mut());
            check(
                ffi::VecScatterCreate(parts.0, is_from.0, mine.0, is_to.0, &mut to_mine.0),
                "VecScatterCreate",
            )?;
            let (mut to_all, mut whole) = (Scatter(ptr::null_mut()), Vector(ptr::null_mut()));
            check(
                ffi::VecScatterCreateToAll(sum.0, &mut to_all.0, &mut whole.0),
                "VecScatterCreateToAll",
            )?;
            // the scatter's target made anew without storage, on the same (one-process)
            // communicator, so that no whole vector is held between sums
            let mut own_comm: ffi::MPI_Comm = std::mem::zeroed();
            check(
                ffi::PetscObjectGetComm(whole.0 as ffi::PetscObject, &mut own_comm),
                "PetscObjectGetComm",
            )?;
            let mut all = Vector(ptr::null_mut());
            check(
                ffi::VecCreateSeqWithArray(own_comm, 1, int(n)?, ptr::null(), &mut all.0),
                "VecCreateSeqWithArray",
            )?;
            drop(whole);
            gathers.push(Gather {
                n,
                parts,
                mine,
                to_mine,
                sum,
                all,
                to_all,
            });
        }
        let g = gathers.iter_mut().find(|g| g.n == n).expect("made above");
        // `v` is read by the first scatter and written by the second: placed in the storage-less
        // vectors for their duration only
        check(ffi::VecPlaceArray(g.parts.0, v.as_ptr()), "VecPlaceArray")?;
        let sent = scatter(&g.to_mine, &g.parts, &g.mine);
        check(ffi::VecResetArray(g.parts.0), "VecResetArray")?;
        sent?;
        // this rank's chunk, summed in rank order
        let m = own.len();
        let mut mine: *const ffi::PetscScalar = ptr::null();
        check(ffi::VecGetArrayRead(g.mine.0, &mut mine), "VecGetArrayRead")?;
        let blocks = std::slice::from_raw_parts(mine, m * size);
        let mut arr: *mut ffi::PetscScalar = ptr::null_mut();
        check(ffi::VecGetArray(g.sum.0, &mut arr), "VecGetArray")?;
        for (k, x) in std::slice::from_raw_parts_mut(arr, m)
            .iter_mut()
            .enumerate()
        {
            let mut sum = blocks[k];
            for q in 1..size {
                sum += blocks[q * m + k];
            }
            *x = sum;
        }
        check(ffi::VecRestoreArray(g.sum.0, &mut arr), "VecRestoreArray")?;
        check(
            ffi::VecRestoreArrayRead(g.mine.0, &mut mine),
            "VecRestoreArrayRead",
        )?;
        check(
            ffi::VecPlaceArray(g.all.0, v.as_mut_ptr().cast_const()),
            "VecPlaceArray",
        )?;
        let received = scatter(&g.to_all, &g.sum, &g.all);
        check(ffi::VecResetArray(g.all.0), "VecResetArray")?;
        received?;
    }
    Ok(())
}

/// An index set of `idx` (copied) on `comm`.
///
/// # Safety
/// PETSc is initialised and the caller holds the lock.
unsafe fn index_set(
    comm: ffi::MPI_Comm,
    idx: &[ffi::PetscInt],
) -> Result<IndexSet, LinearSolverError> {
    let mut is = IndexSet(ptr::null_mut());
    check(
        ffi::ISCreateGeneral(
            comm,
            idx.len() as ffi::PetscInt,
            idx.as_ptr(),
            ffi::PETSC_COPY_VALUES,
            &mut is.0,
        ),
        "ISCreateGeneral",
    )?;
    Ok(is)
}

/// Scatters `x` into `y` by `s` (inserting).
///
/// # Safety
/// PETSc is initialised, the caller holds the lock, and `s` was made for `x` and `y`.
unsafe fn scatter(s: &Scatter, x: &Vector, y: &Vector) -> Result<(), LinearSolverError> {
    scatter_with(s, x, y, ffi::INSERT_VALUES, ffi::SCATTER_FORWARD)
}

/// `s` from `x` to `y` (forward) or from `y` to `x` (reverse, `x` and `y` as `s` was made),
/// inserting or adding.
///
/// # Safety
/// As [`scatter`].
unsafe fn scatter_with(
    s: &Scatter,
    x: &Vector,
    y: &Vector,
    insert: ffi::InsertMode,
    mode: ffi::ScatterMode,
) -> Result<(), LinearSolverError> {
    let (from, to) = if mode == ffi::SCATTER_REVERSE {
        (y, x)
    } else {
        (x, y)
    };
    for step in [ffi::VecScatterBegin, ffi::VecScatterEnd] {
        check(step(s.0, from.0, to.0, insert, mode), "VecScatter")?;
    }
    Ok(())
}

/// The [`Exchange`] of a rank that holds its own equations ([`LocalEquations`]) by PETSc's
/// vector scatters, between the distributed vector of the owned equations (PETSc's rows, the
/// layout of Newton's vectors) and the ranks' stacks of their own equations (owned and ghosts):
/// a rank sends and receives only the entries it shares with its neighbours, not vectors of the
/// whole problem.
pub struct PetscExchange {
    /// The owned equations' entries, rank after rank (the global numbering's blocks).
    owned: Vector,
    /// Every rank's own equations, stacked.
    stacked: Vector,
    /// From `owned` to `stacked` (reversed: ghosts' contributions added to their owners).
    scatter: Scatter,
    /// The index among the owned of each local equation, `None` for a ghost.
    slots: Vec<Option<usize>>,
}

// SAFETY: every call into PETSc holds the process-wide lock
unsafe impl Sync for PetscExchange {}

impl PetscExchange {
    /// The exchange of the rank whose equations are `equations` (collective: every rank makes
    /// its own at the same point).
    pub fn new(equations: &LocalEquations) -> Result<Self, LinearSolverError> {
        initialize()?;
        let int = |k: usize| {
            ffi::PetscInt::try_from(k).map_err(|_| {
                LinearSolverError::Failed(format!(
                    "{k} equations are too many for this PETSc's 32-bit indices"
                ))
            })
        };
        let (n_owned, n_local) = (equations.n_owned(), equations.global.len());
        let global = int(equations.n_global())?;
        let _guard = lock();
        // SAFETY: PETSc is initialised; every handle is owned by a wrapper that destroys it
        unsafe {
            let comm = ffi::comm_world();
            let mut owned = Vector(ptr::null_mut());
            check(
                ffi::VecCreateMPI(comm, int(n_owned)?, global, &mut owned.0),
                "VecCreateMPI",
            )?;
            let (mut lo, mut hi) = (0, 0);
            check(
                ffi::VecGetOwnershipRange(owned.0, &mut lo, &mut hi),
                "VecGetOwnershipRange",
            )?;
            let rank = equations.rank;
            if (lo as usize, hi as usize) != (equations.start[rank], equations.start[rank + 1]) {
                return Err(LinearSolverError::Failed(format!(
                    "rank {rank}: PETSc's rows {lo}..{hi} are not the owned equations {}..{}",
                    equations.start[rank],
                    equations.start[rank + 1]
                )));
            }
            let mut stacked = Vector(ptr::null_mut());
            check(
                ffi::VecCreateMPI(
                    comm,
                    int(n_local)?,
                    ffi::PETSC_DECIDE as ffi::PetscInt,
                    &mut stacked.0,
                ),
                "VecCreateMPI",
            )?;
            check(
                ffi::VecGetOwnershipRange(stacked.0, &mut lo, &mut hi),
                "VecGetOwnershipRange",
            )?;
            let from: Vec<ffi::PetscInt> = equations
                .global
                .iter()
                .map(|&g| g as ffi::PetscInt)
                .collect();
            let to: Vec<ffi::PetscInt> = (lo..hi).collect();
            let (is_from, is_to) = (index_set(comm, &from)?, index_set(comm, &to)?);
            let mut scatter = Scatter(ptr::null_mut());
            check(
                ffi::VecScatterCreate(owned.0, is_from.0, stacked.0, is_to.0, &mut scatter.0),
                "VecScatterCreate",
            )?;
            Ok(PetscExchange {
                owned,
                stacked,
                scatter,
                slots: equations.slots(),
            })
        }
    }

    /// Writes `values` into `v`'s local array (of the same length).
    ///
    /// # Safety
    /// The caller holds the lock; `v` is live and its local part has `values.len()` entries.
    unsafe fn write(v: &Vector, values: impl Iterator<Item = (usize, f64)>) -> Result<(), String> {
        let mut arr: *mut ffi::PetscScalar = ptr::null_mut();
        check(ffi::VecGetArray(v.0, &mut arr), "VecGetArray").map_err(|e| e.to_string())?;
        let mut len: ffi::PetscInt = 0;
        ffi::VecGetLocalSize(v.0, &mut len);
        let local = std::slice::from_raw_parts_mut(arr, len.max(0) as usize);
        values.for_each(|(i, x)| local[i] = x);
        check(ffi::VecRestoreArray(v.0, &mut arr), "VecRestoreArray").map_err(|e| e.to_string())
    }

    /// Calls `read` with `v`'s local array.
    ///
    /// # Safety
    /// The caller holds the lock; `v` is live.
    unsafe fn read(v: &Vector, read: impl FnOnce(&[f64])) -> Result<(), String> {
        let mut arr: *const ffi::PetscScalar = ptr::null();
        check(ffi::VecGetArrayRead(v.0, &mut arr), "VecGetArrayRead").map_err(|e| e.to_string())?;
        let mut len: ffi::PetscInt = 0;
        ffi::VecGetLocalSize(v.0, &mut len);
        read(std::slice::from_raw_parts(arr, len.max(0) as usize));
        check(
            ffi::VecRestoreArrayRead(v.0, &mut arr),
            "VecRestoreArrayRead",
        )
        .map_err(|e| e.to_string())
    }

    fn check_len(&self, local: &[f64]) -> Result<(), String> {
        if local.len() == self.slots.len() {
            Ok(())
        } else {
            Err(format!(
                "a vector of {} values for this rank's {} equations",
                local.len(),
                self.slots.len()
            ))
        }
    }
}

impl Exchange for PetscExchange {
    fn add_to_owners(&self, local: &mut [f64]) -> Result<(), String> {
        self.check_len(local)?;
        let _guard = lock();
        // SAFETY: the vectors are live and have the local lengths the slots were made for
        unsafe {
            Self::write(&self.stacked, local.iter().copied().enumerate())?;
            check(ffi::VecSet(self.owned.0, 0.0), "VecSet").map_err(|e| e.to_string())?;
            scatter_with(
                &self.scatter,
                &self.owned,
                &self.stacked,
                ffi::ADD_VALUES,
                ffi::SCATTER_REVERSE,
            )
            .map_err(|e| e.to_string())?;
            Self::read(&self.owned, |owned| {
                for (x, slot) in local.iter_mut().zip(&self.slots) {
                    if let Some(i) = *slot {
                        *x = owned[i];
                    }
                }
            })
        }
    }

    fn to_ghosts(&self, local: &mut [f64]) -> Result<(), String> {
        self.check_len(local)?;
        let _guard = lock();
        // SAFETY: as in `add_to_owners`
        unsafe {
            let owned = local
                .iter()
                .zip(&self.slots)
                .filter_map(|(&x, slot)| slot.map(|i| (i, x)));
            Self::write(&self.owned, owned)?;
            scatter_with(
                &self.scatter,
                &self.owned,
                &self.stacked,
                ffi::INSERT_VALUES,
                ffi::SCATTER_FORWARD,
            )
            .map_err(|e| e.to_string())?;
            Self::read(&self.stacked, |stacked| local.copy_from_slice(stacked))
        }
    }

    fn sum(&self, values: &mut [f64]) -> Result<(), String> {
        sum_over_ranks(values).map_err(|e| e.to_string())
    }
}

/// This process's part of the orthonormal near-null space of `layout`'s system: the rigid-body
/// modes of the free displacements (3 translations and 3 rotations about the centroid in 3-D,
/// the axial translation in the meridian plane; zero on the potential rows), then, if there are
/// potentials, the constant potential (the near-null vector of the electrostatic Laplacian).
///
/// The modes are built on the rows whose unknowns `unknowns` lists (`None`: a padding row,
/// zero), and orthonormalised over every process's rows: `sum` adds a few numbers over the
/// processes (the dot products of classical Gram–Schmidt, twice for orthogonality to
/// round-off). No process holds a whole mode, which would cost 8 bytes per mode and unknown of
/// the whole problem. A tie's unknown moves with its first node. Modes that the free unknowns
/// cannot tell apart are dropped (on every process alike: the sums are the same on each).
/// Returns the modes and how many of them are rigid-body modes (the constant comes last).
pub fn near_null_modes(
    layout: &DofLayout,
    unknowns: &[Option<usize>],
    sum: &mut dyn FnMut(&mut [f64]) -> Result<(), LinearSolverError>,
) -> Result<(Vec<Vec<f64>>, usize), LinearSolverError> {
    let is_u = |e: usize| layout.field[e] < 3;
    let on_rows = |value: &dyn Fn(usize) -> f64| -> Vec<f64> {
        unknowns.iter().map(|u| u.map_or(0.0, value)).collect()
    };
    let mut rigid: Vec<Vec<f64>> = Vec::new();
    if layout.axisymmetric {
        rigid.push(on_rows(&|e| f64::from(layout.field[e] == 1)));
    } else {
        for f in 0..3u8 {
            rigid.push(on_rows(&|e| f64::from(layout.field[e] == f)));
        }
        // the centroid of the free displacements' nodes, from the layout every process holds,
        // or, where each holds its own part, summed over the processes' rows
        let (mut c, mut count) = ([0.0; 3], 0.0);
        let divided = layout.equations.is_some();
        let counted: Vec<usize> = if divided {
            unknowns.iter().flatten().copied().collect()
        } else {
            (0..layout.node.len()).collect()
        };
        for e in counted.into_iter().filter(|&e| is_u(e)) {
            let x = layout.coords[layout.node[e]];
            (0..3).for_each(|i| c[i] += x[i]);
            count += 1.0;
        }
        if divided {
            let mut sums = [c[0], c[1], c[2], count];
            sum(&mut sums)?;
            (c, count) = ([sums[0], sums[1], sums[2]], sums[3]);
        }
        if count > 0.0 {
            c.iter_mut().for_each(|v| *v /= count);
        }
        // u = ω × (x − c) for ω along each axis
        for axis in 0..3 {
            rigid.push(on_rows(&|e| {
                if !is_u(e) {
                    return 0.0;
                }
                let x = layout.coords[layout.node[e]];
                let d = [x[0] - c[0], x[1] - c[1], x[2] - c[2]];
                let mut w = [0.0; 3];
                w[axis] = 1.0;
                let u = [
                    w[1] * d[2] - w[2] * d[1],
                    w[2] * d[0] - w[0] * d[2],
                    w[0] * d[1] - w[1] * d[0],
                ];
                u[layout.field[e] as usize]
            }));
        }
    }
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut basis: Vec<Vec<f64>> = Vec::new();
    for mut m in rigid {
        let mut before = [dot(&m, &m)];
        sum(&mut before)?;
        if before[0] == 0.0 {
            continue;
        }
        // (nothing to project out of the first mode)
        for _ in 0..(if basis.is_empty() { 0 } else { 2 }) {
            let mut p: Vec<f64> = basis.iter().map(|b| dot(&m, b)).collect();
            sum(&mut p)?;
            for (b, p) in basis.iter().zip(&p) {
                m.iter_mut().zip(b).for_each(|(v, w)| *v -= p * w);
            }
        }
        let mut after = [dot(&m, &m)];
        sum(&mut after)?;
        if after[0] > 1e-20 * before[0] {
            let norm = after[0].sqrt();
            m.iter_mut().for_each(|v| *v /= norm);
            basis.push(m);
        }
    }
    let rigid = basis.len();
    let potentials = layout.field.iter().filter(|&&f| f == 3).count();
    if potentials > 0 {
        let v = 1.0 / (potentials as f64).sqrt();
        basis.push(on_rows(&|e| if layout.field[e] == 3 { v } else { 0.0 }));
    }
    Ok((basis, rigid))
}

/// Where the free unknowns sit among PETSc's rows.
///
/// With a layout every node that has a free unknown takes four consecutive rows (ux, uy, uz, Φ),
/// so the matrix has a block size of 4 even where supports, symmetry planes or electrodes hold
/// some of a node's unknowns: algebraic multigrid then aggregates whole nodes, with the
/// rigid-body modes per node. A held unknown's row is padding: decoupled, with a positive diagonal
/// and a zero right-hand side, so its solution is zero and it adds a positive pivot only (the
/// count of negative pivots, which the stability test reads, is unchanged). Without a layout the
/// rows are the unknowns.
#[derive(Debug, Clone, PartialEq)]
struct Numbering {
    /// PETSc's row of each free unknown, increasing unless ordered by owners (empty: the
    /// identity).
    row: Vec<usize>,
    /// The free unknown of each PETSc row, [`PADDING`] for a padding row (empty: the identity).
    unknown: Vec<usize>,
    /// Number of PETSc rows.
    n: usize,
    /// 4 with a layout (whole nodes), else what the pattern allows ([`block_size`]).
    block_size: usize,
    /// With owners, the first row of each rank's and the end (empty: rows split evenly).
    starts: Vec<usize>,
    /// The first row that `unknown` covers (0, or this rank's first when it covers its rows
    /// only).
    first: usize,
}

/// Marks a padding row in [`Numbering::unknown`].
const PADDING: usize = usize::MAX;

impl Numbering {
    /// The rows of `a`'s unknowns: whole nodes of `layout` when it describes them, else the
    /// identity with the block size that `a`'s pattern allows. With `owner` (the rank of each
    /// unknown, below `size`), the nodes are ordered by the rank of their first unknown, each
    /// rank's rows one range; without, in the order of the unknowns.
    fn new(
        a: &CsrMatrix,
        layout: Option<&DofLayout>,
        owner: Option<&[usize]>,
        size: usize,
    ) -> Numbering {
        let identity = |block_size| Numbering {
            row: Vec::new(),
            unknown: Vec::new(),
            n: a.n,
            block_size,
            starts: Vec::new(),
            first: 0,
        };
        let Some(layout) = layout.filter(|l| l.node.len() == a.n && a.n > 0) else {
            return identity(block_size(a));
        };
        let owner = owner.filter(|o| o.len() == a.n && o.iter().all(|&r| r < size));
        // nodes in order of their first unknown: the unknowns are numbered node-major
        let mut block = vec![PADDING; layout.coords.len()];
        let mut block_owner = Vec::new();
        for (e, &node) in layout.node.iter().enumerate() {
            if node >= block.len() || usize::from(layout.field[e]) >= FIELDS {
                return identity(block_size(a));
            }
            if block[node] == PADDING {
                block[node] = block_owner.len();
                block_owner.push(owner.map_or(0, |o| o[e]));
            }
        }
        let blocks = block_owner.len();
        // blocks by rank, in their order within a rank (a counting sort)
        let mut starts = vec![0usize; size.max(1) + 1];
        for &r in &block_owner {
            starts[r + 1] += 1;
        }
        for r in 0..starts.len() - 1 {
            starts[r + 1] += starts[r];
        }
        let mut next = starts.clone();
        let place: Vec<usize> = block_owner
            .iter()
            .map(|&r| {
                next[r] += 1;
                next[r] - 1
            })
            .collect();
        let n = FIELDS * blocks;
        let mut row = Vec::with_capacity(a.n);
        let mut unknown = vec![PADDING; n];
        for (e, (&node, &field)) in layout.node.iter().zip(&layout.field).enumerate() {
            let r = FIELDS * place[block[node]] + usize::from(field);
            // two unknowns in one place, or (without owners) rows out of the unknowns' order,
            // which must be one range of unknowns per rank
            if unknown[r] != PADDING || (owner.is_none() && row.last().is_some_and(|&l| l >= r)) {
                return identity(block_size(a));
            }
            unknown[r] = e;
            row.push(r);
        }
        Numbering {
            row,
            unknown,
            n,
            block_size: FIELDS,
            starts: if owner.is_some() {
                starts.iter().map(|&b| FIELDS * b).collect()
            } else {
                Vec::new()
            },
            first: 0,
        }
    }

    /// The rows of a system whose ranks each hold their own equations (`equations`, of `a`'s
    /// unknowns): whole nodes of four rows ([`LocalEquations::rows`], block size 4), this
    /// rank's rows its owned nodes' blocks; `unknown` covers this rank's rows only.
    fn of_equations(equations: &LocalEquations) -> Numbering {
        let rank = equations.rank;
        let first = equations.row_start[rank];
        let mut unknown = vec![PADDING; equations.row_start[rank + 1] - first];
        for (e, &r) in equations.rows.iter().enumerate() {
            if equations.owned[e] {
                unknown[r - first] = e;
            }
        }
        Numbering {
            row: equations.rows.clone(),
            unknown,
            n: equations.row_start.last().copied().unwrap_or(0),
            block_size: FIELDS,
            starts: equations.row_start.clone(),
            first,
        }
    }

    /// The rows of `rank` among `size`: its owners' range, else an even split in whole blocks.
    fn owned(&self, rank: usize, size: usize) -> std::ops::Range<usize> {
        if self.starts.len() == size + 1 {
            self.starts[rank]..self.starts[rank + 1]
        } else {
            owned_rows(self.n, self.block_size, rank, size)
        }
    }

    /// PETSc's row of unknown `e`.
    fn row(&self, e: usize) -> usize {
        if self.row.is_empty() {
            e
        } else {
            self.row[e]
        }
    }

    /// The unknown of PETSc's row `r`, or `None` for a padding row.
    fn unknown(&self, r: usize) -> Option<usize> {
        if self.unknown.is_empty() {
            Some(r)
        } else {
            Some(self.unknown[r - self.first]).filter(|&e| e != PADDING)
        }
    }

    /// The unknowns whose rows lie in `rows` (one range: without owners the rows increase with
    /// the unknowns).
    fn unknowns_in(&self, rows: &std::ops::Range<usize>) -> std::ops::Range<usize> {
        debug_assert!(self.starts.is_empty());
        if self.row.is_empty() {
            return rows.clone();
        }
        self.row.partition_point(|&r| r < rows.start)..self.row.partition_point(|&r| r < rows.end)
    }

    /// The padding rows among `rows`.
    fn padding_in(&self, rows: std::ops::Range<usize>) -> impl Iterator<Item = usize> + '_ {
        rows.filter(|&r| self.unknown(r).is_none())
    }
}

/// The PETSc objects of one matrix pattern. Fields drop in order: the solver before its matrix.
struct System {
    ksp: Ksp,
    /// The gather of the whole solution to every rank, and its sequential vector there; `None`
    /// when each rank holds its own unknowns only ([`DofLayout::equations`]): the vectors are
    /// then its rows' part.
    gather: Option<(Scatter, Vector)>,
    /// Without the gather: the index in the vectors of the rank's owned unknowns of each of its
    /// rows, [`PADDING`] for a padding row.
    slots: Vec<usize>,
    x: Vector,
    b: Vector,
    mat: Mat,
    options: Options,
    /// Number of unknowns of the matrix passed (PETSc's rows are `numbering.n`).
    n: usize,
    /// Number of unknowns of the whole problem (`n`, or with the unknowns divided between the
    /// ranks all ranks' together).
    total: usize,
    nnz: usize,
    /// Where the unknowns sit among PETSc's rows.
    numbering: Numbering,
    /// Whether the matrix is this rank's part of a shared assembly (it passes every entry),
    /// else the whole matrix (it passes its rows').
    shared: bool,
    /// Number of rigid-body modes attached as the near-null space.
    modes: usize,
    /// Krylov iterations of the last solve (of both attempts when a kept preconditioner was
    /// renewed during it).
    iterations: usize,
    /// Decades of residual reduction the last solve was asked for (0 for a direct solve).
    decades: f64,
    /// The PETSc rows this rank owns.
    rows: std::ops::Range<usize>,
    /// Whether the preconditioner is a MUMPS Cholesky (LDLᵀ) factorisation, which gives the
    /// inertia.
    gives_inertia: bool,
    /// Whether the KSP iterates (not `preonly`): only then may a solve stop at Newton's
    /// forcing term.
    iterates: bool,
    /// The preconditioner's life across matrices ([`Renewal`]).
    renewal: Renewal,
    /// Rank 0 with `DEASIM_PETSC_VERBOSE` set: a line per solve on stderr.
    verbose: bool,
    description: String,
}

/// When an iterating KSP's preconditioner is set up anew. Setting up algebraic multigrid costs
/// several Krylov iterations' worth (a whole hierarchy of Galerkin products), and a
/// preconditioner of a nearby tangent usually still serves: the tangents of one run change
/// slowly between Newton iterations and load steps.
#[derive(Debug, Clone, Default)]
struct Renewal {
    /// Keep the preconditioner across matrices, setting it up anew only when it has grown
    /// stale (else: at every matrix, PETSc's default).
    keeps: bool,
    /// Whether a preconditioner has been set up at all.
    set_up: bool,
    /// The next matrix gets a fresh preconditioner.
    due: bool,
    /// The preconditioner was set up with the current matrix.
    fresh: bool,
    /// Krylov iterations per decade of residual reduction of the first solve after the last
    /// set-up: the measure of a fresh preconditioner's quality.
    baseline: Option<f64>,
    /// Preconditioner set-ups so far.
    setups: usize,
}

/// A kept preconditioner is renewed once a solve needs this many times the Krylov iterations per
/// decade of the first solve after its set-up.
const STALE_GROWTH: f64 = 2.0;

impl Renewal {
    /// Whether the next set-up keeps the preconditioner.
    fn keep_next(&self) -> bool {
        self.keeps && self.set_up && !self.due
    }

    /// Records a set-up: fresh (`kept` false) or the old preconditioner kept.
    fn record_set_up(&mut self, kept: bool) {
        self.fresh = !kept;
        if !kept {
            self.set_up = true;
            self.due = false;
            self.baseline = None;
            self.setups += 1;
        }
    }

    /// Records a converged solve of `iterations` Krylov iterations that reduced the residual by
    /// `decades` decades; marks the preconditioner due for renewal when it has grown stale.
    fn record_solve(&mut self, iterations: usize, decades: f64) {
        let rate = iterations as f64 / decades.max(1.0);
        match self.baseline {
            None => self.baseline = Some(rate.max(1.0)),
            Some(base) => {
                if self.keeps && rate > STALE_GROWTH * base {
                    self.due = true;
                }
            }
        }
    }
}

/// While alive, `options` is PETSc's default options database (the lock must be held).
struct Scope;

impl Scope {
    fn push(options: &Options) -> Result<Scope, LinearSolverError> {
        // SAFETY: the database is live; it is popped by the guard's drop
        check(
            unsafe { ffi::PetscOptionsPush(options.0) },
            "PetscOptionsPush",
        )?;
        Ok(Scope)
    }
}

impl Drop for Scope {
    fn drop(&mut self) {
        // SAFETY: pops what `push` pushed
        unsafe {
            ffi::PetscOptionsPop();
        }
    }
}

/// The block size of the matrix: 4 when every aligned group of 4 rows has one pattern made of
/// whole aligned groups of 4 columns (every node keeps all its unknowns free), else 1.
pub fn block_size(a: &CsrMatrix) -> usize {
    const BS: usize = 4;
    if a.n == 0 || !a.n.is_multiple_of(BS) {
        return 1;
    }
    for block in 0..a.n / BS {
        let first = block * BS;
        let cols = &a.col_idx[a.row_ptr[first]..a.row_ptr[first + 1]];
        if !cols.len().is_multiple_of(BS) {
            return 1;
        }
        for chunk in cols.chunks(BS) {
            let c0 = chunk[0] as usize;
            if !c0.is_multiple_of(BS)
                || chunk.iter().enumerate().any(|(k, &c)| c as usize != c0 + k)
            {
                return 1;
            }
        }
        for r in first + 1..first + BS {
            if a.col_idx[a.row_ptr[r]..a.row_ptr[r + 1]] != *cols {
                return 1;
            }
        }
    }
    BS
}

/// The rows of `rank` among `size`: contiguous, whole blocks, as even as possible.
fn owned_rows(n: usize, block_size: usize, rank: usize, size: usize) -> std::ops::Range<usize> {
    let blocks = n / block_size;
    let lo = blocks * rank / size;
    let hi = blocks * (rank + 1) / size;
    lo * block_size..hi * block_size
}

impl System {
    /// Creates the matrix (preallocated with the pattern of every rank's entries in this rank's
    /// rows), the vectors, the gather to every rank and the KSP with its defaults and the options
    /// applied.
    fn new(
        a: &CsrMatrix,
        options: &str,
        fixed: bool,
        keep: bool,
        layout: Option<&DofLayout>,
    ) -> Result<System, LinearSolverError> {
        if ffi::PetscInt::try_from(a.n).is_err() {
            return Err(LinearSolverError::Failed(format!(
                "{} unknowns are too many for this PETSc's 32-bit indices",
                a.n
            )));
        }
        let (rank, size) = world()?;
        let layout = layout.filter(|l| l.node.len() == a.n);
        let shared = layout.is_some_and(|l| l.shared);
        // each rank holds its own equations' entries of the vectors only
        let divided = layout.and_then(|l| l.equations.as_ref());
        // with shared cells, each rank owns the rows of the equations it takes the terms of
        // (at nodes of its own cells), so that most of its entries stay on it
        let mut owner: Option<Vec<usize>> = None;
        if let Some(owned) = layout.and_then(|l| l.owned.as_ref()).filter(|_| shared) {
            let mut ranks: Vec<f64> = owned
                .iter()
                .map(|&own| if own { (rank + 1) as f64 } else { 0.0 })
                .collect();
            sum_over_ranks(&mut ranks)?;
            owner = Some(
                ranks
                    .iter()
                    .map(|&r| (r as usize).wrapping_sub(1))
                    .collect(),
            );
        }
        let mut numbering = match divided {
            Some(equations) => Numbering::of_equations(equations),
            None => Numbering::new(a, layout, owner.as_deref(), size),
        };
        drop(owner);
        if ffi::PetscInt::try_from(numbering.n).is_err() {
            return Err(LinearSolverError::Failed(format!(
                "{} rows (the unknowns in whole nodes) are too many for this PETSc's 32-bit \
                 indices",
                numbering.n
            )));
        }
        if shared && numbering.row.is_empty() {
            // each rank sees only its part of the pattern: the block size holds if it holds
            // on every rank
            let mut fails = [f64::from(u8::from(numbering.block_size == 1))];
            sum_over_ranks(&mut fails)?;
            if fails[0] > 0.0 {
                numbering.block_size = 1;
            }
        }
        let _guard = lock();
        let rows = numbering.owned(rank, size);
        if shared && std::env::var_os("DEASIM_PETSC_VERBOSE").is_some() {
            let total = divided.map_or(a.n, |e| e.n_global());
            report_locality(a, &numbering, &rows, (rank, size), total);
        }
        // SAFETY throughout: PETSc is initialised, every handle is created before it is used
        // and owned by a wrapper that destroys it
        unsafe {
            let comm = ffi::comm_world();
            let mut db = Options(ptr::null_mut());
            check(ffi::PetscOptionsCreate(&mut db.0), "PetscOptionsCreate")?;
            let scope = Scope::push(&db)?;
            let mat = create_matrix(comm, a, &numbering, rows.clone(), shared)?;
            let (mut x, mut b) = (Vector(ptr::null_mut()), Vector(ptr::null_mut()));
            check(
                ffi::MatCreateVecs(mat.0, &mut x.0, &mut b.0),
                "MatCreateVecs",
            )?;
            let mut slots = Vec::new();
            let gather = if let Some(equations) = divided {
                let first = equations.start[rank];
                slots = rows
                    .clone()
                    .map(|r| {
                        numbering
                            .unknown(r)
                            .map_or(PADDING, |e| equations.global[e] - first)
                    })
                    .collect();
                None
            } else {
                let (mut scatter, mut x_all) = (Scatter(ptr::null_mut()), Vector(ptr::null_mut()));
                check(
                    ffi::VecScatterCreateToAll(x.0, &mut scatter.0, &mut x_all.0),
                    "VecScatterCreateToAll",
                )?;
                Some((scatter, x_all))
            };
            let (ksp, mut description, gives_inertia) = create_ksp(comm, &mat, options, fixed)?;
            let iterates = ksp_type(&ksp)? != "preonly";
            // a kept preconditioner only under a Krylov method, never for the inertia (that
            // needs the current matrix's factor), and not against PETSc's own
            // `-ksp_reuse_preconditioner`, which keeps it for good
            let renewal = Renewal {
                keeps: keep
                    && iterates
                    && !gives_inertia
                    && !has_option(c"-ksp_reuse_preconditioner")?,
                ..Renewal::default()
            };
            let mut modes = 0;
            // a factorisation needs no modes
            let direct = description.contains("PC cholesky") || description.contains("PC lu");
            if let Some(layout) = layout.filter(|_| !direct) {
                modes = attach_modes(comm, &ksp, &mat, layout, &numbering, rows.clone())?;
                description.push_str(&format!(", near-null space of {modes} rigid-body modes"));
            }
            if rank == 0 && std::env::var_os("DEASIM_PETSC_VERBOSE").is_some() {
                log::info!("deasim: PETSc solves by {description}");
            }
            drop(scope);
            Ok(System {
                ksp,
                gather,
                slots,
                x,
                b,
                mat,
                options: db,
                n: a.n,
                total: divided.map_or(a.n, |e| e.n_global()),
                nnz: a.nnz(),
                numbering,
                shared,
                modes,
                iterations: 0,
                decades: 0.0,
                rows,
                gives_inertia,
                iterates,
                renewal,
                verbose: rank == 0 && std::env::var_os("DEASIM_PETSC_VERBOSE").is_some(),
                description,
            })
        }
    }

    /// Copies this rank's values into the matrix and sets up (factors) the preconditioner.
    fn factor(&mut self, a: &CsrMatrix) -> Result<Option<Inertia>, LinearSolverError> {
        let _guard = lock();
        let _scope = Scope::push(&self.options)?;
        let passed = passed_unknowns(&self.numbering, &self.rows, a.n, self.shared);
        // the padding's diagonal: the mean magnitude of the passed diagonal entries
        let (mut sum, mut count) = (0.0, 0usize);
        if self
            .numbering
            .padding_in(self.rows.clone())
            .next()
            .is_some()
        {
            for i in passed.clone() {
                if let Some(k) = a.position(i, i) {
                    sum += a.values[k].abs();
                    count += 1;
                }
            }
        }
        let diagonal = if count > 0 && sum > 0.0 {
            sum / count as f64
        } else {
            1.0
        };
        // SAFETY: the handles are live; the matrix has the pattern of exactly these entries.
        // Repeated and other ranks' entries of one position are summed.
        unsafe {
            check(ffi::MatZeroEntries(self.mat.0), "MatZeroEntries")?;
            set_rows(
                &self.mat,
                a,
                &self.numbering,
                passed,
                self.rows.clone(),
                Some(&a.values),
                diagonal,
                ffi::ADD_VALUES,
            )?;
            for option in [ffi::MAT_SYMMETRIC, ffi::MAT_SYMMETRY_ETERNAL] {
                check(
                    ffi::MatSetOption(self.mat.0, option, ffi::PETSC_TRUE),
                    "MatSetOption",
                )?;
            }
            self.set_up(self.renewal.keep_next())?;
            if !self.gives_inertia {
                return Ok(None);
            }
            let mut pc: ffi::PC = ptr::null_mut();
            check(ffi::KSPGetPC(self.ksp.0, &mut pc), "KSPGetPC")?;
            let mut factor: ffi::Mat = ptr::null_mut();
            check(ffi::PCFactorGetMatrix(pc, &mut factor), "PCFactorGetMatrix")?;
            let mut negative: ffi::PetscInt = 0;
            check(
                ffi::MatGetInertia(factor, &mut negative, ptr::null_mut(), ptr::null_mut()),
                "MatGetInertia",
            )?;
            let negative = negative as usize;
            Ok(Some(Inertia {
                positive: self.total - negative.min(self.total),
                negative,
                zero: 0,
            }))
        }
    }

    /// Sets the KSP up for the current matrix: the preconditioner anew, or the old one kept
    /// (`keep`, with [`Renewal::keeps`] only; the Krylov method then runs on the new matrix).
    ///
    /// # Safety
    /// The caller holds the lock and has pushed the solver's options.
    unsafe fn set_up(&mut self, keep: bool) -> Result<(), LinearSolverError> {
        if self.renewal.keeps {
            check(
                ffi::KSPSetReusePreconditioner(
                    self.ksp.0,
                    if keep {
                        ffi::PETSC_TRUE
                    } else {
                        ffi::PETSC_FALSE
                    },
                ),
                "KSPSetReusePreconditioner",
            )?;
        }
        check(ffi::KSPSetUp(self.ksp.0), "KSPSetUp")?;
        let mut pc: ffi::PC = ptr::null_mut();
        check(ffi::KSPGetPC(self.ksp.0, &mut pc), "KSPGetPC")?;
        let mut failed: ffi::PCFailedReason = ffi::PC_NOERROR;
        check(ffi::PCGetFailedReason(pc, &mut failed), "PCGetFailedReason")?;
        if failed == ffi::PC_FACTOR_STRUCT_ZEROPIVOT || failed == ffi::PC_FACTOR_NUMERIC_ZEROPIVOT {
            return Err(LinearSolverError::Singular(0));
        }
        if failed != ffi::PC_NOERROR {
            return Err(LinearSolverError::Failed(format!(
                "PETSc preconditioner set-up failed ({}; PCFailedReason {failed})",
                self.description
            )));
        }
        self.renewal.record_set_up(keep);
        Ok(())
    }

    /// Runs the KSP on the filled right-hand side: its iterations and converged reason.
    ///
    /// # Safety
    /// The caller holds the lock and has pushed the solver's options.
    unsafe fn krylov(&mut self) -> Result<(usize, ffi::KSPConvergedReason), LinearSolverError> {
        check(ffi::KSPSolve(self.ksp.0, self.b.0, self.x.0), "KSPSolve")?;
        let mut its: ffi::PetscInt = 0;
        check(
            ffi::KSPGetIterationNumber(self.ksp.0, &mut its),
            "KSPGetIterationNumber",
        )?;
        let mut reason: ffi::KSPConvergedReason = 0;
        check(
            ffi::KSPGetConvergedReason(self.ksp.0, &mut reason),
            "KSPGetConvergedReason",
        )?;
        let its = its.max(0) as usize;
        self.iterations += its;
        Ok((its, reason))
    }

    /// Solves with this rank's part of `b` and overwrites all of `b` with the solution. An
    /// iterating KSP stops at the relative residual `forcing` when that is looser than its own
    /// tolerance (as PETSc's SNES does with `-snes_ksp_ew`: the KSP's own norm, by default the
    /// preconditioned residual's for GMRES); its tolerances are restored afterwards. A solve
    /// that fails with a kept preconditioner is repeated once with a fresh one.
    fn solve(&mut self, b: &mut [f64], forcing: Option<f64>) -> Result<(), LinearSolverError> {
        let _guard = lock();
        let _scope = Scope::push(&self.options)?;
        // SAFETY: the handles are live; arrays obtained from PETSc are restored before return
        // and have the local (for b) or global (for x_all) length
        self.iterations = 0;
        unsafe {
            let mut arr: *mut ffi::PetscScalar = ptr::null_mut();
            check(ffi::VecGetArray(self.b.0, &mut arr), "VecGetArray")?;
            let owned = self.slots.iter().filter(|&&s| s != PADDING).count();
            if self.gather.is_none() && b.len() != owned {
                check(ffi::VecRestoreArray(self.b.0, &mut arr), "VecRestoreArray")?;
                return Err(LinearSolverError::Failed(format!(
                    "a right-hand side of {} values for this rank's {owned} unknowns",
                    b.len()
                )));
            }
            let local = std::slice::from_raw_parts_mut(arr, self.rows.len());
            if self.gather.is_some() {
                for (x, r) in local.iter_mut().zip(self.rows.clone()) {
                    *x = self.numbering.unknown(r).map_or(0.0, |e| b[e]);
                }
            } else {
                // `b` holds this rank's owned unknowns
                for (x, &slot) in local.iter_mut().zip(&self.slots) {
                    *x = if slot == PADDING { 0.0 } else { b[slot] };
                }
            }
            check(ffi::VecRestoreArray(self.b.0, &mut arr), "VecRestoreArray")?;

            let (mut rtol, mut atol, mut dtol, mut max_its) = (0.0, 0.0, 0.0, 0);
            check(
                ffi::KSPGetTolerances(self.ksp.0, &mut rtol, &mut atol, &mut dtol, &mut max_its),
                "KSPGetTolerances",
            )?;
            // the tolerance of this solve: Newton's forcing term when looser than the KSP's
            let loose = forcing.filter(|&eta| self.iterates && eta > rtol);
            let target = loose.unwrap_or(rtol);
            if let Some(eta) = loose {
                check(
                    ffi::KSPSetTolerances(self.ksp.0, eta, atol, dtol, max_its),
                    "KSPSetTolerances",
                )?;
            }
            let mut solved = self.krylov();
            if matches!(solved, Ok((_, reason)) if reason <= 0)
                && self.renewal.keeps
                && !self.renewal.fresh
            {
                // a kept preconditioner no longer serves: once more with a fresh one
                solved = self.set_up(false).and_then(|()| self.krylov());
            }
            if loose.is_some() {
                check(
                    ffi::KSPSetTolerances(self.ksp.0, rtol, atol, dtol, max_its),
                    "KSPSetTolerances",
                )?;
            }
            let (its, reason) = solved?;
            if reason <= 0 {
                let mut rnorm: ffi::PetscReal = 0.0;
                ffi::KSPGetResidualNorm(self.ksp.0, &mut rnorm);
                let name = type_name(*ffi::KSPConvergedReasons.offset(reason as isize));
                return Err(LinearSolverError::Failed(format!(
                    "PETSc solve did not converge ({}): {name} after {its} iterations, residual \
                     norm {rnorm:.3e}",
                    self.description
                )));
            }
            if self.verbose {
                log::info!(
                    "deasim: PETSc solve: {its} Krylov iterations to {target:.1e} with a {} \
                     preconditioner",
                    if self.renewal.fresh { "fresh" } else { "kept" }
                );
            }
            self.decades = 0.0;
            if self.iterates && target > 0.0 {
                self.decades = -target.log10();
                self.renewal.record_solve(its, self.decades);
            }

            let Some((gather, x_all)) = &self.gather else {
                let mut arr: *const ffi::PetscScalar = ptr::null();
                check(ffi::VecGetArrayRead(self.x.0, &mut arr), "VecGetArrayRead")?;
                let x = std::slice::from_raw_parts(arr, self.rows.len());
                for (&v, &slot) in x.iter().zip(&self.slots) {
                    if slot != PADDING {
                        b[slot] = v;
                    }
                }
                check(
                    ffi::VecRestoreArrayRead(self.x.0, &mut arr),
                    "VecRestoreArrayRead",
                )?;
                return Ok(());
            };
            scatter(gather, &self.x, x_all)?;
            let mut arr: *const ffi::PetscScalar = ptr::null();
            check(ffi::VecGetArrayRead(x_all.0, &mut arr), "VecGetArrayRead")?;
            let all = std::slice::from_raw_parts(arr, self.numbering.n);
            for (e, x) in b.iter_mut().enumerate().take(self.n) {
                *x = all[self.numbering.row(e)];
            }
            check(
                ffi::VecRestoreArrayRead(x_all.0, &mut arr),
                "VecRestoreArrayRead",
            )?;
        }
        Ok(())
    }
}

/// Prints on stderr how many of the whole problem's `total` unknowns this rank's rows hold, and
/// how many of the entries this rank passes (its own cells' part of a shared
/// assembly) lie in the PETSc rows it owns, and how many would with the rows split evenly: with
/// the rows following the cell partition, most entries need no communication.
fn report_locality(
    a: &CsrMatrix,
    numbering: &Numbering,
    rows: &std::ops::Range<usize>,
    (rank, size): (usize, usize),
    total: usize,
) {
    let even = owned_rows(numbering.n, numbering.block_size, rank, size);
    let (mut all, mut own, mut split) = (0usize, 0usize, 0usize);
    for i in passed_unknowns(numbering, rows, a.n, true) {
        let (r, len) = (numbering.row(i), a.row_ptr[i + 1] - a.row_ptr[i]);
        all += len;
        own += usize::from(rows.contains(&r)) * len;
        split += usize::from(even.contains(&r)) * len;
    }
    let percent = |k: usize| 100.0 * k as f64 / all.max(1) as f64;
    // the rows that are unknowns, not padding of a node's held ones
    let unknowns = if numbering.unknown.is_empty() {
        rows.len()
    } else {
        rows.clone()
            .filter(|&r| numbering.unknown(r).is_some())
            .count()
    };
    let line = format!(
        "deasim: rank {rank}: PETSc rows {}..{} of {} ({unknowns} of {} unknowns); of the {all} \
         entries it passes, {:.1} % in its own rows ({:.1} % with the rows split evenly)\n",
        rows.start,
        rows.end,
        numbering.n,
        total,
        percent(own),
        percent(split)
    );
    // one write, so that the ranks' lines do not interleave
    use std::io::Write;
    let _ = std::io::stderr().write_all(line.as_bytes());
}

/// The unknowns of `a` whose rows this rank passes to PETSc: every unknown of a shared assembly
/// (`a` is this rank's part of a sum, its entries may lie in any row), else those of the PETSc
/// rows `rows` it owns.
fn passed_unknowns(
    numbering: &Numbering,
    rows: &std::ops::Range<usize>,
    n: usize,
    shared: bool,
) -> std::ops::Range<usize> {
    if shared {
        0..n
    } else {
        numbering.unknowns_in(rows)
    }
}

/// Puts the entries of `a`'s rows `passed` on `numbering`'s rows, and `diagonal` on the padding
/// rows among `rows`, into `mat` by `MatSetValues` with `mode`, and assembles it: rows another
/// rank owns are sent to it, where PETSc sums them. The values are `a`'s, or zeros without
/// `values` (the pattern alone).
///
/// # Safety
/// PETSc is initialised, the caller holds the lock, and `mat` has `numbering.n` rows.
#[allow(clippy::too_many_arguments)]
unsafe fn set_rows(
    mat: &Mat,
    a: &CsrMatrix,
    numbering: &Numbering,
    passed: std::ops::Range<usize>,
    rows: std::ops::Range<usize>,
    values: Option<&[f64]>,
    diagonal: f64,
    mode: ffi::InsertMode,
) -> Result<(), LinearSolverError> {
    let longest = passed
        .clone()
        .map(|i| a.row_ptr[i + 1] - a.row_ptr[i])
        .max()
        .unwrap_or(0);
    let zeros = if values.is_none() {
        vec![0.0; longest]
    } else {
        Vec::new()
    };
    let mut cols: Vec<ffi::PetscInt> = Vec::with_capacity(longest);
    for i in passed {
        let span = a.row_ptr[i]..a.row_ptr[i + 1];
        if span.is_empty() {
            continue;
        }
        cols.clear();
        cols.extend(
            a.col_idx[span.clone()]
                .iter()
                .map(|&j| numbering.row(j as usize) as ffi::PetscInt),
        );
        let row = numbering.row(i) as ffi::PetscInt;
        check(
            ffi::MatSetValues(
                mat.0,
                1,
                &row,
                cols.len() as ffi::PetscInt,
                cols.as_ptr(),
                values.map_or(zeros.as_ptr(), |v| v[span].as_ptr()),
                mode,
            ),
            "MatSetValues",
        )?;
    }
    for r in numbering.padding_in(rows) {
        let r = r as ffi::PetscInt;
        check(
            ffi::MatSetValues(mat.0, 1, &r, 1, &r, &diagonal, mode),
            "MatSetValues",
        )?;
    }
    for step in [ffi::MatAssemblyBegin, ffi::MatAssemblyEnd] {
        check(step(mat.0, ffi::MAT_FINAL_ASSEMBLY), "MatAssembly")?;
    }
    Ok(())
}

/// An empty matrix of `type_name` on `numbering`'s rows, of which this rank owns `rows`.
///
/// # Safety
/// PETSc is initialised and the caller holds the lock.
unsafe fn new_mat(
    comm: ffi::MPI_Comm,
    numbering: &Numbering,
    rows: &std::ops::Range<usize>,
    type_name: &[u8],
) -> Result<Mat, LinearSolverError> {
    let (n, local) = (numbering.n as ffi::PetscInt, rows.len() as ffi::PetscInt);
    let mut mat = Mat(ptr::null_mut());
    check(ffi::MatCreate(comm, &mut mat.0), "MatCreate")?;
    check(ffi::MatSetSizes(mat.0, local, local, n, n), "MatSetSizes")?;
    check(
        ffi::MatSetType(mat.0, type_name.as_ptr().cast()),
        "MatSetType",
    )?;
    check(
        ffi::MatSetBlockSize(mat.0, numbering.block_size as ffi::PetscInt),
        "MatSetBlockSize",
    )?;
    Ok(mat)
}

/// An AIJ matrix on `numbering`'s rows whose rows `rows` are this rank's, preallocated with the
/// union over the ranks of the pattern each passes ([`passed_unknowns`]) and of the padding
/// diagonal.
///
/// The pattern goes through PETSc's preallocator matrix (`MATPREALLOCATOR`: hash sets of the
/// entries, other ranks' rows sent to them), which is freed before the first values arrive. The
/// values then go in by `MatSetValues` ([`set_rows`]), so PETSc keeps nothing beside the AIJ
/// matrix itself: its COO assembly kept maps of several words per entry for the whole run (on a
/// 62 500-unknown cube on one rank, 164 MB against the matrix's 76 MB).
///
/// # Safety
/// PETSc is initialised and the caller holds the lock.
unsafe fn create_matrix(
    comm: ffi::MPI_Comm,
    a: &CsrMatrix,
    numbering: &Numbering,
    rows: std::ops::Range<usize>,
    shared: bool,
) -> Result<Mat, LinearSolverError> {
    let passed = passed_unknowns(numbering, &rows, a.n, shared);
    let pattern = new_mat(comm, numbering, &rows, ffi::MATPREALLOCATOR)?;
    check(ffi::MatSetUp(pattern.0), "MatSetUp")?;
    set_rows(
        &pattern,
        a,
        numbering,
        passed,
        rows.clone(),
        None,
        0.0,
        ffi::INSERT_VALUES,
    )?;
    let mat = new_mat(comm, numbering, &rows, ffi::MATAIJ)?;
    // the pattern filled in with zeros: entries no rank passes never appear
    check(
        ffi::MatPreallocatorPreallocate(pattern.0, ffi::PETSC_TRUE, mat.0),
        "MatPreallocatorPreallocate",
    )?;
    drop(pattern);
    check(
        ffi::MatSetOption(mat.0, ffi::MAT_NEW_NONZERO_ALLOCATION_ERR, ffi::PETSC_TRUE),
        "MatSetOption",
    )?;
    Ok(mat)
}

/// Distributed vectors of `modes`, each this rank's part (the same length on every mode), for a
/// null space on `comm`.
///
/// # Safety
/// PETSc is initialised and the caller holds the lock.
unsafe fn mode_vectors(
    comm: ffi::MPI_Comm,
    modes: &[Vec<f64>],
) -> Result<NullSpace, LinearSolverError> {
    let mut vectors: Vec<Vector> = Vec::with_capacity(modes.len());
    for m in modes {
        let mut v = Vector(ptr::null_mut());
        check(
            ffi::VecCreateMPI(
                comm,
                m.len() as ffi::PetscInt,
                ffi::PETSC_DECIDE as ffi::PetscInt,
                &mut v.0,
            ),
            "VecCreateMPI",
        )?;
        let mut arr: *mut ffi::PetscScalar = ptr::null_mut();
        check(ffi::VecGetArray(v.0, &mut arr), "VecGetArray")?;
        std::slice::from_raw_parts_mut(arr, m.len()).copy_from_slice(m);
        check(ffi::VecRestoreArray(v.0, &mut arr), "VecRestoreArray")?;
        vectors.push(v);
    }
    let handles: Vec<ffi::Vec> = vectors.iter().map(|v| v.0).collect();
    let mut space = NullSpace(ptr::null_mut());
    // the null space keeps its own references to the vectors
    check(
        ffi::MatNullSpaceCreate(
            comm,
            ffi::PETSC_FALSE,
            handles.len() as ffi::PetscInt,
            handles.as_ptr(),
            &mut space.0,
        ),
        "MatNullSpaceCreate",
    )?;
    Ok(space)
}

/// Attaches the orthonormal near-null space of [`near_null_modes`] on this rank's rows `rows`
/// as the near-null space of `mat`, and names the fields for a field-split preconditioner:
/// split `u` (the displacement rows, with the rigid-body modes restricted to them as its
/// near-null space) and split `p` (the potential rows), when both are present. Returns the
/// number of rigid-body modes.
///
/// # Safety
/// PETSc is initialised, the caller holds the lock and has pushed the solver's database.
unsafe fn attach_modes(
    comm: ffi::MPI_Comm,
    ksp: &Ksp,
    mat: &Mat,
    layout: &DofLayout,
    numbering: &Numbering,
    rows: std::ops::Range<usize>,
) -> Result<usize, LinearSolverError> {
    let unknowns: Vec<Option<usize>> = rows.clone().map(|r| numbering.unknown(r)).collect();
    let (space, rigid) = near_null_modes(layout, &unknowns, &mut sum_over_ranks)?;
    // the field of each row: a padding row's is its place in the node's block
    let field = |r: usize| match numbering.unknown(r) {
        Some(e) => layout.field[e],
        None => (r % FIELDS) as u8,
    };
    if !space.is_empty() {
        let space = mode_vectors(comm, &space)?;
        check(
            ffi::MatSetNearNullSpace(mat.0, space.0),
            "MatSetNearNullSpace",
        )?;
    }
    let has_u = layout.field.iter().any(|&f| f < 3);
    let has_p = layout.field.contains(&3);
    if !(has_u && has_p) {
        return Ok(rigid);
    }
    let mut pc: ffi::PC = ptr::null_mut();
    check(ffi::KSPGetPC(ksp.0, &mut pc), "KSPGetPC")?;
    for (name, potential) in [(c"u", false), (c"p", true)] {
        let rows_of: Vec<ffi::PetscInt> = rows
            .clone()
            .filter(|&r| (field(r) == 3) == potential)
            .map(|r| r as ffi::PetscInt)
            .collect();
        let is = index_set(comm, &rows_of)?;
        if !potential && rigid > 0 {
            // the displacement block's modes: the sub-matrix's rows are the IS's, in order (the
            // rigid-body modes are zero on the potential rows, so they stay orthonormal)
            let restricted: Vec<Vec<f64>> = space[..rigid]
                .iter()
                .map(|m| {
                    rows.clone()
                        .zip(m)
                        .filter(|&(r, _)| field(r) < 3)
                        .map(|(_, &v)| v)
                        .collect()
                })
                .collect();
            let space = mode_vectors(comm, &restricted)?;
            check(
                ffi::PetscObjectCompose(
                    is.0 as ffi::PetscObject,
                    c"nearnullspace".as_ptr(),
                    space.0 as ffi::PetscObject,
                ),
                "PetscObjectCompose",
            )?;
        }
        // a no-op unless the preconditioner is a field split
        check(
            ffi::PCFieldSplitSetIS(pc, name.as_ptr(), is.0),
            "PCFieldSplitSetIS",
        )?;
    }
    Ok(rigid)
}

/// Makes `ksp` a direct solve by MUMPS's Cholesky (LDLᵀ for symmetric indefinite matrices).
///
/// # Safety
/// PETSc is initialised and `ksp` is a live KSP.
unsafe fn set_mumps_ldlt(ksp: &Ksp) -> Result<(), LinearSolverError> {
    check(
        ffi::KSPSetType(ksp.0, ffi::KSPPREONLY.as_ptr().cast()),
        "KSPSetType",
    )?;
    let mut pc: ffi::PC = ptr::null_mut();
    check(ffi::KSPGetPC(ksp.0, &mut pc), "KSPGetPC")?;
    check(
        ffi::PCSetType(pc, ffi::PCCHOLESKY.as_ptr().cast()),
        "PCSetType",
    )?;
    check(
        ffi::PCFactorSetMatSolverType(pc, ffi::MATSOLVERMUMPS.as_ptr().cast()),
        "PCFactorSetMatSolverType",
    )
}

/// The KSP on `mat`: deasim's default (MUMPS Cholesky, i.e. LDLᵀ), then the scenario's options
/// and `PETSC_OPTIONS` inserted into the current (the solver's own) database and applied; with
/// `fixed` the default method is kept whatever they say (only MUMPS's parameters apply).
/// Returns it with a description and whether its factorisation gives the inertia.
///
/// # Safety
/// PETSc is initialised, the caller holds the lock and has pushed the solver's database.
unsafe fn create_ksp(
    comm: ffi::MPI_Comm,
    mat: &Mat,
    options: &str,
    fixed: bool,
) -> Result<(Ksp, String, bool), LinearSolverError> {
    let mut ksp = Ksp(ptr::null_mut());
    check(ffi::KSPCreate(comm, &mut ksp.0), "KSPCreate")?;
    check(ffi::KSPSetOperators(ksp.0, mat.0, mat.0), "KSPSetOperators")?;
    set_mumps_ldlt(&ksp)?;
    insert_options(options, "[solver] petsc_options")?;
    if let Ok(env) = std::env::var("PETSC_OPTIONS") {
        insert_options(&env, "PETSC_OPTIONS")?;
    }
    check(ffi::KSPSetFromOptions(ksp.0), "KSPSetFromOptions")?;
    if fixed {
        // the method again, whatever the options chose; MUMPS's own options (`-mat_mumps_…`)
        // are read when the factor is made, so they still apply
        set_mumps_ldlt(&ksp)?;
    }
    let mut pc: ffi::PC = ptr::null_mut();
    check(ffi::KSPGetPC(ksp.0, &mut pc), "KSPGetPC")?;

    let ksp_type = ksp_type(&ksp)?;
    let mut pc_type: ffi::PCType = ptr::null();
    check(ffi::PCGetType(pc, &mut pc_type), "PCGetType")?;
    let pc_type = type_name(pc_type);
    let mut solver_type = String::new();
    if pc_type == "cholesky" || pc_type == "lu" {
        let mut t: ffi::MatSolverType = ptr::null();
        check(
            ffi::PCFactorGetMatSolverType(pc, &mut t),
            "PCFactorGetMatSolverType",
        )?;
        solver_type = type_name(t);
    }
    let mumps = solver_type == "mumps";
    if mumps && !has_option(c"-mat_mumps_icntl_13")? {
        // the inertia counted over all ranks (the root front not split by ScaLAPACK)
        check(
            ffi::PetscOptionsSetValue(
                ptr::null_mut(),
                c"-mat_mumps_icntl_13".as_ptr(),
                c"1".as_ptr(),
            ),
            "PetscOptionsSetValue",
        )?;
    }
    let description = if solver_type.is_empty() {
        format!("KSP {ksp_type}, PC {pc_type}")
    } else {
        format!("KSP {ksp_type}, PC {pc_type} ({solver_type})")
    };
    Ok((ksp, description, mumps && pc_type == "cholesky"))
}

/// The type name of `ksp` (`gmres`, `preonly`, ...).
///
/// # Safety
/// PETSc is initialised, the caller holds the lock and `ksp` is live.
unsafe fn ksp_type(ksp: &Ksp) -> Result<String, LinearSolverError> {
    let mut t: ffi::KSPType = ptr::null();
    check(ffi::KSPGetType(ksp.0, &mut t), "KSPGetType")?;
    Ok(type_name(t))
}

/// A [`LinearSolver`] by PETSc: KSP and PC from the options (default MUMPS LDLᵀ), the matrix
/// distributed by rows over the ranks of `PETSC_COMM_WORLD`.
pub struct PetscSolver {
    options: String,
    /// Whether the method is MUMPS's LDLᵀ whatever the options say ([`PetscSolver::mumps_ldlt`]).
    fixed: bool,
    system: Option<System>,
    factored: bool,
    /// The layout of the current system's unknowns (near-null space, fields, shared entries).
    layout: Option<DofLayout>,
    stats: SolverStats,
    /// Whether an iterating KSP stops at Newton's forcing term when that is looser than its
    /// own tolerance.
    adaptive: bool,
    /// Newton's forcing term for the next solves.
    forcing: Option<f64>,
    /// Whether an iterating KSP keeps its preconditioner across matrices until it grows stale.
    keep: bool,
}

impl std::fmt::Debug for PetscSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PetscSolver")
            .field("options", &self.options)
            .field("factored", &self.factored)
            .field(
                "method",
                &self.system.as_ref().map(|s| s.description.as_str()),
            )
            .finish()
    }
}

impl PetscSolver {
    /// A solver with the scenario's PETSc options (inserted into PETSc's options database at
    /// the first factorisation).
    pub fn new(options: &str) -> Self {
        PetscSolver {
            options: options.to_string(),
            fixed: false,
            system: None,
            factored: false,
            layout: None,
            stats: SolverStats::default(),
            adaptive: false,
            forcing: None,
            keep: false,
        }
    }

    /// Lets an iterating KSP stop each solve at Newton's forcing term when that is looser than
    /// its own tolerance (`-ksp_rtol`), which then bounds it from below
    /// ([`LinearSolver::set_forcing`]); a direct solve (`preonly`) is unaffected.
    pub fn adaptive(mut self, adaptive: bool) -> Self {
        self.adaptive = adaptive;
        self
    }

    /// Lets an iterating KSP keep its preconditioner across matrices (Newton iterations, load
    /// and time steps) and set it up anew only when a solve needs twice the Krylov iterations
    /// per decade of the first solve after the last set-up, or fails (then solved once more with
    /// a fresh one). A factorisation that gives the inertia is always renewed.
    pub fn keep_preconditioner(mut self, keep: bool) -> Self {
        self.keep = keep;
        self
    }

    /// MUMPS's LDLᵀ (exact, with pivoting, for symmetric indefinite matrices), kept whatever
    /// `PETSC_OPTIONS` says of the KSP and PC: for systems that no iterative method tuned for
    /// the static steps would suit. MUMPS's own options (`-mat_mumps_icntl_…`) still apply.
    pub fn mumps_ldlt() -> Self {
        PetscSolver {
            fixed: true,
            ..PetscSolver::new("")
        }
    }

    /// The KSP and PC in use (known after the first factorisation).
    pub fn method(&self) -> Option<&str> {
        self.system.as_ref().map(|s| s.description.as_str())
    }

    /// The number of rigid-body modes attached as the near-null space (known after the first
    /// factorisation; 0 without a layout).
    pub fn near_null_space_size(&self) -> Option<usize> {
        self.system.as_ref().map(|s| s.modes)
    }

    /// The block size of the PETSc matrix (known after the first factorisation).
    pub fn matrix_block_size(&self) -> Option<usize> {
        self.system.as_ref().map(|s| s.numbering.block_size)
    }
}

impl LinearSolver for PetscSolver {
    fn factor(&mut self, a: &CsrMatrix) -> Result<Option<Inertia>, LinearSolverError> {
        self.factored = false;
        let same = matches!(&self.system, Some(s) if s.n == a.n && s.nnz == a.nnz());
        if !same {
            self.system = None;
            self.system = Some(System::new(
                a,
                &self.options,
                self.fixed,
                self.keep,
                self.layout.as_ref(),
            )?);
        }
        let system = self.system.as_mut().expect("set above");
        let before = system.renewal.setups;
        let inertia = system.factor(a);
        // a kept preconditioner is no factorisation
        self.stats.factorizations += system.renewal.setups - before;
        let inertia = inertia?;
        self.factored = true;
        Ok(inertia)
    }

    fn solve_in_place(&mut self, b: &mut [f64]) -> Result<(), LinearSolverError> {
        if !self.factored {
            return Err(LinearSolverError::NotFactored);
        }
        let system = self.system.as_mut().ok_or(LinearSolverError::NotFactored)?;
        let before = system.renewal.setups;
        let solved = system.solve(b, self.forcing.filter(|_| self.adaptive));
        self.stats.factorizations += system.renewal.setups - before;
        self.stats.krylov_iterations += system.iterations;
        solved?;
        self.stats.solves += 1;
        self.stats.krylov_decades += system.decades;
        Ok(())
    }

    fn stats(&self) -> SolverStats {
        self.stats
    }

    fn sums_shared_entries(&self) -> bool {
        true
    }

    /// Always: the layout names the current system's shared entries, and gives the rigid-body
    /// modes and the fields.
    fn needs_layout(&self, _n: usize) -> bool {
        true
    }

    /// A layout other than the held one makes the next factorisation set the system up anew.
    fn set_layout(&mut self, layout: DofLayout) {
        if self.layout.as_ref() != Some(&layout) {
            self.layout = Some(layout);
            self.system = None;
            self.factored = false;
        }
    }

    fn method(&self) -> Option<String> {
        PetscSolver::method(self).map(str::to_string)
    }

    fn name(&self) -> &'static str {
        "PETSc"
    }

    fn is_factored(&self) -> bool {
        self.factored
    }

    fn invalidate(&mut self) {
        self.factored = false;
    }

    fn set_forcing(&mut self, rtol: Option<f64>) {
        self.forcing = rtol;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn csr(n: usize, entries: &[(usize, usize, f64)]) -> CsrMatrix {
        let mut rows = vec![Vec::new(); n];
        for &(i, j, v) in entries {
            rows[i].push((j, v));
        }
        let n_rows = n;
        let (mut row_ptr, mut col_idx, mut values) = (vec![0usize], Vec::new(), Vec::<f64>::new());
        for mut r in rows {
            r.sort_by_key(|e| e.0);
            for (j, v) in r {
                col_idx.push(j);
                values.push(v);
            }
            row_ptr.push(col_idx.len());
        }
        CsrMatrix::from_usize(n_rows, row_ptr, col_idx, values)
    }

    #[test]
    fn block_size_four_only_for_whole_aligned_blocks() {
        let full: Vec<_> = (0..8)
            .flat_map(|i| (0..8).map(move |j| (i, j, 1.0)))
            .collect();
        assert_eq!(block_size(&csr(8, &full)), 4);
        let diag: Vec<_> = (0..8).map(|i| (i, i, 1.0)).collect();
        assert_eq!(block_size(&csr(8, &diag)), 1);
        let odd: Vec<_> = (0..6)
            .flat_map(|i| (0..6).map(move |j| (i, j, 1.0)))
            .collect();
        assert_eq!(block_size(&csr(6, &odd)), 1);
    }

    /// Node 0 with ux and Φ free, node 1 with nothing free, node 2 with uy, uz and Φ free.
    fn partly_held_layout() -> DofLayout {
        DofLayout {
            node: vec![0, 0, 2, 2, 2],
            field: vec![0, 3, 1, 2, 3],
            coords: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            axisymmetric: false,
            shared: false,
            owned: None,
            equations: None,
        }
    }

    /// A symmetric saddle system on the unknowns of [`partly_held_layout`]: positive on the
    /// displacements, negative on the potentials, coupled.
    fn saddle_on_partly_held_layout() -> CsrMatrix {
        let diagonal = [4.0, -3.0, 5.0, 6.0, -2.0];
        let mut entries: Vec<(usize, usize, f64)> = (0..5).map(|i| (i, i, diagonal[i])).collect();
        for (i, j, v) in [
            (0, 1, 1.0),
            (0, 2, 0.5),
            (1, 4, 0.7),
            (2, 3, -1.0),
            (3, 4, 0.3),
        ] {
            entries.push((i, j, v));
            entries.push((j, i, v));
        }
        csr(5, &entries)
    }

    #[test]
    fn a_layout_puts_every_node_in_a_block_of_four_rows() {
        let a = saddle_on_partly_held_layout();
        let layout = partly_held_layout();
        let numbering = Numbering::new(&a, Some(&layout), None, 1);
        assert_eq!(numbering.block_size, 4);
        // node 1 has no free unknown: two blocks
        assert_eq!(numbering.n, 8);
        assert_eq!(
            (0..5).map(|e| numbering.row(e)).collect::<Vec<_>>(),
            [0, 3, 5, 6, 7]
        );
        assert_eq!(
            (0..8).map(|r| numbering.unknown(r)).collect::<Vec<_>>(),
            [
                Some(0),
                None,
                None,
                Some(1),
                None,
                Some(2),
                Some(3),
                Some(4)
            ]
        );
        assert_eq!(numbering.unknowns_in(&(0..4)), 0..2);
        assert_eq!(numbering.unknowns_in(&(4..8)), 2..5);
        assert_eq!(numbering.padding_in(0..8).collect::<Vec<_>>(), [1, 2, 4]);
        // without a layout, or with one of other unknowns, the rows are the unknowns
        let plain = Numbering::new(&a, None, None, 1);
        assert_eq!((plain.n, plain.block_size, plain.row(3)), (5, 1, 3));
        let mut other = layout.clone();
        other.node.pop();
        other.field.pop();
        assert_eq!(Numbering::new(&a, Some(&other), None, 1).n, 5);
        assert_eq!(numbering.owned(0, 2), 0..4);
    }

    #[test]
    fn owners_take_their_nodes_rows_in_one_range() {
        let a = saddle_on_partly_held_layout();
        let layout = partly_held_layout();
        // node 0's unknowns are rank 1's, node 2's rank 0's
        let numbering = Numbering::new(&a, Some(&layout), Some(&[1, 1, 0, 0, 0]), 2);
        assert_eq!(numbering.block_size, 4);
        assert_eq!(
            (0..5).map(|e| numbering.row(e)).collect::<Vec<_>>(),
            [4, 7, 1, 2, 3]
        );
        assert_eq!(numbering.owned(0, 2), 0..4);
        assert_eq!(numbering.owned(1, 2), 4..8);
        assert_eq!(numbering.padding_in(0..8).collect::<Vec<_>>(), [0, 5, 6]);
        // an owner out of range: the unknowns' order and an even split
        let fallback = Numbering::new(&a, Some(&layout), Some(&[2, 1, 0, 0, 0]), 2);
        assert_eq!(fallback.row(0), 0);
        assert_eq!(fallback.owned(1, 2), 4..8);
    }

    #[test]
    fn padding_rows_change_neither_the_solution_nor_the_inertia() {
        let a = saddle_on_partly_held_layout();
        let b = [1.0, -2.0, 0.5, 3.0, -1.0];
        let mut plain = PetscSolver::new("");
        let plain_inertia = plain.factor(&a).unwrap();
        let mut x = b.to_vec();
        plain.solve_in_place(&mut x).unwrap();
        let mut blocked = PetscSolver::new("");
        blocked.set_layout(partly_held_layout());
        let inertia = blocked.factor(&a).unwrap();
        assert_eq!(blocked.matrix_block_size(), Some(4));
        assert_eq!(plain.matrix_block_size(), Some(1));
        assert_eq!(inertia, plain_inertia);
        assert_eq!(inertia.map(|i| i.negative), Some(2));
        let mut y = b.to_vec();
        blocked.solve_in_place(&mut y).unwrap();
        // the residual of the blocked solution
        let mut ay = vec![0.0; 5];
        a.mul_vec(&y, &mut ay);
        for e in 0..5 {
            assert!((ay[e] - b[e]).abs() < 1e-13, "{ay:?} against {b:?}");
            assert!((x[e] - y[e]).abs() < 1e-13, "{x:?} against {y:?}");
        }
    }

    #[test]
    fn rows_split_in_whole_blocks() {
        assert_eq!(owned_rows(10, 1, 0, 1), 0..10);
        assert_eq!(owned_rows(12, 4, 0, 2), 0..4);
        assert_eq!(owned_rows(12, 4, 1, 2), 4..12);
        assert_eq!(owned_rows(7, 1, 1, 2), 3..7);
    }

    #[test]
    fn a_kept_preconditioner_is_due_once_the_iterations_per_decade_double() {
        let mut r = Renewal {
            keeps: true,
            ..Renewal::default()
        };
        assert!(!r.keep_next(), "nothing to keep before the first set-up");
        r.record_set_up(false);
        assert!(r.fresh && r.setups == 1);
        r.record_solve(8, 8.0); // the baseline: 1 iteration per decade
        r.record_set_up(true);
        assert!(!r.fresh && r.setups == 1 && r.keep_next());
        r.record_solve(2, 1.0); // twice the baseline: still kept
        r.record_solve(16, 8.0);
        assert!(r.keep_next());
        r.record_solve(17, 8.0);
        assert!(!r.keep_next(), "more than twice the baseline");
        r.record_set_up(false);
        assert!(r.fresh && r.setups == 2 && r.baseline.is_none() && r.keep_next());
        // PETSc's default: a set-up at every matrix, however the iterations go
        let mut every = Renewal::default();
        every.record_set_up(false);
        every.record_solve(1, 8.0);
        every.record_solve(100, 8.0);
        assert!(!every.keep_next() && !every.due);
    }

    #[test]
    fn a_kept_preconditioner_that_fails_is_renewed_and_the_solve_retried() {
        // an exact LU under GMRES limited to one iteration: only the current matrix's own
        // factor solves within it
        let tridiagonal = |d: f64| {
            let mut e = Vec::new();
            for i in 0..6 {
                e.push((i, i, d + i as f64));
                if i > 0 {
                    e.push((i, i - 1, -1.0));
                    e.push((i - 1, i, -1.0));
                }
            }
            csr(6, &e)
        };
        let mut s = PetscSolver::new(
            "-ksp_type gmres -pc_type lu -pc_factor_mat_solver_type mumps -ksp_max_it 1 \
             -ksp_rtol 1e-12",
        )
        .keep_preconditioner(true);
        let residual = |a: &CsrMatrix, x: &[f64], b: &[f64]| {
            let mut ax = vec![0.0; b.len()];
            a.mul_vec(x, &mut ax);
            ax.iter()
                .zip(b)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f64::max)
        };
        let b = vec![1.0, 2.0, 0.0, -1.0, 3.0, 0.5];
        let first = tridiagonal(4.0);
        s.factor(&first).unwrap();
        let mut x = b.clone();
        s.solve_in_place(&mut x).unwrap();
        assert!(residual(&first, &x, &b) < 1e-12);
        assert_eq!(s.stats().factorizations, 1);
        // another matrix of the same pattern: its factorisation keeps the first factor ...
        let second = tridiagonal(9.0);
        s.factor(&second).unwrap();
        assert_eq!(s.stats().factorizations, 1, "the preconditioner was kept");
        // ... which cannot solve it in one iteration: renewed, and solved again
        let mut x = b.clone();
        s.solve_in_place(&mut x).unwrap();
        assert!(residual(&second, &x, &b) < 1e-12, "{x:?}");
        let stats = s.stats();
        assert_eq!(stats.factorizations, 2, "{stats:?}");
        assert_eq!(
            stats.krylov_iterations, 3,
            "one, then one failed and one: {stats:?}"
        );
        // renewed: a solve that fails with a fresh preconditioner is an error as before
        let mut never =
            PetscSolver::new("-ksp_type gmres -pc_type jacobi -ksp_max_it 1 -ksp_rtol 1e-12")
                .keep_preconditioner(true);
        never.factor(&second).unwrap();
        let mut x = b.clone();
        let err = never.solve_in_place(&mut x).unwrap_err().to_string();
        assert!(err.contains("DIVERGED_ITS"), "{err}");
        assert_eq!(never.stats().factorizations, 1);
    }

    #[test]
    fn solves_a_small_saddle_system_with_its_inertia() {
        // [[2, 1], [1, -1]]: one positive and one negative eigenvalue
        let a = csr(2, &[(0, 0, 2.0), (0, 1, 1.0), (1, 0, 1.0), (1, 1, -1.0)]);
        let mut s = PetscSolver::new("");
        let inertia = s.factor(&a).unwrap();
        assert_eq!(
            inertia,
            Some(Inertia {
                positive: 1,
                negative: 1,
                zero: 0
            })
        );
        let mut b = vec![3.0, 0.0];
        s.solve_in_place(&mut b).unwrap();
        assert!(
            (b[0] - 1.0).abs() < 1e-14 && (b[1] - 1.0).abs() < 1e-14,
            "{b:?}"
        );
    }
}
