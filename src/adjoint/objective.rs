//! The objective J of a gradient: the sum of the scenario's `[[objective]]` terms, each a function
//! of the states of the accepted steps of one stage.

use super::tape::{Tape, TapedStep};
use crate::io::scenario::{InputError, ObjectiveSpec, Scenario, VoltageSpec};
use crate::job::plan::Plan;
use crate::job::probes::{Probe, ProbeInput, ProbeKind};
use crate::problem::field_penalty::field_penalty;
use crate::problem::points::PointStates;
use crate::time::mass::NodalMass;
use std::path::Path;

/// One term of J.
#[derive(Debug, Clone, PartialEq)]
pub enum Term {
    /// ½ · weight · (probe at the stage's end − target)²; `relative`: the probe's value less
    /// its value at the stage's start.
    ProbeFinal {
        probe: usize,
        stage: usize,
        target: f64,
        weight: f64,
        relative: bool,
        /// The taped step read instead of the stage's last (a single residual of a misfit, as
        /// a device calibration differentiates them one by one).
        step: Option<usize>,
    },
    /// ½ · weight · Σₖ (probe(tₖ) − target(tₖ))² over the stage's accepted steps k (its start
    /// state excluded); `relative` as for [`Term::ProbeFinal`].
    ProbeMisfit {
        probe: usize,
        stage: usize,
        target: Target,
        weight: f64,
        relative: bool,
    },
    /// ½ · weight · ∫ V² dt (`rate`: ∫ (dV/dt)² dt) over a stage of a controlled electrode's
    /// piecewise-linear voltage: exact for the table, a sum over its intervals.
    DriveEffort {
        /// The stage and the electrode's name (a control of that stage).
        stage: usize,
        electrode: String,
        rate: bool,
        weight: f64,
    },
    /// weight · ½ vᵀMv: the kinetic energy at the end of a dynamic stage.
    Rest { stage: usize, weight: f64 },
    /// weight · Σₖ ½ ∫ max(0, |E| − limit)² dV over the stage's accepted steps k (its start state
    /// excluded), the true field at every quadrature point, the whole device's volume
    /// ([`crate::problem::field_penalty`]).
    FieldPenalty {
        stage: usize,
        limit: f64,
        weight: f64,
    },
}

/// The target history of a misfit term.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// `time,value` data in the run's clock (s), interpolated linearly.
    Data(Vec<(f64, f64)>),
    /// A waveform of stage time; the stage starts at `start` in the run's clock (s).
    Waveform {
        waveform: crate::waveform::Waveform,
        start: f64,
    },
}

impl Target {
    /// The target at time `t` of the run's clock.
    pub fn at(&self, t: f64) -> f64 {
        match self {
            Target::Data(d) => interpolate(d, t),
            Target::Waveform { waveform, start } => waveform.value(t - start),
        }
    }
}

/// J: the sum of its terms.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Objective {
    pub terms: Vec<Term>,
}

/// A probe's value as a term of J read it: ½·weight·(value − target)² is its share of J.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading {
    /// The term's index, its stage (in the plan) and the taped step.
    pub term: usize,
    pub stage: usize,
    pub step: usize,
    /// The run's clock (s).
    pub time: f64,
    /// The probe's value (less its value at the stage's start for a relative term).
    pub value: f64,
    pub target: f64,
    pub weight: f64,
}

impl Objective {
    /// The terms of `s.objective` (scenario file `file`, data paths relative to `base`), checked
    /// against `plan`: the probes and stages must exist, the probes must read nodal values, the
    /// data must be a `time,value` CSV whose times increase and cover the stage.
    pub fn build(
        s: &Scenario,
        plan: &Plan,
        file: &str,
        base: Option<&Path>,
    ) -> Result<Objective, InputError> {
        let mut terms = Vec::new();
        if s.objective.is_empty() {
            return Err(InputError::at_key(
                file,
                "objective",
                "a gradient needs at least one [[objective]] term (kind = \"probe-final\" or \
                 \"probe-misfit\")",
            ));
        }
        for (i, o) in s.objective.iter().enumerate() {
            let key = |k: &str| format!("objective.{i}.{k}");
            terms.push(term(o, plan, file, base, &key)?);
        }
        Ok(Objective { terms })
    }
}

