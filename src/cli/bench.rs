//! Benchmarks of the static core (`deasim bench`, `cargo bench --bench core`): the film of
//! docs/theory.md (homogeneous film) on hex8 meshes of increasing size. For each: dofs, one residual + tangent
//! assembly (the best of five), the first factorisation (ordering + symbolic + numeric), a later numeric factorisation,
//! one triangular solve, one Newton iteration (assembly + numeric factorisation + solve), a whole
//! static solve to 20 kV in two load steps, Newton iterations, and the process's peak memory.
//! Sizes run in increasing order, so the peak after a size is that size's peak.

use crate::job::statics::solve_static;
use crate::mesh::ElementKind;
use crate::problem::examples::film;
use crate::problem::statics::StaticProblem;
use crate::solve::linear::{Ordering, SolverKind, SolverSettings};
use crate::solve::newton::{NewtonSettings, NonlinearSystem};
use crate::solve::stepping::{LoadedSystem, StepControl};
use crate::time::integrator::Scheme;
use std::time::Instant;

use crate::io::memory::peak_memory_in;
pub use crate::io::memory::peak_memory_mib;

/// Column titles of [`bench_film`]'s rows.
pub const HEADER: &str = "          mesh      dofs    nnz(K) assem_s resid_s factor1_s numer_s solve_s newton_s static_s its L_nnz(M) peak_MiB";

/// Assemblies timed per row of [`bench_film`] (the best is reported).
const REPEATS: usize = 5;

