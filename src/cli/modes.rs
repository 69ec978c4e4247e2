//! `deasim modes`: the natural modes of a scenario about its loaded state — the state at the end
//! of the static (and quasi-static) stages that precede the first dynamic stage, with the
//! electrodes held at the voltages they have there (a DC bias lowers the frequencies). Writes a
//! table and the mode shapes for ParaView.

use crate::cli::app::{load_scenario, EXIT_BAD_INPUT, EXIT_OK, EXIT_SOLVE_FAILED};
use crate::element::CellFields;
use crate::io::atomic::write_atomic;
use crate::io::build::Plan;
use crate::io::vtu::{write_pvd, write_vtu, CellType, DataArray, VtuPiece};
use crate::job::plan::StageKind;
use crate::job::run::{run, Observer, RunSummary, StepRecord};
use crate::mesh::ElementKind;
use crate::problem::dofs::{Dirichlet, Field, FIELDS, PHI};
use crate::solve::newton::NewtonSettings;
use crate::time::mass::{MassKind, NodalMass};
use crate::time::modal::{modes, Mode, ModeSettings};
use std::fmt::Write as _;
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
        .take_while(|s| !matches!(s.kind, StageKind::Dynamic { .. }))
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
    if plan.densities.iter().all(|&d| d <= 0.0) && plan.rigid.iter().all(|r| r.mass <= 0.0) {
        eprintln!("error: the scenario has no mass: give `materials.<m>.density` (kg/m³)");
        return EXIT_BAD_INPUT;
    }
    if plan.model.materials.iter().any(|m| m.state_size() > 0) {
        eprintln!(
            "error: materials with `branches` are not linearised yet (their relaxed state and \
             complex modulus); use the elastic material or a dynamic stage"
        );
        return EXIT_BAD_INPUT;
    }
    plan.stages.truncate(n_static);
    let dir: PathBuf = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| Path::new("deasim-out").join(format!("{}-modes", plan.name)));
    let mut last = LastState::default();
    let summary = run(&plan, &NewtonSettings::default(), &mut last);
    if !summary.converged {
        eprintln!(
            "error: the loaded state was not reached: {}",
            summary.error.unwrap_or_default()
        );
        return EXIT_SOLVE_FAILED;
    }
    let state = last.0;
    // supports, and every electrode held at the voltage it has in the loaded state
    let mut model = plan.model.clone();
    model.dirichlet = plan.supports.clone();
    let mut bias = Vec::new();
    for e in &plan.electrodes {
        let v = state[e.nodes[0] * FIELDS + PHI];
        bias.push((e.name.clone(), v));
        model.dirichlet.push(Dirichlet {
            nodes: e.nodes.clone(),
            field: Field::Phi,
            value: v,
        });
    }
    let mut mass = NodalMass::new(&model, &plan.densities, MassKind::Consistent);
    for r in &plan.rigid {
        if r.mass > 0.0 {
            mass.add_point_mass(r.nodes[0], r.mass);
        }
    }
    let found = match modes(
        &model,
        &state,
        &mass,
        &plan.solver,
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
    println!("  mode  frequency_hz     residual");
    for (i, m) in found.iter().enumerate() {
        println!("  {:>4} {:>12.6} {:>12.1e}", i + 1, m.frequency, m.residual);
    }
    match write(&plan, &dir, &state, &found) {
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

/// `modes.csv`, `modes.pvd` and `modes/mode_NN.vtu`.
fn write(plan: &Plan, dir: &Path, state: &[f64], found: &[Mode]) -> Result<(), String> {
    std::fs::create_dir_all(dir.join("modes")).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut csv = String::from("mode,frequency_hz,eigenvalue_rad2_per_s2,residual\n");
    for (i, m) in found.iter().enumerate() {
        let _ = writeln!(
            csv,
            "{},{},{},{:e}",
            i + 1,
            m.frequency,
            m.eigenvalue,
            m.residual
        );
    }
    let path = dir.join("modes.csv");
    write_atomic(&path, csv.as_bytes()).map_err(|e| format!("{}: {e}", path.display()))?;
    let mesh = &plan.model.mesh;
    let n = mesh.n_nodes();
    let disp: Vec<f64> = (0..n)
        .flat_map(|a| state[a * FIELDS..a * FIELDS + 3].to_vec())
        .collect();
    let cell_type = match mesh.kind {
        ElementKind::Hex8 => CellType::Hex8,
        ElementKind::Tet4 => CellType::Tet4,
        ElementKind::Tet10 => CellType::Tet10,
    };
    let mut entries = Vec::new();
    for (i, m) in found.iter().enumerate() {
        // shapes scaled to a largest displacement of 1 (dimensionless), potential alike
        let largest = (0..n)
            .map(|a| {
                (0..3)
                    .map(|c| m.shape[a * FIELDS + c].powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        let shape: Vec<f64> = (0..n)
            .flat_map(|a| (0..3).map(move |c| (a, c)))
            .map(|(a, c)| m.shape[a * FIELDS + c] / largest)
            .collect();
        let phi: Vec<f64> = (0..n)
            .map(|a| m.shape[a * FIELDS + PHI] / largest)
            .collect();
        let name = format!("mode_{:02}.vtu", i + 1);
        let piece = VtuPiece {
            points: &mesh.nodes,
            cell_type,
            connectivity: &mesh.connectivity,
            point_data: vec![
                DataArray {
                    name: "displacement",
                    components: 3,
                    values: &disp,
                },
                DataArray {
                    name: "mode_shape",
                    components: 3,
                    values: &shape,
                },
                DataArray {
                    name: "mode_potential",
                    components: 1,
                    values: &phi,
                },
            ],
            cell_data: Vec::new(),
        };
        write_vtu(&dir.join("modes").join(&name), &piece).map_err(|e| e.to_string())?;
        entries.push((m.frequency, format!("modes/{name}")));
    }
    write_pvd(&dir.join("modes.pvd"), &entries).map_err(|e| e.to_string())
}
