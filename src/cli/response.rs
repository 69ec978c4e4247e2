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

/// Keeps the state and the probe values of the last accepted step.
#[derive(Default)]
struct LastState(Vec<f64>, Vec<f64>);

impl Observer for LastState {
    fn step(&mut self, _: &Plan, record: &StepRecord, state: &[f64], _: &[CellFields]) {
        self.0.clear();
        self.0.extend_from_slice(state);
        self.1.clone_from(&record.probes);
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

/// The biased state of a scenario and its linearisation, shared by `response` and `reduce`.
pub struct Prepared {
    pub plan: Plan,
    pub model: Model,
    pub state: Vec<f64>,
    pub lin: crate::time::frequency::Linearisation,
    /// The probes that are linearised (plan indices; not the energies and the largest field).
    pub probes: Vec<usize>,
    pub bias: f64,
    pub electrode: String,
    /// The loaded state (before the bias) and the run's probe values there: deflections are
    /// measured from the run's reference, which the linearisation does not know.
    loaded: Vec<f64>,
    loaded_probes: Vec<f64>,
}

impl Prepared {
    /// The linearised probes' values at the biased state as the run reports them (offset and
    /// reference included).
    pub fn offsets(&self) -> Result<Vec<f64>, String> {
        let (at_bias, at_load) = (
            self.probe_values(&self.state)?,
            self.probe_values(&self.loaded)?,
        );
        Ok(self
            .probes
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let offset = self.plan.probes[i].1.offset;
                at_bias[k] + (self.loaded_probes[i] - offset - at_load[k]) + offset
            })
            .collect())
    }

    /// The probes' values (offsets removed) at a state.
    pub fn probe_values(&self, s: &[f64]) -> Result<Vec<f64>, String> {
        let plan = &self.plan;
        let reactions = crate::problem::statics::nodal_reactions(&self.model, s)?;
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
            reference: &self.loaded,
            max_field: f64::NAN,
            symmetry: plan.symmetry_factor,
        };
        Ok(self
            .probes
            .iter()
            .map(|&i| plan.probes[i].1.evaluate(&input) - plan.probes[i].1.offset)
            .collect())
    }

    /// The probes' first-order change along the perturbation `dq` (`FIELDS` values per node), by
    /// a central difference of step h·dq, h = min(1, 10 nm / largest displacement of dq): small
    /// against any device, large against round-off (the probes are smooth in the state).
    pub fn gradient(&self, dq: &[f64]) -> Result<Vec<f64>, String> {
        let largest = dq
            .iter()
            .enumerate()
            .filter(|(d, _)| d % FIELDS != PHI)
            .map(|(_, v)| v.abs())
            .fold(0.0, f64::max);
        let h = if largest > 0.0 {
            (1e-8 / largest).min(1.0)
        } else {
            1.0
        };
        let plus: Vec<f64> = self.state.iter().zip(dq).map(|(s, d)| s + h * d).collect();
        let minus: Vec<f64> = self.state.iter().zip(dq).map(|(s, d)| s - h * d).collect();
        let (p, m) = (self.probe_values(&plus)?, self.probe_values(&minus)?);
        Ok(p.iter().zip(&m).map(|(a, b)| (a - b) / (2.0 * h)).collect())
    }

    /// Names of the linearised probes.
    pub fn names(&self) -> Vec<String> {
        self.probes
            .iter()
            .map(|&i| self.plan.probes[i].0.clone())
            .collect()
    }
}

