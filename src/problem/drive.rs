//! The drive of a stage: what its electrodes are held at or fed with, as functions of the stage
//! time t (0 at the stage's start, as Abaqus' step time). Every stage kind evaluates the same
//! drive: a static stage ramps to its value at the stage's end, a quasi-static stage follows it
//! at t = s·duration of its load factor s, a dynamic step takes it at the step's time levels.
//! The dead-load-like inputs (the charges of charge-controlled electrodes, pressures, supports)
//! follow the stage's load factor in the model itself.

use super::dofs::{FIELDS, PHI};
use crate::waveform::Waveform;

/// The electrode inputs of one stage.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Drive {
    /// Electrodes at a prescribed potential: their nodes and their voltage (V) in stage time
    /// (a stage with its electrodes off holds them at 0 V).
    pub voltages: Vec<(Vec<usize>, Waveform)>,
    /// The source voltage (V) of each of the model's circuits (`Model::circuits` order).
    pub circuits: Vec<Waveform>,
}

impl Drive {
    /// No electrode follows a waveform.
    pub fn none() -> Drive {
        Drive::default()
    }

    /// Each prescribed electrode's nodes and voltage (V) at stage time `t`.
    pub fn voltages_at(&self, t: f64) -> impl Iterator<Item = (&[usize], f64)> + '_ {
        self.voltages
            .iter()
            .map(move |(n, w)| (n.as_slice(), w.value(t)))
    }

    /// Sets the potential of every prescribed electrode's nodes in `state` (4 values per node) to
    /// its voltage at stage time `t`.
    pub fn apply_voltages(&self, state: &mut [f64], t: f64) {
        for (nodes, v) in self.voltages_at(t) {
            for &node in nodes {
                state[node * FIELDS + PHI] = v;
            }
        }
    }

    /// Each circuit's source voltage (V) at stage time `t`.
    pub fn circuit_sources_at(&self, t: f64) -> Vec<f64> {
        self.circuits.iter().map(|w| w.value(t)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The electrodes' potentials and the circuits' sources follow their waveforms in stage time.
    #[test]
    fn a_drive_gives_its_waveforms_at_stage_time() {
        let ramp = Waveform {
            shape: crate::waveform::Shape::Ramp { rise_time: 2.0 },
            ..Waveform::constant(1e3)
        };
        let drive = Drive {
            voltages: vec![(vec![0, 2], ramp.clone())],
            circuits: vec![Waveform::constant(5.0), ramp.clone()],
        };
        let mut state = vec![0.0; 3 * FIELDS];
        drive.apply_voltages(&mut state, 1.0);
        assert_eq!(state[PHI], ramp.value(1.0));
        assert_eq!(state[2 * FIELDS + PHI], ramp.value(1.0));
        assert_eq!(state[FIELDS + PHI], 0.0);
        assert!(ramp.value(1.0) > 0.0 && ramp.value(1.0) < 1e3);
        assert_eq!(drive.circuit_sources_at(1.0), vec![5.0, ramp.value(1.0)]);
    }
}
