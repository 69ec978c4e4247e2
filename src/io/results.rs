//! The one rule of every command that writes results into a directory (`run`, `modes`,
//! `response`, `reduce`, `lumped`, `material`, `sweep`): it takes the directory's lock
//! ([`DirLock`]) for as long as it writes, and it keeps a manifest, `DIR/.deasim-results.json`,
//! naming the command and the scenario (name and hash) whose results the directory holds and
//! listing every file the command wrote there.
//!
//! A command finds the directory acceptable when it holds nothing of deasim's, or the results of
//! the same command and the same scenario (which it replaces: the files of the manifest are
//! removed first). The results of another command or another scenario are refused unless
//! `--overwrite` is given; then every file of their manifest is removed. Files the manifest does
//! not list were not written by deasim and stay, except the fixed names and numbered field files
//! of a run ([`OutputWriter::check_directory`]), which a killed run may have written before
//! listing them, and which a directory written before the manifest existed holds without one.

use super::atomic::write_atomic;
use super::lock::{DirLock, LOCK_FILE};
use super::output::OutputWriter;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};
use std::time::{Duration, Instant};

/// The name of the manifest inside a results directory.
pub const MANIFEST: &str = ".deasim-results.json";

/// Files that only the commands other than `run` write: a directory without a manifest that
/// holds one of them holds another command's results.
const OTHER_COMMANDS_FILES: [(&str, &str); 6] = [
    ("modes.csv", "modes"),
    ("modes.pvd", "modes"),
    ("frequency_response.csv", "response"),
    ("reduced_model.json", "reduce"),
    ("lumped.csv", "lumped"),
    ("sweep.csv", "sweep"),
];

/// What a results directory holds: written by `command` for `scenario`, the `files` (paths
/// relative to the directory, `/`-separated).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Manifest {
    pub command: String,
    pub scenario: String,
    /// The scenario's fingerprint (16 hex digits) where the command has a model, else empty.
    #[serde(default)]
    pub scenario_hash: String,
    pub files: Vec<String>,
}

impl Manifest {
    /// The manifest of `dir`, if it has a readable one.
    pub fn read(dir: &Path) -> Option<Manifest> {
        let text = std::fs::read_to_string(dir.join(MANIFEST)).ok()?;
        serde_json::from_str(&text).ok()
    }

    /// "the results of `deasim modes` for scenario `film`".
    fn describe(&self) -> String {
        format!(
            "the results of `deasim {}` for `{}`",
            self.command, self.scenario
        )
    }
}

/// Size, modification time and inode of a file: what tells a file a command wrote (a new one, or
/// one replaced or changed) from one it found.
type Stamp = (u64, Option<std::time::SystemTime>, u64);

/// A results directory held by one command: its lock, its manifest, and the files found in it
/// when the command started.
#[derive(Debug)]
pub struct ResultsDir {
    dir: PathBuf,
    _lock: DirLock,
    manifest: Manifest,
    before: BTreeMap<String, Stamp>,
    last_record: Option<Instant>,
}

impl ResultsDir {
    /// Takes the lock of `dir` (created if needed) for `command` on `scenario` and clears the
    /// earlier results it may replace; refused (a message naming the directory, what it holds,
    /// `--overwrite` and `--out`) when it holds another command's or scenario's results and not
    /// `overwrite`.
    pub fn open(
        dir: &Path,
        command: &str,
        scenario: &str,
        scenario_hash: &str,
        overwrite: bool,
    ) -> Result<ResultsDir, String> {
        let lock = DirLock::acquire(dir)?;
        let refuse = |what: String| -> String {
            format!(
                "{} holds {what}; use --overwrite to replace them (deasim removes the files it \
                 wrote there) or --out to choose another directory",
                dir.display()
            )
        };
        match Manifest::read(dir) {
            Some(old) => {
                let own = old.command == command && old.scenario == scenario;
                if !own && !overwrite {
                    return Err(refuse(old.describe()));
                }
                remove_files(dir, &old.files)?;
                if old.command == "run" {
                    OutputWriter::check_directory(dir, scenario, true)?;
                }
            }
            None if dir.join(MANIFEST).exists() && !overwrite => {
                return Err(refuse(format!(
                    "a {MANIFEST} that deasim cannot read (results of another version?)"
                )))
            }
            None => {
                // a directory written before the manifest existed: a run's has its summary.json
                // (and may hold the tables of its small-signal stages), another command's one of
                // that command's files
                let holder = if dir.join("summary.json").is_file() {
                    Some(("summary.json", "run"))
                } else {
                    OTHER_COMMANDS_FILES
                        .iter()
                        .copied()
                        .find(|(f, _)| dir.join(f).is_file())
                };
                if let Some((file, c)) = holder {
                    if c != command && !overwrite {
                        return Err(refuse(format!("the results of `deasim {c}` ({file})")));
                    }
                }
                if command == "run" || overwrite {
                    OutputWriter::check_directory(dir, scenario, overwrite)?;
                }
                if overwrite {
                    let legacy: Vec<String> = OTHER_COMMANDS_FILES
                        .iter()
                        .map(|(f, _)| f.to_string())
                        .collect();
                    remove_files(dir, &legacy)?;
                }
            }
        }
        let mut r = ResultsDir {
            dir: dir.to_path_buf(),
            _lock: lock,
            manifest: Manifest {
                command: command.into(),
                scenario: scenario.into(),
                scenario_hash: scenario_hash.into(),
                files: Vec::new(),
            },
            before: BTreeMap::new(),
            last_record: None,
        };
        r.write_manifest()?;
        r.before = snapshot(dir);
        Ok(r)
    }

