//! Natural modes of a pre-stretched rectangular membrane clamped on its edges (`time::modal`;
//! the model is `examples::membrane`, the solve and the filter of flexural modes
//! `validate::small_signal`, shared with `deasim validate`).
//!
//! Reference: a membrane of tension T (N/m) and mass per area ρ_A vibrates out of plane at
//! f_mn = ½ √(T/ρ_A) √(m²/L² + n²/W²) (L, W the stretched sides). A square film of neo-Hooke
//! (μ = 100 kPa, κ ≈ 100 μ, ρ₀ = 1000 kg/m³), 10 × 10 × 0.1 mm, is stretched equibiaxially by
//! λ = 1.5 with its side faces held; T/ρ_A = σ₁₁ h/(ρ₀h₀/λ²) from the homogeneous equibiaxial state
//! (thickness free). The plate's bending stiffness adds (D k²/T ≈ 1e-4 here); hex8 cells that are
//! thin and wide over-stiffen bending, so the lowest flexural frequency converges from above as
//! the cells shrink in plane (measured +1.52 % on 8 × 8, +0.70 % on 16 × 16 cells). The side
//! faces are held in plane at the stretched position and out of plane along their bottom edge,
//! so that the homogeneous state (the film thinning freely) is exact. With a voltage V on full electrodes the Maxwell stress takes εE²h
//! from the tension (E the true field in the thinned film, from the homogeneous coupled state):
//! the frequencies fall as √(T(V)/T(0)).

mod common;
use deasim::cli::validate::small_signal::{flexural, homogeneous};
use deasim::problem::examples::{MEMBRANE_SIDE, MEMBRANE_STRETCH};

/// T/ρ_A (m²/s²) of the homogeneous state at `volts`.
fn tension_over_density(volts: f64) -> f64 {
    homogeneous(volts).1
}

#[test]
fn prestretched_membrane_frequencies_and_their_electric_softening() {
    let c2 = tension_over_density(0.0);
    let l = MEMBRANE_STRETCH * MEMBRANE_SIDE;
    let f_mn = |m: f64, n: f64| 0.5 * c2.sqrt() * (m * m + n * n).sqrt() / l;
    let mut errors = Vec::new();
    for n in [8, 16] {
        let f = flexural(n, 0.0, 12).unwrap();
        assert!(f.len() >= 3, "{f:?}");
        let e11 = f[0] / f_mn(1.0, 1.0) - 1.0;
        // (1, 2) and (2, 1) are degenerate
        let e12 = f[1] / f_mn(1.0, 2.0) - 1.0;
        let e21 = f[2] / f_mn(2.0, 1.0) - 1.0;
        println!(
            "{n}×{n}: f11 {:.3} Hz ({e11:+.2e}), f12 {:.3} ({e12:+.2e}), f21 {:.3} ({e21:+.2e}); \
             membrane {:.3}, {:.3} Hz",
            f[0],
            f[1],
            f[2],
            f_mn(1.0, 1.0),
            f_mn(1.0, 2.0)
        );
        assert!((f[1] / f[2] - 1.0).abs() < 1e-6, "degenerate pair {f:?}");
        errors.push(e11);
    }
    // from above, converging
    assert!(errors[1] > 0.0 && errors[1] < 0.5 * errors[0], "{errors:?}");
    assert!(errors[1] < 0.01, "{errors:?}");

    // a voltage lowers the frequencies as the tension it takes away
    let volts = 2000.0;
    let expect = (tension_over_density(volts) / c2).sqrt();
    let (f0, fv) = (
        flexural(16, 0.0, 4).unwrap()[0],
        flexural(16, volts, 4).unwrap()[0],
    );
    println!(
        "{volts} V: f11 {fv:.4} Hz against {f0:.4} Hz at 0 V, ratio {:.6}, membrane {expect:.6}",
        fv / f0
    );
    assert!(fv < f0);
    // the frequency ratio carries the mesh's bending over-stiffness, whose share grows as the
    // tension falls: within the 0 V discretisation error (measured 0.35 % against 0.70 %)
    assert!(
        (fv / f0 / expect - 1.0).abs() < errors[1],
        "{} vs {expect}",
        fv / f0
    );
}

