//! `[[stages]]`: static and dynamic stages (steps, duration, time step, integrator, mass matrix,
//! `electrodes_on`), and the warning about a time step too long for a periodic voltage.

use super::{Ctx, Electrode, Stage, StageKind, MIN_STEPS_PER_PERIOD};
use crate::io::scenario::{closest, InputError, Scenario, StageSpec};
use crate::job::plan::{HarmonicStability, ResponseMethod};
use crate::job::plan::{PathParameter, PathTarget};
use crate::time::integrator::Scheme;
use crate::time::mass::MassKind;
use crate::time::stage::Method;
use crate::units::Short;

/// The stages in order; at least one, with distinct names.
pub(super) fn build_stages(
    ctx: &Ctx,
    s: &Scenario,
    electrodes: &[Electrode],
) -> Result<Vec<Stage>, InputError> {
    if s.stages.is_empty() {
        return Err(ctx.err("stages", "at least one stage is needed"));
    }
    let mut stages: Vec<Stage> = Vec::new();
    for (i, st) in s.stages.iter().enumerate() {
        let stage = build_stage(ctx, s, i, st, electrodes)?;
        if stages.iter().any(|s| s.name == stage.name) {
            return Err(ctx.err(
                format!("stages.{i}.name"),
                format!("two stages are named `{}`", stage.name),
            ));
        }
        stages.push(stage);
    }
    Ok(stages)
}

/// A time step that cannot resolve a periodic voltage aliases it (the midpoint rule samples the
/// signal at t + Δt/2): say so rather than report a response to a signal never seen.
pub(super) fn aliasing_warnings(stages: &[Stage], electrodes: &[Electrode]) -> Vec<String> {
    let mut warnings = Vec::new();
    for st in stages {
        let StageKind::Dynamic { dt, .. } = st.kind else {
            continue;
        };
        if !st.electrodes_on {
            continue;
        }
        for e in electrodes {
            if let Some(f) = e.voltage.frequency() {
                let per_period = 1.0 / (f * dt);
                if per_period < MIN_STEPS_PER_PERIOD {
                    warnings.push(format!(
                        "stage `{}`: dt = {dt:e} s gives only {per_period:.1} steps per period of \
                         the {f} Hz voltage of electrode `{}` (at least {MIN_STEPS_PER_PERIOD} \
                         are needed to resolve it; the response is aliased)",
                        st.name, e.name
                    ));
                }
            }
        }
    }
    warnings
}

