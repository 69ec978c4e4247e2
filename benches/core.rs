//! Benchmark of the static core on the film (PHYSICS.md §6.1) at about 10k, 100k and 400k dofs:
//! one residual + tangent assembly, the first factorisation (symbolic + numeric), a later numeric
//! factorisation, one Newton iteration, a whole static solve to 20 kV, and peak memory.
//!
//! `cargo bench --bench core` runs every size, each in its own process so that the peak memory
//! (VmHWM) belongs to one size; `cargo bench --bench core -- 50x50x10` runs one mesh.

use deasim::analysis::statics::{solve_static, StaticProblem};
use deasim::examples::film;
use deasim::mesh::ElementKind;
use deasim::solve::linear::{FaerLdlt, LinearSolver, Ordering};
use deasim::solve::newton::{NewtonSettings, NonlinearSystem};
use deasim::solve::stepping::{LoadedSystem, StepControl};
use std::time::Instant;

fn peak_memory_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse::<f64>().ok())
        .map(|kib| kib / 1024.0)
        .unwrap_or(f64::NAN)
}

fn run(div: [usize; 3], ordering: Ordering) {
    let model = film(div, ElementKind::Hex8, 20e3).expect("film model");
    let t = Instant::now();
    let mut p = StaticProblem::new(&model, None);
    let setup = t.elapsed().as_secs_f64();
    p.set_load(0.5);
    let n = p.n();
    let mut k = p.new_matrix();
    let mut r = vec![0.0; n];
    let t = Instant::now();
    p.evaluate(&mut r, Some(&mut k)).unwrap();
    let assembly = t.elapsed().as_secs_f64();
    let t = Instant::now();
    p.evaluate(&mut r, None).unwrap();
    let residual_only = t.elapsed().as_secs_f64();
    let mut solver = FaerLdlt::with_ordering(ordering);
    let t = Instant::now();
    solver.factor(&k).unwrap();
    let first_factor = t.elapsed().as_secs_f64();
    let t = Instant::now();
    solver.factor(&k).unwrap();
    let numeric = t.elapsed().as_secs_f64();
    let mut dx: Vec<f64> = r.iter().map(|v| -v).collect();
    let t = Instant::now();
    solver.solve_in_place(&mut dx).unwrap();
    let solve = t.elapsed().as_secs_f64();
    let newton_iteration = assembly + numeric + solve;
    let t = Instant::now();
    let mut iterations = 0;
    let outcome = solve_static(
        &model,
        None,
        &StepControl {
            steps: 2,
            ..Default::default()
        },
        &NewtonSettings {
            check_stability: false,
            ..Default::default()
        },
        |_, s| iterations += s.newton.iterations,
    );
    outcome.result.expect("20 kV converges");
    let total = t.elapsed().as_secs_f64();
    println!(
        "{:>14} {:>9} {:>10} {:>7.3} {:>8.3} {:>8.3} {:>9.3} {:>8.3} {:>7.3} {:>8.3} {:>8.2} {:>4} {:>10.0} {:>9.0}",
        format!("{}x{}x{}{}", div[0], div[1], div[2], if ordering == Ordering::Amd { " amd" } else { "" }),
        n,
        k.nnz(),
        setup,
        assembly,
        residual_only,
        first_factor,
        numeric,
        solve,
        newton_iteration,
        total,
        iterations,
        solver.factor_nnz() as f64 / 1e6,
        peak_memory_mib()
    );
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let parse = |s: &str| -> Option<[usize; 3]> {
        let v: Vec<usize> = s.split('x').filter_map(|p| p.parse().ok()).collect();
        (v.len() == 3).then(|| [v[0], v[1], v[2]])
    };
    let header = || {
        println!(
            "{:>14} {:>9} {:>10} {:>7} {:>8} {:>8} {:>9} {:>8} {:>7} {:>8} {:>8} {:>4} {:>10} {:>9}",
            "mesh", "dofs", "nnz(K)", "setup", "assem_s", "resid_s", "factor1_s", "numer_s", "solve_s",
            "newton_s", "static_s", "its", "L_nnz(M)", "peak_MiB"
        )
    };
    let ordering = if args.iter().any(|a| a == "amd") {
        Ordering::Amd
    } else {
        Ordering::NestedDissection
    };
    if let Some(div) = args.first().and_then(|a| parse(a)) {
        run(div, ordering);
        return;
    }
    println!(
        "film benchmark, hex8, {} rayon threads (times in s; newton = assembly + numeric factorisation + solve)",
        rayon::current_num_threads()
    );
    header();
    let exe = std::env::current_exe().expect("own path");
    for size in [
        "25x25x4",
        "25x25x4 amd",
        "64x64x5",
        "64x64x5 amd",
        "50x50x10",
        "128x128x5",
    ] {
        let out = std::process::Command::new(&exe)
            .args(size.split(' '))
            .output()
            .expect("run size");
        print!("{}", String::from_utf8_lossy(&out.stdout));
        if !out.status.success() {
            eprintln!("{size}: {}", String::from_utf8_lossy(&out.stderr));
        }
    }
}
