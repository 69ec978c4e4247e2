//! Arc-length continuation of a loaded system through limit points (Riks 1979; Crisfield 1981).
//!
//! The load factor s joins the free unknowns x, and each step from a converged point (xₙ, sₙ)
//! is closed by the constraint
//!
//! g = ‖Δx‖² + ψ² Δs² − Δl² = 0,  Δx = x − xₙ, Δs = s − sₙ,
//!
//! solved with the residual by Newton on the bordered system. Each iteration solves the tangent
//! twice, K δxᵣ = −r and K δxₜ = −∂r/∂s, and takes from the linearised constraint
//! δs = −(g/2 + Δx·δxᵣ)/(Δx·δxₜ + ψ²Δs), δx = δxᵣ + δs δxₜ. The bordered matrix is never formed,
//! so the symmetric factorisation of K serves, also where K is indefinite past a limit point.
//! ∂r/∂s is a central difference of the residual in s (the loads are set through
//! [`LoadedSystem::set_load`]), which costs two residual evaluations and changes only the rate of
//! convergence, not the converged point.
//!
//! The first step is load-controlled (s = s₀ + `increment`). It fixes the scale ψ² = ‖Δx₁‖²/Δs₁²,
//! so that load and state share the arc equally, and the first arc length Δl = √2‖Δx₁‖. The arc
//! length then adapts to the corrector's iteration count, is halved when a step fails, and is
//! capped so that |Δs| ≤ `increment`. The predictor follows the tangent t = dx/ds, oriented by
//! the sign of its product with the previous increment: (t·Δxₙ + ψ²Δsₙ) > 0 (Feng, Owen &
//! Perić 1996). That rule keeps going through limit points, where det K changes sign, while
//! the sign of det K would turn back.
//!
//! Each converged point is reported with the inertia of K, the tangent at fixed load. More negative
//! pivots than the system's potential unknowns means the state is unstable under load control,
//! even though continuation reaches it. A change of the sign of Δs between two steps brackets a
//! limit point of the load. Its arc position and load come from the parabola through the three
//! points around it, and the state there is the quadratic interpolation of those three points. Both
//! are handed to the caller before the path goes on.

use super::linear::{Inertia, LinearSolver};
use super::newton::NewtonSettings;
use crate::algebra::csr::CsrMatrix;
use crate::algebra::system::LoadedSystem;

/// Settings of a continuation.
#[derive(Debug, Clone)]
pub struct ContinuationSettings {
    /// Load-factor increment of the first (load-controlled) step, and the largest |Δs| of any step.
    pub increment: f64,
    /// Direction of the first step: +1 (load rising) or −1.
    pub direction: f64,
    /// Largest number of points.
    pub max_points: usize,
    /// Land exactly on this load factor when the path crosses it, and stop there.
    pub target_load: Option<f64>,
    /// Corrector iterations aimed at: the arc length scales by √(aim/iterations), within ½…2.
    pub aim_iterations: usize,
    /// Smallest arc length, as a fraction of the first one.
    pub min_fraction: f64,
}

impl Default for ContinuationSettings {
    fn default() -> Self {
        ContinuationSettings {
            increment: 0.05,
            direction: 1.0,
            max_points: 500,
            target_load: None,
            aim_iterations: 5,
            min_fraction: 1.0 / 1024.0,
        }
    }
}

/// A converged point of the path.
#[derive(Debug, Clone)]
pub struct PathPoint {
    /// 1 for the first point after the start.
    pub index: usize,
    pub load: f64,
    /// Arc length from the start (in the scaled norm of the constraint).
    pub arc: f64,
    /// Corrector iterations.
    pub iterations: usize,
    /// Inertia of the tangent at fixed load (`None` when the solver cannot tell it).
    pub inertia: Option<Inertia>,
    /// Stable under load control: no more negative pivots than potential unknowns.
    pub stable: bool,
}

/// A limit point of the load between two points of the path.
#[derive(Debug, Clone, PartialEq)]
pub struct LimitPoint {
    pub load: f64,
    pub arc: f64,
    /// A maximum of the load (true) or a minimum.
    pub maximum: bool,
    /// Index of the point nearest to it.
    pub near: usize,
}