/// Stage `i` (`stages.<i>`).
fn build_stage(
    ctx: &Ctx,
    s: &Scenario,
    i: usize,
    st: &StageSpec,
    electrodes: &[Electrode],
) -> Result<Stage, InputError> {
    let key = format!("stages.{i}");
    let name = st.name.clone().unwrap_or_else(|| format!("stage{i}"));
    let linear_keys = [
        ("count", st.count.is_some()),
        ("shift", st.shift.is_some()),
        ("electrode", st.electrode.is_some()),
        ("frequencies", st.frequencies.is_some()),
        ("from", st.from.is_some()),
        ("to", st.to.is_some()),
        ("points", st.points.is_some()),
        ("method", st.method.is_some()),
        ("harmonic", st.harmonic.is_some()),
    ];
    if matches!(st.kind.as_str(), "modes" | "frequency-response") {
        for (k, v) in [
            ("duration", st.duration.is_some()),
            ("steps", st.steps.is_some()),
            ("dt", st.dt.is_some()),
            ("integrator", st.integrator.is_some()),
            ("mass", st.mass.is_some()),
            ("electrodes_on", st.electrodes_on.is_some()),
        ] {
            if v {
                return Err(ctx.err(
                    format!("{key}.{k}"),
                    format!(
                        "does not apply to a `{}` stage: it takes no time and holds every \
                         electrode at the voltage the previous stage left",
                        st.kind
                    ),
                ));
            }
        }
        for (mname, m) in &s.materials {
            if !m.density.is_some_and(|d| d > 0.0) {
                return Err(ctx.err(
                    format!("materials.{mname}.density"),
                    format!(
                        "`{}` stage `{name}` needs a positive mass density in kg/m³",
                        st.kind
                    ),
                ));
            }
        }
        let kind = if st.kind == "modes" {
            modes_kind(ctx, &key, st)?
        } else if st.harmonic.as_ref().is_some_and(|h| h.to_vec() != [0.0]) {
            // an electrode's voltage is the same at every angle: it drives harmonic 0 alone
            return Err(ctx.err(
                format!("{key}.harmonic"),
                "a `frequency-response` stage takes `harmonic = 0` only: a small voltage on an \
                 electrode is the same at every angle, so it drives the axisymmetric response \
                 alone and every harmonic n ≥ 1 answers it with zero (their modes: a `modes` \
                 stage with `harmonic`)",
            ));
        } else {
            response_kind(ctx, &key, st, electrodes)?
        };
        return Ok(Stage {
            name,
            kind,
            duration: 0.0,
            electrodes_on: true,
            controls: Vec::new(),
            stability: None,
        });
    }
    for (k, v) in linear_keys {
        if v && !(k == "electrode" && st.kind == "continuation") {
            return Err(ctx.err(
                format!("{key}.{k}"),
                "applies to `modes` and `frequency-response` stages only",
            ));
        }
    }
    if st.kind != "continuation" {
        for (k, v) in [
            ("parameter", st.parameter.is_some()),
            ("target", st.target.is_some()),
            ("max_points", st.max_points.is_some()),
        ] {
            if v {
                return Err(ctx.err(
                    format!("{key}.{k}"),
                    "applies to `continuation` stages only",
                ));
            }
        }
    }
    let duration = match st.duration {
        Some(d) => ctx.positive(&format!("{key}.duration"), Some(d), "duration in s")?,
        None => 1.0,
    };
    let kind = match st.kind.as_str() {
        "static" => static_kind(ctx, &key, st)?,
        "quasi-static" => quasi_static_kind(ctx, &key, st, duration)?,
        "dynamic" => dynamic_kind(ctx, s, &key, &name, st)?,
        "continuation" => continuation_kind(ctx, s, &key, st, electrodes)?,
        o => {
            let hint = closest(
                o,
                [
                    "static",
                    "quasi-static",
                    "dynamic",
                    "modes",
                    "frequency-response",
                    "continuation",
                ],
            )
            .map(|c| format!("; did you mean `{c}`?"))
            .unwrap_or_default();
            return Err(ctx.err(
                format!("{key}.kind"),
                format!(
                    "unknown stage kind `{o}`: expected `static`, `quasi-static`, `dynamic`, \
                     `continuation`, `modes` or `frequency-response`{hint}"
                ),
            ));
        }
    };
    let stability = stability(ctx, s, &key, st)?;
    Ok(Stage {
        name,
        kind,
        duration,
        electrodes_on: st.electrodes_on.unwrap_or(true),
        controls: Vec::new(),
        stability,
    })
}

/// `stability_harmonics = N` and `after_instability` of a static or quasi-static stage of an
/// axisymmetric model without follower pressures and internal variables (what the harmonic
/// tangent covers).
fn stability(
    ctx: &Ctx,
    s: &Scenario,
    key: &str,
    st: &StageSpec,
) -> Result<Option<HarmonicStability>, InputError> {
    let Some(n) = st.stability_harmonics else {
        if st.after_instability.is_some() {
            return Err(ctx.err(
                format!("{key}.after_instability"),
                "applies with `stability_harmonics` only",
            ));
        }
        return Ok(None);
    };
    let at = format!("{key}.stability_harmonics");
    if !matches!(st.kind.as_str(), "static" | "quasi-static" | "continuation") {
        return Err(ctx.err(
            at,
            format!(
                "applies to `static`, `quasi-static` and `continuation` stages; a `{}` stage \
                 has no test against harmonics",
                st.kind
            ),
        ));
    }
    if !(1..=MAX_HARMONIC as u64).contains(&n) {
        return Err(ctx.err(
            at,
            format!(
                "expected the largest circumferential harmonic tested, an integer from 1 to \
                 {MAX_HARMONIC}; got {n}"
            ),
        ));
    }
    if s.mesh.geometry.as_deref() != Some("axisymmetric") {
        return Err(ctx.err(
            at,
            "circumferential harmonics are those of an axisymmetric model \
             (`mesh.geometry = \"axisymmetric\"`); a 3-D model's stage tests every \
             perturbation its mesh admits",
        ));
    }
    if s.loads.as_ref().is_some_and(|l| !l.pressure.is_empty()) {
        return Err(ctx.err(
            at,
            "the load stiffness of follower pressures has no harmonic form yet: remove \
             `loads.pressure` or the test",
        ));
    }
    let stop = match st.after_instability.as_deref() {
        None | Some("stop") => true,
        Some("continue") => false,
        Some(o) => {
            return Err(ctx.err(
                format!("{key}.after_instability"),
                format!("expected `stop` or `continue`; got `{o}`"),
            ))
        }
    };
    Ok(Some(HarmonicStability {
        harmonics: n as u32,
        stop,
    }))
}

