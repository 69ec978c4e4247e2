//! A run on the MPI ranks a launcher started (one process without a launcher): the plan of each
//! rank, the output directory that rank 0 prepares, the run with its writers and checkpoints, and
//! the resumption of a checkpointed run. What `deasim run` does, for any front end.
//!
//! With a distributed (PETSc) solver every rank runs the whole program and makes the same
//! collective calls; rank 0 writes the outputs and every rank its piece of the field files. A
//! fault every rank finds is told by rank 0 alone ([`Error::OtherRank`] on the others). Messages
//! go through the `log` facade.

use super::error::Error;
use super::results::Results;
use super::simulation::{outcome, prepare_output, run_plan, Cancel, RunOptions, Simulation};
use crate::io::build::{Plan, StageKind};
use crate::io::checkpoint::{CheckpointCadence, CheckpointWriter, ScenarioSource};
use crate::io::lock::DirLock;
use crate::io::output::OutputWriter;
use crate::io::pieces::Pieces;
use crate::io::results::ResultsDir;
use crate::io::scenario::{parse, Scenario};
use crate::job::observer::Observer;
use crate::job::run::RunState;
use std::path::{Path, PathBuf};

/// How to run on the ranks ([`Simulation::run_on_ranks`], [`Resume::run_on_ranks`]).
#[derive(Default)]
pub struct RankOptions<'a> {
    /// The output directory (default `deasim-out/<scenario name>`); a resumed run continues in
    /// its own directory (another one is refused).
    pub out: Option<PathBuf>,
    /// Replace another command's or scenario's results in `out`.
    pub overwrite: bool,
    /// A checkpoint every that many accepted steps (a resumed run keeps its interval; another
    /// one is refused).
    pub checkpoint_every: Option<usize>,
    /// Further observers (progress displays), on rank 0 only, after the output writer.
    pub observers: Vec<&'a mut dyn Observer>,
    /// Stops the run (every rank) when cancelled on any rank.
    pub cancel: Option<Cancel>,
}

/// What a rank's run gave.
#[derive(Debug)]
pub struct RankRun {
    /// This process's rank and the number of ranks (0 of 1 on one process).
    pub rank: usize,
    pub ranks: usize,
    /// The output directory.
    pub dir: PathBuf,
    /// The results, or why the run failed after it started (rank 0's [`Results`] hold every
    /// record; another rank's are its own view of the same run).
    pub outcome: Result<Results, Error>,
}

impl Simulation {
    /// Runs the scenario on the MPI ranks the launcher started (one process without one) and
    /// writes the files of `deasim run` into the output directory. Collective: every rank calls
    /// it. An error before the run started is the `Err`; after, it is the [`RankRun::outcome`].
    pub fn run_on_ranks(&self, options: RankOptions) -> Result<RankRun, Error> {
        // under a launcher every process reads the same scenario: one says why
        let s = parse(&self.text, &self.name, &self.overrides).map_err(|e| {
            if launched_rank() == 0 {
                Error::Input(e)
            } else {
                Error::OtherRank { input: true }
            }
        })?;
        let RankPlan {
            plan,
            rank,
            ranks,
            pieces,
            fingerprint,
        } = plan_on_ranks(
            &s,
            &self.name,
            self.base.as_deref(),
            &self.overrides,
            true,
            |_| Ok(()),
        )?;
        let RankOptions {
            out,
            overwrite,
            checkpoint_every,
            observers,
            cancel,
        } = options;
        let dir: PathBuf = out.unwrap_or_else(|| Path::new("deasim-out").join(&plan.name));
        // on rank parts every rank writes its part's checkpoints; else rank 0 the whole state
        let checkpoint = checkpoint_every.map(|every| CheckpointWriter {
            dir: dir.clone(),
            every,
            source: ScenarioSource {
                text: self.text.clone(),
                file: self.name.clone(),
                base_dir: self.base.as_ref().map(|b| b.display().to_string()),
                overrides: self.overrides.clone(),
            },
            fingerprint,
            ranks: ranks as u64,
            part: plan.part.as_ref().map(|_| rank as u64),
        });
        let done = |outcome| {
            Ok(RankRun {
                rank,
                ranks,
                dir: dir.clone(),
                outcome,
            })
        };
        if rank > 0 {
            // rank 0 prepares the directory first
            if !ranks_agree(true) {
                return Err(Error::OtherRank { input: true });
            }
            return done(run_secondary_rank(
                &plan, &dir, pieces, None, checkpoint, cancel,
            ));
        }
        let prepared = prepare_output(&dir, &plan, overwrite);
        if ranks > 1 && !ranks_agree(prepared.is_ok()) {
            return Err(match prepared {
                Err(e) => Error::Refused(e),
                Ok(_) => Error::OtherRank { input: true },
            });
        }
        // the lock is held until the run ends: a second run into the directory is refused
        let (mut results, mut writer) = prepared.map_err(Error::Refused)?;
        writer.overrides.clone_from(&self.overrides);
        if let Some(p) = pieces {
            writer.split_fields(p, false);
        }
        let run = Run {
            plan: &plan,
            dir: &dir,
            ranks,
            start: None,
            observers,
            cancel,
        };
        done(run.execute(writer, checkpoint, &mut results))
    }
}

