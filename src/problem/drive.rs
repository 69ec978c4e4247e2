//! The drive of a stage: every input that the stage prescribes, as functions of the stage time t
//! (0 at the stage's start, as Abaqus' step time) or of its load factor s = t/duration. Every
//! stage kind evaluates the same drive:
//! - the electrodes at a prescribed potential follow their waveforms in stage time (a static
//!   stage holds its own electrodes among the supports, ramped to their values at its end);
//! - the circuits' sources follow their waveforms in stage time;
//! - the charges of charge-controlled electrodes that follow a waveform or a control
//!   ([`Drive::charges`]) follow it in stage time (a static stage ramps them to their values at
//!   its end, with the dead loads);
//! - the dead loads (tractions, body and point forces, and the free charges of charge-controlled
//!   electrodes, which enter as loads on their potential equations) and each pressure follow a
//!   [`Ramp`] of their full value over the load factor;
//! - the supports (prescribed displacements and held potentials) go from their values in the
//!   stage's start state to the model's targets ([`Drive::supports`]).
//!
//! A dynamic step takes the drive at its time levels with the loads and supports held.

use super::dofs::{apply_dirichlet, Dirichlet, DofMap, FIELDS, PHI};
use super::model::Model;
use crate::waveform::Waveform;

/// A fraction of a load's full value that goes linearly from `from` at load factor 0 to `to` at
/// load factor 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ramp {
    pub from: f64,
    pub to: f64,
}

impl Ramp {
    /// On from nothing: 0 → 1.
    pub const ON: Ramp = Ramp { from: 0.0, to: 1.0 };
    /// Held at full value.
    pub const HELD: Ramp = Ramp { from: 1.0, to: 1.0 };

    /// The fraction `level` throughout.
    pub fn held_at(level: f64) -> Ramp {
        Ramp {
            from: level,
            to: level,
        }
    }

    /// The fraction at load factor `s`.
    pub fn at(&self, s: f64) -> f64 {
        self.from + s * (self.to - self.from)
    }
}

/// The electrode inputs of one stage.
#[derive(Debug, Clone, PartialEq)]
pub struct Drive {
    /// Electrodes at a prescribed potential: their nodes and their voltage (V) in stage time
    /// (a stage with its electrodes off holds them at 0 V).
    pub voltages: Vec<(Vec<usize>, Waveform)>,
    /// The source voltage (V) of each of the model's circuits (`Model::circuits` order).
    pub circuits: Vec<Waveform>,
    /// The fraction of the model's dead loads (and of the charges of charge-controlled
    /// electrodes) over the load factor.
    pub dead_loads: Ramp,
    /// Each pressure's fraction of its value over the load factor (`Model::pressures` order; a
    /// volume-controlled pressure starts at its `from`, its level is then an unknown).
    pub pressures: Vec<Ramp>,
    /// The supports: each constrained dof's value at load factor 0 and 1 (the stage's start
    /// state and the model's target); filled by [`Drive::support_from`].
    pub supports: Vec<(usize, Ramp)>,
    /// Values set while the stage runs that replace some of `voltages`' waveforms (a feedback
    /// controller's held outputs).
    pub held: HeldVoltages,
    /// The charge-controlled electrodes whose charge the drive gives (a waveform that is not
    /// constant, or a control); a constant charge is a dead load of the model instead.
    pub charges: Vec<DrivenCharge>,
}

/// A free charge that the drive gives: on the potential equation of `node` (its electrode's
/// potential unknown), `ramp.at(s) · charge(t)` at load factor s and stage time t (or at the
/// fixed time `at`).
#[derive(Debug, Clone, PartialEq)]
pub struct DrivenCharge {
    pub node: usize,
    /// The charge of the meshed part (C: the device's over the symmetry factor).
    pub charge: Waveform,
    /// A static stage ramps the charge on with its dead loads, to its waveform's value at the
    /// stage's end (`at`); stages in time hold it at its waveform (`at` = `None`).
    pub ramp: Ramp,
    pub at: Option<f64>,
}

impl DrivenCharge {
    /// The time at which the charge is read at stage time `t`.
    pub fn time(&self, t: f64) -> f64 {
        self.at.unwrap_or(t)
    }
}

/// Voltages set while a stage runs, per entry of [`Drive::voltages`]: the value that replaces
/// its waveform's from now on, if any. Clones share the values, so whoever holds a clone of the
/// drive (a time step, a projection) sees what the run sets between steps.
#[derive(Debug, Clone, Default)]
pub struct HeldVoltages(std::sync::Arc<std::sync::Mutex<Vec<Option<f64>>>>);

impl HeldVoltages {
    /// The values, `None` where the waveform applies.
    fn values(&self) -> std::sync::MutexGuard<'_, Vec<Option<f64>>> {
        // a panic elsewhere cannot leave the values half-written: take them as they are
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Holds entry `k` of the drive's voltages at `volts` (V) from now on.
    pub fn set(&self, k: usize, volts: f64) {
        let mut v = self.values();
        if v.len() <= k {
            v.resize(k + 1, None);
        }
        v[k] = Some(volts);
    }

    /// The held value of entry `k`, if any.
    pub fn get(&self, k: usize) -> Option<f64> {
        self.values().get(k).copied().flatten()
    }
}

impl PartialEq for HeldVoltages {
    fn eq(&self, other: &Self) -> bool {
        // clones share one lock: compare their values once
        std::sync::Arc::ptr_eq(&self.0, &other.0) || {
            let mine = self.values().clone();
            mine == *other.values()
        }
    }
}

