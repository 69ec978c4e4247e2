//! An observer-based state-feedback controller that sets an electrode's voltage from measured
//! probes, with the gains of a sampled LQR/Kalman design on a reduced model
//! ([`crate::time::lqr::StateFeedbackDesign`], written by `deasim reduce --lqr`).
//!
//! At each sample instant t_k (as the PID's: every sample period from the stage's start, taken by
//! the first accepted step at or after it) with the voltage u_{k−1} held since the last sample
//! and ũ = u − V_bias, the controller
//!
//! ```text
//! z̄_k = A_d ẑ_{k−1} + B_d ũ_{k−1}                 (prediction; z̄_0 = 0, the biased state)
//! ỹ_k = y_k − y_bias − D ũ_{k−1}                  (the measured outputs' change, noise added)
//! ẑ_k = z̄_k + L (ỹ_k − C z̄_k)                     (correction: the current estimator)
//! v_k = V_bias + u_ff(t_k) + N̄ r̃_k − K ẑ_k − k_I ξ_k,   r̃_k = r(t_k) − y₁_bias,
//! u_k = min(max(v_k, lower), upper),   ξ_{k+1} = ξ_k + T (ỹ₁_k − r̃_k)
//! ```
//!
//! and holds u_k until the next sample. The measurement at t_k was taken under u_{k−1}, so its
//! direct feed-through D ũ_{k−1} is known and removed. The prediction uses the output as held,
//! after the limits: an estimate fed with the saturated input stays right while the output is
//! limited, the anti-windup of an observer-based controller (Åström & Wittenmark,
//! "Computer-Controlled Systems", 3rd ed., 1997, §9.4). N̄ makes a constant set point the steady
//! state of the model; a disturbance or a model error leaves a steady error unless the design
//! has integral action (k_I ≠ 0), whose integrator ξ of the measured tracking error is held while
//! the output is limited and the error would drive it further.

use super::noise::gaussian;
use crate::time::lqr::StateFeedbackDesign;
use crate::waveform::Waveform;
use serde::{Deserialize, Serialize};

/// The settings of a state-feedback controller on an electrode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StateFeedback {
    /// The design file, as the scenario names it (for messages).
    pub model_path: String,
    /// The design: the sampled model, the gains, the bias and the output offsets.
    pub design: StateFeedbackDesign,
    /// The plan's probe index of each of the design's measured outputs, and its row in the
    /// design's outputs.
    pub probes: Vec<usize>,
    pub rows: Vec<usize>,
    /// The set point of the tracked output, in its unit, in stage time.
    pub setpoint: Waveform,
    /// The output limits (V), lower < upper.
    pub lower: f64,
    pub upper: f64,
    /// Drive added to the law's output before the limits (V), in stage time.
    pub feedforward: Waveform,
    /// Standard deviation of the tracked output's measurement noise (its unit; 0: none) and the
    /// seed of its generator; another measured output's noise is scaled by the ratio of its
    /// static gain to the tracked output's (the same noise in volts of static drive).
    pub noise: f64,
    pub seed: u64,
}