/// The newest checkpoint of an output directory, read to continue its run: the scenario stored in
/// it and the run state. On the process of rank 0 (or without a launcher) it holds the directory's
/// lock until the resumed run ends.
pub struct Resume {
    dir: PathBuf,
    lock: Option<DirLock>,
    scenario: Scenario,
    checkpoint: CheckpointWriter,
    state: RunState,
    /// The threads the checkpoint was written with.
    threads: u64,
}

impl std::fmt::Debug for Resume {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Resume")
            .field("dir", &self.dir)
            .field("accepted", &self.state.accepted)
            .field("stage", &self.state.stage)
            .finish_non_exhaustive()
    }
}

/// Reads the newest checkpoint of the output directory `dir` to continue its run
/// ([`Resume::start`] on one process, [`Resume::run_on_ranks`] as `deasim run --resume`). A run
/// that finished (its `summary.json` says converged), a checkpoint of another deasim version or
/// one whose stored scenario no longer parses is refused. Warns (through `log`) of the newer
/// checkpoints skipped as unreadable.
pub fn read_checkpoint(dir: &Path) -> Result<Resume, Error> {
    if !dir.is_dir() {
        return Err(Error::Refused(format!(
            "cannot resume from {}: no such directory",
            dir.display()
        )));
    }
    // under an MPI launcher the process of rank 0 locks the directory and speaks
    let first = launched_rank() == 0;
    let lock = if first {
        Some(DirLock::acquire(dir).map_err(Error::Refused)?)
    } else {
        None
    };
    let refuse = |e: String| Error::Refused(format!("cannot resume from {}: {e}", dir.display()));
    // a run that ended converged wrote its summary.json (a new run deletes the earlier one)
    if let Ok(text) = std::fs::read_to_string(dir.join("summary.json")) {
        let v = serde_json::from_str::<serde_json::Value>(&text).ok();
        if v.is_some_and(|v| v.get("converged") == Some(&serde_json::Value::Bool(true))) {
            return Err(refuse(format!(
                "the run in {} already finished (its summary.json says converged): there is \
                 nothing to resume; to run it again, use `deasim run SCENARIO --out {}`",
                dir.display(),
                dir.display()
            )));
        }
    }
    let (ck, _, skipped) = crate::io::checkpoint::latest(dir).map_err(|e| refuse(e.to_string()))?;
    for w in skipped.iter().filter(|_| first) {
        log::warn!("warning: {w}");
    }
    let version = env!("CARGO_PKG_VERSION");
    if ck.deasim_version != version {
        return Err(refuse(format!(
            "the checkpoint was written by deasim {}, this is deasim {version}",
            ck.deasim_version
        )));
    }
    let src = &ck.source;
    let scenario = parse(&src.text, &src.file, &src.overrides)
        .map_err(|e| refuse(format!("stored scenario: {e}")))?;
    if ck.every < 1 {
        return Err(refuse("the checkpoint has no interval".to_string()));
    }
    let checkpoint = CheckpointWriter {
        dir: dir.to_path_buf(),
        every: ck.every as usize,
        source: ck.source.clone(),
        fingerprint: ck.fingerprint,
        ranks: ck.ranks,
        part: ck.part,
    };
    Ok(Resume {
        dir: dir.to_path_buf(),
        lock,
        scenario,
        checkpoint,
        state: ck.state,
        threads: ck.threads,
    })
}

