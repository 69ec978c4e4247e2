//! Electrodes driven by a source through a series resistance R: R dQ/dt = V_s(t) − V_e, with Q
//! the electrode's free charge and V_e its potential (one unknown shared by its nodes).
//!
//! In a time step the charge enters Gauss's law of the electrode, ∂Π/∂Φ_e + Q = 0, at the
//! integrator's evaluation point, integrated consistently with it:
//! - midpoint: Q at t_{n+½} is Q_n + Δt/(2R)(V_s(t_{n+½}) − V_{n+½}) and
//!   Q_{n+1} = Q_n + Δt/R (V_s(t_{n+½}) − V_{n+½}) (the midpoint rule of the circuit equation);
//! - Newmark (Gauss's law at t_{n+1}): Q_{n+1} = Q_n + Δt/(2R)(V_s,n − V_n + V_s,n+1 − V_{n+1})
//!   (the trapezoidal rule, second order like the average-acceleration scheme).
//!
//! In static stages the circuit carries no current: the electrode is at the source's voltage.

/// A circuit-driven electrode of the meshed part.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Circuit {
    /// The electrode's nodes; the first one's potential is the tied unknown.
    pub nodes: Vec<usize>,
    /// Series resistance seen by the meshed part (Ω): the device's times the symmetry factor,
    /// as the part carries that fraction of the current through the same voltage drop.
    pub resistance: f64,
}

/// One circuit over one time step: its charge and potential at the start and the source at
/// t_n, t_{n+½} and t_{n+1}.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircuitStep {
    pub charge: f64,
    pub voltage: f64,
    pub source: [f64; 3],
}

impl CircuitStep {
    /// The charge at the evaluation point and its derivative with respect to the potential
    /// there (`v_eval`: the midpoint potential for the midpoint rule, V_{n+1} for Newmark).
    pub fn charge_at(&self, midpoint: bool, dt: f64, resistance: f64, v_eval: f64) -> (f64, f64) {
        let g = dt / (2.0 * resistance);
        if midpoint {
            (self.charge + g * (self.source[1] - v_eval), -g)
        } else {
            let drop = self.source[0] - self.voltage + self.source[2] - v_eval;
            (self.charge + g * drop, -g)
        }
    }

    /// The charge at t_{n+1} of the converged step (`v_eval` as in [`CircuitStep::charge_at`]).
    pub fn end_charge(&self, midpoint: bool, dt: f64, resistance: f64, v_eval: f64) -> f64 {
        if midpoint {
            self.charge + dt / resistance * (self.source[1] - v_eval)
        } else {
            self.charge_at(false, dt, resistance, v_eval).0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a fixed capacitor C (Q = C·V) both rules reproduce the exact charging curve
    /// V_s(1 − e^{−t/RC}) to second order: the error falls 4× when Δt halves; and the derivative
    /// of the charge matches a finite difference.
    #[test]
    fn rc_charging_is_second_order() {
        let (r, c, vs) = (1e3, 1e-6, 10.0);
        let tau = r * c;
        for midpoint in [true, false] {
            let mut errors = Vec::new();
            for steps in [50usize, 100] {
                let dt = 2.0 * tau / steps as f64;
                let (mut q, mut v) = (0.0, 0.0);
                for _ in 0..steps {
                    let st = CircuitStep {
                        charge: q,
                        voltage: v,
                        source: [vs; 3],
                    };
                    // Gauss's law Q = C·V at the evaluation point (linear in V_eval), then the
                    // potential at t_{n+1} from the end charge (the projection)
                    let (q0, dq) = st.charge_at(midpoint, dt, r, 0.0);
                    let v_eval = q0 / (c - dq);
                    q = st.end_charge(midpoint, dt, r, v_eval);
                    v = q / c;
                }
                let exact = vs * (1.0 - (-2.0f64).exp());
                errors.push((v - exact).abs() / vs);
            }
            let ratio = errors[0] / errors[1];
            assert!((ratio - 4.0).abs() < 0.1, "midpoint {midpoint}: {errors:?}");
            assert!(errors[1] < 1e-4, "{errors:?}");
        }
        let st = CircuitStep {
            charge: 1e-6,
            voltage: 3.0,
            source: [5.0, 6.0, 7.0],
        };
        for midpoint in [true, false] {
            let (_, dq) = st.charge_at(midpoint, 1e-3, r, 4.0);
            let h = 1e-6;
            let fd = (st.charge_at(midpoint, 1e-3, r, 4.0 + h).0
                - st.charge_at(midpoint, 1e-3, r, 4.0 - h).0)
                / (2.0 * h);
            assert!((dq - fd).abs() < 1e-9 * dq.abs(), "{dq} vs {fd}");
        }
    }
}
