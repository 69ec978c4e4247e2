//! The time history of a lumped simulation: the probes of the FE model (pad deflection,
//! capacitance, charge, largest true field) plus the mechanical energy.

use std::fmt::Write;

/// One recorded instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Time t (s).
    pub time: f64,
    /// Pad deflection x (m, positive downward, from the flat pre-stretched state).
    pub deflection: f64,
    /// Pad velocity ẋ (m/s).
    pub velocity: f64,
    /// Electrode voltage V(t) (V).
    pub voltage: f64,
    /// Capacitance of the electroded annulus (F).
    pub capacitance: f64,
    /// Charge C·V on an electrode (C).
    pub charge: f64,
    /// Largest true field V/h over the electroded annulus (V/m); h is smallest at the pad edge.
    pub max_field: f64,
    /// Mechanical energy ½ m_eff ẋ² + Π(x, V(t)) (J); constant for η = 0 and constant V.
    pub energy: f64,
}

/// Samples at t₀ and after every time step.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct History {
    pub samples: Vec<Sample>,
}

impl History {
    /// Mean deflection over [t₀, t₁] (trapezoidal rule on the samples), m.
    pub fn mean_deflection(&self, t0: f64, t1: f64) -> f64 {
        let s: Vec<&Sample> = self
            .samples
            .iter()
            .filter(|s| s.time >= t0 - 1e-12 && s.time <= t1 + 1e-12)
            .collect();
        let (mut area, mut span) = (0.0, 0.0);
        for w in s.windows(2) {
            let dt = w[1].time - w[0].time;
            area += 0.5 * dt * (w[0].deflection + w[1].deflection);
            span += dt;
        }
        if span > 0.0 {
            area / span
        } else {
            s.first().map_or(f64::NAN, |s| s.deflection)
        }
    }

    /// Largest deflection over [t₀, t₁] (m).
    pub fn max_deflection(&self, t0: f64, t1: f64) -> f64 {
        self.samples
            .iter()
            .filter(|s| s.time >= t0 - 1e-12 && s.time <= t1 + 1e-12)
            .map(|s| s.deflection)
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// CSV text with a header line (SI units).
    pub fn to_csv(&self) -> String {
        let mut out = String::from(
            "time_s,deflection_m,velocity_m_per_s,voltage_V,capacitance_F,charge_C,max_field_V_per_m,energy_J\n",
        );
        for s in &self.samples {
            let _ = writeln!(
                out,
                "{:e},{:e},{:e},{:e},{:e},{:e},{:e},{:e}",
                s.time,
                s.deflection,
                s.velocity,
                s.voltage,
                s.capacitance,
                s.charge,
                s.max_field,
                s.energy
            );
        }
        out
    }
}
