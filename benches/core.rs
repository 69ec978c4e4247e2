//! `cargo bench --bench core [-- SIZE [amd]]`: the film benchmark of `deasim::cli::bench`, each size in
//! its own process so that the peak memory belongs to one size. SIZE is NXxNYxNZ (hex8 cells).

use deasim::cli::bench::{bench_film, HEADER};
use deasim::solve::linear::Ordering;

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let parse = |s: &str| -> Option<[usize; 3]> {
        let v: Vec<usize> = s.split('x').filter_map(|p| p.parse().ok()).collect();
        (v.len() == 3).then(|| [v[0], v[1], v[2]])
    };
    let ordering = if args.iter().any(|a| a == "amd") {
        Ordering::Amd
    } else {
        Ordering::NestedDissection
    };
    if let Some(div) = args.first().and_then(|a| parse(a)) {
        match bench_film(div, ordering) {
            Ok(row) => println!("{row}"),
            Err(e) => eprintln!("{e}"),
        }
        return;
    }
    println!(
        "film benchmark, hex8, {} rayon threads; times in s",
        rayon::current_num_threads()
    );
    println!("{HEADER}");
    let exe = std::env::current_exe().expect("own path");
    for size in [
        "25x25x4",
        "25x25x4 amd",
        "64x64x5",
        "64x64x5 amd",
        "50x50x10",
        "128x128x5",
    ] {
        match std::process::Command::new(&exe)
            .args(size.split(' '))
            .output()
        {
            Ok(out) => {
                print!("{}", String::from_utf8_lossy(&out.stdout));
                eprint!("{}", String::from_utf8_lossy(&out.stderr));
            }
            Err(e) => eprintln!("{size}: {e}"),
        }
    }
}
