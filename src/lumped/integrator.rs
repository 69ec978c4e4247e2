//! Time integration of m ẍ + c(x) ẋ + f(x, t) = 0 by the variational midpoint rule, the scheme
//! deasim's finite element dynamics uses (docs/theory.md), here for one degree of freedom:
//!
//! ```text
//! R(x₁) = m (x₁ − x₀)/Δt − p₀ + (Δt/2) [f(x½, t½) + c(x½) (x₁ − x₀)/Δt] = 0,   x½ = (x₀ + x₁)/2
//! p₁    = 2m (x₁ − x₀)/Δt − p₀
//! ```
//!
//! Second order, symplectic for c = 0 and a time-independent f (the energy error stays bounded,
//! O(Δt²), without drift; for a linear f it is exactly conserved), and the same phase error
//! 2 arctan(ωΔt/2) per step as the FE model, so lumped and FE histories can be compared step for
//! step. Loads are evaluated at t½. The scalar equation is solved by Newton's method with the
//! tangent m/Δt + (Δt/4) k(x½) + c/2 (the small term in dc/dx is left out; the iteration then
//! converges linearly, at a rate of order |dc/dx ẋ| Δt/m).

use super::LumpedError;

/// A one-degree-of-freedom model m ẍ + c(x) ẋ + f(x, t) = 0 with f = ∂Π/∂x.
pub trait Oscillator {
    /// Mass m (kg, or 1 in dimensionless models).
    fn mass(&self) -> f64;
    /// Generalised restoring force f(x, t) = ∂Π/∂x (loads included).
    fn force(&self, x: f64, t: f64) -> Result<f64, LumpedError>;
    /// Stiffness ∂f/∂x.
    fn stiffness(&self, x: f64, t: f64) -> Result<f64, LumpedError>;
    /// Viscous coefficient c(x) ≥ 0 (force c ẋ).
    fn damping(&self, x: f64) -> Result<f64, LumpedError>;
}

/// One midpoint step from (x₀, v₀) at t over Δt; returns (x₁, v₁).
pub fn midpoint_step<O: Oscillator + ?Sized>(
    osc: &O,
    t: f64,
    dt: f64,
    x0: f64,
    v0: f64,
) -> Result<(f64, f64), LumpedError> {
    let fail = |reason: String| LumpedError::StepFailed { time: t, reason };
    let m = osc.mass();
    let p0 = m * v0;
    let tm = t + 0.5 * dt;
    let wrap = |e: LumpedError| match e {
        LumpedError::StepFailed { .. } => e,
        other => fail(other.to_string()),
    };
    // predictor: constant velocity
    let mut x1 = x0 + dt * v0;
    let xm = 0.5 * (x0 + x1);
    let tangent = m / dt
        + 0.25 * dt * osc.stiffness(xm, tm).map_err(wrap)?
        + 0.5 * osc.damping(xm).map_err(wrap)?;
    if !(tangent > 0.0 && tangent.is_finite()) {
        return Err(fail(format!(
            "the step's tangent m/Δt + Δt k/4 + c/2 = {tangent:e} is not positive: Δt too large \
             for the negative stiffness"
        )));
    }
    let scale = x0.abs().max(x1.abs()).max(dt * v0.abs());
    for _ in 0..100 {
        let xm = 0.5 * (x0 + x1);
        let vm = (x1 - x0) / dt;
        let r = m * vm - p0
            + 0.5 * dt * (osc.force(xm, tm).map_err(wrap)? + osc.damping(xm).map_err(wrap)? * vm);
        let dx = -r / tangent;
        x1 += dx;
        if !x1.is_finite() {
            return Err(fail("the step diverged".into()));
        }
        if dx.abs() <= 1e-13 * scale.max(x1.abs()) || r == 0.0 {
            let v1 = 2.0 * (x1 - x0) / dt - v0;
            return Ok((x1, v1));
        }
    }
    Err(fail(
        "Newton iteration of the midpoint step did not converge in 100 iterations".into(),
    ))
}

/// Integrates from (x₀, v₀) at t₀ to t_end with steps Δt (the last step is shortened to end at
/// t_end), calling `record(t, x, v)` at t₀ and after every step.
pub fn integrate<O, R>(
    osc: &O,
    t0: f64,
    x0: f64,
    v0: f64,
    t_end: f64,
    dt: f64,
    mut record: R,
) -> Result<(), LumpedError>
where
    O: Oscillator + ?Sized,
    R: FnMut(f64, f64, f64) -> Result<(), LumpedError>,
{
    super::check("dt", dt, dt > 0.0, "the time step must be positive (s)")?;
    super::check(
        "t_end",
        t_end,
        t_end >= t0,
        "the end time must not precede the start",
    )?;
    let (mut x, mut v) = (x0, v0);
    record(t0, x, v)?;
    // whole steps; a remainder below 1 % of Δt is merged into the last step (a tiny step would
    // lose the velocity 2(x₁ − x₀)/Δt − v₀ to cancellation)
    let span = t_end - t0;
    let mut n = (span / dt).floor() as usize;
    if span - n as f64 * dt > 0.01 * dt || (n == 0 && span > 0.0) {
        n += 1;
    }
    let mut t = t0;
    for i in 0..n {
        let t_next = if i + 1 == n {
            t_end
        } else {
            t0 + (i + 1) as f64 * dt
        };
        (x, v) = midpoint_step(osc, t, t_next - t, x, v)?;
        t = t_next;
        record(t, x, v)?;
    }
    Ok(())
}
