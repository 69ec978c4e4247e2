//! `electrodes.<name>.controller`: a feedback controller that sets an electrode's voltage from a
//! probe in the dynamic and quasi-static stages ([`crate::job::controller`]).

use super::electrodes::build_waveform;
use super::{Ctx, Electrode, Stage, StageKind};
use crate::io::scenario::{closest, ControllerSpec, InputError, Scenario, VoltageSpec};
use crate::job::controller::{Controller, Pid};
use crate::job::probes::Probe;
use crate::job::state_feedback::StateFeedback;
use crate::time::lqr::StateFeedbackDesign;
use crate::waveform::{Shape, Waveform};
use std::path::Path;

/// The controller kinds by scenario name.
const KINDS: [&str; 2] = ["pid", "state-feedback"];

/// The keys of a PID that a state feedback takes from its design file instead.
const PID_ONLY: [&str; 6] = [
    "probe",
    "kp",
    "ki",
    "kd",
    "sample_time",
    "derivative_filter",
];

/// The time step of `stage` when a controller acts in it (a dynamic or quasi-static stage with
/// its electrodes on), else `None`.
pub(super) fn controlled_step(stage: &Stage) -> Option<f64> {
    if !stage.electrodes_on {
        return None;
    }
    match stage.kind {
        StageKind::Dynamic { dt, .. } => Some(dt),
        StageKind::QuasiStatic { steps } => Some(stage.duration / steps.max(1) as f64),
        _ => None,
    }
}

/// Puts each electrode's controller of `s` on it, its probe among `probes`.
pub(super) fn build_controllers(
    ctx: &Ctx,
    s: &Scenario,
    electrodes: &mut [Electrode],
    stages: &[Stage],
    probes: &[(String, Probe)],
    base_dir: Option<&Path>,
) -> Result<(), InputError> {
    for e in electrodes.iter_mut() {
        let Some(spec) = s
            .electrodes
            .get(&e.name)
            .and_then(|x| x.controller.as_ref())
        else {
            continue;
        };
        let key = format!("electrodes.{}.controller", e.name);
        e.controller = Some(build_controller(
            ctx, &key, spec, e, stages, probes, base_dir,
        )?);
    }
    Ok(())
}

