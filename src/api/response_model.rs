//! A model of an optimal control problem's Hessian in its knots, the start of the optimiser's
//! quasi-Newton recursion: the Gauss–Newton matrix GᵀWG of its probe-misfit terms and the exact
//! Hessian of its drive-effort terms.
//!
//! The electrostatic force grows with the square of the drive, and the actuator responds to
//! that force almost linearly and the same way at any time. So the response of a misfit's probe
//! to a knot j of a control is modelled as ∂y(t)/∂v_j ≈ 2v_j·h(t − t_j), with h the response to
//! a unit change of the squared drive at one knot, measured once by a finite difference of two
//! runs, and shifted in time to every knot. The factor 2v_j follows the drive as it changes,
//! which a response in the drive itself (a fixed G) would miss: the force's gain varies
//! several-fold along a typical optimal drive. The model only starts the recursion: the
//! correction pairs of the true gradients refine it, and the gradient is always the adjoint's.

use crate::adjoint::objective::{Finished, Objective, Reading, Term};
use crate::waveform::table_value;
use faer::Mat;

/// One control as the optimiser sees it: its variables' range, its plan stage, its knot times
/// (run clock, s) and its scale (variable = knot value / scale).
pub(super) struct Slot {
    pub first: usize,
    pub stage: usize,
    pub times: Vec<f64>,
    pub scale: f64,
}

/// The response model: B(z) = S(4 v vᵀ ∘ B_u + E)S in the scaled knots z = v/s.
pub(super) struct ResponseModel {
    /// Σ_r w_r g_r gᵣᵀ with g_r the readings' responses to each knot's squared drive.
    squared: Mat<f64>,
    /// The drive-effort terms' Hessian in the knots (exact: they are quadratic).
    effort: Mat<f64>,
    scale: Vec<f64>,
}

/// The finite-difference step of the measured response, in the scaled knots (a hundredth of
/// the bounds' range).
pub(super) const PROBE_STEP: f64 = 1e-2;

/// The knot of a control whose response is measured: the second (a whole hat, and the
/// response over nearly the whole stage), or the first of a control with fewer than three.
pub(super) fn probed_knot(slot: &Slot) -> usize {
    if slot.times.len() >= 3 {
        1
    } else {
        0
    }
}

