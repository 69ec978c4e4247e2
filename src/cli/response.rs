//! `deasim response`: the frequency response of a scenario's probes to a small harmonic voltage
//! on one electrode about its DC bias, by direct solves of the linearised system
//! ([`crate::time::frequency`]); CSV and Bode plots.

use crate::cli::app::{load_scenario, EXIT_BAD_INPUT, EXIT_OK, EXIT_SOLVE_FAILED};
use crate::element::CellFields;
use crate::io::atomic::write_atomic;
use crate::io::build::Plan;
use crate::io::plot::{stacked_plot, PlotSpec, Series};
use crate::job::plan::StageKind;
use crate::job::probes::{ProbeInput, ProbeKind};
use crate::job::run::{run, Observer, RunSummary, StepRecord};
use crate::job::statics::solve_static;
use crate::problem::dofs::{Dirichlet, Field, FIELDS, PHI};
use crate::problem::model::Model;
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::StepControl;
use crate::time::frequency::linearise;
use crate::time::mass::{MassKind, NodalMass};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What to compute (the command line's arguments).
#[derive(Debug, Clone)]
pub struct ResponseArgs {
    pub scenario: Option<PathBuf>,
    pub overrides: Vec<String>,
    /// The driven electrode (default: the first one with a non-zero voltage).
    pub electrode: Option<String>,
    /// DC voltage of the driven electrode (default: its voltage in the loaded state).
    pub bias: Option<f64>,
    /// Frequencies (Hz); when empty, `points` log-spaced values from `from` to `to`.
    pub frequencies: Vec<f64>,
    pub from: f64,
    pub to: f64,
    pub points: usize,
    pub out: Option<PathBuf>,
}

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

/// The complex response of one probe per volt at each frequency.
pub struct ProbeResponse {
    pub name: String,
    pub values: Vec<(f64, f64)>,
}

/// Runs the command; returns the exit status.
pub fn cmd_response(args: &ResponseArgs) -> i32 {
    match response(args) {
        Ok((dir, frequencies, probes, bias, electrode)) => {
            println!(
                "response of {} probe(s) to a small voltage on `{electrode}` about {bias:.3} V, \
                 {} frequencies; results in {}",
                probes.len(),
                frequencies.len(),
                dir.display()
            );
            EXIT_OK
        }
        Err((code, e)) => {
            eprintln!("error: {e}");
            code
        }
    }
}

type Outcome = (PathBuf, Vec<f64>, Vec<ProbeResponse>, f64, String);

/// The response: the loaded and biased state, the linearisation, a solve per frequency, the
/// probes linearised by central differences along the response.
pub fn response(args: &ResponseArgs) -> Result<Outcome, (i32, String)> {
    let bad = |e: String| (EXIT_BAD_INPUT, e);
    let failed = |e: String| (EXIT_SOLVE_FAILED, e);
    let (_, mut plan) =
        load_scenario(args.scenario.as_deref(), &args.overrides).map_err(|e| bad(e.to_string()))?;
    let frequencies = if args.frequencies.is_empty() {
        if !(args.from > 0.0 && args.to > args.from && args.points >= 2) {
            return Err(bad(format!(
                "--from/--to/--points: expected 0 < from < to and at least 2 points; got {}, {}, {}",
                args.from, args.to, args.points
            )));
        }
        let (a, b) = (args.from.ln(), args.to.ln());
        (0..args.points)
            .map(|i| (a + (b - a) * i as f64 / (args.points - 1) as f64).exp())
            .collect()
    } else {
        args.frequencies.clone()
    };
    if let Some(f) = frequencies.iter().find(|f| !(f.is_finite() && **f > 0.0)) {
        return Err(bad(format!(
            "--frequencies: expected positive values in Hz; got {f}"
        )));
    }
    let n_static = plan
        .stages
        .iter()
        .take_while(|s| !matches!(s.kind, StageKind::Dynamic { .. }))
        .count();
    if n_static == 0 {
        return Err(bad(format!(
            "`{}` starts with a dynamic stage: the response is taken about the state after the \
             static stages before the first dynamic one; add a static stage first",
            plan.name
        )));
    }
    if plan.densities.iter().all(|&d| d <= 0.0) && plan.rigid.iter().all(|r| r.mass <= 0.0) {
        return Err(bad(
            "the scenario has no mass: give `materials.<m>.density` (kg/m³)".into(),
        ));
    }
    let driven = match &args.electrode {
        Some(name) => plan
            .electrodes
            .iter()
            .position(|e| &e.name == name)
            .ok_or_else(|| {
                bad(format!(
                    "--electrode: no electrode `{name}`; the scenario has {}",
                    plan.electrodes
                        .iter()
                        .map(|e| e.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            })?,
        None => plan
            .electrodes
            .iter()
            .position(|e| e.voltage.amplitude != 0.0 || e.voltage.offset != 0.0)
            .ok_or_else(|| {
                bad("no electrode carries a voltage; name one with --electrode".into())
            })?,
    };
    plan.stages.truncate(n_static);
    let mut last = LastState::default();
    let summary = run(&plan, &NewtonSettings::default(), &mut last);
    if !summary.converged {
        return Err(failed(format!(
            "the loaded state was not reached: {}",
            summary.error.unwrap_or_default()
        )));
    }
    let mut state = last.0;
    // the biased state: the driven electrode ramped to the bias from the loaded state
    let bias = args
        .bias
        .unwrap_or(state[plan.electrodes[driven].nodes[0] * FIELDS + PHI]);
    let mut model: Model = plan.model.clone();
    model.dirichlet = plan.supports.clone();
    for (i, e) in plan.electrodes.iter().enumerate() {
        model.dirichlet.push(Dirichlet {
            nodes: e.nodes.clone(),
            field: Field::Phi,
            value: if i == driven {
                bias
            } else {
                state[e.nodes[0] * FIELDS + PHI]
            },
        });
    }
    model.dead_load_start = 1.0;
    let biased = solve_static(
        &model,
        Some(state.clone()),
        &StepControl {
            steps: 4,
            ..Default::default()
        },
        &NewtonSettings::default(),
        |_, _| {},
    );
    if let Err(f) = biased.result {
        return Err(failed(format!(
            "the bias of {bias} V was not reached: {}",
            f.reason
        )));
    }
    state = biased.state;
    let mut mass = NodalMass::new(&model, &plan.densities, MassKind::Consistent);
    for r in &plan.rigid {
        if r.mass > 0.0 {
            mass.add_point_mass(r.nodes[0], r.mass);
        }
    }
    let mut lin = linearise(
        &model,
        &state,
        &mass,
        &plan.viscosities,
        &plan.electrodes[driven].nodes,
        &plan.solver,
    )
    .map_err(failed)?;
    if !lin.drives_motion() {
        eprintln!(
            "warning: `{}` is at {bias} V: the electrostatic force is ∝ 2 V_dc ṽ, so at zero bias \
             a small voltage moves nothing to first order (only charge follows); give --bias",
            plan.electrodes[driven].name
        );
    }
    let probes: Vec<usize> = (0..plan.probes.len())
        .filter(|&i| {
            !matches!(
                plan.probes[i].1.kind,
                ProbeKind::MaxElectricField | ProbeKind::StoredEnergy | ProbeKind::ElectricEnergy
            )
        })
        .collect();
    let mut out: Vec<ProbeResponse> = probes
        .iter()
        .map(|&i| ProbeResponse {
            name: plan.probes[i].0.clone(),
            values: Vec::new(),
        })
        .collect();
    let reference = state.clone();
    let evaluate = |s: &[f64]| -> Result<Vec<f64>, String> {
        let reactions = crate::problem::statics::nodal_reactions(&model, s)?;
        let electrodes: Vec<(&[usize], f64)> = plan
            .electrodes
            .iter()
            .map(|e| (e.nodes.as_slice(), s[e.nodes[0] * FIELDS + PHI]))
            .collect();
        let input = ProbeInput {
            state: s,
            reactions: &reactions,
            electrodes: &electrodes,
            stored: 0.0,
            electric: 0.0,
            reference: &reference,
            max_field: f64::NAN,
            symmetry: plan.symmetry_factor,
        };
        Ok(probes
            .iter()
            .map(|&i| plan.probes[i].1.evaluate(&input) - plan.probes[i].1.offset)
            .collect())
    };
    let h = 1.0;
    for &f in &frequencies {
        let (xr, xi) = lin
            .response(2.0 * std::f64::consts::PI * f)
            .map_err(failed)?;
        let mut parts = Vec::new();
        for x in [&xr, &xi] {
            let plus: Vec<f64> = state.iter().zip(x).map(|(s, d)| s + h * d).collect();
            let minus: Vec<f64> = state.iter().zip(x).map(|(s, d)| s - h * d).collect();
            let (p, m) = (
                evaluate(&plus).map_err(failed)?,
                evaluate(&minus).map_err(failed)?,
            );
            parts.push(
                p.iter()
                    .zip(&m)
                    .map(|(a, b)| (a - b) / (2.0 * h))
                    .collect::<Vec<f64>>(),
            );
        }
        for (j, r) in out.iter_mut().enumerate() {
            r.values.push((parts[0][j], parts[1][j]));
        }
    }
    let dir: PathBuf = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("deasim-out").join(format!("{}-response", plan.name)));
    write(
        &dir,
        &frequencies,
        &out,
        bias,
        &plan.electrodes[driven].name,
    )
    .map_err(failed)?;
    Ok((
        dir,
        frequencies,
        out,
        bias,
        plan.electrodes[driven].name.clone(),
    ))
}

/// `response.csv` and one Bode plot per probe.
fn write(
    dir: &Path,
    frequencies: &[f64],
    probes: &[ProbeResponse],
    bias: f64,
    electrode: &str,
) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut csv = format!("# per volt on `{electrode}` about {bias} V\nfrequency_hz");
    for p in probes {
        let n = &p.name;
        let _ = write!(csv, ",{n}:magnitude,{n}:phase_deg,{n}:real,{n}:imag");
    }
    csv.push('\n');
    for (i, f) in frequencies.iter().enumerate() {
        let _ = write!(csv, "{f:e}");
        for p in probes {
            let (re, im) = p.values[i];
            let _ = write!(
                csv,
                ",{:e},{:e},{re:e},{im:e}",
                re.hypot(im),
                im.atan2(re).to_degrees()
            );
        }
        csv.push('\n');
    }
    let path = dir.join("response.csv");
    write_atomic(&path, csv.as_bytes()).map_err(|e| format!("{}: {e}", path.display()))?;
    for p in probes {
        let mag = Series {
            label: p.name.clone(),
            x: frequencies.iter().map(|f| f.log10()).collect(),
            y: p.values
                .iter()
                .map(|(re, im)| re.hypot(*im).max(f64::MIN_POSITIVE).log10())
                .collect(),
        };
        let phase = Series {
            label: p.name.clone(),
            x: mag.x.clone(),
            y: p.values
                .iter()
                .map(|(re, im)| im.atan2(*re).to_degrees())
                .collect(),
        };
        let path = dir.join(format!("bode_{}.png", p.name));
        stacked_plot(
            &path,
            &[
                PlotSpec {
                    title: &format!("{}: per volt on {electrode} about {bias:.0} V", p.name),
                    x_label: "log10 frequency [Hz]",
                    y_label: "log10 |response| [probe unit / V]",
                    series: std::slice::from_ref(&mag),
                },
                PlotSpec {
                    title: "",
                    x_label: "log10 frequency [Hz]",
                    y_label: "phase [deg]",
                    series: std::slice::from_ref(&phase),
                },
            ],
        )
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}
