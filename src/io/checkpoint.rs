//! Restart files: `DIR/checkpoint/checkpoint-NNNNNNNNN.bin`, written every N accepted steps with
//! `deasim run --checkpoint-every N` (and when a run stops on SIGINT/SIGTERM), read by
//! `deasim run --resume DIR`.
//!
//! The format is self-written and small (see `docs/checkpoint.md`): the magic `DEASIMCK`, a
//! format version (u32), the payload length (u64), the payload, and the CRC-32 (IEEE) of all the
//! bytes before it. Numbers are little-endian; `f64`s are stored by their bit patterns, so a
//! resumed run continues from exactly the numbers the killed run had. Every length read from a
//! file is checked against the bytes left before anything is allocated, so a corrupt or hostile
//! file gives an error, never a panic or an unbounded allocation.

use super::atomic::write_atomic;
use crate::job::run::{Energies, StageSummary, StepRecord};
use std::path::{Path, PathBuf};

/// The first bytes of every checkpoint.
pub const MAGIC: &[u8; 8] = b"DEASIMCK";
/// Version of the layout below; a file of another version is refused.
pub const FORMAT_VERSION: u32 = 1;
/// The sub-directory of the output directory that holds the checkpoints.
pub const SUBDIR: &str = "checkpoint";
/// How many checkpoints are kept (older ones are deleted after a new one is written).
pub const KEEP: usize = 2;

/// Where a stage stood at the checkpoint.
#[derive(Debug, Clone, PartialEq)]
pub enum StagePosition {
    /// A static stage: the load ramp's position and the state the ramp started from (its
    /// prescribed values at load factor 0).
    Static {
        ramp: crate::solve::stepping::RampPosition,
        stage_start: Vec<f64>,
        /// Load factor of the last recorded step (for the pseudo-time increment).
        last_load: f64,
    },
    /// A dynamic stage: stage time, the next step size and the iterations so far.
    Dynamic { t: f64, dt: f64, iterations: u64 },
}

/// Energy bookkeeping of the run's recorder (see `analysis::run`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RecorderState {
    pub prev_reactions: Vec<f64>,
    pub prev_state: Vec<f64>,
    pub boundary_work: f64,
    pub initial_potential: Option<f64>,
    pub external_factor: f64,
    pub prev_factor: f64,
    pub prev_external: Vec<f64>,
    pub load_change_work: f64,
    pub reference: Vec<f64>,
    pub broken_down: Vec<bool>,
    pub warnings: Vec<String>,
}

/// Everything needed to continue a run bit-for-bit.
#[derive(Debug, Clone)]
pub struct Checkpoint {
    /// `CARGO_PKG_VERSION` of the deasim that wrote it.
    pub deasim_version: String,
    /// The scenario: its TOML text, the name it was read under, its directory (for relative
    /// mesh files) and the `--set` overrides.
    pub scenario_text: String,
    pub scenario_file: String,
    pub base_dir: Option<String>,
    pub overrides: Vec<String>,
    /// Fingerprint of the built plan ([`fingerprint`]): refuses a changed mesh file.
    pub fingerprint: u64,
    /// Rayon threads of the writing run (bitwise continuation needs the same count).
    pub threads: u64,
    /// The checkpoint interval (accepted steps).
    pub every: u64,
    /// Accepted steps of the stages so far (pre-stretch steps excluded).
    pub accepted: u64,
    /// Index of the stage in progress and the global time at its start.
    pub stage: u64,
    pub stage_time: f64,
    /// Step number of the last recorded step within the stage.
    pub step_no: u64,
    /// Pre-stretch steps and iterations recorded under the first stage.
    pub first_step: u64,
    pub prestretch_iterations: u64,
    pub position: StagePosition,
    /// State q, velocity, acceleration (4 per node).
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    /// Energy dissipated so far (J, of the modelled part).
    pub dissipated: f64,
    /// The model's dead-load factor at the stage start.
    pub dead_load_start: f64,
    pub recorder: RecorderState,
    /// Summaries of the completed stages and the run's warnings so far.
    pub stages: Vec<StageSummary>,
    pub warnings: Vec<String>,
    /// Every recorded step so far (the rows of `history.csv`).
    pub records: Vec<StepRecord>,
    /// Wall time spent before the checkpoint (s).
    pub wall_s: f64,
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
    #[error("{0}")]
    Io(String),
}

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320), table-driven.
pub fn crc32(bytes: &[u8]) -> u32 {
    const TABLE: [u32; 256] = {
        let mut t = [0u32; 256];
        let mut i = 0;
        while i < 256 {
            let mut c = i as u32;
            let mut k = 0;
            while k < 8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
                k += 1;
            }
            t[i] = c;
            i += 1;
        }
        t
    };
    let mut c = !0u32;
    for &b in bytes {
        c = TABLE[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8);
    }
    !c
}