/// Benchmarks one film mesh and returns the table row.
pub fn bench_film(div: [usize; 3], ordering: Ordering) -> Result<String, String> {
    let model = film(div, ElementKind::Hex8, 20e3).map_err(|e| e.to_string())?;
    let mut p = StaticProblem::new(&model, None);
    p.set_load(0.5);
    let n = p.n();
    let mut k = p.new_matrix();
    let mut r = vec![0.0; n];
    // assemblies are short: the best of a few, so that a busy machine's noise is left out
    let mut assembly = f64::INFINITY;
    let mut residual = f64::INFINITY;
    for _ in 0..REPEATS {
        let t = Instant::now();
        p.evaluate(&mut r, Some(&mut k))?;
        assembly = assembly.min(t.elapsed().as_secs_f64());
        let t = Instant::now();
        p.evaluate(&mut r, None)?;
        residual = residual.min(t.elapsed().as_secs_f64());
    }
    let mut solver = SolverSettings {
        kind: SolverKind::Direct,
        ordering,
        ..Default::default()
    }
    .build();
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
    let l_nnz = solver.factor_nnz().unwrap_or(0);
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

/// Column titles of [`bench_solver`]'s rows.
pub const SOLVER_HEADER: &str =
    "          mesh      dofs  solver  run_s newton per_newton_s factors krylov peak_MiB";

/// The `film` example's run (15 voltage steps to 30 kV, a stability test at every step) on a
/// hex8 mesh with the given solver kind: wall time, Newton iterations, time per Newton
/// iteration, factorisations, Krylov iterations and the process's peak memory so far.
pub fn bench_solver(div: [usize; 3], kind: SolverKind) -> Result<String, String> {
    let run = film_run(div, kind, 15, None)?;
    Ok(format!(
        "{:>14} {:>9} {:>7} {:>6.2} {:>6} {:>12.3} {:>7} {:>6} {:>8.0}",
        format!("{}x{}x{}", div[0], div[1], div[2]),
        run.dofs,
        kind.name(),
        run.wall_s,
        run.newton,
        run.per_newton_s(),
        run.stats.factorizations,
        run.stats.krylov_iterations,
        peak_memory_mib()
    ))
}

/// What one run of the film's voltage ramp cost.
#[derive(Debug, Clone)]
pub struct FilmRun {
    /// Free unknowns.
    pub dofs: usize,
    pub wall_s: f64,
    pub newton: usize,
    /// The linear solver's work, and its name (after `auto`'s choice).
    pub stats: crate::solve::linear::SolverStats,
    pub solver: String,
}

impl FilmRun {
    /// Wall time per Newton iteration (the run's set-up and predictors included).
    pub fn per_newton_s(&self) -> f64 {
        self.wall_s / self.newton.max(1) as f64
    }
}

/// The `film` example on a hex8 mesh, its voltage ramped to 30 kV in `steps` steps with a
/// stability test at every step, solved by `kind` (with `memory_limit` bytes for a factor).
pub fn film_run(
    div: [usize; 3],
    kind: SolverKind,
    steps: usize,
    memory_limit: Option<usize>,
) -> Result<FilmRun, String> {
    use crate::solve::stepping::ramp;
    let model = film(div, ElementKind::Hex8, 30e3).map_err(|e| e.to_string())?;
    let mut p = StaticProblem::new(&model, None);
    let dofs = p.n();
    let mut solver = SolverSettings {
        kind,
        ordering: Ordering::NestedDissection,
        memory_limit,
        ..Default::default()
    }
    .build();
    let t = Instant::now();
    let report = ramp(
        &mut p,
        solver.as_mut(),
        &NewtonSettings::default(),
        &StepControl {
            steps,
            ..Default::default()
        },
        |_, _| {},
    )
    .map_err(|e| e.reason)?;
    Ok(FilmRun {
        dofs,
        wall_s: t.elapsed().as_secs_f64(),
        newton: report.newton_iterations,
        stats: solver.stats(),
        solver: solver.name().to_string(),
    })
}

/// Film meshes of the scaling table: cells about cubic in the film's 5 × 5 × 1 mm quarter, as
/// the example's own 40 × 40 × 8; about 1.5·10⁴, 1.2·10⁵, 3.2·10⁵ and 1.05·10⁶ unknowns.
pub const SCALING_MESHES: [[usize; 3]; 4] =
    [[24, 24, 5], [52, 52, 10], [72, 72, 14], [108, 108, 21]];

/// Voltage steps of a scaling run (to 30 kV): enough Newton iterations for a mean, few enough
/// for the largest mesh.
pub const SCALING_STEPS: usize = 3;

/// Column titles of [`bench_scaling_row`]'s rows.
pub const SCALING_HEADER: &str = "          mesh      dofs  newton  run_s per_newton_s factors krylov krylov/solve krylov/decade peak_MiB  solver";

/// One row of the scaling table: the film on `div` with [`SCALING_STEPS`] steps.
pub fn bench_scaling_row(
    div: [usize; 3],
    kind: SolverKind,
    memory_limit: Option<usize>,
) -> Result<String, String> {
    let run = film_run(div, kind, SCALING_STEPS, memory_limit)?;
    Ok(format!(
        "{:>14} {:>9} {:>7} {:>6.1} {:>12.3} {:>7} {:>6} {:>12.1} {:>13.2} {:>8.0}  {}",
        format!("{}x{}x{}", div[0], div[1], div[2]),
        run.dofs,
        run.newton,
        run.wall_s,
        run.per_newton_s(),
        run.stats.factorizations,
        run.stats.krylov_iterations,
        run.stats.krylov_iterations as f64 / run.stats.solves.max(1) as f64,
        match run.stats.krylov_decades {
            d if d > 0.0 => run.stats.krylov_iterations as f64 / d,
            _ => 0.0,
        },
        peak_memory_mib(),
        run.solver
    ))
}

/// Parses `NXxNYxNZ`.
pub fn parse_mesh(s: &str) -> Option<[usize; 3]> {
    let v: Vec<usize> = s.split('x').filter_map(|p| p.parse().ok()).collect();
    (v.len() == 3 && s.split('x').count() == 3).then(|| [v[0], v[1], v[2]])
}

/// The scaling exponent p of t ∝ nᵖ between two (unknowns, time) points.
pub fn scaling_exponent(a: (f64, f64), b: (f64, f64)) -> f64 {
    (b.1 / a.1).ln() / (b.0 / a.0).ln()
}

/// The peak resident memory (MiB) of a running process, from /proc.
fn peak_memory_of(pid: u32) -> f64 {
    peak_memory_in(&format!("/proc/{pid}/status"))
}

/// `deasim bench --scaling`: the film on [`SCALING_MESHES`] up to `max_dofs` unknowns, each in
/// its own process (so that the peak memory is that mesh's), stopped after `timeout_s`; then the
/// scaling exponent of the time per Newton iteration between the two largest finished meshes.
pub fn cmd_bench_scaling(
    kind: SolverKind,
    max_dofs: usize,
    memory_limit: Option<usize>,
    timeout_s: f64,
) -> i32 {
    println!(
        "scaling: the film example (hex8, cubic cells), {SCALING_STEPS} voltage steps to 30 kV with a \
         stability test at every step, solver `{}`, {} threads; each mesh in its own process, \
         stopped after {timeout_s:.0} s; times in s",
        kind.name(),
        rayon::current_num_threads()
    );
    println!("{SCALING_HEADER}");
    let Ok(exe) = std::env::current_exe() else {
        eprintln!("error: cannot find this program's path");
        return 1;
    };
    let mut points: Vec<(f64, f64)> = Vec::new();
    for div in SCALING_MESHES {
        let nodes = (div[0] + 1) * (div[1] + 1) * (div[2] + 1);
        if nodes * crate::fem::FIELDS > max_dofs {
            continue;
        }
        let mut cmd = std::process::Command::new(&exe);
        cmd.args([
            "bench",
            "--scaling-row",
            &format!("{}x{}x{}", div[0], div[1], div[2]),
            "--solver",
            kind.name(),
        ]);
        if let Some(bytes) = memory_limit {
            cmd.args(["--memory-limit", &bytes.to_string()]);
        }
        let child = cmd
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::inherit())
            .spawn();
        let mut child = match child {
            Ok(c) => c,
            Err(e) => {
                eprintln!("error: cannot start {}: {e}", exe.display());
                return 1;
            }
        };
        let start = Instant::now();
        let mut peak = f64::NAN;
        let status = loop {
            match child.try_wait() {
                Ok(Some(status)) => break Some(status),
                Ok(None) if start.elapsed().as_secs_f64() > timeout_s => {
                    peak = peak_memory_of(child.id());
                    let _ = child.kill();
                    let _ = child.wait();
                    break None;
                }
                Ok(None) => {
                    peak = peak_memory_of(child.id()).max(if peak.is_nan() { 0.0 } else { peak });
                    std::thread::sleep(std::time::Duration::from_millis(200));
                }
                Err(e) => {
                    eprintln!("error: waiting for the benchmark: {e}");
                    return 1;
                }
            }
        };
        let mut out = String::new();
        if let Some(mut so) = child.stdout.take() {
            use std::io::Read;
            let _ = so.read_to_string(&mut out);
        }
        let name = format!("{}x{}x{}", div[0], div[1], div[2]);
        match status {
            Some(s) if s.success() => {
                print!("{out}");
                let fields: Vec<&str> = out.split_whitespace().collect();
                if let (Some(n), Some(t)) = (
                    fields.get(1).and_then(|v| v.parse::<f64>().ok()),
                    fields.get(4).and_then(|v| v.parse::<f64>().ok()),
                ) {
                    points.push((n, t));
                }
            }
            Some(_) => println!("{name:>14} failed (the message is above)"),
            None => println!(
                "{name:>14} {:>9} stopped after {timeout_s:.0} s, peak {peak:.0} MiB so far",
                nodes * crate::fem::FIELDS
            ),
        }
    }
    if points.len() >= 2 {
        let (a, b) = (points[points.len() - 2], points[points.len() - 1]);
        println!(
            "time per Newton iteration grows as n^{:.2} from {:.0} to {:.0} unknowns",
            scaling_exponent(a, b),
            a.0,
            b.0
        );
    }
    0
}