/// What J takes from one taped step: ∂J/∂x, ∂J/∂v (empty where J does not read them) and
/// ∂J/∂Q of each electrode's charge there (empty where J reads no charge).
#[derive(Debug, Clone, Default)]
pub struct StepRead {
    pub state: Vec<f64>,
    pub velocity: Vec<f64>,
    pub charges: Vec<f64>,
}

/// A probe's derivative at a step: in the state, or in electrode `.0`'s charge (`.1`: dvalue/dQ).
enum ProbeDerivative {
    State(Vec<f64>),
    Charge(usize, f64),
}

/// What a term read at one step: the probe's value (or the field penalty, or 2 × the kinetic
/// energy), the target there and the run's clock (s).
#[derive(Debug, Clone, Copy)]
struct Read {
    step: usize,
    value: f64,
    target: f64,
    time: f64,
}

/// J read from the run's last accepted step back to its first, as the adjoint sweep meets them:
/// each step's ∂J/∂x and ∂J/∂v from that step's state alone ([`Backward::at_step`]), and J, the
/// derivative in the reference state and the readings at the end ([`Backward::finish`]) from the
/// scalars kept per step. Every sum runs in the order of the terms and, within a term, of the
/// steps (forwards), so that J and its derivatives are the same numbers whether the states are
/// all held or recomputed from checkpoints. Needs of each stage only its step count and its
/// last step (the start of the next stage's relative terms).
pub struct Backward<'a> {
    objective: &'a Objective,
    plan: &'a Plan,
    /// Accepted steps of each taped stage.
    counts: Vec<usize>,
    /// The taped stage each term reads (`None`: a drive effort).
    stages: Vec<Option<usize>>,
    /// Each probe term's value at its stage's start (0 unless relative), and its gradient there.
    v0: Vec<f64>,
    reference_state: Vec<f64>,
    /// What each term read, from the last step back.
    reads: Vec<Vec<Read>>,
    /// The nodal mass of the stage of each `rest` term.
    masses: Vec<Option<NodalMass>>,
}

/// J, ∂J/∂(the reference state), ∂J/∂(the controls' knots) and the readings of a run.
pub struct Finished {
    pub value: f64,
    pub reference: Vec<f64>,
    pub controls: Vec<Vec<f64>>,
    pub readings: Vec<Reading>,
}

impl<'a> Backward<'a> {
    /// The reader of `objective` over the run `tape` holds (its stages' step counts and last
    /// steps).
    pub fn new(objective: &'a Objective, plan: &'a Plan, tape: &Tape) -> Result<Self, String> {
        let n = plan.model.mesh.n_nodes() * crate::problem::dofs::FIELDS;
        let reference_state = tape.reference_state(n);
        let counts: Vec<usize> = tape.stages.iter().map(|s| s.count()).collect();
        let mut stages = Vec::with_capacity(objective.terms.len());
        let mut v0 = Vec::with_capacity(objective.terms.len());
        let mut masses = Vec::with_capacity(objective.terms.len());
        for t in &objective.terms {
            let stage = match t {
                Term::DriveEffort { .. } => {
                    stages.push(None);
                    v0.push(0.0);
                    masses.push(None);
                    continue;
                }
                Term::ProbeFinal { stage, .. }
                | Term::ProbeMisfit { stage, .. }
                | Term::Rest { stage, .. }
                | Term::FieldPenalty { stage, .. } => *stage,
            };
            let Some(si) = tape.stages.iter().position(|st| st.index == stage) else {
                return Err(format!(
                    "the objective reads stage `{}`, which the run did not reach",
                    plan.stages[stage].name
                ));
            };
            masses.push(match t {
                Term::Rest { .. } => match &tape.stages[si].dynamics {
                    Some(d) => Some(d.mass.clone()),
                    None => {
                        return Err(format!(
                            "stage `{}` is no dynamic stage",
                            plan.stages[stage].name
                        ))
                    }
                },
                _ => None,
            });
            let start = match t {
                Term::ProbeFinal {
                    probe,
                    relative: true,
                    ..
                }
                | Term::ProbeMisfit {
                    probe,
                    relative: true,
                    ..
                } => {
                    // the state the previous taped stage ended at, or the reference state
                    // (pre-stretched, or the undeformed one) before the first
                    let x = match si {
                        0 => &reference_state,
                        _ => &tape.stages[si - 1].last_step().state,
                    };
                    nodal_value(&plan.probes[*probe].1, x, &reference_state)
                }
                _ => 0.0,
            };
            stages.push(Some(si));
            v0.push(start);
        }
        Ok(Backward {
            objective,
            plan,
            counts,
            stages,
            v0,
            reference_state,
            reads: vec![Vec::new(); objective.terms.len()],
            masses,
        })
    }

