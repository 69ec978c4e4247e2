//! Static equilibrium of a one-degree-of-freedom model: the first upward zero crossing of the
//! generalised force f(x) = Π'(x) beyond a start point, i.e. the stable equilibrium reached by
//! loading from there.
//!
//! Safeguarded Newton: before a sign change is found, Newton steps (when the stiffness is positive)
//! are capped so that the distance from the start at most doubles per step, so that a narrow
//! window of equilibria is unlikely to be jumped over; once bracketed, Newton steps that leave the
//! bracket are replaced by bisection.

use super::LumpedError;

/// Settings of [`first_root`].
#[derive(Debug, Clone, Copy)]
pub struct Search {
    /// Start x₀ (f(x₀) < 0 expected).
    pub start: f64,
    /// Largest x searched.
    pub limit: f64,
    /// First step (and length scale of the tolerance).
    pub first_step: f64,
    /// Relative tolerance on x.
    pub tol: f64,
}

/// What [`first_root`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Root {
    /// An equilibrium at x.
    At(f64),
    /// f < 0 up to the limit (or up to where the model fails): no equilibrium.
    None { last: f64, reason: &'static str },
}

/// First x ≥ `start` where f crosses zero from below. `eval(x)` returns (f(x), f'(x)); an
/// evaluation error beyond the bracket ends the search there (the model's domain ends), inside the
/// bracket it is returned.
pub fn first_root<F>(mut eval: F, s: Search) -> Result<Root, LumpedError>
where
    F: FnMut(f64) -> Result<(f64, f64), LumpedError>,
{
    let (f0, k0) = eval(s.start)?;
    if f0 >= 0.0 {
        return Ok(Root::At(s.start));
    }
    let tol = |x: f64| s.tol * x.abs().max(s.first_step);
    let (mut lo, mut hi) = (s.start, f64::NAN);
    let mut limit = s.limit;
    // true once an evaluation failed: `limit` is then the model's domain end, approached by bisection
    let mut domain_end = false;
    let (mut x, mut f, mut k) = (s.start, f0, k0);
    for _ in 0..500 {
        let newton = if k > 0.0 { x - f / k } else { f64::NAN };
        let mut cand = if hi.is_nan() {
            let cap = lo + (lo - s.start).max(s.first_step);
            if newton > lo {
                newton.min(cap)
            } else {
                cap
            }
        } else if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if cand >= limit {
            if limit - lo <= tol(limit) {
                return Ok(Root::None {
                    last: lo,
                    reason: if domain_end {
                        "the model fails (material domain) before an equilibrium"
                    } else {
                        "the force stays negative up to the search limit"
                    },
                });
            }
            cand = if domain_end {
                0.5 * (lo + limit)
            } else {
                limit
            };
        }
        let step = (cand - x).abs();
        let (fc, kc) = match eval(cand) {
            Ok(v) => v,
            Err(e) => {
                if hi.is_nan() {
                    // the model's domain ends before cand: search below it
                    limit = cand;
                    domain_end = true;
                    x = lo;
                    f = f64::NAN;
                    k = f64::NAN;
                    continue;
                }
                return Err(e);
            }
        };
        if fc < 0.0 {
            lo = cand;
        } else {
            hi = cand;
        }
        if fc == 0.0 || (!hi.is_nan() && (hi - lo <= tol(cand) || (step <= tol(cand) && kc > 0.0)))
        {
            return Ok(Root::At(cand));
        }
        (x, f, k) = (cand, fc, kc);
    }
    Err(LumpedError::NoEquilibrium {
        load: f64::NAN,
        reason: "equilibrium search did not converge in 500 steps".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn search(limit: f64) -> Search {
        Search {
            start: 0.0,
            limit,
            first_step: 1e-3,
            tol: 1e-13,
        }
    }

    /// f = x³ − 3x² + 2.5x − 0.1 (roots ≈ 0.0433 (up), …): the first upward crossing is found;
    /// a function negative everywhere gives None; a domain error ends the search.
    #[test]
    fn lumped_first_root_finds_the_first_upward_crossing() {
        let f = |x: f64| {
            Ok((
                x * x * x - 3.0 * x * x + 2.5 * x - 0.1,
                3.0 * x * x - 6.0 * x + 2.5,
            ))
        };
        let Root::At(r) = first_root(f, search(10.0)).unwrap() else {
            panic!("no root")
        };
        assert!(
            (r * r * r - 3.0 * r * r + 2.5 * r - 0.1).abs() < 1e-13,
            "{r}"
        );
        assert!(r < 0.1, "{r}");
        // x² − 1 − 0.5 x⁴/… : negative f everywhere below the limit
        let g = |x: f64| Ok((-1.0 - x * x, -2.0 * x));
        assert!(matches!(
            first_root(g, search(5.0)).unwrap(),
            Root::None { .. }
        ));
        // a (tanh-like) force that only turns positive beyond a domain end at x = 2
        let h = |x: f64| {
            if x > 2.0 {
                Err(LumpedError::StepFailed {
                    time: 0.0,
                    reason: "domain".into(),
                })
            } else {
                Ok((x - 3.0, 1.0))
            }
        };
        assert!(matches!(
            first_root(h, search(10.0)).unwrap(),
            Root::None { .. }
        ));
    }
}