/// `deasim bench`: prints the tables; `large` adds the ~400k-dof mesh.
pub fn cmd_bench(large: bool) -> i32 {
    if cmd_bench_speed() != 0 {
        return 1;
    }
    println!();
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
    println!();
    println!(
        "solvers: the film example's run (15 steps to 30 kV, inertia at every step), exact \
         factorisation at every Newton iteration (direct) against factorisations reused as FGMRES \
         preconditioners (auto); times in s"
    );
    println!("{SOLVER_HEADER}");
    for div in [[30, 30, 6], [40, 40, 8]] {
        for kind in [SolverKind::Auto, SolverKind::Direct] {
            match bench_solver(div, kind) {
                Ok(row) => println!("{row}"),
                Err(e) => {
                    eprintln!("error: {div:?} {}: {e}", kind.name());
                    return 1;
                }
            }
        }
    }
    println!();
    println!(
        "material cost: the film ({:?} hex8) with VHB 4910, elastic (vhb4910-ab-wang) against three \
         Maxwell branches (vhb4910-wang2016, a step of 0.5 s from the committed state); times in s",
        MATERIAL_MESH
    );
    println!("{MATERIAL_HEADER}");
    for preset in ["vhb4910-ab-wang", "vhb4910-wang2016"] {
        match bench_material(MATERIAL_MESH, preset) {
            Ok(row) => println!("{row}"),
            Err(e) => {
                eprintln!("error: {preset}: {e}");
                return 1;
            }
        }
    }
    println!();
    println!(
        "dynamic film: midpoint integrator, 20 kV step at t = 0, dt = 20 µs, time per step (s)"
    );
    println!("{DYNAMIC_HEADER}");
    for (div, steps) in [([4, 4, 2], 200), ([40, 40, 6], 20)] {
        for reuse in [false, true] {
            match bench_dynamic(div, steps, 2e-5, reuse) {
                Ok(row) => println!("{row}"),
                Err(e) => {
                    eprintln!("error: {div:?}: {e}");
                    return 1;
                }
            }
        }
    }
    println!();
    println!(
        "the default diaphragm, axisymmetric against 3-D (diaphragm-3d); solves only, no output \
         files; times in s"
    );
    println!("{AXISYMMETRIC_HEADER}");
    match bench_axisymmetric() {
        Ok(rows) => rows.iter().for_each(|r| println!("{r}")),
        Err(e) => {
            eprintln!("error: axisymmetric benchmark: {e}");
            return 1;
        }
    }
    println!();
    println!(
        "small-signal analyses of the diaphragm (2928 dofs, 2 kV bias) against a time-domain \
         sweep; times in s"
    );
    println!("{LINEAR_HEADER}");
    match bench_linear(200) {
        Ok(rows) => rows.iter().for_each(|r| println!("{r}")),
        Err(e) => {
            eprintln!("error: small-signal benchmark: {e}");
            return 1;
        }
    }
    println!();
    println!(
        "modes of the default diaphragm: harmonics 0-3 of the axisymmetric model ({HARMONICS_COUNT} \
         of each) against the full 3-D disc; each row in its own process; times in s"
    );
    println!("{HARMONICS_HEADER}");
    match bench_harmonics() {
        Ok(rows) => rows.iter().for_each(|r| println!("{r}")),
        Err(e) => {
            eprintln!("error: harmonics benchmark: {e}");
            return 1;
        }
    }
    println!();
    match bench_calibration() {
        Ok((wall, rms, iterations)) => println!(
            "calibration: VHB 4910, 3 rates (Hossain et al. 2012), 7 parameters: {wall:.3} s, \
             {iterations} iterations, RMS {:.3} kPa",
            rms / 1e3
        ),
        Err(e) => {
            eprintln!("error: calibration benchmark: {e}");
            return 1;
        }
    }
    println!();
    cmd_bench_adjoint()
}

/// The gradient and optimal-control tables: the adjoint's time against the forward run's, and
/// the optimisation of `diaphragm-control`.
pub fn cmd_bench_adjoint() -> i32 {
    println!("gradients by the adjoint (a control with knots every 10 ms and 4 parameters):");
    println!("{GRADIENT_HEADER}");
    for (name, sets) in [
        ("diaphragm", &[][..]),
        ("diaphragm-3d", &["stages.1.duration=0.1".to_string()][..]),
        // the whole example: the short row's forward run is half its static stage
        ("diaphragm-3d", &[][..]),
        ("diaphragm-visco", &[][..]),
    ] {
        match bench_gradient(name, sets) {
            Ok(row) => println!("{row}"),
            Err(e) => println!("{name:>16} {e}"),
        }
    }
    println!();
    println!("optimal control of diaphragm-control (a knot every 1 ms):");
    println!("{CONTROL_HEADER}");
    for duration in [0.3, 1.0] {
        for model in [true, false] {
            match bench_control(duration, 300, model) {
                Ok(row) => println!("{row}"),
                Err(e) => println!("{duration:>10} s {e}"),
            }
        }
    }
    0
}

/// Column titles of [`bench_control`]'s rows.
pub const CONTROL_HEADER: &str =
    "  stage_s  knots model iterations runs  converged      J_start        J_end   wall_s s/run";

/// The optimisation of `diaphragm-control` with its `actuate` stage `duration` s long (a knot
/// every 1 ms) to convergence or `max_iterations`, with or without the response `model`:
/// iterations, runs (each with its adjoint), the objective before and after, and the wall time.
pub fn bench_control(duration: f64, max_iterations: usize, model: bool) -> Result<String, String> {
    use crate::api::{ControlOptions, Simulation};
    let sim = Simulation::from_example("diaphragm-control")
        .map_err(|e| e.to_string())?
        .with_overrides(&[
            format!("stages.1.duration={duration}"),
            "output.fields_every=0".into(),
            "output.plots=false".into(),
        ]);
    let o = sim
        .control(
            &ControlOptions {
                max_iterations,
                response_model: model,
                ..Default::default()
            },
            |_| {},
        )
        .map_err(|e| e.to_string())?;
    let knots: usize = o.drives.iter().map(|d| d.values.len()).sum();
    Ok(format!(
        "{duration:>9.2} {knots:>6} {:>5} {:>10} {:>4} {:>10} {:>12.4e} {:>12.4e} {:>8.1} {:>5.2}",
        if model { "yes" } else { "no" },
        o.history.len() - 1,
        o.evaluations,
        o.converged,
        o.history[0].objective,
        o.objective,
        o.wall_s,
        o.wall_s / o.evaluations as f64
    ))
}

/// Column titles of [`bench_gradient`]'s rows.
pub const GRADIENT_HEADER: &str = "         example  steps forward_s adjoint_s  ratio tape_MB";