fn build_controller(
    ctx: &Ctx,
    key: &str,
    spec: &ControllerSpec,
    e: &Electrode,
    stages: &[Stage],
    probes: &[(String, Probe)],
    base_dir: Option<&Path>,
) -> Result<Controller, InputError> {
    let k = |s: &str| format!("{key}.{s}");
    if !KINDS.contains(&spec.kind.as_str()) {
        let hint = closest(&spec.kind, KINDS)
            .map(|c| format!("; did you mean `{c}`?"))
            .unwrap_or_default();
        return Err(ctx.err(
            k("kind"),
            format!(
                "unknown controller kind `{}` (known: {}){hint}",
                spec.kind,
                KINDS.join(", ")
            ),
        ));
    }
    if e.charge.is_some() || e.resistance.is_some() {
        return Err(ctx.err(
            key,
            format!(
                "electrode `{}` is {}: a controller sets the voltage of a voltage-controlled \
                 electrode",
                e.name,
                if e.charge.is_some() {
                    "charge-controlled"
                } else {
                    "driven through a circuit"
                }
            ),
        ));
    }
    if e.voltage.shape == Shape::Constant && e.voltage.value(0.0) == 0.0 {
        return Err(ctx.err(
            key,
            format!(
                "electrode `{}` is grounded (`voltage` = 0, the reference of the potential): a \
                 controller drives a live electrode; give it a `voltage` for the stages without \
                 the controller (e.g. its bias)",
                e.name
            ),
        ));
    }
    let active: Vec<(&Stage, f64)> = stages
        .iter()
        .filter_map(|st| controlled_step(st).map(|dt| (st, dt)))
        .collect();
    if active.is_empty() {
        return Err(ctx.err(
            key,
            "no dynamic or quasi-static stage with its electrodes on: the controller would never \
             act",
        ));
    }
    for st in stages {
        if controlled_step(st).is_some() && st.controls.iter().any(|(n, _)| *n == e.name) {
            return Err(ctx.err(
                key,
                format!(
                    "electrode `{}` has a `[[controls]]` table in stage `{}` too: one drive per \
                     electrode and stage",
                    e.name, st.name
                ),
            ));
        }
    }
    if spec.kind == "state-feedback" {
        return build_state_feedback(ctx, key, spec, e, stages, probes, base_dir);
    }
    if spec.model.is_some() {
        return Err(ctx.err(
            k("model"),
            "a PID takes no design file: `model` is a key of `kind = \"state-feedback\"`",
        ));
    }
    let probe_name = spec
        .probe
        .as_deref()
        .ok_or_else(|| ctx.err(k("probe"), "missing: the name of the probe measured"))?;
    let probe = probes
        .iter()
        .position(|(n, _)| n == probe_name)
        .ok_or_else(|| {
            let names: Vec<&str> = probes.iter().map(|(n, _)| n.as_str()).collect();
            let hint = closest(probe_name, names.iter().copied())
                .map(|c| format!("; did you mean `{c}`?"))
                .unwrap_or_default();
            ctx.err(
                k("probe"),
                format!(
                    "unknown probe `{probe_name}` (probes: {}){hint}",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                ),
            )
        })?;
    let setpoint = setpoint(ctx, key, spec, base_dir)?;
    let feedforward = match &spec.feedforward {
        None => Waveform::constant(0.0),
        Some(w) => build_waveform(ctx, &k("feedforward"), w, base_dir)?,
    };
    let gain = |name: &str, v: Option<f64>, unit: &str| non_negative(ctx, &k(name), v, unit);
    let kp = gain("kp", spec.kp, "V per probe unit")?;
    let ki = gain("ki", spec.ki, "V per probe unit per s")?;
    let kd = gain("kd", spec.kd, "V·s per probe unit")?;
    if kp == 0.0 && ki == 0.0 && kd == 0.0 {
        return Err(ctx.err(
            k("kp"),
            "every gain is 0: give at least one of `kp`, `ki`, `kd` a positive value",
        ));
    }
    let sample_time = ctx.positive(&k("sample_time"), spec.sample_time, "sample period in s")?;
    for (st, dt) in &active {
        if sample_time < dt * (1.0 - 1e-9) {
            return Err(ctx.err(
                k("sample_time"),
                format!(
                    "{} s is shorter than the time step {} s of stage `{}`: expected a sample \
                     period of at least one step",
                    crate::units::Short(sample_time),
                    crate::units::Short(*dt),
                    st.name
                ),
            ));
        }
    }
    let (lower, upper) = limits(ctx, key, spec)?;
    let noise = gain(
        "noise",
        spec.noise,
        "standard deviation in the probe's unit",
    )?;
    let derivative_filter = gain(
        "derivative_filter",
        spec.derivative_filter,
        "filter time constant in s",
    )?;
    Ok(Controller::Pid(Box::new(Pid {
        probe,
        probe_name: probe_name.to_string(),
        setpoint,
        kp,
        ki,
        kd,
        sample_time,
        lower,
        upper,
        feedforward,
        noise,
        seed: spec.seed.unwrap_or(0),
        derivative_filter,
    })))
}

/// The set point of `spec` (`key.setpoint`): a number or a waveform, in the measured unit.
fn setpoint(
    ctx: &Ctx,
    key: &str,
    spec: &ControllerSpec,
    base_dir: Option<&Path>,
) -> Result<Waveform, InputError> {
    let k = format!("{key}.setpoint");
    match &spec.setpoint {
        None => Err(ctx.err(
            k,
            "missing: the set point in the probe's unit (a number or a waveform table)",
        )),
        Some(VoltageSpec::Constant(x)) => Ok(Waveform::constant(ctx.finite(
            &k,
            *x,
            "set point in the probe's unit",
        )?)),
        Some(w) => build_waveform(ctx, &k, w, base_dir),
    }
}

