//! `deasim sweep`: runs a scenario for every value of one parameter (several runs at a time where
//! memory allows) and tabulates and plots every probe's final value, maximum and steady-state
//! peak-to-peak against the swept value.

use crate::api::{run_plan, Error, RunOptions};
use crate::cli::app::{load, EXIT_BAD_INPUT, EXIT_OK, EXIT_SOLVE_FAILED};
use crate::element::CellFields;
use crate::io::atomic::write_atomic;
use crate::io::build::{Plan, StageKind};
use crate::io::output::OutputWriter;
use crate::io::plot::{stacked_plot, PlotSpec, Series};
use crate::job::observer::Observer;
use crate::job::run::StepRecord;
use crate::job::state::RunSummary;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Fewest records in the steady-state window for a peak-to-peak value (else NaN).
const MIN_WINDOW_SAMPLES: usize = 8;

/// Largest number of values of one sweep.
const MAX_VALUES: usize = 1000;

/// The swept parameter: a dotted scenario path and its values.
#[derive(Debug, Clone, PartialEq)]
pub struct Range {
    pub path: String,
    pub values: Vec<f64>,
}

/// Parses `PATH=START:STOP:N` (N values, linear or, with `log`, geometric) or `PATH=v1,v2,...`.
pub fn parse_range(spec: &str, log: bool) -> Result<Range, String> {
    let (path, rest) = spec.split_once('=').ok_or_else(|| {
        format!("--set-range `{spec}`: expected PATH=START:STOP:N or PATH=v1,v2,…")
    })?;
    let num = |s: &str| -> Result<f64, String> {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("--set-range `{spec}`: `{s}` is not a finite number"))
    };
    let values = if rest.contains(':') {
        let parts: Vec<&str> = rest.split(':').collect();
        let [a, b, n] = parts.as_slice() else {
            return Err(format!("--set-range `{spec}`: expected START:STOP:N"));
        };
        let (a, b) = (num(a)?, num(b)?);
        let n: usize = n
            .trim()
            .parse()
            .ok()
            .filter(|n| (1..=MAX_VALUES).contains(n))
            .ok_or_else(|| format!("--set-range `{spec}`: N must be between 1 and {MAX_VALUES}"))?;
        if log && (a <= 0.0 || b <= 0.0) {
            return Err(format!(
                "--set-range `{spec}`: --log needs positive START and STOP"
            ));
        }
        (0..n)
            .map(|i| {
                let s = if n == 1 {
                    0.0
                } else {
                    i as f64 / (n - 1) as f64
                };
                if log {
                    a * (b / a).powf(s)
                } else {
                    a + s * (b - a)
                }
            })
            .collect()
    } else {
        let v = rest.split(',').map(num).collect::<Result<Vec<f64>, _>>()?;
        if v.is_empty() || v.len() > MAX_VALUES {
            return Err(format!("--set-range `{spec}`: 1 to {MAX_VALUES} values"));
        }
        v
    };
    Ok(Range {
        path: path.trim().to_string(),
        values,
    })
}

/// Parses one or more `--set-range` values: the first is the swept parameter (the x axis), the
/// others move along with it (e.g. a time step that follows the frequency) and need as many values.
pub fn parse_ranges(specs: &[String], log: bool) -> Result<Vec<Range>, String> {
    if specs.is_empty() {
        return Err("--set-range: at least one PATH=START:STOP:N is needed".into());
    }
    let ranges = specs
        .iter()
        .map(|s| parse_range(s, log))
        .collect::<Result<Vec<_>, _>>()?;
    let n = ranges[0].values.len();
    if let Some(r) = ranges.iter().find(|r| r.values.len() != n) {
        return Err(format!(
            "--set-range `{}` has {} values, `{}` has {n}: ranges that move together need as many",
            r.path,
            r.values.len(),
            ranges[0].path
        ));
    }
    Ok(ranges)
}

/// Figures of one probe over one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeFigures {
    pub last: f64,
    /// The smallest finite value over the run.
    pub min: f64,
    pub max: f64,
    /// Peak-to-peak over the last period of the driving signal in the last stage (the last
    /// quarter of the stage when the signal is not periodic); NaN for a static last stage or
    /// when fewer than 8 records fall in that window.
    pub peak_to_peak: f64,
}

