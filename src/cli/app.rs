//! The commands of the `deasim` binary. `main.rs` only parses arguments and calls these; each
//! returns the process exit status: 0 success, 1 the solve failed, 2 bad input.

use crate::api::{
    launched_rank, launched_size, read_checkpoint, read_scenario, Error, RankOptions, RankRun,
    Resume, Simulation,
};
use crate::element::CellFields;
use crate::io::build::{build, Plan, StageKind};
use crate::io::examples::{example, EXAMPLES};
use crate::io::scenario::{parse, InputError};
use crate::job::controller::Controller;
use crate::job::observer::Observer;
use crate::job::plan::ResponseMethod;
use crate::job::run::StepRecord;
use crate::job::state::FrequencyResponse;
use crate::job::state::RunSummary;
use crate::time::modal::Mode;
use crate::units::Short;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::Path;

/// Exit status: success.
pub const EXIT_OK: i32 = 0;
/// Exit status: the solve failed.
pub const EXIT_SOLVE_FAILED: i32 = 1;
/// Exit status: bad input.
pub const EXIT_BAD_INPUT: i32 = 2;
/// Exit status: stopped by SIGINT/SIGTERM (outputs hold the last accepted step).
pub const EXIT_INTERRUPTED: i32 = 130;

/// Reads and builds a scenario file (or the default example when `path` is `None`).
pub fn load(path: Option<&Path>, overrides: &[String]) -> Result<Plan, InputError> {
    load_scenario(path, overrides).map(|(_, plan)| plan)
}

/// As [`load`], also returning the parsed scenario (for commands that read its geometry).
pub fn load_scenario(
    path: Option<&Path>,
    overrides: &[String],
) -> Result<(crate::io::scenario::Scenario, Plan), InputError> {
    let (text, name, base) = read_scenario(path)?;
    let blame = |e| crate::io::scenario::blame_override(e, overrides);
    let scenario = parse(&text, &name, overrides).map_err(blame)?;
    let plan = build(&scenario, &name, base.as_deref()).map_err(blame)?;
    Ok((scenario, plan))
}

/// [`load_scenario`] without the electrodes' state-feedback controllers, for the small-signal
/// commands, which run open loop: the design file such a controller reads may not exist yet, as
/// it is what `deasim reduce --lqr` on this scenario writes.
pub fn load_scenario_open_loop(
    path: Option<&Path>,
    overrides: &[String],
) -> Result<(crate::io::scenario::Scenario, Plan), InputError> {
    let (text, name, base) = read_scenario(path)?;
    let blame = |e| crate::io::scenario::blame_override(e, overrides);
    let mut scenario = parse(&text, &name, overrides).map_err(blame)?;
    for e in scenario.electrodes.values_mut() {
        if e.controller
            .as_ref()
            .is_some_and(|c| c.kind == "state-feedback")
        {
            e.controller = None;
        }
    }
    let plan = build(&scenario, &name, base.as_deref()).map_err(blame)?;
    Ok((scenario, plan))
}

/// Shows progress: a bar on a terminal, plain lines otherwise.
struct Progress {
    bar: Option<ProgressBar>,
    total_steps: u64,
    /// Whether `total_steps` is the plan's ([`Progress::size`]).
    sized: bool,
    done: u64,
    /// When the last plain line was printed (plain lines: at most one a second).
    last_line: Option<std::time::Instant>,
    /// When the progress started, and the steps already done then (a resumed run).
    started: std::time::Instant,
    done_at_start: u64,
}