/// A finite number ≥ 0 at `key` (0 when not given).
fn non_negative(ctx: &Ctx, key: &str, v: Option<f64>, unit: &str) -> Result<f64, InputError> {
    let v = v.unwrap_or(0.0);
    if !(v.is_finite() && v >= 0.0) {
        return Err(ctx.err(
            key,
            format!(
                "must be a finite number ≥ 0 ({unit}); got {}",
                crate::units::Short(v)
            ),
        ));
    }
    Ok(v)
}

/// The output limits `lower` (default 0) < `upper` (V).
fn limits(ctx: &Ctx, key: &str, spec: &ControllerSpec) -> Result<(f64, f64), InputError> {
    let k = |s: &str| format!("{key}.{s}");
    let lower = ctx.finite(&k("lower"), spec.lower.unwrap_or(0.0), "output limit in V")?;
    let upper = match spec.upper {
        None => {
            return Err(ctx.err(
                k("upper"),
                "missing: the largest output in V (the amplifier's limit)",
            ))
        }
        Some(u) => ctx.finite(&k("upper"), u, "output limit in V")?,
    };
    if lower >= upper {
        return Err(ctx.err(
            k("upper"),
            format!(
                "must exceed `lower` ({} V); got {} V",
                crate::units::Short(lower),
                crate::units::Short(upper)
            ),
        ));
    }
    Ok((lower, upper))
}

