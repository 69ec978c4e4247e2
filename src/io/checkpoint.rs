//! Restart files: `DIR/checkpoint/checkpoint-NNNNNNNNN.bin`, written every N accepted steps with
//! `deasim run --checkpoint-every N` (and when a run stops on SIGINT/SIGTERM), read by
//! `deasim run --resume DIR`.
//!
//! A file is the magic `DEASIMCK`, a format version (u32, little-endian), the payload length
//! (u64), the payload — the [`Checkpoint`] (where the scenario came from and the whole
//! [`RunState`]) serialised with `postcard` — and the CRC-32 (`crc32fast`) of all the bytes before
//! it. `f64`s keep their bit patterns, so a resumed run continues from exactly the numbers the
//! stopped run had. A file of another version, a wrong checksum or a malformed payload is refused
//! with an error naming the file, never a panic.

use super::atomic::write_atomic;
use crate::job::observer::Observer;
use crate::job::plan::Plan;
use crate::job::state::{RunState, StepRecord};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The first bytes of every checkpoint.
pub const MAGIC: &[u8; 8] = b"DEASIMCK";
/// Version of the layout; a file of another version is refused.
pub const FORMAT_VERSION: u32 = 8;
/// The sub-directory of the output directory that holds the checkpoints.
pub const SUBDIR: &str = "checkpoint";
/// How many checkpoints are kept (older ones are deleted after a new one is written).
pub const KEEP: usize = 2;
/// Bytes of the header (magic, version, length) and of the trailing checksum.
const HEADER: usize = 20;
const TRAILER: usize = 4;

/// Where a run reads its scenario from; stored in its checkpoints so that `--resume` rebuilds
/// the same plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScenarioSource {
    pub text: String,
    /// The name the scenario was read under (its path, or `<embedded NAME>`).
    pub file: String,
    /// Its directory (relative mesh files are read from there).
    pub base_dir: Option<String>,
    pub overrides: Vec<String>,
}

/// A checkpoint: what is needed to rebuild the plan, and the run state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// `CARGO_PKG_VERSION` of the deasim that wrote it.
    pub deasim_version: String,
    pub source: ScenarioSource,
    /// Fingerprint of the built plan ([`Plan::fingerprint`]): refuses a changed mesh file.
    pub fingerprint: u64,
    /// Rayon threads of the writing run (bitwise continuation needs the same count).
    pub threads: u64,
    /// MPI ranks sharing the writing run's assembly (1 when not distributed); bitwise
    /// continuation needs the same count, since the partition sets the order of the sums.
    pub ranks: u64,
    /// The checkpoint interval (accepted steps).
    pub every: u64,
    /// The rank whose part of the run the file holds, when each rank held only its part (every
    /// rank writes its own file; `None`: the whole state, written by rank 0).
    pub part: Option<u64>,
    pub state: RunState,
}

/// Why a checkpoint was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CheckpointError {
    #[error("{path}: not a deasim checkpoint (bad magic bytes)")]
    Magic { path: String },
    #[error(
        "{path}: checkpoint format version {found}, this deasim reads version {FORMAT_VERSION}"
    )]
    Version { path: String, found: u32 },
    #[error("{path}: truncated checkpoint ({len} bytes, {expected} expected)")]
    Truncated {
        path: String,
        len: usize,
        expected: usize,
    },
    #[error("{path}: checksum mismatch (CRC-32 stored {stored:08x}, computed {computed:08x}): the checkpoint is corrupt")]
    Checksum {
        path: String,
        stored: u32,
        computed: u32,
    },
    #[error("{path}: malformed checkpoint payload: {what}")]
    Payload { path: String, what: String },
    #[error("{path}: the part of rank {rank} is missing (the run stopped while its ranks wrote their parts)")]
    Incomplete { path: String, rank: usize },
    #[error("{0}")]
    Io(String),
}

