//! The test of a static, quasi-static or continuation stage's states against circumferential
//! harmonics (`stability_harmonics = N` on an axisymmetric model): every state Newton converged to, and
//! found stable in its own (axisymmetric, harmonic 0) tangent, is tested against the harmonics
//! n = 1…N before the ramp accepts it. A state unstable against one of them is rejected like a
//! state past a limit point, so the ramp bisects its load step down to its smallest increment:
//! the onset is located between two load factors that differ by at most twice that increment.
//! There the critical harmonic (the one with the most negative eigenvalue when several lose
//! stability together) and its mode are found, and the stage either stops at the last stable
//! state or accepts the state and goes on without testing again. A continuation stage tests the
//! points of its path as they come (an infinite resolution: every unstable point is the onset).
//!
//! A clamped pre-stretched membrane that loses its in-plane tension under voltage loses stability
//! against every out-of-plane harmonic at once where its total (mechanical plus Maxwell) stress
//! vanishes; a central electrode inside a passive ring can make one harmonic n ≥ 1 go first, which
//! the axisymmetric solution alone does not show.

use super::plan::HarmonicStability;
use crate::problem::model::Model;
use crate::time::harmonic::{harmonic_inertia, harmonic_modes};
use crate::time::mass::{MassKind, NodalMass};
use crate::time::modal::{modes, Mode, ModeSettings};

/// How the reason of a state rejected by the test begins.
pub const HARMONIC_REASON: &str = "unstable against circumferential harmonic";

/// The harmonic found unstable at the located onset, with its mode.
#[derive(Debug, Clone)]
pub struct Onset {
    pub harmonic: u32,
    /// The last stable and the first unstable load factor of the ramp.
    pub stable_load: f64,
    pub load: f64,
    /// Every harmonic of 1…N unstable at `load` (empty for harmonic 0).
    pub unstable: Vec<u32>,
    /// The critical mode: the eigenvector of the harmonic tangent (potential condensed) whose
    /// eigenvalue is the most negative, in the metric of the body's mass (density 1 kg/m³ for a
    /// material without one); normalised by [`crate::time::modal`].
    pub mode: Mode,
    /// The first unstable state, as the ramp held it (for harmonic 0, the last stable one).
    pub state: Vec<f64>,
}

/// The test of one stage.
pub struct HarmonicCheck {
    settings: HarmonicStability,
    /// Steps at most this long (in load factor) locate the onset.
    resolution: f64,
    densities: Vec<f64>,
    pub onset: Option<Onset>,
}

impl HarmonicCheck {
    /// The test with `settings` for a ramp whose smallest increment is `min_increment`; the
    /// mode's metric uses `densities` (one per material, kg/m³).
    pub fn new(settings: HarmonicStability, min_increment: f64, densities: &[f64]) -> Self {
        HarmonicCheck {
            settings,
            resolution: 2.0 * min_increment,
            densities: densities
                .iter()
                .map(|&d| if d > 0.0 { d } else { 1.0 })
                .collect(),
            onset: None,
        }
    }

    /// Whether the stage ends at the onset.
    pub fn stops(&self) -> bool {
        self.settings.stop
    }

    /// The onset of a loss of stability in harmonic 0 that stopped the ramp (its own test, of
    /// the axisymmetric tangent): between the last stable load factor `from`, whose state
    /// `state` is, and `to`; the critical mode is the one nearest zero at `state`. `None` when
    /// the test found an onset of its own.
    pub fn axisymmetric_onset(
        &self,
        model: &Model,
        state: &[f64],
        from: f64,
        to: f64,
    ) -> Result<Option<Onset>, String> {
        if self.onset.is_some() {
            return Ok(None);
        }
        let metric = NodalMass::new(model, &self.densities, MassKind::Consistent);
        let settings = ModeSettings {
            count: 1,
            ..Default::default()
        };
        let solver = crate::solve::linear::SolverSettings {
            kind: crate::solve::linear::SolverKind::Direct,
            ..Default::default()
        };
        let mode = modes(model, state, &metric, &solver, &settings)
            .map_err(|e| format!("the critical mode: {e}"))?
            .into_iter()
            .next()
            .ok_or("the critical mode: no mode found")?;
        Ok(Some(Onset {
            harmonic: 0,
            stable_load: from,
            load: to,
            unstable: Vec::new(),
            mode,
            state: state.to_vec(),
        }))
    }

    /// The harmonics of 1…N against which `state` is unstable: their tangents have more
    /// negative pivots than free potential unknowns. With `all = false` the first one found.
    fn unstable(&self, model: &Model, state: &[f64], all: bool) -> Result<Vec<u32>, String> {
        let mut out = Vec::new();
        for n in 1..=self.settings.harmonics {
            let (inertia, expected) = harmonic_inertia(model, state, n)?;
            if inertia.negative > expected || inertia.zero > 0 {
                out.push(n);
                if !all {
                    break;
                }
            }
        }
        Ok(out)
    }

    /// The ramp's acceptance test of the converged `state` of the step from load factor `from`
    /// to `to` (module docs): `Err` rejects the state.
    pub fn check(
        &mut self,
        model: &Model,
        state: &[f64],
        from: f64,
        to: f64,
    ) -> Result<(), String> {
        if !self.settings.stop && self.onset.is_some() {
            return Ok(());
        }
        let located = to - from <= self.resolution;
        let unstable = self
            .unstable(model, state, located)
            .map_err(|e| format!("stability against harmonics: {e}"))?;
        let Some(&first) = unstable.first() else {
            return Ok(());
        };
        if !located {
            return Err(format!(
                "{HARMONIC_REASON} {first} (located by smaller steps)"
            ));
        }
        let metric = NodalMass::new(model, &self.densities, MassKind::Consistent);
        let mut critical: Option<Mode> = None;
        for &n in &unstable {
            let settings = ModeSettings {
                count: 2,
                shift_hz: 0.0,
                harmonic: n,
                ..Default::default()
            };
            let modes = harmonic_modes(model, state, &metric, &settings, n, &[])
                .map_err(|e| format!("the critical mode: {e}"))?;
            for m in modes {
                if critical
                    .as_ref()
                    .is_none_or(|c| m.eigenvalue < c.eigenvalue)
                {
                    critical = Some(m);
                }
            }
        }
        let mode = critical.ok_or("the critical mode: no mode found")?;
        let harmonic = mode.harmonic;
        self.onset = Some(Onset {
            harmonic,
            stable_load: from,
            load: to,
            unstable,
            mode,
            state: state.to_vec(),
        });
        if self.settings.stop {
            Err(format!(
                "{HARMONIC_REASON} {harmonic} at load factor {to:.6}"
            ))
        } else {
            Ok(())
        }
    }
}
