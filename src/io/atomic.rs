//! Atomic file output: write to a temporary sibling file, flush it to disk, then rename it over
//! the target. A run that is interrupted (Ctrl-C, crash, full disk) therefore leaves either the
//! previous complete file or the new complete file, never a half-written one.
//!
//! The temporary file lives in the same directory as the target (so the final rename does not
//! cross file systems) and is named `.<name>.tmp-<pid>-<n>`, where `n` is a per-process counter
//! that keeps concurrent writers of the same target (e.g. parallel tests) from colliding.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Per-process counter making temporary names unique across threads.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` atomically (temporary sibling file + flush + rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Streams the content produced by `f` into a temporary sibling of `path` through a
/// [`BufWriter`], flushes and syncs it, then renames it over `path`.
///
/// If `f` (or any later step) fails, the temporary file is removed, the target is left
/// untouched, and the error is returned.
pub fn write_atomic_with<F>(path: &Path, f: F) -> io::Result<()>
where
    F: FnOnce(&mut dyn Write) -> io::Result<()>,
{
    let tmp = temp_sibling_path(path, None)?;
    let result = write_temp(&tmp, f).and_then(|()| fs::rename(&tmp, path));
    if result.is_err() {
        // Best effort: the temporary may not exist (e.g. creation failed).
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// Returns a fresh temporary path next to `path`: `.<name>.tmp-<pid>-<n>[.<extension>]`.
///
/// The optional `extension` is appended for writers that pick their format from the file
/// extension (e.g. the PNG encoder). The file is not created. Fails with
/// [`io::ErrorKind::InvalidInput`] if `path` has no file name.
pub fn temp_sibling_path(path: &Path, extension: Option<&str>) -> io::Result<PathBuf> {
    let name = path.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{}: output path has no file name", path.display()),
        )
    })?;
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}-{}", std::process::id(), n));
    if let Some(ext) = extension {
        tmp_name.push(".");
        tmp_name.push(ext);
    }
    Ok(path.with_file_name(tmp_name))
}

/// Moves a completed temporary file over the target; removes the temporary on failure.
pub fn persist_temp(tmp: &Path, path: &Path) -> io::Result<()> {
    let result = File::open(tmp)
        .and_then(|file| file.sync_all())
        .and_then(|()| fs::rename(tmp, path));
    if result.is_err() {
        let _ = fs::remove_file(tmp);
    }
    result
}

fn write_temp<F>(tmp: &Path, f: F) -> io::Result<()>
where
    F: FnOnce(&mut dyn Write) -> io::Result<()>,
{
    let file = OpenOptions::new().write(true).create_new(true).open(tmp)?;
    let mut writer = BufWriter::new(file);
    f(&mut writer)?;
    writer.flush()?;
    let file = writer.into_inner().map_err(|e| e.into_error())?;
    file.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .expect("read dir")
            .map(|e| {
                e.expect("dir entry")
                    .file_name()
                    .to_string_lossy()
                    .into_owned()
            })
            .collect();
        names.sort();
        names
    }

    #[test]
    fn writes_new_file_and_leaves_no_temporary() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-atomic-new-")
            .tempdir()
            .unwrap();
        let dir = tmp.path();
        let target = dir.join("out.txt");
        write_atomic(&target, b"hello").expect("write");
        assert_eq!(fs::read(&target).expect("read"), b"hello");
        assert_eq!(entries(dir), vec!["out.txt".to_string()]);
    }

    #[test]
    fn replaces_existing_file() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-atomic-replace-")
            .tempdir()
            .unwrap();
        let dir = tmp.path();
        let target = dir.join("out.txt");
        fs::write(&target, b"old content that is longer").expect("seed");
        write_atomic(&target, b"new").expect("write");
        assert_eq!(fs::read(&target).expect("read"), b"new");
        assert_eq!(entries(dir), vec!["out.txt".to_string()]);
    }

    #[test]
    fn streaming_writer_produces_all_content() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-atomic-stream-")
            .tempdir()
            .unwrap();
        let dir = tmp.path();
        let target = dir.join("big.dat");
        write_atomic_with(&target, |w| {
            for i in 0..10_000 {
                writeln!(w, "{i}")?;
            }
            Ok(())
        })
        .expect("write");
        let text = fs::read_to_string(&target).expect("read");
        assert_eq!(text.lines().count(), 10_000);
        assert_eq!(text.lines().last(), Some("9999"));
    }

    #[test]
    fn failing_writer_keeps_old_file_and_removes_temporary() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-atomic-fail-")
            .tempdir()
            .unwrap();
        let dir = tmp.path();
        let target = dir.join("out.txt");
        fs::write(&target, b"previous").expect("seed");
        let err = write_atomic_with(&target, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("simulated failure"))
        })
        .expect_err("must fail");
        assert_eq!(err.to_string(), "simulated failure");
        assert_eq!(fs::read(&target).expect("read"), b"previous");
        assert_eq!(entries(dir), vec!["out.txt".to_string()]);
    }

    #[test]
    fn missing_directory_is_an_error() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-atomic-missing-")
            .tempdir()
            .unwrap();
        let dir = tmp.path();
        let target = dir.join("no-such-dir").join("out.txt");
        assert!(write_atomic(&target, b"x").is_err());
        assert!(!target.exists());
    }

    #[test]
    fn path_without_file_name_is_an_error() {
        let err = write_atomic(Path::new("/"), b"x").expect_err("must fail");
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    }

    #[test]
    fn temp_sibling_is_hidden_unique_and_in_same_directory() {
        let target = Path::new("some/dir/result.png");
        let a = temp_sibling_path(target, Some("png")).expect("tmp");
        let b = temp_sibling_path(target, Some("png")).expect("tmp");
        assert_ne!(a, b);
        assert_eq!(a.parent(), target.parent());
        let name = a.file_name().expect("name").to_string_lossy().into_owned();
        assert!(name.starts_with(".result.png.tmp-"), "{name}");
        assert!(name.ends_with(".png"), "{name}");
    }

    #[test]
    fn persist_temp_moves_file() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-atomic-persist-")
            .tempdir()
            .unwrap();
        let dir = tmp.path();
        let target = dir.join("final.bin");
        let tmp = temp_sibling_path(&target, None).expect("tmp");
        fs::write(&tmp, b"data").expect("write tmp");
        persist_temp(&tmp, &target).expect("persist");
        assert_eq!(fs::read(&target).expect("read"), b"data");
        assert_eq!(entries(dir), vec!["final.bin".to_string()]);
    }
}