impl Checkpoint {
    /// The whole file: header, payload, checksum.
    pub fn encode(&self) -> Vec<u8> {
        let payload = postcard::to_stdvec(self).expect("a checkpoint always serialises");
        let mut out = Vec::with_capacity(payload.len() + HEADER + TRAILER);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&payload);
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Reads a whole file; `path` names it in errors. Checks, in order: magic, version, length,
    /// checksum, then decodes the payload.
    pub fn decode(bytes: &[u8], path: &str) -> Result<Checkpoint, CheckpointError> {
        let path = path.to_string();
        let min = HEADER + TRAILER;
        if bytes.len() < 8 || &bytes[..8] != MAGIC {
            if bytes.len() < 8 && MAGIC.starts_with(bytes) {
                return Err(CheckpointError::Truncated {
                    path,
                    len: bytes.len(),
                    expected: min,
                });
            }
            return Err(CheckpointError::Magic { path });
        }
        if bytes.len() < min {
            return Err(CheckpointError::Truncated {
                path,
                len: bytes.len(),
                expected: min,
            });
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
        if version != FORMAT_VERSION {
            return Err(CheckpointError::Version {
                path,
                found: version,
            });
        }
        let len = u64::from_le_bytes(bytes[12..20].try_into().expect("8 bytes"));
        let expected = usize::try_from(len)
            .ok()
            .and_then(|l| l.checked_add(min))
            .unwrap_or(usize::MAX);
        if bytes.len() != expected {
            return Err(CheckpointError::Truncated {
                path,
                len: bytes.len(),
                expected,
            });
        }
        let body = &bytes[..expected - TRAILER];
        let stored = u32::from_le_bytes(bytes[expected - TRAILER..].try_into().expect("4 bytes"));
        let computed = crc32fast::hash(body);
        if stored != computed {
            return Err(CheckpointError::Checksum {
                path,
                stored,
                computed,
            });
        }
        let (ck, rest) = postcard::take_from_bytes::<Checkpoint>(&body[HEADER..]).map_err(|e| {
            CheckpointError::Payload {
                path: path.clone(),
                what: e.to_string(),
            }
        })?;
        if !rest.is_empty() {
            return Err(CheckpointError::Payload {
                path,
                what: format!("{} bytes after the run state", rest.len()),
            });
        }
        Ok(ck)
    }

    /// Writes the checkpoint atomically into `out_dir/checkpoint/` as
    /// `checkpoint-<accepted, 9 digits>.bin` (a part's of rank r > 0:
    /// `checkpoint-<accepted>.rank-<r>.bin`), then deletes all but the [`KEEP`] newest of its
    /// rank.
    pub fn write(&self, out_dir: &Path) -> std::io::Result<PathBuf> {
        let rank = self.part.unwrap_or(0) as usize;
        std::fs::create_dir_all(out_dir.join(SUBDIR))?;
        let path = file_of(out_dir, self.state.accepted, rank);
        write_atomic(&path, &self.encode())?;
        let files = list_of(out_dir, rank);
        if files.len() > KEEP {
            for old in &files[..files.len() - KEEP] {
                if old != &path {
                    let _ = std::fs::remove_file(old);
                }
            }
        }
        Ok(path)
    }

    /// Reads and checks one checkpoint file.
    pub fn read(path: &Path) -> Result<Checkpoint, CheckpointError> {
        let name = path.display().to_string();
        let meta =
            std::fs::metadata(path).map_err(|e| CheckpointError::Io(format!("{name}: {e}")))?;
        // a checkpoint holds the state and the history: far below this
        if meta.len() > 1 << 36 {
            return Err(CheckpointError::Payload {
                path: name,
                what: format!("{} bytes is too large", meta.len()),
            });
        }
        let bytes = std::fs::read(path).map_err(|e| CheckpointError::Io(format!("{name}: {e}")))?;
        Checkpoint::decode(&bytes, &name)
    }
}

/// The checkpoint file of step `accepted` of rank `rank` (rank 0: the whole state's, or the
/// first rank's part).
pub fn file_of(out_dir: &Path, accepted: usize, rank: usize) -> PathBuf {
    let name = if rank == 0 {
        format!("checkpoint-{accepted:09}.bin")
    } else {
        format!("checkpoint-{accepted:09}.rank-{rank}.bin")
    };
    out_dir.join(SUBDIR).join(name)
}

/// The checkpoint files of an output directory written by rank 0 (the whole state, or rank 0's
/// part), oldest first (by their step number).
pub fn list(out_dir: &Path) -> Vec<PathBuf> {
    list_of(out_dir, 0)
}

/// [`list`] of rank `rank`'s files.
fn list_of(out_dir: &Path, rank: usize) -> Vec<PathBuf> {
    let mut files: Vec<(u64, PathBuf)> = checkpoint_files(out_dir)
        .into_iter()
        .filter(|(_, r, _)| *r == rank)
        .map(|(n, _, p)| (n, p))
        .collect();
    files.sort();
    files.into_iter().map(|(_, p)| p).collect()
}

/// Every checkpoint file of an output directory, of every rank (step, rank, path).
pub fn checkpoint_files(out_dir: &Path) -> Vec<(u64, usize, PathBuf)> {
    std::fs::read_dir(out_dir.join(SUBDIR))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let rest = name.strip_prefix("checkpoint-")?.strip_suffix(".bin")?;
            let (digits, rank) = match rest.split_once(".rank-") {
                Some((d, r)) => (d, r.parse().ok().filter(|&r| r > 0)?),
                None => (rest, 0),
            };
            let n = Some(digits)
                .filter(|d| d.len() == 9 && d.bytes().all(|b| b.is_ascii_digit()))?
                .parse()
                .ok()?;
            Some((n, rank, e.path()))
        })
        .collect()
}