/// Loads the scenario, runs its static stages before the first dynamic one, ramps the driven
/// electrode to the bias and linearises there.
pub fn prepare(
    scenario: Option<&Path>,
    overrides: &[String],
    electrode: Option<&str>,
    bias: Option<f64>,
) -> Result<Prepared, (i32, String)> {
    let bad = |e: String| (EXIT_BAD_INPUT, e);
    let failed = |e: String| (EXIT_SOLVE_FAILED, e);
    let (_, mut plan) = load_scenario(scenario, overrides).map_err(|e| bad(e.to_string()))?;
    let n_static = plan
        .stages
        .iter()
        .take_while(|s| !matches!(s.kind, StageKind::Dynamic { .. }))
        .count();
    if n_static == 0 {
        return Err(bad(format!(
            "`{}` starts with a dynamic stage: the small-signal model is taken about the state \
             after the static stages before the first dynamic one; add a static stage first",
            plan.name
        )));
    }
    if plan.densities.iter().all(|&d| d <= 0.0) && plan.rigid.iter().all(|r| r.mass <= 0.0) {
        return Err(bad(
            "the scenario has no mass: give `materials.<m>.density` (kg/m³)".into(),
        ));
    }
    if plan.model.materials.iter().any(|m| m.state_size() > 0) {
        return Err(bad(
            "materials with `branches` are not linearised yet (their relaxed state and complex \
             modulus); use the elastic material or a dynamic stage"
                .into(),
        ));
    }
    let driven = match electrode {
        Some(name) => plan
            .electrodes
            .iter()
            .position(|e| e.name == name)
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
    let full_stages = plan.stages.clone();
    plan.stages.truncate(n_static);
    let mut last = LastState::default();
    let summary = run(&plan, &NewtonSettings::default(), &mut last);
    plan.stages = full_stages;
    if !summary.converged {
        return Err(failed(format!(
            "the loaded state was not reached: {}",
            summary.error.unwrap_or_default()
        )));
    }
    let loaded = last.0.clone();
    let loaded_probes = last.1.clone();
    let mut state = last.0;
    // the biased state: the driven electrode ramped to the bias from the loaded state
    let bias = bias.unwrap_or(state[plan.electrodes[driven].nodes[0] * FIELDS + PHI]);
    if !bias.is_finite() {
        return Err(bad(format!("--bias: expected a voltage in V; got {bias}")));
    }
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
    let lin = linearise(
        &model,
        &state,
        &mass,
        &plan.viscosities,
        &plan.electrodes[driven].nodes,
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
    let electrode = plan.electrodes[driven].name.clone();
    Ok(Prepared {
        plan,
        model,
        state,
        lin,
        probes,
        bias,
        electrode,
        loaded,
        loaded_probes,
    })
}

/// The response: a solve per frequency, the probes linearised along it.
pub fn response(args: &ResponseArgs) -> Result<Outcome, (i32, String)> {
    let bad = |e: String| (EXIT_BAD_INPUT, e);
    let failed = |e: String| (EXIT_SOLVE_FAILED, e);
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
    let mut p = prepare(
        args.scenario.as_deref(),
        &args.overrides,
        args.electrode.as_deref(),
        args.bias,
    )?;
    let mut out: Vec<ProbeResponse> = p
        .names()
        .into_iter()
        .map(|name| ProbeResponse {
            name,
            values: Vec::new(),
        })
        .collect();
    for &f in &frequencies {
        let (xr, xi) = p
            .lin
            .response(2.0 * std::f64::consts::PI * f)
            .map_err(failed)?;
        let (gr, gi) = (
            p.gradient(&xr).map_err(failed)?,
            p.gradient(&xi).map_err(failed)?,
        );
        for (j, r) in out.iter_mut().enumerate() {
            r.values.push((gr[j], gi[j]));
        }
    }
    let dir: PathBuf = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("deasim-out").join(format!("{}-response", p.plan.name)));
    write(&dir, &frequencies, &out, p.bias, &p.electrode).map_err(failed)?;
    Ok((dir, frequencies, out, p.bias, p.electrode))
}

/// `frequency_response.csv` and one Bode plot per probe.
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
    let path = dir.join("frequency_response.csv");
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
        // the phase unwrapped (continuous across ±180°) for the plot
        let mut unwrapped: Vec<f64> = Vec::with_capacity(p.values.len());
        for (re, im) in &p.values {
            let mut ph = im.atan2(*re).to_degrees();
            if let Some(&last) = unwrapped.last() {
                ph += 360.0 * ((last - ph) / 360.0).round();
            }
            unwrapped.push(ph);
        }
        let phase = Series {
            label: p.name.clone(),
            x: mag.x.clone(),
            y: unwrapped,
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

/// Arguments of `deasim reduce`.
#[derive(Debug, Clone)]
pub struct ReduceArgs {
    pub scenario: Option<PathBuf>,
    pub overrides: Vec<String>,
    pub electrode: Option<String>,
    pub bias: Option<f64>,
    /// Modes kept.
    pub modes: usize,
    /// A finite element run's output directory to overlay (its first dynamic stage).
    pub compare: Option<PathBuf>,
    pub out: Option<PathBuf>,
}

/// `deasim reduce`: the reduced state-space model, its matrices, its simulation of the first
/// dynamic stage's drive, and (with `--compare`) the overlay on a finite element history.
pub fn cmd_reduce(args: &ReduceArgs) -> i32 {
    match reduce(args) {
        Ok(lines) => {
            for l in lines {
                println!("{l}");
            }
            EXIT_OK
        }
        Err((code, e)) => {
            eprintln!("error: {e}");
            code
        }
    }
}

/// The work of [`cmd_reduce`]; returns the lines to print.
pub fn reduce(args: &ReduceArgs) -> Result<Vec<String>, (i32, String)> {
    let bad = |e: String| (EXIT_BAD_INPUT, e);
    let failed = |e: String| (EXIT_SOLVE_FAILED, e);
    if args.modes == 0 {
        return Err(bad("--modes: at least one mode".into()));
    }
    if let Some(dir) = &args.compare {
        if !dir.join("history.csv").is_file() {
            return Err(bad(format!(
                "--compare: {} holds no history.csv of a run",
                dir.display()
            )));
        }
    }
    let p = prepare(
        args.scenario.as_deref(),
        &args.overrides,
        args.electrode.as_deref(),
        args.bias,
    )?;
    let offsets = p.offsets().map_err(failed)?;
    let names = p.names();
    let gradient = |dq: &[f64]| p.gradient(dq);
    let model = crate::time::reduced::ReducedModel::build(
        &p.lin,
        args.modes,
        &p.plan.solver,
        &crate::time::reduced::Outputs {
            names: names.clone(),
            offsets: offsets.clone(),
            gradient: &gradient,
        },
        &p.electrode,
        p.bias,
    )
    .map_err(failed)?;
    let dir: PathBuf = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("deasim-out").join(format!("{}-reduced", p.plan.name)));
    std::fs::create_dir_all(&dir).map_err(|e| failed(format!("{}: {e}", dir.display())))?;
    let json = serde_json::to_string_pretty(&model).map_err(|e| failed(e.to_string()))?;
    let put = |name: &str, text: &str| -> Result<(), (i32, String)> {
        let path = dir.join(name);
        write_atomic(&path, text.as_bytes()).map_err(|e| failed(format!("{}: {e}", path.display())))
    };
    put("reduced_model.json", &json)?;
    let matrix = |m: &[Vec<f64>]| -> String {
        m.iter()
            .map(|row| {
                row.iter()
                    .map(|v| format!("{v:e}"))
                    .collect::<Vec<_>>()
                    .join(",")
            })
            .collect::<Vec<_>>()
            .join("\n")
            + "\n"
    };
    for (name, m) in [
        ("A", &model.a),
        ("B", &model.b),
        ("C", &model.c),
        ("D", &model.d),
    ] {
        put(&format!("{name}.csv"), &matrix(m))?;
    }
    let mut lines = vec![format!(
        "{}: reduced model of {} modes ({} states) about {:.3} V on `{}`, outputs {}; modes {:.4?} Hz",
        p.plan.name,
        args.modes,
        2 * args.modes,
        p.bias,
        p.electrode,
        names.join(", "),
        model.frequencies_hz
    )];
    // the first dynamic stage's drive, simulated
    let Some(si) = p
        .plan
        .stages
        .iter()
        .position(|s| matches!(s.kind, StageKind::Dynamic { .. }))
    else {
        lines.push(format!("results in {}", dir.display()));
        return Ok(lines);
    };
    let stage = &p.plan.stages[si];
    let StageKind::Dynamic { dt, .. } = stage.kind else {
        unreachable!("a dynamic stage")
    };
    let waveform = p
        .plan
        .electrodes
        .iter()
        .find(|e| e.name == p.electrode)
        .map(|e| e.voltage.clone())
        .expect("the driven electrode exists");
    let fe = match &args.compare {
        Some(d) => Some(fe_history(d, &stage.name, &names).map_err(bad)?),
        None => None,
    };
    let times: Vec<f64> = match &fe {
        Some((t, _)) => t.clone(),
        None => {
            let n = (stage.duration / dt).round().max(1.0) as usize;
            (0..=n)
                .map(|i| stage.duration * i as f64 / n as f64)
                .collect()
        }
    };
    let v = |t: f64| waveform.value(t);
    let y = model.simulate(&v, &times);
    let mut csv = String::from("time");
    for n in &names {
        let _ = write!(csv, ",{n}");
    }
    csv.push('\n');
    for (t, row) in times.iter().zip(&y) {
        let _ = write!(csv, "{t:e}");
        for v in row {
            let _ = write!(csv, ",{v:e}");
        }
        csv.push('\n');
    }
    put("reduced_history.csv", &csv)?;
    if let Some((_, fe_rows)) = &fe {
        for (k, name) in names.iter().enumerate() {
            let a: Vec<f64> = fe_rows.iter().map(|r| r[k]).collect();
            let b: Vec<f64> = y.iter().map(|r| r[k]).collect();
            let finite = |x: &f64| x.is_finite();
            let (lo, hi) = a
                .iter()
                .filter(|x| finite(x))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
                    (l.min(x), h.max(x))
                });
            let worst = a
                .iter()
                .zip(&b)
                .filter(|(x, y)| finite(x) && finite(y))
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            lines.push(format!(
                "{name}: largest difference to the finite element run {worst:.4e} = {:.3e} of its \
                 peak-to-peak {:.4e}",
                worst / (hi - lo).max(f64::MIN_POSITIVE),
                hi - lo
            ));
            let series = [
                Series {
                    label: "finite elements".into(),
                    x: fe.as_ref().map(|f| f.0.clone()).unwrap_or_default(),
                    y: a,
                },
                Series {
                    label: format!("reduced ({} modes)", args.modes),
                    x: times.clone(),
                    y: b,
                },
            ];
            let path = dir.join(format!("compare_{name}.png"));
            crate::io::plot::line_plot(
                &path,
                &PlotSpec {
                    title: &format!("{name}: reduced model against the finite element run"),
                    x_label: "stage time [s]",
                    y_label: name,
                    series: &series,
                },
            )
            .map_err(|e| failed(e.to_string()))?;
        }
    }
    lines.push(format!("results in {}", dir.display()));
    Ok(lines)
}