/// The largest circumferential harmonic a `modes` stage takes.
const MAX_HARMONIC: f64 = 1000.0;

/// `kind = "modes"`: `count` modes (default 6) nearest to `shift` (Hz, default 0) of each
/// circumferential harmonic of `harmonic` (default 0).
fn modes_kind(ctx: &Ctx, key: &str, st: &StageSpec) -> Result<StageKind, InputError> {
    let count = st.count.unwrap_or(6);
    if !(1..=200).contains(&count) {
        return Err(ctx.err(
            format!("{key}.count"),
            format!("expected a number of modes between 1 and 200; got {count}"),
        ));
    }
    let shift_hz = st.shift.unwrap_or(0.0);
    if !(shift_hz.is_finite() && shift_hz >= 0.0) {
        return Err(ctx.err(
            format!("{key}.shift"),
            format!(
                "expected a frequency ≥ 0 in Hz; got {}",
                crate::units::Short(shift_hz)
            ),
        ));
    }
    let harmonics = match &st.harmonic {
        None => vec![0],
        Some(h) => {
            let values = h.to_vec();
            let mut out = Vec::with_capacity(values.len());
            for v in values {
                if !(v.fract() == 0.0 && (0.0..=MAX_HARMONIC).contains(&v)) {
                    return Err(ctx.err(
                        format!("{key}.harmonic"),
                        format!(
                            "expected a circumferential harmonic n, an integer from 0 to \
                             {MAX_HARMONIC}, or a list of them; got {v}"
                        ),
                    ));
                }
                out.push(v as u32);
            }
            if out.is_empty() {
                return Err(ctx.err(
                    format!("{key}.harmonic"),
                    "expected at least one harmonic".to_string(),
                ));
            }
            out
        }
    };
    Ok(StageKind::Modes {
        count: count as usize,
        shift_hz,
        harmonics,
    })
}

