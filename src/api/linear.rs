//! Small-signal analyses of a scenario about its loaded state — the state at the end of the
//! static (and quasi-static) stages before the first dynamic stage: its natural modes with the
//! electrodes held at the voltages they have there, and, about a DC bias of one electrode, the
//! frequency response of its probes and its reduced state-space model. What `deasim modes`,
//! `deasim response` and `deasim reduce` compute; the loaded state is reached by a run
//! ([`run_plan`]), so that observers and a [`super::Cancel`] token work as for any run.

use super::error::Error;
use super::results::{FieldsKept, Results};
use super::simulation::{run_plan, RunOptions};
use crate::io::build::Plan;
use crate::job::linear::{
    check_linearisable, device_mass, has_branches, held_model, linear_probes, mode_symmetry_note,
    modes_of_harmonics, response_values, zero_bias_warning, ProbeMap,
};
use crate::job::plan::{ResponseMethod, StageKind};
use crate::job::state::FrequencyResponse;
use crate::job::statics::solve_static;
use crate::problem::dofs::{FIELDS, PHI};
use crate::problem::model::Model;
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::StepControl;
use crate::time::frequency::{linearise, Linearisation};
use crate::time::modal::{Mode, ModeSettings};
use crate::time::reduced::{Outputs, ReducedModel};

/// The number of stages before the first dynamic or linearised one.
fn static_count(plan: &Plan) -> usize {
    plan.stages
        .iter()
        .take_while(|s| !matches!(s.kind, StageKind::Dynamic { .. }) && !s.kind.is_linearised())
        .count()
}

/// Runs the static stages of `plan` (already cut to them), keeping the last state; a failed run
/// says that the loaded state was not reached.
fn loaded_run(plan: &Plan, options: RunOptions) -> Result<Results, Error> {
    let options = RunOptions {
        fields: FieldsKept::Last,
        out: None,
        start: None,
        ..options
    };
    run_plan(plan, options).map_err(|e| match e {
        Error::Solve { reason, results } => Error::Solve {
            reason: format!("the loaded state was not reached: {reason}"),
            results,
        },
        e => e,
    })
}

/// The state (u and Φ per node) of the last accepted step of `results`, which kept it.
fn last_state(results: &Results) -> Vec<f64> {
    results
        .fields
        .last()
        .map(|f| f.nodal.clone())
        .unwrap_or_default()
}

/// `plan` cut to the static stages its modes are taken after, once `settings` and the plan are
/// checked: it must start with a static stage and have a mass.
pub fn modes_plan(mut plan: Plan, settings: &ModeSettings) -> Result<Plan, Error> {
    if !(settings.shift_hz.is_finite() && settings.shift_hz >= 0.0) {
        return Err(Error::Refused(format!(
            "shift: expected a frequency ≥ 0 in Hz; got {}",
            settings.shift_hz
        )));
    }
    if settings.count == 0 {
        return Err(Error::Refused("count: at least one mode".into()));
    }
    let n_static = static_count(&plan);
    if n_static == 0 {
        return Err(Error::Refused(format!(
            "`{}` starts with a dynamic stage: the modes are taken about the state after the \
             static stages before the first dynamic one; add a static stage (e.g. `steps = 1`) \
             first",
            plan.name
        )));
    }
    check_linearisable(&plan).map_err(Error::Refused)?;
    plan.stages.truncate(n_static);
    Ok(plan)
}

/// The natural modes of a scenario about its loaded state.
#[derive(Debug, Clone)]
pub struct LoadedModes {
    /// The stage whose end state the modes are taken about.
    pub stage: String,
    /// Each electrode's name and its voltage (V) in that state.
    pub bias: Vec<(String, f64)>,
    /// The loaded state, `FIELDS` values per node.
    pub state: Vec<f64>,
    /// The modes, lowest (or nearest the shift) first.
    pub modes: Vec<Mode>,
    /// What the model's symmetry hides (axisymmetric, symmetric halves), if anything.
    pub note: Option<String>,
    /// The run to the loaded state.
    pub results: Results,
}

/// Runs `plan` (cut by [`modes_plan`]) to its loaded state and finds its modes there; `options`
/// give the run's observers and cancel token (its output directory and start are not used).
pub fn loaded_modes(
    plan: &Plan,
    settings: &ModeSettings,
    options: RunOptions,
) -> Result<LoadedModes, Error> {
    loaded_modes_of_harmonics(plan, settings, &[settings.harmonic], options)
}

