//! The lock of an output directory: `DIR/.deasim.lock`, created with `create_new` and holding the
//! pid of the run that writes there, removed when the run ends (the [`DirLock`] is dropped). A
//! second run into the same directory finds the lock and is refused; a lock whose process is gone
//! (a `kill -9`, a second Ctrl-C) is stale and is taken over with a warning.

use std::io::{ErrorKind, Write};
use std::path::{Path, PathBuf};

/// The name of the lock file inside the output directory.
pub const LOCK_FILE: &str = ".deasim.lock";

/// A held lock; dropping it removes the lock file.
#[derive(Debug)]
pub struct DirLock {
    path: PathBuf,
}

/// Whether process `pid` exists (a process of another user counts as existing).
fn alive(pid: i32) -> bool {
    if pid <= 0 {
        return false;
    }
    // SAFETY: kill with signal 0 sends nothing; it only checks that the process exists.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
}

impl DirLock {
    /// Creates `dir` if needed and takes its lock. Refused (with a message naming the directory
    /// and the other process) while another live process holds it; a stale lock is taken over
    /// and a warning printed.
    pub fn acquire(dir: &Path) -> Result<DirLock, String> {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create the output directory {}: {e}", dir.display()))?;
        let path = dir.join(LOCK_FILE);
        for _ in 0..50 {
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
            {
                Ok(mut f) => {
                    let written = writeln!(f, "{}", std::process::id()).and_then(|()| f.sync_all());
                    if let Err(e) = written {
                        let _ = std::fs::remove_file(&path);
                        return Err(format!(
                            "{}: cannot write the lock file: {e}",
                            path.display()
                        ));
                    }
                    return Ok(DirLock { path });
                }
                Err(e) if e.kind() == ErrorKind::AlreadyExists => {
                    let text = std::fs::read_to_string(&path).unwrap_or_default();
                    match text.trim().parse::<i32>() {
                        Ok(pid) if alive(pid) => {
                            return Err(format!(
                                "{} is in use by another deasim run (process {pid}, lock file {}); \
                                 wait for it to finish or choose another --out",
                                dir.display(),
                                path.display()
                            ))
                        }
                        Ok(pid) => {
                            log::warn!(
                                "warning: {}: taking over the stale lock of process {pid}, \
                                 which no longer runs",
                                path.display()
                            );
                            let _ = std::fs::remove_file(&path);
                        }
                        // being written by a process that has just created it, or garbage
                        Err(_) => {
                            let young = std::fs::metadata(&path)
                                .and_then(|m| m.modified())
                                .ok()
                                .and_then(|t| t.elapsed().ok())
                                .is_none_or(|age| age.as_secs_f64() < 2.0);
                            if young {
                                std::thread::sleep(std::time::Duration::from_millis(50));
                            } else {
                                log::warn!(
                                    "warning: {}: taking over a lock file without a process id",
                                    path.display()
                                );
                                let _ = std::fs::remove_file(&path);
                            }
                        }
                    }
                }
                Err(e) => {
                    return Err(format!(
                        "{}: cannot create the lock file: {e}",
                        path.display()
                    ))
                }
            }
        }
        Err(format!(
            "{}: cannot take the lock of the output directory (lock file {})",
            dir.display(),
            path.display()
        ))
    }
}

impl Drop for DirLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn second_lock_is_refused_and_stale_one_taken_over() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-lock-")
            .tempdir()
            .unwrap();
        // a directory that does not exist yet: the lock creates it
        let dir = tmp.path().join("out");
        let lock = DirLock::acquire(&dir).unwrap();
        let e = DirLock::acquire(&dir).unwrap_err();
        assert!(
            e.contains("in use by another deasim run")
                && e.contains(&format!("process {}", std::process::id())),
            "{e}"
        );
        drop(lock);
        assert!(!dir.join(LOCK_FILE).exists());
        // a pid that cannot exist
        std::fs::write(dir.join(LOCK_FILE), "2147483600\n").unwrap();
        let lock = DirLock::acquire(&dir).unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.join(LOCK_FILE)).unwrap().trim(),
            std::process::id().to_string()
        );
        drop(lock);
    }
}