/// The gradient of a misfit of the pad's deflection over the dynamic stage `actuate` of example
/// `name` (with `sets`) in the first parameter of its material (C₁₀ of a Yeoh model), the pad's
/// mass, the top electrode's voltage and the pre-stretch, and in the knots of a control of the
/// top electrode every 10 ms: the forward run's and the adjoint's wall times and the taped
/// states.
pub fn bench_gradient(name: &str, sets: &[String]) -> Result<String, String> {
    use crate::api::{GradientOptions, Simulation};
    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
    std::fs::write(dir.path().join("d.csv"), "time,value\n0,3e-4\n1e3,3e-4\n")
        .map_err(|e| e.to_string())?;
    let base = crate::io::examples::example(name).ok_or("no such example")?;
    let sim = Simulation::from_toml(base, Some(dir.path()));
    let plan = sim.plan().map_err(|e| e.to_string())?;
    let material = &plan.material_names[0];
    let first = plan.model.materials[0]
        .parameters()
        .and_then(|p| p.names.first().cloned())
        .ok_or("the material has no parameters")?;
    let text = format!(
        "{base}\n[[parameters]]\npath = \"materials.{material}.{first}\"\n\
         [[parameters]]\npath = \"loads.rigid.0.mass\"\n\
         [[parameters]]\npath = \"electrodes.top.voltage.amplitude\"\n\
         [[parameters]]\npath = \"prestretch.stretch\"\n\
         [[controls]]\nelectrode = \"top\"\nstage = \"actuate\"\ninterval = 0.01\n\
         [[objective]]\nkind = \"probe-misfit\"\nprobe = \"center_deflection\"\n\
         stage = \"actuate\"\ndata = \"d.csv\"\nweight = 1e8\n"
    );
    let mut overrides = sets.to_vec();
    overrides.push("output.fields_every=0".into());
    overrides.push("output.plots=false".into());
    let sim = Simulation::from_toml(&text, Some(dir.path())).with_overrides(&overrides);
    let r = sim
        .gradient(&GradientOptions::default())
        .map_err(|e| e.to_string())?;
    let steps = sim
        .plan()
        .map_err(|e| e.to_string())?
        .stages
        .iter()
        .map(|s| s.kind.nominal_steps(s.duration))
        .sum::<usize>();
    Ok(format!(
        "{name:>16} {steps:>6} {:>9.3} {:>9.3} {:>6.2} {:>7.1}",
        r.forward_s,
        r.adjoint_s,
        r.adjoint_s / r.forward_s,
        r.tape_bytes as f64 / 1e6
    ))
}

/// Mesh of [`bench_material`] in `deasim bench`.
pub const MATERIAL_MESH: [usize; 3] = [25, 25, 4];

/// Column titles of [`bench_material`]'s rows.
pub const MATERIAL_HEADER: &str =
    "            material  state/pt assem_s resid_s newton_s  (best of 5)";

/// The cost of one material in the film's assembly: residual and tangent, residual alone, and a
/// Newton iteration (assembly + numeric factorisation + solve), best of five, with the material's
/// point states (a step of 0.5 s from the virgin state for materials with internal variables).
pub fn bench_material(div: [usize; 3], preset: &str) -> Result<String, String> {
    let (name, params) =
        crate::material::registry::preset(preset).ok_or_else(|| format!("no preset {preset}"))?;
    let (mat, _) = crate::material::registry::build(name, &params).map_err(|e| e.to_string())?;
    let mut model = film(div, ElementKind::Hex8, 5e3).map_err(|e| e.to_string())?;
    model.materials = vec![mat.clone()];
    let mut p = StaticProblem::new(&model, None);
    p.duration = 1.0;
    p.set_load(0.5);
    let n = p.n();
    let mut k = p.new_matrix();
    let mut r = vec![0.0; n];
    let mut solver = SolverSettings::default().build();
    p.evaluate(&mut r, Some(&mut k))?;
    solver.factor(&k).map_err(|e| e.to_string())?;
    let best = |f: &mut dyn FnMut() -> Result<(), String>| -> Result<f64, String> {
        let mut best = f64::INFINITY;
        for _ in 0..5 {
            let t = Instant::now();
            f()?;
            best = best.min(t.elapsed().as_secs_f64());
        }
        Ok(best)
    };
    let assembly = best(&mut || p.evaluate(&mut r, Some(&mut k)))?;
    let residual = best(&mut || p.evaluate(&mut r, None))?;
    let newton = best(&mut || {
        p.evaluate(&mut r, Some(&mut k))?;
        solver.factor(&k).map_err(|e| e.to_string())?;
        let mut dx: Vec<f64> = r.iter().map(|v| -v).collect();
        solver.solve_in_place(&mut dx).map_err(|e| e.to_string())
    })?;
    Ok(format!(
        "{preset:>20} {:>9} {assembly:>7.3} {residual:>7.3} {newton:>8.3}",
        mat.state_size()
    ))
}

/// Benchmarks the dynamic film (1000 kg/m³, 20 kV step, midpoint integrator): `steps` steps of
/// `dt`, with plain and with modified Newton. Returns the table row.
pub fn bench_dynamic(
    div: [usize; 3],
    steps: usize,
    dt: f64,
    reuse: bool,
) -> Result<String, String> {
    use crate::time::integrator::TimeLevel;
    use crate::time::mass::{MassKind, NodalMass};
    use crate::time::stage::{run_dynamic, DynamicInputs, DynamicSettings, Method};
    use crate::waveform::Waveform;
    let mut model = film(div, ElementKind::Hex8, 0.0).map_err(|e| e.to_string())?;
    // supports only: the electrodes are driven by the stage
    model
        .dirichlet
        .retain(|d| d.field != crate::problem::dofs::Field::Phi);
    let bottom = model.mesh.node_sets["z0"].clone();
    let top = model.mesh.node_sets["z1"].clone();
    let mass = NodalMass::new(&model, &[1000.0], MassKind::Consistent);
    let inputs = DynamicInputs {
        mass: &mass,
        viscosity: vec![0.0],
        drive: crate::problem::drive::Drive {
            voltages: vec![
                (bottom, Waveform::constant(0.0)),
                (top, Waveform::constant(20e3)),
            ],
            ..crate::problem::drive::Drive::held(&model)
        },
        points: Default::default(),
        part: None,
    };
    let n = model.mesh.n_nodes() * 4;
    let start = TimeLevel {
        t: 0.0,
        q: vec![0.0; n],
        v: vec![0.0; n],
        a: vec![0.0; n],
    };
    let settings = DynamicSettings {
        duration: dt * steps as f64,
        dt,
        scheme: Method::Implicit(Scheme::Midpoint),
        min_fraction: 1.0 / 1024.0,
        easy_iterations: 6,
        reuse_factorization: reuse,
        solver: Default::default(),
    };
    let t = Instant::now();
    let mut its = 0;
    let mut accepted = 0;
    run_dynamic(
        &model,
        &inputs,
        start,
        &settings,
        &NewtonSettings::default(),
        |_, info| {
            its += info.newton_iterations;
            accepted += 1;
        },
    )
    .map_err(|(_, f)| f.reason)?;
    let total = t.elapsed().as_secs_f64();
    Ok(format!(
        "{:>10} {:>8} {:>6} {:>9} {:>10.4} {:>8.2} {:>8.0}",
        format!("{}x{}x{}", div[0], div[1], div[2]),
        n,
        accepted,
        if reuse { "modified" } else { "full" },
        total / accepted.max(1) as f64,
        its as f64 / accepted.max(1) as f64,
        peak_memory_mib()
    ))
}

