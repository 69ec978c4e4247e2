//! Input and output: scenario files, ParaView files, CSV/JSON histories, plots.

pub mod atomic;
pub mod build;
pub mod checkpoint;
pub mod examples;
pub mod linear;
pub mod lock;
pub mod memory;
pub mod output;
pub mod periods;
pub mod pieces;
pub mod plot;
pub mod results;
pub mod revolve;
pub mod scenario;
pub mod vtu;

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                rust_files(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }

    /// The unit tests of the writers take their scratch directories from `tempfile` (unique, and
    /// removed when dropped, also when a test fails), never a name of their own in the system's
    /// temporary directory.
    #[test]
    fn scratch_directories_come_from_tempfile() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/io");
        let mut files = Vec::new();
        rust_files(&dir, &mut files);
        assert!(files.len() > 10, "{files:?}");
        let by_hand = concat!("temp_", "dir()");
        let found: Vec<_> = files
            .iter()
            .filter(|f| std::fs::read_to_string(f).unwrap().contains(by_hand))
            .collect();
        assert!(found.is_empty(), "{by_hand} in {found:?}");
    }
}
