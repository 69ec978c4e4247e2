//! The PETSc linear solver (`[solver] kind = "petsc"`, a build with `--features petsc`) against
//! the default sparse LDLᵀ on the examples, and the pass-through of PETSc options.
//!
//! Reference: the same scenario run with the default `direct` solver. Both default methods are
//! exact factorisations (MUMPS's LDLᵀ and faer's LDLᵀ), so every probe at every step agrees to
//! round-off amplified by the conditioning of the Newton systems: 1e-10 relative to the largest
//! magnitude of that probe over the run. An iterative method agrees to its own tolerance, and one
//! that cannot converge makes the run fail instead of giving a number.
#![cfg(feature = "petsc")]

mod common;

use common::vtu::{read_pvtu, read_vtu, VtuData};
use deasim::io::build::{build, Plan};
use deasim::io::examples::example;
use deasim::io::scenario::parse;
use deasim::job::observer::Observer;
use deasim::job::run::{run, StepRecord};
use deasim::job::state::RunSummary;
use deasim::solve::newton::NewtonSettings;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

/// Keeps every record.
#[derive(Default)]
struct Records(Vec<StepRecord>);

impl Observer for Records {
    fn step(&mut self, _: &Plan, r: &StepRecord, _: &[f64], _: &[deasim::element::CellFields]) {
        self.0.push(r.clone());
    }
    fn finished(&mut self, _: &Plan, _: &RunSummary) {}
}

/// Runs an example with a `[solver]` table appended (none: the default solver).
fn run_example(name: &str, solver: Option<&str>) -> (Plan, RunSummary, Records) {
    let mut text = example(name).unwrap().to_string();
    assert!(
        !text.contains("[solver]"),
        "{name} already chooses a solver"
    );
    if let Some(s) = solver {
        text.push_str("\n[solver]\n");
        text.push_str(s);
        text.push('\n');
    }
    let scenario = parse(&text, "test.toml", &[]).unwrap_or_else(|e| panic!("{e}"));
    let plan = build(&scenario, "test.toml", None).unwrap_or_else(|e| panic!("{e}"));
    let mut records = Records::default();
    let t = Instant::now();
    let summary = run(&plan, &mut records);
    eprintln!(
        "{name} with {}: {:.2} s",
        plan.solver.describe(plan.model.mesh.n_nodes() * 4),
        t.elapsed().as_secs_f64()
    );
    (plan, summary, records)
}

/// The largest difference of any probe at any step, relative to that probe's largest magnitude.
fn probe_difference(plan: &Plan, a: &Records, b: &Records) -> f64 {
    assert_eq!(a.0.len(), b.0.len(), "different numbers of steps");
    let mut worst: f64 = 0.0;
    for (k, (name, _)) in plan.probes.iter().enumerate() {
        let finite = |v: f64| v.is_finite().then_some(v.abs());
        let scale =
            a.0.iter()
                .filter_map(|r| finite(r.probes[k]))
                .fold(0.0, f64::max);
        if scale == 0.0 {
            continue;
        }
        for (ra, rb) in a.0.iter().zip(&b.0) {
            let (va, vb) = (ra.probes[k], rb.probes[k]);
            // undefined in both (a capacitance at zero voltage) is agreement
            if va.is_nan() && vb.is_nan() {
                continue;
            }
            let d = (va - vb).abs() / scale;
            assert!(d.is_finite(), "probe {name}: {va} vs {vb}");
            worst = worst.max(d);
        }
    }
    worst
}

fn agrees_with_the_direct_solver(name: &str) {
    let (plan, reference_summary, reference) = run_example(name, None);
    assert!(reference_summary.converged, "{:?}", reference_summary.error);
    let (_, summary, petsc) = run_example(name, Some("kind = \"petsc\""));
    assert!(summary.converged, "{:?}", summary.error);
    let d = probe_difference(&plan, &reference, &petsc);
    eprintln!("{name}: largest relative probe difference PETSc/MUMPS vs faer LDLT: {d:.2e}");
    assert!(d < 1e-10, "{name}: {d:e}");
}

#[test]
fn film_agrees_with_the_direct_solver() {
    agrees_with_the_direct_solver("film");
}

#[test]
fn stack_agrees_with_the_direct_solver() {
    agrees_with_the_direct_solver("stack");
}

#[test]
fn krylov_options_are_passed_through() {
    let (plan, _, reference) = run_example("film", None);
    let (_, summary, gmres) = run_example(
        "film",
        Some("kind = \"petsc\"\npetsc_options = \"-ksp_type gmres -pc_type jacobi -ksp_rtol 1e-12 -ksp_atol 0 -ksp_max_it 20000 -ksp_gmres_restart 200\""),
    );
    assert!(summary.converged, "{:?}", summary.error);
    let d = probe_difference(&plan, &reference, &gmres);
    eprintln!("film: largest relative probe difference GMRES/Jacobi (rtol 1e-12) vs LDLT: {d:.2e}");
    // Newton stops at its own tolerance on either path; the inexact solves move the converged
    // state by far less than that
    assert!(d < 1e-6, "{d:e}");
}

#[test]
fn a_krylov_solve_that_cannot_converge_is_an_error() {
    let (_, summary, _) = run_example(
        "film",
        Some("kind = \"petsc\"\npetsc_options = \"-ksp_type gmres -pc_type none -ksp_max_it 1 -ksp_rtol 1e-12\""),
    );
    assert!(
        !summary.converged,
        "an unconverged linear solve gave a result"
    );
    let error = summary.error.unwrap_or_default();
    // named as the linear solver's failure, not as a material's limit or a pull-in
    assert!(
        error.starts_with("linear solver failure (")
            && error.contains("did not converge")
            && error.contains("DIVERGED_ITS"),
        "{error}"
    );
}

/// A method PETSc does not know is refused with the scenario, naming the key, before any step
/// (not reported as a failure of the first load step after its cut-backs); so is a
/// preconditioner. A method it knows is accepted.
#[test]
fn a_misspelt_petsc_method_is_refused_with_the_scenario() {
    let build_with = |options: &str| {
        let mut text = example("film").unwrap().to_string();
        text.push_str(&format!(
            "\n[solver]\nkind = \"petsc\"\npetsc_options = \"{options}\"\n"
        ));
        let scenario = parse(&text, "test.toml", &[]).unwrap_or_else(|e| panic!("{e}"));
        build(&scenario, "test.toml", None).map(|_| ())
    };
    for (options, name) in [
        ("-ksp_type nonsense", "nonsense"),
        ("-ksp_type gmres -pc_type nopc", "nopc"),
    ] {
        let error = build_with(options).expect_err(options).to_string();
        assert!(
            error.contains("test.toml")
                && error.contains("solver.petsc_options")
                && error.contains(name),
            "{error}"
        );
    }
    build_with("-ksp_type gmres -pc_type gamg").unwrap();
    // the same for an unknown preconditioner in the environment's PETSC_OPTIONS (in a process of
    // its own: the variable would reach the other tests' solvers)
    let dir = common::tempdir("petsc-bad-environment");
    let out = without_mpi_variables(&mut Command::new(env!("CARGO_BIN_EXE_deasim")))
        .args([
            "run",
            "film",
            "--set",
            "solver.kind=\"petsc\"",
            "--out",
            "out",
        ])
        .env("PETSC_OPTIONS", "-pc_type bogus")
        .current_dir(&dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && stderr.contains("solver.petsc_options")
            && stderr.contains("PETSC_OPTIONS = \"-pc_type bogus\"")
            && stderr.contains("bogus")
            && !stderr.contains("no stable equilibrium"),
        "{stderr}"
    );
}

/// The probe columns and the dissipated energy of a `history.csv`: names and one row of values
/// per step.
fn history_probes(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    csv_columns(path, |h| h.starts_with("probe:") || h == "dissipated")
}

/// Runs a dynamic `example` (with `extra` overrides) serially and on `ranks` ranks, each
/// holding its part, and asserts that the run finished and that its probes, kinetic energy
/// (summed over the ranks' parts) over the whole history and final fields agree to `tolerance`
/// of their largest values.
fn assert_dynamic_parts_agree(ranks: usize, example_name: &str, extra: &[&str], tolerance: f64) {
    let mut kinetic = f64::NAN;
    let (d, fields, serial, log) = on_ranks_of(
        ranks,
        example_name,
        example(example_name).unwrap(),
        extra,
        |a, b| {
            kinetic = csv_difference(&a.join("history.csv"), &b.join("history.csv"), |h| {
                h == "kinetic"
            })
        },
    );
    assert!(serial.contains("finished in"), "{serial}");
    assert_parts(&log, ranks);
    assert!(
        d < tolerance && fields < tolerance && kinetic < tolerance,
        "{example_name} {extra:?}: probes {d:e}, fields {fields:e}, kinetic energy {kinetic:e}"
    );
}

/// The columns of a CSV file whose header passes `keep`: their names and the rows of numbers.
fn csv_columns(path: &Path, keep: impl Fn(&str) -> bool) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let columns: Vec<usize> = (0..header.len()).filter(|&i| keep(header[i])).collect();
    let rows = lines
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            columns.iter().map(|&i| cells[i].parse().unwrap()).collect()
        })
        .collect();
    (
        columns.iter().map(|&i| header[i].to_string()).collect(),
        rows,
    )
}

/// The largest difference of the probes (and the dissipated energy) of two `history.csv` files
/// at any step, relative to that column's largest finite magnitude in the first; a NaN in both
/// (a capacitance at 0 V) is no difference.
fn history_difference(a: &Path, b: &Path) -> f64 {
    columns_difference(history_probes(a), history_probes(b))
}

/// As [`history_difference`] for the columns of two CSV files that pass `keep`.
fn csv_difference(a: &Path, b: &Path, keep: impl Fn(&str) -> bool + Copy) -> f64 {
    columns_difference(csv_columns(a, keep), csv_columns(b, keep))
}

/// The largest difference of two tables of the same columns, relative to each column's largest
/// finite magnitude in the first; a NaN in both is no difference.
fn columns_difference(
    (names, x): (Vec<String>, Vec<Vec<f64>>),
    (names_b, y): (Vec<String>, Vec<Vec<f64>>),
) -> f64 {
    assert_eq!(names, names_b);
    assert!(!names.is_empty(), "no columns to compare");
    assert_eq!(x.len(), y.len(), "different numbers of rows");
    let mut worst: f64 = 0.0;
    for k in 0..names.len() {
        let scale = x
            .iter()
            .map(|r| r[k])
            .filter(|v| v.is_finite())
            .fold(0.0f64, |m, v| m.max(v.abs()));
        if scale == 0.0 {
            continue;
        }
        for (rx, ry) in x.iter().zip(&y) {
            if !(rx[k].is_nan() && ry[k].is_nan()) {
                worst = worst.max((rx[k] - ry[k]).abs() / scale);
            }
        }
    }
    worst
}