/// Column titles of [`bench_dynamic`]'s rows.
pub const DYNAMIC_HEADER: &str = "      mesh     dofs  steps    newton   s/step  its/step peak_MiB";

/// An observer that keeps nothing (the benchmarks time the solve alone).
struct Quiet;

impl crate::job::observer::Observer for Quiet {
    fn step(
        &mut self,
        _: &crate::job::plan::Plan,
        _: &crate::job::run::StepRecord,
        _: &[f64],
        _: &[crate::element::CellFields],
    ) {
    }
    fn finished(&mut self, _: &crate::job::plan::Plan, _: &crate::job::state::RunSummary) {}
}

/// A stage's name, wall time (s) and steps.
type StageWall = (String, f64, usize);

/// Runs an example with overrides through the library (no output files): the model's unknowns
/// and, per stage, its name, wall time (s) and steps.
fn run_example(name: &str, sets: &[String]) -> Result<(usize, Vec<StageWall>), String> {
    let text = crate::io::examples::example(name).ok_or_else(|| format!("no example {name}"))?;
    run_text(text, name, sets)
}

/// [`run_example`] of a scenario's text.
fn run_text(text: &str, name: &str, sets: &[String]) -> Result<(usize, Vec<StageWall>), String> {
    use crate::io::build::build;
    use crate::io::scenario::parse;
    let s = parse(text, name, sets).map_err(|e| e.to_string())?;
    let plan = build(&s, name, None).map_err(|e| e.to_string())?;
    let summary = crate::job::run::run(&plan, &mut Quiet);
    if !summary.converged {
        return Err(summary.error.unwrap_or_default());
    }
    Ok((
        plan.model.mesh.n_nodes() * crate::fem::FIELDS,
        summary
            .stages
            .iter()
            .map(|st| (st.name.clone(), st.wall_s, st.steps))
            .collect(),
    ))
}

/// Wall time (s) and steps of the stage `name` of a [`run_example`] result.
fn wall(stages: &[StageWall], name: &str) -> (f64, usize) {
    stages
        .iter()
        .find(|s| s.0 == name)
        .map(|s| (s.1, s.2))
        .unwrap_or((f64::NAN, 0))
}

/// Column titles of [`bench_axisymmetric`]'s rows.
pub const AXISYMMETRIC_HEADER: &str =
    "            model   dofs  sag_solve_s  default_run_s  peak_MiB";

/// The default diaphragm (axisymmetric) against the same actuator in 3-D (`diaphragm-3d`, a
/// quarter disc): the static sag (the `load` stage, pre-stretch included) and the whole default
/// run (load and 1 s of actuation), solved through the library without writing output files;
/// the process's peak memory after each (the axisymmetric model runs first).
pub fn bench_axisymmetric() -> Result<Vec<String>, String> {
    let mut rows = Vec::new();
    for name in ["diaphragm", "diaphragm-3d"] {
        let (dofs, stages) = run_example(name, &[])?;
        let total: f64 = stages.iter().map(|s| s.1).sum();
        rows.push(format!(
            "{name:>17} {dofs:>6} {:>12.3} {total:>14.3} {:>9.0}",
            wall(&stages, "load").0,
            peak_memory_mib()
        ));
    }
    Ok(rows)
}

/// Column titles of [`bench_harmonics_row`]'s rows.
pub const HARMONICS_HEADER: &str =
    "                              model   dofs modes  load_s modes_s peak_MiB";

/// Modes per harmonic of the axisymmetric row of `deasim bench`'s harmonics table.
pub const HARMONICS_COUNT: usize = 3;
/// Modes of the 3-D disc that reach its lowest pair of harmonic 3.
pub const HARMONICS_TO_N3: usize = 28;

/// One row of the harmonics table: `row` 0, modes of harmonics 0–3 of the axisymmetric
/// diaphragm (`diaphragm-modes`, `count` of each); 1 and 2, the same actuator meshed in 3-D as a
/// full disc (no symmetry planes: every harmonic) with as many modes, and with `to_n3` modes
/// (enough to reach its lowest pair of n = 3); each after its `load` stage, with `sets` (e.g. the
/// mesh), solved through the library without output files: unknowns, modes, the wall times of
/// the `load` and `modes` stages and the process's peak memory (a row of its own process is
/// that row's: [`cmd_bench`] runs each so).
pub fn bench_harmonics_row(
    row: usize,
    count: usize,
    to_n3: usize,
    sets: &[String],
) -> Result<String, String> {
    use crate::io::examples::example;
    if row > 2 {
        return Err(format!("row {row}: expected 0, 1 or 2"));
    }
    let (what, text, extra, modes) = if row == 0 {
        let text = example("diaphragm-modes").ok_or("no example diaphragm-modes")?;
        (
            "axisymmetric, harmonics 0-3".to_string(),
            text.to_string(),
            vec![
                "stages.1.harmonic=[0, 1, 2, 3]".to_string(),
                format!("stages.1.count={count}"),
            ],
            4 * count,
        )
    } else {
        let modes = if row == 1 { 4 * count } else { to_n3 };
        let quarter = example("diaphragm-3d").ok_or("no example diaphragm-3d")?;
        let find = |what: &str| {
            quarter
                .find(what)
                .ok_or_else(|| format!("diaphragm-3d: no `{what}`"))
        };
        let (start, end) = (find("[[constraints]]")?, find("[prestretch]")?);
        let (stage, probes) = (find("[[stages]]\nname = \"actuate\"")?, find("[probes.")?);
        let full = format!(
            "{}{}[[stages]]\nname = \"modes\"\nkind = \"modes\"\n\n{}",
            &quarter[..start],
            &quarter[end..stage],
            &quarter[probes..]
        )
        .replace("quarter = true", "quarter = false");
        (
            format!("3-D full disc, {modes} modes"),
            full,
            vec![format!("stages.1.count={modes}")],
            modes,
        )
    };
    let mut all = sets.to_vec();
    all.extend(extra);
    let (dofs, stages) = run_text(&text, &what, &all)?;
    let (load, modes_s) = (wall(&stages, "load").0, wall(&stages, "modes").0);
    Ok(format!(
        "{what:>35} {dofs:>6} {modes:>5} {load:>7.3} {modes_s:>7.3} {:>8.0}",
        peak_memory_mib()
    ))
}