/// The newest valid checkpoint of an output directory, its file, and a warning for every newer
/// file that was skipped because it is corrupt (bad magic, truncated, checksum, payload): the
/// older checkpoint is kept for this case. A file of another format version is not skipped but
/// refused. When no file is valid, the error lists them all and says how to start over.
pub fn latest(out_dir: &Path) -> Result<(Checkpoint, PathBuf, Vec<String>), CheckpointError> {
    let files = list(out_dir);
    if files.is_empty() {
        return Err(CheckpointError::Io(format!(
            "{}: no checkpoint (checkpoint-NNNNNNNNN.bin) found; was the run started with --checkpoint-every?",
            out_dir.join(SUBDIR).display()
        )));
    }
    let mut skipped = Vec::new();
    for path in files.iter().rev() {
        match Checkpoint::read(path) {
            // a run of rank parts stopped while its ranks wrote this step: an older one
            Ok(ck) if missing_part(out_dir, &ck).is_some() => {
                skipped.push(CheckpointError::Incomplete {
                    path: path.display().to_string(),
                    rank: missing_part(out_dir, &ck).unwrap_or_default(),
                });
            }
            Ok(ck) => {
                let warnings = skipped
                    .iter()
                    .map(|e: &CheckpointError| {
                        let what = match e {
                            CheckpointError::Incomplete { .. } => "an incomplete",
                            _ => "a corrupt",
                        };
                        format!(
                            "skipping {what} checkpoint: {e}; resuming from {}",
                            path.display()
                        )
                    })
                    .collect();
                return Ok((ck, path.clone(), warnings));
            }
            Err(e @ CheckpointError::Version { .. }) => return Err(e),
            Err(e) => skipped.push(e),
        }
    }
    Err(CheckpointError::Io(format!(
        "no valid checkpoint in {}:\n  {}\nto start over, run the scenario again without --resume \
         (`deasim run SCENARIO --out {}`), which replaces these files",
        out_dir.join(SUBDIR).display(),
        skipped
            .iter()
            .map(|e| e.to_string())
            .collect::<Vec<_>>()
            .join("\n  "),
        out_dir.display()
    )))
}

/// The first rank > 0 whose file of `ck`'s step is missing, for a checkpoint of rank parts.
fn missing_part(out_dir: &Path, ck: &Checkpoint) -> Option<usize> {
    ck.part?;
    (1..ck.ranks as usize).find(|&r| !file_of(out_dir, ck.state.accepted, r).is_file())
}

/// A checkpoint writer's cadence on an MPI rank that does not write the checkpoints: it asks
/// for the run state at the same steps as the writer on rank 0, because making the state is
/// collective (every rank contributes its own cells' internal variables), and drops it.
#[derive(Debug, Clone, Copy)]
pub struct CheckpointCadence {
    /// The writer's interval, in accepted steps.
    pub every: usize,
}

impl Observer for CheckpointCadence {
    fn step(&mut self, _: &Plan, _: &StepRecord, _: &[f64], _: &[crate::element::CellFields]) {}

