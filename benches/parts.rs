//! Rank 0's set-up of a run of rank parts: the film's whole plan built, then every rank's part
//! cut and encoded as the message rank 0 sends it (`job::part::messages`), without MPI.
//!
//! ```sh
//! cargo bench --bench parts -- 108x108x21 2 8 32
//! ```
//!
//! The mesh is that of `scripts/bench-mpi.sh` (the film's 5 × 5 × 1 mm quarter in NX × NY × NZ
//! hex8 cells). Prints the time to build the whole plan (as rank 0 builds it, without the cells'
//! geometry), then per rank count P: the time to cut
//! and encode all P parts (the partition and each problem's numbering made once), that time per
//! rank, the bytes of all messages and of the largest, and the process's peak resident memory
//! so far (`VmHWM`: the whole plan, plus one message at a time).

fn main() {
    use deasim::cli::bench::peak_memory_mib;
    use deasim::job::part::messages;
    use std::time::Instant;

    let mut args = std::env::args().skip(1).filter(|a| a != "--bench");
    let divisions = args.next().unwrap_or_else(|| "52x52x10".into());
    let ranks: Vec<usize> = args.filter_map(|a| a.parse().ok()).collect();
    let ranks = if ranks.is_empty() { vec![2, 8] } else { ranks };
    let overrides = vec![
        "mesh.size=[5e-3,5e-3,1e-3]".to_string(),
        format!("mesh.divisions=[{}]", divisions.replace('x', ",")),
        "probes.inplane_stretch.at=[5e-3,5e-3,1e-3]".to_string(),
    ];
    let text = deasim::io::examples::example("film").expect("the film example");
    let scenario =
        deasim::io::scenario::parse(text, "film.toml", &overrides).expect("the film scenario");
    let start = Instant::now();
    // as rank 0 builds it: without the cells' geometry, which each rank computes for its own
    let plan = deasim::io::build::build_with(&scenario, "film.toml", None, false)
        .expect("the film's plan");
    println!(
        "film {divisions}: {} nodes, {} cells, {} unknowns; whole plan built in {:.2} s, peak {:.0} MiB",
        plan.model.mesh.n_nodes(),
        plan.model.mesh.n_cells(),
        4 * plan.model.mesh.n_nodes(),
        start.elapsed().as_secs_f64(),
        peak_memory_mib()
    );
    println!(
        "{:>6} {:>9} {:>12} {:>12} {:>14} {:>9}",
        "ranks", "cut_s", "per_rank_s", "all_MB", "largest_MB", "peak_MiB"
    );
    for p in ranks {
        let start = Instant::now();
        let (mut all, mut largest) = (0usize, 0usize);
        for m in messages(&plan, p, 0).expect("the film divides") {
            let m = m.expect("every rank's part");
            all += m.len();
            largest = largest.max(m.len());
        }
        let t = start.elapsed().as_secs_f64();
        println!(
            "{p:>6} {t:>9.2} {:>12.3} {:>12.1} {:>14.2} {:>9.0}",
            t / p as f64,
            all as f64 / 1e6,
            largest as f64 / 1e6,
            peak_memory_mib()
        );
    }
}