    /// A run resumed in `dir`, whose lock `lock` it holds: its manifest keeps the files listed so
    /// far, and gains those the resumed run writes.
    pub fn resume(dir: &Path, lock: DirLock, scenario: &str, scenario_hash: &str) -> ResultsDir {
        let manifest = Manifest::read(dir)
            .filter(|m| m.command == "run")
            .unwrap_or_else(|| Manifest {
                command: "run".into(),
                scenario: scenario.into(),
                scenario_hash: scenario_hash.into(),
                files: Vec::new(),
            });
        ResultsDir {
            dir: dir.to_path_buf(),
            _lock: lock,
            manifest,
            before: snapshot(dir),
            last_record: None,
        }
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Lists in the manifest the files written since the command started (new ones, and those
    /// replaced or changed) and writes it.
    pub fn record(&mut self) -> Result<(), String> {
        self.last_record = Some(Instant::now());
        let mut files: BTreeSet<String> = self.manifest.files.iter().cloned().collect();
        for (name, stamp) in snapshot(&self.dir) {
            if self.before.get(&name) != Some(&stamp) {
                files.insert(name);
            }
        }
        self.manifest.files = files.into_iter().collect();
        self.write_manifest()
    }

    /// [`ResultsDir::record`] when the last was at least `every` ago (a long run keeps its
    /// manifest nearly current without scanning the directory at every step).
    pub fn record_every(&mut self, every: Duration) -> Result<(), String> {
        if self.last_record.is_none_or(|t| t.elapsed() >= every) {
            self.record()
        } else {
            Ok(())
        }
    }

    fn write_manifest(&self) -> Result<(), String> {
        let path = self.dir.join(MANIFEST);
        let text = serde_json::to_string_pretty(&self.manifest).unwrap_or_default();
        write_atomic(&path, text.as_bytes())
            .map_err(|e| format!("could not write {}: {e}", path.display()))
    }
}

/// A run keeps its manifest nearly current: a killed run's directory lists what it wrote.
impl crate::job::observer::Observer for ResultsDir {
    fn step(
        &mut self,
        _plan: &crate::io::build::Plan,
        _record: &crate::job::run::StepRecord,
        _state: &[f64],
        _fields: &[crate::element::CellFields],
    ) {
        // a manifest that cannot be written now is reported by the final record
        let _ = self.record_every(Duration::from_secs(10));
    }

    fn finished(
        &mut self,
        _plan: &crate::io::build::Plan,
        _summary: &crate::job::state::RunSummary,
    ) {
    }
}

/// Whether a manifest's entry is a plain relative path inside the directory (no `..`, not
/// absolute): a manifest is never followed out of its directory.
fn inside(name: &str) -> bool {
    let p = Path::new(name);
    !name.is_empty() && p.components().all(|c| matches!(c, Component::Normal(_)))
}

/// Removes the files `names` (relative to `dir`) that exist, and then the sub-directories they
/// leave empty; a directory is never followed through a symbolic link.
fn remove_files(dir: &Path, names: &[String]) -> Result<(), String> {
    let mut parents = BTreeSet::new();
    for name in names.iter().filter(|n| inside(n)) {
        let path = dir.join(name);
        let Ok(meta) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        if meta.is_dir() {
            continue;
        }
        std::fs::remove_file(&path).map_err(|e| {
            format!(
                "cannot remove {} of the earlier results: {e}",
                path.display()
            )
        })?;
        let mut p = Path::new(name).parent();
        while let Some(d) = p.filter(|d| !d.as_os_str().is_empty()) {
            parents.insert(d.to_path_buf());
            p = d.parent();
        }
    }
    // the deepest first; one that holds anything else stays
    let mut parents: Vec<PathBuf> = parents.into_iter().collect();
    parents.sort_by_key(|p| std::cmp::Reverse(p.components().count()));
    for d in parents {
        let _ = std::fs::remove_dir(dir.join(d));
    }
    Ok(())
}

/// The files under `dir` (relative `/`-separated names, symbolic links as files, the lock and
/// the manifest left out) with their stamps.
fn snapshot(dir: &Path) -> BTreeMap<String, Stamp> {
    use std::os::unix::fs::MetadataExt;
    let mut out = BTreeMap::new();
    let mut todo = vec![(dir.to_path_buf(), String::new())];
    while let Some((d, prefix)) = todo.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if prefix.is_empty() && (name == LOCK_FILE || name == MANIFEST) {
                continue;
            }
            let rel = format!("{prefix}{name}");
            let Ok(meta) = std::fs::symlink_metadata(e.path()) else {
                continue;
            };
            if meta.is_dir() {
                todo.push((e.path(), format!("{rel}/")));
            } else {
                out.insert(rel, (meta.ino(), meta.modified().ok(), meta.len()));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A results directory, `out` in a fresh temporary directory (removed when the first is
    /// dropped) that also holds what a manifest may point at outside it.
    fn tmp(name: &str) -> (tempfile::TempDir, PathBuf) {
        let t = tempfile::Builder::new()
            .prefix(&format!("deasim-results-{name}-"))
            .tempdir()
            .unwrap();
        let d = t.path().join("out");
        std::fs::create_dir_all(&d).unwrap();
        (t, d)
    }

    /// A command's own results are replaced; another command's are refused, and with
    /// `overwrite` all of them go; a file deasim did not write stays.
    #[test]
    fn own_results_are_replaced_and_others_refused_unless_overwrite() {
        let (_tmp, d) = tmp("rule");
        std::fs::write(d.join("notes.txt"), "mine").unwrap();
        let mut r = ResultsDir::open(&d, "modes", "film", "", false).unwrap();
        std::fs::create_dir_all(d.join("modes")).unwrap();
        std::fs::write(d.join("modes.csv"), "1").unwrap();
        std::fs::write(d.join("modes/mode_001.vtu"), "1").unwrap();
        r.record().unwrap();
        drop(r);
        let m = Manifest::read(&d).unwrap();
        assert_eq!(m.files, ["modes.csv", "modes/mode_001.vtu"]);
        let e = ResultsDir::open(&d, "run", "film", "", false).unwrap_err();
        assert!(
            e.contains(&d.display().to_string())
                && e.contains("`deasim modes` for `film`")
                && e.contains("--overwrite")
                && e.contains("--out"),
            "{e}"
        );
        let e = ResultsDir::open(&d, "modes", "stack", "", false).unwrap_err();
        assert!(e.contains("`deasim modes` for `film`"), "{e}");
        assert!(d.join("modes.csv").exists());
        // the same command and scenario: replaced
        let r = ResultsDir::open(&d, "modes", "film", "", false).unwrap();
        assert!(!d.join("modes.csv").exists() && !d.join("modes").exists());
        assert!(d.join("notes.txt").exists());
        drop(r);
        // a manifest never leads out of its directory
        std::fs::write(d.join("../outside-deasim-results"), "x").unwrap();
        std::fs::write(
            d.join(MANIFEST),
            r#"{"command":"lumped","scenario":"x","files":["../outside-deasim-results","notes.txt"]}"#,
        )
        .unwrap();
        let _r = ResultsDir::open(&d, "run", "film", "", true).unwrap();
        assert!(d.join("../outside-deasim-results").exists());
        assert!(!d.join("notes.txt").exists());
    }

    /// A directory written before the manifest existed: another command's results are recognised
    /// by their files and refused.
    #[test]
    fn results_without_a_manifest_are_recognised() {
        let (_tmp, d) = tmp("legacy");
        std::fs::write(d.join("frequency_response.csv"), "1").unwrap();
        let e = ResultsDir::open(&d, "run", "film", "", false).unwrap_err();
        assert!(e.contains("`deasim response`"), "{e}");
        assert!(d.join("frequency_response.csv").exists());
        let _r = ResultsDir::open(&d, "run", "film", "", true).unwrap();
        assert!(!d.join("frequency_response.csv").exists());
    }
}