    fn finished(&mut self, _: &Plan, _: &crate::job::state::RunSummary) {}

    fn wants_state(&self, accepted: usize, stopping: bool) -> bool {
        checkpoint_due(self.every, accepted, stopping)
    }
}

/// Whether a checkpoint is due after `accepted` steps at an interval of `every`.
fn checkpoint_due(every: usize, accepted: usize, stopping: bool) -> bool {
    stopping || accepted.is_multiple_of(every.max(1))
}

/// The observer that writes checkpoints: every `every` accepted steps and when the run stops on
/// a signal.
#[derive(Debug, Clone)]
pub struct CheckpointWriter {
    /// The output directory (checkpoints go to its `checkpoint/`).
    pub dir: PathBuf,
    /// Write one every this many accepted steps (≥ 1).
    pub every: usize,
    pub source: ScenarioSource,
    /// Fingerprint of the plan being run.
    pub fingerprint: u64,
    /// MPI ranks sharing the run's assembly (1 when not distributed).
    pub ranks: u64,
    /// This rank, when each rank holds only its part and writes its own file (`None`: the whole
    /// state, written by rank 0).
    pub part: Option<u64>,
}

impl Observer for CheckpointWriter {
    fn step(&mut self, _: &Plan, _: &StepRecord, _: &[f64], _: &[crate::element::CellFields]) {}

    fn finished(&mut self, _: &Plan, _: &crate::job::state::RunSummary) {}

    fn takes_states(&self) -> bool {
        true
    }

    fn wants_state(&self, accepted: usize, stopping: bool) -> bool {
        checkpoint_due(self.every, accepted, stopping)
    }