/// The largest difference of two sets of field arrays (same names, same order), relative to
/// each array's largest magnitude in `a`, the stresses to `stress_scale`.
fn arrays_difference(a: &[(String, Vec<f64>)], b: &[(String, Vec<f64>)], stress_scale: f64) -> f64 {
    assert_eq!(a.len(), b.len());
    let largest = |x: &[f64]| x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // a tensor written as one array per component (`A1_xx` … `A1_zz`): the largest of them, so
    // that components at round-off (a stretch's shears) are measured on the tensor's scale
    let tensor = |name: &str| {
        name.rsplit_once('_')
            .filter(|(_, c)| c.len() == 2 && c.chars().all(|ch| "xyz".contains(ch)))
            .map(|(t, _)| t.to_string())
    };
    let mut worst: f64 = 0.0;
    for ((name, x), (name_b, y)) in a.iter().zip(b) {
        assert_eq!((name, x.len()), (name_b, y.len()));
        let scale = if name.ends_with("stress") {
            stress_scale
        } else if let Some(t) = tensor(name) {
            a.iter()
                .filter(|(n, _)| tensor(n).as_ref() == Some(&t))
                .map(|(_, v)| largest(v))
                .fold(0.0, f64::max)
        } else {
            largest(x)
        };
        if scale > 0.0 {
            for (u, v) in x.iter().zip(y) {
                worst = worst.max((u - v).abs() / scale);
            }
        }
    }
    worst
}

/// Runs `example` serially with the default solver and under `mpirun -np 2` with the PETSc
/// solver: every rank runs the program, the linear system is one PETSc system distributed by rows
/// over the two ranks, rank 0 writes. Returns the largest difference of any probe at any step
/// relative to that probe's largest magnitude, and the two runs' stderr.
fn two_ranks(example_name: &str) -> (f64, String, String) {
    let (d, _, serial, mpi) = on_ranks(2, example_name, &[]);
    (d, serial, mpi)
}

/// The last field file of a run directory with extension `ext` (`vtu`: a serial run's whole
/// file; `pvtu`: a shared run's index over its pieces).
fn last_fields(dir: &Path, ext: &str) -> std::path::PathBuf {
    let mut files: Vec<_> = std::fs::read_dir(dir.join("fields"))
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("step_") && !n.contains("_p"))
                && p.extension().is_some_and(|e| e == ext)
        })
        .collect();
    files.sort();
    files.pop().expect("no field file")
}

/// The last revolved view of an axisymmetric run (written whole, by rank 0 on several ranks).
fn last_revolved(dir: &Path) -> Option<std::path::PathBuf> {
    let mut files: Vec<_> = std::fs::read_dir(dir.join("fields"))
        .ok()?
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("revolved_") && n.ends_with(".vtu"))
        })
        .collect();
    files.sort();
    files.pop()
}

/// The point and cell arrays of a whole field file, by name.
fn whole_arrays(v: &VtuData) -> Vec<(String, Vec<f64>)> {
    v.point_data
        .iter()
        .chain(&v.cell_data)
        .map(|(n, (_, x))| (n.clone(), x.clone()))
        .collect()
}

/// The pieces of a shared run's field file `pvtu` put together in the node and cell order of
/// the serial run's file `whole` (nodes matched by their coordinates, which both write exactly;
/// cells by their nodes): each node and cell must be in the pieces, each cell in exactly one
/// piece, and each piece must be one rank's (its `rank` array). Returns the arrays as
/// [`whole_arrays`] does.
fn pieced_arrays(pvtu: &Path, whole: &VtuData, ranks: usize) -> Vec<(String, Vec<f64>)> {
    use std::collections::HashMap;
    let pieces = read_pvtu(pvtu).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(pieces.len(), ranks, "one piece per rank");
    let key = |p: &[f64; 3]| p.map(f64::to_bits);
    let node_of: HashMap<[u64; 3], usize> = whole
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| (key(p), i))
        .collect();
    let npc = whole.offsets[0];
    let cell_key = |nodes: &[usize]| {
        let mut k = nodes.to_vec();
        k.sort_unstable();
        k
    };
    let cell_of: HashMap<Vec<usize>, usize> = whole
        .connectivity
        .chunks(npc)
        .enumerate()
        .map(|(c, nodes)| (cell_key(nodes), c))
        .collect();
    let n_nodes = whole.points.len();
    let n_cells = whole.types.len();
    let mut out: Vec<(String, Vec<f64>)> = whole_arrays(whole)
        .into_iter()
        .map(|(n, x)| (n, vec![f64::NAN; x.len()]))
        .collect();
    let mut cell_seen = vec![0usize; n_cells];
    for (rank, piece) in pieces.iter().enumerate() {
        let global: Vec<usize> = piece
            .points
            .iter()
            .map(|p| {
                *node_of
                    .get(&key(p))
                    .expect("a piece's point is not a mesh node")
            })
            .collect();
        let cells: Vec<usize> = piece
            .connectivity
            .chunks(npc)
            .map(|nodes| {
                let g: Vec<usize> = nodes.iter().map(|&l| global[l]).collect();
                *cell_of
                    .get(&cell_key(&g))
                    .expect("a piece's cell is not a mesh cell")
            })
            .collect();
        cells.iter().for_each(|&c| cell_seen[c] += 1);
        let (_, ranks_of) = &piece.cell_data["rank"];
        assert!(ranks_of.iter().all(|&r| r == rank as f64));
        for (name, values) in out.iter_mut() {
            let (arrays, at, count) = match piece.point_data.get(name) {
                Some(a) => (a, &global, n_nodes),
                None => (&piece.cell_data[name], &cells, n_cells),
            };
            let comps = values.len() / count;
            for (k, &g) in at.iter().enumerate() {
                values[g * comps..(g + 1) * comps]
                    .copy_from_slice(&arrays.1[k * comps..(k + 1) * comps]);
            }
        }
    }
    assert!(cell_seen.iter().all(|&k| k == 1), "each cell in one piece");
    for (name, values) in &out {
        assert!(values.iter().all(|v| !v.is_nan()), "{name} not covered");
    }
    out
}

/// `command` without the MPI variables of this test process, which may itself be an MPI
/// singleton (PETSc initialised by the other tests): they would make mpirun think it is nested,
/// and a child deasim think it was launched.
fn without_mpi_variables(command: &mut Command) -> &mut Command {
    for (k, _) in std::env::vars() {
        if ["OMPI_", "PMIX_", "ORTE_", "OPAL_", "PMI_"]
            .iter()
            .any(|p| k.starts_with(p))
        {
            command.env_remove(k);
        }
    }
    command
}

/// Writes `text` with the PETSc solver chosen as `petsc.toml` into `dir`.
fn write_petsc_scenario(dir: &Path, text: &str) {
    std::fs::write(
        dir.join("petsc.toml"),
        format!("{text}\n[solver]\nkind = \"petsc\"\n"),
    )
    .unwrap();
}

/// Runs deasim with `args` in `dir` under `mpirun -np ranks`.
fn mpirun(ranks: usize, dir: &Path, args: &[&str]) -> std::process::Output {
    mpirun_with(ranks, dir, args, &[])
}

/// [`mpirun`] with more environment variables for the ranks.
fn mpirun_with(
    ranks: usize,
    dir: &Path,
    args: &[&str],
    vars: &[(&str, &str)],
) -> std::process::Output {
    mpirun_command(ranks, dir, args, vars)
        .output()
        .expect("mpirun not found: install Open MPI (scripts/install-petsc.sh)")
}

/// The command of [`mpirun_with`], to be started.
fn mpirun_command(ranks: usize, dir: &Path, args: &[&str], vars: &[(&str, &str)]) -> Command {
    let mut mpirun = Command::new("mpirun");
    without_mpi_variables(&mut mpirun)
        .envs(vars.iter().copied())
        .args(["--oversubscribe", "-np", &ranks.to_string()])
        .arg(env!("CARGO_BIN_EXE_deasim"))
        .args(args)
        .current_dir(dir)
        .env("RAYON_NUM_THREADS", "1")
        // each rank reports where the entries it passes lie (checked by `on_ranks_of`)
        .env("DEASIM_PETSC_VERBOSE", "1")
        // Open MPI refuses root unless told (containers, CI)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
    mpirun
}

/// As [`two_ranks`] on `ranks` ranks, with more `--set` overrides (those of `solver.` for the
/// distributed run only, the others for both); also returns
/// the largest difference of the final fields (every array of the last VTU file, relative to
/// that array's largest magnitude).
fn on_ranks(ranks: usize, example_name: &str, extra: &[&str]) -> (f64, f64, String, String) {
    let text = example(example_name).unwrap();
    on_ranks_of(ranks, example_name, text, extra, |_, _| {})
}

/// [`on_ranks`] of the scenario `text` (named `example_name` in messages); `compare` sees the
/// serial and the distributed run's output directories before they are removed.
fn on_ranks_of(
    ranks: usize,
    example_name: &str,
    text: &str,
    extra: &[&str],
    compare: impl FnOnce(&Path, &Path),
) -> (f64, f64, String, String) {
    on_ranks_with(ranks, example_name, text, extra, &[], compare)
}