/// Final value, maximum and steady peak-to-peak of every probe, from the records of a run.
pub fn figures(plan: &Plan, records: &[StepRecord]) -> Vec<ProbeFigures> {
    let Some(last_stage) = plan.stages.last() else {
        return Vec::new();
    };
    let t_end = records.last().map(|r| r.time).unwrap_or(0.0);
    let period = if last_stage.electrodes_on {
        plan.electrodes
            .iter()
            .find_map(|e| e.voltage.frequency().map(|f| 1.0 / f))
    } else {
        None
    };
    let window = match period {
        Some(p) if p <= last_stage.duration => p,
        _ => 0.25 * last_stage.duration,
    };
    let dynamic = matches!(last_stage.kind, StageKind::Dynamic { .. });
    (0..plan.probes.len())
        .map(|i| {
            let values = records
                .iter()
                .map(|r| r.probes[i])
                .filter(|v| v.is_finite());
            let min = values.clone().fold(f64::NAN, f64::min);
            let max = values.clone().fold(f64::NAN, f64::max);
            let tail: Vec<f64> = records
                .iter()
                .filter(|r| r.stage == last_stage.name && r.time >= t_end - window * (1.0 + 1e-9))
                .map(|r| r.probes[i])
                .filter(|v| v.is_finite())
                .collect();
            // too few samples in the window cannot show a peak-to-peak (the step is too long)
            let peak_to_peak = if dynamic && tail.len() >= MIN_WINDOW_SAMPLES {
                tail.iter().fold(f64::MIN, |a, &b| a.max(b))
                    - tail.iter().fold(f64::MAX, |a, &b| a.min(b))
            } else {
                f64::NAN
            };
            ProbeFigures {
                last: records.last().map(|r| r.probes[i]).unwrap_or(f64::NAN),
                min,
                max,
                peak_to_peak,
            }
        })
        .collect()
}

/// Forwards the steps and the end of a run to its output writer (a sweep's runs write their
/// history, fields and summary).
struct Forward<'a> {
    writer: &'a mut OutputWriter,
}

impl Observer for Forward<'_> {
    fn step(&mut self, plan: &Plan, record: &StepRecord, state: &[f64], fields: &[CellFields]) {
        self.writer.step(plan, record, state, fields);
    }
    fn finished(&mut self, plan: &Plan, summary: &RunSummary) {
        self.writer.finished(plan, summary);
    }
}

/// One finished run of the sweep.
struct Outcome {
    value: f64,
    converged: bool,
    error: Option<String>,
    /// The run's warnings (dielectric breakdown, aliasing, …).
    warnings: Vec<String>,
    figures: Vec<ProbeFigures>,
}

