//! `deasim response`: the frequency response of a scenario's probes to a small harmonic voltage
//! on one electrode about its DC bias, by direct solves of the linearised system
//! ([`crate::time::frequency`]); CSV and Bode plots.

use crate::api::Error;
pub use crate::api::Prepared;
use crate::cli::app::{
    load_scenario_open_loop, EXIT_BAD_INPUT, EXIT_INTERRUPTED, EXIT_OK, EXIT_SOLVE_FAILED,
};
use crate::io::atomic::write_atomic;
use crate::io::build::log_range;
use crate::io::build::Plan;
use crate::io::linear::write_response;
use crate::io::plot::{PlotSpec, Series};
use crate::io::results::ResultsDir;
use crate::job::plan::StageKind;
use crate::job::state::FrequencyResponse;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What to compute (the command line's arguments).
#[derive(Debug, Clone)]
pub struct ResponseArgs {
    pub scenario: Option<PathBuf>,
    pub overrides: Vec<String>,
    /// The driven electrode (default: the first one with a non-zero voltage).
    pub electrode: Option<String>,
    /// DC voltage of the driven electrode (default: its voltage in the loaded state).
    pub bias: Option<f64>,
    /// Frequencies (Hz); when empty, `points` log-spaced values from `from` to `to`.
    pub frequencies: Vec<f64>,
    pub from: f64,
    pub to: f64,
    pub points: usize,
    pub out: Option<PathBuf>,
    /// Replace another command's or scenario's results in the output directory.
    pub overwrite: bool,
}

/// Runs the command; returns the exit status.
pub fn cmd_response(args: &ResponseArgs) -> i32 {
    match response(args) {
        Ok((dir, r)) => {
            println!(
                "response of {} probe(s) per volt on `{}` about {:.3} V, {} frequencies; results \
                 in {}",
                r.probes.len(),
                r.electrode,
                r.bias,
                r.frequencies.len(),
                dir.display()
            );
            EXIT_OK
        }
        Err((code, e)) => {
            eprintln!("error: {e}");
            code
        }
    }
}

type Outcome = (PathBuf, FrequencyResponse);

/// Loads the scenario and prepares its biased linearisation ([`crate::api::prepare`]); prints
/// the warning of a bias that drives nothing.
pub fn prepare(
    scenario: Option<&Path>,
    overrides: &[String],
    electrode: Option<&str>,
    bias: Option<f64>,
) -> Result<Prepared, (i32, String)> {
    let (_, plan) = load_scenario_open_loop(scenario, overrides)
        .map_err(|e| (EXIT_BAD_INPUT, e.to_string()))?;
    let p = crate::api::prepare(plan, electrode, bias, crate::api::RunOptions::default()).map_err(
        |e| {
            let code = match e {
                Error::Input(_) | Error::Refused(_) => EXIT_BAD_INPUT,
                Error::Interrupted { .. } => EXIT_INTERRUPTED,
                _ => EXIT_SOLVE_FAILED,
            };
            (code, e.to_string())
        },
    )?;
    if let Some(w) = &p.warning {
        eprintln!("warning: {w} (--bias)");
    }
    Ok(p)
}

/// The response: a solve per frequency, the probes linearised along it.
pub fn response(args: &ResponseArgs) -> Result<Outcome, (i32, String)> {
    let bad = |e: String| (EXIT_BAD_INPUT, e);
    let failed = |e: String| (EXIT_SOLVE_FAILED, e);
    let frequencies = if args.frequencies.is_empty() {
        if !(args.from > 0.0 && args.to > args.from && args.points >= 2) {
            return Err(bad(format!(
                "--from/--to/--points: expected 0 < from < to and at least 2 points; got {}, {}, {}",
                args.from, args.to, args.points
            )));
        }
        log_range(args.from, args.to, args.points)
    } else {
        args.frequencies.clone()
    };
    if let Some(f) = frequencies.iter().find(|f| !(f.is_finite() && **f > 0.0)) {
        return Err(bad(format!(
            "--frequencies: expected positive values in Hz; got {f}"
        )));
    }
    let mut p = prepare(
        args.scenario.as_deref(),
        &args.overrides,
        args.electrode.as_deref(),
        args.bias,
    )?;
    let dir: PathBuf = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("deasim-out").join(format!("{}-response", p.plan.name)));
    let hash = format!("{:016x}", p.plan.fingerprint());
    let mut results =
        ResultsDir::open(&dir, "response", &p.plan.name, &hash, args.overwrite).map_err(bad)?;
    let r = p
        .frequency_response(&frequencies)
        .map_err(|e| failed(e.to_string()))?;
    let unit = |name: &str| probe_unit(&p.plan, name);
    let written = write_response(&r, &dir, "frequency_response", Some((&dir, "png")), &unit);
    let recorded = results.record();
    let skipped = written.map_err(failed)?;
    recorded.map_err(failed)?;
    for s in skipped {
        eprintln!("warning: {s}");
    }
    Ok((dir, r))
}

