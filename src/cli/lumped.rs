//! `deasim lumped`: the lumped diaphragm model of a scenario, its linearisation, a simulation of
//! the first dynamic stage, and the comparison with a finite element history.

use crate::cli::app::{load_scenario, EXIT_BAD_INPUT, EXIT_OK, EXIT_SOLVE_FAILED};
use crate::io::atomic::write_atomic;
use crate::io::build::Plan;
use crate::io::plot::{line_plot, PlotSpec, Series};
use crate::io::results::ResultsDir;
use crate::job::probes::ProbeKind;
use crate::lumped::setup::{from_scenario, LumpedSetup};
use crate::lumped::History;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Runs the command; returns the exit status.
pub fn cmd_lumped(
    scenario: Option<&Path>,
    out: Option<&Path>,
    overrides: &[String],
    compare: Option<&Path>,
    overwrite: bool,
) -> i32 {
    let file = scenario
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| format!("<embedded {}>", crate::io::examples::DEFAULT));
    let (s, plan) = match load_scenario(scenario, overrides) {
        Ok(x) => x,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    let setup = match from_scenario(&s, &plan, &file) {
        Ok(x) => x,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    if let Some(fe_dir) = compare {
        match check_compare(fe_dir, &plan, overrides) {
            Ok(warnings) => warnings
                .iter()
                .for_each(|w| eprintln!("warning: --compare: {w}")),
            Err(e) => {
                eprintln!("error: --compare: {e}");
                return EXIT_BAD_INPUT;
            }
        }
    }
    let dir: PathBuf = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| Path::new("deasim-out").join(format!("{}-lumped", plan.name)));
    let hash = format!("{:016x}", plan.fingerprint());
    let mut results = match ResultsDir::open(&dir, "lumped", &plan.name, &hash, overwrite) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    let written = run(&setup, &plan, &dir, compare);
    match written.and(results.record()) {
        Ok(()) => EXIT_OK,
        Err(e) => {
            eprintln!("error: {e}");
            EXIT_SOLVE_FAILED
        }
    }
}

/// Checks, before simulating, that `fe_dir` holds a finite element run of this model to compare
/// with: its `history.csv` and `summary.json` must be readable and be a run of the same scenario
/// (else the error: comparing the diaphragm with a film means nothing). A run whose model differs
/// (its `model_hash`: an edited material, geometry, load, drive or stage, or other `--set`
/// overrides) or that did not finish gives warnings.
fn check_compare(fe_dir: &Path, plan: &Plan, overrides: &[String]) -> Result<Vec<String>, String> {
    let name = &plan.name;
    let history = fe_dir.join("history.csv");
    if !history.is_file() {
        return Err(format!(
            "{} holds no history.csv: give the output directory of a `deasim run`",
            fe_dir.display()
        ));
    }
    let path = fe_dir.join("summary.json");
    let summary: serde_json::Value = std::fs::read_to_string(&path)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))
        .and_then(|t| {
            serde_json::from_str(&t).map_err(|e| format!("{}: not JSON: {e}", path.display()))
        })?;
    match summary["scenario"].as_str() {
        Some(s) if s == name => {}
        other => {
            return Err(format!(
                "{} holds a run of scenario `{}`, not of `{name}`: compare with a run of the same \
                 scenario",
                fe_dir.display(),
                other.unwrap_or("?")
            ))
        }
    }
    let mut warnings = Vec::new();
    if summary["converged"] != serde_json::Value::Bool(true) {
        warnings.push(format!(
            "the run in {} did not finish ({}): the comparison covers its recorded part only",
            fe_dir.display(),
            summary["error"].as_str().unwrap_or("interrupted")
        ));
    }
    let theirs: Vec<&str> = summary["overrides"]
        .as_array()
        .map(|l| l.iter().filter_map(|v| v.as_str()).collect())
        .unwrap_or_default();
    let ours: Vec<&str> = overrides.iter().map(String::as_str).collect();
    let ours_hash = format!("{:016x}", plan.model_hash());
    match summary["model_hash"].as_str() {
        Some(h) if h == ours_hash => {}
        Some(_) => warnings.push(format!(
            "the run in {} solved another model than this scenario's (its material, geometry, \
             loads, drive or stages differ; its overrides [{}], these [{}]): the comparison is \
             not of the same device",
            fe_dir.display(),
            theirs.join(", "),
            ours.join(", ")
        )),
        None => warnings.push(format!(
            "{} records no model_hash (a run of an older deasim): cannot tell whether it solved \
             the same model",
            path.display()
        )),
    }
    Ok(warnings)
}