/// A state feedback (`kind = "state-feedback"`) from the design file `model`: the design must be
/// for this electrode at the voltage it has when the controller starts, its measured outputs
/// probes of the scenario, its sample period no shorter than a step, and the controller must act
/// in dynamic stages only (the design's model has inertia).
fn build_state_feedback(
    ctx: &Ctx,
    key: &str,
    spec: &ControllerSpec,
    e: &Electrode,
    stages: &[Stage],
    probes: &[(String, Probe)],
    base_dir: Option<&Path>,
) -> Result<Controller, InputError> {
    let k = |s: &str| format!("{key}.{s}");
    let given = |name: &str| match name {
        "probe" => spec.probe.is_some(),
        "kp" => spec.kp.is_some(),
        "ki" => spec.ki.is_some(),
        "kd" => spec.kd.is_some(),
        "sample_time" => spec.sample_time.is_some(),
        _ => spec.derivative_filter.is_some(),
    };
    if let Some(name) = PID_ONLY.iter().find(|n| given(n)) {
        return Err(ctx.err(
            k(name),
            format!(
                "not a key of a state feedback: its measured probes, gains and sample period \
                 come from its design file (`model`); `{name}` is a PID's"
            ),
        ));
    }
    let model_key = k("model");
    let file = spec.model.as_deref().ok_or_else(|| {
        ctx.err(
            &model_key,
            "missing: the design file written by `deasim reduce --lqr` (lqr.json), relative to \
             the scenario",
        )
    })?;
    let path = base_dir
        .map(|d| d.join(file))
        .unwrap_or_else(|| file.into());
    let text = std::fs::read_to_string(&path).map_err(|err| {
        ctx.err(
            &model_key,
            format!("cannot read `{}`: {err}", path.display()),
        )
    })?;
    let design: StateFeedbackDesign = serde_json::from_str(&text).map_err(|err| {
        ctx.err(
            &model_key,
            format!(
                "`{}`: not a state-feedback design of `deasim reduce --lqr`: {err}",
                path.display()
            ),
        )
    })?;
    let mismatch = |what: String| ctx.err(&model_key, format!("`{}` {what}", path.display()));
    if design.electrode != e.name {
        return Err(mismatch(format!(
            "was designed for electrode `{}`, not `{}`",
            design.electrode, e.name
        )));
    }
    let n = design.ad.len();
    let p = design.outputs.len();
    let shaped = n > 0
        && design.ad.iter().all(|r| r.len() == n)
        && design.bd.len() == n
        && design.bd.iter().all(|r| r.len() == 1)
        && design.k.len() == 1
        && design.k[0].len() == n
        && design.l.len() == n
        && design.l.iter().all(|r| r.len() == design.measured.len())
        && design.c.len() == p
        && design.c.iter().all(|r| r.len() == n)
        && design.d.len() == p
        && design.d.iter().all(|r| r.len() == 1)
        && design.output_offsets.len() == p
        && design.static_gains.len() == p
        && p > 0
        && design.outputs[0] == design.tracked
        && !design.measured.is_empty();
    let finite = design
        .ad
        .iter()
        .chain(&design.bd)
        .chain(&design.c)
        .chain(&design.d)
        .chain(&design.k)
        .chain(&design.l)
        .flatten()
        .chain(&design.output_offsets)
        .chain(&design.static_gains)
        .chain([&design.n_bar, &design.bias_v, &design.sample_time])
        .all(|x| x.is_finite());
    if !(shaped && finite && design.sample_time > 0.0) {
        return Err(mismatch(
            "has inconsistent matrix sizes or values that are not finite numbers".into(),
        ));
    }
    // the bias: the electrode's voltage at the end of the stage before the first controlled one
    let first = stages
        .iter()
        .position(|st| controlled_step(st).is_some())
        .expect("checked: a controlled stage");
    let bias = match first.checked_sub(1) {
        Some(i) => stages[i].electrode_waveform(e).value(stages[i].duration),
        None => e.voltage.value(0.0),
    };
    if (design.bias_v - bias).abs() > 1e-6 * bias.abs().max(1.0) {
        return Err(mismatch(format!(
            "was designed about a bias of {} V; electrode `{}` is at {} V when the controller \
             starts: reduce the scenario again about this bias",
            crate::units::Short(design.bias_v),
            e.name,
            crate::units::Short(bias)
        )));
    }
    let mut probe_index = Vec::new();
    let mut rows = Vec::new();
    for m in &design.measured {
        let found = probes.iter().position(|(name, _)| name == m);
        let row = design.outputs.iter().position(|o| o == m);
        match (found, row) {
            (Some(i), Some(r)) => {
                probe_index.push(i);
                rows.push(r);
            }
            (None, _) => {
                let names: Vec<&str> = probes.iter().map(|(n, _)| n.as_str()).collect();
                return Err(mismatch(format!(
                    "measures probe `{m}`, which the scenario does not have (probes: {})",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                )));
            }
            (_, None) => {
                return Err(mismatch(format!(
                    "measures `{m}` but has no row of it among its outputs"
                )))
            }
        }
    }
    for st in stages {
        let Some(dt) = controlled_step(st) else {
            continue;
        };
        if !matches!(st.kind, StageKind::Dynamic { .. }) {
            return Err(ctx.err(
                key,
                format!(
                    "stage `{}` is quasi-static with the electrodes on: a state feedback acts in \
                     dynamic stages (its model has inertia); turn the electrodes off there or use \
                     a PID",
                    st.name
                ),
            ));
        }
        if design.sample_time < dt * (1.0 - 1e-9) {
            return Err(mismatch(format!(
                "has a sample period of {} s, shorter than the time step {} s of stage `{}`: \
                 design it at a sample period of at least one step (`reduce --sample-time`)",
                crate::units::Short(design.sample_time),
                crate::units::Short(dt),
                st.name
            )));
        }
    }
    let setpoint = setpoint(ctx, key, spec, base_dir)?;
    let feedforward = match &spec.feedforward {
        None => Waveform::constant(0.0),
        Some(w) => build_waveform(ctx, &k("feedforward"), w, base_dir)?,
    };
    let (lower, upper) = limits(ctx, key, spec)?;
    let noise = non_negative(
        ctx,
        &k("noise"),
        spec.noise,
        "standard deviation in the tracked output's unit",
    )?;
    Ok(Controller::StateFeedback(Box::new(StateFeedback {
        model_path: file.to_string(),
        design,
        probes: probe_index,
        rows,
        setpoint,
        lower,
        upper,
        feedforward,
        noise,
        seed: spec.seed.unwrap_or(0),
    })))
}