/// The harmonics table of [`cmd_bench`]: each row of [`bench_harmonics_row`] in its own process
/// (`deasim bench --harmonics-row N`), so that its peak memory is its own.
fn bench_harmonics() -> Result<Vec<String>, String> {
    rows_in_processes("--harmonics-row", 3)
}

/// Rows 0 to `count` − 1 of a table, each printed by `deasim bench FLAG N` in a process of its
/// own (so that the row's peak memory is its own).
fn rows_in_processes(flag: &str, count: usize) -> Result<Vec<String>, String> {
    let exe = std::env::current_exe().map_err(|e| format!("this program's path: {e}"))?;
    let mut rows = Vec::new();
    for row in 0..count {
        let out = std::process::Command::new(&exe)
            .args(["bench", flag, &row.to_string()])
            .stderr(std::process::Stdio::inherit())
            .output()
            .map_err(|e| format!("cannot start {}: {e}", exe.display()))?;
        if !out.status.success() {
            return Err(format!("row {row} failed (the message is above)"));
        }
        rows.push(String::from_utf8_lossy(&out.stdout).trim_end().to_string());
    }
    Ok(rows)
}

/// Column titles of [`bench_linear`]'s rows.
pub const LINEAR_HEADER: &str =
    "                        analysis  count   total_s   per_item_s peak_MiB";

/// The small-signal analyses of the diaphragm (`diaphragm-response` with `points` frequencies,
/// 2 kV bias) against the time-domain sweep they replace: the `modes` stage (4 modes), the
/// direct and the modal (20 modes) `frequency-response` stage, and one dynamic run of the
/// diaphragm with a small 30 Hz sinusoid about 2 kV, 10 periods of 40 steps, whose time per step
/// prices a sweep of `points` such runs (a lower bound: high frequencies need more periods for
/// their transients to decay). Returns the rows.
pub fn bench_linear(points: usize) -> Result<Vec<String>, String> {
    let mut rows = Vec::new();
    let row = |what: &str, count: usize, total: f64| {
        format!(
            "{what:>32} {count:>6} {total:>9.3} {:>12.5} {:>8.0}",
            total / count.max(1) as f64,
            peak_memory_mib()
        )
    };
    let (_, direct) = run_example("diaphragm-response", &[format!("stages.3.points={points}")])?;
    rows.push(row("modes stage (4 modes)", 4, wall(&direct, "modes").0));
    rows.push(row(
        "frequency response, direct",
        points,
        wall(&direct, "response").0,
    ));
    let (_, modal) = run_example(
        "diaphragm-response",
        &[
            format!("stages.3.points={points}"),
            "stages.3.method=\"modal\"".into(),
            "stages.3.count=20".into(),
        ],
    )?;
    rows.push(row(
        "frequency response, modal (20)",
        points,
        wall(&modal, "response").0,
    ));
    let f = 30.0;
    let (_, time_domain) = run_example(
        "diaphragm-3d",
        &[
            "electrodes.top.voltage.waveform=\"sine\"".into(),
            "electrodes.top.voltage.polarity=\"bipolar\"".into(),
            "electrodes.top.voltage.amplitude=10.0".into(),
            "electrodes.top.voltage.offset=2000.0".into(),
            format!("electrodes.top.voltage.frequency={f}"),
            format!("stages.1.duration={}", 10.0 / f),
            format!("stages.1.dt={}", 1.0 / (40.0 * f)),
        ],
    )?;
    let (t, steps) = wall(&time_domain, "actuate");
    rows.push(row("time domain, one frequency", steps, t));
    rows.push(format!(
        "{:>32} {points:>6} {:>9.1} {:>12.5}   (estimate: {points} runs of {steps} steps)",
        "time-domain sweep it replaces",
        t * points as f64,
        t
    ));
    Ok(rows)
}

