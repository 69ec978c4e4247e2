//! The sampled controllers that set an electrode's voltage from probes (the measured outputs):
//! a PID on one probe, or an observer-based state feedback designed on a reduced model
//! ([`super::state_feedback`]); their common state, sample clock and measurement noise.
//!
//! The PID:
//! At each sample instant t_k (stage time, every `sample_time` T from the stage's start; the
//! first accepted step at or after the instant takes the sample) the controller reads the probe
//! y_k (plus Gaussian noise), forms the error e_k = r(t_k) − y_k against the set point r and
//! holds the output
//!
//! ```text
//! v_k = u_ff(t_k) + kp e_k + I_k + D_k,   u_k = min(max(v_k, lower), upper)
//! D_k = (T_f D_{k−1} − kd (y_k − y_{k−1})) / (T_f + T)   (0 at the first sample)
//! I_{k+1} = I_k + ki T e_k   unless v_k ≥ upper with e_k > 0, or v_k ≤ lower with e_k < 0
//! ```
//!
//! until the next sample (zero-order hold). The derivative acts on the measurement, not on the
//! error, so that a set-point step gives no kick; T_f (`derivative_filter`) is the time constant
//! of its first-order filter (backward difference of the filtered derivative). The integrator
//! stops while the output is saturated and the error would drive it further into the limit:
//! conditional integration, the anti-windup of Åström & Hägglund, "Advanced PID Control" (ISA,
//! 2006), chapter 3 (integrator windup).

use super::noise::gaussian;
use super::state_feedback::StateFeedback;
use crate::waveform::Waveform;
use serde::{Deserialize, Serialize};

/// A controller on an electrode, sampled at its period with a zero-order hold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Controller {
    Pid(Box<Pid>),
    StateFeedback(Box<StateFeedback>),
}

/// The settings of a PID controller on an electrode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Pid {
    /// The probe it measures (plan index) and its name.
    pub probe: usize,
    pub probe_name: String,
    /// The set point in the probe's unit, in stage time.
    pub setpoint: Waveform,
    /// Proportional (V per probe unit), integral (V per probe unit per s) and derivative
    /// (V·s per probe unit) gains, none negative.
    pub kp: f64,
    pub ki: f64,
    pub kd: f64,
    /// The sample period T (s).
    pub sample_time: f64,
    /// The output limits (V), lower < upper.
    pub lower: f64,
    pub upper: f64,
    /// Drive added to the PID output before the limits (V), in stage time.
    pub feedforward: Waveform,
    /// Standard deviation of the Gaussian measurement noise (probe unit; 0: none) and the seed
    /// of its generator.
    pub noise: f64,
    pub seed: u64,
    /// Time constant T_f (s) of the derivative's first-order filter (0: unfiltered).
    pub derivative_filter: f64,
}

/// The state of a controller between samples: what a checkpoint keeps.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControllerState {
    /// The integral term I_k (V) the next sample uses; a state feedback's integrated tracking
    /// error ξ_k (output unit·s).
    pub integral: f64,
    /// The (filtered) derivative term D of the last sample (V).
    pub derivative: f64,
    /// The last (noisy) measurement, `None` before the first sample.
    pub last_measurement: Option<f64>,
    /// The held output (V).
    pub output: f64,
    /// The next sample instant (stage time, s).
    pub next_sample: f64,
    /// The noise generator's state (SplitMix64).
    pub rng: u64,
    /// Samples taken so far.
    pub samples: u64,
    /// The state feedback's estimate ẑ of the reduced state after the last sample (empty before
    /// the first; always empty for a PID).
    pub estimate: Vec<f64>,
}

impl Controller {
    /// The state before the first sample: no integral, no measurement, no estimate; the held
    /// output at the state feedback's bias (the voltage before its first sample).
    pub fn start(&self) -> ControllerState {
        let (seed, output) = match self {
            Controller::Pid(c) => (c.seed, 0.0),
            Controller::StateFeedback(c) => (c.seed, c.design.bias_v),
        };
        ControllerState {
            integral: 0.0,
            derivative: 0.0,
            last_measurement: None,
            output,
            next_sample: 0.0,
            rng: seed,
            samples: 0,
            estimate: Vec::new(),
        }
    }