/// FNV-1a (64 bit) of a byte stream, for fingerprints.
#[derive(Debug, Clone, Copy)]
pub struct Fnv(pub u64);

impl Default for Fnv {
    fn default() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    /// Adds bytes.
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

/// Fingerprint of a built plan: its name, node coordinates, connectivity, cell materials and
/// stage kinds/durations. A resume whose rebuilt plan differs (e.g. a changed mesh file) is refused.
pub fn fingerprint(plan: &crate::io::build::Plan) -> u64 {
    let mut h = Fnv::default();
    h.write(plan.name.as_bytes());
    let m = &plan.model.mesh;
    for x in &m.nodes {
        for c in x {
            h.write(&c.to_bits().to_le_bytes());
        }
    }
    for &c in &m.connectivity {
        h.write(&(c as u64).to_le_bytes());
    }
    for &c in &plan.model.cell_material {
        h.write(&(c as u64).to_le_bytes());
    }
    for s in &plan.stages {
        h.write(s.name.as_bytes());
        h.write(&s.duration.to_bits().to_le_bytes());
        h.write(&(s.kind.nominal_steps(s.duration) as u64).to_le_bytes());
    }
    h.0
}

/// Little-endian encoder.
#[derive(Default)]
struct Enc(Vec<u8>);

impl Enc {
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }
    fn bool(&mut self, v: bool) {
        self.0.push(v as u8);
    }
    fn str(&mut self, s: &str) {
        self.u64(s.len() as u64);
        self.0.extend_from_slice(s.as_bytes());
    }
    fn f64s(&mut self, v: &[f64]) {
        self.u64(v.len() as u64);
        for &x in v {
            self.f64(x);
        }
    }
    fn strs(&mut self, v: &[String]) {
        self.u64(v.len() as u64);
        for s in v {
            self.str(s);
        }
    }
    fn opt_f64(&mut self, v: Option<f64>) {
        self.bool(v.is_some());
        self.f64(v.unwrap_or(0.0));
    }
}

/// Bounds-checked little-endian decoder.
struct Dec<'a> {
    b: &'a [u8],
    pos: usize,
}

