//! A model of an optimal control problem's Hessian in its knots, the start of the optimiser's
//! quasi-Newton recursion: the Gauss–Newton matrix GᵀWG of its probe-misfit terms and the exact
//! Hessian of its drive-effort terms.
//!
//! The electrostatic force grows with the square of the drive, and the actuator responds to
//! that force almost linearly and the same way at any time. So each step n of a controlled
//! stage is given the input uₙ = Σ_q w_q V(τ_q)², the drive squared where the step evaluates
//! it (its midpoint for the midpoint rule; both ends, weighted 1 − γ and γ, for Newmark's
//! velocity update), and a probe read at step k responds to it through a kernel of the lag
//! alone, ∂y_k/∂uₙ = p(k − n) (a discrete linear time-invariant system in the steps). The
//! kernel is measured once by a finite difference of two runs, the control's first knot moved,
//! and a deconvolution by the change of the inputs. Then
//! ∂y_k/∂v_j = Σₙ p(k − n)·Σ_q w_q 2V(τ_q)·φ_j(τ_q), with φ_j the knot's hat: the factor 2V
//! follows the drive as it changes (the force's gain varies several-fold along a typical
//! optimal drive), and the hats carry the drive's interpolation between the knots into the
//! steps. The model only starts the recursion: the correction pairs of the true gradients
//! refine it, and the gradient is always the adjoint's.

use crate::adjoint::objective::{Finished, Objective, Reading, Term};
use crate::waveform::table_value;
use faer::Mat;

/// One control as the optimiser sees it: its variables' range, its plan stage and that stage's
/// start (run clock, s), its knot times (run clock, s), its scale (variable = knot value /
/// scale) and where in a step the stage's scheme takes the drive: (fraction of the step,
/// weight) pairs, `Scheme::drive_weights`.
pub(super) struct Slot {
    pub first: usize,
    pub stage: usize,
    pub start: f64,
    pub times: Vec<f64>,
    pub scale: f64,
    pub drive_points: Vec<(f64, f64)>,
}

/// The most steps (over all controlled stages) the model is built for: it holds a dense matrix
/// of their number squared (128 MiB at this size).
pub(super) const MOST_STEPS: usize = 4096;

/// The finite-difference step of the measured response, in the scaled knots (a hundredth of
/// the bounds' range).
pub(super) const PROBE_STEP: f64 = 1e-2;

/// The knot of every control whose response is measured: the first, whose hat reaches the
/// fewest steps (the deconvolution's pivot is its first step's input).
pub(super) const PROBED_KNOT: usize = 0;

/// The steps of one control's stage: their drive times τ (run clock, s) with their weights.
struct Steps {
    drive_times: Vec<Vec<(f64, f64)>>,
    /// The position of the slot's first input among all inputs.
    offset: usize,
}

/// The response model: B(z) = S(CᵀMC + E)S in the scaled knots z = v/s, with M = PᵀWP over
/// the steps' inputs and C(z)ₙⱼ = Σ_q w_q 2V(τ_q)φ_j(τ_q).
pub(super) struct ResponseModel {
    /// PᵀWP over all controlled steps' inputs.
    inputs: Mat<f64>,
    /// The drive-effort terms' Hessian in the knots (exact: they are quadratic).
    effort: Mat<f64>,
    scale: Vec<f64>,
    /// Per slot: its first variable, its knot times and its steps.
    slots: Vec<(usize, Vec<f64>, Steps)>,
}

/// The hats of the knots `times` at `t` (the piecewise-linear table's weights, held beyond its
/// ends): at most two (knot, weight).
fn hats(times: &[f64], t: f64) -> Vec<(usize, f64)> {
    let n = times.len();
    if n == 0 {
        return Vec::new();
    }
    if n == 1 || t <= times[0] {
        return vec![(0, 1.0)];
    }
    if t >= times[n - 1] {
        return vec![(n - 1, 1.0)];
    }
    let i = times.partition_point(|&k| k <= t);
    let w = (t - times[i - 1]) / (times[i] - times[i - 1]);
    vec![(i - 1, 1.0 - w), (i, w)]
}