/// The unit of the probe `name` of `plan` (empty when unknown).
fn probe_unit(plan: &Plan, name: &str) -> String {
    plan.probes
        .iter()
        .find(|(n, _)| n == name)
        .map(|(_, p)| p.unit.clone())
        .unwrap_or_default()
}

/// The axis title of the probe `name` of `plan`: `name [unit]`, so that the plot gives it a
/// metric prefix (µm, pF), or the name alone when its unit is unknown.
fn probe_label(plan: &Plan, name: &str) -> String {
    let unit = probe_unit(plan, name);
    if unit.is_empty() {
        name.to_string()
    } else {
        format!("{name} [{unit}]")
    }
}

/// Arguments of `deasim reduce`.
#[derive(Debug, Clone)]
pub struct ReduceArgs {
    pub scenario: Option<PathBuf>,
    pub overrides: Vec<String>,
    pub electrode: Option<String>,
    pub bias: Option<f64>,
    /// Modes kept.
    pub modes: usize,
    /// A finite element run's output directory to overlay (its first dynamic stage).
    pub compare: Option<PathBuf>,
    pub out: Option<PathBuf>,
    /// Replace another command's or scenario's results in the output directory.
    pub overwrite: bool,
    /// `Q,R`: design a sampled LQR state feedback with these weights ([`crate::time::lqr`]).
    pub lqr: Option<String>,
    /// `W,V`: the observer's noise variances (default 1,1e-2).
    pub kalman: Option<String>,
    /// The weight of the integrated tracking error (0: no integral action).
    pub integral: Option<f64>,
    /// The design's sample period (s; default: the first dynamic stage's time step).
    pub sample_time: Option<f64>,
    /// The tracked output (needed with `lqr`).
    pub track: Option<String>,
    /// The measured outputs (default: the tracked one).
    pub measure: Vec<String>,
}

/// Two positive numbers `a,b` given to option `option` (named `what`).
fn weight_pair(option: &str, text: &str, what: &str) -> Result<(f64, f64), String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let parsed: Vec<f64> = parts.iter().filter_map(|p| p.parse().ok()).collect();
    match parsed[..] {
        [a, b] if parts.len() == 2 && a.is_finite() && a > 0.0 && b.is_finite() && b > 0.0 => {
            Ok((a, b))
        }
        _ => Err(format!(
            "{option}: expected {what} as two positive numbers `a,b`; got `{text}`"
        )),
    }
}

/// The design settings of `args` (`None` without `--lqr`), the sample period defaulting to the
/// first dynamic stage's step of `plan`.
fn lqr_settings(
    args: &ReduceArgs,
    plan: &Plan,
) -> Result<Option<crate::time::lqr::LqrSettings>, String> {
    let Some(lqr) = &args.lqr else {
        for (given, name) in [
            (args.kalman.is_some(), "--kalman"),
            (args.integral.is_some(), "--integral"),
            (args.sample_time.is_some(), "--sample-time"),
            (args.track.is_some(), "--track"),
            (!args.measure.is_empty(), "--measure"),
        ] {
            if given {
                return Err(format!(
                    "{name}: an option of the design, which needs --lqr Q,R"
                ));
            }
        }
        return Ok(None);
    };
    let (q, r) = weight_pair("--lqr", lqr, "the weights Q (tracked output) and R (volt)")?;
    let tracked = args.track.clone().ok_or(
        "--lqr needs --track PROBE: the output whose set point the state feedback follows",
    )?;
    let (w, v) = match &args.kalman {
        Some(k) => weight_pair(
            "--kalman",
            k,
            "the variances W (drive disturbance) and V (measurement noise)",
        )?,
        None => (1.0, 1e-2),
    };
    let qi = match args.integral {
        None => 0.0,
        Some(x) if x.is_finite() && x >= 0.0 => x,
        Some(x) => return Err(format!("--integral: expected a weight ≥ 0 (1/s²); got {x}")),
    };
    let sample_time = match args.sample_time {
        Some(t) if t.is_finite() && t > 0.0 => t,
        Some(t) => {
            return Err(format!(
                "--sample-time: expected a positive number of s; got {t}"
            ))
        }
        None => plan
            .stages
            .iter()
            .find_map(|s| match s.kind {
                StageKind::Dynamic { dt, .. } => Some(dt),
                _ => None,
            })
            .ok_or(
                "--lqr: the scenario has no dynamic stage whose time step could be the sample \
                 period: give --sample-time",
            )?,
    };
    Ok(Some(crate::time::lqr::LqrSettings {
        weights: crate::time::lqr::Weights { q, r, w, v, qi },
        sample_time,
        tracked,
        measured: args.measure.clone(),
    }))
}