/// Runs the sweep; returns the exit status (1 when a run failed, after writing the rest).
pub fn cmd_sweep(
    scenario: Option<&Path>,
    out: Option<&Path>,
    overrides: &[String],
    ranges: &[String],
    log: bool,
    jobs: Option<usize>,
    overwrite: bool,
) -> i32 {
    let ranges = match parse_ranges(ranges, log) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    // a `--set` of a swept path would be overridden by the range's value: refused, not ignored
    for o in overrides {
        let path = o.split_once('=').map_or(o.as_str(), |(p, _)| p).trim();
        let swept = ranges.iter().find(|r| {
            path == r.path
                || r.path.starts_with(&format!("{path}."))
                || path.starts_with(&format!("{}.", r.path))
        });
        if let Some(r) = swept {
            eprintln!(
                "error: `--set {o}` sets `{}`, which the sweep varies (`--set-range`): give its \
                 values in the range only",
                r.path
            );
            return EXIT_BAD_INPUT;
        }
    }
    let range = &ranges[0];
    // every value must give a valid scenario before anything runs
    let mut plans = Vec::new();
    for (k, &v) in range.values.iter().enumerate() {
        let mut sets = overrides.to_vec();
        for r in &ranges {
            sets.push(format!("{}={}", r.path, r.values[k]));
        }
        // per-run outputs: history and summary, the last state's fields, no plots
        sets.push("output.plots=false".into());
        sets.push("output.fields_every=0".into());
        match load(scenario, &sets) {
            Ok(p) => plans.push((v, p)),
            Err(e) => {
                eprintln!("error: {} = {v}: {e}", range.path);
                return EXIT_BAD_INPUT;
            }
        }
    }
    let name = plans[0].1.name.clone();
    let dir: PathBuf = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| Path::new("deasim-out").join(format!("{name}-sweep")));
    // the runs are many models: the manifest names the scenario alone
    let mut listed = match crate::io::results::ResultsDir::open(&dir, "sweep", &name, "", overwrite)
    {
        Ok(l) => l,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    if let Err(e) = std::fs::create_dir_all(dir.join("plots")) {
        eprintln!("error: cannot create {}: {e}", dir.display());
        return EXIT_BAD_INPUT;
    }
    let workers = jobs
        .unwrap_or_else(|| default_jobs(&plans[0].1))
        .clamp(1, plans.len());
    eprintln!(
        "deasim sweep: `{name}`, {} = {} values, {workers} run(s) at a time; output in {}",
        range.path,
        plans.len(),
        dir.display()
    );
    let _ = ctrlc::set_handler(|| {
        if crate::solve::interrupt::request() {
            std::process::exit(crate::cli::app::EXIT_INTERRUPTED);
        }
    });
    let queue = Mutex::new(plans.into_iter().enumerate().collect::<Vec<_>>());
    let results: Mutex<Vec<(usize, Outcome)>> = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let Some((i, (value, plan))) = queue.lock().map(|mut q| q.pop()).ok().flatten()
                else {
                    break;
                };
                let sets: Vec<(String, f64)> = ranges
                    .iter()
                    .map(|r| (r.path.clone(), r.values[i]))
                    .collect();
                let outcome = run_one(&dir, i, value, &plan, &sets);
                eprintln!(
                    "  run {i}: {} = {value:e}: {}",
                    range.path,
                    if outcome.converged {
                        "converged".to_string()
                    } else {
                        format!(
                            "FAILED ({})",
                            outcome.error.as_deref().unwrap_or("no reason given")
                        )
                    }
                );
                for w in &outcome.warnings {
                    eprintln!("    warning: {w}");
                }
                if let Ok(mut r) = results.lock() {
                    r.push((i, outcome));
                }
            });
        }
    });
    let mut results = results.into_inner().unwrap_or_default();
    results.sort_by_key(|r| r.0);
    let plan = match load(scenario, overrides) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    let outcomes: Vec<Outcome> = results.into_iter().map(|r| r.1).collect();
    let written = write_table(&dir, &plan, &ranges, &outcomes, log);
    if let Err(e) = written.and(listed.record()) {
        eprintln!("error: {e}");
        return EXIT_SOLVE_FAILED;
    }
    let failed: Vec<String> = outcomes
        .iter()
        .filter(|o| !o.converged)
        .map(|o| {
            format!(
                "{} = {:e}: {}",
                range.path,
                o.value,
                o.error.as_deref().unwrap_or("")
            )
        })
        .collect();
    if failed.is_empty() {
        EXIT_OK
    } else {
        for f in &failed {
            eprintln!("error: {f}");
        }
        EXIT_SOLVE_FAILED
    }
}

