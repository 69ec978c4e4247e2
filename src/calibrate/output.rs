//! The files of a calibration: `calibration.json`, `fitted.toml` (a `[material]` table that
//! `deasim material` and a calibration spec take as they are), `fit_<experiment>.csv` and the
//! plots.

use super::Calibration;
use crate::io::atomic::write_atomic;
use crate::io::plot::{line_plot, PlotSpec, Series};
use crate::io::scenario::{BranchSpec, MaterialSpec, Numbers};
use crate::material::MaterialParams;
use std::fmt::Write as _;
use std::path::Path;

/// A finite number, or JSON null.
fn num(x: f64) -> serde_json::Value {
    serde_json::Number::from_f64(x).map_or(serde_json::Value::Null, serde_json::Value::Number)
}

/// The `calibration.json` document.
pub fn json(c: &Calibration) -> serde_json::Value {
    use serde_json::{json, Map, Value};
    let mut params = Map::new();
    for p in &c.parameters {
        params.insert(
            p.path.clone(),
            json!({
                "initial": num(p.initial),
                "fitted": num(p.fitted),
                "std_error": num(p.std_error),
                "ci95": [num(p.ci95[0]), num(p.ci95[1])],
            }),
        );
    }
    let mut by = Map::new();
    for e in &c.experiments {
        by.insert(e.name.clone(), num(e.rms));
    }
    let mut corr = Map::new();
    for (a, p) in c.parameters.iter().enumerate() {
        let mut row = Map::new();
        for (b, q) in c.parameters.iter().enumerate() {
            row.insert(q.path.clone(), num(c.correlation[a][b]));
        }
        corr.insert(p.path.clone(), Value::Object(row));
    }
    json!({
        "parameters": params,
        "rms": num(c.rms),
        "rms_by_experiment": by,
        "correlation": corr,
        "iterations": c.iterations,
        "converged": c.converged,
        "reason": c.reason,
        "start": c.start,
        "residual_variance": num(c.statistics.variance),
        "degrees_of_freedom": c.statistics.dof,
        "t_quantile": num(c.statistics.quantile),
        "jacobian_rank": c.statistics.rank,
        "warnings": c.warnings,
    })
}

/// The material table of a model and its parameters, as a scenario writes it.
pub fn material_spec(model: &str, p: &MaterialParams) -> MaterialSpec {
    MaterialSpec {
        model: Some(model.to_string()),
        mu: match p.mu.len() {
            0 => None,
            1 => Some(Numbers::One(p.mu[0])),
            _ => Some(Numbers::Many(p.mu.clone())),
        },
        alpha: (!p.alpha.is_empty()).then(|| p.alpha.clone()),
        lambda: p.lambda,
        kappa: p.kappa,
        c10: p.c10,
        c20: p.c20,
        c30: p.c30,
        c01: p.c01,
        d1: p.d1,
        d2: p.d2,
        d3: p.d3,
        jm: p.jm,
        lambda_m: p.lambda_m,
        permittivity: p.permittivity,
        c1: p.c1,
        c2: p.c2,
        branches: (!p.branches.is_empty()).then(|| {
            p.branches
                .iter()
                .map(|&(mu, tau)| BranchSpec { mu, tau })
                .collect()
        }),
        ..Default::default()
    }
}

/// `fitted.toml`: the fitted material as a `[material]` table.
pub fn fitted_toml(c: &Calibration) -> Result<String, String> {
    #[derive(serde::Serialize)]
    struct Doc {
        material: MaterialSpec,
    }
    let doc = Doc {
        material: material_spec(&c.model, &c.fitted_params),
    };
    let body = toml::to_string(&doc).map_err(|e| e.to_string())?;
    Ok(format!(
        "# deasim calibrate: the fitted material (RMS {:.6e} Pa, {})\n{body}",
        c.rms, c.reason
    ))
}

