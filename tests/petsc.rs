//! The PETSc linear solver (`[solver] kind = "petsc"`, a build with `--features petsc`) against
//! the default sparse LDLᵀ on the examples, and the pass-through of PETSc options.
//!
//! Reference: the same scenario run with the default `direct` solver. Both default methods are
//! exact factorisations (MUMPS's LDLᵀ and faer's LDLᵀ), so every probe at every step agrees to
//! round-off amplified by the conditioning of the Newton systems: 1e-10 relative to the largest
//! magnitude of that probe over the run. An iterative method agrees to its own tolerance, and one
//! that cannot converge makes the run fail instead of giving a number.
#![cfg(feature = "petsc")]

use deasim::io::build::{build, Plan};
use deasim::io::examples::example;
use deasim::io::scenario::parse;
use deasim::job::run::{run, Observer, RunSummary, StepRecord};
use deasim::solve::newton::NewtonSettings;
use std::time::Instant;

/// Keeps every record.
#[derive(Default)]
struct Records(Vec<StepRecord>);

impl Observer for Records {
    fn step(&mut self, _: &Plan, r: &StepRecord, _: &[f64], _: &[deasim::element::CellFields]) {
        self.0.push(r.clone());
    }
    fn finished(&mut self, _: &Plan, _: &RunSummary) {}
}

/// Runs an example with a `[solver]` table appended (none: the default solver).
fn run_example(name: &str, solver: Option<&str>) -> (Plan, RunSummary, Records) {
    let mut text = example(name).unwrap().to_string();
    assert!(
        !text.contains("[solver]"),
        "{name} already chooses a solver"
    );
    if let Some(s) = solver {
        text.push_str("\n[solver]\n");
        text.push_str(s);
        text.push('\n');
    }
    let scenario = parse(&text, "test.toml", &[]).unwrap_or_else(|e| panic!("{e}"));
    let plan = build(&scenario, "test.toml", None).unwrap_or_else(|e| panic!("{e}"));
    let mut records = Records::default();
    let t = Instant::now();
    let summary = run(&plan, &NewtonSettings::default(), &mut records);
    eprintln!(
        "{name} with {}: {:.2} s",
        plan.solver.describe(),
        t.elapsed().as_secs_f64()
    );
    (plan, summary, records)
}

/// The largest difference of any probe at any step, relative to that probe's largest magnitude.
fn probe_difference(plan: &Plan, a: &Records, b: &Records) -> f64 {
    assert_eq!(a.0.len(), b.0.len(), "different numbers of steps");
    let mut worst: f64 = 0.0;
    for (k, (name, _)) in plan.probes.iter().enumerate() {
        let finite = |v: f64| v.is_finite().then_some(v.abs());
        let scale =
            a.0.iter()
                .filter_map(|r| finite(r.probes[k]))
                .fold(0.0, f64::max);
        if scale == 0.0 {
            continue;
        }
        for (ra, rb) in a.0.iter().zip(&b.0) {
            let (va, vb) = (ra.probes[k], rb.probes[k]);
            // undefined in both (a capacitance at zero voltage) is agreement
            if va.is_nan() && vb.is_nan() {
                continue;
            }
            let d = (va - vb).abs() / scale;
            assert!(d.is_finite(), "probe {name}: {va} vs {vb}");
            worst = worst.max(d);
        }
    }
    worst
}

fn agrees_with_the_direct_solver(name: &str) {
    let (plan, reference_summary, reference) = run_example(name, None);
    assert!(reference_summary.converged, "{:?}", reference_summary.error);
    let (_, summary, petsc) = run_example(name, Some("kind = \"petsc\""));
    assert!(summary.converged, "{:?}", summary.error);
    let d = probe_difference(&plan, &reference, &petsc);
    eprintln!("{name}: largest relative probe difference PETSc/MUMPS vs faer LDLT: {d:.2e}");
    assert!(d < 1e-10, "{name}: {d:e}");
}

#[test]
fn film_agrees_with_the_direct_solver() {
    agrees_with_the_direct_solver("film");
}

#[test]
fn stack_agrees_with_the_direct_solver() {
    agrees_with_the_direct_solver("stack");
}

#[test]
fn krylov_options_are_passed_through() {
    let (plan, _, reference) = run_example("film", None);
    let (_, summary, gmres) = run_example(
        "film",
        Some("kind = \"petsc\"\npetsc_options = \"-ksp_type gmres -pc_type jacobi -ksp_rtol 1e-12 -ksp_atol 0 -ksp_max_it 20000 -ksp_gmres_restart 200\""),
    );
    assert!(summary.converged, "{:?}", summary.error);
    let d = probe_difference(&plan, &reference, &gmres);
    eprintln!("film: largest relative probe difference GMRES/Jacobi (rtol 1e-12) vs LDLT: {d:.2e}");
    // Newton stops at its own tolerance on either path; the inexact solves move the converged
    // state by far less than that
    assert!(d < 1e-6, "{d:e}");
}

#[test]
fn a_krylov_solve_that_cannot_converge_is_an_error() {
    let (_, summary, _) = run_example(
        "film",
        Some("kind = \"petsc\"\npetsc_options = \"-ksp_type gmres -pc_type none -ksp_max_it 1 -ksp_rtol 1e-12\""),
    );
    assert!(
        !summary.converged,
        "an unconverged linear solve gave a result"
    );
    let error = summary.error.unwrap_or_default();
    assert!(
        error.contains("did not converge") && error.contains("DIVERGED_ITS"),
        "{error}"
    );
}
