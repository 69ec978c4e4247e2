//! A projected limited-memory BFGS method for a smooth function on a convex feasible set
//! (bounds and rate chains, [`Feasible`]).
//!
//! # The method
//! Each iteration takes the L-BFGS direction (Nocedal 1980; the two-loop recursion of Nocedal &
//! Wright, *Numerical Optimization*, 2006, Alg. 7.4) in the variables that are free: a variable
//! at a bound whose gradient pushes it out of the box is held, as in the projected quasi-Newton
//! methods of Bertsekas (1982) and Kim, Sra & Dhillon (2010). The trial point P(x + αd) is
//! the direction's step projected onto the feasible set, accepted by the Armijo condition
//! J(x⁺) ≤ J(x) + c₁ ∇J·(x⁺ − x) with halving α. When the projection spoils the quasi-Newton
//! direction (no descent along the projected arc), the iteration falls back to the projected
//! gradient arc P(x − α∇J), along which the Armijo condition always holds for a small α. A
//! function value that cannot be computed (a run that fails) is treated as +∞ and shortens the
//! step. [`minimize_with`] may start the recursion from a model of the Hessian instead of a
//! scalar (a damped Gauss–Newton matrix, [`Curvature`]).
//!
//! A small method of our own, because no maintained Rust crate minimises over bounds (`argmin`
//! 0.11 has L-BFGS without bounds; L-BFGS-B bindings need Fortran) and none over rate limits.
//!
//! # Stop criteria
//! - `converged, "projected gradient"`: g(x) ≤ `gradient_tolerance` · g(x₀), where
//!   g(x) = ‖x − P(x − α∇J)‖∞/α with α = 10⁻⁴/‖∇J‖∞ is the largest entry of ∇J among the
//!   variables free to move against it (the first-order condition, relative to the start);
//! - `converged, "objective change"`: (Jₖ − Jₖ₊₁) ≤ `objective_tolerance` · max(|Jₖ|, |Jₖ₊₁|)
//!   over an accepted iteration;
//! - not converged: `"iteration limit"`, `"line search"` (no decrease along the projected
//!   gradient either), or the evaluation's own error at the start point.

use super::feasible::Feasible;
use faer::linalg::solvers::Solve;
use faer::Mat;
use std::collections::VecDeque;

/// A model B(x) of the objective's Hessian at x (dense, symmetric, positive semi-definite),
/// for the recursion's start H₀ = (B_FF + μI)⁻¹ over the free variables F.
pub type Curvature<'a> = &'a dyn Fn(&[f64]) -> Mat<f64>;

/// What the minimiser stops at.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    pub max_iterations: usize,
    pub gradient_tolerance: f64,
    pub objective_tolerance: f64,
    /// Correction pairs kept.
    pub memory: usize,
    /// The first trial step's largest change of a variable (later steps start at α = 1).
    pub first_step: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            max_iterations: 200,
            gradient_tolerance: 1e-6,
            objective_tolerance: 1e-10,
            memory: 100,
            first_step: 0.1,
        }
    }
}

/// One accepted iteration (the start is iteration 0).
#[derive(Debug, Clone, PartialEq)]
pub struct Iteration {
    pub objective: f64,
    /// The projected gradient's largest entry at the iterate (see the stop criteria).
    pub projected_gradient: f64,
    /// Function evaluations so far.
    pub evaluations: usize,
}

/// The outcome: the best point, its value and gradient, the history and why it stopped.
#[derive(Debug, Clone, PartialEq)]
pub struct Minimum {
    pub x: Vec<f64>,
    pub objective: f64,
    pub gradient: Vec<f64>,
    pub history: Vec<Iteration>,
    pub converged: bool,
    pub reason: String,
    pub evaluations: usize,
}

/// The step (in the scaled variables) of the projected gradient's measure.
const PG_STEP: f64 = 1e-4;

/// Armijo's constant and the halvings of a line search.
const ARMIJO: f64 = 1e-4;
const HALVINGS: usize = 40;

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn max_abs(a: &[f64]) -> f64 {
    a.iter().fold(0.0f64, |m, v| m.max(v.abs()))
}