/// What the caller is shown.
#[derive(Debug, Clone)]
pub enum PathEvent<'a> {
    /// A converged point; the system holds its state.
    Point(&'a PathPoint),
    /// A limit point; the system holds the interpolated state there (restored afterwards).
    Limit(&'a LimitPoint),
}

/// The caller's answer to a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Next {
    Continue,
    Stop,
}

/// Why a continuation ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PathEnd {
    /// The caller asked to stop (a target of its own was reached).
    Stopped,
    /// `target_load` was reached exactly.
    TargetLoad,
    /// `max_points` points were computed.
    MaxPoints,
}

/// Summary of a continuation that ended normally.
#[derive(Debug, Clone)]
pub struct PathReport {
    pub points: usize,
    pub iterations: usize,
    pub cutbacks: usize,
    pub limits: Vec<LimitPoint>,
    pub end: PathEnd,
}

/// A continuation that could not go on: the system holds the last converged point.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("continuation stopped after {points} points at load factor {last_load}: {reason}")]
pub struct PathFailure {
    pub points: usize,
    pub last_load: f64,
    pub iterations: usize,
    pub limits: Vec<LimitPoint>,
    pub reason: String,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Relative step of the central difference in s.
const DS: f64 = 1e-5;
/// Residuals up to this multiple of the floor count as converged once they stagnate (as Newton).
const ROUNDOFF_BAND: f64 = 100.0;

/// The path's work state.
struct Path<'s, S: LoadedSystem + ?Sized> {
    system: &'s mut S,
    solver: &'s mut dyn LinearSolver,
    k: CsrMatrix,
    r: Vec<f64>,
    /// ∂r/∂s scratch.
    plus: Vec<f64>,
    minus: Vec<f64>,
    newton: NewtonSettings,
}

/// One converged step.
struct Step {
    dx: Vec<f64>,
    ds: f64,
    iterations: usize,
}