impl Resume {
    /// The checkpointed run's scenario and overrides, as stored in the checkpoint.
    pub fn simulation(&self) -> Simulation {
        let source = &self.checkpoint.source;
        Simulation {
            text: source.text.clone(),
            name: source.file.clone(),
            base: source.base_dir.as_ref().map(PathBuf::from),
            overrides: source.overrides.clone(),
        }
    }

    /// The scenario as stored in the checkpoint (its text, file name, base directory and
    /// overrides).
    pub fn source(&self) -> &ScenarioSource {
        &self.checkpoint.source
    }

    /// The interval of the checkpointed run's checkpoints (accepted steps).
    pub fn every(&self) -> usize {
        self.checkpoint.every
    }

    /// The run state at the checkpoint.
    pub fn state(&self) -> &RunState {
        &self.state
    }

    /// The state to continue `plan` from ([`RunOptions::start`]), checked against it: the plan
    /// must be the checkpointed run's (its fingerprint) and the state must fit its stages and
    /// sizes. A checkpoint of MPI ranks that held their parts is refused (it resumes only on as
    /// many ranks, [`Resume::run_on_ranks`]).
    pub fn start(&self, plan: &Plan) -> Result<RunState, Error> {
        if self.checkpoint.part.is_some() {
            return Err(Error::Refused(format!(
                "cannot resume from {}: the checkpoint holds the parts of {} MPI rank(s): it \
                 resumes on as many ranks",
                self.dir.display(),
                self.checkpoint.ranks
            )));
        }
        fits(plan, self.checkpoint.fingerprint, Some(&self.state)).map_err(|why| {
            Error::Refused(format!("cannot resume from {}: {why}", self.dir.display()))
        })?;
        Ok(self.state.clone())
    }

