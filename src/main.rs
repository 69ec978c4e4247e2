//! The `deasim` command line: argument parsing only; the commands live in `deasim::cli::app`.

use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "deasim",
    version,
    about = "Finite-strain electro-mechanical simulation of dielectric elastomer actuators"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scenario (the embedded default when no file is given).
    #[command(
        after_help = "Exit status: 0 success; 1 the solve failed (the reason is in summary.json) \
or an output could not be written; 2 bad input; 130 stopped by Ctrl-C/SIGTERM (the outputs hold \
the last accepted step).\n\nEnvironment: RAYON_NUM_THREADS (threads), DEASIM_NEWTON_VERBOSE=1 \
(every Newton iteration on stderr)."
    )]
    Run {
        /// Scenario file (TOML), the name of an embedded example, or - for standard input.
        scenario: Option<PathBuf>,
        /// Output directory (default ./deasim-out/<scenario name>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override a value by its dotted path, e.g. --set stages.0.steps=20 (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Replace the results of a different scenario found in the output directory.
        #[arg(long)]
        overwrite: bool,
        /// Write a restart file into OUT/checkpoint/ every N accepted steps (and on SIGINT/SIGTERM).
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
        checkpoint_every: Option<u64>,
        /// Continue the run whose checkpoints are in DIR (its output directory).
        #[arg(long, value_name = "DIR", conflicts_with_all = ["out", "overwrite"])]
        resume: Option<PathBuf>,
    },
    /// Validate a scenario; print its mesh, extents, materials (with the resolved parameters of
    /// presets), stages and probes, and estimate the run time and disk use from a trial of the
    /// first steps.
    #[command(
        after_help = "Exit status: 0 valid; 2 invalid (every problem is listed with the file and key)."
    )]
    Check {
        /// Scenario file (TOML), the name of an embedded example, or - for standard input.
        scenario: PathBuf,
        /// Override a value by its dotted path before checking (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Skip the trial of the first steps that estimates the run's time and disk use.
        #[arg(long)]
        no_trial: bool,
    },
    /// The gradient of the scenario's [[objective]] in its [[parameters]] by the discrete
    /// adjoint of the run; writes OUT/gradient.json beside the run's files.
    #[command(
        after_help = "Exit status: 0 success; 1 the forward run failed; 2 bad input, or a stage, \
material, parameter or objective term whose adjoint is not built yet (the message names it)."
    )]
    Gradient {
        /// Scenario file (TOML), the name of an embedded example, or - for standard input.
        scenario: Option<PathBuf>,
        /// Output directory (default ./deasim-out/<scenario name>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override a value by its dotted path (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Replace the results of a different scenario found in the output directory.
        #[arg(long)]
        overwrite: bool,
        /// Also compare each derivative with a central finite difference (h = 1e-4·|p|) and run
        /// a Taylor remainder test (its order must be about 2).
        #[arg(long)]
        check: bool,
        /// The finite differences' step relative to each value (default 1e-4).
        #[arg(long, value_name = "H")]
        fd_step: Option<f64>,
        /// The memory budget of the taped states, e.g. "256 MiB" or bytes (as the scenario's
        /// `gradient.memory`, which it overrides; default 1 GiB): beyond it the dynamic stages
        /// are recomputed from checkpoints.
        #[arg(long, value_name = "SIZE")]
        memory: Option<String>,
    },
    /// The drive of the scenario's [[controls]] that minimises its [[objective]] (a projected
    /// quasi-Newton method with adjoint gradients); writes OUT/control.json, control.csv,
    /// controlled.toml and the optimised run's files.
    #[command(
        after_help = "Exit status: 0 success (control.json says whether the optimisation \
converged); 1 the run at the starting drive failed; 2 bad input (bounds that exclude the starting \
drive, a term or stage whose adjoint is not built)."
    )]
    Control {
        /// Scenario file (TOML), the name of an embedded example, or - for standard input.
        scenario: Option<PathBuf>,
        /// Output directory (default ./deasim-out/<scenario name>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override a value by its dotted path (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Replace the results of a different scenario found in the output directory.
        #[arg(long)]
        overwrite: bool,
        /// Iterations at most.
        #[arg(long, default_value_t = 200)]
        max_iterations: usize,
        /// Converged when the projected gradient has fallen by this factor from the start.
        #[arg(long, default_value_t = 1e-6)]
        gradient_tolerance: f64,
        /// Converged when an iteration lowers the objective by less than this share of it.
        #[arg(long, default_value_t = 1e-10)]
        objective_tolerance: f64,
        /// Start the quasi-Newton recursion from a scalar, without the measured response model.
        #[arg(long)]
        no_model: bool,
    },
    /// List the embedded examples, or print one as TOML.
    Example {
        /// The example to print (omit it for the list).
        name: Option<String>,
    },
    /// The lumped (one-degree-of-freedom) model of a diaphragm scenario: seconds instead of minutes.
    Lumped {
        /// Scenario file (TOML), an embedded example's name or - for standard input; the
        /// embedded default when omitted.
        scenario: Option<PathBuf>,
        /// Output directory (default ./deasim-out/<scenario name>-lumped/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace the results of another command or scenario found in the output directory.
        #[arg(long)]
        overwrite: bool,
        /// Override a value by its dotted path (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Output directory of a finite element run of the same scenario to overlay and compare.
        #[arg(long, value_name = "DIR")]
        compare: Option<PathBuf>,
    },
    /// Run a scenario for every value of one parameter; tabulate and plot every probe's final
    /// value, maximum and steady peak-to-peak against it.
    Sweep {
        /// Scenario file (TOML), an embedded example's name or - for standard input; the
        /// embedded default when omitted.
        scenario: Option<PathBuf>,
        /// The swept parameter: PATH=START:STOP:N (N values) or PATH=v1,v2,...; repeat it for
        /// parameters that move along with the first (same N), e.g. a time step.
        #[arg(long = "set-range", value_name = "PATH=START:STOP:N", required = true)]
        set_range: Vec<String>,
        /// Geometric spacing of START:STOP:N (e.g. frequencies).
        #[arg(long)]
        log: bool,
        /// Output directory (default ./deasim-out/<scenario name>-sweep/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace the results of another command or scenario found in the output directory.
        #[arg(long)]
        overwrite: bool,
        /// Override a value for every run (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Runs at a time (default: the cores, as memory allows).
        #[arg(long)]
        jobs: Option<usize>,
    },
    /// Fit a material's parameters (hyperelastic base, Maxwell branches) to measured homogeneous
    /// test curves: bounded least squares with exact Jacobians, standard errors, 95 % intervals
    /// and correlations; calibration.json, fitted.toml and plots (docs/calibration.md).
    Calibrate {
        /// The calibration spec (TOML): [material], [[parameters]], [[experiments]], [fit].
        spec: PathBuf,
        /// Output directory (default ./deasim-out/calibrate-<spec name>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace the results of another command or scenario found in the output directory.
        #[arg(long)]
        overwrite: bool,
        /// Number of starts (replaces the spec's `fit.starts`; a device scenario's fit starts
        /// from its values, then from points spread over the parameters' bounds).
        #[arg(long)]
        starts: Option<usize>,
        /// Override a key of the spec or scenario (repeatable), e.g. `--set material.mu=2e4`,
        /// `--set stages.1.duration=0.02`.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
    /// The material models with their parameters, and the presets; with a name, that preset's
    /// resolved parameters (the values a scenario's `preset = NAME` uses).
    Materials {
        /// A preset or a model name.
        name: Option<String>,
    },
    /// Homogeneous material-point tests of a preset or a scenario's material (same material
    /// code as a run): ramps at stretch rates, load–unload cycles, relaxation, creep; CSV and plots.
    Material {
        /// A preset name (e.g. vhb4910-wang2016) or a scenario file holding the material.
        material: String,
        /// The material's name in a scenario file (default: its first material).
        #[arg(long)]
        name: Option<String>,
        /// uniaxial | equibiaxial | pure-shear (ramps to --stretch at each --rate), cyclic
        /// (load–unload between 1 and --stretch), relaxation (to --stretch in --ramp-time, held
        /// --hold s) or creep (to --stress in --ramp-time, held --hold s).
        #[arg(long, default_value = "uniaxial")]
        test: String,
        /// Deformation of cyclic, relaxation and creep tests: uniaxial | equibiaxial | pure-shear.
        #[arg(long, default_value = "uniaxial")]
        mode: String,
        /// Largest or held stretch.
        #[arg(long, default_value_t = 2.5)]
        stretch: f64,
        /// Stretch rates dλ/dt in 1/s, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "0.01,0.03,0.05")]
        rate: Vec<f64>,
        /// Held nominal stress of a creep test, Pa.
        #[arg(long)]
        stress: Option<f64>,
        /// Time to reach the stretch or stress of relaxation and creep tests, s.
        #[arg(long, default_value_t = 0.1)]
        ramp_time: f64,
        /// Hold time of relaxation and creep tests, s.
        #[arg(long, default_value_t = 60.0)]
        hold: f64,
        /// Load–unload cycles of the cyclic test.
        #[arg(long, default_value_t = 1)]
        cycles: usize,
        /// Time steps per segment (ramp, hold, half cycle).
        #[arg(long, default_value_t = 200)]
        steps: usize,
        /// Output directory (default ./deasim-out/material-<name>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace the results of another command or scenario found in the output directory.
        #[arg(long)]
        overwrite: bool,
    },
    /// Natural modes about the loaded state (after the static stages before the first dynamic
    /// one, electrodes held at their voltages there): a table, modes.csv and ParaView shapes.
    Modes {
        /// Scenario file (TOML), an embedded example's name or - for standard input; the
        /// embedded default when omitted.
        scenario: Option<PathBuf>,
        /// Number of modes.
        #[arg(long, default_value_t = 6)]
        count: usize,
        /// The modes nearest to this frequency (Hz); 0 gives the lowest.
        #[arg(long, default_value_t = 0.0)]
        shift: f64,
        /// Circumferential harmonic n of an axisymmetric model (0: the axisymmetric modes), or
        /// a list (1,2,3): `count` modes of each.
        #[arg(long, value_delimiter = ',', default_value = "0")]
        harmonic: Vec<u32>,
        /// Output directory (default ./deasim-out/<scenario name>-modes/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace the results of another command or scenario found in the output directory.
        #[arg(long)]
        overwrite: bool,
        /// Override a value by its dotted path (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
    /// Frequency response of the probes to a small harmonic voltage on one electrode about its
    /// DC bias (after the static stages before the first dynamic one): CSV and Bode plots.
    Response {
        /// Scenario file (TOML), an embedded example's name or - for standard input; the
        /// embedded default when omitted.
        scenario: Option<PathBuf>,
        /// The driven electrode (default: the first with a non-zero voltage).
        #[arg(long)]
        electrode: Option<String>,
        /// DC voltage of the driven electrode, V (default: its voltage after the static stages).
        #[arg(long)]
        bias: Option<f64>,
        /// Frequencies in Hz, comma-separated (else --from/--to/--points, log-spaced).
        #[arg(long, value_delimiter = ',')]
        frequencies: Vec<f64>,
        /// Lowest frequency of the log range, Hz.
        #[arg(long, default_value_t = 1.0)]
        from: f64,
        /// Highest frequency of the log range, Hz.
        #[arg(long, default_value_t = 1e4)]
        to: f64,
        /// Frequencies of the log range.
        #[arg(long, default_value_t = 200)]
        points: usize,
        /// Output directory (default ./deasim-out/<scenario name>-response/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace the results of another command or scenario found in the output directory.
        #[arg(long)]
        overwrite: bool,
        /// Override a value by its dotted path (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
    /// A reduced state-space model (A, B, C, D) of the first modes with a static correction about
    /// a DC bias, for control: JSON and CSV matrices, its simulation of the first dynamic stage's
    /// drive, and the overlay on a finite element run.
    Reduce {
        /// Scenario file (TOML), an embedded example's name or - for standard input; the
        /// embedded default when omitted.
        scenario: Option<PathBuf>,
        /// Modes kept (the model has twice as many states).
        #[arg(long, default_value_t = 4)]
        modes: usize,
        /// The driven electrode (default: the first with a non-zero voltage).
        #[arg(long)]
        electrode: Option<String>,
        /// DC voltage of the driven electrode, V (default: its voltage after the static stages).
        #[arg(long)]
        bias: Option<f64>,
        /// Output directory of a finite element run of the scenario to overlay.
        #[arg(long, value_name = "DIR")]
        compare: Option<PathBuf>,
        /// Design a sampled LQR state feedback with a Kalman observer (lqr.json, for
        /// `kind = "state-feedback"`): Q weighs the tracked output's change in volts of static
        /// drive, R the drive's volts (docs/control.md).
        #[arg(long, value_name = "Q,R")]
        lqr: Option<String>,
        /// The observer's variances: W of a voltage disturbance on the drive, V of each measured
        /// output's noise in volts of static drive (V²); default 1,1e-2.
        #[arg(long, value_name = "W,V")]
        kalman: Option<String>,
        /// Integral action: the weight q_I of the integrated tracking error (1/s², 0: none);
        /// q_I/Q is the square of the integrator's corner frequency in rad/s.
        #[arg(long, value_name = "Q_I")]
        integral: Option<f64>,
        /// The design's sample period, s (default: the first dynamic stage's time step).
        #[arg(long)]
        sample_time: Option<f64>,
        /// The output the state feedback tracks (a probe; needed with --lqr).
        #[arg(long, value_name = "PROBE")]
        track: Option<String>,
        /// The outputs the observer measures (default: the tracked one).
        #[arg(long, value_name = "PROBE", value_delimiter = ',')]
        measure: Vec<String>,
        /// Output directory (default ./deasim-out/<scenario name>-reduced/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace the results of another command or scenario found in the output directory.
        #[arg(long)]
        overwrite: bool,
        /// Override a value by its dotted path (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
    /// Run the verification manual: every family against closed forms and published values,
    /// printed as one table (docs/validation.md).
    Validate {
        /// Only this family (materials, cook, film, dynamics, viscoelasticity, axisymmetric,
        /// small-signal).
        #[arg(long)]
        family: Option<String>,
    },
    /// Run the benchmark scenarios and print timings and memory.
    Bench {
        /// Also run the ~400k-dof mesh (minutes, several GB).
        #[arg(long)]
        large: bool,
        /// Instead, the scaling table: the film from 1.5·10⁴ to 10⁶ unknowns, time per Newton
        /// iteration, Krylov iterations, peak memory, and the scaling exponent.
        #[arg(long)]
        scaling: bool,
        /// The linear solver of the scaling table (auto, direct, iterative).
        #[arg(long, default_value = "auto")]
        solver: String,
        /// Only meshes of at most this many unknowns in the scaling table.
        #[arg(long, default_value_t = 1_100_000)]
        max_dofs: usize,
        /// The largest factor (bytes) a direct solver may hold in the scaling table (default: 80 %
        /// of the memory available); `auto` switches to `iterative` above it.
        #[arg(long)]
        memory_limit: Option<usize>,
        /// Seconds after which one mesh of the scaling table is stopped.
        #[arg(long, default_value_t = 1800.0)]
        timeout: f64,
        /// One row of the scaling table (NXxNYxNZ), in this process.
        #[arg(long, hide = true)]
        scaling_row: Option<String>,
        /// One row (0, 1, 2) of the harmonics table, in this process.
        #[arg(long, hide = true)]
        harmonics_row: Option<usize>,
        /// Instead, the speed table alone: `diaphragm-3d`, the film 40 × 40 × 8 and the default
        /// run, with Newton iterations, factorisations, Krylov iterations, the assembly per
        /// quadrature point, a factorisation, a solve, wall time and peak memory.
        #[arg(long)]
        speed: bool,
        /// One row (0, 1, 2) of the speed table, in this process.
        #[arg(long, hide = true)]
        speed_row: Option<usize>,
        /// Instead, the gradient and optimal-control tables alone.
        #[arg(long)]
        adjoint: bool,
    },
}

fn main() {
    // a closed pipe (`deasim example diaphragm | head`) ends the process quietly, as it does for
    // other Unix tools, instead of making the next `println!` panic
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    deasim::cli::stderr_log::install();
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() {
                deasim::cli::app::EXIT_BAD_INPUT
            } else {
                0
            };
            let _ = e.print();
            std::process::exit(code);
        }
    };
    // under an MPI launcher only `run` shares its work between the processes
    if !matches!(cli.command, Command::Run { .. }) {
        let command = std::env::args().nth(1).unwrap_or_default();
        if let Some(code) = deasim::cli::app::refuse_under_mpi(&command) {
            std::process::exit(code);
        }
    }
    let code = match cli.command {
        Command::Run {
            scenario,
            out,
            set,
            overwrite,
            checkpoint_every,
            resume,
        } => {
            let every = checkpoint_every.map(|n| usize::try_from(n).unwrap_or(usize::MAX));
            match resume {
                Some(dir) => deasim::cli::app::cmd_resume(&dir, scenario.as_deref(), &set, every),
                None => deasim::cli::app::cmd_run(
                    scenario.as_deref(),
                    out.as_deref(),
                    &set,
                    overwrite,
                    every,
                ),
            }
        }
        Command::Check {
            scenario,
            set,
            no_trial,
        } => deasim::cli::app::cmd_check(&scenario, &set, !no_trial),
        Command::Gradient {
            scenario,
            out,
            set,
            overwrite,
            check,
            fd_step,
            memory,
        } => {
            let mut set = set;
            if let Some(m) = memory {
                set.push(format!("gradient.memory=\"{}\"", m.replace('"', "")));
            }
            deasim::cli::gradient::cmd_gradient(
                scenario.as_deref(),
                out.as_deref(),
                &set,
                overwrite,
                check.then_some(fd_step),
            )
        }
        Command::Control {
            scenario,
            out,
            set,
            overwrite,
            max_iterations,
            gradient_tolerance,
            objective_tolerance,
            no_model,
        } => deasim::cli::control::cmd_control(
            scenario.as_deref(),
            out.as_deref(),
            &set,
            overwrite,
            deasim::api::ControlOptions {
                max_iterations,
                gradient_tolerance,
                objective_tolerance,
                response_model: !no_model,
                ..Default::default()
            },
        ),
        Command::Example { name } => deasim::cli::app::cmd_example(name.as_deref()),
        Command::Lumped {
            scenario,
            out,
            overwrite,
            set,
            compare,
        } => deasim::cli::lumped::cmd_lumped(
            scenario.as_deref(),
            out.as_deref(),
            &set,
            compare.as_deref(),
            overwrite,
        ),
        Command::Sweep {
            scenario,
            set_range,
            log,
            out,
            overwrite,
            set,
            jobs,
        } => deasim::cli::sweep::cmd_sweep(
            scenario.as_deref(),
            out.as_deref(),
            &set,
            &set_range,
            log,
            jobs,
            overwrite,
        ),
        Command::Calibrate {
            spec,
            out,
            overwrite,
            starts,
            set,
        } => deasim::cli::calibrate::cmd_calibrate(&deasim::cli::calibrate::CalibrateArgs {
            spec,
            out,
            overwrite,
            starts,
            set,
        }),
        Command::Materials { name } => deasim::cli::material::cmd_materials(name.as_deref()),
        Command::Material {
            material,
            name,
            test,
            mode,
            stretch,
            rate,
            stress,
            ramp_time,
            hold,
            cycles,
            steps,
            out,
            overwrite,
        } => deasim::cli::material::cmd_material(&deasim::cli::material::MaterialTest {
            material,
            name,
            test,
            mode,
            stretch,
            rates: rate,
            stress,
            ramp_time,
            hold,
            cycles,
            steps,
            out,
            overwrite,
        }),
        Command::Modes {
            scenario,
            count,
            shift,
            harmonic,
            out,
            overwrite,
            set,
        } => deasim::cli::modes::cmd_modes(
            scenario.as_deref(),
            out.as_deref(),
            &set,
            count,
            shift,
            &harmonic,
            overwrite,
        ),
        Command::Response {
            scenario,
            electrode,
            bias,
            frequencies,
            from,
            to,
            points,
            out,
            overwrite,
            set,
        } => deasim::cli::response::cmd_response(&deasim::cli::response::ResponseArgs {
            scenario,
            overrides: set,
            electrode,
            bias,
            frequencies,
            from,
            to,
            points,
            out,
            overwrite,
        }),
        Command::Reduce {
            scenario,
            modes,
            electrode,
            bias,
            compare,
            lqr,
            kalman,
            integral,
            sample_time,
            track,
            measure,
            out,
            overwrite,
            set,
        } => deasim::cli::response::cmd_reduce(&deasim::cli::response::ReduceArgs {
            scenario,
            overrides: set,
            electrode,
            bias,
            modes,
            compare,
            out,
            overwrite,
            lqr,
            kalman,
            integral,
            sample_time,
            track,
            measure,
        }),
        Command::Validate { family } => deasim::cli::validate::cmd_validate(family.as_deref()),
        Command::Bench {
            large,
            scaling,
            solver,
            max_dofs,
            memory_limit,
            timeout,
            scaling_row,
            harmonics_row,
            speed,
            speed_row,
            adjoint,
        } => {
            use deasim::cli::bench;
            use deasim::solve::linear::SolverKind;
            if let Some(row) = speed_row {
                std::process::exit(match bench::bench_speed_row(row) {
                    Ok(row) => {
                        println!("{row}");
                        0
                    }
                    Err(e) => {
                        eprintln!("error: --speed-row: {e}");
                        1
                    }
                });
            }
            if speed {
                std::process::exit(bench::cmd_bench_speed());
            }
            if adjoint {
                std::process::exit(bench::cmd_bench_adjoint());
            }
            if let Some(row) = harmonics_row {
                let row = bench::bench_harmonics_row(
                    row,
                    bench::HARMONICS_COUNT,
                    bench::HARMONICS_TO_N3,
                    &[],
                );
                std::process::exit(match row {
                    Ok(row) => {
                        println!("{row}");
                        0
                    }
                    Err(e) => {
                        eprintln!("error: --harmonics-row: {e}");
                        1
                    }
                });
            }
            match (SolverKind::from_name(&solver), scaling_row) {
                (None, _) => {
                    eprintln!(
                        "error: --solver: expected one of {}, found `{solver}`",
                        SolverKind::NAMES.join(", ")
                    );
                    2
                }
                (Some(kind), Some(mesh)) => match bench::parse_mesh(&mesh) {
                    None => {
                        eprintln!("error: --scaling-row: expected NXxNYxNZ, found `{mesh}`");
                        2
                    }
                    Some(div) => match bench::bench_scaling_row(div, kind, memory_limit) {
                        Ok(row) => {
                            println!("{row}");
                            0
                        }
                        Err(e) => {
                            eprintln!("error: {mesh}: {e}");
                            1
                        }
                    },
                },
                (Some(kind), None) if scaling => {
                    bench::cmd_bench_scaling(kind, max_dofs, memory_limit, timeout)
                }
                (Some(_), None) => bench::cmd_bench(large),
            }
        }
    };
    std::process::exit(code);
}