/// Names of the scenario's probes of the kinds the lumped model computes (FE names where the
/// scenario has such a probe).
struct Names {
    deflection: String,
    capacitance: String,
    charge: String,
    field: String,
}

fn names(plan: &Plan) -> Names {
    let find = |pred: &dyn Fn(&ProbeKind) -> bool, default: &str| {
        plan.probes
            .iter()
            .find(|p| pred(&p.1.kind) && p.1.scale == 1.0 && p.1.offset == 0.0)
            .map(|p| p.0.clone())
            .unwrap_or_else(|| default.to_string())
    };
    Names {
        deflection: find(
            &|k| matches!(k, ProbeKind::Deflection(..)),
            "center_deflection",
        ),
        capacitance: find(&|k| matches!(k, ProbeKind::Capacitance(_)), "capacitance"),
        charge: find(&|k| matches!(k, ProbeKind::Charge(_)), "charge"),
        field: find(&|k| matches!(k, ProbeKind::MaxElectricField), "max_field"),
    }
}

/// Simulates, prints, writes `lumped.csv` and plots into `dir`, and compares with the FE
/// history in `compare` when given.
fn run(setup: &LumpedSetup, plan: &Plan, dir: &Path, compare: Option<&Path>) -> Result<(), String> {
    let model = &setup.model;
    let (lin, history, dt) = setup.simulate().map_err(|e| e.to_string())?;
    let peak = (0..2001)
        .map(|i| {
            setup
                .waveform
                .value(setup.duration * i as f64 / 2000.0)
                .abs()
        })
        .fold(0.0, f64::max);
    println!("lumped diaphragm model of `{}` (docs/lumped.md)", plan.name);
    println!(
        "  membrane: T₀ = {:.4} N/m, h = {:.4e} m, 2πT₀/ln(b/a) = {:.4} N/m",
        model.prestress_tension(),
        model.flat_thickness(),
        model.membrane_stiffness()
    );
    print!("  {lin}");
    println!(
        "  C(x0) is the lumped model's parallel-plate capacitance, ε ∫ (current area / current \
         thickness) over the electroded annulus only; the finite element `capacitance` probe \
         also counts the fringing field beyond the electrode's edge and the field's \
         non-uniformity, so at the same state it reads somewhat higher"
    );
    println!(
        "  static deflection: {:.6e} m at 0 V; natural frequency {:.4} Hz, damping ratio {:.4}",
        lin.equilibrium,
        lin.natural_frequency(),
        lin.damping_ratio()
    );
    if peak > 0.0 {
        match model.static_deflection(peak) {
            Ok(x) => println!(
                "  static deflection at the peak voltage {peak:.1} V: {x:.6e} m (extra {:.4e} m)",
                x - lin.equilibrium
            ),
            Err(e) => println!("  no static equilibrium at the peak voltage {peak:.1} V: {e}"),
        }
    }
    std::fs::create_dir_all(dir.join("plots"))
        .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let n = names(plan);
    let mut csv = format!(
        "time,voltage,probe:{},probe:{},probe:{},probe:{}\n",
        n.deflection, n.capacitance, n.charge, n.field
    );
    for s in &history.samples {
        let c = s.capacitance + setup.pad_capacitance;
        let _ = writeln!(
            csv,
            "{:e},{:e},{:e},{:e},{:e},{:e}",
            setup.start + s.time,
            s.voltage,
            s.deflection,
            c,
            c * s.voltage,
            s.max_field
        );
    }
    let csv_path = dir.join("lumped.csv");
    write_atomic(&csv_path, csv.as_bytes()).map_err(|e| e.to_string())?;
    let t: Vec<f64> = history
        .samples
        .iter()
        .map(|s| setup.start + s.time)
        .collect();
    let x: Vec<f64> = history.samples.iter().map(|s| s.deflection).collect();
    let mut series = vec![Series {
        label: "lumped".into(),
        x: t.clone(),
        y: x.clone(),
    }];
    let last = history.samples.last().map(|s| s.deflection).unwrap_or(0.0);
    println!(
        "  simulated {} s in {} steps of {dt:.3e} s: final deflection {last:.6e} m, mean over the stage {:.6e} m",
        setup.duration,
        history.samples.len().saturating_sub(1),
        history.mean_deflection(0.0, setup.duration)
    );
    if let Some(fe_dir) = compare {
        let fe = read_fe(fe_dir, &n.deflection, setup.start)?;
        let report = difference(&history, setup.start, &fe, lin.equilibrium);
        println!(
            "  against the finite element history in {}:",
            fe_dir.display()
        );
        println!(
            "    static deflection: FE {:.6e} m, lumped {:.6e} m (relative difference {:+.3e})",
            fe.static_deflection,
            lin.equilibrium,
            (lin.equilibrium - fe.static_deflection) / fe.static_deflection
        );
        println!(
            "    during the stage: max |lumped − FE| = {:.4e} m; of the extra deflection (each from \
             its own static state) {:.4e} m; peak-to-peak FE {:.4e} m, lumped {:.4e} m",
            report.max_abs, report.max_abs_extra, report.fe_range, report.lumped_range
        );
        series.push(Series {
            label: "finite elements".into(),
            x: fe.t.clone(),
            y: fe.x.clone(),
        });
    }
    let plot = dir.join(format!("plots/lumped_{}.png", n.deflection));
    line_plot(
        &plot,
        &PlotSpec {
            title: "pad deflection: lumped model",
            x_label: "time [s]",
            y_label: "center deflection [m]",
            series: &series,
        },
    )
    .map_err(|e| e.to_string())?;
    println!("  wrote {} and {}", csv_path.display(), plot.display());
    Ok(())
}