/// [`on_ranks_of`] with more environment variables `vars` for the ranks.
fn on_ranks_with(
    ranks: usize,
    example_name: &str,
    text: &str,
    extra: &[&str],
    vars: &[(&str, &str)],
    compare: impl FnOnce(&Path, &Path),
) -> (f64, f64, String, String) {
    // one directory per call: tests of one example run side by side in this process
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = common::tempdir(&format!("petsc-mpi-{example_name}-{call}"));
    std::fs::write(dir.join("serial.toml"), text).unwrap();
    write_petsc_scenario(&dir, text);
    let mut sets = vec![
        "--set",
        "output.plots=false",
        "--set",
        "output.fields_every=1000000",
        "--set",
        "output.vtu_format=\"ascii\"",
    ];
    // settings of the solver are the distributed run's: the serial run keeps the default solver
    let mut solver = Vec::new();
    for e in extra {
        if e.starts_with("solver.") {
            solver.extend(["--set", e]);
        } else {
            sets.extend(["--set", e]);
        }
    }
    let mut args = vec!["run", "serial.toml", "--out", "serial"];
    args.extend(&sets);
    let serial = common::deasim(&args, &dir);
    let serial_log = String::from_utf8_lossy(&serial.stderr).into_owned();
    let t = Instant::now();
    let mut args = vec!["run", "petsc.toml", "--out", "mpi"];
    args.extend(&sets);
    args.extend(&solver);
    let mpi = mpirun_with(ranks, &dir, &args, vars);
    let log = String::from_utf8_lossy(&mpi.stderr).into_owned();
    assert!(
        log.contains(&format!("one linear system on {ranks} MPI ranks")),
        "{log}{}",
        String::from_utf8_lossy(&mpi.stdout)
    );
    assert_eq!(
        serial.status.success(),
        mpi.status.success(),
        "serial:\n{serial_log}\n2 ranks:\n{log}"
    );
    eprintln!(
        "{example_name} on {ranks} MPI ranks: {:.2} s",
        t.elapsed().as_secs_f64()
    );

    let worst = history_difference(
        &dir.join("serial/history.csv"),
        &dir.join("mpi/history.csv"),
    );
    eprintln!(
        "{example_name}: largest relative probe difference {ranks} ranks (PETSc) vs serial LDLT: {worst:.2e}"
    );
    // the rows follow the cells: each rank reports, per linear system, where the entries it
    // passes lie; over the ranks, most lie in the passing rank's own rows (seven in ten: on
    // the 32-cell film a fifth of the entries lie at the partition's interface, and the
    // explicit scheme's systems of the potentials alone and of the displacements alone, on
    // rank parts, put 27 % there), and at least as many as with the rows split evenly
    let (mut all, mut own, mut even) = (0.0, 0.0, 0.0);
    let mut first_unknowns = Vec::new();
    for r in 0..ranks {
        for part in log.split(&format!("rank {r}: PETSc rows ")).skip(1) {
            // the partition balancing the unknowns and the boundary dealt out: each rank holds
            // about its share of the unknowns (held ones pad PETSc's rows to whole nodes)
            let counts: Vec<f64> = part
                .split(" unknowns)")
                .next()
                .and_then(|t| t.rsplit('(').next())
                .unwrap()
                .split(" of ")
                .map(|v| v.parse().unwrap())
                .collect();
            let (mine, total) = (counts[0], counts[1]);
            let share = mine / total;
            if first_unknowns.len() == r {
                first_unknowns.push(format!("{mine} of {total}"));
            }
            assert!(
                (share * ranks as f64 - 1.0).abs() <= 0.1,
                "{example_name}: rank {r} holds {mine} of {total} unknowns:\n{log}"
            );
            let number = |after: &str| -> f64 {
                let tail = part.split(after).nth(1).unwrap_or_else(|| panic!("{part}"));
                tail.split_whitespace().next().unwrap().parse().unwrap()
            };
            let entries = number("of the ");
            all += entries;
            own += entries * number("entries it passes, ") / 100.0;
            even += entries * number("own rows (") / 100.0;
        }
    }
    let (own, even) = (own / all, even / all);
    eprintln!(
        "{example_name}: {:.1} % of the entries passed lie in the passing rank's rows ({:.1} % \
         with the rows split evenly); the first system's unknowns per rank: {}",
        100.0 * own,
        100.0 * even,
        first_unknowns.join(", ")
    );
    assert!(
        all > 0.0 && own >= 0.7 && own >= even - 0.005,
        "{example_name}: {own} of the entries in own rows ({even} split evenly):\n{log}"
    );
    // the cells really were shared: each rank assembled some
    let counts: Vec<usize> = log
        .split("the ranks assemble ")
        .nth(1)
        .and_then(|t| t.split(" of the ").next())
        .unwrap_or_else(|| panic!("no partition line in: {log}"))
        .split(", ")
        .map(|c| c.parse().unwrap())
        .collect();
    assert!(
        counts.len() == ranks && counts.iter().all(|&c| c > 0),
        "{log}"
    );
    let mut fields: f64 = 0.0;
    if serial.status.success() {
        let whole = read_vtu(&last_fields(&dir.join("serial"), "vtu")).unwrap();
        let a = whole_arrays(&whole);
        let b = pieced_arrays(&last_fields(&dir.join("mpi"), "pvtu"), &whole, ranks);
        // the collection lists the indexes
        let pvd = std::fs::read_to_string(dir.join("mpi/fields.pvd")).unwrap();
        assert!(pvd.contains(".pvtu\"") && !pvd.contains(".vtu\""), "{pvd}");
        // the total (Cauchy) stress is the mechanical minus the Maxwell stress, which cancel on
        // a free film (28 kPa each, 6e-9 Pa left): stresses are measured on their common scale
        let stress_scale = a
            .iter()
            .filter(|(name, _)| name.ends_with("stress"))
            .map(|(_, x)| x.iter().fold(0.0f64, |m, v| m.max(v.abs())))
            .fold(0.0f64, f64::max);
        fields = arrays_difference(&a, &b, stress_scale);
        // an axisymmetric model's revolved view: every cell's fields, those of the other
        // ranks' cells summed into rank 0's
        if let Some(r) = last_revolved(&dir.join("serial")) {
            let m = last_revolved(&dir.join("mpi")).expect("no revolved view on the ranks");
            assert_eq!(r.file_name(), m.file_name());
            let a = whole_arrays(&read_vtu(&r).unwrap());
            let b = whole_arrays(&read_vtu(&m).unwrap());
            fields = fields.max(arrays_difference(&a, &b, stress_scale));
        }
        eprintln!(
            "{example_name}: largest relative difference of the final fields {ranks} ranks vs \
             serial: {fields:.2e} (cells per rank {counts:?})"
        );
    }
    if serial.status.success() {
        compare(&dir.join("serial"), &dir.join("mpi"));
    }
    (worst, fields, serial_log, log)
}

/// Each rank assembles its own cells (a METIS partition); the residual is summed over the
/// ranks and the tangent by PETSc's COO assembly: the sums run in another order than the serial
/// assembly's, so the results agree to round-off amplified by the Newton systems.
#[test]
fn film_on_two_mpi_ranks_agrees_with_the_serial_run() {
    let (d, fields, _, log) = on_ranks(2, "film", &[]);
    assert_parts(&log, 2);
    assert!(d < 1e-10 && fields < 1e-10, "{d:e} {fields:e}");
}

#[test]
fn stack_on_two_mpi_ranks_agrees_with_the_serial_run() {
    let (d, fields, _, log) = on_ranks(2, "stack", &[]);
    assert_parts(&log, 2);
    assert!(d < 1e-10 && fields < 1e-10, "{d:e} {fields:e}");
}

/// The 3-D diaphragm on 2 ranks, each holding its part: the electrodes, the rigid pad and both
/// symmetry planes cross the partition (see `the_partition_of_the_3d_diaphragm_cuts_its_special_sets`).
/// Its pre-stretch and static `load` stage, then 5 ms of the dynamic stage: the midpoint steps
/// and the electrostatic projections on the ranks' owned unknowns, the pad's mass and dashpot
/// on one rank, the kinetic energy and the Kelvin–Voigt dissipation summed over the ranks.
#[test]
fn the_3d_diaphragm_on_two_mpi_ranks_agrees_with_the_serial_run() {
    assert_dynamic_parts_agree(2, "diaphragm-3d", &["stages.1.duration=0.005"], 1e-10);
}

/// The 3-D diaphragm with a quasi-static `actuate` stage instead of its dynamic one: every
/// stage static, so each rank holds only its part, through the pre-stretch, the hung mass and
/// the voltage; the partition cuts the electrodes, the rigid pad and both symmetry planes (see
/// `the_partition_of_the_3d_diaphragm_cuts_its_special_sets`).
#[test]
fn the_static_3d_diaphragm_on_two_mpi_ranks_in_parts_agrees_with_the_serial_run() {
    let text = example("diaphragm-3d").unwrap();
    let dynamic = "kind = \"dynamic\"\nduration = 1.0";
    assert!(
        text.contains(dynamic),
        "the test assumes the example's dynamic stage"
    );
    let text = text
        // ends in the square wave's first half period, the voltage on (its fields are not
        // round-off about zero)
        .replace(
            dynamic,
            "kind = \"quasi-static\"\nsteps = 5\nduration = 0.2",
        )
        .replace("dt = 1e-3", "");
    let (d, fields, _, log) = on_ranks_of(2, "diaphragm-3d-static", &text, &[], |_, _| {});
    assert_parts(&log, 2);
    assert!(d < 1e-10 && fields < 1e-10, "{d:e} {fields:e}");
}

/// A follower pressure under volume control (the balloon octant), each rank holding its part:
/// the pressure's stiffness is a term that is not a cell term, added by the rank of each face;
/// the bordered step's column and row are summed into their owners' entries, the volume and
/// its start are sums of the ranks' shares, and the step's dot products sums over the ranks.
///
/// The wall is nearly incompressible (κ = 10⁴ μ): its stresses carry the round-off of the
/// volume ratio J times κ (7.7e-11 of the stresses' scale from a J that differs by 1.6e-13 on
/// this machine, 1.05e-10 on another CPU). The kinematic fields agree to 1e-10; the stresses to
/// four times κ's amplification of J's difference.
#[test]
fn a_pressure_load_on_two_mpi_ranks_agrees_with_the_serial_run() {
    let text = example("balloon-volume").unwrap();
    let kappa = 1e9;
    assert!(
        text.contains("kappa = 1e9 "),
        "the test assumes the scenario's bulk modulus"
    );
    let (mut kinematic, mut amplified) = (f64::NAN, f64::NAN);
    let (d, fields, _, log) = on_ranks_of(2, "balloon-volume", text, &[], |serial, mpi| {
        let whole = read_vtu(&last_fields(serial, "vtu")).unwrap();
        let (a, b) = (
            whole_arrays(&whole),
            pieced_arrays(&last_fields(mpi, "pvtu"), &whole, 2),
        );
        let not_stress = |v: &[(String, Vec<f64>)]| -> Vec<(String, Vec<f64>)> {
            v.iter()
                .filter(|(n, _)| !n.ends_with("stress"))
                .cloned()
                .collect()
        };
        kinematic = arrays_difference(&not_stress(&a), &not_stress(&b), 0.0);
        let array = |v: &[(String, Vec<f64>)], name: &str| -> Vec<f64> {
            v.iter().find(|(n, _)| n == name).unwrap().1.clone()
        };
        let (ja, jb) = (array(&a, "J"), array(&b, "J"));
        let dj = ja
            .iter()
            .zip(&jb)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        let stress_scale = a
            .iter()
            .filter(|(n, _)| n.ends_with("stress"))
            .flat_map(|(_, x)| x.iter().map(|v| v.abs()))
            .fold(0.0, f64::max);
        amplified = kappa * dj / stress_scale;
    });
    eprintln!(
        "balloon-volume: kinematic fields {kinematic:.2e}, κ times J's difference {amplified:.2e} \
         of the stresses' scale"
    );
    assert_parts(&log, 2);
    assert!(d < 1e-10 && kinematic < 1e-10, "{d:e} {kinematic:e}");
    assert!(
        fields <= (4.0 * amplified).max(1e-10) && fields < 1e-9,
        "{fields:e} {amplified:e}"
    );
}

/// `balloon-volume` under pressure control: its pressure of `value` (Pa) at load factor 1
/// instead of the prescribed volume, its bulk modulus lowered to 100 μ (so that the stresses do
/// not amplify the round-off of J, see the test above), and the replacements `more` made.
fn balloon_under_pressure(value: &str, more: &[(&str, &str)]) -> String {
    let mut text = example("balloon-volume").unwrap().to_string();
    let volume = "volume = 1.3724e-4";
    let replacements = [(volume, format!("value = {value}"))]
        .into_iter()
        .chain([("kappa = 1e9 ", "kappa = 1e7 ".to_string())])
        .chain(more.iter().map(|(a, b)| (*a, b.to_string())));
    for (from, to) in replacements {
        assert!(
            text.contains(from),
            "the test assumes the example's `{from}`"
        );
        text = text.replace(from, &to);
    }
    text
}

/// A follower pressure under pressure control, with the surface probes (the cavity's volume,
/// the outer electrode's area strain, the pressure): each rank holds only its part, each face
/// of the pressure and of the probes on the rank of its cell. The balloon octant inflated to
/// 2 kPa, below its pressure maximum ([`balloon_under_pressure`]).
#[test]
fn a_follower_pressure_on_two_mpi_ranks_in_parts_agrees_with_the_serial_run() {
    let text = balloon_under_pressure("2e3", &[])
        + "\n[probes.area]\nkind = \"area_strain\"\nset = \"outer\"\n";
    let (d, fields, _, log) = on_ranks_of(
        2,
        "balloon-pressure",
        &text,
        &["stages.1.steps=8"],
        |serial, _| {
            // the pressure inflated the balloon: the probes compared are not round-off
            let (header, rows) = csv_columns(&serial.join("history.csv"), |h| {
                h == "probe:volume" || h == "probe:area" || h == "probe:pressure"
            });
            let last = rows.last().unwrap();
            let at = |name: &str| last[header.iter().position(|h| h == name).unwrap()];
            assert_eq!(at("probe:pressure"), 2e3);
            assert!(at("probe:area") > 0.05, "{}", at("probe:area"));
            assert!(at("probe:volume") > 4.3e-6, "{}", at("probe:volume"));
        },
    );
    eprintln!("balloon under pressure on parts: probes {d:.2e}, fields {fields:.2e}");
    assert_parts(&log, 2);
    assert!(d < 1e-10 && fields < 1e-10, "{d:e} {fields:e}");
}