/// The stage-time records of stage `stage` in a run's `history.csv`: times from the stage start
/// (the state it starts from included) and the probes `names`.
#[allow(clippy::type_complexity)]
fn fe_history(
    dir: &Path,
    stage: &str,
    names: &[String],
) -> Result<(Vec<f64>, Vec<Vec<f64>>), String> {
    let path = dir.join("history.csv");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let col = |n: &str| {
        head.iter()
            .position(|h| *h == n)
            .ok_or_else(|| format!("{}: no column `{n}`", path.display()))
    };
    let (ct, cs, cd) = (col("time")?, col("stage")?, col("dt")?);
    let cols: Vec<usize> = names
        .iter()
        .map(|n| col(&format!("probe:{n}")))
        .collect::<Result<_, _>>()?;
    let rows: Vec<Vec<&str>> = lines
        .map(|l| l.split(',').collect::<Vec<&str>>())
        .filter(|v| v.get(cs) == Some(&stage))
        .collect();
    let num = |s: &str| s.parse::<f64>().unwrap_or(f64::NAN);
    let first = rows
        .iter()
        .find(|v| v[2] != "0")
        .ok_or_else(|| format!("{}: no step of stage `{stage}`", path.display()))?;
    let t0 = num(first[ct]) - num(first[cd]);
    let times: Vec<f64> = rows.iter().map(|v| num(v[ct]) - t0).collect();
    let values = rows
        .iter()
        .map(|v| cols.iter().map(|&c| num(v[c])).collect())
        .collect();
    Ok((times, values))
}