/// Minimises `f` (value and gradient, or an error) over `set` from `x0`, which must be
/// feasible. `progress` sees every accepted iteration.
pub fn minimize<F, E>(
    f: F,
    x0: &[f64],
    set: &Feasible,
    options: &Options,
    progress: impl FnMut(&Iteration),
) -> Result<Minimum, E>
where
    F: FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
{
    minimize_with(f, x0, set, options, None, progress)
}

/// The damping μ of a curvature model relative to its largest diagonal entry: its start, the
/// factor by which a step that needs shortening raises it (per halving) and a full step lowers
/// it, and its range.
const DAMPING_START: f64 = 1e-6;
const DAMPING_FACTOR: f64 = 4.0;
const DAMPING_RANGE: (f64, f64) = (1e-12, 1.0);

/// [`minimize`] with a model of the Hessian as the quasi-Newton recursion's start (in place of
/// the scalar γ = sᵀy/yᵀy): H₀ = (B_FF + μI)⁻¹ over the free variables, with the damping μ
/// adapted as in Levenberg–Marquardt: lowered after a full step, raised with each halving the
/// line search needs. A Gauss–Newton model of a least-squares objective makes the first
/// iterations Gauss–Newton steps, which the correction pairs then refine.
pub fn minimize_with<F, E>(
    mut f: F,
    x0: &[f64],
    set: &Feasible,
    options: &Options,
    curvature: Option<Curvature>,
    mut progress: impl FnMut(&Iteration),
) -> Result<Minimum, E>
where
    F: FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
{
    let mut damping = DAMPING_START;
    let n = x0.len();
    let mut x = x0.to_vec();
    let (mut fx, mut g) = f(&x)?;
    let mut evaluations = 1;
    // the projected gradient ‖x − P(x − α∇J)‖∞/α for a small α: ∇J's largest entry among the
    // variables free to move against it (a unit α would saturate at the box's size)
    let projected = |x: &[f64], g: &[f64]| -> f64 {
        let largest = max_abs(g);
        if largest == 0.0 {
            return 0.0;
        }
        let alpha = PG_STEP / largest;
        let t: Vec<f64> = x.iter().zip(g).map(|(a, b)| a - alpha * b).collect();
        let p = set.project(&t);
        x.iter()
            .zip(&p)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
            / alpha
    };
    let pg0 = projected(&x, &g);
    let mut history = vec![Iteration {
        objective: fx,
        projected_gradient: pg0,
        evaluations,
    }];
    progress(&history[0]);
    let mut pairs: VecDeque<(Vec<f64>, Vec<f64>)> = VecDeque::new();
    let done = |converged: bool, reason: &str, x, fx, g, history, evaluations| Minimum {
        x,
        objective: fx,
        gradient: g,
        history,
        converged,
        reason: reason.to_string(),
        evaluations,
    };
    if pg0 == 0.0 {
        return Ok(done(
            true,
            "projected gradient",
            x,
            fx,
            g,
            history,
            evaluations,
        ));
    }
    for iteration in 0..options.max_iterations {
        // variables held at a bound that the gradient pushes against
        let held: Vec<bool> = (0..n)
            .map(|i| (x[i] <= set.lower[i] && g[i] > 0.0) || (x[i] >= set.upper[i] && g[i] < 0.0))
            .collect();
        let start = curvature.and_then(|b| Start::new(&b(&x), &held, damping));
        let mut d = two_loop(&g, &pairs, &held, start.as_ref());
        let mut first = if iteration == 0 && pairs.is_empty() && start.is_none() {
            (options.first_step / max_abs(&d).max(f64::MIN_POSITIVE)).min(1.0)
        } else {
            1.0
        };
        let mut accepted = None;
        let mut halvings = 0;
        for fallback in [false, true] {
            if fallback {
                pairs.clear();
                d = g.iter().map(|v| -v).collect();
                first = (options.first_step / max_abs(&d).max(f64::MIN_POSITIVE)).min(1.0);
            }
            let mut alpha = first;
            for _ in 0..HALVINGS {
                let trial: Vec<f64> = x.iter().zip(&d).map(|(a, b)| a + alpha * b).collect();
                let trial = set.project(&trial);
                let step: Vec<f64> = trial.iter().zip(&x).map(|(a, b)| a - b).collect();
                let slope = dot(&g, &step);
                if slope >= 0.0 {
                    if !fallback && alpha == first {
                        break; // the projection spoiled the direction: take the gradient's
                    }
                    alpha *= 0.5;
                    continue;
                }
                evaluations += 1;
                if let Ok((ft, gt)) = f(&trial) {
                    if ft.is_finite() && ft <= fx + ARMIJO * slope {
                        accepted = Some((trial, ft, gt, step));
                        break;
                    }
                }
                alpha *= 0.5;
                halvings += 1;
            }
            if accepted.is_some() {
                break;
            }
            halvings = HALVINGS;
        }
        damping = if halvings == 0 {
            damping / DAMPING_FACTOR
        } else {
            damping * DAMPING_FACTOR.powi(halvings.min(10) as i32)
        }
        .clamp(DAMPING_RANGE.0, DAMPING_RANGE.1);

        let Some((xn, fnew, gn, s)) = accepted else {
            return Ok(done(false, "line search", x, fx, g, history, evaluations));
        };
        let y: Vec<f64> = gn.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        if sy > 1e-12 * dot(&s, &s).sqrt() * dot(&y, &y).sqrt() {
            pairs.push_back((s, y));
            if pairs.len() > options.memory {
                pairs.pop_front();
            }
        }
        let change = fx - fnew;
        x = xn;
        g = gn;
        let old = fx;
        fx = fnew;
        let pg = projected(&x, &g);
        history.push(Iteration {
            objective: fx,
            projected_gradient: pg,
            evaluations,
        });
        progress(history.last().expect("pushed"));
        if pg <= options.gradient_tolerance * pg0 {
            return Ok(done(
                true,
                "projected gradient",
                x,
                fx,
                g,
                history,
                evaluations,
            ));
        }
        if change <= options.objective_tolerance * old.abs().max(fx.abs()) {
            return Ok(done(
                true,
                "objective change",
                x,
                fx,
                g,
                history,
                evaluations,
            ));
        }
    }
    Ok(done(
        false,
        "iteration limit",
        x,
        fx,
        g,
        history,
        evaluations,
    ))
}