impl<S: LoadedSystem + ?Sized> Path<'_, S> {
    /// The dot products of `pairs` of vectors of the unknowns, over every process's part of
    /// them (one reduction; [`NonlinearSystem::sum_over_processes`]), so that every process
    /// takes the same path.
    fn dots<const N: usize>(&self, pairs: [(&[f64], &[f64]); N]) -> Result<[f64; N], String> {
        let mut v = pairs.map(|(a, b)| dot(a, b));
        self.system.sum_over_processes(&mut v)?;
        Ok(v)
    }

    /// Whether every entry of `v` is finite, on every process's part.
    fn finite(&self, v: &[f64]) -> Result<bool, String> {
        let mut bad = [v.iter().filter(|x| !x.is_finite()).count() as f64];
        self.system.sum_over_processes(&mut bad)?;
        Ok(bad[0] == 0.0)
    }

    /// ∂r/∂s at the current state and load `s` into `out` (central difference).
    fn load_derivative(&mut self, s: f64, out: &mut [f64]) -> Result<(), String> {
        let h = DS * s.abs().max(1.0);
        let snap = self.system.snapshot();
        self.system.set_load(s + h);
        let a = self.system.evaluate(&mut self.plus, None);
        self.system.restore(&snap);
        self.system.set_load(s - h);
        let b = self.system.evaluate(&mut self.minus, None);
        self.system.restore(&snap);
        a?;
        b?;
        for ((o, p), m) in out.iter_mut().zip(&self.plus).zip(&self.minus) {
            *o = (p - m) / (2.0 * h);
        }
        Ok(())
    }

    /// Factors the tangent at the current state: its inertia.
    fn factor(&mut self) -> Result<Option<Inertia>, String> {
        // a shared assembly's tangent is whole only to a solver that knows its entries
        if self.system.shares_cells() {
            super::newton::prepare_solver(&*self.system, self.solver)?;
        }
        self.system.evaluate(&mut self.r, Some(&mut self.k))?;
        let inertia = self.solver.factor(&self.k).map_err(|e| e.to_string())?;
        self.system.factored();
        Ok(inertia)
    }

    /// The tangent dx/ds = −K⁻¹ ∂r/∂s at the current state and load `s` (K factored there).
    fn tangent(&mut self, s: f64) -> Result<Vec<f64>, String> {
        let mut t = vec![0.0; self.system.n()];
        self.load_derivative(s, &mut t)?;
        t.iter_mut().for_each(|v| *v = -*v);
        self.solver
            .solve_in_place(&mut t)
            .map_err(|e| e.to_string())?;
        if !self.finite(&t)? {
            return Err("non-finite tangent".into());
        }
        Ok(t)
    }

    /// From the converged point at load `s0` with tangent `t`, the predictor `ds0`·t followed by
    /// Newton on the residual and, with `arc = Some((Δl, ψ²))`, the arc-length constraint (else
    /// the load stays at s0 + ds0). On failure the system is left where it stopped.
    fn correct(
        &mut self,
        s0: f64,
        t: &[f64],
        ds0: f64,
        arc: Option<(f64, f64)>,
    ) -> Result<Step, String> {
        let n = self.system.n();
        let mut dx: Vec<f64> = t.iter().map(|v| v * ds0).collect();
        let mut ds = ds0;
        self.system.set_load(s0 + ds);
        self.system.increment(&dx, 1.0);
        let floor = self.system.residual_floor();
        let mut tol = f64::NAN;
        let mut history: Vec<f64> = Vec::new();
        let mut q = vec![0.0; n];
        let mut xr = vec![0.0; n];
        for iteration in 0..=self.newton.max_iterations {
            self.system.evaluate(&mut self.r, Some(&mut self.k))?;
            let [rr] = self.dots([(&self.r, &self.r)])?;
            let rn = rr.sqrt();
            if !rn.is_finite() {
                return Err("non-finite residual".into());
            }
            if tol.is_nan() {
                tol = (self.newton.rtol * rn).max(floor);
            }
            history.push(rn);
            let m = history.len();
            let plateau = m >= 3 && rn <= ROUNDOFF_BAND * floor && rn > 0.5 * history[m - 3];
            if rn <= tol || plateau {
                return Ok(Step {
                    dx,
                    ds,
                    iterations: iteration,
                });
            }
            if iteration == self.newton.max_iterations {
                break;
            }
            if self.newton.verbose {
                log::info!(
                    "    arc-length it {iteration}: |r| = {rn:.3e}, s = {:.6}",
                    s0 + ds
                );
            }
            self.solver
                .factor(&self.k)
                .map_err(|e| format!("singular tangent: {e}"))?;
            self.system.factored();
            xr.iter_mut().zip(&self.r).for_each(|(a, b)| *a = -b);
            self.solver
                .solve_in_place(&mut xr)
                .map_err(|e| e.to_string())?;
            let mut dstep = 0.0;
            if let Some((dl, psi2)) = arc {
                self.load_derivative(s0 + ds, &mut q)?;
                q.iter_mut().for_each(|v| *v = -*v);
                self.solver
                    .solve_in_place(&mut q)
                    .map_err(|e| e.to_string())?;
                let [dx2, dxq, dxr] = self.dots([(&dx, &dx), (&dx, &q), (&dx, &xr)])?;
                let g = dx2 + psi2 * ds * ds - dl * dl;
                let den = dxq + psi2 * ds;
                if den == 0.0 || !den.is_finite() {
                    return Err("degenerate arc-length constraint".into());
                }
                dstep = -(0.5 * g + dxr) / den;
            }
            let delta: Vec<f64> = xr.iter().zip(&q).map(|(a, b)| a + dstep * b).collect();
            if !self.finite(&delta)? {
                return Err("non-finite update".into());
            }
            ds += dstep;
            self.system.set_load(s0 + ds);
            self.system.increment(&delta, 1.0);
            dx.iter_mut().zip(&delta).for_each(|(a, b)| *a += b);
            if rn > 1e8 * history[0].max(floor) {
                return Err(format!("diverged (residual {rn:.3e})"));
            }
        }
        Err(format!(
            "no convergence in {} iterations (residual {:.3e}, first {:.3e})",
            self.newton.max_iterations,
            history.last().copied().unwrap_or(f64::NAN),
            history[0]
        ))
    }
}