/// `deasim reduce`: the reduced state-space model, its matrices, its simulation of the first
/// dynamic stage's drive, and (with `--compare`) the overlay on a finite element history.
pub fn cmd_reduce(args: &ReduceArgs) -> i32 {
    match reduce(args) {
        Ok(lines) => {
            for l in lines {
                println!("{l}");
            }
            EXIT_OK
        }
        Err((code, e)) => {
            eprintln!("error: {e}");
            code
        }
    }
}

/// The work of [`cmd_reduce`]; returns the lines to print.
pub fn reduce(args: &ReduceArgs) -> Result<Vec<String>, (i32, String)> {
    let bad = |e: String| (EXIT_BAD_INPUT, e);
    let failed = |e: String| (EXIT_SOLVE_FAILED, e);
    if args.modes == 0 {
        return Err(bad("--modes: at least one mode".into()));
    }
    if let Some(dir) = &args.compare {
        if !dir.join("history.csv").is_file() {
            return Err(bad(format!(
                "--compare: {} holds no history.csv of a run",
                dir.display()
            )));
        }
    }
    let p = prepare(
        args.scenario.as_deref(),
        &args.overrides,
        args.electrode.as_deref(),
        args.bias,
    )?;
    let lqr = lqr_settings(args, &p.plan).map_err(bad)?;
    if let Some(s) = &lqr {
        let outputs = p.names();
        for name in std::iter::once(&s.tracked).chain(&s.measured) {
            if !outputs.contains(name) {
                return Err(bad(format!(
                    "--{}: `{name}` is not a probe of the scenario ({})",
                    if s.tracked == *name {
                        "track"
                    } else {
                        "measure"
                    },
                    outputs.join(", ")
                )));
            }
        }
    }
    let dir: PathBuf = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("deasim-out").join(format!("{}-reduced", p.plan.name)));
    let hash = format!("{:016x}", p.plan.fingerprint());
    let mut results =
        ResultsDir::open(&dir, "reduce", &p.plan.name, &hash, args.overwrite).map_err(bad)?;
    let written = write_reduced(args, &p, &dir, lqr.as_ref());
    // the files written, also when one failed
    let listed = results.record().map_err(failed);
    let lines = written?;
    listed?;
    Ok(lines)
}