    /// The value and state gradient of the probe of term `ti` at `x`.
    fn probe_at(&self, probe: usize, x: &[f64]) -> Result<(f64, Vec<f64>), String> {
        let (name, p) = &self.plan.probes[probe];
        let g = p
            .state_gradient(x)
            .ok_or_else(|| format!("the probe `{name}` has no derivative in the state"))?;
        Ok((nodal_value(p, x, &self.reference_state), g))
    }

    /// −Σ weight · r over the readings of relative probe term `ti` (forwards): dJ/d(its probe at
    /// the stage's start).
    fn start_derivative(&self, ti: usize) -> f64 {
        let weight = match &self.objective.terms[ti] {
            Term::ProbeFinal { weight, .. } | Term::ProbeMisfit { weight, .. } => *weight,
            _ => return 0.0,
        };
        let mut start = 0.0;
        for r in self.reads[ti].iter().rev() {
            start -= weight * (r.value - self.v0[ti] - r.target);
        }
        start
    }

    /// The value of probe `probe` at taped step `step` and its derivative: in the state, or,
    /// for an electrode's charge, in that charge (which [`super::charge::charge_adjoint`]
    /// takes further).
    fn read_probe(&self, probe: usize, step: &TapedStep) -> Result<(f64, ProbeDerivative), String> {
        let p = &self.plan.probes[probe].1;
        let Some(e) = charge_of(p) else {
            let (v, g) = self.probe_at(probe, &step.state)?;
            return Ok((v, ProbeDerivative::State(g)));
        };
        let model = &self.plan.model;
        let points = PointStates::from_data(model, &step.points);
        let nodes = [self.plan.electrodes[e].nodes.as_slice()];
        let q = super::charge::charges(model, &nodes, &step.state, &points)?[0];
        let (n, symmetry) = (self.plan.electrodes.len(), self.plan.symmetry_factor);
        let value = charge_value(p, e, n, q, symmetry);
        // the probe is affine in the charge: its slope from two values
        let slope = charge_value(p, e, n, 1.0, symmetry) - charge_value(p, e, n, 0.0, symmetry);
        Ok((value, ProbeDerivative::Charge(e, slope)))
    }