impl Dec<'_> {
    fn take(&mut self, n: usize, what: &str) -> Result<&[u8], String> {
        if self.b.len() - self.pos < n {
            return Err(format!(
                "{what}: {n} bytes needed at offset {}, {} left",
                self.pos,
                self.b.len() - self.pos
            ));
        }
        let s = &self.b[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u64(&mut self, what: &str) -> Result<u64, String> {
        let s = self.take(8, what)?;
        Ok(u64::from_le_bytes(s.try_into().expect("8 bytes")))
    }
    fn usize(&mut self, what: &str) -> Result<usize, String> {
        let v = self.u64(what)?;
        usize::try_from(v).map_err(|_| format!("{what}: {v} too large"))
    }
    fn f64(&mut self, what: &str) -> Result<f64, String> {
        Ok(f64::from_bits(self.u64(what)?))
    }
    fn bool(&mut self, what: &str) -> Result<bool, String> {
        match self.take(1, what)?[0] {
            0 => Ok(false),
            1 => Ok(true),
            b => Err(format!("{what}: {b} is not a boolean")),
        }
    }
    /// A length of items of `item` bytes each, checked against the bytes left.
    fn len(&mut self, item: usize, what: &str) -> Result<usize, String> {
        let n = self.usize(what)?;
        if n.checked_mul(item)
            .is_none_or(|bytes| bytes > self.b.len() - self.pos)
        {
            return Err(format!("{what}: length {n} exceeds the file"));
        }
        Ok(n)
    }
    fn str(&mut self, what: &str) -> Result<String, String> {
        let n = self.len(1, what)?;
        String::from_utf8(self.take(n, what)?.to_vec()).map_err(|_| format!("{what}: not UTF-8"))
    }
    fn f64s(&mut self, what: &str) -> Result<Vec<f64>, String> {
        let n = self.len(8, what)?;
        (0..n).map(|_| self.f64(what)).collect()
    }
    fn strs(&mut self, what: &str) -> Result<Vec<String>, String> {
        let n = self.len(8, what)?;
        (0..n).map(|_| self.str(what)).collect()
    }
    fn opt_f64(&mut self, what: &str) -> Result<Option<f64>, String> {
        let some = self.bool(what)?;
        let v = self.f64(what)?;
        Ok(some.then_some(v))
    }
}

impl Checkpoint {
    /// The whole file: header, payload, checksum.
    pub fn encode(&self) -> Vec<u8> {
        let mut e = Enc::default();
        e.str(&self.deasim_version);
        e.str(&self.scenario_text);
        e.str(&self.scenario_file);
        e.bool(self.base_dir.is_some());
        e.str(self.base_dir.as_deref().unwrap_or(""));
        e.strs(&self.overrides);
        e.u64(self.fingerprint);
        e.u64(self.threads);
        e.u64(self.every);
        e.u64(self.accepted);
        e.u64(self.stage);
        e.f64(self.stage_time);
        e.u64(self.step_no);
        e.u64(self.first_step);
        e.u64(self.prestretch_iterations);
        match &self.position {
            StagePosition::Static {
                ramp,
                stage_start,
                last_load,
            } => {
                e.u64(0);
                e.f64(ramp.load);
                e.f64(ramp.increment);
                e.u64(ramp.next_nominal as u64);
                e.u64(ramp.accepted_steps as u64);
                e.u64(ramp.cutbacks as u64);
                e.u64(ramp.newton_iterations as u64);
                e.f64s(stage_start);
                e.f64(*last_load);
            }
            StagePosition::Dynamic { t, dt, iterations } => {
                e.u64(1);
                e.f64(*t);
                e.f64(*dt);
                e.u64(*iterations);
            }
        }
        e.f64s(&self.q);
        e.f64s(&self.v);
        e.f64s(&self.a);
        e.f64(self.dissipated);
        e.f64(self.dead_load_start);
        let r = &self.recorder;
        e.f64s(&r.prev_reactions);
        e.f64s(&r.prev_state);
        e.f64(r.boundary_work);
        e.opt_f64(r.initial_potential);
        e.f64(r.external_factor);
        e.f64(r.prev_factor);
        e.f64s(&r.prev_external);
        e.f64(r.load_change_work);
        e.f64s(&r.reference);
        e.u64(r.broken_down.len() as u64);
        for &b in &r.broken_down {
            e.bool(b);
        }
        e.strs(&r.warnings);
        e.u64(self.stages.len() as u64);
        for s in &self.stages {
            e.str(&s.name);
            e.str(&s.kind);
            e.u64(s.steps as u64);
            e.u64(s.newton_iterations as u64);
            e.f64(s.wall_s);
            e.bool(s.converged);
        }
        e.strs(&self.warnings);
        e.u64(self.records.len() as u64);
        for r in &self.records {
            e.f64(r.time);
            e.str(&r.stage);
            e.u64(r.step as u64);
            e.f64(r.voltage);
            e.u64(r.newton_iterations as u64);
            e.f64(r.dt);
            let en = &r.energies;
            for v in [
                en.kinetic,
                en.stored,
                en.electric,
                en.gravity,
                en.dissipated,
                en.energy_error,
            ] {
                e.f64(v);
            }
            e.f64s(&r.probes);
            e.f64(r.max_electric_field);
        }
        e.f64(self.wall_s);
        let payload = e.0;
        let mut out = Vec::with_capacity(payload.len() + 24);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&payload);
        let crc = crc32(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Reads a whole file; `path` names it in errors. Checks, in order: magic, version, length,
    /// checksum, then decodes the payload.
    pub fn decode(bytes: &[u8], path: &str) -> Result<Checkpoint, CheckpointError> {
        let path = path.to_string();
        if bytes.len() < 8 || &bytes[..8] != MAGIC {
            if bytes.len() < 8 && MAGIC.starts_with(bytes) {
                return Err(CheckpointError::Truncated {
                    path,
                    len: bytes.len(),
                    expected: 24,
                });
            }
            return Err(CheckpointError::Magic { path });
        }
        if bytes.len() < 24 {
            return Err(CheckpointError::Truncated {
                path,
                len: bytes.len(),
                expected: 24,
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
            .and_then(|l| l.checked_add(24))
            .unwrap_or(usize::MAX);
        if bytes.len() != expected {
            return Err(CheckpointError::Truncated {
                path,
                len: bytes.len(),
                expected,
            });
        }
        let body = &bytes[..expected - 4];
        let stored = u32::from_le_bytes(bytes[expected - 4..].try_into().expect("4 bytes"));
        let computed = crc32(body);
        if stored != computed {
            return Err(CheckpointError::Checksum {
                path,
                stored,
                computed,
            });
        }
        let mut d = Dec {
            b: &body[20..],
            pos: 0,
        };
        Self::decode_payload(&mut d).map_err(|what| CheckpointError::Payload { path, what })
    }

    fn decode_payload(d: &mut Dec) -> Result<Checkpoint, String> {
        let deasim_version = d.str("deasim version")?;
        let scenario_text = d.str("scenario text")?;
        let scenario_file = d.str("scenario file")?;
        let has_base = d.bool("base dir")?;
        let base = d.str("base dir")?;
        let overrides = d.strs("overrides")?;
        let fingerprint = d.u64("fingerprint")?;
        let threads = d.u64("threads")?;
        let every = d.u64("interval")?;
        let accepted = d.u64("accepted steps")?;
        let stage = d.u64("stage")?;
        let stage_time = d.f64("stage time")?;
        let step_no = d.u64("step")?;
        let first_step = d.u64("first step")?;
        let prestretch_iterations = d.u64("pre-stretch iterations")?;
        let position = match d.u64("stage kind")? {
            0 => {
                let ramp = crate::solve::stepping::RampPosition {
                    load: d.f64("load")?,
                    increment: d.f64("increment")?,
                    next_nominal: d.usize("next nominal")?,
                    accepted_steps: d.usize("accepted")?,
                    cutbacks: d.usize("cutbacks")?,
                    newton_iterations: d.usize("iterations")?,
                };
                StagePosition::Static {
                    ramp,
                    stage_start: d.f64s("stage start")?,
                    last_load: d.f64("last load")?,
                }
            }
            1 => StagePosition::Dynamic {
                t: d.f64("t")?,
                dt: d.f64("dt")?,
                iterations: d.u64("iterations")?,
            },
            k => return Err(format!("unknown stage kind {k}")),
        };
        let q = d.f64s("q")?;
        let v = d.f64s("v")?;
        let a = d.f64s("a")?;
        let dissipated = d.f64("dissipated")?;
        let dead_load_start = d.f64("dead load")?;
        let recorder = RecorderState {
            prev_reactions: d.f64s("reactions")?,
            prev_state: d.f64s("previous state")?,
            boundary_work: d.f64("boundary work")?,
            initial_potential: d.opt_f64("initial potential")?,
            external_factor: d.f64("external factor")?,
            prev_factor: d.f64("previous factor")?,
            prev_external: d.f64s("previous external")?,
            load_change_work: d.f64("load change work")?,
            reference: d.f64s("reference")?,
            broken_down: {
                let n = d.len(1, "breakdown flags")?;
                (0..n)
                    .map(|_| d.bool("breakdown flag"))
                    .collect::<Result<_, _>>()?
            },
            warnings: d.strs("recorder warnings")?,
        };
        let n = d.len(8 * 4, "stages")?;
        let mut stages = Vec::with_capacity(n);
        for _ in 0..n {
            stages.push(StageSummary {
                name: d.str("stage name")?,
                kind: d.str("stage kind")?,
                steps: d.usize("stage steps")?,
                newton_iterations: d.usize("stage iterations")?,
                wall_s: d.f64("stage wall")?,
                converged: d.bool("stage converged")?,
            });
        }
        let warnings = d.strs("warnings")?;
        let n = d.len(8 * 14, "records")?;
        let mut records = Vec::with_capacity(n);
        for _ in 0..n {
            let time = d.f64("record time")?;
            let stage = d.str("record stage")?;
            let step = d.usize("record step")?;
            let voltage = d.f64("record voltage")?;
            let newton_iterations = d.usize("record iterations")?;
            let dt = d.f64("record dt")?;
            let mut en = [0.0; 6];
            for x in &mut en {
                *x = d.f64("record energy")?;
            }
            records.push(StepRecord {
                time,
                stage,
                step,
                voltage,
                newton_iterations,
                dt,
                energies: Energies {
                    kinetic: en[0],
                    stored: en[1],
                    electric: en[2],
                    gravity: en[3],
                    dissipated: en[4],
                    energy_error: en[5],
                },
                probes: d.f64s("record probes")?,
                max_electric_field: d.f64("record field")?,
            });
        }
        let wall_s = d.f64("wall time")?;
        if d.pos != d.b.len() {
            return Err(format!("{} trailing bytes", d.b.len() - d.pos));
        }
        Ok(Checkpoint {
            deasim_version,
            scenario_text,
            scenario_file,
            base_dir: has_base.then_some(base),
            overrides,
            fingerprint,
            threads,
            every,
            accepted,
            stage,
            stage_time,
            step_no,
            first_step,
            prestretch_iterations,
            position,
            q,
            v,
            a,
            dissipated,
            dead_load_start,
            recorder,
            stages,
            warnings,
            records,
            wall_s,
        })
    }

    /// Writes the checkpoint atomically into `out_dir/checkpoint/` as
    /// `checkpoint-<accepted, 9 digits>.bin`, then deletes all but the [`KEEP`] newest.
    pub fn write(&self, out_dir: &Path) -> std::io::Result<PathBuf> {
        let dir = out_dir.join(SUBDIR);
        std::fs::create_dir_all(&dir)?;
        let path = dir.join(format!("checkpoint-{:09}.bin", self.accepted));
        write_atomic(&path, &self.encode())?;
        let files = list(out_dir);
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

/// The checkpoint files of an output directory, oldest first (by their step number).
pub fn list(out_dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<(u64, PathBuf)> = std::fs::read_dir(out_dir.join(SUBDIR))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let n = name
                .strip_prefix("checkpoint-")
                .and_then(|r| r.strip_suffix(".bin"))
                .filter(|d| d.len() == 9 && d.bytes().all(|b| b.is_ascii_digit()))?
                .parse()
                .ok()?;
            Some((n, e.path()))
        })
        .collect();
    files.sort();
    files.into_iter().map(|(_, p)| p).collect()
}

/// The newest checkpoint of an output directory. A newest file that fails its checks is an error
/// (it is not silently skipped: the user decides whether to delete it).
pub fn latest(out_dir: &Path) -> Result<Checkpoint, CheckpointError> {
    let files = list(out_dir);
    let Some(path) = files.last() else {
        return Err(CheckpointError::Io(format!(
            "{}: no checkpoint (checkpoint-NNNNNNNNN.bin) found; was the run started with --checkpoint-every?",
            out_dir.join(SUBDIR).display()
        )));
    };
    Checkpoint::read(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Checkpoint {
        Checkpoint {
            deasim_version: "0.1.0".into(),
            scenario_text: "name = \"x\"\n".into(),
            scenario_file: "x.toml".into(),
            base_dir: Some("/tmp".into()),
            overrides: vec!["a=1".into()],
            fingerprint: 42,
            threads: 2,
            every: 5,
            accepted: 10,
            stage: 1,
            stage_time: 0.5,
            step_no: 7,
            first_step: 0,
            prestretch_iterations: 0,
            position: StagePosition::Dynamic {
                t: 0.25,
                dt: 1e-5,
                iterations: 33,
            },
            q: vec![1.0, -0.0, f64::NAN, 3.5],
            v: vec![0.0; 4],
            a: vec![1e-300; 4],
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
            }],
            wall_s: 1.5,
        }
    }

    #[test]
    fn crc32_of_the_check_string() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn round_trip_is_bitwise() {
        let c = sample();
        let bytes = c.encode();
        let d = Checkpoint::decode(&bytes, "t").unwrap();
        // NaN != NaN: compare the encodings
        assert_eq!(d.encode(), bytes);
        assert_eq!(d.q[2].to_bits(), f64::NAN.to_bits());
        assert_eq!(d.q[1].to_bits(), (-0.0f64).to_bits());
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

    #[test]
    fn hostile_lengths_do_not_allocate() {
        // a valid header and checksum around a payload that claims a huge string
        let mut payload = Vec::new();
        payload.extend_from_slice(&u64::MAX.to_le_bytes());
        let mut out = Vec::new();
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&payload);
        let crc = crc32(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        let e = Checkpoint::decode(&out, "t").unwrap_err();
        assert!(e.to_string().contains("exceeds the file"), "{e}");
    }
}