/// Wall time (s) of the calibration of `tests/data/calibrate/hossain2012.toml`: a neo-Hookean
/// network and three Maxwell branches (7 parameters) fitted to the three loading–unloading cycles
/// of Hossain, Vu & Steinmann (2012) at once; with the overall RMS (Pa) and the iterations.
pub fn bench_calibration() -> Result<(f64, f64, usize), String> {
    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
    let data = dir.path().join("vhb4910-hossain2012");
    let cal = dir.path().join("calibrate");
    for d in [&data, &cal] {
        std::fs::create_dir_all(d).map_err(|e| e.to_string())?;
    }
    let files = [
        (
            "uniaxial-cycle-rate-0.01.csv",
            include_str!("../../tests/data/vhb4910-hossain2012/uniaxial-cycle-rate-0.01.csv"),
        ),
        (
            "uniaxial-cycle-rate-0.03.csv",
            include_str!("../../tests/data/vhb4910-hossain2012/uniaxial-cycle-rate-0.03.csv"),
        ),
        (
            "uniaxial-cycle-rate-0.05.csv",
            include_str!("../../tests/data/vhb4910-hossain2012/uniaxial-cycle-rate-0.05.csv"),
        ),
    ];
    for (name, text) in files {
        std::fs::write(data.join(name), text).map_err(|e| e.to_string())?;
    }
    let spec = cal.join("hossain2012.toml");
    std::fs::write(
        &spec,
        include_str!("../../tests/data/calibrate/hossain2012.toml"),
    )
    .map_err(|e| e.to_string())?;
    let t = Instant::now();
    let c =
        crate::calibrate::calibrate_file(&spec, &Default::default()).map_err(|e| e.to_string())?;
    Ok((t.elapsed().as_secs_f64(), c.rms, c.iterations))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mesh names parse only in the NXxNYxNZ form; the exponent of t ∝ n² is 2.
    #[test]
    fn calibration_row_fits_the_three_rates() {
        let (wall, rms, iterations) = bench_calibration().unwrap();
        assert!(wall > 0.0 && iterations > 0);
        // the preset it starts from is about 20 kPa off; the fit under 1 kPa
        assert!(rms < 1e3, "{rms}");
    }

    /// The gradient rows of the diaphragm and of the visco example (timed pre-stretch,
    /// Maxwell branches), shortened: each a row of six figures.
    #[test]
    fn gradient_rows() {
        let row = bench_gradient("diaphragm", &["stages.1.duration=0.02".into()]).unwrap();
        assert_eq!(row.split_whitespace().count(), 6, "{row}");
        assert!(row.trim_start().starts_with("diaphragm"), "{row}");
        let short = [
            "stages.1.duration=0.02".into(),
            "prestretch.hold=1.0".into(),
            "prestretch.hold_steps=2".into(),
        ];
        let row = bench_gradient("diaphragm-visco", &short).unwrap();
        assert_eq!(row.split_whitespace().count(), 6, "{row}");
        assert!(row.trim_start().starts_with("diaphragm-visco"), "{row}");
    }

    /// A control row: ten figures, J falling, with and without the response model.
    #[test]
    fn control_rows() {
        for (model, name) in [(true, "yes"), (false, "no")] {
            let row = bench_control(0.05, 3, model).unwrap();
            let cells: Vec<&str> = row.split_whitespace().collect();
            assert_eq!(cells.len(), 10, "{row}");
            assert_eq!(cells[2], name, "{row}");
            let (start, end): (f64, f64) = (cells[6].parse().unwrap(), cells[7].parse().unwrap());
            assert!(end < start, "{row}");
        }
    }

    #[test]
    fn scaling_helpers() {
        assert_eq!(parse_mesh("108x108x21"), Some([108, 108, 21]));
        assert_eq!(parse_mesh("10x10"), None);
        assert_eq!(parse_mesh("10x10x2x3"), None);
        assert_eq!(parse_mesh("10xax2"), None);
        assert!((scaling_exponent((1e5, 2.0), (1e6, 200.0)) - 2.0).abs() < 1e-12);
    }

    /// A scaling row runs the film and reports its work: Newton iterations, a factorisation per
    /// stability test (direct), no Krylov iterations; the iterative solver reports its iterations.
    #[test]
    fn scaling_rows_report_the_solver_work() {
        let direct = film_run([3, 3, 1], SolverKind::Direct, SCALING_STEPS, None).unwrap();
        assert!(direct.newton >= SCALING_STEPS, "{direct:?}");
        assert!(direct.stats.factorizations > SCALING_STEPS, "{direct:?}");
        assert_eq!(direct.stats.krylov_iterations, 0);
        let gmres = film_run([6, 6, 2], SolverKind::Iterative, SCALING_STEPS, None).unwrap();
        assert!(gmres.stats.krylov_iterations > 0, "{gmres:?}");
        assert!(gmres.solver.contains("FGMRES"), "{gmres:?}");
        let row = bench_scaling_row([3, 3, 1], SolverKind::Direct, None).unwrap();
        let fields: Vec<&str> = row.split_whitespace().collect();
        assert_eq!(fields[0], "3x3x1");
        assert_eq!(fields[1].parse::<usize>().unwrap(), direct.dofs);
    }

    /// The small-signal benchmark runs every analysis and prices the sweep from a measured run.
    #[test]
    fn linear_rows_cover_every_analysis() {
        let rows = bench_linear(3).unwrap();
        assert_eq!(rows.len(), 5, "{rows:?}");
        rows.iter().for_each(|r| println!("{r}"));
        for r in &rows {
            let total: f64 = r
                .split_whitespace()
                .rev()
                .nth(if r.contains("estimate") { 7 } else { 2 })
                .and_then(|v| v.parse().ok())
                .unwrap_or(f64::NAN);
            assert!(total.is_finite() && total > 0.0, "{r}");
        }
        assert!(rows[3].contains(" 400 "), "{}", rows[3]);
    }

    /// The harmonics rows: the axisymmetric model's 4 × count modes in far fewer unknowns than
    /// the full 3-D disc's, with times and memory.
    #[test]
    fn harmonic_rows() {
        let sets = ["mesh.radial=6".to_string()];
        let cells: Vec<Vec<f64>> = (0..3)
            .map(|row| {
                let r = bench_harmonics_row(row, 2, 10, &sets).unwrap();
                println!("{r}");
                // from the right: peak, modes_s, load_s, modes, dofs
                r.split_whitespace()
                    .rev()
                    .take(5)
                    .map(|v| v.parse().unwrap())
                    .collect()
            })
            .collect();
        assert_eq!((cells[0][3], cells[1][3], cells[2][3]), (8.0, 8.0, 10.0));
        assert!(cells[1][4] > 10.0 * cells[0][4], "{cells:?}");
        assert_eq!(cells[1][4], cells[2][4]);
        for c in &cells {
            assert!(c[0] > 0.0 && c[1] > 0.0 && c[2] > 0.0, "{cells:?}");
        }
    }

    /// The material benchmark runs for both presets and reports their point-state sizes.
    #[test]
    fn material_rows_name_the_state_size() {
        let elastic = bench_material([2, 2, 1], "vhb4910-ab-wang").unwrap();
        let visco = bench_material([2, 2, 1], "vhb4910-wang2016").unwrap();
        assert_eq!(elastic.split_whitespace().nth(1), Some("0"), "{elastic}");
        assert_eq!(visco.split_whitespace().nth(1), Some("27"), "{visco}");
        assert!(bench_material([2, 2, 1], "nope").is_err());
    }
}

/// Column titles of [`bench_speed_row`]'s rows.
pub const SPEED_HEADER: &str = "                case unknowns newton factors krylov resid_ns/qp tangent_ns/qp factor_s solve_ms   wall_s peak_MiB";

/// Rows of the speed table ([`bench_speed_row`]).
pub const SPEED_ROWS: usize = 3;