    fn run_state(&mut self, _: &Plan, state: &RunState) -> Result<(), String> {
        let ck = Checkpoint {
            deasim_version: env!("CARGO_PKG_VERSION").to_string(),
            source: self.source.clone(),
            fingerprint: self.fingerprint,
            threads: rayon::current_num_threads() as u64,
            ranks: self.ranks,
            every: self.every as u64,
            part: self.part,
            state: state.clone(),
        };
        ck.write(&self.dir).map(|_| ()).map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::job::state::{Energies, RecorderState, StagePosition, StageSummary};

    fn sample() -> Checkpoint {
        Checkpoint {
            deasim_version: "0.1.0".into(),
            source: ScenarioSource {
                text: "name = \"x\"\n".into(),
                file: "x.toml".into(),
                base_dir: Some("/tmp".into()),
                overrides: vec!["a=1".into()],
            },
            fingerprint: 42,
            threads: 2,
            ranks: 1,
            every: 5,
            part: None,
            state: RunState {
                accepted: 10,
                stage: 1,
                stage_time: 0.5,
                step_no: 7,
                pressure_start: vec![0.25],
                first_step: 0,
                prestretch_iterations: 0,
                position: StagePosition::Dynamic {
                    t: 0.25,
                    driver: crate::job::state::DynamicResume {
                        t_start: 0.0,
                        dt: 1e-5,
                        iterations: 33,
                        last_h: 1e-5,
                        step_factor: None,
                        projection_factor: Some(vec![0.5, -1.0]),
                        linear: crate::solve::linear::SolverStats {
                            factorizations: 2,
                            solves: 40,
                            krylov_iterations: 0,
                            krylov_decades: 0.0,
                        },
                    },
                },
                q: vec![1.0, -0.0, f64::NAN, 3.5],
                v: vec![0.0; 4],
                a: vec![1e-300; 4],
                points: vec![],
                dissipated: 1e-9,
                dead_load_start: 1.0,
                recorder: RecorderState {
                    initial_potential: Some(-3.0),
                    broken_down: vec![false, true],
                    warnings: vec!["w".into()],
                    ..Default::default()
                },
                stages: vec![StageSummary {
                    name: "s".into(),
                    kind: "static".into(),
                    steps: 3,
                    newton_iterations: 9,
                    wall_s: 0.1,
                    converged: true,
                    modes_hz: vec![30.5],
                    modes_harmonic: vec![0],
                    instability: None,
                    linear: Default::default(),
                }],
                warnings: vec![],
                records: vec![StepRecord {
                    time: 0.1,
                    stage: "s".into(),
                    step: 1,
                    voltage: 2.0,
                    newton_iterations: 3,
                    dt: 0.1,
                    energies: Energies::default(),
                    probes: vec![1.0, 2.0],
                    max_electric_field: 5.0,
                    electrodes: vec![[2.0, 1e-9, 1e-6, 2e-6, 0.0, 0.0]],
                }],
                wall_s: 1.5,
                controllers: vec![crate::job::controller::ControllerState {
                    integral: 12.5,
                    derivative: -0.25,
                    last_measurement: Some(1e-4),
                    output: 2050.0,
                    next_sample: 0.003,
                    rng: 0x1234_5678_9abc_def0,
                    samples: 3,
                    estimate: vec![1e-9, -2e-7],
                }],
            },
        }
    }

    /// Each rank of a run of parts writes and prunes its own files; rank 0's files are the
    /// run's list, and a step whose part of another rank is missing is skipped with a warning.
    #[test]
    fn the_parts_of_a_step_are_kept_by_rank_and_an_incomplete_step_is_skipped() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-ck-parts-")
            .tempdir()
            .unwrap();
        let dir = tmp.path().join("out");
        let part = |rank: u64, accepted: usize| {
            let mut c = sample();
            c.ranks = 2;
            c.part = Some(rank);
            c.state.accepted = accepted;
            c.write(&dir).unwrap()
        };
        for accepted in [10, 20, 30] {
            part(1, accepted);
        }
        part(0, 20);
        part(0, 30);
        // rank 0 wrote step 40, rank 1 had not yet
        part(0, 40);
        let steps = |rank: usize| -> Vec<u64> {
            let mut s: Vec<u64> = checkpoint_files(&dir)
                .into_iter()
                .filter(|(_, r, _)| *r == rank)
                .map(|(n, _, _)| n)
                .collect();
            s.sort();
            s
        };
        assert_eq!(steps(1), [20, 30], "rank 1 keeps its {KEEP} newest");
        assert_eq!(steps(0), [30, 40]);
        assert_eq!(list(&dir), [file_of(&dir, 30, 0), file_of(&dir, 40, 0)]);
        let (ck, path, warnings) = latest(&dir).unwrap();
        assert_eq!((ck.state.accepted, ck.part), (30, Some(0)));
        assert_eq!(path, file_of(&dir, 30, 0));
        assert_eq!(warnings.len(), 1);
        assert!(
            warnings[0].starts_with("skipping an incomplete checkpoint")
                && warnings[0].contains("the part of rank 1 is missing"),
            "{warnings:?}"
        );
    }

    #[test]
    fn round_trip_is_bitwise() {
        let c = sample();
        let bytes = c.encode();
        let d = Checkpoint::decode(&bytes, "t").unwrap();
        // NaN != NaN: compare the encodings
        assert_eq!(d.encode(), bytes);
        assert_eq!(d.state.q[2].to_bits(), f64::NAN.to_bits());
        assert_eq!(d.state.q[1].to_bits(), (-0.0f64).to_bits());
    }

    #[test]
    fn every_byte_flip_and_truncation_is_refused() {
        let bytes = sample().encode();
        for i in 0..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x10;
            assert!(Checkpoint::decode(&b, "t").is_err(), "flip at {i}");
            assert!(Checkpoint::decode(&bytes[..i], "t").is_err(), "cut at {i}");
        }
        let mut b = bytes.clone();
        b[100] ^= 1;
        let e = Checkpoint::decode(&b, "t").unwrap_err();
        assert!(e.to_string().contains("checksum"), "{e}");
        let mut b = bytes;
        b[8] = 9;
        let e = Checkpoint::decode(&b, "t").unwrap_err();
        assert!(
            matches!(e, CheckpointError::Version { found: 9, .. }),
            "{e}"
        );
    }

    /// A valid frame around a payload that claims a huge vector is refused without allocating it.
    #[test]
    fn hostile_lengths_are_refused() {
        let payload = [0xffu8, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x01];
        let mut out = Vec::new();
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&payload);
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        let e = Checkpoint::decode(&out, "t").unwrap_err();
        assert!(matches!(e, CheckpointError::Payload { .. }), "{e}");
    }
}
