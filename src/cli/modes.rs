//! `deasim modes`: the natural modes of a scenario about its loaded state — the state at the end
//! of the static (and quasi-static) stages that precede the first dynamic stage, with the
//! electrodes held at the voltages they have there (a DC bias lowers the frequencies). Writes a
//! table and the mode shapes for ParaView.

use crate::cli::app::{load_scenario, EXIT_BAD_INPUT, EXIT_OK, EXIT_SOLVE_FAILED};
use crate::element::CellFields;
use crate::io::build::Plan;
use crate::io::linear::write_modes;
use crate::io::results::ResultsDir;
use crate::job::linear::{check_linearisable, mode_symmetry_note, modes_at};
use crate::job::observer::Observer;
use crate::job::plan::StageKind;
use crate::job::run::{run, StepRecord};
use crate::job::state::RunSummary;
use crate::problem::dofs::{FIELDS, PHI};
use crate::time::modal::ModeSettings;
use std::path::{Path, PathBuf};

/// Keeps the state of the last accepted step.
#[derive(Default)]
struct LastState(Vec<f64>);

impl Observer for LastState {
    fn step(&mut self, _: &Plan, _: &StepRecord, state: &[f64], _: &[CellFields]) {
        self.0.clear();
        self.0.extend_from_slice(state);
    }
    fn finished(&mut self, _: &Plan, _: &RunSummary) {}
}

/// Runs the command; returns the exit status.
pub fn cmd_modes(
    scenario: Option<&Path>,
    out: Option<&Path>,
    overrides: &[String],
    count: usize,
    shift_hz: f64,
    overwrite: bool,
) -> i32 {
    let (_, mut plan) = match load_scenario(scenario, overrides) {
        Ok(x) => x,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    if !(shift_hz.is_finite() && shift_hz >= 0.0) {
        eprintln!("error: --shift: expected a frequency ≥ 0 in Hz; got {shift_hz}");
        return EXIT_BAD_INPUT;
    }
    let n_static = plan
        .stages
        .iter()
        .take_while(|s| !matches!(s.kind, StageKind::Dynamic { .. }) && !s.kind.is_linearised())
        .count();
    if n_static == 0 {
        eprintln!(
            "error: `{}` starts with a dynamic stage: deasim modes linearises about the state \
             after the static stages before the first dynamic one; add a static stage (e.g. \
             `steps = 1`) first",
            plan.name
        );
        return EXIT_BAD_INPUT;
    }
    if let Err(e) = check_linearisable(&plan) {
        eprintln!("error: {e}");
        return EXIT_BAD_INPUT;
    }
    plan.stages.truncate(n_static);
    let dir: PathBuf = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| Path::new("deasim-out").join(format!("{}-modes", plan.name)));
    let hash = format!("{:016x}", plan.fingerprint());
    let mut results = match ResultsDir::open(&dir, "modes", &plan.name, &hash, overwrite) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    let mut last = LastState::default();
    let summary = run(&plan, &mut last);
    if !summary.converged {
        eprintln!(
            "error: the loaded state was not reached: {}",
            summary.error.unwrap_or_default()
        );
        return EXIT_SOLVE_FAILED;
    }
    let state = last.0;
    let bias: Vec<(String, f64)> = plan
        .electrodes
        .iter()
        .map(|e| (e.name.clone(), state[e.nodes[0] * FIELDS + PHI]))
        .collect();
    let found = match modes_at(
        &plan,
        &state,
        &ModeSettings {
            count,
            shift_hz,
            ..Default::default()
        },
    ) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_SOLVE_FAILED;
        }
    };
    let biased: Vec<String> = bias
        .iter()
        .map(|(n, v)| format!("{n} at {v:.6} V"))
        .collect();
    println!(
        "{}: {} modes about the state after stage `{}` (electrodes: {})",
        plan.name,
        found.len(),
        plan.stages[n_static - 1].name,
        if biased.is_empty() {
            "none".to_string()
        } else {
            biased.join(", ")
        }
    );
    if let Some(note) = mode_symmetry_note(&plan) {
        println!("note: {note}");
    }
    println!("  mode  frequency_hz     residual");
    for (i, m) in found.iter().enumerate() {
        println!("  {:>4} {:>12.6} {:>12.1e}", i + 1, m.frequency, m.residual);
    }
    let written = write_modes(&plan, &dir, "modes", &state, &found);
    match written.and(results.record()) {
        Ok(()) => {
            println!("results in {}", dir.display());
            EXIT_OK
        }
        Err(e) => {
            eprintln!("error: {e}");
            EXIT_SOLVE_FAILED
        }
    }
}