impl StateFeedback {
    /// The law on the plan's probe values `probes` at stage time `t` with the output `held`
    /// since the last sample: the new output, with the `estimate` (empty before the first
    /// sample), the `integral` of the tracking error and the noise generator's state `rng`
    /// advanced.
    pub fn law(
        &self,
        estimate: &mut Vec<f64>,
        integral: &mut f64,
        rng: &mut u64,
        held: f64,
        t: f64,
        probes: &[f64],
    ) -> f64 {
        let d = &self.design;
        let n = d.ad.len();
        let held = held - d.bias_v;
        let mut z = vec![0.0; n];
        if estimate.len() == n {
            for i in 0..n {
                z[i] = d.bd[i][0] * held + (0..n).map(|j| d.ad[i][j] * estimate[j]).sum::<f64>();
            }
        }
        // the measured outputs' change about the bias, less the feed-through of the held volts
        let measured: Vec<f64> = self
            .probes
            .iter()
            .zip(&self.rows)
            .map(|(&p, &r)| {
                let noise = if self.noise > 0.0 {
                    let scale = (d.static_gains[r] / d.static_gains[0]).abs();
                    self.noise * scale * gaussian(rng)
                } else {
                    0.0
                };
                probes[p] + noise - d.output_offsets[r] - d.d[r][0] * held
            })
            .collect();
        let innovation: Vec<f64> = measured
            .iter()
            .zip(&self.rows)
            .map(|(y, &r)| y - (0..n).map(|j| d.c[r][j] * z[j]).sum::<f64>())
            .collect();
        for i in 0..n {
            z[i] += d.l[i]
                .iter()
                .zip(&innovation)
                .map(|(l, e)| l * e)
                .sum::<f64>();
        }
        let reference = self.setpoint.value(t) - d.output_offsets[0];
        let feedback: f64 = (0..n).map(|j| d.k[0][j] * z[j]).sum();
        let v = d.bias_v + self.feedforward.value(t) + d.n_bar * reference
            - feedback
            - d.k_i * *integral;
        *estimate = z;
        // the integrator (ξ_{k+1} = ξ_k + T e_k on the measured error), held while the output is
        // limited and the error would drive it further (the PID's conditional integration)
        if d.k_i != 0.0 {
            if let Some(m) = self.rows.iter().position(|&r| r == 0) {
                let e = measured[m] - reference;
                let push = -d.k_i * e;
                let winding_up = (v >= self.upper && push > 0.0) || (v <= self.lower && push < 0.0);
                if !winding_up {
                    *integral += d.sample_time * e;
                }
            }
        }
        v.clamp(self.lower, self.upper)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::job::controller::Controller;
    use crate::time::lqr::Weights;

    /// A one-state design: A_d 0.5, B_d 2, C 3, D 0.1, K 0.25, L 0.2, N̄ 4 about 100 V, the
    /// output's offset 10.
    fn scalar(upper: f64) -> Controller {
        scalar_with(upper, 0.0)
    }

    /// [`scalar`] with the integral gain `k_i`.
    fn scalar_with(upper: f64, k_i: f64) -> Controller {
        let one = |x: f64| vec![vec![x]];
        Controller::StateFeedback(Box::new(StateFeedback {
            model_path: "lqr.json".into(),
            design: StateFeedbackDesign {
                scenario: "s".into(),
                electrode: "e".into(),
                bias_v: 100.0,
                sample_time: 0.1,
                frequencies_hz: vec![],
                outputs: vec!["y".into()],
                tracked: "y".into(),
                measured: vec!["y".into()],
                output_offsets: vec![10.0],
                static_gains: vec![1.0],
                weights: Weights {
                    q: 1.0,
                    r: 1.0,
                    w: 1.0,
                    v: 1.0,
                    qi: 0.0,
                },
                ad: one(0.5),
                bd: one(2.0),
                c: one(3.0),
                d: one(0.1),
                k: one(0.25),
                k_i,
                l: one(0.2),
                nx: vec![0.0],
                nu: 0.0,
                n_bar: 4.0,
                open_loop_radius: 0.5,
                closed_loop_radius: 0.0,
                observer_radius: 0.0,
                control_residual: 0.0,
                filter_residual: 0.0,
            },
            probes: vec![1],
            rows: vec![0],
            setpoint: Waveform::constant(11.0),
            lower: 0.0,
            upper,
            feedforward: Waveform::constant(0.0),
            noise: 0.0,
            seed: 0,
        }))
    }

    /// The first sample corrects the zero estimate by the measurement; the next predicts with
    /// the held output, removes the feed-through of the voltage the measurement was taken under,
    /// and feeds back the corrected estimate; a limited output is what the next prediction
    /// uses.
    #[test]
    fn the_law_predicts_corrects_and_feeds_back() {
        let c = scalar(1000.0);
        let mut s = c.start();
        assert_eq!(s.output, 100.0);
        // ỹ = 0.6, ẑ = 0.12, v = 100 + 4·1 − 0.25·0.12
        let u0 = c.sample(&mut s, 0.0, &[f64::NAN, 10.6]);
        assert!((s.estimate[0] - 0.12).abs() < 1e-15);
        assert!((u0 - 103.97).abs() < 1e-12, "{u0}");
        // z̄ = 0.5·0.12 + 2·3.97 = 8.0; y = 10 + 3·8 + 0.1·3.97 + 0.3 → innovation 0.3
        let y1 = 10.0 + 24.0 + 0.397 + 0.3;
        let u1 = c.sample(&mut s, 0.1, &[f64::NAN, y1]);
        assert!((s.estimate[0] - 8.06).abs() < 1e-12, "{}", s.estimate[0]);
        assert!((u1 - (104.0 - 0.25 * 8.06)).abs() < 1e-12, "{u1}");
        assert!((s.next_sample - 0.2).abs() < 1e-15);
        // limited at 101 V: the held 1 V above the bias drives the next prediction
        let limited = scalar(101.0);
        let mut s = limited.start();
        limited.sample(&mut s, 0.0, &[0.0, 10.6]);
        assert_eq!(s.output, 101.0);
        let y1 = 10.0 + 3.0 * (0.06 + 2.0) + 0.1;
        limited.sample(&mut s, 0.1, &[0.0, y1]);
        assert!((s.estimate[0] - 2.06).abs() < 1e-12, "{}", s.estimate[0]);
    }
    /// The integrator adds T times the measured error each sample and enters the output with
    /// −k_I; it holds while the output is limited and the error would push it further.
    #[test]
    fn the_integrator_integrates_the_measured_error_and_holds_at_a_limit() {
        let c = scalar_with(1000.0, -2.0);
        let mut s = c.start();
        // ỹ = 0.6 against r̃ = 1: e = −0.4, ξ = 0 for this output, then −0.04
        let u0 = c.sample(&mut s, 0.0, &[0.0, 10.6]);
        assert!((u0 - 103.97).abs() < 1e-12, "{u0}");
        assert!((s.integral + 0.04).abs() < 1e-15, "{}", s.integral);
        let y1 = 10.0 + 24.0 + 0.397 + 0.3;
        let u1 = c.sample(&mut s, 0.1, &[0.0, y1]);
        assert!(
            (u1 - (104.0 - 0.25 * 8.06 + 2.0 * -0.04)).abs() < 1e-12,
            "{u1}"
        );
        // e = 24.3 − 1: ξ grows by 0.1·23.3
        assert!(
            (s.integral - (-0.04 + 2.33)).abs() < 1e-12,
            "{}",
            s.integral
        );
        // at the upper limit with the error pushing up (−k_I e > 0 for e > 0): ξ holds
        let limited = scalar_with(101.0, -2.0);
        let mut s = limited.start();
        limited.sample(&mut s, 0.0, &[0.0, 10.6]);
        assert_eq!(s.output, 101.0);
        assert!(
            (s.integral + 0.04).abs() < 1e-15,
            "the error −0.4 pulls down: integrated"
        );
        let xi = s.integral;
        limited.sample(&mut s, 0.1, &[0.0, 40.0]);
        assert_eq!(s.output, 101.0);
        assert_eq!(s.integral, xi);
    }
}