/// The reduced model of `p`, its matrices, its simulation and the overlay, written into `dir`;
/// returns the lines to print.
fn write_reduced(
    args: &ReduceArgs,
    p: &Prepared,
    dir: &Path,
    lqr: Option<&crate::time::lqr::LqrSettings>,
) -> Result<Vec<String>, (i32, String)> {
    let bad = |e: String| (EXIT_BAD_INPUT, e);
    let failed = |e: String| (EXIT_SOLVE_FAILED, e);
    let names = p.names();
    let model = p
        .reduced_model(args.modes)
        .map_err(|e| failed(e.to_string()))?;
    std::fs::create_dir_all(dir).map_err(|e| failed(format!("{}: {e}", dir.display())))?;
    let json = serde_json::to_string_pretty(&model).map_err(|e| failed(e.to_string()))?;
    let put = |name: &str, text: &str| -> Result<(), (i32, String)> {
        let path = dir.join(name);
        write_atomic(&path, text.as_bytes()).map_err(|e| failed(format!("{}: {e}", path.display())))
    };
    put("reduced_model.json", &json)?;
    let matrix = |m: &[Vec<f64>]| -> String {
        m.iter()
            .map(|row| {
                row.iter()
                    .map(|v| format!("{v:e}"))
                    .collect::<Vec<_>>()
                    .join(",")
            })
            .collect::<Vec<_>>()
            .join("\n")
            + "\n"
    };
    for (name, m) in [
        ("A", &model.a),
        ("B", &model.b),
        ("C", &model.c),
        ("D", &model.d),
    ] {
        put(&format!("{name}.csv"), &matrix(m))?;
    }
    let mut lines = vec![format!(
        "{}: reduced model of {} modes ({} states) about {:.3} V on `{}`, outputs {}; modes {:.4?} Hz",
        p.plan.name,
        args.modes,
        2 * args.modes,
        p.bias,
        p.electrode,
        names.join(", "),
        model.frequencies_hz
    )];
    if let Some(settings) = lqr {
        let design = crate::time::lqr::design(&model, &p.plan.name, settings).map_err(|e| {
            let code = if e.contains("Riccati") {
                EXIT_SOLVE_FAILED
            } else {
                EXIT_BAD_INPUT
            };
            (code, format!("--lqr: {e}"))
        })?;
        let json = serde_json::to_string_pretty(&design).map_err(|e| failed(e.to_string()))?;
        put("lqr.json", &json)?;
        lines.push(lqr_line(&design));
    }
    // the first dynamic stage's drive, simulated
    let Some(si) = p
        .plan
        .stages
        .iter()
        .position(|s| matches!(s.kind, StageKind::Dynamic { .. }))
    else {
        lines.push(format!("results in {}", dir.display()));
        return Ok(lines);
    };
    let stage = &p.plan.stages[si];
    let StageKind::Dynamic { dt, .. } = stage.kind else {
        unreachable!("a dynamic stage")
    };
    let waveform = p
        .plan
        .electrodes
        .iter()
        .find(|e| e.name == p.electrode)
        .map(|e| e.voltage.clone())
        .expect("the driven electrode exists");
    let fe = match &args.compare {
        Some(d) => Some(fe_history(d, &stage.name, &names).map_err(bad)?),
        None => None,
    };
    let times: Vec<f64> = match &fe {
        Some((t, _)) => t.clone(),
        None => {
            let n = (stage.duration / dt).round().max(1.0) as usize;
            (0..=n)
                .map(|i| stage.duration * i as f64 / n as f64)
                .collect()
        }
    };
    let v = |t: f64| waveform.value(t);
    let y = model.simulate(&v, &times);
    let mut csv = String::from("time");
    for n in &names {
        let _ = write!(csv, ",{n}");
    }
    csv.push('\n');
    for (t, row) in times.iter().zip(&y) {
        let _ = write!(csv, "{t:e}");
        for v in row {
            let _ = write!(csv, ",{v:e}");
        }
        csv.push('\n');
    }
    put("reduced_history.csv", &csv)?;
    if let Some((_, fe_rows)) = &fe {
        for (k, name) in names.iter().enumerate() {
            let a: Vec<f64> = fe_rows.iter().map(|r| r[k]).collect();
            let b: Vec<f64> = y.iter().map(|r| r[k]).collect();
            let finite = |x: &f64| x.is_finite();
            let (lo, hi) = a
                .iter()
                .filter(|x| finite(x))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
                    (l.min(x), h.max(x))
                });
            let pairs: Vec<f64> = a
                .iter()
                .zip(&b)
                .filter(|(x, y)| finite(x) && finite(y))
                .map(|(x, y)| (x - y).abs())
                .collect();
            let computed = b.iter().any(finite);
            lines.push(compare_line(name, &pairs, a.len(), computed, hi - lo));
            if !computed {
                continue;
            }
            let series = [
                Series {
                    label: "finite elements".into(),
                    x: fe.as_ref().map(|f| f.0.clone()).unwrap_or_default(),
                    y: a,
                },
                Series {
                    label: format!("reduced ({} modes)", args.modes),
                    x: times.clone(),
                    y: b,
                },
            ];
            let path = dir.join(format!("compare_{name}.png"));
            let y_label = probe_label(&p.plan, name);
            crate::io::plot::line_plot(
                &path,
                &PlotSpec {
                    title: &format!("{name}: reduced model against the finite element run"),
                    x_label: "stage time [s]",
                    y_label: &y_label,
                    series: &series,
                },
            )
            .map_err(|e| failed(e.to_string()))?;
        }
    }
    lines.push(format!("results in {}", dir.display()));
    Ok(lines)
}

