//! The film solved with each MPI rank holding only its own part: its cells, the nodes they
//! touch and the vectors of its own unknowns (owned and ghosts), through Newton and PETSc.
//!
//! ```sh
//! cargo bench --features petsc --bench distributed --no-run
//! mpirun -np 2 target/release/deps/distributed-<hash> 52x52x10
//! ```
//!
//! The problem is that of `scripts/bench-mpi.sh` with `STEPS=1 FORCING=fixed
//! PRECONDITIONER=renewed`: the film's 5 × 5 × 1 mm quarter in NX × NY × NZ hex8 cells, one
//! load step to 30 kV, GMRES with GAMG (rtol 1e-8, restart 100, the rigid-body modes), so that
//! the two can be compared. Unlike `deasim run`, nothing but the solve: no outputs, and the
//! whole mesh is built on every rank (its partition, its node owners and the whole problem's
//! numbering are computed from it), but no whole model, geometry, state or vector. Each rank
//! prints its unknowns, the Newton and Krylov iterations, the time per Newton iteration and
//! its peak resident memory (`VmHWM`).

#[cfg(feature = "petsc")]
fn main() {
    use deasim::algebra::exchange::LocalEquations;
    use deasim::algebra::system::NonlinearSystem;
    use deasim::material::EPSILON_0;
    use deasim::mesh::distribute::{LocalMesh, Numbering};
    use deasim::mesh::generate::box_mesh;
    use deasim::mesh::partition::partition_cells;
    use deasim::mesh::ElementKind;
    use deasim::problem::assembly::node_processes;
    use deasim::problem::distributed::{equation_owners, OwnedSystem};
    use deasim::problem::dofs::{constrained_flags, Dirichlet, DofMap, Field, FIELDS};
    use deasim::problem::examples::{film_on, FILM_EPS_R, FILM_MU};
    use deasim::problem::statics::StaticProblem;
    use deasim::solve::linear::LinearSolver;
    use deasim::solve::newton::NewtonSettings;
    use deasim::solve::petsc::{world, PetscExchange, PetscSolver};
    use deasim::solve::stepping::{ramp, StepControl};
    use std::sync::Arc;
    use std::time::Instant;

    let divisions = std::env::args()
        .nth(1)
        .and_then(|a| {
            let v: Vec<usize> = a.split('x').filter_map(|p| p.parse().ok()).collect();
            (v.len() == 3).then(|| [v[0], v[1], v[2]])
        })
        .unwrap_or([52, 52, 10]);
    let voltage = 30e3;
    let (rank, ranks) = world().expect("PETSc and MPI");
    let start = Instant::now();
    let mesh = box_mesh([5e-3, 5e-3, 1e-3], divisions, ElementKind::Hex8);
    // the whole problem's numbering from the film's conditions on the whole mesh
    let set = |name: &str| mesh.set_nodes(name).expect("a film set");
    let conditions = [
        ("x0", Field::Ux),
        ("y0", Field::Uy),
        ("z0", Field::Uz),
        ("z0", Field::Phi),
        ("z1", Field::Phi),
    ]
    .map(|(name, field)| Dirichlet {
        nodes: set(name),
        field,
        value: 0.0,
    });
    let flags = constrained_flags(mesh.n_nodes(), &conditions);
    let scale = (FILM_MU / (FILM_EPS_R * EPSILON_0)).sqrt();
    let dofs = DofMap::new(mesh.n_nodes(), &flags, scale);
    drop(flags);
    let part = partition_cells(&mesh, ranks, None);
    let node_owner = node_processes(&mesh, &dofs, &part, ranks);
    let numbering = Numbering::contiguous(&equation_owners(&dofs, &node_owner), ranks);
    let local = LocalMesh::of_rank(&mesh, &part, &node_owner, rank, ranks).expect("a part");
    let model = film_on(local.mesh.clone(), voltage).expect("the film's part");
    let problem = StaticProblem::new(&model, None);
    let equations = Arc::new(
        LocalEquations::new(&dofs, &numbering, &local, &problem.dofs).expect("its equations"),
    );
    let n_global = dofs.n_free;
    drop((mesh, part, node_owner, numbering, dofs));
    let exchange = Arc::new(PetscExchange::new(&equations).expect("the exchange"));
    // the residual floor: the ranks' floors averaged (the same bits on every rank)
    let mut floor = [problem.residual_floor() / ranks as f64];
    deasim::solve::petsc::sum_over_ranks(&mut floor).expect("a sum");
    let mut system =
        OwnedSystem::new(problem, Arc::clone(&equations), exchange, floor[0]).expect("a system");
    let set_up = start.elapsed().as_secs_f64();
    let mut solver = PetscSolver::new(
        "-ksp_type gmres -pc_type gamg -ksp_rtol 1e-8 -ksp_atol 0 -ksp_gmres_restart 100",
    );
    let settings = NewtonSettings::default();
    let control = StepControl {
        steps: 1,
        ..StepControl::default()
    };
    let solve = Instant::now();
    let report = ramp(&mut system, &mut solver, &settings, &control, |_, _| {});
    let seconds = solve.elapsed().as_secs_f64();
    let newton = match &report {
        Ok(r) => r.newton_iterations,
        Err(f) => {
            eprintln!("rank {rank}: the ramp failed: {f}");
            f.newton_iterations
        }
    };
    let peak = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kib| kib / 1024.0);
    let uz = (0..model.mesh.n_nodes())
        .map(|n| system.local.state[n * FIELDS + 2])
        .fold(0.0_f64, f64::min);
    println!(
        "rank {rank}/{ranks}: {divisions:?} cells, {} of {n_global} unknowns owned, {} ghosts; \
         set-up {set_up:.2} s; {newton} Newton, {} Krylov iterations, {seconds:.2} s, \
         {:.2} s per Newton iteration; peak {peak:.0} MiB; least u_z {uz:.6e} m",
        equations.n_owned(),
        equations.global.len() - equations.n_owned(),
        solver.stats().krylov_iterations,
        seconds / newton.max(1) as f64,
    );
}

#[cfg(not(feature = "petsc"))]
fn main() {
    eprintln!("this benchmark needs `--features petsc` and runs under mpirun");
}