    /// What J takes from step `k` of taped stage `si`, whose record is `step`; called for
    /// every step from the run's last to its first.
    pub fn at_step(&mut self, si: usize, k: usize, step: &TapedStep) -> Result<StepRead, String> {
        let last = self.counts[si] - 1;
        let mut slot: Vec<f64> = Vec::new();
        let mut vslot: Vec<f64> = Vec::new();
        let mut charges: Vec<f64> = Vec::new();
        let n_electrodes = self.plan.electrodes.len();
        let mut take = |slot: &mut Vec<f64>, d: ProbeDerivative, factor: f64| match d {
            ProbeDerivative::State(g) => {
                if slot.is_empty() {
                    slot.resize(g.len(), 0.0);
                }
                slot.iter_mut().zip(&g).for_each(|(s, v)| *s += factor * v);
            }
            ProbeDerivative::Charge(e, slope) => {
                charges.resize(n_electrodes, 0.0);
                charges[e] += factor * slope;
            }
        };
        let add = |slot: &mut Vec<f64>, g: &[f64], factor: f64| {
            if slot.is_empty() {
                slot.resize(g.len(), 0.0);
            }
            slot.iter_mut().zip(g).for_each(|(s, v)| *s += factor * v);
        };
        for ti in 0..self.objective.terms.len() {
            let here = self.stages[ti] == Some(si);
            match &self.objective.terms[ti] {
                Term::DriveEffort { .. } => {}
                Term::FieldPenalty { limit, weight, .. } => {
                    if here {
                        let factor = weight * self.plan.symmetry_factor;
                        let mut g = vec![0.0; step.state.len()];
                        let value =
                            field_penalty(&self.plan.model, &step.state, *limit, Some(&mut g))?;
                        self.reads[ti].push(Read {
                            step: k,
                            value,
                            target: 0.0,
                            time: step.time,
                        });
                        add(&mut slot, &g, factor);
                    }
                }
                Term::Rest { weight, .. } => {
                    if here && k == last {
                        let v = &step.v;
                        let mut mv = vec![0.0; v.len()];
                        if let Some(m) = &self.masses[ti] {
                            m.mul(v, &mut mv);
                        }
                        let value = v.iter().zip(&mv).map(|(a, b)| a * b).sum::<f64>();
                        self.reads[ti].push(Read {
                            step: k,
                            value,
                            target: 0.0,
                            time: step.time,
                        });
                        if vslot.is_empty() {
                            vslot.resize(v.len(), 0.0);
                        }
                        vslot
                            .iter_mut()
                            .zip(&mv)
                            .for_each(|(s, m)| *s += weight * m);
                    }
                }
                Term::ProbeFinal {
                    probe,
                    target,
                    weight,
                    relative,
                    step: chosen,
                    ..
                } => {
                    if here && k == chosen.unwrap_or(last).min(last) {
                        let (v, d) = self.read_probe(*probe, step)?;
                        let r = v - self.v0[ti] - target;
                        self.reads[ti].push(Read {
                            step: k,
                            value: v,
                            target: *target,
                            time: step.time,
                        });
                        take(&mut slot, d, weight * r);
                    } else if *relative && self.stages[ti] == Some(si + 1) && k == last {
                        let start = self.start_derivative(ti);
                        if start != 0.0 {
                            let (_, g0) = self.probe_at(*probe, &step.state)?;
                            add(&mut slot, &g0, start);
                        }
                    }
                }
                Term::ProbeMisfit {
                    probe,
                    target,
                    weight,
                    relative,
                    ..
                } => {
                    if here {
                        let (v, d) = self.read_probe(*probe, step)?;
                        let target = target.at(step.time);
                        let r = v - self.v0[ti] - target;
                        self.reads[ti].push(Read {
                            step: k,
                            value: v,
                            target,
                            time: step.time,
                        });
                        take(&mut slot, d, weight * r);
                    } else if *relative && self.stages[ti] == Some(si + 1) && k == last {
                        let start = self.start_derivative(ti);
                        if start != 0.0 {
                            let (_, g0) = self.probe_at(*probe, &step.state)?;
                            add(&mut slot, &g0, start);
                        }
                    }
                }
            }
        }
        Ok(StepRead {
            state: slot,
            velocity: vslot,
            charges,
        })
    }