/// One row of the speed table, the cases the project measures its speed by: row 0,
/// `diaphragm-3d` (its whole run: the sag, then 1 s of actuation in 1000 midpoint steps); row 1,
/// the film 40 × 40 × 8 hex8 (the `film` example, 15 steps to 30 kV with a stability test at
/// every step); both through the library without output files. Each gives its free unknowns,
/// Newton iterations, factorisations and Krylov iterations over the run; the residual and the
/// residual with its tangent per quadrature point ([`assembly_per_point`]); one numeric LDLᵀ
/// factorisation of the tangent at the run's last state and one solve with it; the run's wall
/// time and the process's peak memory (a row of its own process is that row's: [`cmd_bench`]
/// runs each so). Row 2, the default `deasim run` with all its outputs, as a process of its
/// own: its wall time only.
pub fn bench_speed_row(row: usize) -> Result<String, String> {
    use crate::io::build::build;
    use crate::io::scenario::parse;
    if row == 2 {
        let exe = std::env::current_exe().map_err(|e| format!("this program's path: {e}"))?;
        let dir = tempfile::tempdir().map_err(|e| format!("a scratch directory: {e}"))?;
        let t = Instant::now();
        let out = std::process::Command::new(&exe)
            .args(["run", "--out"])
            .arg(dir.path().join("out"))
            .output()
            .map_err(|e| format!("cannot start {}: {e}", exe.display()))?;
        let wall = t.elapsed().as_secs_f64();
        if !out.status.success() {
            return Err(String::from_utf8_lossy(&out.stderr).into_owned());
        }
        return Ok(format!(
            "{:>20} {:>8} {:>6} {:>7} {:>6} {:>11} {:>13} {:>8} {:>8} {wall:>8.3} {:>8}",
            "deasim run", "", "", "", "", "", "", "", "", ""
        ));
    }
    let (name, sets): (&str, Vec<String>) = match row {
        0 => ("diaphragm-3d", Vec::new()),
        1 => ("film", vec!["mesh.divisions=[40, 40, 8]".into()]),
        _ => return Err(format!("no row {row} (0 to {})", SPEED_ROWS - 1)),
    };
    let text = crate::io::examples::example(name).ok_or_else(|| format!("no example {name}"))?;
    let t = Instant::now();
    let s = parse(text, name, &sets).map_err(|e| e.to_string())?;
    let plan = build(&s, name, None).map_err(|e| e.to_string())?;
    let mut last = LastState::default();
    let summary = crate::job::run::run(&plan, &mut last);
    let wall = t.elapsed().as_secs_f64();
    if !summary.converged {
        return Err(summary.error.unwrap_or_default());
    }
    let newton: usize = summary.stages.iter().map(|s| s.newton_iterations).sum();
    let linear = summary
        .stages
        .iter()
        .fold(crate::solve::linear::SolverStats::default(), |a, s| {
            a + s.linear
        });
    let model = supported(&plan);
    let (residual, tangent) = assembly_per_point(&model, &last.0)?;
    // a factorisation and a solve of the tangent at the run's last state
    let mut p = StaticProblem::new(&model, Some(last.0.clone()));
    let n = p.n();
    let mut k = p.new_matrix();
    let mut r = vec![0.0; n];
    p.evaluate(&mut r, Some(&mut k))?;
    let mut solver = SolverSettings {
        kind: SolverKind::Direct,
        ordering: Ordering::NestedDissection,
        ..Default::default()
    }
    .build();
    // the first factorisation orders; the second is numeric only
    solver.factor(&k).map_err(|e| e.to_string())?;
    let t = Instant::now();
    solver.factor(&k).map_err(|e| e.to_string())?;
    let factor = t.elapsed().as_secs_f64();
    let mut dx: Vec<f64> = r.iter().map(|v| -v).collect();
    let t = Instant::now();
    solver.solve_in_place(&mut dx).map_err(|e| e.to_string())?;
    let solve = t.elapsed().as_secs_f64();
    let case = if row == 1 { "film 40x40x8" } else { name };
    Ok(format!(
        "{case:>20} {n:>8} {newton:>6} {:>7} {:>6} {:>11.1} {:>13.1} {factor:>8.3} {:>8.3} {wall:>8.3} {:>8.0}",
        linear.factorizations,
        linear.krylov_iterations,
        residual * 1e9,
        tangent * 1e9,
        solve * 1e3,
        peak_memory_mib()
    ))
}

/// The plan's model with its supports, and its electrodes held (at 0 V; a drive holds them in a
/// run): a static problem whose tangent is regular.
fn supported(plan: &crate::job::plan::Plan) -> crate::problem::model::Model {
    let mut model = plan.model.clone();
    model.dirichlet = plan.supports.clone();
    for e in &plan.electrodes {
        model.dirichlet.push(crate::problem::dofs::Dirichlet {
            nodes: e.nodes.clone(),
            field: crate::problem::dofs::Field::Phi,
            value: 0.0,
        });
    }
    model
}

/// Seconds per quadrature point of the static residual, and of the residual with its tangent,
/// of `model` at `state`: the best of [`REPEATS`] evaluations on the thread pool, over the
/// model's quadrature points.
pub fn assembly_per_point(
    model: &crate::problem::model::Model,
    state: &[f64],
) -> Result<(f64, f64), String> {
    let mut points = 0usize;
    model.for_each_cell(state, |_, g, _, _| {
        points += g.n_qp;
        Ok::<(), String>(())
    })?;
    let mut p = StaticProblem::new(model, Some(state.to_vec()));
    let mut k = p.new_matrix();
    let mut r = vec![0.0; p.n()];
    let (mut residual, mut tangent) = (f64::INFINITY, f64::INFINITY);
    // each in a loop of its own: the residuals one after the other, as a time step's Newton
    // iterations make them, without a tangent assembly (on other threads) between them
    for _ in 0..REPEATS {
        let t = Instant::now();
        p.evaluate(&mut r, None)?;
        residual = residual.min(t.elapsed().as_secs_f64());
    }
    for _ in 0..REPEATS {
        let t = Instant::now();
        p.evaluate(&mut r, Some(&mut k))?;
        tangent = tangent.min(t.elapsed().as_secs_f64());
    }
    let per = 1.0 / points.max(1) as f64;
    Ok((residual * per, tangent * per))
}

/// An observer that keeps the last state of a run.
#[derive(Default)]
struct LastState(Vec<f64>);

impl crate::job::observer::Observer for LastState {
    fn step(
        &mut self,
        _: &crate::job::plan::Plan,
        _: &crate::job::run::StepRecord,
        state: &[f64],
        _: &[crate::element::CellFields],
    ) {
        self.0.clear();
        self.0.extend_from_slice(state);
    }
    fn finished(&mut self, _: &crate::job::plan::Plan, _: &crate::job::state::RunSummary) {}
}

/// The speed table: each row of [`bench_speed_row`] in its own process
/// (`deasim bench --speed-row N`), so that its peak memory is its own.
pub fn bench_speed() -> Result<Vec<String>, String> {
    rows_in_processes("--speed-row", SPEED_ROWS)
}

/// `deasim bench --speed`: the speed table alone.
pub fn cmd_bench_speed() -> i32 {
    println!(
        "speed: the cases of docs/validation.md's \"Speed and memory at a glance\", {} threads, \
         each in its own process; times in s",
        rayon::current_num_threads()
    );
    println!("{SPEED_HEADER}");
    match bench_speed() {
        Ok(rows) => {
            rows.iter().for_each(|r| println!("{r}"));
            0
        }
        Err(e) => {
            eprintln!("error: speed table: {e}");
            1
        }
    }
}