/// Runs the sweep's run `i` into `dir/runs/<i>/`, which records its swept values
/// (`sweep-value.json`: parameter path → value).
fn run_one(dir: &Path, i: usize, value: f64, plan: &Plan, sets: &[(String, f64)]) -> Outcome {
    let run_dir = dir.join(format!("runs/{i:03}"));
    let failed = |e: String| Outcome {
        value,
        converged: false,
        error: Some(e),
        warnings: Vec::new(),
        figures: Vec::new(),
    };
    if let Err(e) = OutputWriter::check_directory(&run_dir, &plan.name, true) {
        return failed(e);
    }
    let mut writer = match OutputWriter::new(&run_dir) {
        Ok(w) => w,
        Err(e) => return failed(format!("{}: {e}", run_dir.display())),
    };
    writer.overrides = sets.iter().map(|(k, v)| format!("{k}={v}")).collect();
    let values: serde_json::Map<String, serde_json::Value> = sets
        .iter()
        .map(|(k, v)| (k.clone(), serde_json::json!(v)))
        .collect();
    let json = serde_json::to_string_pretty(&values).unwrap_or_else(|_| "{}".into());
    if let Err(e) = write_atomic(&run_dir.join("sweep-value.json"), json.as_bytes()) {
        return failed(format!(
            "{}: {e}",
            run_dir.join("sweep-value.json").display()
        ));
    }
    let mut forward = Forward {
        writer: &mut writer,
    };
    let ran = run_plan(
        plan,
        RunOptions {
            observers: vec![&mut forward],
            ..RunOptions::default()
        },
    );
    let (summary, records) = match ran {
        Ok(r) => (r.summary, r.records),
        Err(Error::Solve { results, .. } | Error::Interrupted { results, .. }) => {
            (results.summary, results.records)
        }
        Err(e) => return failed(e.to_string()),
    };
    let figures = figures(plan, &records);
    let failure = writer.write_failure();
    Outcome {
        value,
        converged: summary.converged && failure.is_none(),
        error: summary.error.or(failure),
        warnings: summary.warnings,
        figures,
    }
}

/// Runs at a time: the cores, limited by the available memory over a rough per-run estimate
/// (≈ 40 kB per unknown for the tangent, its factor and the work vectors).
fn default_jobs(plan: &Plan) -> usize {
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let per_run = 40e3 * (plan.model.mesh.n_nodes() * 4) as f64 + 50e6;
    let available = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("MemAvailable:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<f64>().ok())
        })
        .map(|kb| kb * 1024.0)
        .unwrap_or(2e9);
    cores.min((0.8 * available / per_run).floor().max(1.0) as usize)
}

/// Writes `sweep.csv` and one plot per probe; prints the table.
fn write_table(
    dir: &Path,
    plan: &Plan,
    ranges: &[Range],
    outcomes: &[Outcome],
    log: bool,
) -> Result<(), String> {
    let range = &ranges[0];
    let mut csv = String::new();
    for r in ranges {
        let _ = write!(csv, "{},", r.path);
    }
    csv.push_str("converged,status,warnings");
    for (name, _) in &plan.probes {
        let _ = write!(
            csv,
            ",{name}:final,{name}:min,{name}:max,{name}:peak_to_peak"
        );
    }
    csv.push('\n');
    // a free text in one CSV field: quoted, inner quotes doubled
    let quoted = |t: &str| format!("\"{}\"", t.replace('"', "\"\""));
    for (k, o) in outcomes.iter().enumerate() {
        for r in ranges {
            let _ = write!(csv, "{:e},", r.values[k]);
        }
        let status = if o.converged {
            "converged".to_string()
        } else {
            format!(
                "failed: {}",
                o.error.as_deref().unwrap_or("no reason given")
            )
        };
        let _ = write!(
            csv,
            "{},{},{}",
            o.converged,
            quoted(&status),
            quoted(&o.warnings.join("; "))
        );
        for i in 0..plan.probes.len() {
            // a failed run has no final value: its cells stay empty
            match o.figures.get(i).filter(|_| o.converged) {
                Some(f) => {
                    let _ = write!(
                        csv,
                        ",{:e},{:e},{:e},{:e}",
                        f.last, f.min, f.max, f.peak_to_peak
                    );
                }
                None => csv.push_str(",,,,"),
            }
        }
        csv.push('\n');
    }
    write_atomic(&dir.join("sweep.csv"), csv.as_bytes())
        .map_err(|e| format!("{}: {e}", dir.join("sweep.csv").display()))?;
    print!("{csv}");
    let x: Vec<f64> = outcomes
        .iter()
        .map(|o| if log { o.value.log10() } else { o.value })
        .collect();
    let unit = parameter_unit(&range.path);
    let x_label = match (log, unit) {
        (true, Some(u)) => format!("log10 {} (in {u})", range.path),
        (true, None) => format!("log10 {}", range.path),
        (false, Some(u)) => format!("{} [{u}]", range.path),
        (false, None) => range.path.clone(),
    };
    let ext = &plan.output.plot_format;
    for (i, (name, _)) in plan.probes.iter().enumerate() {
        // failed runs are not drawn (NaN points are skipped)
        let pick = |f: fn(&ProbeFigures) -> f64| -> Vec<f64> {
            outcomes
                .iter()
                .map(|o| {
                    o.figures
                        .get(i)
                        .filter(|_| o.converged)
                        .map(f)
                        .unwrap_or(f64::NAN)
                })
                .collect()
        };
        let mut panels = vec![
            ("final value", "final", pick(|f| f.last)),
            ("maximum", "maximum", pick(|f| f.max)),
        ];
        let pp = pick(|f| f.peak_to_peak);
        if pp.iter().any(|v| v.is_finite()) {
            panels.push(("steady peak-to-peak (last period)", "peak-to-peak", pp));
        }
        let series: Vec<Series> = panels
            .iter()
            .map(|(_, label, y)| Series {
                label: label.to_string(),
                x: x.clone(),
                y: y.clone(),
            })
            .collect();
        let path = dir.join(format!("plots/sweep_{name}.{ext}"));
        let y_label = crate::io::output::probe_axis(name, &plan.probes[i].1);
        let titles: Vec<String> = panels
            .iter()
            .map(|(what, ..)| format!("{name}: {what}"))
            .collect();
        // one panel per statistic: their magnitudes differ (a peak-to-peak is small beside a
        // final value), so one shared axis would flatten some of them
        let specs: Vec<PlotSpec> = series
            .iter()
            .zip(&titles)
            .map(|(s, title)| PlotSpec {
                title,
                x_label: &x_label,
                y_label: &y_label,
                series: std::slice::from_ref(s),
            })
            .collect();
        if let Err(e) = stacked_plot(&path, &specs) {
            eprintln!("warning: {e}");
        }
    }
    Ok(())
}