impl ResponseModel {
    /// The model from the run at the starting knots `z0` (`base`) and, per slot, the run with
    /// its probed knot moved from `z0` to `moved` (`responses`). `None` when no misfit term
    /// reads a controlled stage and no effort term applies: nothing to model.
    pub fn new(
        objective: &Objective,
        slots: &[Slot],
        z0: &[f64],
        base: &Finished,
        responses: &[(f64, Finished)],
    ) -> Option<ResponseModel> {
        let n = z0.len();
        let misfit = |r: &Reading| matches!(objective.terms[r.term], Term::ProbeMisfit { .. });
        // the rows: the misfit readings of the controlled stages, in a fixed order
        let rows: Vec<&Reading> = base
            .readings
            .iter()
            .filter(|r| misfit(r) && slots.iter().any(|s| s.stage == r.stage))
            .collect();
        let mut g = Mat::<f64>::zeros(rows.len(), n);
        for (slot, (moved, run)) in slots.iter().zip(responses) {
            let j = probed_knot(slot);
            let (v0, v1) = (z0[slot.first + j] * slot.scale, moved * slot.scale);
            let du = v1 * v1 - v0 * v0;
            if du == 0.0 {
                continue;
            }
            let hat = if j + 1 < slot.times.len() {
                slot.times[j + 1] - slot.times[j]
            } else if j > 0 {
                slot.times[j] - slot.times[j - 1]
            } else {
                continue;
            };
            // per term: the response per unit squared drive against the lag after the knot
            let mut samples: Vec<(usize, Vec<(f64, f64)>)> = Vec::new();
            for r in base
                .readings
                .iter()
                .filter(|r| misfit(r) && r.stage == slot.stage)
            {
                let Some(m) = run
                    .readings
                    .iter()
                    .find(|q| q.term == r.term && q.step == r.step && q.stage == r.stage)
                else {
                    continue;
                };
                let at = match samples.iter().position(|(t, _)| *t == r.term) {
                    Some(at) => at,
                    None => {
                        samples.push((r.term, Vec::new()));
                        samples.len() - 1
                    }
                };
                samples[at]
                    .1
                    .push((r.time - slot.times[j], (m.value - r.value) / du));
            }
            for (_, s) in samples.iter_mut() {
                s.sort_by(|a, b| a.0.total_cmp(&b.0));
            }
            for (row, r) in rows.iter().enumerate() {
                if r.stage != slot.stage {
                    continue;
                }
                let Some((_, s)) = samples.iter().find(|(t, _)| *t == r.term) else {
                    continue;
                };
                for (k, &tk) in slot.times.iter().enumerate() {
                    g[(row, slot.first + k)] = response(s, r.time - tk, hat);
                }
            }
        }
        for (row, r) in rows.iter().enumerate() {
            let w = r.weight.max(0.0).sqrt();
            for c in 0..n {
                g[(row, c)] *= w;
            }
        }
        let squared = g.transpose() * &g;
        let mut effort = Mat::<f64>::zeros(n, n);
        let mut any_effort = false;
        for t in &objective.terms {
            let Term::DriveEffort {
                stage,
                rate,
                weight,
                ..
            } = t
            else {
                continue;
            };
            // the effort of the slot in its stage (the objective checked that it is controlled)
            for slot in slots.iter().filter(|s| s.stage == *stage) {
                for (k, w) in slot.times.windows(2).enumerate() {
                    let h = w[1] - w[0];
                    if h <= 0.0 {
                        continue;
                    }
                    let (a, b) = (slot.first + k, slot.first + k + 1);
                    let (diag, off) = if *rate {
                        (weight / h, -weight / h)
                    } else {
                        (weight * h / 3.0, weight * h / 6.0)
                    };
                    effort[(a, a)] += diag;
                    effort[(b, b)] += diag;
                    effort[(a, b)] += off;
                    effort[(b, a)] += off;
                    any_effort = true;
                }
            }
        }
        let any_misfit = (0..n).any(|i| squared[(i, i)] > 0.0);
        if !any_misfit && !any_effort {
            return None;
        }
        let mut scale = vec![1.0; n];
        for slot in slots {
            for k in 0..slot.times.len() {
                scale[slot.first + k] = slot.scale;
            }
        }
        Some(ResponseModel {
            squared,
            effort,
            scale,
        })
    }

    /// B at the scaled knots `z`.
    pub fn hessian(&self, z: &[f64]) -> Mat<f64> {
        let v: Vec<f64> = z.iter().zip(&self.scale).map(|(z, s)| z * s).collect();
        Mat::from_fn(z.len(), z.len(), |i, j| {
            self.scale[i]
                * self.scale[j]
                * (4.0 * v[i] * v[j] * self.squared[(i, j)] + self.effort[(i, j)])
        })
    }
}

/// The response `lag` after a knot, from the samples (lag, response) of the probed knot: zero a
/// hat's width `hat` or more before it (causality), linear between the samples, held after the
/// last.
fn response(samples: &[(f64, f64)], lag: f64, hat: f64) -> f64 {
    if samples.is_empty() || lag <= -hat {
        return 0.0;
    }
    let first = samples[0];
    if lag <= first.0 && first.0 > -hat {
        return first.1 * (lag + hat) / (first.0 + hat);
    }
    table_value(samples, lag)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_response_is_causal_interpolated_and_held() {
        let s = [(0.0, 1.0), (1.0, 3.0), (2.0, 2.0)];
        assert_eq!(response(&s, -1.0, 1.0), 0.0);
        assert_eq!(response(&s, -0.5, 1.0), 0.5);
        assert_eq!(response(&s, 0.5, 1.0), 2.0);
        assert_eq!(response(&s, 1.5, 1.0), 2.5);
        assert_eq!(response(&s, 7.0, 1.0), 2.0);
        assert_eq!(response(&[], 0.5, 1.0), 0.0);
    }
}