impl Progress {
    /// `n/N steps, p %, ETA …` for a log line: the remaining nominal steps at the mean rate so
    /// far (steps cut back make the total grow; the ETA is then omitted past the nominal end).
    fn position(&self) -> String {
        let total = self.total_steps.max(1);
        let pct = (100.0 * self.done as f64 / total as f64).min(100.0);
        let run = self.done.saturating_sub(self.done_at_start);
        let elapsed = self.started.elapsed().as_secs_f64();
        let eta = if run > 0 && self.done < total {
            let s = elapsed / run as f64 * (total - self.done) as f64;
            if s >= 60.0 {
                format!(", ETA {}m{:02}s", (s / 60.0).floor(), (s % 60.0).floor())
            } else {
                format!(", ETA {s:.0} s")
            }
        } else {
            String::new()
        };
        // a continuation's points and cut-back steps can pass the nominal count
        let shown = self.total_steps.max(self.done);
        format!("{}/{shown} steps, {pct:.0} %{eta}", self.done)
    }

    /// A progress display; it learns the plan's nominal steps at the run's first event that
    /// carries the plan (the plan is built on the ranks after it is made).
    fn new() -> Self {
        let bar = std::io::stderr().is_terminal().then(|| {
            let b = ProgressBar::new(0);
            b.set_style(
                ProgressStyle::with_template(
                    "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} steps {msg} (ETA {eta})",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            b
        });
        Progress {
            bar,
            total_steps: 0,
            sized: false,
            done: 0,
            last_line: None,
            started: std::time::Instant::now(),
            done_at_start: 0,
        }
    }

    /// Takes the nominal steps of `plan`'s stages as the total (once) and starts the clock.
    fn size(&mut self, plan: &Plan) {
        if self.sized {
            return;
        }
        self.sized = true;
        self.total_steps = plan
            .stages
            .iter()
            .map(|s| s.kind.nominal_steps(s.duration) as u64)
            .sum();
        if let Some(b) = &self.bar {
            b.set_length(self.total_steps);
        }
        self.started = std::time::Instant::now();
    }
}

impl Progress {
    /// A line above the bar (or on stderr without one).
    fn say(&self, line: &str) {
        match &self.bar {
            Some(b) => b.println(line),
            None => eprintln!("{line}"),
        }
    }
}

impl Observer for Progress {
    fn modes(&mut self, plan: &Plan, stage: &str, _state: &[f64], modes: &[Mode]) {
        self.size(plan);
        let list: Vec<String> = modes
            .iter()
            .map(|m| format!("{:.4}", m.frequency))
            .collect();
        self.say(&format!(
            "  {stage}: natural frequencies (Hz): {}",
            list.join(", ")
        ));
        if let Some(note) = crate::job::linear::mode_symmetry_note(plan) {
            self.say(&format!("  {stage}: note: {note}"));
        }
    }

    fn frequency_response(&mut self, plan: &Plan, stage: &str, r: &FrequencyResponse) {
        self.size(plan);
        self.say(&format!(
            "  {stage}: {} frequencies, solved by {}",
            r.frequencies.len(),
            r.solved_by
        ));
        for (name, values) in &r.probes {
            let (k, peak) = values
                .iter()
                .map(|(re, im)| re.hypot(*im))
                .enumerate()
                .fold((0, 0.0), |a, (i, m)| if m > a.1 { (i, m) } else { a });
            self.say(&format!(
                "  {stage}: {name}: largest |response| {peak:.4e} per volt at {:.4} Hz \
                 (on `{}` about {} V)",
                r.frequencies.get(k).copied().unwrap_or(f64::NAN),
                r.electrode,
                r.bias
            ));
        }
    }

    fn limit_point(&mut self, plan: &Plan, l: &crate::job::run::LimitRecord) {
        let (name, unit) = plan
            .stages
            .iter()
            .find(|s| s.name == l.stage)
            .and_then(|s| match &s.kind {
                StageKind::Continuation { parameter, .. } => Some(parameter.column(plan)),
                _ => None,
            })
            .unwrap_or_else(|| ("parameter".into(), "-"));
        self.say(&format!(
            "  {}: limit point: {} of {name} = {:.6e} {unit} at load factor {:.6}",
            l.stage,
            if l.maximum { "maximum" } else { "minimum" },
            l.parameter,
            l.load_factor
        ));
    }

    fn instability(
        &mut self,
        plan: &Plan,
        i: &crate::job::run::InstabilityRecord,
        _state: &[f64],
        _mode: &Mode,
    ) {
        self.size(plan);
        let voltages: Vec<String> = i
            .voltages
            .iter()
            .map(|(n, v)| format!("`{n}` at {v:.1} V"))
            .collect();
        let kind = match (i.harmonic, i.axial_share > 0.5) {
            (0, _) => "axisymmetric loss of stability",
            (_, true) => "wrinkling (out of plane)",
            (_, false) => "loss of stability in plane",
        };
        self.say(&format!(
            "  {}: {kind}, n = {}, at {} (load factor {:.6}, t = {:.6} s; critical mode in \
             instability.pvd){}",
            i.stage,
            i.harmonic,
            if voltages.is_empty() {
                "the stage's loads".to_string()
            } else {
                voltages.join(", ")
            },
            i.load_factor,
            i.time,
            if i.stopped {
                "; the run stops at the last stable state"
            } else {
                "; the run goes on along the axisymmetric (unstable) path"
            }
        ));
    }

    fn stage_started(&mut self, index: usize, name: &str) {
        match &self.bar {
            Some(b) => b.set_message(format!("stage {name}")),
            None => eprintln!("stage {index} `{name}`"),
        }
    }

    fn step(&mut self, plan: &Plan, r: &StepRecord, _state: &[f64], _fields: &[CellFields]) {
        self.size(plan);
        if r.step == 0 {
            return;
        }
        self.done += 1;
        let msg = format!(
            "t = {}, V = {:.1} V, {} Newton it.",
            progress_time(r.time, r.dt),
            r.voltage,
            r.newton_iterations
        );
        match &self.bar {
            Some(b) => {
                b.set_position(self.done.min(self.total_steps));
                b.set_message(format!("{} {msg}", r.stage));
            }
            None => {
                if self
                    .last_line
                    .is_none_or(|t| t.elapsed().as_secs_f64() >= 1.0)
                {
                    eprintln!("  {} step {}: {msg} [{}]", r.stage, r.step, self.position());
                    self.last_line = Some(std::time::Instant::now());
                }
            }
        }
    }

    fn resumed(&mut self, plan: &Plan, records: &[StepRecord], _: &[f64], _: &[CellFields]) {
        self.size(plan);
        self.done = records.iter().filter(|r| r.step > 0).count() as u64;
        self.done_at_start = self.done;
        self.started = std::time::Instant::now();
        if let Some(b) = &self.bar {
            b.set_position(self.done.min(self.total_steps));
        }
    }

    // the closing line waits for the outputs ([`report`]): a failed write is no "finished"
    fn finished(&mut self, _plan: &Plan, _s: &RunSummary) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

/// `deasim run`; with `checkpoint_every`, a checkpoint every that many accepted steps. On the
/// MPI ranks a launcher started, every rank runs it ([`Simulation::run_on_ranks`]).
pub fn cmd_run(
    scenario: Option<&Path>,
    out: Option<&Path>,
    overrides: &[String],
    overwrite: bool,
    checkpoint_every: Option<usize>,
) -> i32 {
    let sim = match Simulation::read(scenario) {
        Ok(s) => s.with_overrides(overrides),
        Err(e) => {
            // under a launcher every process reads the same scenario: one says why
            if launched_rank() == 0 {
                eprintln!("error: {e}");
            }
            return EXIT_BAD_INPUT;
        }
    };
    catch_signals();
    let mut progress = Progress::new();
    // a scenario's [[objective]] is evaluated on its run (in one process)
    let mut objective = if launched_size() <= 1 {
        match sim.objective_tape() {
            Ok(t) => t,
            Err(e) => return fail(&e),
        }
    } else {
        None
    };
    let mut observers: Vec<&mut dyn Observer> = vec![&mut progress];
    if let Some(t) = objective.as_mut() {
        observers.push(t.observer());
    }
    let ran = sim.run_on_ranks(RankOptions {
        out: out.map(Path::to_path_buf),
        overwrite,
        checkpoint_every,
        observers,
        cancel: None,
    });
    if let (Some(t), Ok(run)) = (&objective, &ran) {
        if run.outcome.is_ok() {
            match t.value() {
                Ok(j) => {
                    println!("objective J = {j:.15e}");
                    if let Err(m) = crate::io::output::add_to_summary(
                        &run.dir,
                        "objective",
                        serde_json::json!(j),
                    ) {
                        eprintln!("error: {m}");
                        return EXIT_SOLVE_FAILED;
                    }
                }
                Err(e) => eprintln!("warning: the objective was not evaluated: {e}"),
            }
        }
    }
    report(ran)
}

/// The exit status of a run on the ranks, its closing lines said on rank 0 (and its errors on
/// the rank that found them).
fn report(ran: Result<RankRun, Error>) -> i32 {
    let run = match ran {
        Ok(r) => r,
        Err(e) => return fail(&e),
    };
    let results = match run.outcome {
        Ok(r) => r,
        // the other ranks stay silent but for what only they know
        Err(e) if run.rank > 0 => {
            return match e {
                Error::Solve { .. } => EXIT_SOLVE_FAILED,
                Error::Interrupted { .. } => EXIT_INTERRUPTED,
                Error::Output { .. } => {
                    eprintln!("error: {e}");
                    EXIT_SOLVE_FAILED
                }
                e => fail(&e),
            }
        }
        Err(Error::Solve { results, .. } | Error::Interrupted { results, .. }) => *results,
        Err(Error::Output {
            message, results, ..
        }) => {
            let summary = &results.summary;
            eprintln!(
                "error: {message}; the other outputs in {} hold the last state written",
                run.dir.display()
            );
            eprintln!(
                "{} in {:.2} s, but the outputs are incomplete",
                if summary.interrupted {
                    "stopped on request"
                } else if summary.converged {
                    "solved"
                } else {
                    "FAILED"
                },
                summary.wall_s
            );
            if summary.interrupted {
                return EXIT_INTERRUPTED;
            }
            return EXIT_SOLVE_FAILED;
        }
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_SOLVE_FAILED;
        }
    };
    let summary = &results.summary;
    eprintln!(
        "{} in {:.2} s",
        if summary.interrupted {
            "stopped on request"
        } else if summary.converged {
            "finished"
        } else {
            "FAILED"
        },
        summary.wall_s
    );
    if summary.interrupted {
        eprintln!("interrupted: the outputs hold the last accepted step");
        return EXIT_INTERRUPTED;
    }
    if summary.converged {
        EXIT_OK
    } else {
        eprintln!(
            "error: {}",
            summary.error.as_deref().unwrap_or("the solve failed")
        );
        EXIT_SOLVE_FAILED
    }
}

/// Says why a run could not start (unless another rank says it) and gives its exit status.
pub fn fail(e: &Error) -> i32 {
    if !matches!(e, Error::OtherRank { .. }) {
        eprintln!("error: {e}");
    }
    match e {
        Error::Input(_) | Error::Refused(_) | Error::OtherRank { input: true } => EXIT_BAD_INPUT,
        Error::Interrupted { .. } => EXIT_INTERRUPTED,
        _ => EXIT_SOLVE_FAILED,
    }
}

/// `deasim COMMAND` for a command other than `run` under an MPI launcher that started several
/// processes: each would do the whole work and write the same files, so the command refuses
/// (the first process says why). `None` without a launcher or with one process.
pub fn refuse_under_mpi(command: &str) -> Option<i32> {
    let size = launched_size();
    if size < 2 {
        return None;
    }
    if launched_rank() == 0 {
        eprintln!(
            "error: `deasim {command}` runs in one process, but an MPI launcher started {size}: \
             each would do the whole work and write the same files. Run it without the \
             launcher; under MPI only `deasim run` (with `[solver] kind = \"petsc\"`) shares \
             its work, and its `modes` and `frequency-response` stages are the distributed form \
             of `deasim modes`, `response` and `reduce`"
        );
    }
    Some(EXIT_BAD_INPUT)
}

/// First SIGINT/SIGTERM: finish the current step, write the outputs, exit 130; second: stop at
/// once. Every rank of a distributed run catches them (the launcher passes them on).
fn catch_signals() {
    let _ = ctrlc::set_handler(|| {
        if crate::solve::interrupt::request() {
            std::process::exit(EXIT_INTERRUPTED);
        }
    });
}

/// `deasim run --resume DIR`: continues the run whose newest checkpoint is in `dir`, with the
/// scenario stored in it ([`read_checkpoint`], [`Resume::run_on_ranks`]). A scenario file or
/// overrides given again must equal the stored ones.
pub fn cmd_resume(
    dir: &Path,
    scenario: Option<&Path>,
    overrides: &[String],
    checkpoint_every: Option<usize>,
) -> i32 {
    let resume = match read_checkpoint(dir) {
        Ok(r) => r,
        Err(e) => return fail(&e),
    };
    if let Err(e) = matches_given(&resume, scenario, overrides, checkpoint_every) {
        eprintln!("error: cannot resume from {}: {e}", dir.display());
        return EXIT_BAD_INPUT;
    }
    catch_signals();
    let mut progress = Progress::new();
    report(resume.run_on_ranks(RankOptions {
        observers: vec![&mut progress],
        ..RankOptions::default()
    }))
}

/// Whether what is given again on the command line (a scenario file, overrides, an interval)
/// is what the checkpointed run used.
fn matches_given(
    resume: &Resume,
    scenario: Option<&Path>,
    overrides: &[String],
    checkpoint_every: Option<usize>,
) -> Result<(), String> {
    let src = resume.source();
    if let Some(p) = scenario {
        let (text, _, _) = read_scenario(Some(p)).map_err(|e| e.to_string())?;
        if text != src.text {
            return Err(format!(
                "{} differs from the scenario stored in the checkpoint (`{}`); resume without a \
                 scenario argument to use the stored one",
                p.display(),
                src.file
            ));
        }
    }
    if !overrides.is_empty() && overrides != src.overrides.as_slice() {
        return Err(format!(
            "--set {} differs from the stored overrides [{}]",
            overrides.join(" --set "),
            src.overrides.join(", ")
        ));
    }
    if let Some(n) = checkpoint_every {
        if n != resume.every() {
            return Err(format!(
                "--checkpoint-every {n} differs from the interval {} of the checkpointed run",
                resume.every()
            ));
        }
    }
    Ok(())
}

/// The time of a progress line with the digits its step `dt` needs (s): `0.5000 s`, or in µs
/// below 10 ms (`12.5 µs`), so that successive µs steps do not all read `t = 0.0000 s`.
fn progress_time(t: f64, dt: f64) -> String {
    let step = if dt > 0.0 { dt } else { t.abs() };
    // decimals that resolve the step in `unit`
    let decimals = |unit: f64| {
        if step > 0.0 && step.is_finite() {
            ((-(step / unit).log10()).ceil() as i64 + 1).clamp(0, 9) as usize
        } else {
            0
        }
    };
    if t != 0.0 && t.abs() < 1e-2 {
        format!("{:.*} µs", decimals(1e-6).max(1), t * 1e6)
    } else {
        format!("{:.*} s", decimals(1.0).max(4), t)
    }
}

/// `deasim check`; with `trial`, the first steps are solved to estimate the run's time and disk use.
pub fn cmd_check(scenario: &Path, overrides: &[String], trial: bool) -> i32 {
    match load(Some(scenario), overrides) {
        Ok(plan) => {
            let m = &plan.model.mesh;
            println!("scenario `{}` is valid", plan.name);
            println!(
                "mesh: {} nodes, {} {} cells",
                m.n_nodes(),
                m.n_cells(),
                m.kind.name()
            );
            let (lo, hi) = m.extents();
            println!(
                "extents: x {:.4e} … {:.4e} m, y {:.4e} … {:.4e} m, z {:.4e} … {:.4e} m",
                lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]
            );
            println!("dofs: {} ({} per node)", m.n_nodes() * 4, 4);
            for (name, lines) in plan.material_names.iter().zip(&plan.material_parameters) {
                println!("material `{name}`:");
                for l in lines {
                    println!("  {l}");
                }
            }
            for e in &plan.electrodes {
                match e.charge.as_ref().map(|w| w.constant_value()) {
                    None => println!("electrode `{}`: {} nodes", e.name, e.nodes.len()),
                    Some(Some(q)) => println!(
                        "electrode `{}`: {} nodes, charge-controlled: {q:e} C (its voltage is an \
                         unknown)",
                        e.name,
                        e.nodes.len()
                    ),
                    Some(None) => println!(
                        "electrode `{}`: {} nodes, charge-controlled by a waveform in C (its \
                         voltage is an unknown)",
                        e.name,
                        e.nodes.len()
                    ),
                }
                match &e.controller {
                    Some(Controller::Pid(c)) => println!(
                        "  controller: PID on probe `{}` (kp {:e}, ki {:e}, kd {:e}), sampled every \
                         {:e} s, output {} … {} V, in the dynamic and quasi-static stages with the \
                         electrodes on",
                        c.probe_name, c.kp, c.ki, c.kd, c.sample_time, c.lower, c.upper
                    ),
                    Some(Controller::StateFeedback(c)) => println!(
                        "  controller: state feedback from `{}` ({} states, about {} V) tracking \
                         `{}`, observer on {}, sampled every {:e} s, output {} … {} V, in the \
                         dynamic stages with the electrodes on",
                        c.model_path,
                        c.design.ad.len(),
                        c.design.bias_v,
                        c.design.tracked,
                        c.design
                            .measured
                            .iter()
                            .map(|m| format!("`{m}`"))
                            .collect::<Vec<_>>()
                            .join(", "),
                        c.design.sample_time,
                        c.lower,
                        c.upper
                    ),
                    None => {}
                }
            }
            if let Some(p) = plan.prestretch {
                println!(
                    "pre-stretch: equibiaxial {} before the first stage (fallback ramp: {} steps)",
                    p.stretch, p.steps
                );
            }
            let g = plan
                .model
                .body_force
                .iter()
                .zip(&plan.densities)
                .find(|(_, &r)| r > 0.0);
            if let Some((b, rho)) = g {
                // in the scenario's order: a meridian model holds (R, Z, 0), the scenario (x, y, z)
                let b = if plan.model.is_axisymmetric() {
                    [b[0], b[2], b[1]]
                } else {
                    [b[0], b[1], b[2]]
                };
                println!(
                    "gravity: [{}, {}, {}] m/s²",
                    Short(b[0] / rho),
                    Short(b[1] / rho),
                    Short(b[2] / rho)
                );
            }
            for r in &plan.rigid {
                println!(
                    "rigid region `{}`: {} nodes, attached mass {} kg in the mesh",
                    r.set,
                    r.nodes.len(),
                    r.mass
                );
            }
            if plan.symmetry_factor != 1.0 {
                println!(
                    "symmetry: the mesh is 1/{} of the device; global probes and energies are \
                     for the whole device",
                    plan.symmetry_factor
                );
            }
            for (i, s) in plan.stages.iter().enumerate() {
                match s.kind {
                    StageKind::Static { steps } => {
                        println!(
                            "stage {i} `{}`: static, {steps} steps, duration {} s",
                            s.name, s.duration
                        )
                    }
                    StageKind::QuasiStatic { steps } => {
                        println!(
                            "stage {i} `{}`: quasi-static, {steps} steps over {} s",
                            s.name, s.duration
                        )
                    }
                    StageKind::Dynamic { dt, scheme, .. } => println!(
                        "stage {i} `{}`: dynamic ({}), duration {} s, dt {dt} s ({} steps)",
                        s.name,
                        scheme.name(),
                        s.duration,
                        s.kind.nominal_steps(s.duration)
                    ),
                    StageKind::Modes {
                        count,
                        shift_hz,
                        ref harmonics,
                    } => println!(
                        "stage {i} `{}`: modes, {count} nearest to {shift_hz} Hz{}",
                        s.name,
                        if harmonics == &[0] {
                            String::new()
                        } else {
                            format!(" of each harmonic {harmonics:?}")
                        }
                    ),
                    StageKind::Continuation {
                        steps,
                        ref parameter,
                        ref target,
                        max_points,
                    } => println!(
                        "stage {i} `{}`: continuation (arc length) in `{}`, first load step \
                         1/{steps}, until {}",
                        s.name,
                        parameter.column(&plan).0,
                        match target {
                            crate::job::plan::PathTarget::Load(l) =>
                                format!("load factor {l} (at most {max_points} points)"),
                            crate::job::plan::PathTarget::Probe { name, value } => format!(
                                "probe `{name}` reaches {value} (at most {max_points} points)"
                            ),
                            crate::job::plan::PathTarget::Points => format!("{max_points} points"),
                        }
                    ),
                    StageKind::FrequencyResponse {
                        electrode,
                        ref frequencies,
                        method,
                    } => println!(
                        "stage {i} `{}`: frequency response to `{}`, {} frequencies from {} to \
                         {} Hz ({})",
                        s.name,
                        plan.electrodes[electrode].name,
                        frequencies.len(),
                        frequencies.first().copied().unwrap_or(0.0),
                        frequencies.last().copied().unwrap_or(0.0),
                        match method {
                            ResponseMethod::Direct => "direct solves".to_string(),
                            ResponseMethod::Modal { count } =>
                                format!("{count} modes with a static correction"),
                        }
                    ),
                }
            }
            println!(
                "probes: {}",
                plan.probes
                    .iter()
                    .map(|p| p.0.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            let mut warnings = plan.warnings.clone();
            let mut problems = Vec::new();
            if trial {
                let (w, p) = print_estimate(&plan);
                warnings.extend(w);
                problems.extend(p);
            }
            if problems.is_empty() {
                println!("problems: none");
            } else {
                println!("problems:");
                for p in &problems {
                    println!("  {p}");
                }
            }
            if !warnings.is_empty() {
                println!("warnings:");
                for w in &warnings {
                    println!("  {w}");
                }
            }
            if problems.is_empty() {
                EXIT_OK
            } else {
                EXIT_BAD_INPUT
            }
        }
        Err(e) => {
            println!("problems:\n  {e}");
            EXIT_BAD_INPUT
        }
    }
}

/// Prints the estimate of a short trial run; returns the warnings of a long run or large output
/// (or of a trial that reached a limit point, where the run will stop) and the problems: a trial
/// that failed otherwise.
fn print_estimate(plan: &Plan) -> (Vec<String>, Vec<String>) {
    use super::estimate::{
        estimate, human_bytes, human_duration, TrialError, LARGE_OUTPUT_BYTES, LONG_RUN_S,
    };
    let mut warnings = Vec::new();
    let mut problems = Vec::new();
    match estimate(plan) {
        Ok(e) => {
            // a trial stopped at a limit point shows where the run will stop; any other
            // failure is a problem of the scenario
            if let Some(f) = &e.failure {
                if f.contains("pull-in") || f.contains("limit point") {
                    warnings.push(format!("the trial stopped: {f}"));
                } else {
                    problems.push(format!("the trial run failed: {f}"));
                }
            }
            println!(
                "estimate: {} for {} steps (each stage's steps at the rate of a trial of its \
                 first steps, {} steps in {} stage(s); cut-back steps and slower convergence \
                 later in a stage take longer)",
                human_duration(e.run_s),
                e.steps,
                e.trial_steps,
                e.stages_timed
            );
            let revolved = if plan.output.revolve.is_some() {
                " (the section and its revolved view)"
            } else {
                ""
            };
            println!(
                "estimate: {} on disk: {} field files of {}{revolved} and the history",
                human_bytes(e.disk_bytes()),
                e.field_files,
                human_bytes(e.field_file_bytes as f64)
            );
            if e.run_s > LONG_RUN_S {
                warnings.push(format!(
                    "the run may take {}: a coarser mesh, fewer steps or a larger time step \
                     shorten it",
                    human_duration(e.run_s)
                ));
            }
            if e.disk_bytes() > LARGE_OUTPUT_BYTES {
                let smaller = if plan.output.revolve.is_some() {
                    "; fewer `output.revolve_wedges` or `output.revolve = false` shrink the \
                     revolved view"
                } else {
                    ""
                };
                warnings.push(format!(
                    "the outputs may take {}: a larger `output.fields_every` writes fewer \
                     field files{smaller}",
                    human_bytes(e.disk_bytes())
                ));
            }
        }
        Err(TrialError::NoSteps(e)) => println!("estimate: none ({e})"),
        Err(TrialError::Failed(e)) => {
            println!("estimate: none (the trial failed)");
            problems.push(format!("the trial run failed: {e}"));
        }
    }
    (warnings, problems)
}

/// `deasim example [NAME]`.
pub fn cmd_example(name: Option<&str>) -> i32 {
    match name {
        None => {
            for (n, text) in EXAMPLES {
                let desc = text
                    .lines()
                    .find_map(|l| l.strip_prefix("description = "))
                    .unwrap_or("")
                    .trim_matches('"');
                println!("{n:<16} {desc}");
            }
            EXIT_OK
        }
        Some(n) => match example(n) {
            Some(t) => {
                print!("{t}");
                EXIT_OK
            }
            None => {
                let names: Vec<&str> = EXAMPLES.iter().map(|e| e.0).collect();
                let hint = crate::io::scenario::closest(n, names.iter().copied())
                    .map(|c| format!("; did you mean `{c}`?"))
                    .unwrap_or_default();
                eprintln!(
                    "error: no example named `{n}` (examples: {}){hint}",
                    names.join(", ")
                );
                EXIT_BAD_INPUT
            }
        },
    }
}

#[cfg(test)]
mod progress_tests {
    use super::{progress_time, Progress};
    use crate::job::observer::Observer;
    use crate::job::run::StepRecord;

    /// A progress made before the plan is built takes the plan's nominal steps from its first
    /// step, and counts from there.
    #[test]
    fn progress_learns_the_total_from_the_run() {
        let plan = super::load(Some(std::path::Path::new("film")), &[]).unwrap();
        let mut progress = Progress::new();
        assert_eq!(progress.total_steps, 0);
        let record = |step| StepRecord {
            time: 0.0,
            stage: "charge".into(),
            step,
            voltage: 0.0,
            newton_iterations: 0,
            dt: 0.0,
            energies: Default::default(),
            probes: Vec::new(),
            max_electric_field: 0.0,
            electrodes: Vec::new(),
        };
        progress.step(&plan, &record(0), &[], &[]);
        progress.step(&plan, &record(1), &[], &[]);
        assert_eq!(progress.total_steps, 15);
        assert!(
            progress.position().starts_with("1/15 steps, 7 %"),
            "{}",
            progress.position()
        );
    }

    /// µs steps are told apart; a ms step keeps its four decimals.
    #[test]
    fn progress_time_resolves_the_step() {
        assert_eq!(progress_time(12.5e-6, 2.5e-6), "12.5 µs");
        assert_eq!(progress_time(13e-6, 1e-6), "13.0 µs");
        assert_ne!(progress_time(1e-6, 1e-6), progress_time(2e-6, 1e-6));
        assert_eq!(progress_time(0.5, 1e-3), "0.5000 s");
        assert_eq!(progress_time(0.0, 1e-3), "0.0000 s");
    }
}