/// On 3 ranks the partition also cuts the rigid pad (one tied unknown per direction shared by
/// cells of two ranks); METIS's 2-way partition keeps the pad whole. The static `load` stage
/// and 1 ms of the dynamic one, each rank holding its part.
#[test]
fn the_3d_diaphragm_on_three_mpi_ranks_agrees_with_the_serial_run() {
    let (d, fields, _, log) = on_ranks(3, "diaphragm-3d", &["stages.1.duration=0.001"]);
    assert_parts(&log, 3);
    assert!(d < 1e-10 && fields < 1e-10, "{d:e} {fields:e}");
}

/// The 3-D diaphragm's dynamic run on 2 ranks each holding the whole state (as a run with
/// checkpoints does): every rank assembles its own cells into the shared system.
#[test]
fn the_3d_diaphragm_on_two_mpi_ranks_holding_the_whole_state_agrees_with_the_serial_run() {
    let text = example("diaphragm-3d").unwrap();
    let (d, fields, _, log) = on_ranks_with(
        2,
        "diaphragm-3d-whole",
        text,
        &["stages.1.duration=0.005"],
        &[("DEASIM_WHOLE_STATE", "1")],
        |_, _| {},
    );
    assert!(
        log.contains("every rank holds the whole state: DEASIM_WHOLE_STATE is set"),
        "{log}"
    );
    assert!(d < 1e-10 && fields < 1e-10, "{d:e} {fields:e}");
}

/// The partitions these runs use (the function the run set-up calls) cut the sets whose
/// unknowns are shared in special ways: on 2 ranks, both ranks own cells on the top electrode
/// and on both symmetry planes; on 3 ranks, also on the rigid pad.
#[test]
fn the_partition_of_the_3d_diaphragm_cuts_its_special_sets() {
    use deasim::problem::dofs::Field;
    let text = example("diaphragm-3d").unwrap();
    let scenario = parse(text, "test.toml", &[]).unwrap();
    let plan = build(&scenario, "test.toml", None).unwrap();
    let mesh = &plan.model.mesh;
    let ranks_on = |parts: usize, nodes: &[usize]| -> usize {
        let part = plan.partition(parts);
        let mut on = vec![false; mesh.n_nodes()];
        nodes.iter().for_each(|&n| on[n] = true);
        let mut ranks: Vec<usize> = (0..mesh.n_cells())
            .filter(|&c| mesh.cell(c).iter().any(|&n| on[n]))
            .map(|c| part[c])
            .collect();
        ranks.sort_unstable();
        ranks.dedup();
        ranks.len()
    };
    let pad = &plan.rigid[0].nodes;
    let top = &plan
        .electrodes
        .iter()
        .find(|e| e.name == "top")
        .unwrap()
        .nodes;
    let plane = |f: Field| {
        &plan
            .supports
            .iter()
            .find(|d| d.field == f && d.nodes.len() > 1)
            .unwrap()
            .nodes
    };
    for (name, nodes) in [
        ("top electrode", top),
        ("symmetry x", plane(Field::Ux)),
        ("symmetry y", plane(Field::Uy)),
    ] {
        assert_eq!(ranks_on(2, nodes), 2, "{name} on 2 ranks");
    }
    assert!(ranks_on(3, pad) >= 2, "the pad on 3 ranks");
}

#[test]
fn the_axisymmetric_diaphragm_on_two_mpi_ranks_agrees_with_the_serial_run() {
    // pre-stretch, the rigid pad (one tied unknown per direction) and 1 s of dynamics
    let (d, _, _) = two_ranks("diaphragm");
    assert!(d < 1e-9, "{d:e}");
}

/// The film's free vibration on 2 ranks, each holding its part (probes and the kinetic energy
/// over the whole history; the final fields).
#[test]
fn a_dynamic_run_on_two_mpi_ranks_agrees_with_the_serial_run() {
    assert_dynamic_parts_agree(2, "film-vibration", &[], 1e-9);
}

/// The process ids of the ranks whose environment holds `tag` (a variable of one test's
/// `mpirun`), by rank (Open MPI's `OMPI_COMM_WORLD_RANK`).
fn rank_processes(tag: &str) -> Vec<(usize, u32)> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(environ) = std::fs::read(entry.path().join("environ")) else {
            continue;
        };
        let vars: Vec<&[u8]> = environ.split(|&b| b == 0).collect();
        if !vars.contains(&tag.as_bytes()) {
            continue;
        }
        let rank = vars.iter().find_map(|v| {
            std::str::from_utf8(v.strip_prefix(b"OMPI_COMM_WORLD_RANK=")?)
                .ok()?
                .parse()
                .ok()
        });
        if let Some(rank) = rank {
            found.push((rank, pid));
        }
    }
    found.sort_unstable();
    found
}