/// The SI unit of a swept scenario value, by its key, when the key says it.
fn parameter_unit(path: &str) -> Option<&'static str> {
    let key = path.rsplit('.').next().unwrap_or(path);
    let in_voltage = path.split('.').any(|k| k == "voltage");
    Some(match key {
        "voltage" => "V",
        "amplitude" | "offset" if in_voltage => "V",
        "frequency" | "shift_hz" => "Hz",
        "duration" | "dt" | "rise_time" | "at" | "hold" => "s",
        "mass" => "kg",
        "density" => "kg/m³",
        "mu" | "kappa" | "lambda" | "c10" | "c01" | "c20" | "c30" => "Pa",
        "stretch" | "permittivity" | "jm" | "duty" => "-",
        "viscosity" => "Pa·s",
        "breakdown_field" => "V/m",
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse_and_reject() {
        let r = parse_range("electrodes.top.voltage.amplitude=0:5000:6", false).unwrap();
        assert_eq!(r.path, "electrodes.top.voltage.amplitude");
        assert_eq!(r.values, vec![0.0, 1000.0, 2000.0, 3000.0, 4000.0, 5000.0]);
        let r = parse_range("f=1:1e4:5", true).unwrap();
        for (v, e) in r.values.iter().zip([1.0, 10.0, 100.0, 1000.0, 1e4]) {
            assert!((v - e).abs() < 1e-9 * e);
        }
        assert_eq!(
            parse_range("a=1,2.5", false).unwrap().values,
            vec![1.0, 2.5]
        );
        for bad in [
            "a",
            "a=1:2",
            "a=1:2:0",
            "a=x:2:3",
            "a=nan:1:2",
            "a=1:2:3:4",
            "a=",
        ] {
            assert!(parse_range(bad, false).is_err(), "{bad}");
        }
        assert!(parse_range("a=0:10:3", true).is_err());
        let r = parse_ranges(&["f=1:100:3".into(), "dt=0.01,0.001,0.0001".into()], false).unwrap();
        assert_eq!(r[1].values, vec![0.01, 0.001, 0.0001]);
        assert!(parse_ranges(&["f=1:100:3".into(), "dt=1,2".into()], false).is_err());
        assert!(parse_ranges(&[], false).is_err());
    }
}