fn file_name(s: &str) -> String {
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

/// Writes every file into `dir`.
pub fn write(c: &Calibration, dir: &Path) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let put = |name: &str, bytes: &[u8]| {
        let f = dir.join(name);
        write_atomic(&f, bytes).map_err(|e| format!("{}: {e}", f.display()))
    };
    let text = serde_json::to_string_pretty(&json(c)).map_err(|e| e.to_string())?;
    put("calibration.json", text.as_bytes())?;
    put("fitted.toml", fitted_toml(c)?.as_bytes())?;
    let mut residual_series = Vec::new();
    for e in &c.experiments {
        let mut csv = String::from("stretch,time_s,measured_pa,model_pa,residual_pa\n");
        for i in 0..e.measured.len() {
            let t = e.time.as_ref().map_or(String::new(), |t| t[i].to_string());
            let _ = writeln!(
                csv,
                "{},{t},{},{},{}",
                e.stretch[i],
                e.measured[i],
                e.model[i],
                e.model[i] - e.measured[i]
            );
        }
        let stem = file_name(&e.name);
        put(&format!("fit_{stem}.csv"), csv.as_bytes())?;
        let timed = e.time.is_some();
        let (x_data, x_path, x_label) = if timed {
            (
                e.time.clone().unwrap_or_default(),
                e.path.time.clone(),
                "time [s]",
            )
        } else {
            (e.stretch.clone(), e.path.stretch.clone(), "stretch λ [-]")
        };
        let series = [
            Series {
                label: "measured".into(),
                x: x_data.clone(),
                y: e.measured.clone(),
            },
            Series {
                label: "fitted model".into(),
                x: x_path,
                y: e.path.stress.clone(),
            },
        ];
        let title = format!("{}: RMS {:.4} kPa", e.name, e.rms / 1e3);
        line_plot(
            &dir.join(format!("fit_{stem}.png")),
            &PlotSpec {
                title: &title,
                x_label,
                y_label: "nominal stress P₁₁ [Pa]",
                series: &series,
            },
        )
        .map_err(|e| e.to_string())?;
        residual_series.push(Series {
            label: e.name.clone(),
            x: (1..=e.measured.len()).map(|i| i as f64).collect(),
            y: e.model
                .iter()
                .zip(&e.measured)
                .map(|(m, d)| m - d)
                .collect(),
        });
    }
    line_plot(
        &dir.join("residuals.png"),
        &PlotSpec {
            title: "residuals (model − measured)",
            x_label: "data point [-]",
            y_label: "residual [Pa]",
            series: &residual_series,
        },
    )
    .map_err(|e| e.to_string())?;
    let names: Vec<&str> = c.parameters.iter().map(|p| p.path.as_str()).collect();
    correlation_plot(dir, &names, &c.correlation)
}

/// `correlation.png`: the correlation matrix of the fitted parameters `names`, a curve per row.
pub fn correlation_plot(
    dir: &Path,
    names: &[&str],
    correlation: &[Vec<f64>],
) -> Result<(), String> {
    let n = names.len();
    let series: Vec<Series> = names
        .iter()
        .zip(correlation)
        .map(|(name, row)| Series {
            label: name.to_string(),
            x: (1..=n).map(|i| i as f64).collect(),
            y: row.clone(),
        })
        .collect();
    line_plot(
        &dir.join("correlation.png"),
        &PlotSpec {
            title: "correlation of the fitted parameters (row per parameter)",
            x_label: "parameter number [-]",
            y_label: "correlation [-]",
            series: &series,
        },
    )
    .map_err(|e| e.to_string())
}

/// The table on the terminal.
pub fn table(c: &Calibration) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<28} {:>13} {:>13} {:>12} {:>27}",
        "parameter", "initial", "fitted", "std error", "95 % interval"
    );
    for p in &c.parameters {
        let _ = writeln!(
            s,
            "{:<28} {:>13.6e} {:>13.6e} {:>12.4e} [{:>12.5e}, {:>12.5e}]",
            p.path, p.initial, p.fitted, p.std_error, p.ci95[0], p.ci95[1]
        );
    }
    let _ = writeln!(
        s,
        "{:<28} {:>13} {:>13}",
        "experiment", "RMS start", "RMS fit"
    );
    for e in &c.experiments {
        let _ = writeln!(
            s,
            "{:<28} {:>10.4} kPa {:>9.4} kPa",
            e.name,
            e.rms_initial / 1e3,
            e.rms / 1e3
        );
    }
    let _ = writeln!(
        s,
        "overall RMS {:.4} kPa; {} iterations; {} ({})",
        c.rms / 1e3,
        c.iterations,
        if c.converged {
            "converged"
        } else {
            "not converged"
        },
        c.reason
    );
    s
}