/// A converged point kept for locating limit points: its arc position, load, snapshot and
/// position in the scaled unknowns (the sum of the increments from the start).
#[derive(Clone)]
struct Near {
    arc: f64,
    load: f64,
    snapshot: Vec<f64>,
    position: Vec<f64>,
}

/// Refinements of a located limit point.
const LIMIT_REFINEMENTS: usize = 3;

impl<S: LoadedSystem + ?Sized> Path<'_, S> {
    /// Three points around a limit point of the load, closer to it than `near`: up to
    /// [`LIMIT_REFINEMENTS`] times, a new point is solved at the arc position of the parabola's
    /// vertex (an arc step from the nearest point before it) and the three points nearest the
    /// vertex are kept. A refinement that fails keeps what it had. The system is left at some
    /// point of the path; the caller restores it.
    fn refine_limit(&mut self, mut near: Vec<Near>, psi2: f64) -> Vec<Near> {
        for _ in 0..LIMIT_REFINEMENTS {
            let l = [near[0].arc, near[1].arc, near[2].arc];
            let (x, _, _) = vertex(l, [near[0].load, near[1].load, near[2].load]);
            // from the last point before the vertex, towards the next one
            let a = if x >= near[1].arc { 1 } else { 0 };
            let (from, to) = (&near[a], &near[a + 1]);
            let dl = x - from.arc;
            if dl <= 1e-9 * (to.arc - from.arc) || x >= to.arc {
                break;
            }
            self.system.restore(&from.snapshot);
            let t = match self.factor().and_then(|_| self.tangent(from.load)) {
                Ok(t) => t,
                Err(_) => break,
            };
            let towards: Vec<f64> = to
                .position
                .iter()
                .zip(&from.position)
                .map(|(b, a)| b - a)
                .collect();
            let Ok([t_towards, tt]) = self.dots([(&t, &towards), (&t, &t)]) else {
                break;
            };
            let sign = if t_towards + psi2 * (to.load - from.load) >= 0.0 {
                1.0
            } else {
                -1.0
            };
            let ds0 = sign * dl / (tt + psi2).sqrt();
            let Ok(step) = self.correct(from.load, &t, ds0, Some((dl, psi2))) else {
                break;
            };
            let point = Near {
                arc: from.arc + dl,
                load: from.load + step.ds,
                snapshot: self.system.snapshot(),
                position: from
                    .position
                    .iter()
                    .zip(&step.dx)
                    .map(|(p, d)| p + d)
                    .collect(),
            };
            near.insert(a + 1, point);
            // keep the three nearest the vertex, in arc order
            while near.len() > 3 {
                let first = (near[0].arc - x).abs();
                let last = (near[near.len() - 1].arc - x).abs();
                if first > last {
                    near.remove(0);
                } else {
                    near.pop();
                }
            }
        }
        near
    }
}

/// The parabola through (l₀, s₀), (l₁, s₁), (l₂, s₂): its vertex (l*, s*) clamped to [l₀, l₂],
/// and the Lagrange weights of the three points at l*.
fn vertex(l: [f64; 3], s: [f64; 3]) -> (f64, f64, [f64; 3]) {
    let weights = |x: f64| {
        [
            (x - l[1]) * (x - l[2]) / ((l[0] - l[1]) * (l[0] - l[2])),
            (x - l[0]) * (x - l[2]) / ((l[1] - l[0]) * (l[1] - l[2])),
            (x - l[0]) * (x - l[1]) / ((l[2] - l[0]) * (l[2] - l[1])),
        ]
    };
    // s(l) = a l² + b l + c from divided differences
    let d01 = (s[1] - s[0]) / (l[1] - l[0]);
    let d12 = (s[2] - s[1]) / (l[2] - l[1]);
    let a = (d12 - d01) / (l[2] - l[0]);
    let b = d01 - a * (l[0] + l[1]);
    let x = if a != 0.0 { -b / (2.0 * a) } else { l[1] };
    let x = x.clamp(l[0], l[2]);
    let w = weights(x);
    (x, w[0] * s[0] + w[1] * s[1] + w[2] * s[2], w)
}

