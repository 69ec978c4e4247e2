//! `deasim material`: homogeneous material-point tests of a preset or of a scenario's material,
//! with the same material code as a device run — uniaxial, equibiaxial and pure-shear ramps at
//! given stretch rates, load–unload cycles, relaxation and creep — written as CSV and plots, so
//! that a user sees a material (its rate dependence, its relaxation) before running a device.

use crate::cli::app::{load_scenario, EXIT_BAD_INPUT, EXIT_OK, EXIT_SOLVE_FAILED};
use crate::io::atomic::write_atomic;
use crate::io::plot::{line_plot, PlotSpec, Series};
use crate::io::results::ResultsDir;
use crate::material::lab::{Curve, TestSpec};
use crate::material::point_history::PointRecord;
use crate::material::registry::{build, preset, PRESETS};
use crate::material::Material;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use crate::material::lab::TESTS;

/// What to run (the command line's arguments).
#[derive(Debug, Clone)]
pub struct MaterialTest {
    /// A preset name, or a scenario file (TOML) holding the material.
    pub material: String,
    /// The material's name in a scenario file (default: its only or first material).
    pub name: Option<String>,
    /// One of [`TESTS`].
    pub test: String,
    /// The deformation of `cyclic`, `relaxation` and `creep`: `uniaxial`, `equibiaxial` or
    /// `pure-shear`.
    pub mode: String,
    /// Largest (ramps, cycles) or held (relaxation) stretch.
    pub stretch: f64,
    /// Stretch rates dλ/dt (1/s) of the ramps and cycles.
    pub rates: Vec<f64>,
    /// Held nominal stress of a creep test (Pa).
    pub stress: Option<f64>,
    /// Time (s) in which relaxation and creep tests reach their stretch or stress.
    pub ramp_time: f64,
    /// Hold time (s) of relaxation and creep tests.
    pub hold: f64,
    /// Load–unload cycles of the cyclic test.
    pub cycles: usize,
    /// Time steps per segment (ramp, hold, half cycle).
    pub steps: usize,
    pub out: Option<PathBuf>,
    /// Replace another command's or test's results in the output directory.
    pub overwrite: bool,
}

impl MaterialTest {
    /// The test to run.
    pub fn spec(&self) -> TestSpec {
        TestSpec {
            test: self.test.clone(),
            mode: self.mode.clone(),
            stretch: self.stretch,
            rates: self.rates.clone(),
            stress: self.stress,
            ramp_time: self.ramp_time,
            hold: self.hold,
            cycles: self.cycles,
            steps: self.steps,
        }
    }
}

/// Runs the command; returns the exit status.
pub fn cmd_material(args: &MaterialTest) -> i32 {
    let (label, mat) = match material(args) {
        Ok(x) => x,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    if let Err(e) = args.spec().check().map_err(|e| format!("--{e}")) {
        eprintln!("error: {e}");
        return EXIT_BAD_INPUT;
    }
    let dir = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("deasim-out").join(format!("material-{}", sanitize(&label))));
    // one test of one material: another test is another set of results
    let what = format!("{label}, {} test", args.test);
    let mut results = match ResultsDir::open(&dir, "material", &what, "", args.overwrite) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    let curves = match args.spec().curves(mat.as_ref()) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_SOLVE_FAILED;
        }
    };
    let written = write(args, &label, &dir, &curves);
    match written.and(results.record()) {
        Ok(()) => {
            summary(args, &label, &curves);
            println!("results in {}", dir.display());
            EXIT_OK
        }
        Err(e) => {
            eprintln!("error: {e}");
            EXIT_SOLVE_FAILED
        }
    }
}

/// The material: a preset by name, a file's `[material]` table (a calibration's `fitted.toml`),
/// or a scenario file's material.
fn material(args: &MaterialTest) -> Result<(String, Arc<dyn Material>), String> {
    if let Some((model, p)) = preset(&args.material) {
        if args.name.is_some() {
            return Err(format!(
                "--name selects a material of a scenario file; `{}` is a preset",
                args.material
            ));
        }
        let (m, _) = build(model, &p).map_err(|e| format!("preset `{}`: {e}", args.material))?;
        return Ok((args.material.clone(), m));
    }
    let path = Path::new(&args.material);
    if !path.exists() {
        return Err(format!(
            "`{}` is neither a preset ({}) nor a scenario file",
            args.material,
            PRESETS.join(", ")
        ));
    }
    // a `[material]` table alone: a calibration's fitted.toml (or its spec)
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if let Some(m) = crate::calibrate::spec::material_table(&text, &args.material) {
        let (model, mat) = m.map_err(|e| e.to_string())?;
        let stem = path
            .file_stem()
            .map_or(model, |s| s.to_string_lossy().into_owned());
        return Ok((stem, mat));
    }
    let (_, plan) = load_scenario(Some(path), &[]).map_err(|e| e.to_string())?;
    let names = &plan.material_names;
    let i = match &args.name {
        Some(n) => names.iter().position(|m| m == n).ok_or_else(|| {
            format!(
                "{}: no material `{n}`; the scenario has {}",
                args.material,
                names.join(", ")
            )
        })?,
        None => 0,
    };
    Ok((
        format!("{}:{}", plan.name, names[i]),
        plan.model.materials[i].clone(),
    ))
}