/// The FE center deflection during the first dynamic stage (from `start`), and at its start.
struct FeHistory {
    t: Vec<f64>,
    x: Vec<f64>,
    static_deflection: f64,
}

fn read_fe(dir: &Path, probe: &str, start: f64) -> Result<FeHistory, String> {
    let path = dir.join("history.csv");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| format!("{}: no column `{name}`", path.display()))
    };
    let (ct, cx) = (col("time")?, col(&format!("probe:{probe}"))?);
    let mut fe = FeHistory {
        t: Vec::new(),
        x: Vec::new(),
        static_deflection: f64::NAN,
    };
    for (i, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let num = |c: usize| {
            f.get(c)
                .and_then(|v| v.parse::<f64>().ok())
                .ok_or_else(|| format!("{}:{}: bad number", path.display(), i + 2))
        };
        let (t, x) = (num(ct)?, num(cx)?);
        if t <= start + 1e-12 {
            fe.static_deflection = x;
        } else {
            fe.t.push(t);
            fe.x.push(x);
        }
    }
    if fe.t.is_empty() || !fe.static_deflection.is_finite() {
        return Err(format!(
            "{}: no rows of the dynamic stage starting at t = {start} s",
            path.display()
        ));
    }
    Ok(fe)
}

/// Largest difference of the lumped deflection (interpolated) from the FE one, and both ranges.
struct Difference {
    max_abs: f64,
    max_abs_extra: f64,
    fe_range: f64,
    lumped_range: f64,
}

fn difference(h: &History, start: f64, fe: &FeHistory, x0: f64) -> Difference {
    let s = &h.samples;
    let interp = |t: f64| {
        let tl = t - start;
        let i = s.partition_point(|p| p.time < tl).clamp(1, s.len() - 1);
        let (a, b) = (&s[i - 1], &s[i]);
        let w = if b.time > a.time {
            ((tl - a.time) / (b.time - a.time)).clamp(0.0, 1.0)
        } else {
            1.0
        };
        a.deflection + w * (b.deflection - a.deflection)
    };
    let range = |v: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = v.fold((f64::MAX, f64::MIN), |(l, h), x| (l.min(x), h.max(x)));
        hi - lo
    };
    let max_diff = |shift: f64| {
        fe.t.iter()
            .zip(&fe.x)
            .map(|(&t, &x)| (interp(t) - x - shift).abs())
            .fold(0.0, f64::max)
    };
    Difference {
        max_abs: max_diff(0.0),
        max_abs_extra: max_diff(x0 - fe.static_deflection),
        fe_range: range(&mut fe.x.iter().copied()),
        lumped_range: range(&mut s.iter().map(|p| p.deflection)),
    }
}
