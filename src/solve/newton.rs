//! Newton–Raphson with a backtracking line search on the residual norm.
//!
//! Works on any [`NonlinearSystem`]: the system owns its state and evaluates the scaled residual
//! and tangent over its free unknowns; Newton only sees vectors and a sparse matrix. A system
//! with a [`Border`] (one extra unknown μ and its equation g = 0) is solved by block elimination
//! with the same factorisation: K δxᵣ = −r, K z = −b, δμ = −(g + c·δxᵣ)/(c·z), δx = δxᵣ + δμ z.
//! Its line search takes the longest admissible step, and divergence is judged against the first
//! residual with g in residual units, ‖b‖·|g|/|c·z| (the residual that the change of μ removing
//! g would cause).

use super::linear::{Inertia, LinearSolver, LinearSolverError};
use crate::algebra::csr::CsrMatrix;

pub use crate::algebra::system::{Border, NonlinearSystem};

/// Newton settings.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NewtonSettings {
    /// Largest number of iterations.
    pub max_iterations: usize,
    /// Converged when ‖r‖ ≤ rtol·‖r₀‖ (or below the system's floor).
    pub rtol: f64,
    /// Largest number of halvings of the step in the line search.
    pub max_backtracks: usize,
    /// Factor the tangent at the converged state and check its inertia.
    pub check_stability: bool,
    /// Print a convergence table per iteration on stderr.
    pub verbose: bool,
    /// Modified Newton: keep the solver's factorisation (from an earlier iteration or step) and
    /// refactor only when an iteration reduces the residual by less than 10× (above round-off).
    pub reuse_factorization: bool,
    /// Let an iterative solver stop each solve at Newton's forcing term ([`forcing_term`]);
    /// false: every solve to the solver's own tolerance (a load step retried after a failure,
    /// where a loose first solve can leave Newton creeping next to a limit point).
    pub inexact: bool,
    /// With a new tangent at every iteration (`reuse_factorization` false): evaluate it at the
    /// start of the iteration that needs it rather than with the residual after each step, so
    /// that the converged iterate's tangent is never assembled and the line search's residual
    /// is not evaluated twice.
    pub lazy_tangent: bool,
    /// With a new tangent at every iteration and inexact solves, no border: once the residual
    /// is below [`LAG_BAND`] of the first, iterate on the tangent already assembled at the
    /// previous iterate instead of assembling one (a chord step, which near the root contracts
    /// about as much as the Newton step before it did), and assemble again after a chord step
    /// that reduced the residual less than [`LAG_CONTRACTION`]. Tangents are evaluated lazily
    /// (as with `lazy_tangent`); the stability test still factors the converged state's own.
    pub lag_tangent: bool,
    /// With a new tangent at every iteration and inexact solves, no border, and a solver that
    /// holds a factorisation of an earlier tangent: its Krylov solves take the tangent's
    /// products with vectors as differences of residuals
    /// ([`NonlinearSystem::difference_step`], Jacobian-free Newton–Krylov: Knoll & Keyes, J.
    /// Comput. Phys. 193 (2004) 357–397, §2.2) instead of the assembled tangent's, which is then
    /// assembled only when the solver renews its factor, and for the stability test (a
    /// residual costs about an eighth of a tangent on the film's hex8 cells). No chord steps
    /// ([`NewtonSettings::lag_tangent`]): every iteration's step is Newton's, to its forcing
    /// term.
    #[serde(default = "yes")]
    pub tangent_products: bool,
}

/// The default of a setting that older checkpoints do not hold.
fn yes() -> bool {
    true
}

/// The residual, relative to the first, below which [`NewtonSettings::lag_tangent`] keeps the
/// previous iterate's tangent. On the film 40 × 40 × 8 this is the last iteration of most load
/// steps (docs/validation.md).
pub const LAG_BAND: f64 = 1e-4;

/// The least reduction of a chord step on a kept tangent after which the next iteration may
/// keep it again.
pub const LAG_CONTRACTION: f64 = 1e-2;

/// Residuals up to this multiple of the system's floor count as converged once they stagnate.
/// The floor is estimated in the reference configuration; a nearly incompressible wall stretched
/// 2.5 times (an inflated balloon) carries round-off in its forces about 130 times that estimate.
const ROUNDOFF_BAND: f64 = 1000.0;

/// A residual within this multiple of the system's floor is mostly round-off: how little an
/// iteration reduced it says nothing of the factor's age, so modified Newton does not refactor.
/// (A resting dynamic step's residual hovers at 1.3–2 times the floor.)
const REFACTOR_BAND: f64 = 10.0;

impl Default for NewtonSettings {
    fn default() -> Self {
        NewtonSettings {
            max_iterations: 25,
            rtol: 1e-10,
            max_backtracks: 6,
            check_stability: true,
            // a table of every iteration on stderr (for diagnosing a failing solve)
            verbose: std::env::var_os("DEASIM_NEWTON_VERBOSE").is_some(),
            reuse_factorization: false,
            inexact: true,
            lazy_tangent: false,
            lag_tangent: true,
            tangent_products: true,
        }
    }
}

/// A converged solve.
#[derive(Debug, Clone)]
pub struct NewtonReport {
    pub iterations: usize,
    /// Residual norms, first to last.
    pub residuals: Vec<f64>,
    /// Inertia of the tangent at the converged state (when checked); `None` also when the
    /// linear solver cannot tell it: the stability was then not checked.
    pub inertia: Option<Inertia>,
    /// False when the converged state has more negative pivots than potential unknowns (true
    /// when the stability was not checked).
    pub stable: bool,
}

