//! `[[controls]]`: an electrode's voltage (or its circuit's source, or its charge) in a stage as
//! a piecewise-linear table of knot values, the unknowns of the gradient's controls and of
//! optimal control.

use super::Ctx;
use crate::io::scenario::{InputError, Scenario};
use crate::job::plan::{Electrode, Stage, StageKind};

/// Puts each control of `s` on its stage: the knots every `interval` s of stage time (0 or
/// absent: the stage's nominal step; the last at the stage's end), at `values` or at the
/// electrode's waveform there.
pub(super) fn build_controls(
    ctx: &Ctx,
    s: &Scenario,
    stages: &mut [Stage],
    electrodes: &[Electrode],
) -> Result<(), InputError> {
    for (i, c) in s.controls.iter().enumerate() {
        let key = |k: &str| format!("controls.{i}.{k}");
        let names: Vec<&str> = electrodes.iter().map(|e| e.name.as_str()).collect();
        let e = electrodes
            .iter()
            .find(|e| e.name == c.electrode)
            .ok_or_else(|| {
                ctx.err(
                    key("electrode"),
                    format!(
                        "unknown electrode `{}` (electrodes: {})",
                        c.electrode,
                        names.join(", ")
                    ),
                )
            })?;
        // the controlled quantity: a charge (C) or a voltage (V)
        let unit = if e.charge.is_some() { "C" } else { "V" };
        let stage_names: Vec<String> = stages.iter().map(|s| s.name.clone()).collect();
        let si = match c.stage.as_deref() {
            None if stages.len() == 1 => 0,
            None => {
                return Err(ctx.err(
                    key("stage"),
                    format!("missing: which stage ({})", stage_names.join(", ")),
                ))
            }
            Some(n) => stage_names.iter().position(|s| s == n).ok_or_else(|| {
                ctx.err(
                    key("stage"),
                    format!("unknown stage `{n}` (stages: {})", stage_names.join(", ")),
                )
            })?,
        };
        let stage = &stages[si];
        let nominal = match stage.kind {
            StageKind::Dynamic { dt, .. } => dt,
            StageKind::QuasiStatic { steps } => stage.duration / steps as f64,
            _ => {
                return Err(ctx.err(
                    key("stage"),
                    format!(
                        "stage `{}` is no quasi-static or dynamic stage: a control is a history \
                         in time",
                        stage.name
                    ),
                ))
            }
        };
        if !stage.electrodes_on {
            return Err(ctx.err(
                key("stage"),
                format!("stage `{}` has its electrodes off", stage.name),
            ));
        }
        if stage.controls.iter().any(|(n, _)| *n == e.name) {
            return Err(ctx.err(
                key("electrode"),
                format!(
                    "electrode `{}` is controlled twice in stage `{}`",
                    e.name, stage.name
                ),
            ));
        }
        let interval = match c.interval {
            // 0 or absent: a knot at every nominal step
            None | Some(0.0) => nominal,
            Some(v) => ctx.positive(&key("interval"), Some(v), "knot interval in s")?,
        };
        let duration = stage.duration;
        let n = ((duration / interval) - 1e-9).ceil().max(1.0) as usize;
        if n > 1_000_000 {
            return Err(ctx.err(
                key("interval"),
                format!(
                    "{n} knots: expected an interval of at least {:e} s",
                    duration / 1e6
                ),
            ));
        }
        let times: Vec<f64> = (0..=n)
            .map(|j| (j as f64 * interval).min(duration))
            .collect();
        // the start: the electrode's charge or voltage waveform at the knots
        let start = match &e.charge {
            Some(q) => q.clone(),
            None => stage.waveform(&e.voltage),
        };
        let values = match &c.values {
            None => times.iter().map(|&t| start.value(t)).collect(),
            Some(v) if v.len() == times.len() => {
                for (j, x) in v.iter().enumerate() {
                    ctx.finite(&format!("controls.{i}.values.{j}"), *x, unit)?;
                }
                v.clone()
            }
            Some(v) => {
                return Err(ctx.err(
                    key("values"),
                    format!(
                        "{} values for {} knots (every {interval:e} s over {duration:e} s)",
                        v.len(),
                        times.len()
                    ),
                ))
            }
        };
        for (k, v) in [("lower", c.lower), ("upper", c.upper)] {
            if let Some(v) = v {
                ctx.finite(&key(k), v, unit)?;
            }
        }
        if let (Some(l), Some(u)) = (c.lower, c.upper) {
            if l >= u {
                return Err(ctx.err(
                    key("upper"),
                    format!("must exceed `lower` ({l:e} {unit}); got {u:e} {unit}"),
                ));
            }
        }
        if let Some(r) = c.max_rate {
            let what = format!("largest rate of change in {unit}/s");
            ctx.positive(&key("max_rate"), Some(r), &what)?;
        }
        stages[si]
            .controls
            .push((e.name.clone(), times.into_iter().zip(values).collect()));
    }
    Ok(())
}