    /// Continues the checkpointed run on the MPI ranks the launcher started (one process
    /// without one), in its output directory and with its checkpoint interval, as `deasim run
    /// --resume`: the history, field files and checkpoints go on as if the run had not
    /// stopped. Collective: every rank calls it.
    pub fn run_on_ranks(self, options: RankOptions) -> Result<RankRun, Error> {
        let Resume {
            dir,
            lock,
            scenario,
            mut checkpoint,
            state,
            threads,
        } = self;
        let RankOptions {
            out,
            overwrite: _,
            checkpoint_every,
            observers,
            cancel,
        } = options;
        let refuse =
            |why: String| Error::Refused(format!("cannot resume from {}: {why}", dir.display()));
        if out.as_ref().is_some_and(|o| o != &dir) {
            return Err(refuse(
                "a resumed run continues in its own output directory".to_string(),
            ));
        }
        if let Some(n) = checkpoint_every.filter(|&n| n != checkpoint.every) {
            return Err(refuse(format!(
                "the checkpoint interval {n} differs from the interval {} of the checkpointed run",
                checkpoint.every
            )));
        }
        let here = rayon::current_num_threads() as u64;
        if launched_rank() == 0 && threads != here {
            log::warn!(
                "warning: the checkpoint was written with {threads} threads, this run has \
                 {here}: the results agree to round-off, not bit for bit"
            );
        }
        let parts = checkpoint.part.is_some();
        let (fingerprint, source) = (checkpoint.fingerprint, checkpoint.source.clone());
        // a checkpoint of rank parts: each rank checks its own part's state later
        let check =
            |plan: &Plan| fits(plan, fingerprint, (!parts).then_some(&state)).map_err(&refuse);
        let base = source.base_dir.as_deref().map(Path::new);
        let RankPlan {
            plan,
            rank,
            ranks,
            pieces,
            ..
        } = plan_on_ranks(
            &scenario,
            &source.file,
            base,
            &source.overrides,
            parts,
            check,
        )?;
        if rank == 0 {
            log::info!(
                "deasim: resuming `{}` from step {} (stage {}, {} steps recorded)",
                plan.name,
                state.accepted,
                state.stage,
                state.records.len()
            );
        }
        let (pieces, state) = if parts {
            resume_part(&plan, &dir, &checkpoint, state, pieces, rank, ranks).map_err(|e| {
                Error::Refused(format!(
                    "rank {rank}: cannot resume from {}: {e}",
                    dir.display()
                ))
            })?
        } else {
            if rank == 0 && checkpoint.ranks != ranks as u64 {
                log::warn!(
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
        let done = |outcome| {
            Ok(RankRun {
                rank,
                ranks,
                dir: dir.clone(),
                outcome,
            })
        };
        if rank > 0 {
            return done(run_secondary_rank(
                &plan,
                &dir,
                pieces,
                Some(state),
                Some(checkpoint),
                cancel,
            ));
        }
        let Some(lock) = lock else {
            return Err(Error::OtherRank { input: true });
        };
        // the run's own directory: its manifest keeps the files listed so far
        let hash = format!("{:016x}", plan.fingerprint());
        let mut results = ResultsDir::resume(&dir, lock, &plan.name, &hash);
        let mut writer = OutputWriter::new(&dir)
            .map_err(|e| Error::Refused(format!("{}: {e}", dir.display())))?;
        writer.overrides.clone_from(&checkpoint.source.overrides);
        if let Some(p) = pieces {
            writer.split_fields(p, false);
        }
        let run = Run {
            plan: &plan,
            dir: &dir,
            ranks,
            start: Some(state),
            observers,
            cancel,
        };
        done(run.execute(writer, Some(checkpoint), &mut results))
    }
}

/// Rank 0's run of a plan into its output directory.
struct Run<'p, 'o> {
    plan: &'p Plan,
    dir: &'p Path,
    ranks: usize,
    start: Option<RunState>,
    observers: Vec<&'o mut dyn Observer>,
    cancel: Option<Cancel>,
}

impl Run<'_, '_> {
    /// Runs with the output `writer`, the checkpoints and the directory's manifest `results`,
    /// then waits for the other ranks' pieces and lists every file written.
    fn execute(
        self,
        mut writer: OutputWriter,
        checkpoint: Option<CheckpointWriter>,
        results: &mut ResultsDir,
    ) -> Result<Results, Error> {
        let Run {
            plan,
            dir,
            ranks,
            start,
            observers: mut theirs,
            cancel,
        } = self;
        log::info!(
            "deasim: scenario `{}`: {} nodes, {} {} cells, {} dofs; {} thread(s); output in {}",
            plan.name,
            plan.whole_nodes(),
            plan.whole_cells(),
            plan.model.mesh.kind.name(),
            plan.whole_nodes() * 4,
            rayon::current_num_threads(),
            dir.display()
        );
        log::info!(
            "deasim: linear solver: {}",
            plan.solver.describe(plan.whole_nodes() * 4)
        );
        let mut checkpoint = checkpoint;
        let ran = {
            let mut observers: Vec<&mut dyn Observer> = vec![&mut writer];
            for o in theirs.iter_mut() {
                observers.push(&mut **o);
            }
            if let Some(c) = checkpoint.as_mut() {
                observers.push(c);
            }
            observers.push(results);
            run_plan(
                plan,
                RunOptions {
                    observers,
                    start,
                    cancel,
                    ..RunOptions::default()
                },
            )
        };
        let mut run = match ran {
            Ok(r) => r,
            Err(Error::Solve { results, .. } | Error::Interrupted { results, .. }) => *results,
            Err(e) => return Err(e),
        };
        if ranks > 1 {
            // the other ranks' pieces of the field files are written now
            mpi_barrier();
        }
        let listed = results.record();
        for e in &writer.errors {
            log::warn!("warning: {e}");
        }
        run.summary.warnings.extend(writer.errors.iter().cloned());
        if let Some(message) = writer.write_failure().or(listed.err()) {
            return Err(Error::Output {
                path: dir.to_path_buf(),
                message,
                results: Box::new(run),
            });
        }
        outcome(run)
    }
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
/// `check` (on rank 0, given the whole plan) refuses a plan before any part is sent. The ranks
/// that stay silent about a fault return [`Error::OtherRank`].
fn plan_on_ranks(
    s: &Scenario,
    file: &str,
    base: Option<&Path>,
    overrides: &[String],
    parts: bool,
    check: impl Fn(&Plan) -> Result<(), Error>,
) -> Result<RankPlan, Error> {
    let silent = || Error::OtherRank { input: true };
    // a value from a `--set` is named, as `check` names it
    let blame = |e| Error::Input(crate::io::scenario::blame_override(e, overrides));
    // every rank reads the solver settings: PETSc's check of its options is collective (each
    // rank finds the same fault: one says it)
    let solver = crate::io::build::solver_settings(s, file).map_err(|e| {
        if launched_rank() == 0 {
            blame(e)
        } else {
            silent()
        }
    })?;
    let (rank, ranks) = mpi_ranks(&solver)?;
    // `geometry`: whether the plan holds its cells' geometry (rank 0 of a run that may be cut
    // into parts builds it without: each part computes its own cells')
    let whole = |rank: usize, geometry: bool| -> Result<Plan, Error> {
        let plan = crate::io::build::build_with(s, file, base, geometry).map_err(blame)?;
        if ranks > 1 {
            verbose(&format!(
                "deasim: rank {rank}: built the whole plan ({} nodes, {} cells)",
                plan.model.mesh.n_nodes(),
                plan.model.mesh.n_cells()
            ));
        }
        if rank == 0 {
            check(&plan)?;
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
                        log::info!("deasim: every rank holds the whole state: {why}");
                        WHOLE
                    }
                    None => PARTS,
                }
            }
        };
        first = Some(built);
    }
    sum_over_ranks(&mut say).map_err(Error::Ranks)?;
    if say[0] == FAILED {
        return Err(match first {
            Some(Err(e)) => e,
            _ => silent(),
        });
    }
    let built = match first {
        Some(built) => built,
        None if say[0] == WHOLE => whole(rank, true),
        None => Err(silent()),
    };
    if say[0] == WHOLE {
        // each rank has built the whole plan (a failure stops all of them)
        // rank 0 built it without its cells' geometry for parts: the shared cells need it
        let built = built.and_then(|mut plan| {
            if parts && rank == 0 {
                plan.model
                    .hold_every_geometry()
                    .map_err(|e| Error::Refused(e.to_string()))?;
            }
            Ok(plan)
        });
        let mut plan = if ranks_agree(built.is_ok()) {
            built?
        } else {
            return Err(built.err().unwrap_or_else(silent));
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
        .map_err(|e| Error::Ranks(format!("rank {rank}: {e}")))?;
    let cells = plan.model.mesh.n_cells();
    verbose(&format!(
        "deasim: rank {rank}: its part holds {} of the {} nodes and {cells} of the {} cells \
         (peak memory so far {:.0} MiB)",
        plan.model.mesh.n_nodes(),
        plan.whole_nodes(),
        plan.whole_cells(),
        crate::io::memory::peak_memory_mib()
    ));
    let part = plan.part.as_ref().ok_or_else(|| {
        Error::Ranks(format!("rank {rank}: the plan received holds no rank part"))
    })?;
    let counts = part.gather(&[cells as f64]).map_err(Error::Ranks)?;
    if rank == 0 {
        log::info!(
            "deasim: one linear system on {ranks} MPI ranks; rank 0 built the whole mesh and \
             sent each rank its part, and each rank holds only its part of the mesh and the \
             state; rank 0 writes the outputs, each rank its piece of the field files"
        );
        let counts: Vec<String> = counts.iter().map(|c| c[0].to_string()).collect();
        log::info!(
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
    s: &Scenario,
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

/// Reports `line` (through `log`) when the environment variable `DEASIM_PETSC_VERBOSE` is set.
fn verbose(line: &str) {
    if std::env::var_os("DEASIM_PETSC_VERBOSE").is_some() {
        log::info!("{line}");
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
        log::info!(
            "deasim: one linear system on {ranks} MPI ranks; rank 0 writes the outputs, each \
             rank its piece of the field files"
        );
        let counts: Vec<String> = counts.iter().map(|c| c.to_string()).collect();
        log::info!(
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
                log::error!("error: {e}");
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
/// solve the whole problem and write the same files: refused (told by the first process).
fn mpi_ranks(solver: &crate::solve::linear::SolverSettings) -> Result<(usize, usize), Error> {
    #[cfg(feature = "petsc")]
    if solver.kind == crate::solve::linear::SolverKind::Petsc {
        let (rank, ranks) =
            crate::solve::petsc::world().map_err(|e| Error::Ranks(e.to_string()))?;
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
        if launched_rank() != 0 {
            return Err(Error::OtherRank { input: true });
        }
        return Err(Error::Refused(format!(
            "an MPI launcher started {launched} processes, but `[solver] kind = \"{}\"` solves \
             the whole problem in each, and each would write the same files: a distributed run \
             needs `kind = \"petsc\"` (a build with `--features petsc`); otherwise run deasim \
             without the launcher",
            solver.kind.name()
        )));
    }
    Ok((0, 1))
}

/// Number of processes an MPI launcher started (Open MPI's or a PMI launcher's variable); 1
/// without a launcher.
pub fn launched_size() -> usize {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE"]
        .iter()
        .find_map(|v| std::env::var(v).ok()?.parse().ok())
        .unwrap_or(1)
}

/// This process's rank as an MPI launcher set it (Open MPI's or a PMI launcher's variable);
/// 0 without a launcher. Known before MPI is initialised.
pub fn launched_rank() -> usize {
    ["OMPI_COMM_WORLD_RANK", "PMI_RANK"]
        .iter()
        .find_map(|v| std::env::var(v).ok()?.parse().ok())
        .unwrap_or(0)
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
        log::warn!("warning: {e}");
    }
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
    cancel: Option<Cancel>,
) -> Result<Results, Error> {
    let mut writer =
        OutputWriter::new(dir).map_err(|e| Error::Refused(format!("{}: {e}", dir.display())))?;
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
    let ran = {
        let mut observers: Vec<&mut dyn Observer> = vec![&mut writer];
        if let Some(c) = own.as_mut() {
            observers.push(c);
        }
        if let Some(c) = cadence.as_mut() {
            observers.push(c);
        }
        run_plan(
            plan,
            RunOptions {
                observers,
                start,
                cancel,
                ..RunOptions::default()
            },
        )
    };
    mpi_barrier();
    if let Some(message) = writer.write_failure() {
        let results = match ran {
            Ok(r) => r,
            Err(Error::Solve { results, .. } | Error::Interrupted { results, .. }) => *results,
            Err(e) => return Err(e),
        };
        return Err(Error::Output {
            path: dir.to_path_buf(),
            message,
            results: Box::new(results),
        });
    }
    ran
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

/// Whether `plan` is the checkpointed run's (its `fingerprint`) and, if given, the checkpoint's
/// run state fits it.
fn fits(plan: &Plan, fingerprint: u64, state: Option<&RunState>) -> Result<(), String> {
    if plan.fingerprint() != fingerprint {
        return Err(
            "the rebuilt model does not match the checkpoint (a mesh file changed?)".to_string(),
        );
    }
    state.map_or(Ok(()), |st| check_state(plan, st))
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
