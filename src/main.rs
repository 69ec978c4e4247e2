//! The `deasim` command line (argument parsing only).

fn main() {
    eprintln!(
        "deasim {}: the command line arrives with the scenario issue",
        env!("CARGO_PKG_VERSION")
    );
    std::process::exit(2);
}