/// [`loaded_modes`] of each circumferential harmonic of `harmonics` (axisymmetric models), in
/// that order.
pub fn loaded_modes_of_harmonics(
    plan: &Plan,
    settings: &ModeSettings,
    harmonics: &[u32],
    options: RunOptions,
) -> Result<LoadedModes, Error> {
    let results = loaded_run(plan, options)?;
    let state = last_state(&results);
    let bias = plan
        .electrodes
        .iter()
        .map(|e| (e.name.clone(), state[e.nodes[0] * FIELDS + PHI]))
        .collect();
    let modes = match modes_of_harmonics(plan, &state, settings, harmonics) {
        Ok(m) => m,
        Err(reason) => {
            return Err(Error::Solve {
                reason,
                results: Box::new(results),
            })
        }
    };
    Ok(LoadedModes {
        stage: plan
            .stages
            .last()
            .map(|s| s.name.clone())
            .unwrap_or_default(),
        bias,
        state,
        modes,
        note: mode_symmetry_note(plan),
        results,
    })
}

/// The biased state of a scenario and its linearisation, shared by the frequency response and
/// the reduced model.
pub struct Prepared {
    pub plan: Plan,
    pub model: Model,
    pub state: Vec<f64>,
    pub lin: Linearisation,
    /// The probes that are linearised (plan indices; not the energies and the largest field).
    pub probes: Vec<usize>,
    pub bias: f64,
    pub electrode: String,
    /// Set when the drive moves nothing to first order (a zero bias).
    pub warning: Option<String>,
    /// The run to the loaded state.
    pub results: Results,
    /// The loaded state (before the bias) and the run's probe values there: deflections are
    /// measured from the run's reference, which the linearisation does not know.
    loaded: Vec<f64>,
    loaded_probes: Vec<f64>,
}

impl Prepared {
    /// The linearised probes' values at the biased state as the run reports them (offset and
    /// reference included).
    pub fn offsets(&self) -> Result<Vec<f64>, String> {
        let (at_bias, at_load) = (
            self.probe_values(&self.state)?,
            self.probe_values(&self.loaded)?,
        );
        Ok(self
            .probes
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let offset = self.plan.probes[i].1.offset;
                at_bias[k] + (self.loaded_probes[i] - offset - at_load[k]) + offset
            })
            .collect())
    }

    /// The linearised probes about the biased state, deflections from the loaded state.
    fn map(&self) -> ProbeMap<'_> {
        ProbeMap {
            plan: &self.plan,
            model: &self.model,
            state: &self.state,
            reference: &self.loaded,
            probes: self.probes.clone(),
        }
    }

    /// The probes' values (offsets removed) at a state.
    pub fn probe_values(&self, s: &[f64]) -> Result<Vec<f64>, String> {
        self.map().values(s)
    }

    /// The probes' first-order change along the perturbation `dq` (`FIELDS` values per node).
    pub fn gradient(&self, dq: &[f64]) -> Result<Vec<f64>, String> {
        self.map().gradient(dq)
    }

    /// Names of the linearised probes.
    pub fn names(&self) -> Vec<String> {
        self.map().names()
    }

    /// A solve failure after the loaded state was reached, with the run's results.
    fn failed(&self, reason: String) -> Error {
        Error::Solve {
            reason,
            results: Box::new(self.results.clone()),
        }
    }

    /// The frequency response of the linearised probes per volt on the driven electrode, by a
    /// direct solve at each of `frequencies` (Hz, positive).
    pub fn frequency_response(&mut self, frequencies: &[f64]) -> Result<FrequencyResponse, Error> {
        if frequencies.is_empty() {
            return Err(Error::Refused("frequencies: at least one frequency".into()));
        }
        if let Some(f) = frequencies.iter().find(|f| !(f.is_finite() && **f > 0.0)) {
            return Err(Error::Refused(format!(
                "frequencies: expected positive values in Hz; got {f}"
            )));
        }
        let values = {
            let map = ProbeMap {
                plan: &self.plan,
                model: &self.model,
                state: &self.state,
                reference: &self.loaded,
                probes: self.probes.clone(),
            };
            response_values(
                &mut self.lin,
                &map,
                frequencies,
                ResponseMethod::Direct,
                &self.electrode,
                self.bias,
            )
        };
        let values = values.map_err(|e| self.failed(e))?;
        Ok(FrequencyResponse {
            electrode: self.electrode.clone(),
            bias: self.bias,
            frequencies: frequencies.to_vec(),
            probes: self.names().into_iter().zip(values).collect(),
            method: ResponseMethod::Direct,
            solved_by: self.lin.solved_by(),
            warning: None,
        })
    }

    /// The reduced state-space model of `modes` modes (and the static correction) from the
    /// driven electrode's voltage to the linearised probes.
    pub fn reduced_model(&self, modes: usize) -> Result<ReducedModel, Error> {
        if modes == 0 {
            return Err(Error::Refused("modes: at least one mode".into()));
        }
        let offsets = self.offsets().map_err(|e| self.failed(e))?;
        let gradient = |dq: &[f64]| self.gradient(dq);
        ReducedModel::build(
            &self.lin,
            modes,
            &self.plan.solver,
            &Outputs {
                names: self.names(),
                offsets,
                gradient: &gradient,
            },
            &self.electrode,
            self.bias,
        )
        .map_err(|e| self.failed(e))
    }
}

