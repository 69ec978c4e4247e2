//! `electrodes.<name>.controller`: a feedback controller that sets an electrode's voltage from a
//! probe in the dynamic and quasi-static stages ([`crate::job::controller`]).

use super::electrodes::build_waveform;
use super::{Ctx, Electrode, Stage, StageKind};
use crate::io::scenario::{closest, ControllerSpec, InputError, Scenario, VoltageSpec};
use crate::job::controller::Controller;
use crate::job::probes::Probe;
use crate::waveform::{Shape, Waveform};
use std::path::Path;

/// The controller kinds by scenario name.
const KINDS: [&str; 1] = ["pid"];

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
    if spec.kind != "pid" {
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
    let setpoint = match &spec.setpoint {
        None => {
            return Err(ctx.err(
                k("setpoint"),
                "missing: the set point in the probe's unit (a number or a waveform table)",
            ))
        }
        Some(VoltageSpec::Constant(x)) => {
            Waveform::constant(ctx.finite(&k("setpoint"), *x, "set point in the probe's unit")?)
        }
        Some(w) => build_waveform(ctx, &k("setpoint"), w, base_dir)?,
    };
    let feedforward = match &spec.feedforward {
        None => Waveform::constant(0.0),
        Some(w) => build_waveform(ctx, &k("feedforward"), w, base_dir)?,
    };
    let gain = |name: &str, v: Option<f64>, unit: &str| -> Result<f64, InputError> {
        let v = v.unwrap_or(0.0);
        if !(v.is_finite() && v >= 0.0) {
            return Err(ctx.err(
                k(name),
                format!(
                    "must be a finite number ≥ 0 ({unit}); got {}",
                    crate::units::Short(v)
                ),
            ));
        }
        Ok(v)
    };
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
    Ok(Controller {
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
    })
}