    /// The sample period (s).
    pub fn sample_time(&self) -> f64 {
        match self {
            Controller::Pid(c) => c.sample_time,
            Controller::StateFeedback(c) => c.design.sample_time,
        }
    }

    /// Whether a state at stage time `t` takes a sample: at or after the next sample instant
    /// (up to a millionth of the period, the rounding of the step times).
    pub fn due(&self, state: &ControllerState, t: f64) -> bool {
        t >= state.next_sample - 1e-6 * self.sample_time()
    }

    /// Restarts the sample clock at a stage's start: the next sample is at stage time 0.
    pub fn restart_clock(&self, state: &mut ControllerState) {
        state.next_sample = 0.0;
    }

    /// Takes the sample of the probe values `probes` (all of the plan's, by plan index) at stage
    /// time `t` and returns the output held until the next sample; the next sample instant is
    /// the first multiple of the sample time after `t`.
    pub fn sample(&self, state: &mut ControllerState, t: f64, probes: &[f64]) -> f64 {
        let u = match self {
            Controller::Pid(c) => c.law(state, t, probes[c.probe]),
            Controller::StateFeedback(c) => c.law(
                &mut state.estimate,
                &mut state.integral,
                &mut state.rng,
                state.output,
                t,
                probes,
            ),
        };
        state.output = u;
        state.samples += 1;
        let period = self.sample_time();
        let k = ((t + 1e-6 * period) / period).floor() + 1.0;
        state.next_sample = k * period;
        u
    }
}