/// Checks `plan` for a small-signal model about a bias: it must start with a static stage, have
/// a mass and no Maxwell branches.
pub fn check_biasable(plan: &Plan) -> Result<(), Error> {
    if static_count(plan) == 0 {
        return Err(Error::Refused(format!(
            "`{}` starts with a dynamic stage: the small-signal model is taken about the state \
             after the static stages before the first dynamic one; add a static stage first",
            plan.name
        )));
    }
    check_linearisable(plan).map_err(Error::Refused)?;
    if has_branches(plan) {
        return Err(Error::Refused(
            "materials with `branches`: the small-signal model is taken after a ramp to its bias \
             that does not relax them; use a `frequency-response` stage (direct method) after a \
             static stage instead"
                .into(),
        ));
    }
    Ok(())
}

/// Runs the static stages of `plan` before the first dynamic one, ramps the driven electrode
/// (`electrode`, default: the first with a voltage) to `bias` (default: its voltage in the
/// loaded state) and linearises there. `options` give the run's observers and cancel token (its
/// output directory and start are not used).
pub fn prepare(
    mut plan: Plan,
    electrode: Option<&str>,
    bias: Option<f64>,
    options: RunOptions,
) -> Result<Prepared, Error> {
    check_biasable(&plan)?;
    let driven = match electrode {
        Some(name) => plan
            .electrodes
            .iter()
            .position(|e| e.name == name)
            .ok_or_else(|| {
                Error::Refused(format!(
                    "electrode: no electrode `{name}`; the scenario has {}",
                    plan.electrodes
                        .iter()
                        .map(|e| e.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            })?,
        None => plan
            .electrodes
            .iter()
            .position(|e| e.voltage.amplitude != 0.0 || e.voltage.offset != 0.0)
            .ok_or_else(|| {
                Error::Refused("no electrode carries a voltage; name the driven electrode".into())
            })?,
    };
    if let Some(b) = bias {
        if !b.is_finite() {
            return Err(Error::Refused(format!(
                "bias: expected a voltage in V; got {b}"
            )));
        }
    }
    let full_stages = plan.stages.clone();
    plan.stages.truncate(static_count(&plan));
    let results = loaded_run(&plan, options);
    plan.stages = full_stages;
    let results = results?;
    let loaded = last_state(&results);
    let loaded_probes = results
        .records
        .last()
        .map(|r| r.probes.clone())
        .unwrap_or_default();
    // the biased state: the driven electrode ramped to the bias from the loaded state
    let bias = bias.unwrap_or(loaded[plan.electrodes[driven].nodes[0] * FIELDS + PHI]);
    let failed = |reason: String, results: &Results| Error::Solve {
        reason,
        results: Box::new(results.clone()),
    };
    let model = held_model(&plan, &loaded, Some((driven, bias)));
    let biased = solve_static(
        &model,
        Some(loaded.clone()),
        &StepControl {
            steps: 4,
            ..Default::default()
        },
        &NewtonSettings::default(),
        |_, _| {},
    );
    if let Err(f) = biased.result {
        return Err(failed(
            format!("the bias of {bias} V was not reached: {}", f.reason),
            &results,
        ));
    }
    let state = biased.state;
    let mass = device_mass(&plan, &model);
    let lin = match linearise(
        &model,
        &state,
        &mass,
        &plan.viscosities,
        &plan.electrodes[driven].nodes,
        None,
    ) {
        Ok(lin) => lin,
        Err(e) => return Err(failed(e, &results)),
    };
    let warning =
        (!lin.drives_motion()).then(|| zero_bias_warning(&plan.electrodes[driven].name, bias));
    let probes = linear_probes(&plan);
    let electrode = plan.electrodes[driven].name.clone();
    Ok(Prepared {
        plan,
        model,
        state,
        lin,
        probes,
        bias,
        electrode,
        warning,
        results,
        loaded,
        loaded_probes,
    })
}