    /// J, and its derivatives in the reference state and the controls' knots, once every step
    /// was read.
    pub fn finish(self) -> Result<Finished, String> {
        let plan = self.plan;
        let n = self.reference_state.len();
        let mut value = 0.0;
        let mut reference = vec![0.0; n];
        let knots: Vec<ControlKnots> = plan
            .stages
            .iter()
            .enumerate()
            .flat_map(|(si, s)| {
                s.controls
                    .iter()
                    .map(move |(e, k)| (si, e.as_str(), k.as_slice()))
            })
            .collect();
        let mut controls: Vec<Vec<f64>> = knots.iter().map(|k| vec![0.0; k.2.len()]).collect();
        // ∂J/∂(reference state) of relative terms of the first stage
        let mut at_reference: Vec<f64> = Vec::new();
        let mut readings = Vec::new();
        for (ti, t) in self.objective.terms.iter().enumerate() {
            let reads = &self.reads[ti];
            let (probe, stage, weight, relative) = match t {
                Term::DriveEffort {
                    stage,
                    electrode,
                    rate,
                    weight,
                } => {
                    let c = knots
                        .iter()
                        .position(|(si, e, _)| si == stage && e == electrode)
                        .ok_or_else(|| format!("no control of `{electrode}` in the stage"))?;
                    let (e, g) = effort(knots[c].2, *rate);
                    value += 0.5 * weight * e;
                    controls[c]
                        .iter_mut()
                        .zip(&g)
                        .for_each(|(a, b)| *a += 0.5 * weight * b);
                    continue;
                }
                Term::FieldPenalty { weight, .. } => {
                    let factor = weight * plan.symmetry_factor;
                    for r in reads.iter().rev() {
                        value += factor * r.value;
                    }
                    continue;
                }
                Term::Rest { weight, .. } => {
                    for r in reads.iter().rev() {
                        value += weight * 0.5 * r.value;
                    }
                    continue;
                }
                Term::ProbeFinal {
                    probe,
                    stage,
                    weight,
                    relative,
                    ..
                }
                | Term::ProbeMisfit {
                    probe,
                    stage,
                    weight,
                    relative,
                    ..
                } => (*probe, *stage, *weight, *relative),
            };
            let p = &plan.probes[probe].1;
            // a deflection's gradient does not depend on the state: the reference's is that of
            // every step
            let g_reference = if p.reads_reference() || relative {
                self.probe_at(probe, &self.reference_state)?.1
            } else {
                Vec::new()
            };
            let mut start = 0.0;
            for r in reads.iter().rev() {
                let residual = r.value - self.v0[ti] - r.target;
                readings.push(Reading {
                    term: ti,
                    stage,
                    step: r.step,
                    time: r.time,
                    value: r.value - self.v0[ti],
                    target: r.target,
                    weight,
                });
                value += 0.5 * weight * residual * residual;
                if p.reads_reference() {
                    let factor = weight * residual;
                    reference
                        .iter_mut()
                        .zip(&g_reference)
                        .for_each(|(s, v)| *s -= factor * v);
                }
                start -= weight * residual;
            }
            if relative && start != 0.0 {
                if self.stages[ti].is_some_and(|si| si > 0) {
                    if p.reads_reference() {
                        reference
                            .iter_mut()
                            .zip(&g_reference)
                            .for_each(|(s, v)| *s -= start * v);
                    }
                } else if !p.reads_reference() {
                    // the start is the reference state itself (a deflection from it reads 0)
                    if at_reference.is_empty() {
                        at_reference.resize(g_reference.len(), 0.0);
                    }
                    at_reference
                        .iter_mut()
                        .zip(&g_reference)
                        .for_each(|(s, v)| *s += start * v);
                }
            }
        }
        reference
            .iter_mut()
            .zip(&at_reference)
            .for_each(|(s, v)| *s += v);
        Ok(Finished {
            value,
            reference,
            controls,
            readings,
        })
    }
}

/// The value of a probe of nodal values at `state`, deflections measured from `reference`.
fn nodal_value(p: &Probe, state: &[f64], reference: &[f64]) -> f64 {
    p.evaluate(&ProbeInput {
        state,
        reactions: &[],
        electrodes: &[],
        stored: 0.0,
        electric: 0.0,
        reference,
        max_field: 0.0,
        symmetry: 1.0,
        previous: (&[], 0.0),
        circuit_energy: &[],
        pressures: &[],
        charges: &[],
    })
}

/// The electrode whose charge `p` reads (`None`: another kind of probe).
fn charge_of(p: &Probe) -> Option<usize> {
    match p.kind {
        ProbeKind::Charge(e) => Some(e),
        _ => None,
    }
}

/// The value of charge probe `p` for the charge `q` (C, of the meshed model) on its electrode
/// `e` of `n` electrodes: the whole device's charge (times `symmetry`), scaled and offset.
fn charge_value(p: &Probe, e: usize, n: usize, q: f64, symmetry: f64) -> f64 {
    let mut charges = vec![(0.0, 0.0); n];
    charges[e] = (q, 0.0);
    p.evaluate(&ProbeInput {
        state: &[],
        reactions: &[],
        electrodes: &[],
        stored: 0.0,
        electric: 0.0,
        reference: &[],
        max_field: 0.0,
        symmetry,
        previous: (&[], 0.0),
        circuit_energy: &[],
        pressures: &[],
        charges: &charges,
    })
}

/// A control as J reads it: its stage, its electrode's name and its knots (s, V).
type ControlKnots<'a> = (usize, &'a str, &'a [(f64, f64)]);