/// `kind = "frequency-response"`: the driven `electrode`, the `frequencies` (Hz) or a log range
/// `from`–`to` with `points` (default 50), the `method` (`direct` or `modal` with `count` modes).
fn response_kind(
    ctx: &Ctx,
    key: &str,
    st: &StageSpec,
    electrodes: &[Electrode],
) -> Result<StageKind, InputError> {
    let names = || {
        electrodes
            .iter()
            .map(|e| format!("`{}`", e.name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let electrode = match &st.electrode {
        Some(n) => electrodes
            .iter()
            .position(|e| &e.name == n)
            .ok_or_else(|| {
                ctx.err(
                    format!("{key}.electrode"),
                    format!("no electrode `{n}`; the scenario has {}", names()),
                )
            })?,
        None => electrodes
            .iter()
            .position(|e| e.voltage.amplitude != 0.0 || e.voltage.offset != 0.0)
            .ok_or_else(|| {
                ctx.err(
                    format!("{key}.electrode"),
                    "missing: no electrode carries a voltage; name the driven one",
                )
            })?,
    };
    let frequencies = match (&st.frequencies, st.from, st.to) {
        (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
            return Err(ctx.err(
                format!("{key}.frequencies"),
                "give either `frequencies` or `from`/`to`/`points`, not both",
            ))
        }
        (Some(list), None, None) => {
            if list.is_empty() {
                return Err(ctx.err(
                    format!("{key}.frequencies"),
                    "expected at least one frequency in Hz",
                ));
            }
            if let Some(f) = list.iter().find(|f| !(f.is_finite() && **f > 0.0)) {
                return Err(ctx.err(
                    format!("{key}.frequencies"),
                    format!(
                        "expected positive frequencies in Hz; got {}",
                        crate::units::Short(*f)
                    ),
                ));
            }
            list.clone()
        }
        (None, from, to) => {
            let from = ctx.positive(&format!("{key}.from"), from, "lowest frequency in Hz")?;
            let to = ctx.positive(&format!("{key}.to"), to, "highest frequency in Hz")?;
            if to <= from {
                return Err(ctx.err(
                    format!("{key}.to"),
                    format!(
                        "expected a frequency above `from` = {from} Hz; got {}",
                        crate::units::Short(to)
                    ),
                ));
            }
            let points = st.points.unwrap_or(50);
            if !(2..=100_000).contains(&points) {
                return Err(ctx.err(
                    format!("{key}.points"),
                    format!("expected between 2 and 100000 frequencies; got {points}"),
                ));
            }
            log_range(from, to, points as usize)
        }
    };
    if st.points.is_some() && st.frequencies.is_some() {
        return Err(ctx.err(
            format!("{key}.points"),
            "applies to a range `from`/`to` only, not to a list of `frequencies`",
        ));
    }
    let method = match st.method.as_deref().unwrap_or("direct") {
        "direct" => {
            if st.count.is_some() {
                return Err(ctx.err(
                    format!("{key}.count"),
                    "applies to `method = \"modal\"` only",
                ));
            }
            ResponseMethod::Direct
        }
        "modal" => {
            let count = st.count.unwrap_or(10);
            if !(1..=200).contains(&count) {
                return Err(ctx.err(
                    format!("{key}.count"),
                    format!("expected a number of modes between 1 and 200; got {count}"),
                ));
            }
            ResponseMethod::Modal {
                count: count as usize,
            }
        }
        o => {
            return Err(ctx.err(
                format!("{key}.method"),
                format!("expected `direct` or `modal`; got `{o}`"),
            ))
        }
    };
    Ok(StageKind::FrequencyResponse {
        electrode,
        frequencies,
        method,
    })
}

/// `points` frequencies spaced evenly in log from `from` to `to` (both included).
pub fn log_range(from: f64, to: f64, points: usize) -> Vec<f64> {
    let (a, b) = (from.ln(), to.ln());
    (0..points)
        .map(|i| {
            if i + 1 == points {
                to
            } else {
                (a + (b - a) * i as f64 / (points - 1) as f64).exp()
            }
        })
        .collect()
}

/// `kind = "quasi-static"`: real time over `duration`, in `steps` steps or steps of `dt` (s);
/// no inertia keys.
fn quasi_static_kind(
    ctx: &Ctx,
    key: &str,
    st: &StageSpec,
    duration: f64,
) -> Result<StageKind, InputError> {
    for (k, v) in [
        ("integrator", st.integrator.is_some()),
        ("mass", st.mass.is_some()),
    ] {
        if v {
            return Err(ctx.err(format!("{key}.{k}"), "applies to dynamic stages only"));
        }
    }
    let steps = match (st.steps, st.dt) {
        (Some(_), Some(_)) => {
            return Err(ctx.err(
                format!("{key}.dt"),
                "give either `steps` or `dt` for a quasi-static stage, not both",
            ))
        }
        (Some(n), None) => n,
        (None, Some(dt)) => {
            let dt = ctx.positive(&format!("{key}.dt"), Some(dt), "time step in s")?;
            (duration / dt - 1e-9).ceil().max(1.0) as u64
        }
        (None, None) => {
            return Err(ctx.err(
                format!("{key}.dt"),
                "missing: a quasi-static stage needs `dt` (s) or `steps`",
            ))
        }
    };
    if !(1..=1_000_000).contains(&steps) {
        return Err(ctx.err(
            format!("{key}.steps"),
            format!("must be between 1 and 1000000; got {steps}"),
        ));
    }
    Ok(StageKind::QuasiStatic {
        steps: steps as usize,
    })
}

/// `kind = "static"`: `steps` load steps; no dynamic keys.
fn static_kind(ctx: &Ctx, key: &str, st: &StageSpec) -> Result<StageKind, InputError> {
    let steps = st.steps.unwrap_or(1);
    if !(1..=1_000_000).contains(&steps) {
        return Err(ctx.err(
            format!("{key}.steps"),
            format!("must be between 1 and 1000000; got {steps}"),
        ));
    }
    for (k, v) in [
        ("dt", st.dt.is_some()),
        ("integrator", st.integrator.is_some()),
        ("mass", st.mass.is_some()),
    ] {
        if v {
            return Err(ctx.err(format!("{key}.{k}"), "applies to dynamic stages only"));
        }
    }
    Ok(StageKind::Static {
        steps: steps as usize,
    })
}

/// `kind = "continuation"`: `steps` (the first load step is 1/`steps`), the `parameter`
/// (`voltage` or `charge` of `electrode`, `pressure`, or `force`: the dead loads), the `target` (`load`, `probe` with
/// `value`, or `points`) and `max_points` (default 500).
fn continuation_kind(
    ctx: &Ctx,
    s: &Scenario,
    key: &str,
    st: &StageSpec,
    electrodes: &[Electrode],
) -> Result<StageKind, InputError> {
    let StageKind::Static { steps } = static_kind(ctx, key, st)? else {
        unreachable!("static_kind gives a static stage")
    };
    let steps = if st.steps.is_none() { 20 } else { steps };
    let parameter = match st.parameter.as_deref() {
        Some(p @ ("voltage" | "charge")) => {
            let charged = p == "charge";
            let candidates: Vec<usize> = electrodes
                .iter()
                .enumerate()
                .filter(|(_, e)| e.charge.is_some() == charged)
                // a grounded electrode is no parameter
                .filter(|(_, e)| charged || e.voltage != crate::waveform::Waveform::constant(0.0))
                .map(|(i, _)| i)
                .collect();
            let electrode = match &st.electrode {
                Some(name) => {
                    let Some(i) = electrodes.iter().position(|e| &e.name == name) else {
                        return Err(ctx.err(
                            format!("{key}.electrode"),
                            format!("no electrode is named `{name}`"),
                        ));
                    };
                    if electrodes[i].charge.is_some() != charged {
                        return Err(ctx.err(
                            format!("{key}.electrode"),
                            format!(
                                "electrode `{name}` is {}-controlled; parameter `{p}` needs a \
                                 {p}-controlled electrode",
                                if charged { "voltage" } else { "charge" }
                            ),
                        ));
                    }
                    i
                }
                None if candidates.len() == 1 => candidates[0],
                None if candidates.is_empty() => {
                    return Err(ctx.err(
                        format!("{key}.parameter"),
                        if charged {
                            "`charge` needs a charge-controlled electrode (`charge = …`)"
                        } else {
                            "`voltage` needs an electrode whose voltage is not 0"
                        },
                    ))
                }
                None => {
                    return Err(ctx.err(
                        format!("{key}.electrode"),
                        format!(
                            "name the electrode whose {p} is the parameter ({} candidates)",
                            candidates.len()
                        ),
                    ))
                }
            };
            if charged {
                if electrodes[electrode]
                    .charge
                    .as_ref()
                    .is_some_and(|w| w.constant_value().is_none())
                {
                    return Err(ctx.err(
                        format!("{key}.parameter"),
                        format!(
                            "electrode `{}` carries a charge waveform: a continuation follows a \
                             constant charge",
                            electrodes[electrode].name
                        ),
                    ));
                }
                PathParameter::Charge { electrode }
            } else {
                PathParameter::Voltage { electrode }
            }
        }
        Some("pressure") => {
            let n = s.loads.as_ref().map_or(0, |l| l.pressure.len());
            if n == 0 {
                return Err(ctx.err(
                    format!("{key}.parameter"),
                    "`pressure` needs a pressure load (`[[loads.pressure]]`)",
                ));
            }
            if st.electrode.is_some() {
                return Err(ctx.err(
                    format!("{key}.electrode"),
                    "applies to the parameters `voltage` and `charge` only",
                ));
            }
            PathParameter::Pressure { index: 0 }
        }
        Some("force") => {
            let gravity = s.loads.as_ref().and_then(|l| l.gravity).is_some();
            if s.tractions.is_empty() && !gravity {
                return Err(ctx.err(
                    format!("{key}.parameter"),
                    "`force` needs dead loads (`[[tractions]]` or `loads.gravity`)",
                ));
            }
            if st.electrode.is_some() {
                return Err(ctx.err(
                    format!("{key}.electrode"),
                    "applies to the parameters `voltage` and `charge` only",
                ));
            }
            PathParameter::Force
        }
        Some(o) => {
            return Err(ctx.err(
                format!("{key}.parameter"),
                format!(
                    "unknown parameter `{o}`: expected `voltage`, `charge`, `pressure` or `force`"
                ),
            ))
        }
        None => {
            return Err(ctx.err(
                format!("{key}.parameter"),
                "a continuation stage needs the load it follows: `voltage`, `charge`, \
                 `pressure` or `force`",
            ))
        }
    };
    let max_points = st.max_points.unwrap_or(500);
    if !(1..=100_000).contains(&max_points) {
        return Err(ctx.err(
            format!("{key}.max_points"),
            format!("must be between 1 and 100000; got {max_points}"),
        ));
    }
    let t = st.target.clone().unwrap_or_default();
    let given = [t.load.is_some(), t.probe.is_some(), t.points.is_some()];
    if given.iter().filter(|g| **g).count() != 1 {
        return Err(ctx.err(
            format!("{key}.target"),
            "give one target: `{ load = 1.0 }` (a load factor), `{ probe = \"NAME\", value = X }` \
             or `{ points = N }`",
        ));
    }
    let (target, max_points) = if let Some(load) = t.load {
        if !load.is_finite() || load == 0.0 {
            return Err(ctx.err(
                format!("{key}.target.load"),
                format!(
                    "expected a non-zero load factor (1: the stage's end values); got {}",
                    crate::units::Short(load)
                ),
            ));
        }
        (PathTarget::Load(load), max_points as usize)
    } else if let Some(probe) = t.probe {
        if !s.probes.contains_key(&probe) {
            return Err(ctx.err(
                format!("{key}.target.probe"),
                format!("no probe is named `{probe}`"),
            ));
        }
        let Some(value) = t.value.filter(|v| v.is_finite()) else {
            return Err(ctx.err(
                format!("{key}.target.value"),
                "a probe target needs the finite `value` the probe must reach",
            ));
        };
        (
            PathTarget::Probe { name: probe, value },
            max_points as usize,
        )
    } else {
        let n = t.points.unwrap_or(0);
        if !(1..=100_000).contains(&n) {
            return Err(ctx.err(
                format!("{key}.target.points"),
                format!("must be between 1 and 100000; got {n}"),
            ));
        }
        (PathTarget::Points, n as usize)
    };
    if t.value.is_some() && matches!(target, PathTarget::Load(_) | PathTarget::Points) {
        return Err(ctx.err(
            format!("{key}.target.value"),
            "applies to a probe target only",
        ));
    }
    Ok(StageKind::Continuation {
        steps,
        parameter,
        target,
        max_points,
    })
}

/// `kind = "dynamic"`: `duration`, `dt`, `integrator` and `mass`; every material needs a density.
fn dynamic_kind(
    ctx: &Ctx,
    s: &Scenario,
    key: &str,
    name: &str,
    st: &StageSpec,
) -> Result<StageKind, InputError> {
    let duration = st.duration.ok_or_else(|| {
        ctx.err(
            format!("{key}.duration"),
            "missing: dynamic stages need a duration in s",
        )
    })?;
    let dt = ctx.positive(&format!("{key}.dt"), st.dt, "time step in s")?;
    if dt > duration {
        return Err(ctx.err(
            format!("{key}.dt"),
            format!(
                "the time step {} s exceeds the stage duration {} s",
                Short(dt),
                Short(duration)
            ),
        ));
    }
    if duration / dt > 1e7 {
        return Err(ctx.err(
            format!("{key}.dt"),
            format!(
                "{} s in steps of {} s is more than 10⁷ steps",
                Short(duration),
                Short(dt)
            ),
        ));
    }
    if st.steps.is_some() {
        return Err(ctx.err(
            format!("{key}.steps"),
            "applies to static stages only (dynamic stages use `dt`)",
        ));
    }
    let scheme = integrator(ctx, key, st)?;
    for (mname, m) in &s.materials {
        if !m.density.is_some_and(|d| d > 0.0) {
            return Err(ctx.err(
                format!("materials.{mname}.density"),
                format!("dynamic stage `{name}` needs a positive mass density in kg/m³"),
            ));
        }
    }
    let mass = match st.mass.as_deref().unwrap_or("consistent") {
        "consistent" => MassKind::Consistent,
        "lumped" => MassKind::Lumped,
        o => {
            return Err(ctx.err(
                format!("{key}.mass"),
                format!("expected `consistent` or `lumped`; got `{o}`"),
            ))
        }
    };
    Ok(StageKind::Dynamic { dt, scheme, mass })
}

/// The explicit trapezoidal integrator carries no internal variables: it refuses materials with
/// Maxwell branches (the implicit integrators evolve them).
pub(super) fn check_internal_variables(
    ctx: &Ctx,
    stages: &[Stage],
    model: &crate::problem::model::Model,
) -> Result<(), InputError> {
    if model.materials.iter().all(|m| m.state_size() == 0) {
        return Ok(());
    }
    for (i, st) in stages.iter().enumerate() {
        if st.stability.is_some() {
            return Err(ctx.err(
                format!("stages.{i}.stability_harmonics"),
                "the harmonic tangent is that of materials without internal variables; a \
                 material with `branches` has none yet",
            ));
        }
        if let StageKind::Continuation { .. } = st.kind {
            return Err(ctx.err(
                format!("stages.{i}.kind"),
                "a continuation stage moves the load back and forth, which has no meaning in time \
                 for materials with `branches`; use a static or quasi-static stage",
            ));
        }
        if let StageKind::FrequencyResponse {
            method: ResponseMethod::Modal { .. },
            ..
        } = st.kind
        {
            return Err(ctx.err(
                format!("stages.{i}.method"),
                "the modal method has no complex modulus for materials with `branches`; use \
                 `direct`",
            ));
        }
        if let StageKind::Dynamic {
            scheme: Method::Trapezoidal,
            ..
        } = st.kind
        {
            return Err(ctx.err(
                format!("stages.{i}.integrator"),
                "the explicit `trapezoidal` integrator does not evolve materials with `branches`; \
                 use `midpoint` or `newmark`",
            ));
        }
    }
    Ok(())
}

/// `integrator`: `midpoint` (default), `trapezoidal` or `newmark` (β = 1/4, γ = 1/2).
fn integrator(ctx: &Ctx, key: &str, st: &StageSpec) -> Result<Method, InputError> {
    Ok(match st.integrator.as_deref().unwrap_or("midpoint") {
        "midpoint" => Method::Implicit(Scheme::Midpoint),
        "trapezoidal" => Method::Trapezoidal,
        "newmark" => Method::Implicit(Scheme::Newmark {
            beta: 0.25,
            gamma: 0.5,
        }),
        o => {
            let hint = closest(o, ["midpoint", "newmark", "trapezoidal"])
                .map(|c| format!("; did you mean `{c}`?"))
                .unwrap_or_default();
            return Err(ctx.err(
                format!("{key}.integrator"),
                format!(
                    "unknown integrator `{o}`: expected `midpoint`, `newmark` or `trapezoidal`{hint}"
                ),
            ));
        }
    })
}

#[cfg(test)]
mod tests {
    use super::super::testing::{assert_rejected, plan};
    use super::*;

    const DENSE: &str = "[materials.gel]\nmodel = \"neo-hooke\"\nmu = 1e5\nlambda = 1e7\n\
                         permittivity = 4.7\ndensity = 1000.0";

    fn stages(text: &str) -> Vec<Stage> {
        plan(&[("materials", DENSE), ("stages", text)]).stages
    }

    fn dynamic(extra: &str) -> String {
        format!("[[stages]]\nkind = \"dynamic\"\nduration = 0.1\ndt = 0.01\n{extra}")
    }

    #[test]
    fn static_stages_with_their_steps_names_and_durations() {
        let st = stages(
            "[[stages]]\nkind = \"static\"\nsteps = 5\nduration = 2.0\nelectrodes_on = false\n\
             [[stages]]\nname = \"hold\"\nkind = \"static\"",
        );
        assert_eq!(st.len(), 2);
        assert_eq!(st[0].name, "stage0");
        assert_eq!(st[0].kind, StageKind::Static { steps: 5 });
        assert_eq!((st[0].duration, st[0].electrodes_on), (2.0, false));
        assert_eq!(st[1].name, "hold");
        assert_eq!(st[1].kind.nominal_steps(st[1].duration), 1);
        assert_eq!((st[1].duration, st[1].electrodes_on), (1.0, true));
    }

    #[test]
    fn quasi_static_stages_by_dt_or_steps() {
        let st = stages("[[stages]]\nkind = \"quasi-static\"\nduration = 2.0\ndt = 0.25");
        assert_eq!(st[0].kind, StageKind::QuasiStatic { steps: 8 });
        let st = stages("[[stages]]\nkind = \"quasi-static\"\nsteps = 3");
        assert_eq!(st[0].kind, StageKind::QuasiStatic { steps: 3 });
        for (body, key, expected) in [
            ("", "stages.0.dt", "needs `dt` (s) or `steps`"),
            ("dt = 0.1\nsteps = 2", "stages.0.dt", "not both"),
            ("dt = -1.0", "stages.0.dt", "positive"),
            (
                "dt = 0.1\nintegrator = \"midpoint\"",
                "stages.0.integrator",
                "dynamic stages only",
            ),
        ] {
            assert_rejected(
                &[(
                    "stages",
                    &format!("[[stages]]\nkind = \"quasi-static\"\n{body}"),
                )],
                key,
                expected,
            );
        }
    }

    #[test]
    fn dynamic_stages_with_integrator_and_mass() {
        let st = stages(&dynamic(""));
        assert_eq!(
            st[0].kind,
            StageKind::Dynamic {
                dt: 0.01,
                scheme: Method::Implicit(Scheme::Midpoint),
                mass: MassKind::Consistent
            }
        );
        assert_eq!(st[0].kind.nominal_steps(st[0].duration), 10);
        let st = stages(&dynamic("integrator = \"newmark\"\nmass = \"lumped\""));
        assert_eq!(
            st[0].kind,
            StageKind::Dynamic {
                dt: 0.01,
                scheme: Method::Implicit(Scheme::Newmark {
                    beta: 0.25,
                    gamma: 0.5
                }),
                mass: MassKind::Lumped
            }
        );
        let st = stages(&dynamic("integrator = \"trapezoidal\""));
        assert!(matches!(
            st[0].kind,
            StageKind::Dynamic {
                scheme: Method::Trapezoidal,
                ..
            }
        ));
    }

    #[test]
    fn a_time_step_too_long_for_a_periodic_voltage_is_warned_about() {
        let sine = "[electrodes.top]\nset = \"z1\"\n\
                    voltage = { waveform = \"sine\", amplitude = 1.0, frequency = 10.0 }";
        // 10 Hz in steps of 0.01 s: 10 steps per period
        let p = plan(&[
            ("materials", DENSE),
            ("electrodes", sine),
            ("stages", &dynamic("")),
        ]);
        assert_eq!(p.warnings.len(), 1, "{:?}", p.warnings);
        assert!(p.warnings[0].contains("stage `stage0`: dt = 1e-2 s gives only 10.0 steps"));
        assert!(p.warnings[0].contains("electrode `top`"));
        // electrodes off, or a fine enough step: no warning
        let off = dynamic("electrodes_on = false");
        let p = plan(&[("materials", DENSE), ("electrodes", sine), ("stages", &off)]);
        assert!(p.warnings.is_empty(), "{:?}", p.warnings);
        let fine = "[[stages]]\nkind = \"dynamic\"\nduration = 0.1\ndt = 0.001";
        let p = plan(&[("materials", DENSE), ("electrodes", sine), ("stages", fine)]);
        assert!(p.warnings.is_empty(), "{:?}", p.warnings);
    }

    #[test]
    fn bad_kinds_steps_and_names_are_rejected() {
        let with = |t: &'static str| [("materials", DENSE), ("stages", t)];
        assert_rejected(
            &with("[[stages]]\nkind = \"statik\""),
            "stages.0.kind",
            "unknown stage kind `statik`: expected `static`, `quasi-static`, `dynamic`, `continuation`, `modes` or `frequency-response`; did you mean `static`?",
        );
        assert_rejected(
            &with("[[stages]]\nkind = \"static\"\nsteps = 0"),
            "stages.0.steps",
            "must be between 1 and 1000000; got 0",
        );
        assert_rejected(
            &with("[[stages]]\nkind = \"static\"\ndt = 0.1"),
            "stages.0.dt",
            "applies to dynamic stages only",
        );
        assert_rejected(
            &with("[[stages]]\nname = \"a\"\nkind = \"static\"\n[[stages]]\nname = \"a\"\nkind = \"static\""),
            "stages.1.name",
            "two stages are named `a`",
        );
        // `stages` is a top-level key: before the tables
        let empty = [("name", "name = \"t\"\nstages = []"), ("stages", "")];
        assert_rejected(&empty, "stages", "at least one stage is needed");
    }

    #[test]
    fn bad_time_steps_and_durations_are_rejected() {
        let with = |t: String| [("materials", DENSE.to_string()), ("stages", t)];
        let check = |t: String, key: &str, expected: &str| {
            let w = with(t);
            let w: Vec<(&str, &str)> = w.iter().map(|(a, b)| (*a, b.as_str())).collect();
            assert_rejected(&w, key, expected);
        };
        check(
            "[[stages]]\nkind = \"dynamic\"\ndt = 0.01".into(),
            "stages.0.duration",
            "missing: dynamic stages need a duration in s",
        );
        check(
            dynamic("").replace("dt = 0.01", ""),
            "stages.0.dt",
            "missing: expected time step in s (a positive number)",
        );
        check(
            dynamic("").replace("dt = 0.01", "dt = 0.5"),
            "stages.0.dt",
            "the time step 0.5 s exceeds the stage duration 0.1 s",
        );
        check(
            dynamic("").replace("dt = 0.01", "dt = 1e-9"),
            "stages.0.dt",
            "is more than 10⁷ steps",
        );
        check(
            dynamic("steps = 4"),
            "stages.0.steps",
            "applies to static stages only (dynamic stages use `dt`)",
        );
        check(
            dynamic("").replace("duration = 0.1", "duration = -0.1"),
            "stages.0.duration",
            "must be a positive finite number (duration in s); got -0.1",
        );
    }

    #[test]
    fn bad_integrators_masses_and_densities_are_rejected() {
        let with = |t: &str| vec![("materials", DENSE.to_string()), ("stages", dynamic(t))];
        let check = |w: Vec<(&str, String)>, key: &str, expected: &str| {
            let w: Vec<(&str, &str)> = w.iter().map(|(a, b)| (*a, b.as_str())).collect();
            assert_rejected(&w, key, expected);
        };
        check(
            with("integrator = \"newmrk\""),
            "stages.0.integrator",
            "unknown integrator `newmrk`: expected `midpoint`, `newmark` or `trapezoidal`; did you mean `newmark`?",
        );
        check(
            with("mass = \"diagonal\""),
            "stages.0.mass",
            "expected `consistent` or `lumped`; got `diagonal`",
        );
        check(
            vec![("stages", dynamic(""))],
            "materials.gel.density",
            "dynamic stage `stage0` needs a positive mass density in kg/m³",
        );
    }
}