impl Drive {
    /// No waveform; the dead loads and pressures of `model` at full value, its supports held
    /// at their targets (a linearised analysis about a loaded state, a dynamic stage's loads).
    pub fn held(model: &Model) -> Drive {
        Drive {
            voltages: Vec::new(),
            circuits: Vec::new(),
            dead_loads: Ramp::HELD,
            pressures: vec![Ramp::HELD; model.pressures.len()],
            supports: Vec::new(),
            held: HeldVoltages::default(),
            charges: Vec::new(),
        }
    }

    /// No waveform; the dead loads and pressures of `model` ramped on from nothing (a first
    /// static stage).
    pub fn ramped(model: &Model) -> Drive {
        Drive {
            dead_loads: Ramp::ON,
            pressures: vec![Ramp::ON; model.pressures.len()],
            ..Drive::held(model)
        }
    }

    /// Fills [`Drive::supports`]: every dof constrained by `targets` goes from its value in
    /// `start` (4 values per node) to its target.
    pub fn support_from(&mut self, start: &[f64], targets: &[Dirichlet]) {
        let mut end = start.to_vec();
        apply_dirichlet(&mut end, targets);
        self.supports.clear();
        for c in targets {
            for &n in &c.nodes {
                let d = DofMap::dof(n, c.field.index());
                self.supports.push((
                    d,
                    Ramp {
                        from: start[d],
                        to: end[d],
                    },
                ));
            }
        }
    }

    /// Sets the supports' values at load factor `s` in `state`.
    pub fn apply_supports(&self, state: &mut [f64], s: f64) {
        for &(d, r) in &self.supports {
            state[d] = r.at(s);
        }
    }

    /// Each prescribed electrode's nodes and voltage (V) at stage time `t`: its held value
    /// ([`Drive::held`]) or its waveform's.
    pub fn voltages_at(&self, t: f64) -> impl Iterator<Item = (&[usize], f64)> + '_ {
        let held = self.held.values().clone();
        self.voltages.iter().enumerate().map(move |(k, (n, w))| {
            let v = held.get(k).copied().flatten().unwrap_or_else(|| w.value(t));
            (n.as_slice(), v)
        })
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

    /// Each driven charge's node and value (C, meshed part) at stage time `t` and load factor
    /// `s`.
    pub fn charges_at(&self, t: f64, s: f64) -> Vec<(usize, f64)> {
        self.charges
            .iter()
            .map(|c| (c.node, c.ramp.at(s) * c.charge.value(c.time(t))))
            .collect()
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
            shape: crate::waveform::Shape::Ramp {
                rise_time: 2.0,
                cosine: false,
            },
            ..Waveform::constant(1e3)
        };
        let drive = Drive {
            voltages: vec![(vec![0, 2], ramp.clone())],
            circuits: vec![Waveform::constant(5.0), ramp.clone()],
            dead_loads: Ramp::HELD,
            pressures: Vec::new(),
            supports: Vec::new(),
            held: HeldVoltages::default(),
            charges: vec![
                DrivenCharge {
                    node: 1,
                    charge: ramp.scaled(1e-9),
                    ramp: Ramp::HELD,
                    at: None,
                },
                DrivenCharge {
                    node: 2,
                    charge: ramp.scaled(2e-6),
                    ramp: Ramp::ON,
                    at: Some(2.0),
                },
            ],
        };
        // a driven charge follows its waveform in time, or its ramp in the load factor
        assert_eq!(
            drive.charges_at(1.0, 0.25),
            vec![
                (1, 1e-9 * ramp.value(1.0)),
                (2, 0.25 * 2e-6 * ramp.value(2.0))
            ]
        );
        let mut state = vec![0.0; 3 * FIELDS];
        drive.apply_voltages(&mut state, 1.0);
        assert_eq!(state[PHI], ramp.value(1.0));
        assert_eq!(state[2 * FIELDS + PHI], ramp.value(1.0));
        assert_eq!(state[FIELDS + PHI], 0.0);
        assert!(ramp.value(1.0) > 0.0 && ramp.value(1.0) < 1e3);
        assert_eq!(drive.circuit_sources_at(1.0), vec![5.0, ramp.value(1.0)]);
    }

    /// A held value replaces its entry's waveform for whoever holds a clone of the drive; the
    /// other entries keep their waveforms.
    #[test]
    fn held_voltages_replace_the_waveform_in_every_clone() {
        let drive = Drive {
            voltages: vec![
                (vec![0], Waveform::constant(1.0)),
                (vec![1], Waveform::constant(2.0)),
            ],
            circuits: Vec::new(),
            dead_loads: Ramp::HELD,
            pressures: Vec::new(),
            supports: Vec::new(),
            held: HeldVoltages::default(),
            charges: Vec::new(),
        };
        let copy = drive.clone();
        assert_eq!(copy.held.get(1), None);
        drive.held.set(1, 7.5);
        let values: Vec<f64> = copy.voltages_at(0.3).map(|(_, v)| v).collect();
        assert_eq!(values, [1.0, 7.5]);
        let mut state = vec![0.0; 2 * FIELDS];
        copy.apply_voltages(&mut state, 0.0);
        assert_eq!((state[PHI], state[FIELDS + PHI]), (1.0, 7.5));
        assert_eq!(drive, copy);
    }
}