impl Pid {
    /// The PID law on the probe value `measured` at stage time `t`: the output, with the
    /// integral, derivative and last measurement of `state` advanced.
    fn law(&self, state: &mut ControllerState, t: f64, measured: f64) -> f64 {
        let y = if self.noise > 0.0 {
            measured + self.noise * gaussian(&mut state.rng)
        } else {
            measured
        };
        let period = self.sample_time;
        let e = self.setpoint.value(t) - y;
        state.derivative = match state.last_measurement {
            Some(prev) => {
                let tf = self.derivative_filter;
                (tf * state.derivative - self.kd * (y - prev)) / (tf + period)
            }
            None => 0.0,
        };
        let v = self.feedforward.value(t) + self.kp * e + state.integral + state.derivative;
        let u = v.clamp(self.lower, self.upper);
        let winding_up = (v >= self.upper && e > 0.0) || (v <= self.lower && e < 0.0);
        if !winding_up {
            state.integral += self.ki * period * e;
        }
        state.last_measurement = Some(y);
        u
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pid(kp: f64, ki: f64, kd: f64) -> Pid {
        Pid {
            probe: 0,
            probe_name: "y".into(),
            setpoint: Waveform::constant(1.0),
            kp,
            ki,
            kd,
            sample_time: 0.1,
            lower: -10.0,
            upper: 10.0,
            feedforward: Waveform::constant(0.0),
            noise: 0.0,
            seed: 1,
            derivative_filter: 0.0,
        }
    }

    /// The output is u_ff + kp e + I + D with the integral of the errors before the sample and
    /// the derivative of the measurement; the next sample lands on the sample grid.
    #[test]
    fn the_law_adds_its_terms() {
        let c = Controller::Pid(Box::new(Pid {
            feedforward: Waveform::constant(0.5),
            ..pid(2.0, 3.0, 0.4)
        }));
        let mut s = c.start();
        assert!(c.due(&s, 0.0));
        // first sample: e = 0.75, no integral yet, no derivative
        let u0 = c.sample(&mut s, 0.0, &[0.25]);
        assert_eq!(u0, 0.5 + 2.0 * 0.75);
        assert!((s.next_sample - 0.1).abs() < 1e-15);
        assert!(!c.due(&s, 0.05));
        assert!(c.due(&s, 0.1 - 1e-12));
        // second sample: e = 0.5, I = 3·0.1·0.75, D = −0.4·(0.5 − 0.25)/0.1
        let u1 = c.sample(&mut s, 0.1, &[0.5]);
        let expected = 0.5 + 2.0 * 0.5 + 0.3 * 0.75 - 0.4 * 0.25 / 0.1;
        assert!((u1 - expected).abs() < 1e-14, "{u1} {expected}");
        assert!((s.integral - 0.3 * 1.25).abs() < 1e-15);
        // a sample taken late (at 0.27, the first step after 0.2) keeps the grid: next at 0.3
        c.sample(&mut s, 0.27, &[0.5]);
        assert!((s.next_sample - 0.3).abs() < 1e-15);
    }

    /// A set-point step gives no derivative kick: the derivative acts on the measurement.
    #[test]
    fn a_set_point_step_gives_no_derivative_kick() {
        let base = Pid {
            setpoint: Waveform::table(&[(0.0, 0.0), (0.15, 0.0), (0.1500001, 1.0)]),
            ..pid(0.0, 0.0, 5.0)
        };
        let c = Controller::Pid(Box::new(base.clone()));
        let mut s = c.start();
        for k in 0..4 {
            let u = c.sample(&mut s, k as f64 * 0.1, &[0.0]);
            assert_eq!(u, 0.0, "sample {k}");
        }
        // a measurement step does move it, through the filter when there is one
        let u = c.sample(&mut s, 0.4, &[0.1]);
        assert!((u + 5.0 * 0.1 / 0.1).abs() < 1e-12, "{u}");
        let f = Controller::Pid(Box::new(Pid {
            derivative_filter: 0.1,
            ..base
        }));
        let mut s = f.start();
        f.sample(&mut s, 0.0, &[0.0]);
        let u = f.sample(&mut s, 0.1, &[0.1]);
        assert!((u + 5.0 * 0.1 / 0.2).abs() < 1e-12, "{u}");
    }

    /// The output stays within its limits, and the integrator does not grow while the output is
    /// saturated in the direction of the error; it integrates again once the error turns.
    #[test]
    fn the_integrator_does_not_wind_up_at_a_limit() {
        let p = pid(1.0, 50.0, 0.0);
        let c = Controller::Pid(Box::new(p.clone()));
        let mut s = c.start();
        let mut frozen = None;
        for k in 0..50 {
            // the measurement stays at 0: the error 1 keeps pushing up
            let u = c.sample(&mut s, k as f64 * 0.1, &[0.0]);
            assert!((p.lower..=p.upper).contains(&u));
            if u == p.upper {
                let i = *frozen.get_or_insert(s.integral);
                assert_eq!(s.integral, i, "sample {k}");
            }
        }
        let i = frozen.expect("saturated");
        assert!(i < p.upper + 50.0 * 0.1, "{i}");
        // the error reverses: the integral comes down at once
        c.sample(&mut s, 5.0, &[2.0]);
        assert!(s.integral < i);
    }

    /// The noise is reproducible with its seed, differs with another and has about the
    /// standard deviation asked for.
    #[test]
    fn the_noise_follows_its_seed() {
        let draw = |seed: u64| {
            let mut rng = seed;
            (0..20_000).map(|_| gaussian(&mut rng)).collect::<Vec<_>>()
        };
        let (a, b, c) = (draw(7), draw(7), draw(8));
        assert_eq!(a, b);
        assert_ne!(a, c);
        let mean = a.iter().sum::<f64>() / a.len() as f64;
        let var = a.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / a.len() as f64;
        assert!(
            mean.abs() < 0.03 && (var - 1.0).abs() < 0.05,
            "{mean} {var}"
        );
        let noisy = Controller::Pid(Box::new(Pid {
            noise: 0.01,
            ..pid(1.0, 0.0, 0.0)
        }));
        let (mut s1, mut s2) = (noisy.start(), noisy.start());
        assert_eq!(
            noisy.sample(&mut s1, 0.0, &[0.5]),
            noisy.sample(&mut s2, 0.0, &[0.5])
        );
        assert_ne!(noisy.sample(&mut s1, 0.1, &[0.5]), 0.5);
    }
}
