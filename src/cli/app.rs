//! The commands of the `deasim` binary. `main.rs` only parses arguments and calls these; each
//! returns the process exit status: 0 success, 1 the solve failed, 2 bad input.

use crate::api::{prepare_output, read_scenario, run_plan, Error, RunOptions};
use crate::element::CellFields;
use crate::io::build::{build, Plan, StageKind};
use crate::io::checkpoint::{CheckpointCadence, CheckpointWriter, ScenarioSource};
use crate::io::examples::{example, EXAMPLES};
use crate::io::lock::DirLock;
use crate::io::output::OutputWriter;
use crate::io::pieces::Pieces;
use crate::io::results::ResultsDir;
use crate::io::scenario::{parse, InputError};
use crate::job::observer::Observer;
use crate::job::plan::ResponseMethod;
use crate::job::run::{run_with, RunState, StepRecord};
use crate::job::state::FrequencyResponse;
use crate::job::state::RunSummary;
use crate::time::modal::Mode;
use crate::units::Short;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

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

/// Shows progress: a bar on a terminal, plain lines otherwise.
struct Progress {
    bar: Option<ProgressBar>,
    total_steps: u64,
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

    fn new(plan: &Plan) -> Self {
        let total: u64 = plan
            .stages
            .iter()
            .map(|s| s.kind.nominal_steps(s.duration) as u64)
            .sum();
        let bar = std::io::stderr().is_terminal().then(|| {
            let b = ProgressBar::new(total);
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
            total_steps: total,
            done: 0,
            last_line: None,
            started: std::time::Instant::now(),
            done_at_start: 0,
        }
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

    fn frequency_response(&mut self, _plan: &Plan, stage: &str, r: &FrequencyResponse) {
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

    fn stage_started(&mut self, index: usize, name: &str) {
        match &self.bar {
            Some(b) => b.set_message(format!("stage {name}")),
            None => eprintln!("stage {index} `{name}`"),
        }
    }

    fn step(&mut self, _plan: &Plan, r: &StepRecord, _state: &[f64], _fields: &[CellFields]) {
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

    fn resumed(&mut self, _plan: &Plan, records: &[StepRecord], _: &[f64], _: &[CellFields]) {
        self.done = records.iter().filter(|r| r.step > 0).count() as u64;
        self.done_at_start = self.done;
        self.started = std::time::Instant::now();
        if let Some(b) = &self.bar {
            b.set_position(self.done.min(self.total_steps));
        }
    }

    // the closing line waits for the outputs ([`execute`]): a failed write is no "finished"
    fn finished(&mut self, _plan: &Plan, _s: &RunSummary) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

/// `deasim run`; with `checkpoint_every`, a checkpoint every that many accepted steps.
pub fn cmd_run(
    scenario: Option<&Path>,
    out: Option<&Path>,
    overrides: &[String],
    overwrite: bool,
    checkpoint_every: Option<usize>,
) -> i32 {
    let loaded = read_scenario(scenario).and_then(|(text, name, base)| {
        let s = parse(&text, &name, overrides)?;
        Ok((s, text, name, base))
    });
    let (s, text, name, base) = match loaded {
        Ok(p) => p,
        Err(e) => {
            // under a launcher every process reads the same scenario: one says why
            if launched_rank() == 0 {
                eprintln!("error: {e}");
            }
            return EXIT_BAD_INPUT;
        }
    };
    // a distributed PETSc solve: every rank runs the whole program, rank 0 writes the outputs
    // and every rank its piece of the field files
    let RankPlan {
        plan,
        rank,
        ranks,
        pieces,
        fingerprint,
    } = match plan_on_ranks(&s, &name, base.as_deref(), overrides, true, |_| Ok(())) {
        Ok(p) => p,
        Err((code, e)) => {
            if !e.is_empty() {
                eprintln!("error: {e}");
            }
            return code;
        }
    };
    let dir: PathBuf = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| Path::new("deasim-out").join(&plan.name));
    // on rank parts every rank writes its part's checkpoints; else rank 0 the whole state
    let checkpoint = checkpoint_every.map(|every| CheckpointWriter {
        dir: dir.clone(),
        every,
        source: ScenarioSource {
            text,
            file: name,
            base_dir: base.map(|b| b.display().to_string()),
            overrides: overrides.to_vec(),
        },
        fingerprint,
        ranks: ranks as u64,
        part: plan.part.as_ref().map(|_| rank as u64),
    });
    if rank > 0 {
        // rank 0 prepares the directory first
        if !ranks_agree(true) {
            return EXIT_BAD_INPUT;
        }
        return run_secondary_rank(&plan, &dir, pieces, None, checkpoint);
    }
    let prepared = prepare_output(&dir, &plan, overwrite);
    if ranks > 1 && !ranks_agree(prepared.is_ok()) {
        if let Err(e) = &prepared {
            eprintln!("error: {e}");
        }
        return EXIT_BAD_INPUT;
    }
    // the lock is held until the run ends: a second run into the directory is refused meanwhile
    let (mut results, mut writer) = match prepared {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_BAD_INPUT;
        }
    };
    writer.overrides = overrides.to_vec();
    if let Some(p) = pieces {
        writer.split_fields(p, false);
    }
    let status = execute(&plan, &dir, writer, checkpoint, None, &mut results);
    if ranks > 1 {
        mpi_barrier();
        // the other ranks' pieces of the field files are written now
        if let Err(e) = results.record() {
            eprintln!("error: {e}");
        }
    }
    status
}

/// What a rank runs: its plan, its rank of how many, its piece of the field files (`None` on
/// one rank) and the whole plan's fingerprint (what its checkpoints are checked against).
struct RankPlan {
    plan: Plan,
    rank: usize,
    ranks: usize,
    pieces: Option<Pieces>,
    fingerprint: u64,
}

/// This rank's plan of the scenario `s` (read from `file`, relative names from `base`).
///
/// On one process it is the whole plan. On several PETSc ranks, when `parts` allows it and
/// the plan can be divided, rank 0 alone builds the whole plan. It reads or generates the mesh,
/// cuts every rank's part and sends it ([`crate::job::part::messages`]). Each rank then holds
/// only its part of the mesh and the state. Otherwise every rank builds the whole plan and shares
/// its cells ([`distribute`]); rank 0 says which. A run with the environment variable
/// `DEASIM_WHOLE_STATE` set keeps the whole state (to compare the two).
///
/// `check` (on rank 0, given the whole plan) refuses a plan before any part is sent. An error
/// carries the exit status and its message, which is empty on the ranks that stay silent.
fn plan_on_ranks(
    s: &crate::io::scenario::Scenario,
    file: &str,
    base: Option<&Path>,
    overrides: &[String],
    parts: bool,
    check: impl Fn(&Plan) -> Result<(), String>,
) -> Result<RankPlan, (i32, String)> {
    let bad = |e: String| (EXIT_BAD_INPUT, e);
    // a value from a `--set` is named, as `check` names it
    let blame = |e| crate::io::scenario::blame_override(e, overrides).to_string();
    // every rank reads the solver settings: PETSc's check of its options is collective (each
    // rank finds the same fault: one says it)
    let solver = crate::io::build::solver_settings(s, file).map_err(|e| {
        bad(if launched_rank() == 0 {
            blame(e)
        } else {
            String::new()
        })
    })?;
    let (rank, ranks) = mpi_ranks(&solver)?;
    // `geometry`: whether the plan holds its cells' geometry (rank 0 of a run that may be cut
    // into parts builds it without: each part computes its own cells')
    let whole = |rank: usize, geometry: bool| -> Result<Plan, (i32, String)> {
        let plan =
            crate::io::build::build_with(s, file, base, geometry).map_err(|e| bad(blame(e)))?;
        if ranks > 1 {
            verbose(&format!(
                "deasim: rank {rank}: built the whole plan ({} nodes, {} cells)",
                plan.model.mesh.n_nodes(),
                plan.model.mesh.n_cells()
            ));
        }
        if rank == 0 {
            check(&plan).map_err(bad)?;
        }
        Ok(plan)
    };
    if ranks < 2 {
        let plan = whole(rank, true)?;
        let fingerprint = plan.fingerprint();
        return Ok(RankPlan {
            plan,
            rank,
            ranks,
            pieces: None,
            fingerprint,
        });
    }
    // rank 0 builds the whole plan and says what the others do: stop, build the whole plan
    // too, or take their parts
    const FAILED: f64 = 1.0;
    const WHOLE: f64 = 2.0;
    const PARTS: f64 = 3.0;
    let mut first = None;
    let mut say = [0.0];
    if rank == 0 {
        let built = whole(0, !parts);
        say[0] = match &built {
            Err(_) => FAILED,
            Ok(plan) => {
                let why = if !parts {
                    Some("the checkpoint holds the whole state".to_string())
                } else if std::env::var_os("DEASIM_WHOLE_STATE").is_some() {
                    // for comparisons (scripts/bench-mpi.sh)
                    Some("DEASIM_WHOLE_STATE is set".to_string())
                } else {
                    plan.parts_unsupported()
                };
                match why {
                    Some(why) => {
                        eprintln!("deasim: every rank holds the whole state: {why}");
                        WHOLE
                    }
                    None => PARTS,
                }
            }
        };
        first = Some(built);
    }
    sum_over_ranks(&mut say).map_err(|e| (EXIT_SOLVE_FAILED, e))?;
    if say[0] == FAILED {
        return Err(match first {
            Some(Err(e)) => e,
            _ => (EXIT_BAD_INPUT, String::new()),
        });
    }
    let built = match first {
        Some(built) => built,
        None if say[0] == WHOLE => whole(rank, true),
        None => Err((EXIT_BAD_INPUT, String::new())),
    };
    if say[0] == WHOLE {
        // each rank has built the whole plan (a failure stops all of them)
        // rank 0 built it without its cells' geometry for parts: the shared cells need it
        let built = built.and_then(|mut plan| {
            if parts && rank == 0 {
                plan.model
                    .hold_every_geometry()
                    .map_err(|e| bad(e.to_string()))?;
            }
            Ok(plan)
        });
        let mut plan = if ranks_agree(built.is_ok()) {
            built?
        } else {
            return Err(built.err().unwrap_or((EXIT_BAD_INPUT, String::new())));
        };
        let fingerprint = plan.fingerprint();
        let pieces = distribute(&mut plan, rank, ranks);
        return Ok(RankPlan {
            plan,
            rank,
            ranks,
            pieces,
            fingerprint,
        });
    }
    let plan = take_part(s, file, built.ok(), rank, ranks)
        .map_err(|e| (EXIT_SOLVE_FAILED, format!("rank {rank}: {e}")))?;
    let cells = plan.model.mesh.n_cells();
    verbose(&format!(
        "deasim: rank {rank}: its part holds {} of the {} nodes and {cells} of the {} cells \
         (peak memory so far {:.0} MiB)",
        plan.model.mesh.n_nodes(),
        plan.whole_nodes(),
        plan.whole_cells(),
        crate::cli::bench::peak_memory_mib()
    ));
    let part = plan
        .part
        .as_ref()
        .ok_or((EXIT_SOLVE_FAILED, String::new()))?;
    let counts = part
        .gather(&[cells as f64])
        .map_err(|e| (EXIT_SOLVE_FAILED, e))?;
    if rank == 0 {
        eprintln!(
            "deasim: one linear system on {ranks} MPI ranks; rank 0 built the whole mesh and \
             sent each rank its part, and each rank holds only its part of the mesh and the \
             state; rank 0 writes the outputs, each rank its piece of the field files"
        );
        let counts: Vec<String> = counts.iter().map(|c| c[0].to_string()).collect();
        eprintln!(
            "deasim: the ranks assemble {} of the {} cells (METIS partition)",
            counts.join(", "),
            plan.whole_cells()
        );
    }
    let fingerprint = part.fingerprint;
    let pieces = Some(Pieces::new(
        &plan.model.mesh,
        &vec![true; cells],
        rank,
        ranks,
    ));
    Ok(RankPlan {
        plan,
        rank,
        ranks,
        pieces,
        fingerprint,
    })
}

/// This rank's part of the plan (collective): rank 0 cuts every rank's part of the whole plan
/// it holds (`whole`) and sends it; every other rank receives its own and builds the scenario's
/// materials for it. A rank whose part cannot be made fails, and the others with it.
fn take_part(
    s: &crate::io::scenario::Scenario,
    file: &str,
    whole: Option<Plan>,
    rank: usize,
    ranks: usize,
) -> Result<Plan, String> {
    #[cfg(feature = "petsc")]
    {
        use crate::algebra::exchange::Exchange;
        use crate::solve::petsc::{receive_bytes, send_bytes};
        let (message, materials) = match whole {
            Some(plan) => {
                // rank 0: its own part kept, every other sent (an empty message: rank 0 could
                // not make it); the first failure is rank 0's message
                let mut parts = crate::job::part::messages(&plan, ranks, plan.fingerprint());
                let mut own: Result<Vec<u8>, String> = Err("no part for rank 0".into());
                let mut failure = None;
                for r in 0..ranks {
                    let part = match &mut parts {
                        Ok(all) => all.next().unwrap_or_else(|| Err("no part".into())),
                        Err(e) => Err(e.clone()),
                    };
                    match part {
                        Ok(bytes) if r == 0 => own = Ok(bytes),
                        Ok(bytes) => send_bytes(&bytes, r).map_err(|e| e.to_string())?,
                        Err(e) => {
                            if r > 0 {
                                send_bytes(&[], r).map_err(|e| e.to_string())?;
                            }
                            failure.get_or_insert(format!("the part of rank {r}: {e}"));
                        }
                    }
                }
                let message = match failure {
                    Some(e) => Err(e),
                    None => own,
                };
                (message, Ok(plan.model.materials.clone()))
            }
            None => {
                let bytes = receive_bytes(0).map_err(|e| e.to_string())?;
                verbose(&format!(
                    "deasim: rank {rank}: received its part of the plan from rank 0 ({} bytes)",
                    bytes.len()
                ));
                let message = if bytes.is_empty() {
                    Err("rank 0 could not make this rank's part (its message is on rank 0)".into())
                } else {
                    Ok(bytes)
                };
                let materials = crate::io::build::materials(s, file).map_err(|e| e.to_string());
                (message, materials)
            }
        };
        let exchange = |eq: &std::sync::Arc<crate::algebra::exchange::LocalEquations>| {
            crate::solve::petsc::PetscExchange::new(eq)
                .map(|x| std::sync::Arc::new(x) as std::sync::Arc<dyn Exchange>)
                .map_err(|e| e.to_string())
        };
        match message.and_then(|m| materials.map(|mats| (m, mats))) {
            Ok((message, materials)) => {
                crate::job::part::receive(&message, materials, rank, ranks, ranks_agree, exchange)
            }
            Err(e) => {
                // the others learn of it in their agreement
                ranks_agree(false);
                Err(e)
            }
        }
    }
    #[cfg(not(feature = "petsc"))]
    {
        let _ = (s, file, whole, rank, ranks);
        Err("rank parts need a build with --features petsc".into())
    }
}

/// Writes `line` to stderr in one write (so that the ranks' lines do not interleave) when the
/// environment variable `DEASIM_PETSC_VERBOSE` is set.
fn verbose(line: &str) {
    if std::env::var_os("DEASIM_PETSC_VERBOSE").is_some() {
        use std::io::Write;
        let _ = std::io::stderr().write_all(format!("{line}\n").as_bytes());
    }
}

/// Sums `v` over the ranks of a distributed run (collective); nothing on one rank.
fn sum_over_ranks(v: &mut [f64]) -> Result<(), String> {
    #[cfg(feature = "petsc")]
    return crate::solve::petsc::sum_over_ranks(v).map_err(|e| e.to_string());
    #[cfg(not(feature = "petsc"))]
    {
        let _ = v;
        Ok(())
    }
}

/// On several ranks: shares the cells of `plan` between them (rank 0 says how) and returns this
/// rank's piece of the field files; `None` on one rank.
fn distribute(plan: &mut Plan, rank: usize, ranks: usize) -> Option<Pieces> {
    if ranks < 2 {
        return None;
    }
    let counts = share_cells(plan, rank, ranks);
    if rank == 0 {
        eprintln!(
            "deasim: one linear system on {ranks} MPI ranks; rank 0 writes the outputs, each \
             rank its piece of the field files"
        );
        let counts: Vec<String> = counts.iter().map(|c| c.to_string()).collect();
        eprintln!(
            "deasim: the ranks assemble {} of the {} cells (METIS partition)",
            counts.join(", "),
            plan.model.mesh.n_cells()
        );
    }
    let share = plan.model.share.as_ref()?;
    let owned: Vec<bool> = (0..share.part.len()).map(|c| share.owns(c)).collect();
    Some(Pieces::new(&plan.model.mesh, &owned, rank, ranks))
}

/// Whether every rank of a distributed run says `ok` (a collective call: every rank makes it at
/// the same point); always `ok` on one rank.
fn ranks_agree(ok: bool) -> bool {
    #[cfg(feature = "petsc")]
    {
        let mut failed = [if ok { 0.0 } else { 1.0 }];
        match crate::solve::petsc::sum_over_ranks(&mut failed) {
            Ok(()) => failed[0] == 0.0,
            Err(e) => {
                eprintln!("error: {e}");
                false
            }
        }
    }
    #[cfg(not(feature = "petsc"))]
    ok
}

/// This process's rank and the number of ranks when the plan's solver is distributed (PETSc,
/// which initialises MPI here); `(0, 1)` otherwise.
///
/// Several processes started by an MPI launcher for a solver that is not PETSc's would each
/// solve the whole problem and write the same files: an error (the empty message on all ranks
/// but the first, so that it is printed once).
fn mpi_ranks(
    solver: &crate::solve::linear::SolverSettings,
) -> Result<(usize, usize), (i32, String)> {
    #[cfg(feature = "petsc")]
    if solver.kind == crate::solve::linear::SolverKind::Petsc {
        let (rank, ranks) =
            crate::solve::petsc::world().map_err(|e| (EXIT_SOLVE_FAILED, e.to_string()))?;
        if ranks > 1 {
            // a signal reaches the ranks at different steps: every rank stops at the first step
            // any rank has seen one, or the others would wait for it
            crate::solve::interrupt::agree_over(Box::new(|v| {
                crate::solve::petsc::sum_over_ranks(v).map_err(|e| e.to_string())
            }));
        }
        return Ok((rank, ranks));
    }
    let launched = launched_size();
    if launched > 1 {
        let message = if launched_rank() == 0 {
            format!(
                "an MPI launcher started {launched} processes, but `[solver] kind = \"{}\"` \
                 solves the whole problem in each, and each would write the same files: a \
                 distributed run needs `kind = \"petsc\"` (a build with `--features petsc`); \
                 otherwise run deasim without the launcher",
                solver.kind.name()
            )
        } else {
            String::new()
        };
        return Err((EXIT_BAD_INPUT, message));
    }
    Ok((0, 1))
}

/// Number of processes an MPI launcher started (Open MPI's or a PMI launcher's variable); 1
/// without a launcher.
fn launched_size() -> usize {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE"]
        .iter()
        .find_map(|v| std::env::var(v).ok()?.parse().ok())
        .unwrap_or(1)
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

/// Shares the cells of a distributed run between its `ranks` ranks (this one `rank`): each
/// assembles its part, the residual is summed over the ranks by PETSc. Returns the number of
/// cells of each rank.
fn share_cells(plan: &mut Plan, rank: usize, ranks: usize) -> Vec<usize> {
    #[cfg(feature = "petsc")]
    if ranks > 1 {
        return plan.share_cells(
            rank,
            ranks,
            Box::new(|v: &mut [f64]| {
                crate::solve::petsc::sum_over_ranks(v).map_err(|e| e.to_string())
            }),
        );
    }
    // one process assembles every cell
    let _ = (rank, ranks);
    vec![plan.model.mesh.n_cells()]
}

/// Waits for every rank of a distributed run (rank 0 has written its files).
fn mpi_barrier() {
    #[cfg(feature = "petsc")]
    if let Err(e) = crate::solve::petsc::barrier() {
        eprintln!("warning: {e}");
    }
}

/// This process's rank as an MPI launcher set it (Open MPI's or a PMI launcher's variable);
/// 0 without a launcher. Known before MPI is initialised.
fn launched_rank() -> usize {
    ["OMPI_COMM_WORLD_RANK", "PMI_RANK"]
        .iter()
        .find_map(|v| std::env::var(v).ok()?.parse().ok())
        .unwrap_or(0)
}

/// A rank other than 0 of a distributed run: the same run (the same steps, so the same
/// collective PETSc calls), silent, writing only its `pieces` of the field files into `dir`
/// (from `start` when resuming), and its part's checkpoints when `checkpoint` says so.
fn run_secondary_rank(
    plan: &Plan,
    dir: &Path,
    pieces: Option<Pieces>,
    start: Option<RunState>,
    checkpoint: Option<CheckpointWriter>,
) -> i32 {
    let mut writer = match OutputWriter::new(dir) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("error: {}: {e}", dir.display());
            return EXIT_BAD_INPUT;
        }
    };
    if let Some(p) = pieces {
        writer.split_fields(p, true);
    }
    // rank 0 writes the whole state's checkpoints and this rank takes part in making their
    // state; on rank parts this rank writes its own
    let (mut own, mut cadence) = match checkpoint {
        Some(c) if c.part.is_some() => (Some(c), None),
        Some(c) => (None, Some(CheckpointCadence { every: c.every })),
        None => (None, None),
    };
    catch_signals();
    let mut observers: Vec<&mut dyn Observer> = vec![&mut writer];
    if let Some(c) = own.as_mut() {
        observers.push(c);
    }
    if let Some(c) = cadence.as_mut() {
        observers.push(c);
    }
    let summary = run_with(plan, &mut observers, start);
    mpi_barrier();
    if let Some(f) = writer.write_failure() {
        eprintln!("error: {f}");
        return EXIT_SOLVE_FAILED;
    }
    if summary.interrupted {
        EXIT_INTERRUPTED
    } else if summary.converged {
        EXIT_OK
    } else {
        EXIT_SOLVE_FAILED
    }
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
/// scenario stored in it. A scenario file or overrides given again must equal the stored ones.
pub fn cmd_resume(
    dir: &Path,
    scenario: Option<&Path>,
    overrides: &[String],
    checkpoint_every: Option<usize>,
) -> i32 {
    if !dir.is_dir() {
        eprintln!(
            "error: cannot resume from {}: no such directory",
            dir.display()
        );
        return EXIT_BAD_INPUT;
    }
    // under an MPI launcher the process of rank 0 locks the directory and speaks; a failure
    // here ends the process, and the launcher then stops the others
    let first = launched_rank() == 0;
    let lock = if first {
        match DirLock::acquire(dir) {
            Ok(l) => Some(l),
            Err(e) => {
                eprintln!("error: {e}");
                return EXIT_BAD_INPUT;
            }
        }
    } else {
        None
    };
    match prepare_resume(dir, scenario, overrides, checkpoint_every, first) {
        Ok((s, mut checkpoint, state)) => {
            let source = &checkpoint.source;
            let base = source.base_dir.as_deref().map(Path::new);
            let (fingerprint, parts) = (checkpoint.fingerprint, checkpoint.part.is_some());
            let check = |plan: &Plan| -> Result<(), String> {
                if plan.fingerprint() != fingerprint {
                    return Err(format!(
                        "cannot resume from {}: the rebuilt model does not match the checkpoint \
                         (a mesh file changed?)",
                        dir.display()
                    ));
                }
                if !parts {
                    check_state(plan, &state)
                        .map_err(|e| format!("cannot resume from {}: {e}", dir.display()))?;
                }
                Ok(())
            };
            let RankPlan {
                plan,
                rank,
                ranks,
                pieces,
                ..
            } = match plan_on_ranks(&s, &source.file, base, &source.overrides, parts, check) {
                Ok(p) => p,
                Err((code, e)) => {
                    if !e.is_empty() {
                        eprintln!("error: {e}");
                    }
                    return code;
                }
            };
            if rank == 0 {
                eprintln!(
                    "deasim: resuming `{}` from step {} (stage {}, {} steps recorded)",
                    plan.name,
                    state.accepted,
                    state.stage,
                    state.records.len()
                );
            }
            let (pieces, state) = if checkpoint.part.is_some() {
                match resume_part(&plan, dir, &checkpoint, state, pieces, rank, ranks) {
                    Ok(p) => p,
                    Err(e) => {
                        eprintln!(
                            "error: rank {rank}: cannot resume from {}: {e}",
                            dir.display()
                        );
                        return EXIT_BAD_INPUT;
                    }
                }
            } else {
                if rank == 0 && checkpoint.ranks != ranks as u64 {
                    eprintln!(
                        "warning: the checkpoint was written on {} MPI rank(s), this run has \
                         {ranks}: the partition orders the sums, so the results agree to \
                         round-off, not bit for bit",
                        checkpoint.ranks
                    );
                }
                (pieces, state)
            };
            checkpoint.ranks = ranks as u64;
            checkpoint.part = checkpoint.part.map(|_| rank as u64);
            if rank > 0 {
                return run_secondary_rank(&plan, dir, pieces, Some(state), Some(checkpoint));
            }
            let Some(lock) = lock else {
                return EXIT_BAD_INPUT;
            };
            // the run's own directory: its manifest keeps the files listed so far
            let hash = format!("{:016x}", plan.fingerprint());
            let mut results = ResultsDir::resume(dir, lock, &plan.name, &hash);
            let mut writer = match OutputWriter::new(dir) {
                Ok(w) => w,
                Err(e) => {
                    eprintln!("error: {}: {e}", dir.display());
                    return EXIT_BAD_INPUT;
                }
            };
            writer.overrides.clone_from(&checkpoint.source.overrides);
            if let Some(p) = pieces {
                writer.split_fields(p, false);
            }
            let status = execute(
                &plan,
                dir,
                writer,
                Some(checkpoint),
                Some(state),
                &mut results,
            );
            if ranks > 1 {
                mpi_barrier();
                if let Err(e) = results.record() {
                    eprintln!("error: {e}");
                }
            }
            status
        }
        Err(e) => {
            eprintln!("error: cannot resume from {}: {e}", dir.display());
            EXIT_BAD_INPUT
        }
    }
}

/// On rank parts: this rank's part of `plan` and its part's state at the checkpoint's step
/// (rank 0's is `state`, the others read their own files), checked against the part.
/// Collective: every rank fails when one does.
fn resume_part(
    plan: &Plan,
    dir: &Path,
    checkpoint: &CheckpointWriter,
    state: RunState,
    pieces: Option<Pieces>,
    rank: usize,
    ranks: usize,
) -> Result<(Option<Pieces>, RunState), String> {
    if checkpoint.ranks != ranks as u64 {
        return Err(format!(
            "the checkpoint holds the parts of {} MPI rank(s), this run has {ranks}: a run whose \
             ranks held their parts resumes on as many ranks",
            checkpoint.ranks
        ));
    }
    let own =
        if plan.part.is_none() {
            Err("the checkpoint holds rank parts, but this run keeps the whole state on every rank \
             (is DEASIM_WHOLE_STATE set?)"
            .to_string())
        } else if rank == 0 {
            Ok(state)
        } else {
            let path = crate::io::checkpoint::file_of(dir, state.accepted, rank);
            crate::io::checkpoint::Checkpoint::read(&path)
                .map_err(|e| e.to_string())
                .and_then(|ck| {
                    if ck.part != Some(rank as u64) || ck.fingerprint != checkpoint.fingerprint {
                        Err(format!(
                            "{}: not rank {rank}'s part of this run",
                            path.display()
                        ))
                    } else {
                        Ok(ck.state)
                    }
                })
        };
    let own = own.and_then(|st| check_state(plan, &st).map(|()| st));
    if !ranks_agree(own.is_ok()) {
        return Err(own.err().unwrap_or_else(|| {
            "another rank could not take up its part (its message is on that rank)".to_string()
        }));
    }
    Ok((pieces, own?))
}

/// Whether a checkpoint's run state fits `plan` (its stage kinds and vector sizes).
fn check_state(plan: &Plan, st: &RunState) -> Result<(), String> {
    use crate::job::state::StagePosition;
    let n = plan.model.mesh.n_nodes() * crate::problem::dofs::FIELDS;
    let stage = plan.stages.get(st.stage);
    let kinds_match = matches!(
        (stage.map(|s| &s.kind), &st.position),
        (
            Some(StageKind::Static { .. } | StageKind::QuasiStatic { .. }),
            StagePosition::Static { stage_start, .. }
        )
            if stage_start.len() == n
    ) || matches!(
        (stage.map(|s| &s.kind), &st.position),
        (
            Some(StageKind::Dynamic { .. }),
            StagePosition::Dynamic { .. }
        )
    );
    let sizes_match = [st.q.len(), st.v.len(), st.a.len()].iter().all(|&l| l == n)
        && st
            .records
            .iter()
            .all(|r| r.probes.len() == plan.probes.len())
        && st.recorder.broken_down.len() == plan.model.materials.len()
        && st.recorder.reference.len() == n;
    if kinds_match && sizes_match {
        Ok(())
    } else {
        Err("the checkpoint does not match the scenario's model or stages".to_string())
    }
}

/// Reads the newest checkpoint of `dir` and checks it against what is given again: its stored
/// scenario (parsed), what its writer continues with, and its run state. The plan is rebuilt
/// and checked against the checkpoint later ([`plan_on_ranks`]). `loud`: warns (the process of
/// rank 0).
fn prepare_resume(
    dir: &Path,
    scenario: Option<&Path>,
    overrides: &[String],
    checkpoint_every: Option<usize>,
    loud: bool,
) -> Result<(crate::io::scenario::Scenario, CheckpointWriter, RunState), String> {
    use crate::io::checkpoint::latest;
    // a run that ended converged wrote its summary.json (a new run deletes the earlier one)
    if let Ok(text) = std::fs::read_to_string(dir.join("summary.json")) {
        let v = serde_json::from_str::<serde_json::Value>(&text).ok();
        if v.is_some_and(|v| v.get("converged") == Some(&serde_json::Value::Bool(true))) {
            return Err(format!(
                "the run in {} already finished (its summary.json says converged): there is \
                 nothing to resume; to run it again, use `deasim run SCENARIO --out {}`",
                dir.display(),
                dir.display()
            ));
        }
    }
    let (ck, _, skipped) = latest(dir).map_err(|e| e.to_string())?;
    for w in skipped.iter().filter(|_| loud) {
        eprintln!("warning: {w}");
    }
    let src = &ck.source;
    let version = env!("CARGO_PKG_VERSION");
    if ck.deasim_version != version {
        return Err(format!(
            "the checkpoint was written by deasim {}, this is deasim {version}",
            ck.deasim_version
        ));
    }
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
        if n as u64 != ck.every {
            return Err(format!(
                "--checkpoint-every {n} differs from the interval {} of the checkpointed run",
                ck.every
            ));
        }
    }
    let s =
        parse(&src.text, &src.file, &src.overrides).map_err(|e| format!("stored scenario: {e}"))?;
    if ck.every < 1 {
        return Err("the checkpoint has no interval".to_string());
    }
    let threads = rayon::current_num_threads() as u64;
    if loud && ck.threads != threads {
        eprintln!(
            "warning: the checkpoint was written with {} threads, this run has {threads}: the \
             results agree to round-off, not bit for bit",
            ck.threads
        );
    }
    let checkpoint = CheckpointWriter {
        dir: dir.to_path_buf(),
        every: ck.every as usize,
        source: ck.source.clone(),
        fingerprint: ck.fingerprint,
        ranks: ck.ranks,
        part: ck.part,
    };
    Ok((s, checkpoint, ck.state))
}

/// Runs a plan into `dir` with SIGINT/SIGTERM handling; returns the exit status.
fn execute(
    plan: &Plan,
    dir: &Path,
    mut writer: OutputWriter,
    checkpoint: Option<CheckpointWriter>,
    start: Option<RunState>,
    results: &mut ResultsDir,
) -> i32 {
    eprintln!(
        "deasim: scenario `{}`: {} nodes, {} {} cells, {} dofs; {} thread(s); output in {}",
        plan.name,
        plan.whole_nodes(),
        plan.whole_cells(),
        plan.model.mesh.kind.name(),
        plan.whole_nodes() * 4,
        rayon::current_num_threads(),
        dir.display()
    );
    catch_signals();
    let mut progress = Progress::new(plan);
    eprintln!(
        "deasim: linear solver: {}",
        plan.solver.describe(plan.whole_nodes() * 4)
    );
    let mut checkpoint = checkpoint;
    let mut observers: Vec<&mut dyn Observer> = vec![&mut writer, &mut progress];
    if let Some(c) = checkpoint.as_mut() {
        observers.push(c);
    }
    observers.push(results);
    let ran = run_plan(
        plan,
        RunOptions {
            observers,
            start,
            ..RunOptions::default()
        },
    );
    let summary = match ran {
        Ok(r) => r.summary,
        Err(Error::Solve { results, .. } | Error::Interrupted { results, .. }) => results.summary,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_SOLVE_FAILED;
        }
    };
    let listed = results.record();
    for e in &writer.errors {
        eprintln!("warning: {e}");
    }
    let failure = writer.write_failure().or(listed.err());
    if let Some(f) = failure {
        eprintln!(
            "error: {f}; the other outputs in {} hold the last state written",
            dir.display()
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
                match e.charge {
                    None => println!("electrode `{}`: {} nodes", e.name, e.nodes.len()),
                    Some(q) => println!(
                        "electrode `{}`: {} nodes, charge-controlled: {q:e} C (its voltage is an \
                         unknown)",
                        e.name,
                        e.nodes.len()
                    ),
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
                    StageKind::Modes { count, shift_hz } => println!(
                        "stage {i} `{}`: modes, {count} nearest to {shift_hz} Hz",
                        s.name
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
    use super::progress_time;

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