/// ∫ V² dt (`rate`: ∫ (dV/dt)² dt) of the piecewise-linear table through `knots` and its
/// derivatives in the knots' values: on an interval of length h from a to b, h(a² + ab + b²)/3,
/// or (b − a)²/h.
fn effort(knots: &[(f64, f64)], rate: bool) -> (f64, Vec<f64>) {
    let mut value = 0.0;
    let mut g = vec![0.0; knots.len()];
    for i in 1..knots.len() {
        let ((t0, a), (t1, b)) = (knots[i - 1], knots[i]);
        let h = t1 - t0;
        if h <= 0.0 {
            continue;
        }
        if rate {
            value += (b - a).powi(2) / h;
            g[i - 1] -= 2.0 * (b - a) / h;
            g[i] += 2.0 * (b - a) / h;
        } else {
            value += h * (a * a + a * b + b * b) / 3.0;
            g[i - 1] += h * (2.0 * a + b) / 3.0;
            g[i] += h * (a + 2.0 * b) / 3.0;
        }
    }
    (value, g)
}

/// Linear interpolation in increasing times `data` at `t` (inside their range).
fn interpolate(data: &[(f64, f64)], t: f64) -> f64 {
    let i = data
        .partition_point(|&(ti, _)| ti < t)
        .clamp(1, data.len() - 1);
    let ((t0, v0), (t1, v1)) = (data[i - 1], data[i]);
    if t1 == t0 {
        return v1;
    }
    v0 + (t - t0) / (t1 - t0) * (v1 - v0)
}

