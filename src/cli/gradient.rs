//! `deasim gradient`: the objective's gradient in the scenario's parameters by the discrete
//! adjoint, written to `gradient.json`, with `--check` against finite differences.

use crate::api::{GradientOptions, GradientReport, Simulation};
use crate::cli::app::{fail, EXIT_OK};
use std::path::{Path, PathBuf};

/// Runs the command; returns the exit status.
pub fn cmd_gradient(
    scenario: Option<&Path>,
    out: Option<&Path>,
    overrides: &[String],
    overwrite: bool,
    // `Some(step)`: check against finite differences of that relative step (default 1e-4)
    check: Option<Option<f64>>,
) -> i32 {
    let (sim, dir) = match scenario_and_dir(scenario, overrides, out) {
        Ok(x) => x,
        Err(e) => return fail(&e),
    };
    let options = GradientOptions {
        out: Some(dir.clone()),
        overwrite,
        check: check.is_some(),
        fd_step: check.flatten(),
        memory: None,
    };
    let report = match sim.gradient(&options) {
        Ok(r) => r,
        Err(e) => return fail(&e),
    };
    let plot_format = match sim.plan() {
        Ok(p) => p.output.plots.then_some(p.output.plot_format.clone()),
        Err(e) => return fail(&e),
    };
    let written = match report.write(&dir, plot_format.as_deref()) {
        Ok(w) => w,
        Err(e) => return fail(&e),
    };
    print!("{}", table(&report));
    for path in written {
        println!("wrote {}", path.display());
    }
    EXIT_OK
}

/// The scenario with its overrides and the output directory (`out`, default
/// `deasim-out/<scenario name>`) of a command that runs it.
pub(crate) fn scenario_and_dir(
    scenario: Option<&Path>,
    overrides: &[String],
    out: Option<&Path>,
) -> Result<(Simulation, PathBuf), crate::api::Error> {
    let sim = Simulation::read(scenario)?.with_overrides(overrides);
    let dir = match out {
        Some(d) => d.to_path_buf(),
        None => PathBuf::from("deasim-out").join(sim.scenario()?.name),
    };
    Ok((sim, dir))
}

/// The terminal table: each parameter's value and derivative (and its check).
fn table(r: &GradientReport) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "J = {:.10e}", r.objective);
    let width = r
        .parameters
        .iter()
        .map(|p| p.path.len())
        .max()
        .unwrap_or(9)
        .max(9);
    let _ = write!(
        s,
        "{:width$}  {:>14}  {:>17}",
        "parameter", "value", "dJ/dp (adjoint)"
    );
    if r.taylor.is_some() {
        let _ = write!(s, "  {:>17}  {:>9}", "central FD", "rel. diff");
    }
    s.push('\n');
    for p in &r.parameters {
        let _ = write!(
            s,
            "{:width$}  {:>14.6e}  {:>17.9e}",
            p.path, p.value, p.gradient
        );
        if let Some((fd, _)) = p.finite_difference {
            let rel =
                (p.gradient - fd).abs() / fd.abs().max(p.gradient.abs()).max(f64::MIN_POSITIVE);
            let _ = write!(s, "  {fd:>17.9e}  {rel:>9.1e}");
        }
        s.push('\n');
    }
    for c in &r.controls {
        let largest = c
            .gradient
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
        let _ = write!(
            s,
            "control {} in {}: {} knots",
            c.electrode,
            c.stage,
            c.times.len()
        );
        if let Some((k, g)) = largest {
            let d = if c.quantity == crate::api::ControlQuantity::Charge {
                "dJ/dQ"
            } else {
                "dJ/dV"
            };
            let _ = write!(s, ", largest |{d}| {g:.6e} at t = {:.6e} s", c.times[k]);
        }
        s.push('\n');
        for &(k, fd, _) in &c.finite_differences {
            let g = c.gradient[k];
            let rel = (g - fd).abs() / fd.abs().max(g.abs()).max(f64::MIN_POSITIVE);
            let _ = writeln!(
                s,
                "  knot {k} (t = {:.6e} s): adjoint {g:.9e}, central FD {fd:.9e}, rel. diff {rel:.1e}",
                c.times[k]
            );
        }
    }
    if let Some(t) = &r.taylor {
        let orders: Vec<String> = t.orders.iter().map(|o| format!("{o:.2}")).collect();
        let _ = writeln!(
            s,
            "Taylor remainder orders (expected 2): {}",
            orders.join(", ")
        );
    }
    let _ = writeln!(
        s,
        "forward {:.3} s, adjoint {:.3} s ({} factorisations, {} GMRES iterations), tape at \
         most {:.1} MB (budget {:.1} MB), {} steps recomputed",
        r.forward_s,
        r.adjoint_s,
        r.adjoint_factorizations,
        r.adjoint_krylov_iterations,
        r.tape_bytes as f64 / 1e6,
        r.memory_budget as f64 / 1e6,
        r.recomputed_steps
    );
    s
}