/// The line `reduce --lqr` prints: the gains' size and the loop's and observer's poles.
fn lqr_line(d: &crate::time::lqr::StateFeedbackDesign) -> String {
    let t = d.sample_time;
    // a pole's time constant in samples: −T / ln ρ
    let tau = |rho: f64| -t / rho.ln();
    format!(
        "state feedback (lqr.json) at {} s: tracks `{}`, observer on {}; N̄ {:e} V per unit{}, \
         spectral radius {:.4} open loop (time constant {:.3e} s), {:.4} closed loop ({:.3e} s), \
         {:.4} observer ({:.3e} s); Riccati residuals {:.1e}, {:.1e}",
        t,
        d.tracked,
        d.measured
            .iter()
            .map(|m| format!("`{m}`"))
            .collect::<Vec<_>>()
            .join(", "),
        d.n_bar,
        if d.k_i != 0.0 {
            format!(", integral gain k_I {:e} V per unit·s", d.k_i)
        } else {
            String::new()
        },
        d.open_loop_radius,
        tau(d.open_loop_radius),
        d.closed_loop_radius,
        tau(d.closed_loop_radius),
        d.observer_radius,
        tau(d.observer_radius),
        d.control_residual,
        d.filter_residual
    )
}

/// The line `reduce --compare` prints for output `name`: the largest of the differences `pairs`
/// (at the steps where both runs have a value, of `steps`) against the FE run's peak-to-peak
/// `range`. An output the reduced model does not compute (`reduced_has_values` false: NaN at
/// every step, e.g. a capacitance) or that has no step with both values is said to be not
/// compared, never reported as a difference of 0.
fn compare_line(
    name: &str,
    pairs: &[f64],
    steps: usize,
    reduced_has_values: bool,
    range: f64,
) -> String {
    if !reduced_has_values {
        return format!("{name}: not compared: the reduced model does not compute it");
    }
    if pairs.is_empty() {
        return format!("{name}: not compared: no step where both runs have a value");
    }
    let worst = pairs.iter().copied().fold(0.0, f64::max);
    let mut line = format!(
        "{name}: largest difference to the finite element run {worst:.4e} = {:.3e} of its \
         peak-to-peak {:.4e}",
        worst / range.max(f64::MIN_POSITIVE),
        range
    );
    if pairs.len() < steps {
        line.push_str(&format!(
            " (compared at {} of {steps} steps; the others have no value)",
            pairs.len()
        ));
    }
    line
}

/// The stage-time records of stage `stage` in a run's `history.csv`: times from the stage start
/// (the state it starts from included) and the probes `names`.
#[allow(clippy::type_complexity)]
fn fe_history(
    dir: &Path,
    stage: &str,
    names: &[String],
) -> Result<(Vec<f64>, Vec<Vec<f64>>), String> {
    let path = dir.join("history.csv");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let col = |n: &str| {
        head.iter()
            .position(|h| *h == n)
            .ok_or_else(|| format!("{}: no column `{n}`", path.display()))
    };
    let (ct, cs, cd) = (col("time")?, col("stage")?, col("dt")?);
    let cols: Vec<usize> = names
        .iter()
        .map(|n| col(&format!("probe:{n}")))
        .collect::<Result<_, _>>()?;
    let rows: Vec<Vec<&str>> = lines
        .map(|l| l.split(',').collect::<Vec<&str>>())
        .filter(|v| v.get(cs) == Some(&stage))
        .collect();
    let num = |s: &str| s.parse::<f64>().unwrap_or(f64::NAN);
    let first = rows
        .iter()
        .find(|v| v[2] != "0")
        .ok_or_else(|| format!("{}: no step of stage `{stage}`", path.display()))?;
    let t0 = num(first[ct]) - num(first[cd]);
    let times: Vec<f64> = rows.iter().map(|v| num(v[ct]) - t0).collect();
    let values = rows
        .iter()
        .map(|v| cols.iter().map(|&c| num(v[c])).collect())
        .collect();
    Ok((times, values))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reduced model's comparison plots carry the probe's unit, as the run's plots do.
    #[test]
    fn compare_plots_name_the_probe_unit() {
        let text = crate::io::examples::example("diaphragm").expect("example");
        let s = crate::io::scenario::parse(text, "d.toml", &[]).expect("parse");
        let plan = crate::io::build::build(&s, "d.toml", None).expect("build");
        assert_eq!(
            probe_label(&plan, "center_deflection"),
            "center_deflection [m]"
        );
        assert_eq!(probe_label(&plan, "capacitance"), "capacitance [F]");
        assert_eq!(probe_label(&plan, "no_such_probe"), "no_such_probe");
    }
}