/// One term from its table.
fn term(
    o: &ObjectiveSpec,
    plan: &Plan,
    file: &str,
    base: Option<&Path>,
    key: &dyn Fn(&str) -> String,
) -> Result<Term, InputError> {
    let err = |k: &str, m: String| InputError::at_key(file, key(k), m);
    let weight = o.weight.unwrap_or(1.0);
    if !weight.is_finite() || weight < 0.0 {
        return Err(err(
            "weight",
            format!("expected a weight ≥ 0, got {weight}"),
        ));
    }
    let probe = |o: &ObjectiveSpec| -> Result<usize, InputError> {
        let name = o
            .probe
            .as_deref()
            .ok_or_else(|| err("probe", "this term needs `probe`, a probe's name".into()))?;
        let i = plan
            .probes
            .iter()
            .position(|(n, _)| n == name)
            .ok_or_else(|| {
                let names: Vec<&str> = plan.probes.iter().map(|(n, _)| n.as_str()).collect();
                err(
                    "probe",
                    format!("unknown probe `{name}` (probes: {})", names.join(", ")),
                )
            })?;
        let p = &plan.probes[i].1;
        if charge_of(p).is_some() {
            if o.relative.unwrap_or(false) {
                return Err(err(
                    "relative",
                    format!(
                        "a term on the charge probe `{name}` is not differentiated relative to \
                         its stage's start yet: give the charge itself"
                    ),
                ));
            }
        } else if p
            .state_gradient(&vec![0.0; plan.model.mesh.n_nodes() * 4])
            .is_none()
        {
            return Err(err(
                "probe",
                format!(
                    "the probe `{name}` is not differentiated yet: an objective reads a probe \
                     of nodal values (mean, max, min, point, deflection) or an electrode's \
                     charge"
                ),
            ));
        }
        Ok(i)
    };
    let stage = |o: &ObjectiveSpec| -> Result<usize, InputError> {
        let names: Vec<&str> = plan.stages.iter().map(|s| s.name.as_str()).collect();
        match o.stage.as_deref() {
            None if plan.stages.len() == 1 => Ok(0),
            None => Err(err(
                "stage",
                format!("this term needs `stage` (stages: {})", names.join(", ")),
            )),
            Some(n) => names.iter().position(|s| *s == n).ok_or_else(|| {
                err(
                    "stage",
                    format!("unknown stage `{n}` (stages: {})", names.join(", ")),
                )
            }),
        }
    };
    let unused = |keys: &[(&str, bool)]| -> Result<(), InputError> {
        for (k, given) in keys {
            if *given {
                return Err(err(k, format!("`{k}` is no key of a `{}` term", o.kind)));
            }
        }
        Ok(())
    };
    match o.kind.as_str() {
        "probe-final" => {
            unused(&[
                ("data", o.data.is_some()),
                ("electrode", o.electrode.is_some()),
                ("of", o.of.is_some()),
                ("limit", o.limit.is_some()),
            ])?;
            let target = match &o.target {
                Some(VoltageSpec::Constant(v)) if v.is_finite() => *v,
                Some(_) => {
                    return Err(err(
                        "target",
                        "a `probe-final` term's target is a number in the probe's unit".into(),
                    ))
                }
                None => return Err(err("target", "a `probe-final` term needs `target`".into())),
            };
            Ok(Term::ProbeFinal {
                probe: probe(o)?,
                stage: stage(o)?,
                target,
                weight,
                relative: o.relative.unwrap_or(false),
                step: None,
            })
        }
        "probe-misfit" => {
            unused(&[
                ("electrode", o.electrode.is_some()),
                ("of", o.of.is_some()),
                ("limit", o.limit.is_some()),
            ])?;
            let si = stage(o)?;
            let t0 = plan.stage_start(si);
            let relative = o.relative.unwrap_or(false);
            let path = match (&o.data, &o.target) {
                (Some(_), Some(_)) => {
                    return Err(err(
                        "target",
                        "give `data` (a CSV file) or `target` (a waveform), not both".into(),
                    ))
                }
                (None, None) => {
                    return Err(err(
                        "data",
                        "a `probe-misfit` term needs `data`, a CSV file with the header \
                         `time,value`, or `target`, a number or waveform table of stage time"
                            .into(),
                    ))
                }
                (None, Some(t)) => {
                    let waveform = crate::io::build::waveform(file, &key("target"), t, base)?;
                    return Ok(Term::ProbeMisfit {
                        probe: probe(o)?,
                        stage: si,
                        target: Target::Waveform {
                            waveform,
                            start: t0,
                        },
                        weight,
                        relative,
                    });
                }
                (Some(path), None) => path,
            };
            let full = base.map_or_else(|| Path::new(path).to_path_buf(), |b| b.join(path));
            let data = read_data(&full).map_err(|m| err("data", m))?;
            let t1 = t0 + plan.stages[si].duration;
            let (first, last) = (data[0].0, data[data.len() - 1].0);
            if first > t0 + 1e-12 * t1.abs().max(1.0) || last < t1 - 1e-12 * t1.abs().max(1.0) {
                return Err(err(
                    "data",
                    format!(
                        "{}: the times {first} … {last} s do not cover the stage `{}` ({t0} … \
                         {t1} s in the run's clock)",
                        full.display(),
                        plan.stages[si].name
                    ),
                ));
            }
            Ok(Term::ProbeMisfit {
                probe: probe(o)?,
                stage: si,
                target: Target::Data(data),
                weight,
                relative,
            })
        }
        "drive-effort" => {
            unused(&[
                ("probe", o.probe.is_some()),
                ("data", o.data.is_some()),
                ("target", o.target.is_some()),
                ("limit", o.limit.is_some()),
                ("relative", o.relative.is_some()),
            ])?;
            let si = stage(o)?;
            let electrode = o.electrode.clone().ok_or_else(|| {
                err(
                    "electrode",
                    "a `drive-effort` term needs `electrode`, a controlled electrode".into(),
                )
            })?;
            if !plan.stages[si]
                .controls
                .iter()
                .any(|(e, _)| *e == electrode)
            {
                return Err(err(
                    "electrode",
                    format!(
                        "`{electrode}` is not controlled in stage `{}`: a drive effort reads a \
                         control's table (add a [[controls]] entry for it)",
                        plan.stages[si].name
                    ),
                ));
            }
            let rate = match o.of.as_deref() {
                None | Some("value") => false,
                Some("rate") => true,
                Some(other) => {
                    return Err(err(
                        "of",
                        format!(
                        "expected \"value\" (∫V² dt) or \"rate\" (∫(dV/dt)² dt); got \"{other}\""
                    ),
                    ))
                }
            };
            Ok(Term::DriveEffort {
                stage: si,
                electrode,
                rate,
                weight,
            })
        }
        "rest" => {
            unused(&[
                ("probe", o.probe.is_some()),
                ("data", o.data.is_some()),
                ("target", o.target.is_some()),
                ("electrode", o.electrode.is_some()),
                ("of", o.of.is_some()),
                ("limit", o.limit.is_some()),
                ("relative", o.relative.is_some()),
            ])?;
            let si = stage(o)?;
            if !matches!(
                plan.stages[si].kind,
                crate::job::plan::StageKind::Dynamic { .. }
            ) {
                return Err(err(
                    "stage",
                    format!(
                        "stage `{}` is no dynamic stage: `rest` is its kinetic energy at the end",
                        plan.stages[si].name
                    ),
                ));
            }
            Ok(Term::Rest { stage: si, weight })
        }
        "field-penalty" => {
            unused(&[
                ("probe", o.probe.is_some()),
                ("data", o.data.is_some()),
                ("target", o.target.is_some()),
                ("electrode", o.electrode.is_some()),
                ("of", o.of.is_some()),
                ("relative", o.relative.is_some()),
            ])?;
            let si = stage(o)?;
            let limit = match o.limit {
                Some(l) if l.is_finite() && l >= 0.0 => l,
                Some(l) => {
                    return Err(err(
                        "limit",
                        format!("expected a field ≥ 0 in V/m; got {l}"),
                    ))
                }
                None => {
                    return Err(err(
                        "limit",
                        "a `field-penalty` term needs `limit`, the true field (V/m) above \
                         which it grows"
                            .into(),
                    ))
                }
            };
            Ok(Term::FieldPenalty {
                stage: si,
                limit,
                weight,
            })
        }
        other => Err(err(
            "kind",
            format!(
                "unknown objective term `{other}`: expected probe-final, probe-misfit, \
                 drive-effort, rest or field-penalty"
            ),
        )),
    }
}

