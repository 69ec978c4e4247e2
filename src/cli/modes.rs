//! `deasim modes`: the natural modes of a scenario about its loaded state — the state at the end
//! of the static (and quasi-static) stages that precede the first dynamic stage, with the
//! electrodes held at the voltages they have there (a DC bias lowers the frequencies). Writes a
//! table and the mode shapes for ParaView.

use crate::api::{loaded_modes_of_harmonics, modes_plan, RunOptions};
use crate::cli::app::{fail, load_scenario, EXIT_BAD_INPUT, EXIT_OK, EXIT_SOLVE_FAILED};
use crate::io::linear::write_modes;
use crate::io::results::ResultsDir;
use crate::time::modal::ModeSettings;
use std::path::{Path, PathBuf};

/// Runs the command; returns the exit status.
pub fn cmd_modes(
    scenario: Option<&Path>,
    out: Option<&Path>,
    overrides: &[String],
    count: usize,
    shift_hz: f64,
    harmonics: &[u32],
    overwrite: bool,
) -> i32 {
    let (_, plan) = match load_scenario(scenario, overrides) {
        Ok(x) => x,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    let settings = ModeSettings {
        count,
        shift_hz,
        ..Default::default()
    };
    let plan = match modes_plan(plan, &settings) {
        Ok(p) => p,
        Err(e) => return fail(&e),
    };
    if harmonics.iter().any(|&n| n > 0) && !plan.model.is_axisymmetric() {
        eprintln!(
            "error: --harmonic: circumferential harmonics n ≥ 1 are modes of an axisymmetric \
             model (`mesh.geometry = \"axisymmetric\"`); a 3-D model finds every mode with \
             harmonic 0"
        );
        return EXIT_BAD_INPUT;
    }
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
    let loaded = match loaded_modes_of_harmonics(&plan, &settings, harmonics, RunOptions::default())
    {
        Ok(m) => m,
        Err(e) => return fail(&e),
    };
    let (bias, found, state) = (&loaded.bias, &loaded.modes, &loaded.state);
    let biased: Vec<String> = bias
        .iter()
        .map(|(n, v)| format!("{n} at {v:.6} V"))
        .collect();
    println!(
        "{}: {} modes about the state after stage `{}` (electrodes: {})",
        plan.name,
        found.len(),
        loaded.stage,
        if biased.is_empty() {
            "none".to_string()
        } else {
            biased.join(", ")
        }
    );
    if let Some(note) = &loaded.note {
        println!("note: {note}");
    }
    println!("  mode  harmonic  frequency_hz     residual");
    for (i, m) in found.iter().enumerate() {
        println!(
            "  {:>4} {:>9} {:>13.6} {:>12.1e}",
            i + 1,
            m.harmonic,
            m.frequency,
            m.residual
        );
    }
    let written = write_modes(&plan, &dir, "modes", state, found);
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