/// `deasim modes` on the coarse diaphragm: the table, `modes.csv` (ascending, the pad mode first,
/// within 0.5 % of the lumped model's linearisation) and one readable VTU per mode with its shape
/// normalised to a largest displacement of 1. Scenarios without a static stage first, without
/// mass are refused with exit 2, and so is `deasim response` on viscoelastic branches (it would
/// ramp its bias without relaxing them; the `frequency-response` stage relaxes them).
#[test]
fn modes_command_writes_the_table_and_the_shapes() {
    use deasim::io::build::build;
    use deasim::io::examples::example;
    use deasim::io::scenario::parse;
    let dir = common::tempdir("modes-cli");
    let sets = ["mesh.radial=8", "mesh.layers=1"];
    let mut args = vec!["modes", "--count", "4", "--out", "m"];
    for s in &sets {
        args.extend(["--set", s]);
    }
    let o = common::deasim(&args, &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // the axisymmetric model says which modes it cannot represent
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains(
            "note: an axisymmetric model finds the modes of one circumferential harmonic"
        ),
        "{stdout}"
    );
    let csv = std::fs::read_to_string(dir.join("m/modes.csv")).unwrap();
    let f: Vec<f64> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
        .collect();
    assert_eq!(f.len(), 4);
    assert!(f.windows(2).all(|w| w[0] <= w[1]), "{f:?}");
    let owned: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let s = parse(example("diaphragm").unwrap(), "d.toml", &owned).unwrap();
    let plan = build(&s, "d.toml", None).unwrap();
    let lumped = deasim::lumped::setup::from_scenario(&s, &plan, "d.toml")
        .unwrap()
        .model
        .linearise()
        .unwrap()
        .natural_frequency();
    assert!((f[0] / lumped - 1.0).abs() < 5e-3, "{} vs {lumped}", f[0]);
    for i in 1..=4 {
        let v = common::vtu::read_vtu(&dir.join(format!("m/modes/mode_{i:02}.vtu"))).unwrap();
        let (c, shape) = &v.point_data["mode_shape"];
        assert_eq!(*c, 3);
        let largest = shape
            .chunks(3)
            .map(|u| (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt())
            .fold(0.0, f64::max);
        assert!((largest - 1.0).abs() < 1e-12, "{largest}");
    }
    assert!(dir.join("m/modes.pvd").exists());
    for (example, expect) in [
        ("film-vibration", "starts with a dynamic stage"),
        ("film", "no mass"),
        ("diaphragm-visco", "use a `frequency-response` stage"),
    ] {
        let path = dir.join(format!("{example}.toml"));
        std::fs::write(&path, common::deasim(&["example", example], &dir).stdout).unwrap();
        let command = if example == "diaphragm-visco" {
            "response"
        } else {
            "modes"
        };
        let o = common::deasim(&[command, path.to_str().unwrap()], &dir);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(expect), "{err}");
    }
}

/// Which modes a model's symmetry hides is said for the axisymmetric diaphragm (one harmonic at a time),
/// the quarter disc of `diaphragm-3d` (symmetric about both planes) and not for the full film.
#[test]
fn the_symmetry_of_a_model_names_the_modes_it_cannot_represent() {
    use deasim::io::build::build;
    use deasim::io::examples::example;
    use deasim::io::scenario::parse;
    use deasim::job::linear::mode_symmetry_note;
    let note = |name: &str| {
        let s = parse(example(name).unwrap(), "m.toml", &[]).unwrap();
        mode_symmetry_note(&build(&s, "m.toml", None).unwrap())
    };
    let ax = note("diaphragm").unwrap();
    assert!(
        ax.contains("one circumferential harmonic at a time") && ax.contains("`harmonic = n`"),
        "{ax}"
    );
    let quarter = note("diaphragm-3d").unwrap();
    assert!(
        quarter.contains("1/4 of the device") && quarter.contains("two planes of symmetry"),
        "{quarter}"
    );
    assert_eq!(note("film"), None);
}

/// The mode shapes are written in the encoding of the field files (`output.vtu_format`).
#[test]
fn mode_files_follow_the_vtu_format() {
    let dir = common::tempdir("modes-ascii");
    let args = [
        "modes",
        "--count",
        "2",
        "--out",
        "m",
        "--set",
        "mesh.radial=8",
        "--set",
        "mesh.layers=1",
        "--set",
        "output.vtu_format=\"ascii\"",
    ];
    let o = common::deasim(&args, &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let path = dir.join("m/modes/mode_01.vtu");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.contains("format=\"ascii\""),
        "{}",
        &text[..text.len().min(2000)]
    );
    assert!(!text.contains("format=\"binary\""));
    let v = common::vtu::read_vtu(&path).unwrap();
    assert_eq!(v.point_data["mode_shape"].0, 3);
}

/// `deasim response` without `--bias` on the default scenario (the diaphragm, whose electrodes
/// are at 0 V after its load stage): the capacitance has no response about 0 V, so its Bode plot
/// is left out with a warning, the other plots are drawn, and the command succeeds.
#[test]
fn response_at_zero_bias_skips_the_capacitance_plot_with_a_warning() {
    let dir = common::tempdir("response-zero-bias");
    let args = [
        "response",
        "--points",
        "4",
        "--from",
        "1",
        "--to",
        "100",
        "--out",
        "r",
        "--set",
        "mesh.radial=8",
        "--set",
        "mesh.layers=1",
    ];
    let o = common::deasim(&args, &dir);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("warning:") && stderr.contains("bode_capacitance.png"),
        "{stderr}"
    );
    assert!(!dir.join("r/bode_capacitance.png").exists());
    for probe in ["center_deflection", "charge"] {
        assert!(dir.join(format!("r/bode_{probe}.png")).exists(), "{probe}");
    }
}
