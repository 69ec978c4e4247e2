//! `deasim control`: the drive of the scenario's `[[controls]]` that minimises its
//! `[[objective]]`, with the optimised run's files, `control.json`, `control.csv` and
//! `controlled.toml`.

use crate::api::{ControlOptions, OptimalControl};
use crate::cli::app::{fail, EXIT_OK};
use std::path::Path;

/// Runs the command; returns the exit status.
pub fn cmd_control(
    scenario: Option<&Path>,
    out: Option<&Path>,
    overrides: &[String],
    overwrite: bool,
    limits: ControlOptions,
) -> i32 {
    let (sim, dir) = match crate::cli::gradient::scenario_and_dir(scenario, overrides, out) {
        Ok(x) => x,
        Err(e) => return fail(&e),
    };
    let options = ControlOptions {
        out: Some(dir.clone()),
        overwrite,
        ..limits
    };
    let mut count = 0usize;
    let outcome = sim.control(&options, |i| {
        println!(
            "iteration {count:>4}: J = {:.10e}, projected gradient {:.3e}, {} runs",
            i.objective, i.projected_gradient, i.evaluations
        );
        count += 1;
    });
    let outcome = match outcome {
        Ok(o) => o,
        Err(e) => return fail(&e),
    };
    let plot_format = match sim.plan() {
        Ok(p) => p.output.plots.then_some(p.output.plot_format.clone()),
        Err(e) => return fail(&e),
    };
    let mut written = match outcome.write(&dir, plot_format.as_deref()) {
        Ok(w) => w,
        Err(e) => return fail(&e),
    };
    if let Some(format) = &plot_format {
        let path = dir.join(format!("tracking.{format}"));
        match outcome.plot_tracking(&sim, &path) {
            Ok(true) => written.push(path),
            Ok(false) => {}
            Err(e) => return fail(&e),
        }
    }
    print!("{}", summary(&outcome));
    for path in written {
        println!("wrote {}", path.display());
    }
    EXIT_OK
}

/// The closing lines: the outcome and each control's range.
fn summary(o: &OptimalControl) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let first = o.history.first().map_or(f64::NAN, |i| i.objective);
    let _ = writeln!(
        s,
        "{} ({}) after {} iterations, {} runs with their adjoints, {:.1} s",
        if o.converged {
            "converged"
        } else {
            "NOT converged"
        },
        o.reason,
        o.history.len() - 1,
        o.evaluations,
        o.wall_s
    );
    let _ = writeln!(
        s,
        "J: {first:.6e} at the start, {:.10e} optimised",
        o.objective
    );
    for d in &o.drives {
        let (lo, hi) = d
            .values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        let _ = writeln!(
            s,
            "control {} in {}: {} knots, {lo:.6e} … {hi:.6e} V",
            d.electrode,
            d.stage,
            d.values.len()
        );
    }
    s
}