/// Why Newton stopped without convergence.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NewtonError {
    #[error("Newton did not converge in {iterations} iterations (residual {residual:.3e}, first {first:.3e}){}", blocked.as_ref().map(|b| format!("; full steps were blocked: {b}")).unwrap_or_default())]
    MaxIterations {
        iterations: usize,
        residual: f64,
        first: f64,
        /// Why the last full Newton step that could not be evaluated failed (e.g. a material
        /// outside its domain): the iteration was held back by it.
        blocked: Option<String>,
    },
    #[error("Newton diverged at iteration {iteration} (residual {residual:.3e})")]
    Diverged { iteration: usize, residual: f64 },
    #[error("singular tangent at iteration {iteration}")]
    Singular { iteration: usize },
    #[error("evaluation failed at iteration {iteration}: {message}")]
    Evaluation { iteration: usize, message: String },
    /// The linear solver failed other than by a singular matrix (an iterative solve that did not
    /// converge, a solver library's error, a solver that cannot take the system).
    #[error("the linear solver failed at iteration {iteration}: {message}")]
    LinearSolve { iteration: usize, message: String },
}

/// The norm of a vector of `system`'s unknowns: over every process's part of them
/// ([`NonlinearSystem::sum_over_processes`]); the plain norm when they are all here.
fn system_norm<S: NonlinearSystem + ?Sized>(
    system: &S,
    v: &[f64],
    iteration: usize,
) -> Result<f64, NewtonError> {
    let mut s = [v.iter().map(|x| x * x).sum::<f64>()];
    reduce(system, &mut s, iteration)?;
    Ok(s[0].sqrt())
}

/// [`NonlinearSystem::sum_over_processes`], its failure a Newton error at `iteration`.
fn reduce<S: NonlinearSystem + ?Sized>(
    system: &S,
    values: &mut [f64],
    iteration: usize,
) -> Result<(), NewtonError> {
    system
        .sum_over_processes(values)
        .map_err(|message| NewtonError::Evaluation { iteration, message })
}

/// [`NonlinearSystem::border`], its failure a Newton error at `iteration`.
fn system_border<S: NonlinearSystem + ?Sized>(
    system: &S,
    iteration: usize,
) -> Result<Option<Border>, NewtonError> {
    system
        .border()
        .map_err(|message| NewtonError::Evaluation { iteration, message })
}