/// A `time,value` CSV: a header naming the two columns, then rows of two finite numbers with
/// increasing times. An error names the file and the line.
pub fn read_data(path: &Path) -> Result<Vec<(f64, f64)>, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((hl, header)) = lines.next() else {
        return Err(format!(
            "{}: empty; expected the header `time,value`",
            path.display()
        ));
    };
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let (Some(ti), Some(vi)) = (
        cols.iter().position(|c| *c == "time"),
        cols.iter().position(|c| *c == "value"),
    ) else {
        return Err(format!(
            "{}:{}: the header `{header}` lacks the columns `time` and `value`",
            path.display(),
            hl + 1
        ));
    };
    let mut data: Vec<(f64, f64)> = Vec::new();
    for (ln, line) in lines {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let num = |i: usize, what: &str| -> Result<f64, String> {
            let v = f
                .get(i)
                .and_then(|s| s.parse::<f64>().ok())
                .filter(|v| v.is_finite());
            v.ok_or_else(|| {
                format!(
                    "{}:{}: expected a finite number for `{what}`, got `{}`",
                    path.display(),
                    ln + 1,
                    f.get(i).copied().unwrap_or("")
                )
            })
        };
        let (t, v) = (num(ti, "time")?, num(vi, "value")?);
        if let Some(&(prev, _)) = data.last() {
            if t <= prev {
                return Err(format!(
                    "{}:{}: the time {t} s does not follow {prev} s: times must increase",
                    path.display(),
                    ln + 1
                ));
            }
        }
        data.push((t, v));
    }
    if data.len() < 2 {
        return Err(format!(
            "{}: expected at least two rows of `time,value`",
            path.display()
        ));
    }
    Ok(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Data are read with their header in any column order and interpolated linearly; bad rows
    /// are refused naming the line.
    #[test]
    fn data_files_are_read_and_checked() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.csv");
        std::fs::write(&p, "value,time\n1.0,0\n3.0,2\n").unwrap();
        let d = read_data(&p).unwrap();
        assert_eq!(d, vec![(0.0, 1.0), (2.0, 3.0)]);
        assert_eq!(interpolate(&d, 0.5), 1.5);
        std::fs::write(&p, "time,value\n0,1\n0,2\n").unwrap();
        assert!(read_data(&p).unwrap_err().contains("d.csv:3"));
        std::fs::write(&p, "time,value\n0,1\n1,nan\n").unwrap();
        assert!(read_data(&p).unwrap_err().contains("d.csv:3"));
        std::fs::write(&p, "t,v\n0,1\n").unwrap();
        assert!(read_data(&p).unwrap_err().contains("lacks the columns"));
    }
}
