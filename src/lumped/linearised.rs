//! The linearised diaphragm: m_eff ξ̈ + c ξ̇ + k ξ = β V(t)², ξ = x − x₀ measured from the static
//! equilibrium x₀ at V = 0 with gravity: the form of the experimental study (docs/lumped.md), with
//! its coefficients derived from the Ritz model instead of fitted. β = ½ dC/dx at x₀ is the
//! voltage-dependent part of −Π' (the electrostatic force per V²); the softening of k by the
//! voltage (−½V² C'') is left out, as in the study's form.

use std::f64::consts::PI;
use std::fmt;

use super::history::{History, Sample};
use super::integrator::{integrate, Oscillator};
use super::{check, LumpedError};
use crate::waveform::Waveform;

/// Coefficients of the linearised model (SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Linearised {
    /// Static deflection x₀ at V = 0 under gravity (m).
    pub equilibrium: f64,
    /// Effective mass m_eff (kg).
    pub mass: f64,
    /// Viscous coefficient c (N·s/m).
    pub damping: f64,
    /// Stiffness k = Π''(x₀, 0) (N/m).
    pub stiffness: f64,
    /// β = ½ C'(x₀) (N/V²): F(t) = β V(t)².
    pub force_per_volt2: f64,
    /// Capacitance C(x₀) (F).
    pub capacitance: f64,
    /// Smallest electroded thickness at x₀ (m), for the field V/h.
    pub min_thickness: f64,
}

impl Linearised {
    /// Undamped natural frequency √(k/m)/2π (Hz).
    pub fn natural_frequency(&self) -> f64 {
        (self.stiffness / self.mass).sqrt() / (2.0 * PI)
    }

    /// Damping ratio ζ = c/(2√(km)).
    pub fn damping_ratio(&self) -> f64 {
        self.damping / (2.0 * (self.stiffness * self.mass).sqrt())
    }

    /// Electrostatic force F = β V² (N).
    pub fn force(&self, voltage: f64) -> f64 {
        self.force_per_volt2 * voltage * voltage
    }

    /// Static deflection x₀ + βV²/k (m).
    pub fn static_deflection(&self, voltage: f64) -> f64 {
        self.equilibrium + self.force(voltage) / self.stiffness
    }

    /// Integrates the linear model from rest at its static state under V(0) (midpoint rule, the
    /// same integrator as the nonlinear model). Deflections in the history are x₀ + ξ.
    pub fn simulate(
        &self,
        waveform: &Waveform,
        t_end: f64,
        dt: f64,
    ) -> Result<History, LumpedError> {
        check("t_end", t_end, t_end >= 0.0, "must be ≥ 0 (s)")?;
        check("dt", dt, dt > 0.0, "must be > 0 (s)")?;
        check(
            "stiffness",
            self.stiffness,
            self.stiffness > 0.0 && self.mass > 0.0,
            "the linearised stiffness and mass must be > 0",
        )?;
        let driven = DrivenLinear {
            model: self,
            waveform,
        };
        let xi0 = self.force(waveform.value(0.0)) / self.stiffness;
        let mut history = History::default();
        integrate(&driven, 0.0, xi0, 0.0, t_end, dt, |t, xi, v| {
            let voltage = waveform.value(t);
            let cap = self.capacitance + 2.0 * self.force_per_volt2 * xi;
            history.samples.push(Sample {
                time: t,
                deflection: self.equilibrium + xi,
                velocity: v,
                voltage,
                capacitance: cap,
                charge: cap * voltage,
                max_field: voltage.abs() / self.min_thickness,
                energy: 0.5 * self.mass * v * v + 0.5 * self.stiffness * xi * xi
                    - self.force(voltage) * xi,
            });
            Ok(())
        })?;
        Ok(history)
    }
}

impl fmt::Display for Linearised {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "linearised about x0 = {:.6e} m (V = 0, gravity):",
            self.equilibrium
        )?;
        writeln!(f, "  m_eff = {:.6e} kg", self.mass)?;
        writeln!(
            f,
            "  c     = {:.6e} N s/m (zeta = {:.4e})",
            self.damping,
            self.damping_ratio()
        )?;
        writeln!(
            f,
            "  k     = {:.6e} N/m (f_n = {:.4} Hz)",
            self.stiffness,
            self.natural_frequency()
        )?;
        writeln!(
            f,
            "  F(t)  = beta V(t)^2, beta = {:.6e} N/V^2",
            self.force_per_volt2
        )?;
        write!(
            f,
            "  C(x0) = {:.6e} F, h_min = {:.6e} m",
            self.capacitance, self.min_thickness
        )
    }
}

struct DrivenLinear<'a> {
    model: &'a Linearised,
    waveform: &'a Waveform,
}

impl Oscillator for DrivenLinear<'_> {
    fn mass(&self) -> f64 {
        self.model.mass
    }
    fn force(&self, xi: f64, t: f64) -> Result<f64, LumpedError> {
        Ok(self.model.stiffness * xi - self.model.force(self.waveform.value(t)))
    }
    fn stiffness(&self, _xi: f64, _t: f64) -> Result<f64, LumpedError> {
        Ok(self.model.stiffness)
    }
    fn damping(&self, _xi: f64) -> Result<f64, LumpedError> {
        Ok(self.model.damping)
    }
}