/// Follows the equilibrium path of `system` from its converged state at load factor `start`
/// (the loads set there). `on_event` sees every converged point and every limit point and may
/// stop the path.
pub fn continuation<S: LoadedSystem + ?Sized>(
    system: &mut S,
    solver: &mut dyn LinearSolver,
    newton: &NewtonSettings,
    settings: &ContinuationSettings,
    start: f64,
    mut on_event: impl FnMut(&mut S, PathEvent) -> Next,
) -> Result<PathReport, PathFailure> {
    let n = system.n();
    let k = system.new_matrix();
    let mut path = Path {
        system,
        solver,
        k,
        r: vec![0.0; n],
        plus: vec![0.0; n],
        minus: vec![0.0; n],
        newton: newton.clone(),
    };
    let mut limits: Vec<LimitPoint> = Vec::new();
    let (mut points, mut iterations, mut cutbacks) = (0usize, 0usize, 0usize);
    let mut s = start;
    let fail = |points, s, iterations, limits: &Vec<LimitPoint>, reason: String| PathFailure {
        points,
        last_load: s,
        iterations,
        limits: limits.clone(),
        reason,
    };
    path.system.set_load(s);
    if let Err(e) = path.factor() {
        return Err(fail(0, s, 0, &limits, format!("at the start: {e}")));
    }
    let mut t = match path.tangent(s) {
        Ok(t) => t,
        Err(e) => return Err(fail(0, s, 0, &limits, format!("at the start: {e}"))),
    };
    let direction = if settings.direction < 0.0 { -1.0 } else { 1.0 };
    let max_ds = settings.increment.abs();
    // (Δl, ψ²) once the first step has set them; the first arc length for the floor
    let mut arc: Option<(f64, f64)> = None;
    let mut first_dl = f64::NAN;
    let mut first_ds = direction * max_ds;
    let mut arc_length = 0.0;
    // the last two accepted increments' load changes, and the last three points (arc, load,
    // snapshot) for locating limit points
    let mut last: Option<Step> = None;
    let mut position = vec![0.0; n];
    let mut recent: Vec<Near> = vec![Near {
        arc: 0.0,
        load: s,
        snapshot: path.system.snapshot(),
        position: position.clone(),
    }];
    loop {
        if let Some(reason) = super::interrupt::pending() {
            return Err(fail(points, s, iterations, &limits, reason));
        }
        if points >= settings.max_points {
            return Ok(PathReport {
                points,
                iterations,
                cutbacks,
                limits,
                end: PathEnd::MaxPoints,
            });
        }
        let saved = path.system.snapshot();
        // the predictor's load step and the constraint
        let (ds0, constraint) = match (arc, &last) {
            (Some((dl, psi2)), Some(prev)) => {
                let [t_prev, tt] = match path.dots([(&t, &prev.dx), (&t, &t)]) {
                    Ok(d) => d,
                    Err(e) => return Err(fail(points, s, iterations, &limits, e)),
                };
                let sign = if t_prev + psi2 * prev.ds >= 0.0 {
                    1.0
                } else {
                    -1.0
                };
                let norm_t = (tt + psi2).sqrt();
                let mut ds = sign * dl / norm_t;
                let mut dl = dl;
                if ds.abs() > max_ds {
                    ds = ds.signum() * max_ds;
                    dl = max_ds * norm_t;
                }
                (ds, Some((dl, psi2)))
            }
            _ => (first_ds, None),
        };
        let outcome = path.correct(s, &t, ds0, constraint);
        let step = match outcome {
            Ok(step) => step,
            Err(e) => {
                path.system.restore(&saved);
                cutbacks += 1;
                match &mut arc {
                    Some((dl, _)) => {
                        *dl = constraint.map_or(*dl, |c| c.0) * 0.5;
                        if *dl < settings.min_fraction * first_dl {
                            return Err(fail(points, s, iterations, &limits, e));
                        }
                    }
                    None => {
                        first_ds *= 0.5;
                        if first_ds.abs() < settings.min_fraction * max_ds {
                            return Err(fail(points, s, iterations, &limits, e));
                        }
                    }
                }
                continue;
            }
        };
        iterations += step.iterations;
        let mut step = step;
        let mut end = None;
        // landing on the target load when the step crossed it
        if let Some(target) = settings.target_load {
            let crossed = (s - target) * (s + step.ds - target) < 0.0 || s + step.ds == target;
            if crossed {
                let arc_state = path.system.snapshot();
                path.system.restore(&saved);
                match path.correct(s, &t, target - s, None) {
                    Ok(exact) => {
                        iterations += exact.iterations;
                        step = exact;
                    }
                    Err(_) => path.system.restore(&arc_state),
                }
                end = Some(PathEnd::TargetLoad);
            }
        }
        let inertia = match path.factor() {
            Ok(i) => i,
            Err(e) => {
                return Err(fail(points, s, iterations, &limits, e));
            }
        };
        if let Err(e) = path.system.accept() {
            return Err(fail(points, s, iterations, &limits, e));
        }
        let [dx2] = match path.dots([(&step.dx, &step.dx)]) {
            Ok(d) => d,
            Err(e) => return Err(fail(points, s, iterations, &limits, e)),
        };
        let (dl_step, psi2) = match arc {
            Some((_, psi2)) => ((dx2 + psi2 * step.ds * step.ds).sqrt(), psi2),
            None => {
                // the first step sets the scale of the load in the constraint
                let psi2 = if dx2 > 0.0 {
                    dx2 / (step.ds * step.ds)
                } else {
                    1.0
                };
                let dl = (dx2 + psi2 * step.ds * step.ds).sqrt();
                first_dl = dl;
                (dl, psi2)
            }
        };
        arc_length += dl_step;
        s += step.ds;
        points += 1;
        let stable = match inertia {
            Some(i) => i.negative <= path.system.expected_negative_pivots(),
            None => true,
        };
        // adapt the arc length to the effort of this step
        let factor = (settings.aim_iterations.max(1) as f64 / step.iterations.max(1) as f64)
            .sqrt()
            .clamp(0.5, 2.0);
        arc = Some((dl_step * factor, psi2));
        let point = PathPoint {
            index: points,
            load: s,
            arc: arc_length,
            iterations: step.iterations,
            inertia,
            stable,
        };
        position.iter_mut().zip(&step.dx).for_each(|(p, d)| *p += d);
        recent.push(Near {
            arc: arc_length,
            load: s,
            snapshot: path.system.snapshot(),
            position: position.clone(),
        });
        if recent.len() > 3 {
            recent.remove(0);
        }
        // a limit point between the last three points: the load turned back
        if let Some(prev) = &last {
            if prev.ds * step.ds < 0.0 && recent.len() == 3 {
                let here = path.system.snapshot();
                let near = path.refine_limit(recent.clone(), psi2);
                let l = [near[0].arc, near[1].arc, near[2].arc];
                let sl = [near[0].load, near[1].load, near[2].load];
                let (x, load, w) = vertex(l, sl);
                let interpolated: Vec<f64> = (0..here.len())
                    .map(|i| {
                        w[0] * near[0].snapshot[i]
                            + w[1] * near[1].snapshot[i]
                            + w[2] * near[2].snapshot[i]
                    })
                    .collect();
                path.system.restore(&interpolated);
                let limit = LimitPoint {
                    load,
                    arc: x,
                    maximum: prev.ds > 0.0,
                    near: points - 1,
                };
                let next = on_event(path.system, PathEvent::Limit(&limit));
                path.system.restore(&here);
                // the refinement factored other states: the tangent of this point again
                if let Err(e) = path.factor() {
                    return Err(fail(points, s, iterations, &limits, e));
                }
                limits.push(limit);
                if next == Next::Stop {
                    end = end.or(Some(PathEnd::Stopped));
                }
            }
        }
        if on_event(path.system, PathEvent::Point(&point)) == Next::Stop {
            end = end.or(Some(PathEnd::Stopped));
        }
        if let Some(end) = end {
            return Ok(PathReport {
                points,
                iterations,
                cutbacks,
                limits,
                end,
            });
        }
        // the tangent at the new point (K is factored there)
        t = match path.tangent(s) {
            Ok(t) => t,
            Err(e) => return Err(fail(points, s, iterations, &limits, e)),
        };
        last = Some(step);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::linear::FaerLdlt;

    /// One unknown x under the load s·f with the internal force x − x³/3 + x⁵/50 (a maximum of
    /// the load at x = 1.2 ... then a minimum): r = x − x³/3 + x⁵/50 − s.
    struct Snap {
        x: f64,
        s: f64,
    }

    fn force(x: f64) -> f64 {
        x - x.powi(3) / 3.0 + x.powi(5) / 50.0
    }

    impl crate::algebra::system::NonlinearSystem for Snap {
        fn n(&self) -> usize {
            1
        }
        fn evaluate(&mut self, r: &mut [f64], k: Option<&mut CsrMatrix>) -> Result<(), String> {
            r[0] = force(self.x) - self.s;
            if let Some(k) = k {
                k.values[0] = 1.0 - self.x * self.x + self.x.powi(4) / 10.0;
            }
            Ok(())
        }
        fn increment(&mut self, dx: &[f64], alpha: f64) {
            self.x += alpha * dx[0];
        }
        fn snapshot(&self) -> Vec<f64> {
            vec![self.x, self.s]
        }
        fn restore(&mut self, s: &[f64]) {
            self.x = s[0];
            self.s = s[1];
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
    }

    impl LoadedSystem for Snap {
        fn set_load(&mut self, s: f64) {
            self.s = s;
        }
    }

    /// The snap-through curve s = x − x³/3 + x⁵/50: every point on it, a maximum and a minimum
    /// located where ds/dx = 0 (x² = 5 ∓ √15), the unstable points exactly those between them,
    /// and the target load hit exactly.
    #[test]
    fn snap_through_curve() {
        let mut sys = Snap { x: 0.0, s: 0.0 };
        let settings = ContinuationSettings {
            increment: 0.05,
            target_load: Some(2.0),
            ..Default::default()
        };
        let mut pts = Vec::new();
        let mut limits = Vec::new();
        let report = continuation(
            &mut sys,
            &mut FaerLdlt::new(),
            &NewtonSettings::default(),
            &settings,
            0.0,
            |sys, e| {
                match e {
                    PathEvent::Point(p) => pts.push((sys.x, p.load, p.stable)),
                    PathEvent::Limit(l) => limits.push((sys.x, l.clone())),
                }
                Next::Continue
            },
        )
        .unwrap();
        assert_eq!(report.end, PathEnd::TargetLoad);
        for &(x, s, stable) in &pts {
            assert!((force(x) - s).abs() < 1e-10, "x {x} s {s}");
            // stable where the stiffness 1 − x² + x⁴/10 is positive
            assert_eq!(stable, 1.0 - x * x + x.powi(4) / 10.0 > 0.0, "x {x}");
        }
        assert!(pts.iter().any(|p| !p.2), "no unstable point");
        let (x_max, x_min) = ((5.0 - 15f64.sqrt()).sqrt(), (5.0 + 15f64.sqrt()).sqrt());
        assert_eq!(limits.len(), 2, "{limits:?}");
        assert!(limits[0].1.maximum && !limits[1].1.maximum);
        assert!((limits[0].1.load - force(x_max)).abs() < 1e-4, "{limits:?}");
        assert!((limits[1].1.load - force(x_min)).abs() < 1e-4, "{limits:?}");
        assert!((limits[0].0 - x_max).abs() < 2e-2, "{limits:?}");
        assert!((limits[1].0 - x_min).abs() < 2e-2, "{limits:?}");
        let last = pts.last().unwrap();
        assert_eq!(last.1, 2.0);
        assert!(last.0 > x_min);
    }

    /// The vertex of a parabola through three points and the interpolation weights.
    #[test]
    fn vertex_of_a_parabola() {
        let f = |l: f64| 3.0 - 2.0 * (l - 1.3).powi(2);
        let l = [0.5, 1.0, 2.0];
        let (x, s, w) = vertex(l, l.map(f));
        assert!((x - 1.3).abs() < 1e-12 && (s - 3.0).abs() < 1e-12);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!((w[0] * l[0] + w[1] * l[1] + w[2] * l[2] - x).abs() < 1e-12);
    }
}