/// The recursion's start from a curvature model: the Cholesky factor of B_FF + μ·max diag(B_FF)·I
/// over the free variables F.
struct Start {
    free: Vec<usize>,
    factor: faer::linalg::solvers::Llt<f64>,
}

impl Start {
    /// `None` when the model is zero on the free variables or not positive definite.
    fn new(b: &Mat<f64>, held: &[bool], damping: f64) -> Option<Start> {
        let free: Vec<usize> = (0..held.len()).filter(|&i| !held[i]).collect();
        let largest = free.iter().fold(0.0f64, |m, &i| m.max(b[(i, i)]));
        if free.is_empty() || !(largest > 0.0 && largest.is_finite()) {
            return None;
        }
        let mu = damping * largest;
        let m = Mat::from_fn(free.len(), free.len(), |r, c| {
            b[(free[r], free[c])] + if r == c { mu } else { 0.0 }
        });
        let factor = m.llt(faer::Side::Lower).ok()?;
        Some(Start { free, factor })
    }

    /// q ← H₀q on the free variables.
    fn apply(&self, q: &mut [f64]) {
        let mut rhs = Mat::from_fn(self.free.len(), 1, |r, _| q[self.free[r]]);
        self.factor.solve_in_place(rhs.as_mut());
        for (r, &i) in self.free.iter().enumerate() {
            q[i] = rhs[(r, 0)];
        }
    }
}