/// The CSV and the plots.
fn write(args: &MaterialTest, label: &str, dir: &Path, curves: &[Curve]) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut csv = format!("# deasim material {label}, {} test\n", args.test);
    csv.push_str(
        "rate_per_s,time_s,stretch,lateral_stretch,nominal_stress_pa,cauchy_stress_pa,\
         dissipated_j_per_m3\n",
    );
    for c in curves {
        for r in &c.records {
            let _ = writeln!(
                csv,
                "{},{},{},{},{},{},{}",
                c.rate, r.t, r.stretch, r.lateral, r.nominal, r.cauchy, r.dissipated
            );
        }
    }
    let file = dir.join(format!("{}.csv", args.test));
    write_atomic(&file, csv.as_bytes()).map_err(|e| format!("{}: {e}", file.display()))?;
    let series = |x: fn(&PointRecord) -> f64, y: fn(&PointRecord) -> f64| -> Vec<Series> {
        curves
            .iter()
            .map(|c| Series {
                label: c.label.clone(),
                x: c.records.iter().map(x).collect(),
                y: c.records.iter().map(y).collect(),
            })
            .collect()
    };
    let title = format!("{label}: {} test", args.test);
    let stress = |r: &PointRecord| r.nominal;
    let plots: Vec<(String, &str, &str, Vec<Series>)> = if args.test == "creep" {
        vec![(
            "stretch_time".into(),
            "time [s]",
            "stretch λ [-]",
            series(|r| r.t, |r| r.stretch),
        )]
    } else {
        vec![
            (
                "stress_stretch".into(),
                "stretch λ [-]",
                "nominal stress P₁₁ [Pa]",
                series(|r| r.stretch, stress),
            ),
            (
                "stress_time".into(),
                "time [s]",
                "nominal stress P₁₁ [Pa]",
                series(|r| r.t, stress),
            ),
        ]
    };
    for (name, x, y, s) in plots {
        let path = dir.join(format!("{}_{name}.png", args.test));
        line_plot(
            &path,
            &PlotSpec {
                title: &title,
                x_label: x,
                y_label: y,
                series: &s,
            },
        )
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// A few figures on the terminal.
fn summary(args: &MaterialTest, label: &str, curves: &[Curve]) {
    println!("{label}: {} test", args.test);
    for c in curves {
        let peak = c
            .records
            .iter()
            .map(|r| r.nominal)
            .fold(f64::NEG_INFINITY, f64::max);
        let last = c.records.last().expect("a test has steps");
        println!(
            "  {}: peak nominal stress {:.4} kPa; at t = {:.4} s: stretch {:.5}, stress {:.4} kPa, \
             dissipated {:.4} kJ/m³",
            c.label,
            peak / 1e3,
            last.t,
            last.stretch,
            last.nominal / 1e3,
            last.dissipated / 1e3
        );
    }
}

fn sanitize(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// `deasim materials [NAME]`: the models and presets, or one of them.
pub fn cmd_materials(name: Option<&str>) -> i32 {
    use crate::material::registry::{describe, parameter_names, preset, MODELS, PRESETS};
    match name {
        None => {
            println!("models (parameters):");
            for m in MODELS {
                let names = parameter_names(m).unwrap_or(&[]);
                println!("  {m:<18} {}", names.join(", "));
            }
            println!("presets (`deasim materials NAME` shows the values):");
            for p in PRESETS {
                let model = preset(p).map(|(m, _)| m).unwrap_or("?");
                println!("  {p:<26} {model}");
            }
            println!(
                "every model also takes `permittivity` (relative), `c1`, `c2` (electrostriction, \
                 F/m) and `branches = [{{ mu, tau }}, …]` (Maxwell branches, Pa and s)"
            );
            0
        }
        Some(n) => {
            if let Some((model, params)) = preset(n) {
                println!("preset `{n}`:");
                for line in describe(model, &params) {
                    println!("  {line}");
                }
                0
            } else if let Some(names) = parameter_names(n) {
                println!("model `{n}`: parameters {}", names.join(", "));
                0
            } else {
                let all = MODELS.iter().chain(PRESETS).copied();
                let hint = crate::io::scenario::closest(n, all)
                    .map(|c| format!("; did you mean `{c}`?"))
                    .unwrap_or_default();
                eprintln!(
                    "error: no material model or preset named `{n}` (models: {}; presets: {}){hint}",
                    MODELS.join(", "),
                    PRESETS.join(", ")
                );
                2
            }
        }
    }
}