/// A signal to one rank only (here rank 1 of 2, in parts, then holding the whole state) stops
/// every rank at the same step: the run ends (no rank waits for another), exits 130, and rank 0's
/// outputs hold the last accepted step, as a serial run's do.
#[test]
fn a_signal_to_one_rank_stops_every_rank_cleanly() {
    for call in ["parts", "whole"] {
        let dir = common::tempdir(&format!("petsc-signal-{call}"));
        write_petsc_scenario(&dir, example("film-vibration").unwrap());
        let tag = format!("DEASIM_TEST_SIGNAL={}", dir.display());
        let mut vars = vec![("DEASIM_TEST_SIGNAL", dir.display().to_string())];
        if call == "whole" {
            vars.push(("DEASIM_WHOLE_STATE", "1".to_string()));
        }
        let vars: Vec<(&str, &str)> = vars.iter().map(|(k, v)| (*k, v.as_str())).collect();
        let mut child = mpirun_command(
            2,
            &dir,
            &[
                "run",
                "petsc.toml",
                "--out",
                "o",
                "--set",
                "stages.0.duration=10.0",
                "--set",
                "output.fields_every=50",
            ],
            &vars,
        )
        .stdout(std::process::Stdio::null())
        // a file, not a pipe: nobody reads a pipe while the run goes on, and a full one would
        // block the run
        .stderr(std::fs::File::create(dir.join("log")).unwrap())
        .spawn()
        .expect("mpirun not found: install Open MPI (scripts/install-petsc.sh)");
        // wait until the run has accepted a few steps (history.csv is flushed every 2 s; the
        // ranks may be slow when other tests load the machine)
        let start = Instant::now();
        let rows =
            || std::fs::read_to_string(dir.join("o/history.csv")).map_or(0, |t| t.lines().count());
        while rows() < 4 && start.elapsed().as_secs() < 300 {
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
        let ranks = rank_processes(&tag);
        assert_eq!(
            ranks.iter().map(|r| r.0).collect::<Vec<_>>(),
            [0, 1],
            "{call}"
        );
        let killed = Command::new("kill")
            .args(["-TERM", &ranks[1].1.to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        // a rank left waiting would hang the run: give it a minute, then fail
        let start = Instant::now();
        while child.try_wait().unwrap().is_none() && start.elapsed().as_secs() < 60 {
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
        if child.try_wait().unwrap().is_none() {
            for (_, pid) in &ranks {
                let _ = Command::new("kill")
                    .args(["-KILL", &pid.to_string()])
                    .status();
            }
            child.kill().unwrap();
            panic!("{call}: the ranks did not stop within a minute of the signal to rank 1");
        }
        let status = child.wait().unwrap();
        let log = std::fs::read_to_string(dir.join("log")).unwrap();
        assert_eq!(status.code(), Some(130), "{call}: {log}");
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("o/summary.json")).unwrap())
                .unwrap();
        assert_eq!(summary["converged"], false, "{call}");
        assert!(
            summary["error"]
                .as_str()
                .unwrap()
                .contains("interrupted by a signal"),
            "{call}: {summary}"
        );
        let (header, rows) = csv_columns(&dir.join("o/history.csv"), |h| h == "time");
        assert!(rows.len() > 2, "{call}");
        let t = header.iter().position(|h| h == "time").unwrap();
        let t_last = rows.last().unwrap()[t];
        assert!(t_last > 0.0 && t_last < 10.0, "{call}: {t_last}");
        let pvd = std::fs::read_to_string(dir.join("o/fields.pvd")).unwrap();
        assert!(pvd.trim_end().ends_with("</VTKFile>"), "{call}");
    }
}

/// Newmark on 2 ranks in parts with Kelvin–Voigt damping and a Maxwell branch: the consistent
/// initial acceleration (the ranks' forces and masses, solved over the ranks), each rank's
/// internal variables of its own cells, and the dissipation of both summed over the ranks.
#[test]
fn a_viscoelastic_newmark_run_on_two_mpi_ranks_in_parts_agrees_with_the_serial_run() {
    assert_dynamic_parts_agree(
        2,
        "film-vibration",
        &[
            "stages.0.integrator=\"newmark\"",
            "stages.0.duration=2e-3",
            "materials.elastomer.viscosity=20.0",
            "materials.elastomer.branches=[{mu=5e4,tau=1e-3}]",
        ],
        1e-9,
    );
}

/// The explicit integrator (Störmer–Verlet) with Kelvin–Voigt damping on 2 ranks, each
/// holding its part: each rank evaluates the forces that update the velocities and the
/// dissipated power over its own cells, the velocity equation and the mass solve run over the
/// ranks' owned displacements.
#[test]
fn an_explicit_run_on_two_mpi_ranks_agrees_with_the_serial_run() {
    assert_dynamic_parts_agree(
        2,
        "film-vibration",
        &[
            "stages.0.integrator=\"trapezoidal\"",
            "stages.0.dt=2e-6",
            "stages.0.duration=4e-4",
            "materials.elastomer.viscosity=20.0",
        ],
        1e-9,
    );
}

/// The number that follows the first `marker` in a run's log.
fn number_after(log: &str, marker: &str) -> f64 {
    log.split(marker)
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no number after `{marker}` in: {log}"))
}

#[test]
fn pull_in_is_found_on_two_mpi_ranks() {
    // the stability test reads MUMPS's count of negative pivots (MatGetInertia, with ICNTL(13)
    // so that it is exact on several ranks): both runs stop at the same limit point
    let (d, serial, mpi) = two_ranks("film-pull-in");
    let last = |log: &str| number_after(log, "last converged voltage ");
    let (a, b) = (last(&serial), last(&mpi));
    eprintln!("pull-in: serial {a} V, 2 ranks {b} V");
    assert!(mpi.contains("pull-in"), "{mpi}");
    assert_parts(&mpi, 2);
    assert!(
        (a - b).abs() < 1e-6 * a && (b - 33_695.33).abs() < 0.5,
        "{a} {b}"
    );
    assert!(d < 1e-10, "{d:e}");
}

/// Arc-length continuation on 2 ranks (`film-arc`), each rank holding its part: the
/// arc-length constraint's dot products and the path's other decisions are sums over the
/// ranks' owned unknowns; the path through the limit point (located by the parabola through
/// three points) and the limit voltage agree with the serial run. On 4 × 4 × 2 cells, so that
/// each rank has some (the example has one).
#[test]
fn arc_length_on_two_mpi_ranks_passes_the_same_limit_point() {
    let (d, fields, serial, mpi) = on_ranks(2, "film-arc", &["mesh.divisions=[4,4,2]"]);
    assert_parts(&mpi, 2);
    let limit = |log: &str| number_after(log, "maximum of voltage_top = ");
    let (a, b) = (limit(&serial), limit(&mpi));
    eprintln!("film-arc: limit point serial {a} V, 2 ranks {b} V");
    assert!(
        (a - b).abs() < 1e-6 * a && (a - 33_695.33).abs() < 10.0,
        "{a} {b}"
    );
    assert!(d < 1e-10 && fields < 1e-10, "{d:e} {fields:e}");
}

/// Snap-through on rank parts: the balloon octant (`balloon-volume` under pressure control)
/// followed by arc length with the pressure as the unknown load, through its pressure maximum
/// and minimum (Needleman 1977), each rank holding its part with the pressure's faces. Both
/// limit points, the path and the final fields agree with the serial run
/// ([`balloon_under_pressure`]).
#[test]
fn a_pressure_path_on_two_mpi_ranks_in_parts_passes_both_limit_points() {
    let stage = "kind = \"static\"                 # the volume ramps linearly from its value at the stage start\nsteps = 40";
    let text = balloon_under_pressure(
        "10e3",
        &[(
            stage,
            "kind = \"continuation\"\nparameter = \"pressure\"\nsteps = 20\n\
             target = { probe = \"stretch\", value = 3.2 }",
        )],
    );
    let (d, fields, serial, mpi) = on_ranks_of(2, "balloon-path", &text, &[], |_, _| {});
    assert_parts(&mpi, 2);
    for limit in ["maximum of pressure_0 = ", "minimum of pressure_0 = "] {
        let (a, b) = (number_after(&serial, limit), number_after(&mpi, limit));
        eprintln!("balloon-path: {limit}{a} Pa serial, {b} Pa on 2 ranks");
        assert!((a - b).abs() < 1e-6 * a, "{limit}: {a} {b}");
    }
    // the balloon's pressure maximum at 5 kV on this mesh with κ = 100 μ (5.73 kPa with the
    // example's κ = 10⁴ μ, whose stresses amplify the round-off of J: 1.2e-9 between the runs)
    let max = number_after(&serial, "maximum of pressure_0 = ");
    assert!((max - 5.667e3).abs() < 1.0, "{max}");
    assert!(d < 1e-10 && fields < 1e-10, "{d:e} {fields:e}");
}

/// Charge control on 2 ranks (`film-charge`, 4 × 4 × 2 cells as above): the electrode's
/// potential is one unknown coupled to every rank's electrode nodes. On this mesh the uniform
/// state turns unstable to an inhomogeneous mode, as the example's comment foretells: both runs
/// agree step by step and stop at the same load factor with one negative pivot too many
/// (MUMPS's inertia summed over the ranks).
#[test]
fn charge_control_on_two_mpi_ranks_agrees_with_the_serial_run() {
    let (d, fields, serial, mpi) = on_ranks(2, "film-charge", &["mesh.divisions=[4,4,2]"]);
    let stop = |log: &str| number_after(log, "no stable equilibrium beyond load factor ");
    let (a, b) = (stop(&serial), stop(&mpi));
    eprintln!("film-charge: unstable beyond load factor {a} (serial), {b} (2 ranks)");
    assert!(
        mpi.contains("electromechanical instability under charge control")
            && mpi.contains("last converged charge of `top` ")
            && (a - b).abs() < 1e-6,
        "{mpi}"
    );
    assert_parts(&mpi, 2);
    assert!(d < 1e-10 && fields < 1e-10, "{d:e} {fields:e}");
}

/// Each rank records its own cells only: where the true field first exceeds the dielectric
/// strength is found over every rank's cells, so the 3-D diaphragm on 3 ranks, each holding
/// the whole state, warns about the same cell at the same step as the serial run, and every
/// rank stops there.
#[test]
fn dielectric_breakdown_is_found_over_every_ranks_cells() {
    // below the largest field of the first pulse (1.2e7 V/m)
    let log = breakdown_on_three_ranks("diaphragm-3d", "vhb", "1.1e7", true);
    assert!(
        log.contains("every rank holds the whole state: DEASIM_WHOLE_STATE is set"),
        "{log}"
    );
}

/// As above with each rank holding only its part of the plan, where the field concentrates
/// at the electrodes' edges: the first cell over the ranks' parts, in the whole mesh's
/// numbering, with its centre, is the serial run's, in a static stage (the stack) and in a
/// dynamic one (the 3-D diaphragm).
#[test]
fn dielectric_breakdown_is_found_over_every_ranks_part() {
    // the largest field is 1.8e7 V/m at the third step, 2.4e7 at the fourth
    let log = breakdown_on_three_ranks("stack", "silicone", "2e7", false);
    assert_parts(&log, 3);
    let log = breakdown_on_three_ranks("diaphragm-3d", "vhb", "1.1e7", false);
    assert_parts(&log, 3);
}

/// Runs `example` serially and on 3 ranks with material `material`'s dielectric strength
/// `strength` (V/m), stopping at breakdown, each rank holding the whole state when
/// `whole_state`; checks that both stop with the same warning after as many records. Returns
/// the distributed run's log.
fn breakdown_on_three_ranks(
    example_name: &str,
    material: &str,
    strength: &str,
    whole_state: bool,
) -> String {
    let dir = common::tempdir(&format!(
        "petsc-mpi-breakdown-{example_name}-{}",
        if whole_state { "whole" } else { "parts" }
    ));
    let text = example(example_name).unwrap();
    std::fs::write(dir.join("serial.toml"), text).unwrap();
    write_petsc_scenario(&dir, text);
    let strength = format!("materials.{material}.breakdown_field={strength}");
    let stop = format!("materials.{material}.stop_at_breakdown=true");
    let sets = [
        "--set",
        "output.plots=false",
        "--set",
        "output.fields_every=0",
        "--set",
        &strength,
        "--set",
        &stop,
    ];
    let mut args = vec!["run", "serial.toml", "--out", "serial"];
    args.extend(sets);
    let serial = common::deasim(&args, &dir);
    let mut args = vec!["run", "petsc.toml", "--out", "mpi"];
    args.extend(sets);
    let vars: &[(&str, &str)] = if whole_state {
        &[("DEASIM_WHOLE_STATE", "1")]
    } else {
        &[]
    };
    let mpi = mpirun_with(3, &dir, &args, vars);
    let log = String::from_utf8_lossy(&mpi.stderr).into_owned();
    // both stop at the breakdown (exit status 1)
    assert_eq!(
        serial.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&serial.stderr)
    );
    assert_eq!(mpi.status.code(), Some(1), "{log}");
    let warning = |run: &str| -> String {
        let text = std::fs::read_to_string(dir.join(run).join("summary.json")).unwrap();
        let summary: serde_json::Value = serde_json::from_str(&text).unwrap();
        summary["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|w| w.as_str())
            .find(|w| w.starts_with("dielectric breakdown"))
            .unwrap_or_else(|| panic!("{run}: no breakdown warning in {text}"))
            .to_string()
    };
    let (a, b) = (warning("serial"), warning("mpi"));
    eprintln!("serial: {a}\n3 ranks: {b}");
    // the same cell, position, time and stage; the field to the printed 5 digits
    assert_eq!(a, b);
    let rows = |run: &str| {
        std::fs::read_to_string(dir.join(run).join("history.csv"))
            .unwrap()
            .lines()
            .count()
    };
    assert_eq!(rows("serial"), rows("mpi"));
    log
}

/// Asserts that the distributed run of `log` ran on `ranks` ranks each holding only its part of
/// the plan: rank 0 alone built the whole plan and sent every other rank its part, and each
/// rank's part has fewer nodes and cells than the whole mesh.
fn assert_parts(log: &str, ranks: usize) {
    assert!(log.contains("each rank holds only its part"), "{log}");
    assert_eq!(
        log.matches("built the whole plan").count(),
        1,
        "only rank 0 builds the whole plan: {log}"
    );
    assert!(log.contains("rank 0: built the whole plan"), "{log}");
    for r in 1..ranks {
        assert!(
            log.contains(&format!(
                "rank {r}: received its part of the plan from rank 0"
            )),
            "{log}"
        );
    }
    for r in 0..ranks {
        let line = log
            .split(&format!("rank {r}: its part holds "))
            .nth(1)
            .unwrap_or_else(|| panic!("no part of rank {r} in: {log}"));
        let n: Vec<usize> = line
            .split_whitespace()
            .filter_map(|w| w.parse().ok())
            .take(4)
            .collect();
        assert!(
            n.len() == 4 && n[0] < n[1] && n[2] < n[3],
            "rank {r}: {line}"
        );
    }
}

/// The checkpoint files of run directory `out` written by rank 0, oldest first.
fn checkpoints(out: &Path) -> Vec<std::path::PathBuf> {
    let mut ck: Vec<_> = std::fs::read_dir(out.join("checkpoint"))
        .unwrap_or_else(|e| panic!("{}: {e}", out.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| !p.to_string_lossy().contains(".rank-"))
        .collect();
    ck.sort();
    ck
}

/// Copies the checkpoint of rank 0's file `first` and the files of the other ranks at its step
/// (a run of rank parts) into run directory `out`; returns how many files.
fn copy_checkpoint(first: &Path, out: &Path) -> usize {
    let step = first.file_stem().unwrap().to_string_lossy().into_owned();
    std::fs::create_dir_all(out.join("checkpoint")).unwrap();
    let mut copied = 0;
    for e in std::fs::read_dir(first.parent().unwrap())
        .unwrap()
        .flatten()
    {
        let name = e.file_name().to_string_lossy().into_owned();
        if name == format!("{step}.bin") || name.starts_with(&format!("{step}.rank-")) {
            std::fs::copy(e.path(), out.join("checkpoint").join(&name)).unwrap();
            copied += 1;
        }
    }
    copied
}

/// A run on 2 ranks with checkpoints, each rank holding its part and writing its part's file,
/// cut back to its older checkpoint as a killed run would leave it (newer rows and field files,
/// a stale piece), resumed under `mpirun -np 2`: it ends with the uninterrupted run's history
/// and field files (the same `.pvtu` indexes, every rank's pieces with the same values to
/// round-off). On 3 ranks that checkpoint is refused with the reason; a checkpoint of the whole
/// state (`DEASIM_WHOLE_STATE`) resumes on 3 ranks, with a warning, and so does a run begun in
/// one process and resumed on 2 ranks.
#[test]
fn a_checkpoint_of_two_ranks_resumes_on_two_ranks() {
    let dir = common::tempdir("petsc-mpi-resume");
    let text = example("film").unwrap();
    write_petsc_scenario(&dir, text);
    let log = |o: &std::process::Output| String::from_utf8_lossy(&o.stderr).into_owned();
    let run = |out: &str, vars: &[(&str, &str)]| {
        let args = [
            "run",
            "petsc.toml",
            "--out",
            out,
            "--checkpoint-every",
            "4",
            "--set",
            "output.plots=false",
            "--set",
            "output.vtu_format=\"ascii\"",
        ];
        let full = mpirun_with(2, &dir, &args, vars);
        assert!(full.status.success(), "{}", log(&full));
        full
    };
    let full = run("full", &[]);
    assert_parts(&log(&full), 2);
    run("whole", &[("DEASIM_WHOLE_STATE", "1")]);
    for (cut, ranks, written) in [
        ("cut2", 2, "full"),
        ("cut3", 3, "full"),
        ("whole3", 3, "whole"),
    ] {
        let ck = checkpoints(&dir.join(written));
        assert_eq!(ck.len(), 2, "{ck:?}");
        let out = dir.join(cut);
        std::fs::create_dir_all(out.join("fields")).unwrap();
        // the parts' run: a file of each rank
        let files = if written == "full" { 2 } else { 1 };
        assert_eq!(copy_checkpoint(&ck[0], &out), files);
        let history = std::fs::read_to_string(dir.join(written).join("history.csv")).unwrap();
        let rows: Vec<&str> = history.lines().collect();
        std::fs::write(out.join("history.csv"), rows[..rows.len() - 2].join("\n")).unwrap();
        for e in std::fs::read_dir(dir.join(written).join("fields"))
            .unwrap()
            .flatten()
        {
            std::fs::copy(e.path(), out.join("fields").join(e.file_name())).unwrap();
        }
        std::fs::write(out.join("fields/step_99999_p0001.vtu"), "stale").unwrap();
        let resumed = mpirun(ranks, &dir, &["run", "--resume", cut]);
        if cut == "cut3" {
            assert!(!resumed.status.success());
            assert!(
                log(&resumed).contains(
                    "the checkpoint holds the parts of 2 MPI rank(s), this run has 3: a run \
                     whose ranks held their parts resumes on as many ranks"
                ),
                "{}",
                log(&resumed)
            );
            continue;
        }
        assert!(resumed.status.success(), "{}", log(&resumed));
        assert!(!out.join("fields/step_99999_p0001.vtu").exists());
        // MUMPS schedules its work on several ranks by their load, so two runs agree to
        // round-off, not bit for bit
        let d = history_difference(
            &dir.join(written).join("history.csv"),
            &out.join("history.csv"),
        );
        assert!(
            d <= 1e-10,
            "resumed on {ranks} ranks against uninterrupted: {d:e}"
        );
        if ranks == 2 {
            assert_parts(&log(&resumed), 2);
            assert!(!log(&resumed).contains("written on"), "{}", log(&resumed));
            let mut files = 0;
            for e in std::fs::read_dir(dir.join("full/fields"))
                .unwrap()
                .flatten()
            {
                let name = e.file_name().into_string().unwrap();
                let other = out.join("fields").join(&name);
                if name.ends_with(".pvtu") {
                    assert_eq!(
                        std::fs::read(e.path()).unwrap(),
                        std::fs::read(&other).unwrap()
                    );
                } else {
                    let (p, q) = (read_vtu(&e.path()).unwrap(), read_vtu(&other).unwrap());
                    assert_eq!((&p.points, &p.connectivity), (&q.points, &q.connectivity));
                    let largest = |v: &[f64]| v.iter().fold(0.0f64, |m, t| m.max(t.abs()));
                    let arrays = || p.point_data.iter().chain(&p.cell_data);
                    // the total stress of the free film is the difference of two that cancel:
                    // stresses are compared on their common scale
                    let stress_scale = arrays()
                        .filter(|(n, _)| n.ends_with("stress"))
                        .fold(0.0f64, |m, (_, (_, v))| m.max(largest(v)));
                    for (n, (_, v)) in arrays() {
                        let w = &q.point_data.get(n).or(q.cell_data.get(n)).unwrap().1;
                        let scale = if n.ends_with("stress") {
                            stress_scale
                        } else {
                            largest(v)
                        };
                        for (s, t) in v.iter().zip(w) {
                            assert!((s - t).abs() <= 1e-10 * scale, "{name} {n}");
                        }
                    }
                }
                files += 1;
            }
            // 16 records (the initial state and 15 steps): an index and 2 pieces each
            assert_eq!(files, 16 * 3);
        } else {
            assert!(
                log(&resumed).contains("written on 2 MPI rank(s), this run has 3"),
                "{}",
                log(&resumed)
            );
            let last = last_fields(&out, "pvtu");
            assert_eq!(read_pvtu(&last).unwrap().len(), 3);
        }
    }
    // a run begun in one process and resumed on 2 ranks: the collection lists the whole files
    // before the checkpoint and the indexes after it, and every file it lists exists
    let one = without_mpi_variables(&mut Command::new(env!("CARGO_BIN_EXE_deasim")))
        .args([
            "run",
            "petsc.toml",
            "--out",
            "one",
            "--checkpoint-every",
            "4",
        ])
        .args(["--set", "output.plots=false"])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(one.status.success(), "{}", log(&one));
    let ck = checkpoints(&dir.join("one"));
    assert_eq!(ck.len(), 2, "{ck:?}");
    std::fs::remove_file(&ck[1]).unwrap();
    std::fs::remove_file(dir.join("one/summary.json")).unwrap();
    let resumed = mpirun(2, &dir, &["run", "--resume", "one"]);
    assert!(resumed.status.success(), "{}", log(&resumed));
    assert!(log(&resumed).contains("written on 1 MPI rank(s), this run has 2"));
    let pvd = std::fs::read_to_string(dir.join("one/fields.pvd")).unwrap();
    let files: Vec<&str> = pvd
        .split("file=\"")
        .skip(1)
        .map(|t| t.split('"').next().unwrap())
        .collect();
    assert_eq!(files.len(), 16, "{pvd}");
    assert!(files[..9].iter().all(|f| f.ends_with(".vtu")), "{pvd}");
    assert!(files[9..].iter().all(|f| f.ends_with(".pvtu")), "{pvd}");
    for f in files {
        assert!(dir.join("one").join(f).is_file(), "{f}");
    }
}

/// Runs `petsc.toml` in `dir` on 2 ranks into `full`, a checkpoint every 30 steps, without
/// plots or field files, with the `--set` overrides `set`; asserts that it finished and
/// returns its log.
fn checkpointed_run(dir: &Path, set: &[&str]) -> String {
    let mut args = vec![
        "run",
        "petsc.toml",
        "--out",
        "full",
        "--checkpoint-every",
        "30",
        "--set",
        "output.plots=false",
        "--set",
        "output.fields_every=1000000",
    ];
    for s in set {
        args.extend(["--set", s]);
    }
    let full = mpirun(2, dir, &args);
    let log = String::from_utf8_lossy(&full.stderr).into_owned();
    assert!(full.status.success(), "{log}");
    log
}

/// A dynamic run of rank parts with checkpoints on 2 ranks, cut back as a run killed while
/// its ranks wrote their newer checkpoint would leave it (rank 0's file of that step, not rank
/// 1's): the resumed run skips that step with a warning, takes up the older one, each rank its
/// part (re-factoring the modified-Newton matrix where it was factored), and ends with the
/// uninterrupted run's history.
#[test]
fn a_dynamic_run_of_rank_parts_resumes_from_its_checkpoint() {
    let dir = common::tempdir("petsc-mpi-dynamic-resume");
    write_petsc_scenario(&dir, example("film-vibration").unwrap());
    let log = |o: &std::process::Output| String::from_utf8_lossy(&o.stderr).into_owned();
    assert_parts(&checkpointed_run(&dir, &["stages.0.duration=2e-3"]), 2);
    // 100 steps: the checkpoints of steps 60 and 90 kept
    let ck = checkpoints(&dir.join("full"));
    assert_eq!(ck.len(), 2, "{ck:?}");
    let out = dir.join("cut");
    assert_eq!(copy_checkpoint(&ck[0], &out), 2);
    std::fs::copy(
        &ck[1],
        out.join("checkpoint").join(ck[1].file_name().unwrap()),
    )
    .unwrap();
    let resumed = mpirun(2, &dir, &["run", "--resume", "cut"]);
    let text = log(&resumed);
    assert!(resumed.status.success(), "{text}");
    assert_parts(&text, 2);
    assert!(
        text.contains("skipping an incomplete checkpoint")
            && text.contains("the part of rank 1 is missing")
            && text.contains("resuming `film-vibration` from step 60"),
        "{text}"
    );
    let d = history_difference(&dir.join("full/history.csv"), &out.join("history.csv"));
    assert!(d < 1e-10, "resumed against uninterrupted: {d:e}");
}

/// A viscoelastic model on 2 ranks: each rank updates the internal variables of its own cells
/// only (and sums the energy they dissipate with the others); the history, the internal
/// variables in the field pieces and the revolved view agree with the serial run, and a
/// checkpoint, which collects every cell's internal variables from its rank, resumes on 2 ranks
/// to the uninterrupted run's history.
#[test]
fn a_viscoelastic_run_on_two_mpi_ranks_agrees_with_the_serial_run_and_resumes() {
    let shorter = [
        "prestretch.hold=6.0",
        "prestretch.hold_steps=3",
        "stages.1.duration=0.06",
    ];
    let (d, fields, serial, mpi) = on_ranks(2, "diaphragm-visco", &shorter);
    // the final fields after the dynamic stage: round-off amplified as in the elastic diaphragm
    assert!(
        d < 1e-9 && fields < 1e-8,
        "{d:e} {fields:e}\n{serial}\n{mpi}"
    );

    let dir = common::tempdir("petsc-mpi-visco-resume");
    let text = example("diaphragm-visco").unwrap();
    write_petsc_scenario(&dir, text);
    checkpointed_run(&dir, &shorter);
    let log = |o: &std::process::Output| String::from_utf8_lossy(&o.stderr).into_owned();
    // 10 pre-stretch, 3 hold, 10 load and 60 dynamic steps: checkpoints at 60 and 30 kept,
    // the older in the dynamic stage's ramp-up (viscous branches far from relaxed)
    let ck = checkpoints(&dir.join("full"));
    assert_eq!(ck.len(), 2, "{ck:?}");
    let out = dir.join("cut");
    std::fs::create_dir_all(out.join("checkpoint")).unwrap();
    std::fs::copy(
        &ck[0],
        out.join("checkpoint").join(ck[0].file_name().unwrap()),
    )
    .unwrap();
    let resumed = mpirun(2, &dir, &["run", "--resume", "cut"]);
    assert!(resumed.status.success(), "{}", log(&resumed));
    let d = history_difference(&dir.join("full/history.csv"), &out.join("history.csv"));
    assert!(d < 1e-10, "resumed against uninterrupted: {d:e}");
}

/// The natural frequencies and the frequency response (every real and imaginary part and
/// magnitude; the phases, ill-conditioned where a response is nearly real, follow from them) of
/// two runs, each relative to its column's largest magnitude.
fn linear_analyses_difference(serial: &Path, mpi: &Path) -> (f64, f64) {
    let modes = csv_difference(&serial.join("modes.csv"), &mpi.join("modes.csv"), |h| {
        h == "frequency_hz"
    });
    let response = csv_difference(
        &serial.join("frequency_response.csv"),
        &mpi.join("frequency_response.csv"),
        |h| h.ends_with(":magnitude") || h.ends_with(":real") || h.ends_with(":imag"),
    );
    (modes, response)
}

/// The linear analyses about a biased state on two ranks, each rank assembling the tangent of
/// its own cells: the modes of the 3-D diaphragm carrying its mass at 2 kV (the 4 modes nearest
/// to 500 Hz) and its frequency response (each rank's part of the real form, factored by
/// MUMPS), then
/// the film made of VHB 4910 with three Maxwell branches, whose response carries each branch's
/// complex modulus at the branch's relaxed state on every cell, the other rank's too.
#[test]
fn modes_and_the_frequency_response_on_two_mpi_ranks_agree_with_the_serial_run() {
    let on_two = |label: &str, text: &str, extra: &[&str]| {
        let mut found = None;
        let (d, fields, serial, mpi) = on_ranks_of(2, label, text, extra, |a, b| {
            found = Some(linear_analyses_difference(a, b));
        });
        assert!(
            d < 1e-9 && fields < 1e-9,
            "{label}: history {d:e}, fields {fields:e}\n{serial}\n{mpi}"
        );
        let (modes, response) = found.unwrap_or_else(|| panic!("{label} failed:\n{serial}"));
        // the response by each rank's part of the real form, the serial run's by a complex LU
        assert!(
            mpi.contains("solved by the real form [[A, B], [B, −A]]")
                && mpi.contains("each process holding its own cells' part"),
            "{label}:\n{mpi}"
        );
        assert!(
            serial.contains("solved by a complex sparse LU"),
            "{label}:\n{serial}"
        );
        eprintln!("{label} on 2 ranks: modes {modes:.2e}, frequency response {response:.2e}");
        assert!(
            modes < 1e-9 && response < 1e-8,
            "{label}: modes {modes:e}, response {response:e}"
        );
    };
    // the modes nearest to 500 Hz: K − σM, the mass added once between the ranks
    on_two(
        "diaphragm-response",
        example("diaphragm-response").unwrap(),
        &["stages.3.points=20", "stages.2.shift=500.0"],
    );
    // the modal method (6 modes and the static correction), projected from each rank's part
    let mut found = None;
    let (d, _, serial, mpi) = on_ranks_of(
        2,
        "diaphragm-response-modal",
        example("diaphragm-response").unwrap(),
        &[
            "stages.3.points=20",
            "stages.3.method=\"modal\"",
            "stages.3.count=6",
        ],
        |a, b| found = Some(linear_analyses_difference(a, b)),
    );
    let (_, response) = found.unwrap_or_else(|| panic!("the modal run failed:\n{serial}"));
    assert!(
        mpi.contains("the reduced model of 6 modes and the static correction, projected from each process's own cells' part")
            && serial.contains("the reduced model of 6 modes and the static correction\n"),
        "{mpi}\n{serial}"
    );
    eprintln!("diaphragm-response, modal method, on 2 ranks: frequency response {response:.2e}");
    assert!(
        d < 1e-9 && response < 1e-8,
        "history {d:e}, response {response:e}"
    );
    // the film of `film-modes` made of VHB 4910 (Arruda–Boyce and three Maxwell branches) at 3 kV
    let film = example("film-modes").unwrap();
    let start = film.find("[materials.elastomer]").unwrap();
    let end = start + film[start..].find("[[constraints]]").unwrap();
    let visco = format!(
        "{}[materials.elastomer]\npreset = \"vhb4910-wang2016\"\ndensity = 960.0\n\
         viscosity = 5.0\n\n{}",
        &film[..start],
        &film[end..]
    )
    .replace("voltage = 20e3", "voltage = 3e3");
    assert!(visco.contains("voltage = 3e3"));
    on_two(
        "film-modes-visco",
        &visco,
        &["mesh.divisions=[8,8,2]", "stages.2.points=20"],
    );
}

/// `PETSC_OPTIONS` that choose an iterative method for the static steps leave the frequency
/// response's indefinite real form to MUMPS's LDLᵀ: the run names that method and gives the
/// serial run's response.
#[test]
fn the_frequency_response_keeps_its_direct_method_under_petsc_options() {
    let dir = common::tempdir("petsc-response-options");
    let text = example("film-modes").unwrap();
    std::fs::write(dir.join("serial.toml"), text).unwrap();
    write_petsc_scenario(&dir, text);
    let sets = ["--set", "output.plots=false", "--set", "stages.2.points=12"];
    let mut args = vec!["run", "serial.toml", "--out", "serial"];
    args.extend(sets);
    let serial = common::deasim(&args, &dir);
    assert!(serial.status.success(), "{serial:?}");
    let mut args = vec!["run", "petsc.toml", "--out", "petsc"];
    args.extend(sets);
    let petsc = without_mpi_variables(&mut Command::new(env!("CARGO_BIN_EXE_deasim")))
        .args(&args)
        .current_dir(&dir)
        .env(
            "PETSC_OPTIONS",
            "-ksp_type gmres -pc_type jacobi -ksp_rtol 1e-12 -ksp_atol 0 -ksp_max_it 20000 \
             -ksp_gmres_restart 200",
        )
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&petsc.stderr).into_owned()
        + &String::from_utf8_lossy(&petsc.stdout);
    assert!(petsc.status.success(), "{log}");
    assert!(
        log.contains("with PETSc (KSP preonly, PC cholesky (mumps))"),
        "{log}"
    );
    let (modes, response) = linear_analyses_difference(&dir.join("serial"), &dir.join("petsc"));
    eprintln!("film-modes under PETSC_OPTIONS (GMRES, Jacobi): modes {modes:.2e}, response {response:.2e}");
    assert!(
        modes < 1e-8 && response < 1e-7,
        "modes {modes:e}, response {response:e}"
    );
}

/// GAMG on the whole coupled tangent: GMRES to 1e-12.
const GAMG: &str = "-ksp_type gmres -pc_type gamg -ksp_rtol 1e-12 -ksp_atol 0 -ksp_max_it 2000 \
                    -ksp_gmres_restart 200";

/// The rigid-body modes (and the constant potential) as GAMG's near-null space: on the film's
/// tangent at 2 kV, the solution of the direct solver to 1e-9, in fewer Krylov iterations than
/// with GAMG's default near-null space (one constant vector per block).
#[test]
fn the_rigid_body_modes_help_algebraic_multigrid() {
    use deasim::algebra::system::{LoadedSystem, NonlinearSystem};
    use deasim::job::linear::held_model;
    use deasim::problem::statics::StaticProblem;
    use deasim::solve::linear::{LinearSolver, SolverKind, SolverSettings};
    use deasim::solve::petsc::PetscSolver;
    let scenario = parse(example("film").unwrap(), "test.toml", &[]).unwrap();
    let plan = build(&scenario, "test.toml", None).unwrap();
    let state = vec![0.0; plan.model.mesh.n_nodes() * 4];
    let model = held_model(&plan, &state, Some((0, 2000.0)));
    let mut p = StaticProblem::new(&model, None);
    p.set_load(1.0);
    let mut k = p.new_matrix();
    let mut r = vec![0.0; p.n()];
    p.evaluate(&mut r, Some(&mut k)).unwrap();
    let mut exact = r.clone();
    let mut direct = SolverSettings {
        kind: SolverKind::Direct,
        ..Default::default()
    }
    .build();
    direct.factor(&k).unwrap();
    direct.solve_in_place(&mut exact).unwrap();
    let norm = exact.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let solve = |layout: bool| -> Result<(f64, usize), String> {
        let mut s = PetscSolver::new(GAMG);
        if layout {
            s.set_layout(p.layout().unwrap());
        }
        s.factor(&k).map_err(|e| e.to_string())?;
        if layout {
            assert_eq!(s.near_null_space_size(), Some(6));
            // whole nodes, though the symmetry planes and electrodes hold some unknowns
            assert_eq!(s.matrix_block_size(), Some(4));
        }
        let mut x = r.clone();
        s.solve_in_place(&mut x).map_err(|e| e.to_string())?;
        let d = x
            .iter()
            .zip(&exact)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
            / norm;
        Ok((d, s.stats().krylov_iterations))
    };
    let (d, with) = solve(true).unwrap();
    let without = solve(false);
    eprintln!(
        "film tangent at 2 kV, {GAMG}: {with} iterations with the rigid-body modes (difference \
         to LDLT {d:.1e}), without: {without:?}"
    );
    assert!(d < 1e-9, "{d:e}");
    if let Ok((_, without)) = without {
        assert!(with < without, "{with} vs {without}");
    }
}

/// The near-null space is built on each process's own rows and orthonormalised with sums over
/// the processes: two threads standing for two processes (their sums exchanged through a
/// barrier) give, row for row, the one-process modes of the film's layout; those are
/// orthonormal, zero on the padding rows and span the raw rigid-body motions.
#[test]
fn the_near_null_space_is_built_on_each_processs_rows() {
    use deasim::algebra::system::NonlinearSystem;
    use deasim::problem::statics::StaticProblem;
    use deasim::solve::linear::LinearSolverError;
    use deasim::solve::petsc::near_null_modes;
    use std::sync::{Barrier, Mutex};
    let scenario = parse(example("film").unwrap(), "test.toml", &[]).unwrap();
    let plan = build(&scenario, "test.toml", None).unwrap();
    let p = StaticProblem::new(&plan.model, None);
    let layout = p.layout().unwrap();
    let n = layout.node.len();
    // rows in reverse order of the unknowns, with a padding row after every fifth
    let rows: Vec<Option<usize>> = (0..n)
        .rev()
        .flat_map(|e| {
            if e % 5 == 0 {
                vec![Some(e), None]
            } else {
                vec![Some(e)]
            }
        })
        .collect();
    let (whole, rigid) = near_null_modes(&layout, &rows, &mut |_| Ok(())).unwrap();
    assert_eq!((whole.len(), rigid), (7, 6));
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    for (i, a) in whole.iter().enumerate() {
        for (j, b) in whole.iter().enumerate() {
            let expected = if i == j { 1.0 } else { 0.0 };
            assert!(
                (dot(a, b) - expected).abs() < 1e-12,
                "modes {i}, {j}: {}",
                dot(a, b)
            );
        }
        for (r, e) in rows.iter().enumerate() {
            assert!(e.is_some() || a[r] == 0.0);
        }
    }
    // a rotation about the z axis through the origin lies in the span of the first six
    let rotation: Vec<f64> = rows
        .iter()
        .map(|e| {
            e.map_or(0.0, |e| {
                let x = layout.coords[layout.node[e]];
                match layout.field[e] {
                    0 => -x[1],
                    1 => x[0],
                    _ => 0.0,
                }
            })
        })
        .collect();
    let mut rest = rotation.clone();
    for m in &whole[..rigid] {
        let c = dot(&rest, m);
        rest.iter_mut().zip(m).for_each(|(v, w)| *v -= c * w);
    }
    assert!(dot(&rest, &rest).sqrt() < 1e-12 * dot(&rotation, &rotation).sqrt());

    // two "processes": the first 40 % of the rows and the rest
    let split = 2 * rows.len() / 5;
    let parts = [&rows[..split], &rows[split..]];
    let slots: Mutex<[Vec<f64>; 2]> = Mutex::new([Vec::new(), Vec::new()]);
    let barrier = Barrier::new(2);
    let halves: Vec<Vec<Vec<f64>>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..2)
            .map(|rank| {
                let (slots, barrier, layout, part) = (&slots, &barrier, &layout, parts[rank]);
                scope.spawn(move || {
                    let mut sum = |v: &mut [f64]| -> Result<(), LinearSolverError> {
                        slots.lock().unwrap()[rank] = v.to_vec();
                        barrier.wait();
                        let both = slots.lock().unwrap().clone();
                        for (i, x) in v.iter_mut().enumerate() {
                            *x = both[0][i] + both[1][i];
                        }
                        barrier.wait();
                        Ok(())
                    };
                    near_null_modes(layout, part, &mut sum).unwrap().0
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert_eq!((halves[0].len(), halves[1].len()), (7, 7));
    for (m, w) in whole.iter().enumerate() {
        let joined: Vec<f64> = halves[0][m].iter().chain(&halves[1][m]).copied().collect();
        let d = joined
            .iter()
            .zip(w)
            .fold(0.0f64, |d, (a, b)| d.max((a - b).abs()));
        assert!(d < 1e-14, "mode {m}: {d:e}");
    }
}

/// GAMG with the near-null space on 2 ranks (each rank's modes on its own rows): the film agrees
/// with the serial run.
#[test]
fn film_with_gamg_on_two_mpi_ranks_agrees_with_the_serial_run() {
    let options = format!("solver.petsc_options=\"{GAMG}\"");
    let (d, fields, _, log) = on_ranks(2, "film", &[&options]);
    assert_parts(&log, 2);
    assert!(
        log.contains("near-null space of 6 rigid-body modes"),
        "{log}"
    );
    assert!(d < 1e-10 && fields < 1e-10, "{d:e} {fields:e}");
}

/// A Krylov method with GAMG and the rigid-body modes through a whole run: the film agrees
/// with the default direct solver, with every solve to GMRES's own 1e-12 (`forcing = "fixed"`)
/// and stopped at Newton's forcing term (the default), which saves Krylov iterations.
#[test]
fn film_with_gamg_and_the_rigid_body_modes_agrees_with_the_direct_solver() {
    let (plan, reference_summary, reference) = run_example("film", None);
    assert!(reference_summary.converged, "{:?}", reference_summary.error);
    let mut krylov = Vec::new();
    let mut setups = Vec::new();
    for (forcing, preconditioner) in [
        ("fixed", "renewed"),
        ("adaptive", "renewed"),
        ("adaptive", "kept"),
    ] {
        let (_, summary, gamg) = run_example(
            "film",
            Some(&format!(
                "kind = \"petsc\"\npetsc_options = \"{GAMG}\"\nforcing = \"{forcing}\"\n\
                 preconditioner = \"{preconditioner}\""
            )),
        );
        assert!(
            summary.converged,
            "{forcing}, {preconditioner}: {:?}",
            summary.error
        );
        let d = probe_difference(&plan, &reference, &gamg);
        let (its, newton, factors) = summary.stages.iter().fold((0, 0, 0), |(k, n, f), s| {
            (
                k + s.linear.krylov_iterations,
                n + s.newton_iterations,
                f + s.linear.factorizations,
            )
        });
        eprintln!(
            "film with GAMG, forcing {forcing}, preconditioner {preconditioner}: largest \
             relative probe difference vs LDLT {d:.2e}, {newton} Newton and {its} Krylov \
             iterations, {factors} preconditioner set-ups"
        );
        assert!(d < 1e-10, "{forcing}, {preconditioner}: {d:e}");
        krylov.push(its);
        setups.push(factors);
    }
    assert!(
        (krylov[1] as f64) < 0.8 * krylov[0] as f64,
        "Krylov iterations: fixed {}, adaptive {}",
        krylov[0],
        krylov[1]
    );
    // a kept preconditioner is set up again only when it has grown stale
    assert!(
        setups[2] > 0 && 2 * setups[2] <= setups[1],
        "preconditioner set-ups: renewed {}, kept {}",
        setups[1],
        setups[2]
    );
}

/// The rank-local film of [`newton_on_each_ranks_own_unknowns_on_two_mpi_ranks`]: run on every
/// rank under `mpirun` (ignored in a plain test run). Each rank builds its own part of the film
/// (5 × 5 × 3 hex8 cells at 20 kV, its top face's displacement tied as a rigid pad holds it, so
/// that one equation spans the ranks) on its part of the mesh (`Model::part`), solves it by
/// Newton over the
/// unknowns it owns with PETSc (MUMPS's LDLᵀ with its inertia, then GMRES with GAMG and the
/// rigid-body modes), and compares its nodes with the serial solution that it also computes;
/// then ramps it past pull-in.
#[test]
#[ignore = "run on each rank by newton_on_each_ranks_own_unknowns_on_two_mpi_ranks"]
fn rank_part_of_the_distributed_film() {
    use deasim::algebra::exchange::LocalEquations;
    use deasim::algebra::system::{LoadedSystem, NonlinearSystem};
    use deasim::mesh::distribute::{LocalMesh, Numbering};
    use deasim::mesh::generate::box_mesh;
    use deasim::mesh::partition::partition_cells;
    use deasim::mesh::ElementKind;
    use deasim::problem::assembly::node_processes;
    use deasim::problem::distributed::{equation_owners, OwnedSystem};
    use deasim::problem::dofs::FIELDS;
    use deasim::problem::examples::{tied_film, FILM_SIZE};
    use deasim::problem::statics::StaticProblem;
    use deasim::solve::linear::FaerLdlt;
    use deasim::solve::newton::newton;
    use deasim::solve::petsc::{world, PetscExchange, PetscSolver};
    use deasim::solve::stepping::{ramp, StepControl};
    use std::sync::Arc;

    let voltage = 20e3;
    let mesh = box_mesh(FILM_SIZE, [5, 5, 3], ElementKind::Hex8);
    let whole = tied_film(mesh.clone(), voltage).unwrap();
    let settings = NewtonSettings::default();
    let mut serial = StaticProblem::new(&whole, None);
    serial.set_load(1.0);
    let floor = serial.residual_floor();
    let mut k = serial.new_matrix();
    let serial_report = newton(&mut serial, &mut FaerLdlt::new(), &mut k, &settings).unwrap();
    let scale = |f: usize| {
        (0..mesh.n_nodes())
            .map(|n| serial.state[n * FIELDS + f].abs())
            .fold(0.0_f64, f64::max)
    };
    let (u_scale, phi_scale) = (scale(2), scale(3));

    let (rank, ranks) = world().unwrap();
    assert!(ranks > 1, "run under mpirun with several ranks");
    let dofs = serial.dofs.clone();
    let part = partition_cells(&mesh, ranks, None);
    let node_owner = node_processes(&mesh, &dofs, &part, ranks);
    let numbering = Numbering::contiguous(&equation_owners(&dofs, &node_owner), ranks);
    let local = LocalMesh::of_rank(&mesh, &part, &node_owner, rank, ranks).unwrap();
    let model = whole.part(&local).unwrap();
    let equations = Arc::new({
        let probe = StaticProblem::new(&model, None);
        LocalEquations::new(&dofs, &numbering, &local, &probe.dofs).unwrap()
    });
    assert!(equations.n_owned() < dofs.n_free);
    let ghosts = equations.owned.iter().filter(|&&o| !o).count();
    let exchange = Arc::new(PetscExchange::new(&equations).unwrap());
    for options in [
        "",
        "-ksp_type gmres -pc_type gamg -ksp_rtol 1e-12 -ksp_atol 0",
    ] {
        let mut problem = StaticProblem::new(&model, None);
        problem.set_load(1.0);
        let mut system =
            OwnedSystem::new(problem, Arc::clone(&equations), exchange.clone(), floor).unwrap();
        let mut solver = PetscSolver::new(options);
        let mut k = system.new_matrix();
        let report = newton(&mut system, &mut solver, &mut k, &settings).unwrap();
        // whole nodes of four rows, held unknowns padding
        assert_eq!(solver.matrix_block_size(), Some(4), "rank {rank}");
        let mut worst: f64 = 0.0;
        for (l, &n) in local.nodes.iter().enumerate() {
            for f in 0..FIELDS {
                let (a, b) = (
                    system.local.state[l * FIELDS + f],
                    serial.state[n * FIELDS + f],
                );
                worst = worst.max((a - b).abs() / if f == 3 { phi_scale } else { u_scale });
            }
        }
        let inertia = report.inertia.map(|i| i.negative);
        if options.is_empty() {
            // MUMPS's count over the whole problem: one negative pivot per free potential
            assert_eq!(inertia, Some(dofs.n_free_phi), "rank {rank}");
            assert_eq!(report.iterations, serial_report.iterations, "rank {rank}");
        }
        assert!(worst <= 1e-10, "rank {rank}, `{options}`: {worst:e}");
        println!(
            "rank {rank}: {} of {} unknowns owned, {ghosts} ghosts, `{options}`: {} Newton \
             iterations, negative pivots {inertia:?}, largest difference {worst:.1e}",
            equations.n_owned(),
            dofs.n_free,
            report.iterations
        );
    }

    // pull-in: the film ramped to 40 kV in 4 steps stops at its limit point, found by the
    // inertia of the whole problem, at the load factor of the serial ramp
    let (pull_in_model, whole_pull_in) = {
        let mut whole = whole.clone();
        let mut part = model.clone();
        for m in [&mut whole, &mut part] {
            for d in m.dirichlet.iter_mut().filter(|d| d.value == voltage) {
                d.value = 40e3;
            }
        }
        (part, whole)
    };
    let control = StepControl {
        steps: 4,
        ..StepControl::default()
    };
    let mut serial = StaticProblem::new(&whole_pull_in, None);
    let serial_ramp = ramp(
        &mut serial,
        &mut FaerLdlt::new(),
        &settings,
        &control,
        |_, _| {},
    )
    .expect_err("pull-in below 40 kV");
    let problem = StaticProblem::new(&pull_in_model, None);
    let mut system = OwnedSystem::new(problem, Arc::clone(&equations), exchange, floor).unwrap();
    let failure = ramp(
        &mut system,
        &mut PetscSolver::new(""),
        &settings,
        &control,
        |_, _| {},
    )
    .expect_err("pull-in below 40 kV");
    assert!(
        failure.limit_point && serial_ramp.limit_point,
        "{failure:?}"
    );
    let v = |s: f64| s * 40e3;
    assert!(
        (v(failure.last_converged) - v(serial_ramp.last_converged)).abs() <= 1e-6,
        "rank {rank}: {failure:?} against {serial_ramp:?}"
    );
    println!(
        "rank {rank}: pull-in past {:.4} V (serial {:.4} V)",
        v(failure.last_converged),
        v(serial_ramp.last_converged)
    );
}

/// Each rank holds only its own unknowns (owned and ghosts) through Newton and PETSc's solves:
/// the film with a tie across the partition on 2 ranks reaches the serial solution to 1e-10 of
/// its largest displacement and potential, with the inertia of the whole problem, both with
/// MUMPS and with GAMG (the rigid-body modes about the centroid summed over the ranks); ramped
/// past pull-in, it stops at the serial ramp's last stable load to 1 µV.
#[test]
fn newton_on_each_ranks_own_unknowns_on_two_mpi_ranks() {
    let mut mpirun = Command::new("mpirun");
    let out = without_mpi_variables(&mut mpirun)
        .args(["--oversubscribe", "-np", "2"])
        .arg(std::env::current_exe().unwrap())
        .args([
            "rank_part_of_the_distributed_film",
            "--exact",
            "--ignored",
            "--nocapture",
            "--test-threads=1",
        ])
        .env("RAYON_NUM_THREADS", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .output()
        .expect("mpirun not found: install Open MPI (scripts/install-petsc.sh)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    eprintln!("{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the ranks failed");
    for rank in 0..2 {
        assert_eq!(
            stdout.matches(&format!("rank {rank}: ")).count(),
            3,
            "rank {rank} solved both ways and found pull-in"
        );
    }
}