/// −H∇J by the two-loop recursion over the free variables (held ones get 0), H₀ from the
/// curvature model's `start`, else γI with γ = sᵀy/yᵀy of the newest pair.
fn two_loop(
    g: &[f64],
    pairs: &VecDeque<(Vec<f64>, Vec<f64>)>,
    held: &[bool],
    start: Option<&Start>,
) -> Vec<f64> {
    let free = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .zip(held)
            .map(|(a, h)| if *h { 0.0 } else { *a })
            .collect()
    };
    let mut q = free(g);
    let restricted: Vec<(Vec<f64>, Vec<f64>, f64)> = pairs
        .iter()
        .filter_map(|(s, y)| {
            let (s, y) = (free(s), free(y));
            let sy = dot(&s, &y);
            (sy > 0.0).then_some((s, y, 1.0 / sy))
        })
        .collect();
    let mut alphas = Vec::with_capacity(restricted.len());
    for (s, y, rho) in restricted.iter().rev() {
        let a = rho * dot(s, &q);
        for (qi, yi) in q.iter_mut().zip(y) {
            *qi -= a * yi;
        }
        alphas.push(a);
    }
    if let Some(start) = start {
        start.apply(&mut q);
    } else if let Some((s, y, _)) = restricted.last() {
        let gamma = dot(s, y) / dot(y, y);
        q.iter_mut().for_each(|v| *v *= gamma);
    }
    for ((s, y, rho), a) in restricted.iter().zip(alphas.iter().rev()) {
        let b = rho * dot(y, &q);
        for (qi, si) in q.iter_mut().zip(s) {
            *qi += (a - b) * si;
        }
    }
    q.iter().map(|v| -v).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rosenbrock(x: &[f64]) -> Result<(f64, Vec<f64>), String> {
        let (a, b) = (x[0], x[1]);
        let f = (1.0 - a).powi(2) + 100.0 * (b - a * a).powi(2);
        let g = vec![
            -2.0 * (1.0 - a) - 400.0 * a * (b - a * a),
            200.0 * (b - a * a),
        ];
        Ok((f, g))
    }

    #[test]
    fn an_unbounded_minimum_is_found() {
        let set = Feasible::boxed(vec![-5.0; 2], vec![5.0; 2]);
        let options = Options {
            gradient_tolerance: 1e-10,
            objective_tolerance: 0.0,
            ..Default::default()
        };
        let m = minimize(rosenbrock, &[-1.2, 1.0], &set, &options, |_| {}).unwrap();
        assert!(m.converged, "{}", m.reason);
        assert!(
            (m.x[0] - 1.0).abs() < 1e-6 && (m.x[1] - 1.0).abs() < 1e-6,
            "{:?}",
            m.x
        );
        // the history falls
        assert!(m
            .history
            .windows(2)
            .all(|w| w[1].objective <= w[0].objective));
    }

    #[test]
    fn a_bound_holds_the_minimum_on_its_face() {
        // Rosenbrock with x₀ ≤ 0.5: the minimum is at x₀ = 0.5, x₁ = 0.25 (the valley's floor)
        let set = Feasible::boxed(vec![-5.0, -5.0], vec![0.5, 5.0]);
        let options = Options {
            gradient_tolerance: 1e-10,
            objective_tolerance: 0.0,
            ..Default::default()
        };
        let m = minimize(rosenbrock, &[-1.2, 1.0], &set, &options, |_| {}).unwrap();
        assert!(m.converged, "{}", m.reason);
        assert_eq!(m.x[0], 0.5);
        assert!((m.x[1] - 0.25).abs() < 1e-8, "{:?}", m.x);
    }

    #[test]
    fn a_rate_limited_least_squares_problem_meets_its_limits_and_optimality() {
        // track a step with a rate limit: min ½‖x − t‖², |x_{k+1} − x_k| ≤ 0.2, 0 ≤ x ≤ 1;
        // its minimum is the projection of t, which satisfies (t − x*)·(q − x*) ≤ 0 for
        // every feasible q
        let n = 12;
        let t: Vec<f64> = (0..n).map(|k| if k < 6 { 0.0 } else { 1.0 }).collect();
        let set = Feasible {
            lower: vec![0.0; n],
            upper: vec![1.0; n],
            chains: vec![((0..n).collect(), vec![0.2; n - 1])],
        };
        let f = |x: &[f64]| -> Result<(f64, Vec<f64>), String> {
            let r: Vec<f64> = x.iter().zip(&t).map(|(a, b)| a - b).collect();
            Ok((0.5 * dot(&r, &r), r))
        };
        let options = Options {
            gradient_tolerance: 1e-9,
            objective_tolerance: 0.0,
            max_iterations: 500,
            ..Default::default()
        };
        let m = minimize(f, &vec![0.0; n], &set, &options, |_| {}).unwrap();
        assert!(m.converged, "{}", m.reason);
        assert!(set.violation(&m.x) <= 1e-15);
        let p = set.project(&t);
        assert!(
            m.x.iter().zip(&p).all(|(a, b)| (a - b).abs() < 1e-6),
            "{:?} vs {:?}",
            m.x,
            p
        );
        // the optimum is a symmetric ramp through 0.5 between the sixth and seventh values
        assert!((m.x[5] + m.x[6] - 1.0).abs() < 1e-6, "{:?}", m.x);
    }

    #[test]
    fn a_curvature_model_starts_the_recursion() {
        // an ill-conditioned quadratic ½xᵀAx − bᵀx (eigenvalues 1 … 10⁶) with one bound
        // active at its minimum: its exact Hessian as the model converges in a few iterations,
        // the scalar start needs many
        let n = 40;
        let a = Mat::from_fn(n, n, |i, j| {
            let d = 10f64.powf(6.0 * i as f64 / (n - 1) as f64);
            if i == j {
                d
            } else if i.abs_diff(j) == 1 {
                0.3 * d.min(10f64.powf(6.0 * j as f64 / (n - 1) as f64))
            } else {
                0.0
            }
        });
        let b: Vec<f64> = (0..n)
            .map(|i| (a[(i, i)]) * (1.0 + (i % 3) as f64))
            .collect();
        let f = |x: &[f64]| -> Result<(f64, Vec<f64>), String> {
            let ax: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| a[(i, j)] * x[j]).sum())
                .collect();
            let g: Vec<f64> = ax.iter().zip(&b).map(|(p, q)| p - q).collect();
            Ok((0.5 * dot(x, &ax) - dot(&b, x), g))
        };
        let mut upper = vec![10.0; n];
        upper[n - 1] = 0.2; // the unbounded minimum's last entry is about 0.47
        let set = Feasible::boxed(vec![-10.0; n], upper);
        let options = Options {
            gradient_tolerance: 1e-9,
            objective_tolerance: 0.0,
            max_iterations: 2000,
            ..Default::default()
        };
        let exact = |_: &[f64]| a.clone();
        let model = minimize_with(f, &vec![0.0; n], &set, &options, Some(&exact), |_| {}).unwrap();
        let plain = minimize(f, &vec![0.0; n], &set, &options, |_| {}).unwrap();
        assert!(
            model.converged && plain.converged,
            "{} {}",
            model.reason,
            plain.reason
        );
        assert_eq!(model.x[n - 1], 0.2);
        // the exact minimum: A_FF x_F = b_F − A_F,last · 0.2 on the free entries
        let m = n - 1;
        let aff = Mat::from_fn(m, m, |i, j| a[(i, j)]);
        let mut rhs = Mat::from_fn(m, 1, |i, _| b[i] - a[(i, m)] * 0.2);
        aff.llt(faer::Side::Lower)
            .unwrap()
            .solve_in_place(rhs.as_mut());
        for i in 0..m {
            let exact = rhs[(i, 0)];
            assert!(
                (model.x[i] - exact).abs() < 1e-7 * exact.abs().max(1.0),
                "{i}: {} vs {exact}",
                model.x[i]
            );
            assert!(
                (plain.x[i] - exact).abs() < 1e-4 * exact.abs().max(1.0),
                "{i}: {} vs {exact}",
                plain.x[i]
            );
        }
        assert!(
            model.history.len() <= 8 && plain.history.len() > 4 * model.history.len(),
            "iterations: {} with the model, {} without",
            model.history.len() - 1,
            plain.history.len() - 1
        );
    }

    #[test]
    fn a_failed_evaluation_shortens_the_step() {
        // f = (x − 3)² defined only below 2.5: the minimiser stops at the edge of the domain
        let set = Feasible::boxed(vec![0.0], vec![10.0]);
        let f = |x: &[f64]| -> Result<(f64, Vec<f64>), String> {
            if x[0] > 2.5 {
                Err("outside".into())
            } else {
                Ok(((x[0] - 3.0).powi(2), vec![2.0 * (x[0] - 3.0)]))
            }
        };
        let m = minimize(f, &[0.0], &set, &Options::default(), |_| {}).unwrap();
        assert!(m.x[0] <= 2.5 && m.x[0] > 2.0, "{:?}", m.x);
        assert!(m.objective < 1.0);
    }
}
