//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod gradient;
pub mod vtu;

use deasim::mesh::Mesh;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `deasim` binary with `args` in `dir`.
pub fn deasim(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run deasim")
}

/// [`deasim`] on a thread pool of `threads` threads (`RAYON_NUM_THREADS`).
pub fn deasim_on_threads(args: &[&str], dir: &Path, threads: &str) -> Output {
    Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args(args)
        .current_dir(dir)
        .env("RAYON_NUM_THREADS", threads)
        .output()
        .expect("run deasim")
}

/// A fresh, empty directory for one test (named after the test and the process).
pub fn tempdir(name: &str) -> TempDir {
    TempDir::new(&format!("deasim-test-{name}"))
}

/// A fresh directory of the system's temporary directory (`tempfile`), named `PREFIX-…`,
/// removed with everything in it when the test is done with it, unless the test failed (then it
/// stays for inspection). Reads as the `Path` it names.
pub struct TempDir(Option<tempfile::TempDir>, PathBuf);

impl TempDir {
    pub fn new(prefix: &str) -> Self {
        let d = tempfile::Builder::new()
            .prefix(&format!("{prefix}-"))
            .tempdir()
            .expect("a temporary directory");
        let path = d.path().to_path_buf();
        TempDir(Some(d), path)
    }
}

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.1
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.1
    }
}

impl AsRef<std::ffi::OsStr> for TempDir {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.1.as_os_str()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            if let Some(d) = self.0.take() {
                let _ = d.keep();
            }
        }
    }
}

/// A small deterministic generator (xorshift64*), so tests need no extra crate.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.max(1))
    }
    /// Uniform in [-1, 1).
    pub fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let v = self.0.wrapping_mul(0x2545F4914F6CDD1D);
        (v >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// Moves every node by up to `amount` × `h` in each direction (a distorted but valid mesh).
pub fn distort(mesh: &mut Mesh, h: f64, amount: f64, rng: &mut Rng) {
    for x in &mut mesh.nodes {
        for c in x.iter_mut() {
            *c += amount * h * rng.next();
        }
    }
}

/// Compares the assembled tangent of `p` at its current state with central differences of its
/// residual (step `step` in the scaled unknowns) and checks its symmetry to 1e-12. Returns the
/// largest |K − K_fd| relative to the largest tangent entry.
pub fn tangent_fd_error<S: deasim::solve::newton::NonlinearSystem>(p: &mut S, step: f64) -> f64 {
    let n = p.n();
    let mut k = p.new_matrix();
    let mut r = vec![0.0; n];
    p.evaluate(&mut r, Some(&mut k)).unwrap();
    let kmax = k.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (mut rp, mut rm) = (vec![0.0; n], vec![0.0; n]);
    let mut e = vec![0.0; n];
    let mut worst = 0.0f64;
    for j in 0..n {
        e.iter_mut().for_each(|v| *v = 0.0);
        e[j] = 1.0;
        let s = p.snapshot();
        p.increment(&e, step);
        p.evaluate(&mut rp, None).unwrap();
        p.restore(&s);
        p.increment(&e, -step);
        p.evaluate(&mut rm, None).unwrap();
        p.restore(&s);
        for i in 0..n {
            let fd = (rp[i] - rm[i]) / (2.0 * step);
            let kij = k.position(i, j).map(|q| k.values[q]).unwrap_or(0.0);
            worst = worst.max((fd - kij).abs() / kmax);
        }
    }
    for i in 0..n {
        for q in k.row_ptr[i]..k.row_ptr[i + 1] {
            let j = k.col_idx[q] as usize;
            let kji = k.values[k.position(j, i).unwrap()];
            assert!(
                (k.values[q] - kji).abs() <= 1e-12 * kmax,
                "tangent not symmetric at ({i}, {j})"
            );
        }
    }
    worst
}

/// `text` with its electrode line `voltage = VOLTAGE` replaced by a circuit: `source` (a number or
/// a waveform table) through the series resistance `resistance` (Ω). Panics when `text` has no
/// such line, so that a changed example shows here rather than as a silently unchanged run.
pub fn circuit_instead_of(text: &str, voltage: &str, source: &str, resistance: f64) -> String {
    let from = format!("voltage = {voltage}");
    assert!(text.contains(&from), "the scenario has no `{from}`");
    text.replace(
        &from,
        &format!("circuit = {{ source = {source}, resistance = {resistance:e} }}"),
    )
}