/// The drive of knots `values` at `times` (run clock) at `t`.
fn drive(times: &[f64], values: &[f64], t: f64) -> f64 {
    let points: Vec<(f64, f64)> = times.iter().copied().zip(values.iter().copied()).collect();
    table_value(&points, t)
}

impl ResponseModel {
    /// The model from the run at the starting knots `z0` (`base`) and, per slot, the run with
    /// its first knot moved from `z0` to `moved` (`responses`). `None` when no misfit term
    /// reads a controlled stage and no effort term applies (nothing to model), or when the
    /// controlled stages have more than [`MOST_STEPS`] steps.
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
        // each slot's steps: the ends are the times its stage's misfit readings were taken at
        let mut total = 0;
        let mut steps = Vec::with_capacity(slots.len());
        let mut ends_of = Vec::with_capacity(slots.len());
        for slot in slots {
            let mut ends: Vec<f64> = rows
                .iter()
                .filter(|r| r.stage == slot.stage && r.time > slot.start)
                .map(|r| r.time)
                .collect();
            ends.sort_by(f64::total_cmp);
            ends.dedup();
            let drive_times = ends
                .iter()
                .enumerate()
                .map(|(k, &e)| {
                    let b = if k == 0 { slot.start } else { ends[k - 1] };
                    slot.drive_points
                        .iter()
                        .map(|&(f, w)| (b + f * (e - b), w))
                        .collect()
                })
                .collect();
            steps.push(Steps {
                drive_times,
                offset: total,
            });
            total += ends.len();
            ends_of.push(ends);
        }
        if total > MOST_STEPS {
            return None;
        }
        let values = |z: &[f64], slot: &Slot| -> Vec<f64> {
            z[slot.first..slot.first + slot.times.len()]
                .iter()
                .map(|v| v * slot.scale)
                .collect()
        };
        // P: the rows' responses to the inputs, per slot from its probe's deconvolved kernel
        let mut p = Mat::<f64>::zeros(rows.len(), total);
        for (si, (slot, (moved, run))) in slots.iter().zip(responses).enumerate() {
            let (ends, st) = (&ends_of[si], &steps[si]);
            let v0 = values(z0, slot);
            let mut v1 = v0.clone();
            v1[PROBED_KNOT] = moved * slot.scale;
            let du: Vec<f64> = st
                .drive_times
                .iter()
                .map(|points| {
                    points
                        .iter()
                        .map(|&(t, w)| {
                            w * (drive(&slot.times, &v1, t).powi(2)
                                - drive(&slot.times, &v0, t).powi(2))
                        })
                        .sum()
                })
                .collect();
            let Some(pivot) = du.iter().position(|d| *d != 0.0) else {
                continue;
            };
            // per term: the change of its reading at each step end
            let mut kernels: Vec<(usize, Vec<f64>)> = Vec::new();
            for r in base
                .readings
                .iter()
                .filter(|r| misfit(r) && r.stage == slot.stage && r.time > slot.start)
            {
                let Some(m) = run
                    .readings
                    .iter()
                    .find(|q| q.term == r.term && q.step == r.step && q.stage == r.stage)
                else {
                    continue;
                };
                let Ok(k) = ends.binary_search_by(|e| e.total_cmp(&r.time)) else {
                    continue;
                };
                let at = match kernels.iter().position(|(t, _)| *t == r.term) {
                    Some(at) => at,
                    None => {
                        kernels.push((r.term, vec![f64::NAN; ends.len()]));
                        kernels.len() - 1
                    }
                };
                kernels[at].1[k] = m.value - r.value;
            }
            // deconvolution: dy_{pivot+m} = Σᵢ du_{pivot+i} p(m − i)
            for (_, dy) in kernels.iter_mut() {
                let mut kernel = vec![0.0; ends.len() - pivot];
                for m in 0..kernel.len() {
                    let Some(d) = dy.get(pivot + m).copied().filter(|d| d.is_finite()) else {
                        kernel[m] = if m > 0 { kernel[m - 1] } else { 0.0 };
                        continue;
                    };
                    let earlier: f64 = (1..=m)
                        .take_while(|i| pivot + i < du.len())
                        .map(|i| du[pivot + i] * kernel[m - i])
                        .sum();
                    kernel[m] = (d - earlier) / du[pivot];
                }
                *dy = kernel;
            }
            for (row, r) in rows.iter().enumerate() {
                if r.stage != slot.stage {
                    continue;
                }
                let Some((_, kernel)) = kernels.iter().find(|(t, _)| *t == r.term) else {
                    continue;
                };
                let Ok(k) = ends.binary_search_by(|e| e.total_cmp(&r.time)) else {
                    continue;
                };
                for step in 0..=k {
                    p[(row, st.offset + step)] = kernel.get(k - step).copied().unwrap_or(0.0);
                }
            }
        }
        for (row, r) in rows.iter().enumerate() {
            let w = r.weight.max(0.0).sqrt();
            for c in 0..total {
                p[(row, c)] *= w;
            }
        }
        let inputs = p.transpose() * &p;
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
        let any_misfit = (0..total).any(|i| inputs[(i, i)] > 0.0);
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
            inputs,
            effort,
            scale,
            slots: slots
                .iter()
                .zip(steps)
                .map(|(s, st)| (s.first, s.times.clone(), st))
                .collect(),
        })
    }

    /// B at the scaled knots `z`.
    pub fn hessian(&self, z: &[f64]) -> Mat<f64> {
        let n = z.len();
        // C's entries: per input, its (variable, 2V(τ)φ(τ)) pairs
        let total = self.inputs.nrows();
        let mut c: Vec<Vec<(usize, f64)>> = vec![Vec::new(); total];
        for (first, times, st) in &self.slots {
            let v: Vec<f64> = (0..times.len())
                .map(|k| z[first + k] * self.scale[first + k])
                .collect();
            for (step, points) in st.drive_times.iter().enumerate() {
                let entries = &mut c[st.offset + step];
                for &(t, weight) in points {
                    let twice = 2.0 * weight * drive(times, &v, t);
                    for (k, w) in hats(times, t) {
                        match entries.iter_mut().find(|(j, _)| *j == first + k) {
                            Some(e) => e.1 += twice * w,
                            None => entries.push((first + k, twice * w)),
                        }
                    }
                }
            }
        }
        // T = M Cᵀ (inputs × variables), then CT
        let mut t = Mat::<f64>::zeros(total, n);
        for (m, entries) in c.iter().enumerate() {
            for &(j, w) in entries {
                for i in 0..total {
                    t[(i, j)] += self.inputs[(i, m)] * w;
                }
            }
        }
        let mut b = Mat::<f64>::zeros(n, n);
        for (i, entries) in c.iter().enumerate() {
            for &(j, w) in entries {
                for l in 0..n {
                    b[(j, l)] += w * t[(i, l)];
                }
            }
        }
        Mat::from_fn(n, n, |i, j| {
            self.scale[i] * self.scale[j] * (0.5 * (b[(i, j)] + b[(j, i)]) + self.effort[(i, j)])
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hats_interpolate_as_the_table_does() {
        let times = [0.0, 1.0, 3.0];
        let values = [2.0, -1.0, 5.0];
        for t in [-1.0, 0.0, 0.25, 1.0, 2.5, 3.0, 4.0] {
            let by_hats: f64 = hats(&times, t).iter().map(|(k, w)| values[*k] * w).sum();
            assert!(
                (by_hats - drive(&times, &values, t)).abs() < 1e-14,
                "at {t}"
            );
        }
        assert_eq!(hats(&times, 0.5), vec![(0, 0.5), (1, 0.5)]);
        assert_eq!(hats(&times, 9.0), vec![(2, 1.0)]);
    }
}
