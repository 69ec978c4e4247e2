//! Benchmarks of the static core (`deasim bench`, `cargo bench --bench core`): the film of
//! PHYSICS.md §6.1 on hex8 meshes of increasing size. For each: dofs, one residual + tangent
//! assembly, the first factorisation (ordering + symbolic + numeric), a later numeric factorisation,
//! one triangular solve, one Newton iteration (assembly + numeric factorisation + solve), a whole
//! static solve to 20 kV in two load steps, Newton iterations, and the process's peak memory.
//! Sizes run in increasing order, so the peak after a size is that size's peak.

use crate::analysis::statics::{solve_static, StaticProblem};
use crate::examples::film;
use crate::mesh::ElementKind;
use crate::solve::linear::{FaerLdlt, LinearSolver, Ordering};
use crate::solve::newton::{NewtonSettings, NonlinearSystem};
use crate::solve::stepping::{LoadedSystem, StepControl};
use std::time::Instant;

/// Peak resident memory of this process (MiB), from /proc (NaN where unavailable).
pub fn peak_memory_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<f64>().ok())
        })
        .map(|kib| kib / 1024.0)
        .unwrap_or(f64::NAN)
}

/// Column titles of [`bench_film`]'s rows.
pub const HEADER: &str = "          mesh      dofs    nnz(K) assem_s resid_s factor1_s numer_s solve_s newton_s static_s its L_nnz(M) peak_MiB";

/// Benchmarks one film mesh and returns the table row.
pub fn bench_film(div: [usize; 3], ordering: Ordering) -> Result<String, String> {
    let model = film(div, ElementKind::Hex8, 20e3).map_err(|e| e.to_string())?;
    let mut p = StaticProblem::new(&model, None);
    p.set_load(0.5);
    let n = p.n();
    let mut k = p.new_matrix();
    let mut r = vec![0.0; n];
    let t = Instant::now();
    p.evaluate(&mut r, Some(&mut k))?;
    let assembly = t.elapsed().as_secs_f64();
    let t = Instant::now();
    p.evaluate(&mut r, None)?;
    let residual = t.elapsed().as_secs_f64();
    let mut solver = FaerLdlt::with_ordering(ordering);
    let t = Instant::now();
    solver.factor(&k).map_err(|e| e.to_string())?;
    let first = t.elapsed().as_secs_f64();
    let t = Instant::now();
    solver.factor(&k).map_err(|e| e.to_string())?;
    let numeric = t.elapsed().as_secs_f64();
    let mut dx: Vec<f64> = r.iter().map(|v| -v).collect();
    let t = Instant::now();
    solver.solve_in_place(&mut dx).map_err(|e| e.to_string())?;
    let solve = t.elapsed().as_secs_f64();
    let l_nnz = solver.factor_nnz();
    drop(solver);
    let t = Instant::now();
    let mut its = 0;
    let out = solve_static(
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
        |_, s| its += s.newton.iterations,
    );
    out.result.map_err(|e| e.to_string())?;
    let total = t.elapsed().as_secs_f64();
    let name = format!(
        "{}x{}x{}{}",
        div[0],
        div[1],
        div[2],
        if ordering == Ordering::Amd {
            " amd"
        } else {
            ""
        }
    );
    Ok(format!(
        "{name:>14} {n:>9} {:>9} {assembly:>7.3} {residual:>7.3} {first:>9.3} {numeric:>7.3} {solve:>7.3} {:>8.3} {total:>8.2} {its:>3} {:>8.1} {:>8.0}",
        k.nnz(),
        assembly + numeric + solve,
        l_nnz as f64 / 1e6,
        peak_memory_mib()
    ))
}

/// `deasim bench`: prints the table; `large` adds the ~400k-dof mesh.
pub fn cmd_bench(large: bool) -> i32 {
    println!(
        "film benchmark: hex8, METIS nested dissection + faer LDLT, {} threads; times in s",
        rayon::current_num_threads()
    );
    println!("{HEADER}");
    let mut sizes = vec![[25, 25, 4], [64, 64, 5]];
    if large {
        sizes.push([128, 128, 5]);
    }
    for div in sizes {
        match bench_film(div, Ordering::NestedDissection) {
            Ok(row) => println!("{row}"),
            Err(e) => {
                eprintln!("error: {div:?}: {e}");
                return 1;
            }
        }
    }
    0
}