fn group_norms<S: NonlinearSystem + ?Sized>(
    system: &S,
    v: &[f64],
    groups: &[u8],
) -> Result<[f64; 2], NewtonError> {
    let mut s = [0.0; 2];
    for (x, &g) in v.iter().zip(groups) {
        s[g as usize] += x * x;
    }
    reduce(system, &mut s, 0)?;
    Ok([s[0].sqrt(), s[1].sqrt()])
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// K⁻¹v with the solver's factorisation (the bordered step's second solve).
fn solve_copy(
    solver: &mut dyn LinearSolver,
    mut v: Vec<f64>,
    iteration: usize,
) -> Result<Vec<f64>, NewtonError> {
    solver
        .solve_in_place(&mut v)
        .map_err(|e| NewtonError::LinearSolve {
            iteration,
            message: e.to_string(),
        })?;
    Ok(v)
}

/// Readies `solver` for the tangents of `system`: gives it the layout of the unknowns when it
/// wants one (which also names a shared assembly's entries), and refuses a system that
/// assembles only this process's share of the cells with a solver that would take that share
/// for the whole tangent. Call it before the first factorisation of a system's tangent.
pub fn prepare_solver<S: NonlinearSystem + ?Sized>(
    system: &S,
    solver: &mut dyn LinearSolver,
) -> Result<(), String> {
    if system.shares_cells() && !solver.sums_shared_entries() {
        return Err(format!(
            "this process assembles only its share of the cells, but the {} solver takes the \
             matrix as the whole tangent",
            solver.name()
        ));
    }
    if solver.needs_layout(system.n()) {
        if let Some(layout) = system.layout() {
            solver.set_layout(layout);
        }
    }
    Ok(())
}

/// Largest forcing term: the first iteration of a step solves to a tenth of its residual.
const FORCING_MAX: f64 = 0.1;
/// The last solve of a Newton solve aims at this fraction of its tolerance, so that converged
/// states sit inside the tolerance rather than at its edge. Kelley's half, this tenth and a
/// hundredth left the axisymmetric diaphragm's 1 s history 3.05e-8, 2.70e-8 and 2.58e-8 of a
/// column's scale from the direct solver's (in its kinetic energy): the margin costs little.
const FORCING_MARGIN: f64 = 0.1;
/// γ of Eisenstat and Walker's second choice.
const FORCING_GAMMA: f64 = 0.9;

/// The relative residual the linear solve of a Newton iteration needs (its forcing term):
/// Eisenstat and Walker's second choice η = γ (‖rₖ‖/‖rₖ₋₁‖)², kept from falling faster than
/// γ ηₖ₋₁² while that is above 0.1 (SIAM J. Sci. Comput. 17 (1996) 16–32), at most
/// [`FORCING_MAX`], and no tighter than the Newton tolerance `tol` needs: [`FORCING_MARGIN`]
/// times `tol` over the current residual (the safeguard of Kelley, Iterative Methods for Linear
/// and Nonlinear Equations, SIAM 1995, §6.3, with a tenth for his half). Solvers that solve
/// exactly ignore it.
pub fn forcing_term(rn: f64, previous: Option<(f64, f64)>, tol: f64) -> f64 {
    let eta = match previous {
        None => FORCING_MAX,
        Some((r_prev, eta_prev)) => {
            let eta = FORCING_GAMMA * (rn / r_prev).powi(2);
            let safeguard = FORCING_GAMMA * eta_prev * eta_prev;
            if safeguard > 0.1 {
                eta.max(safeguard)
            } else {
                eta
            }
        }
    };
    let needed = if rn > 0.0 {
        FORCING_MARGIN * tol / rn
    } else {
        0.0
    };
    eta.max(needed).min(FORCING_MAX)
}

/// y = (R(x + hv) − R(x))/h with h = `step`/‖v‖∞ (no unknown moves by more than `step`): the
/// tangent's product with `v` (forward difference: off by about the step's strain), from the
/// residual `r` at the state `base`, to which the system returns. False when the residual
/// cannot be evaluated there.
fn difference_product<S: NonlinearSystem + ?Sized>(
    system: &mut S,
    base: &[f64],
    r: &[f64],
    step: f64,
    v: &[f64],
    y: &mut [f64],
) -> bool {
    let largest = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if largest == 0.0 || !largest.is_finite() {
        y.fill(0.0);
        return largest == 0.0;
    }
    let h = step / largest;
    system.increment(v, h);
    let evaluated = system.evaluate(y, None).is_ok();
    system.restore(base);
    if !evaluated {
        return false;
    }
    y.iter_mut()
        .zip(r)
        .for_each(|(yi, ri)| *yi = (*yi - ri) / h);
    y.iter().all(|v| v.is_finite())
}

/// Solves the system from its current state. On failure the state is left where Newton stopped;
/// callers restore a snapshot. The linear solves follow [`forcing_term`]; the solver's forcing
/// is cleared on return, so later solves outside Newton are to its own tolerance.
pub fn newton<S: NonlinearSystem + ?Sized>(
    system: &mut S,
    solver: &mut dyn LinearSolver,
    k: &mut CsrMatrix,
    settings: &NewtonSettings,
) -> Result<NewtonReport, NewtonError> {
    let out = newton_forced(system, solver, k, settings);
    solver.set_forcing(None);
    out
}

fn newton_forced<S: NonlinearSystem + ?Sized>(
    system: &mut S,
    solver: &mut dyn LinearSolver,
    k: &mut CsrMatrix,
    settings: &NewtonSettings,
) -> Result<NewtonReport, NewtonError> {
    let n = system.n();
    let mut r = vec![0.0; n];
    let mut dx = vec![0.0; n];
    let mut trial = vec![0.0; n];
    let groups = if settings.verbose {
        system.groups()
    } else {
        Vec::new()
    };
    prepare_solver(system, solver).map_err(|message| NewtonError::LinearSolve {
        iteration: 0,
        message,
    })?;
    let floor = system.residual_floor();
    let reuse = settings.reuse_factorization;
    // the step from the tangent's products, where the system gives them and the solver takes
    // them (asked at each iteration)
    let products = match system.difference_step() {
        Some(h) if settings.tangent_products && settings.inexact && !reuse => {
            (!system.shares_cells() && solver.accepts_products(n)).then_some(h)
        }
        _ => None,
    };
    let lag = settings.lag_tangent && settings.inexact && !reuse && products.is_none();
    let lazy = (settings.lazy_tangent || lag || products.is_some()) && !reuse;
    // k_fresh: `k` holds the tangent at the current iterate
    // the last iteration assembled its tangent (at the iterate before the current one)
    let mut assembled_last = false;
    let mut k_fresh = !(lazy || (reuse && solver.is_factored()));
    system
        .evaluate(&mut r, if k_fresh { Some(&mut *k) } else { None })
        .map_err(|message| NewtonError::Evaluation {
            iteration: 0,
            message,
        })?;
    let r0 = system_norm(system, &r, 0)?;
    if !r0.is_finite() {
        return Err(NewtonError::Diverged {
            iteration: 0,
            residual: r0,
        });
    }
    let tol = (settings.rtol * r0).max(floor);
    let mut residuals = vec![r0];
    // the last full step that could not be evaluated, for the report of a failure
    let mut blocked: Option<String> = None;
    let mut rn = r0;
    if settings.verbose {
        log::info!("    tolerance {tol:.3e} (floor {floor:.3e})");
        log::info!(
            "    it   |r|         |r|/|r0|    |r_u|       |r_phi|     |dx_u|      |dx_phi|  alpha"
        );
        let g = group_norms(system, &r, &groups)?;
        log::info!(
            "    {:>2}   {:.3e}   {:.3e}   {:.3e}   {:.3e}",
            0,
            r0,
            1.0,
            g[0],
            g[1]
        );
    }
    let mut iteration = 0;
    let mut refactor = !reuse || !solver.is_factored();
    let mut border = system_border(system, 0)?;
    let mut reference = r0.max(floor);
    let border_open = |b: &Option<Border>| b.as_ref().is_some_and(|b| b.g().abs() > b.tol());
    // the last iteration's residual and forcing term
    let mut forced: Option<(f64, f64)> = None;
    while rn > tol || border_open(&border) {
        // round-off plateau: within ROUNDOFF_BAND of the floor and no longer halving over two
        // iterations; the floor's round-off estimate is a few times off on distorted meshes
        let n_res = residuals.len();
        if n_res >= 3
            && rn <= ROUNDOFF_BAND * floor
            && rn > 0.5 * residuals[n_res - 3]
            && !border_open(&border)
        {
            break;
        }
        if iteration >= settings.max_iterations {
            return Err(NewtonError::MaxIterations {
                iterations: iteration,
                residual: rn,
                first: r0,
                blocked: blocked.take(),
            });
        }
        iteration += 1;
        // a chord step on the tangent of an earlier iterate: after one that assembled it, or
        // after a chord step that still contracted well
        let n_res = residuals.len();
        let chord = lag
            && border.is_none()
            && rn <= LAG_BAND * r0
            && (assembled_last
                || (n_res >= 2 && residuals[n_res - 1] <= LAG_CONTRACTION * residuals[n_res - 2]));
        let eta = forcing_term(rn, forced, tol);
        let by_products = match products {
            Some(h) if border.is_none() => {
                dx.iter_mut().zip(&r).for_each(|(d, v)| *d = -v);
                solver.set_forcing(Some(eta));
                let base = system.snapshot();
                solver
                    .solve_with_products(
                        &mut |v, y| difference_product(system, &base, &r, h, v, y),
                        &mut dx,
                    )
                    .map_err(|e| NewtonError::LinearSolve {
                        iteration,
                        message: e.to_string(),
                    })?
            }
            _ => false,
        };
        // (a chord step's solver still holds the operator of the tangent it keeps)
        let assemble = !by_products && !chord && (refactor || !solver.is_factored());
        if assemble {
            if !k_fresh {
                system
                    .evaluate(&mut r, Some(&mut *k))
                    .map_err(|message| NewtonError::Evaluation { iteration, message })?;
            }
            let before = solver.stats().factorizations;
            solver.set_operator(k).map_err(|e| match e {
                LinearSolverError::Singular(_) => NewtonError::Singular { iteration },
                other => NewtonError::LinearSolve {
                    iteration,
                    message: other.to_string(),
                },
            })?;
            if !solver.reports_factor_points() || solver.stats().factorizations > before {
                system.factored();
            }
        }
        assembled_last = assemble;
        if !assemble && lag && settings.verbose {
            log::info!("    (the tangent of an earlier iterate)");
        }
        if !by_products {
            let factors_before = solver.stats().factorizations;
            dx.iter_mut().zip(&r).for_each(|(d, v)| *d = -v);
            // a bordered step combines two solves into the step: both exact to the solver's own
            // tolerance
            solver.set_forcing((settings.inexact && border.is_none()).then_some(eta));
            solver
                .solve_in_place(&mut dx)
                .map_err(|e| NewtonError::LinearSolve {
                    iteration,
                    message: e.to_string(),
                })?;
            if solver.reports_factor_points() && solver.stats().factorizations > factors_before {
                // the solve renewed the factor at this iterate's tangent
                system.factored();
            }
        }
        forced = Some((rn, eta));
        // every process's part of the step, so that all take the same path
        let mut not_finite = [dx.iter().filter(|v| !v.is_finite()).count() as f64];
        reduce(system, &mut not_finite, iteration)?;
        if not_finite[0] > 0.0 {
            return Err(NewtonError::Singular { iteration });
        }
        // the bordering unknown: its step, and the weight of g in the merit
        let (mut dmu, mut weight) = (0.0, 0.0);
        if let Some(bd) = &border {
            let minus_b: Vec<f64> = bd.b.iter().map(|v| -v).collect();
            let z = solve_copy(solver, minus_b, iteration)?;
            // over every process's part of the unknowns
            let mut sums = [
                dot(&bd.c, &z),
                dot(&bd.c, &dx),
                bd.b.iter().map(|x| x * x).sum::<f64>(),
            ];
            reduce(system, &mut sums, iteration)?;
            let [cz, cx, bb] = sums;
            if cz == 0.0 || !cz.is_finite() {
                return Err(NewtonError::Singular { iteration });
            }
            dmu = -(bd.g() + cx) / cz;
            dx.iter_mut().zip(&z).for_each(|(d, zi)| *d += dmu * zi);
            weight = bb.sqrt() / cz.abs();
            if settings.verbose {
                log::info!(
                    "    border: g {:.3e}, dmu {dmu:.3e}, weight {weight:.3e}, |b| {:.3e}",
                    bd.g(),
                    bb.sqrt()
                );
            }
        }
        let m0 = match &border {
            Some(b) => (rn * rn + (weight * b.g()).powi(2)).sqrt(),
            None => rn,
        };
        // the scale divergence is judged against: the first merit
        if iteration == 1 {
            reference = reference.max(m0);
        }
        // Backtracking: accept the first step that lowers the residual norm; if none does, take the
        // full step when it can be evaluated (plain Newton), else fail.
        let start = system.snapshot();
        let mut alpha = 1.0;
        let mut accepted = false;
        let mut full_step_ok = false;
        // why the full step could not be evaluated (e.g. an inverted element)
        let mut full_step_error: Option<String> = None;
        for _ in 0..=settings.max_backtracks {
            system.increment(&dx, alpha);
            system.increment_border(alpha * dmu);
            let evaluated = system.evaluate(&mut trial, None);
            if let (Err(m), true) = (&evaluated, alpha == 1.0) {
                full_step_error = Some(m.clone());
                blocked = Some(m.clone());
            }
            if evaluated.is_ok() {
                let tn = system_norm(system, &trial, iteration)?;
                if alpha == 1.0 && tn.is_finite() {
                    full_step_ok = true;
                }
                // a bordered system takes the longest admissible step: its merit mixes a
                // constraint with forces, and a nearly incompressible body's forces grow far
                // beyond the weighted constraint over a step that is still converging
                let descent = border.is_some() || tn <= (1.0 - 1e-4 * alpha) * m0;
                if tn.is_finite() && descent {
                    accepted = true;
                    break;
                }
            }
            system.restore(&start);
            alpha *= 0.5;
        }
        if !accepted {
            if !full_step_ok {
                return Err(NewtonError::Evaluation {
                    iteration,
                    message: match full_step_error {
                        Some(m) => format!(
                            "no step along the Newton direction gives an admissible state (full step: {m})"
                        ),
                        None => "no step along the Newton direction gives an admissible state"
                            .into(),
                    },
                });
            }
            alpha = 1.0;
            system.increment(&dx, alpha);
            system.increment_border(dmu);
        }
        if (reuse || lazy) && accepted {
            // the line search already evaluated the residual here
            r.copy_from_slice(&trial);
            k_fresh = false;
        } else if lazy {
            system
                .evaluate(&mut r, None)
                .map_err(|message| NewtonError::Evaluation { iteration, message })?;
            k_fresh = false;
        } else {
            system
                .evaluate(&mut r, if reuse { None } else { Some(&mut *k) })
                .map_err(|message| NewtonError::Evaluation { iteration, message })?;
            k_fresh = !reuse;
        }
        let previous = rn;
        rn = system_norm(system, &r, iteration)?;
        border = system_border(system, iteration)?;
        // a contraction under 10× means a stale factor, unless round-off limits it
        refactor = !reuse || (rn > 0.1 * previous && rn > REFACTOR_BAND * floor);
        residuals.push(rn);
        if settings.verbose {
            let g = group_norms(system, &r, &groups)?;
            let d = group_norms(system, &dx, &groups)?;
            log::info!(
                "    {:>2}   {:.3e}   {:.3e}   {:.3e}   {:.3e}   {:.3e}   {:.3e}  {}",
                iteration,
                rn,
                rn / r0.max(f64::MIN_POSITIVE),
                g[0],
                g[1],
                alpha * d[0],
                alpha * d[1],
                alpha
            );
        }
        if !rn.is_finite() || rn > 1e8 * reference {
            return Err(NewtonError::Diverged {
                iteration,
                residual: rn,
            });
        }
    }
    let mut inertia = None;
    let mut stable = true;
    if settings.check_stability && n > 0 {
        if !k_fresh {
            system
                .evaluate(&mut r, Some(&mut *k))
                .map_err(|message| NewtonError::Evaluation { iteration, message })?;
        }
        match solver.factor(k) {
            Ok(Some(i)) => {
                system.factored();
                // with a border, stability is that of K on the constrained directions c·δx = 0:
                // one negative pivot fewer when cᵀK⁻¹c < 0 (Haynsworth's inertia additivity
                // for the bordered matrix)
                let mut negative = i.negative;
                if let Some(bd) = system_border(system, iteration)? {
                    let z = solve_copy(solver, bd.c.clone(), iteration)?;
                    let mut q = [dot(&bd.c, &z)];
                    reduce(system, &mut q, iteration)?;
                    if q[0] < 0.0 {
                        negative = negative.saturating_sub(1);
                    }
                }
                stable = negative <= system.expected_negative_pivots();
                inertia = Some(i);
            }
            Ok(None) => {
                system.factored();
                if settings.verbose {
                    log::info!("    stability not checked: the linear solver gives no inertia");
                }
            }
            Err(LinearSolverError::Singular(_)) => stable = false,
            Err(e) => {
                return Err(NewtonError::LinearSolve {
                    iteration,
                    message: e.to_string(),
                })
            }
        }
    }
    Ok(NewtonReport {
        iterations: iteration,
        residuals,
        inertia,
        stable,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::linear::FaerLdlt;

    /// The parts of a test system with one unknown that do not depend on its equation: its
    /// size, its 1 × 1 matrix, no negative pivot, a floor of 10⁻¹⁴ and one group.
    macro_rules! one_unknown {
        () => {
            fn n(&self) -> usize {
                1
            }
            fn new_matrix(&self) -> CsrMatrix {
                CsrMatrix::new(1, vec![0, 1], vec![0], vec![0.0])
            }
            fn expected_negative_pivots(&self) -> usize {
                0
            }
            fn residual_floor(&self) -> f64 {
                1e-14
            }
            fn groups(&self) -> Vec<u8> {
                vec![0]
            }
        };
    }

    /// A state that is the one field `$f`: its increment, snapshot and restore.
    macro_rules! one_coordinate {
        ($f:tt) => {
            fn increment(&mut self, dx: &[f64], alpha: f64) {
                self.$f += alpha * dx[0];
            }
            fn snapshot(&self) -> Vec<f64> {
                vec![self.$f]
            }
            fn restore(&mut self, s: &[f64]) {
                self.$f = s[0];
            }
        };
    }

    /// r(x) = x³ + x − 2 = 0 (root x = 1), one unknown.
    struct Cubic(f64);

    impl NonlinearSystem for Cubic {
        one_unknown!();
        fn evaluate(&mut self, r: &mut [f64], k: Option<&mut CsrMatrix>) -> Result<(), String> {
            r[0] = self.0.powi(3) + self.0 - 2.0;
            if let Some(k) = k {
                k.values[0] = 3.0 * self.0 * self.0 + 1.0;
            }
            Ok(())
        }
        one_coordinate!(0);
    }

    /// A double well E = x⁴/4 − x²/2 pulled by a force μ, with x held at `target` by the border
    /// g = x − target: r = x³ − x − μ.
    struct HeldWell {
        x: f64,
        mu: f64,
        target: f64,
    }

    impl NonlinearSystem for HeldWell {
        one_unknown!();
        fn evaluate(&mut self, r: &mut [f64], k: Option<&mut CsrMatrix>) -> Result<(), String> {
            r[0] = self.x.powi(3) - self.x - self.mu;
            if let Some(k) = k {
                k.values[0] = 3.0 * self.x * self.x - 1.0;
            }
            Ok(())
        }
        fn increment(&mut self, dx: &[f64], alpha: f64) {
            self.x += alpha * dx[0];
        }
        fn snapshot(&self) -> Vec<f64> {
            vec![self.x, self.mu]
        }
        fn restore(&mut self, s: &[f64]) {
            self.x = s[0];
            self.mu = s[1];
        }
        fn border(&self) -> Result<Option<Border>, String> {
            Ok(Some(Border {
                b: vec![-1.0],
                c: vec![1.0],
                measure: self.x,
                start: self.target,
                end: self.target,
                load: 1.0,
                rtol: 1e-14 / self.target.abs(),
            }))
        }
        fn increment_border(&mut self, delta: f64) {
            self.mu += delta;
        }
    }

    /// The border holds x where the well's tangent is negative: Newton finds the force that
    /// holds it there (μ = x³ − x), and the state counts as stable, since the constraint leaves
    /// no free direction, although K itself has a negative pivot.
    #[test]
    fn a_bordered_system_solves_for_its_extra_unknown_and_is_stable_under_its_constraint() {
        let settings = NewtonSettings::default();
        let mut sys = HeldWell {
            x: 1.2,
            mu: 0.0,
            target: 0.5,
        };
        let mut k = sys.new_matrix();
        let rep = newton(&mut sys, &mut FaerLdlt::new(), &mut k, &settings).unwrap();
        assert!((sys.x - 0.5).abs() < 1e-14, "{}", sys.x);
        assert!((sys.mu - (0.125 - 0.5)).abs() < 1e-13, "{}", sys.mu);
        assert_eq!(rep.inertia.map(|i| i.negative), Some(1));
        assert!(rep.stable);
    }

    /// A solver that solves exactly but cannot tell the inertia (as a Krylov solver).
    struct NoInertia(FaerLdlt);

    impl LinearSolver for NoInertia {
        fn factor(&mut self, a: &CsrMatrix) -> Result<Option<Inertia>, LinearSolverError> {
            self.0.factor(a).map(|_| None)
        }
        fn solve_in_place(&mut self, b: &mut [f64]) -> Result<(), LinearSolverError> {
            self.0.solve_in_place(b)
        }
        fn name(&self) -> &'static str {
            "no inertia"
        }
    }

    /// Eisenstat and Walker's second choice with its safeguards: the first iteration's bound,
    /// the square of the residual ratio, the floor from the previous term while it is large,
    /// and no tighter than the Newton tolerance needs.
    #[test]
    fn the_forcing_term_follows_eisenstat_walker_with_its_safeguards() {
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-15 * b.abs();
        assert!(close(forcing_term(1.0, None, 1e-12), FORCING_MAX));
        // residual down 10×, previous term small: γ·0.01
        assert!(close(forcing_term(0.1, Some((1.0, 0.01)), 1e-12), 0.009));
        // previous term 0.5: γ·0.25 > 0.1 holds the term up, then the bound caps it
        assert!(close(
            forcing_term(0.1, Some((1.0, 0.5)), 1e-12),
            FORCING_MAX
        ));
        // previous term 0.35: γ·0.1225 = 0.11 > 0.1, capped at the bound
        assert!(close(
            forcing_term(0.01, Some((1.0, 0.35)), 1e-12),
            FORCING_MAX
        ));
        // previous term 0.3: γ·0.09 = 0.081 ≤ 0.1, no floor
        assert!(close(forcing_term(0.01, Some((1.0, 0.3)), 1e-12), 0.9e-4));
        // near the tolerance: no tighter than the margin times tol over the residual
        let eta = forcing_term(1e-9, Some((1e-5, 1e-3)), 1e-10);
        assert!(close(eta, FORCING_MARGIN * 1e-10 / 1e-9), "{eta:e}");
    }

    /// A solver that solves with the relative error Newton allows it: the solution scaled by
    /// 1 + η (a one-unknown system has no other error), recording each forcing term.
    struct Inexact {
        exact: FaerLdlt,
        eta: Option<f64>,
        seen: Vec<Option<f64>>,
    }

    impl LinearSolver for Inexact {
        fn factor(&mut self, a: &CsrMatrix) -> Result<Option<Inertia>, LinearSolverError> {
            self.exact.factor(a)
        }
        fn solve_in_place(&mut self, b: &mut [f64]) -> Result<(), LinearSolverError> {
            self.exact.solve_in_place(b)?;
            b.iter_mut()
                .for_each(|v| *v *= 1.0 + self.eta.unwrap_or(0.0));
            Ok(())
        }
        fn name(&self) -> &'static str {
            "inexact"
        }
        fn set_forcing(&mut self, rtol: Option<f64>) {
            self.eta = rtol;
            self.seen.push(rtol);
        }
    }

    /// Newton hands the solver a forcing term per iteration, loose first and tighter as it
    /// converges, still reaches its tolerance with solves only that accurate, and clears the
    /// term on return.
    #[test]
    fn newton_converges_with_solves_to_its_forcing_terms() {
        let settings = NewtonSettings::default();
        let mut sys = Cubic(3.0);
        let mut k = sys.new_matrix();
        let mut solver = Inexact {
            exact: FaerLdlt::new(),
            eta: None,
            seen: Vec::new(),
        };
        let rep = newton(&mut sys, &mut solver, &mut k, &settings).unwrap();
        assert!((sys.0 - 1.0).abs() < 1e-9, "{}", sys.0);
        let last = *rep.residuals.last().unwrap();
        assert!(
            last <= settings.rtol * rep.residuals[0],
            "{:?}",
            rep.residuals
        );
        let terms: Vec<f64> = solver.seen.iter().flatten().copied().collect();
        assert_eq!(terms.len(), rep.iterations, "{:?}", solver.seen);
        assert_eq!(terms[0], FORCING_MAX);
        assert!(terms.last().unwrap() < &terms[0], "{terms:?}");
        assert_eq!(solver.seen.last(), Some(&None));
        assert_eq!(solver.eta, None);
    }

    /// A linear residual x − 1 whose evaluations carry a round-off that Newton cannot remove:
    /// ±`noise`·0.9ᵏ at the k-th evaluation, so that each iteration reduces the residual by
    /// only 0.9 (and passes the line search); the floor is 10⁻¹⁴.
    struct Plateau {
        x: f64,
        noise: f64,
        evaluations: usize,
    }

    impl NonlinearSystem for Plateau {
        one_unknown!();
        fn evaluate(&mut self, r: &mut [f64], k: Option<&mut CsrMatrix>) -> Result<(), String> {
            self.evaluations += 1;
            let sign = if self.evaluations.is_multiple_of(2) {
                1.0
            } else {
                -1.0
            };
            r[0] = self.x - 1.0 + sign * self.noise * 0.9f64.powi(self.evaluations as i32);
            if let Some(k) = k {
                k.values[0] = 1.0;
            }
            Ok(())
        }
        one_coordinate!(x);
    }

    /// Modified Newton refactors when an iteration reduces the residual by less than 10×, but
    /// not when round-off limits the reduction: a residual hovering at twice the floor keeps
    /// the factor, one at 50 times the floor (above round-off) refactors.
    #[test]
    fn modified_newton_does_not_refactor_for_a_contraction_that_round_off_limits() {
        let settings = NewtonSettings {
            reuse_factorization: true,
            check_stability: false,
            rtol: 1e-16,
            ..NewtonSettings::default()
        };
        let factorizations = |noise: f64| {
            let mut sys = Plateau {
                x: 0.0,
                noise,
                evaluations: 0,
            };
            let mut k = sys.new_matrix();
            let mut solver = FaerLdlt::new();
            let rep = newton(&mut sys, &mut solver, &mut k, &settings).unwrap();
            assert!((sys.x - 1.0).abs() <= 4.0 * noise, "{}", sys.x);
            assert!(rep.iterations >= 3, "{:?}", rep.residuals);
            solver.stats().factorizations
        };
        assert_eq!(factorizations(1e-14), 1);
        assert!(factorizations(3e-13) > 1);
    }

    /// With a solver that gives the inertia the stability is checked; without, Newton converges
    /// to the same root and reports the stability as not checked (no inertia, not unstable).
    #[test]
    fn inertia_is_optional() {
        let settings = NewtonSettings::default();
        let mut sys = Cubic(3.0);
        let mut k = sys.new_matrix();
        let rep = newton(&mut sys, &mut FaerLdlt::new(), &mut k, &settings).unwrap();
        assert!((sys.0 - 1.0).abs() < 1e-8, "{}", sys.0);
        assert_eq!(rep.inertia.map(|i| i.positive), Some(1));
        assert!(rep.stable);
        let mut sys2 = Cubic(3.0);
        let rep2 = newton(
            &mut sys2,
            &mut NoInertia(FaerLdlt::new()),
            &mut k,
            &settings,
        )
        .unwrap();
        assert_eq!(sys2.0, sys.0);
        assert!(rep2.inertia.is_none());
        assert!(rep2.stable);
        assert_eq!(rep2.iterations, rep.iterations);
    }

    /// r(x) = x³ + x − 2 with its derivative scaled by `slope` (1: the exact tangent), and the
    /// evaluations in order: `K` with the tangent, `R` the residual alone.
    struct Logged {
        x: f64,
        slope: f64,
        log: String,
    }

    impl NonlinearSystem for Logged {
        one_unknown!();
        fn evaluate(&mut self, r: &mut [f64], k: Option<&mut CsrMatrix>) -> Result<(), String> {
            r[0] = self.x.powi(3) + self.x - 2.0;
            if let Some(k) = k {
                k.values[0] = self.slope * (3.0 * self.x * self.x + 1.0);
                self.log.push('K');
            } else {
                self.log.push('R');
            }
            Ok(())
        }
        one_coordinate!(x);
    }

    fn logged_solve(slope: f64, settings: &NewtonSettings) -> (Logged, NewtonReport) {
        let mut sys = Logged {
            x: 2.0,
            slope,
            log: String::new(),
        };
        let mut k = sys.new_matrix();
        let rep = newton(&mut sys, &mut FaerLdlt::new(), &mut k, settings).unwrap();
        (sys, rep)
    }

    /// Near the root a lagged Newton keeps the previous iterate's tangent: it reaches the root
    /// that a tangent per iteration reaches, within the tolerance, with fewer tangents than
    /// iterations; the stability test still assembles the converged state's tangent.
    #[test]
    fn a_chord_step_near_the_root_keeps_the_previous_tangent() {
        let (lagged, rep) = logged_solve(1.0, &NewtonSettings::default());
        let (full, rep_full) = logged_solve(
            1.0,
            &NewtonSettings {
                lag_tangent: false,
                ..NewtonSettings::default()
            },
        );
        let tol = 1e-10 * rep.residuals[0];
        assert!(*rep.residuals.last().unwrap() <= tol, "{:?}", rep.residuals);
        assert!((lagged.x - 1.0).abs() <= tol && (full.x - 1.0).abs() <= tol);
        // one tangent per iteration and one for the stability test, without the lag (the last
        // with the converged residual)
        assert_eq!(
            full.log.matches('K').count(),
            rep_full.iterations + 1,
            "{}",
            full.log
        );
        // with it, the last iteration keeps the tangent, the stability test assembles it
        let tangents = lagged.log.matches('K').count();
        assert!(
            tangents < rep.iterations + 1,
            "{} in {} iterations",
            lagged.log,
            rep.iterations
        );
        assert!(lagged.log.ends_with("RK"), "{}", lagged.log);
        assert!(rep.stable && rep.inertia.is_some());
    }

    /// A kept tangent that contracts the residual less than `LAG_CONTRACTION` (here a tangent
    /// 10 % too steep: about 11× an iteration) is renewed at the next iteration: never two
    /// chord steps in a row, and every chord step comes after the residual fell below
    /// `LAG_BAND` of the first.
    #[test]
    fn a_chord_step_that_contracts_little_is_followed_by_a_new_tangent() {
        let (sys, rep) = logged_solve(1.1, &NewtonSettings::default());
        assert!(rep.iterations > 6, "{}", rep.iterations);
        // iterations: the log after its first residual, one `K` (assembled) or none (chord)
        // before each step's residual
        let steps: Vec<bool> = sys.log[1..sys.log.len() - 1]
            .split_inclusive('R')
            .map(|s| s.starts_with('K'))
            .collect();
        assert_eq!(steps.len(), rep.iterations, "{}", sys.log);
        assert!(steps.iter().any(|a| !a), "no chord step: {}", sys.log);
        for (i, w) in steps.windows(2).enumerate() {
            assert!(
                w[0] || w[1],
                "chord steps {} and {} in a row: {}",
                i + 1,
                i + 2,
                sys.log
            );
        }
        for (i, &assembled) in steps.iter().enumerate() {
            if !assembled {
                assert!(
                    rep.residuals[i] <= LAG_BAND * rep.residuals[0],
                    "{i}: {:?}",
                    rep.residuals
                );
            }
        }
    }

    /// Solves to the linear solver's own tolerance (a load step retried after a failure) never
    /// keep a tangent.
    #[test]
    fn exact_solves_assemble_a_tangent_at_every_iteration() {
        let (sys, rep) = logged_solve(
            1.0,
            &NewtonSettings {
                inexact: false,
                ..NewtonSettings::default()
            },
        );
        assert_eq!(
            sys.log.matches('K').count(),
            rep.iterations + 1,
            "{}",
            sys.log
        );
    }

    /// A static problem that counts the tangents it assembles.
    struct Counted<'m> {
        inner: crate::problem::statics::StaticProblem<'m>,
        tangents: usize,
    }

    impl NonlinearSystem for Counted<'_> {
        fn n(&self) -> usize {
            self.inner.n()
        }
        fn evaluate(&mut self, r: &mut [f64], k: Option<&mut CsrMatrix>) -> Result<(), String> {
            self.tangents += usize::from(k.is_some());
            self.inner.evaluate(r, k)
        }
        fn increment(&mut self, dx: &[f64], alpha: f64) {
            self.inner.increment(dx, alpha)
        }
        fn snapshot(&self) -> Vec<f64> {
            self.inner.snapshot()
        }
        fn restore(&mut self, s: &[f64]) {
            self.inner.restore(s)
        }
        fn new_matrix(&self) -> CsrMatrix {
            self.inner.new_matrix()
        }
        fn expected_negative_pivots(&self) -> usize {
            self.inner.expected_negative_pivots()
        }
        fn residual_floor(&self) -> f64 {
            self.inner.residual_floor()
        }
        fn groups(&self) -> Vec<u8> {
            self.inner.groups()
        }
        fn difference_step(&self) -> Option<f64> {
            self.inner.difference_step()
        }
    }

    impl crate::algebra::system::LoadedSystem for Counted<'_> {
        fn set_load(&mut self, s: f64) {
            self.inner.set_load(s)
        }
    }

    /// The film at a loaded, non-uniform state.
    fn loaded_film() -> crate::problem::model::Model {
        crate::problem::examples::film([8, 8, 4], crate::mesh::ElementKind::Hex8, 30e3).unwrap()
    }

    /// The difference of residuals stands for the assembled tangent's product: on the film at
    /// 30 kV (a wavy state, so that every cell differs) within 10⁻⁵ of its size for vectors of
    /// every kind (smooth, alternating, one unknown).
    #[test]
    fn a_difference_of_residuals_is_the_tangents_product() {
        use crate::algebra::system::LoadedSystem;
        let model = loaded_film();
        let state = crate::problem::examples::wavy_state(&model, 1e-2, 1e-6, 0.0);
        let mut p = crate::problem::statics::StaticProblem::new(&model, Some(state));
        p.set_load(1.0);
        let n = p.n();
        let (mut r, mut k) = (vec![0.0; n], p.new_matrix());
        p.evaluate(&mut r, Some(&mut k)).unwrap();
        let base = p.snapshot();
        let step = p
            .difference_step()
            .expect("a static problem gives products");
        let vectors: [Vec<f64>; 3] = [
            (0..n).map(|i| (i as f64 * 0.37).sin()).collect(),
            (0..n)
                .map(|i| if i % 2 == 0 { 1.0 } else { -0.5 })
                .collect(),
            (0..n).map(|i| if i == n / 2 { 1.0 } else { 0.0 }).collect(),
        ];
        let mut worst = 0.0f64;
        for v in &vectors {
            let (mut y, mut kv) = (vec![0.0; n], vec![0.0; n]);
            assert!(difference_product(&mut p, &base, &r, step, v, &mut y));
            k.mul_vec(v, &mut kv);
            let e = y
                .iter()
                .zip(&kv)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
            let size = kv.iter().map(|a| a * a).sum::<f64>().sqrt();
            assert!(size > 0.0);
            worst = worst.max(e / size);
            assert_eq!(p.snapshot(), base, "the system is back at its state");
        }
        println!("difference products: largest relative error {worst:.2e}");
        assert!(worst < 1e-5, "{worst:e}");
        // a zero vector's product is zero, without an evaluation away from the state
        let mut y = vec![1.0; n];
        assert!(difference_product(
            &mut p,
            &base,
            &r,
            step,
            &vec![0.0; n],
            &mut y
        ));
        assert!(y.iter().all(|v| *v == 0.0));
    }

    /// A ramp of the film with a held factorisation (the reusing solver, from any size): with
    /// the tangent's products as differences of residuals it assembles a tangent only for the
    /// stability tests, and reaches the states of the ramp on assembled tangents within
    /// Newton's tolerance.
    #[test]
    fn newton_on_products_assembles_the_stability_tests_tangents_alone() {
        use crate::solve::reused::ReusedLdlt;
        use crate::solve::stepping::{ramp, StepControl};
        let model = loaded_film();
        let run = |products: bool| {
            let mut system = Counted {
                inner: crate::problem::statics::StaticProblem::new(&model, None),
                tangents: 0,
            };
            let mut solver = ReusedLdlt::with_ordering(Default::default())
                .from_unknowns(0)
                .adaptive(true);
            let control = StepControl {
                steps: 4,
                ..Default::default()
            };
            let settings = NewtonSettings {
                tangent_products: products,
                ..Default::default()
            };
            let report = ramp(&mut system, &mut solver, &settings, &control, |_, _| {}).unwrap();
            let stats = solver.stats();
            (system.inner.snapshot(), system.tangents, report, stats)
        };
        let (assembled, t_assembled, rep_a, _) = run(false);
        let (by_products, t_products, rep_p, stats) = run(true);
        assert_eq!(rep_p.accepted_steps, 4);
        // one tangent at the start (the predictor's factor) and one per stability test
        assert_eq!(t_products, 1 + 4, "{t_products} tangents");
        assert!(
            t_assembled > t_products + 4,
            "{t_assembled} against {t_products}"
        );
        assert!(stats.krylov_iterations > 0);
        assert_eq!(stats.factorizations, 1 + 4);
        let size = assembled.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = assembled
            .iter()
            .zip(&by_products)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        println!(
            "products: {} Newton iterations, {t_products} tangents; assembled: {}, {t_assembled}; \
             states {:.1e} of their size apart",
            rep_p.newton_iterations,
            rep_a.newton_iterations,
            diff / size
        );
        assert!(diff <= 1e-8 * size, "{diff:e} of {size:e}");
    }
}
