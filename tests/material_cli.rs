//! `deasim material`: homogeneous material-point tests from the command line.
//!
//! - The relaxation test of `vhb4910-wang2016` (λ = 1.5 in 0.1 s, held to t = 10 s) writes the
//!   material-point history of the library at the same steps (to round-off: the CSV holds
//!   shortest round-trip numbers) and, with 4000 steps per segment, lies within 0.5 % of the
//!   converged incompressible reference (`analytic::viscoelastic_uniaxial`; the difference is the
//!   first-order update and the bulk modulus κ = 1000 G₀; measured −0.28 % at 0.1 s, −0.10 % at
//!   10 s).
//! - Cycles at three rates, creep, and the equibiaxial and pure-shear ramps run and write their
//!   CSV and plots; a cycle returns to λ = 1 and dissipates energy.
//! - Bad arguments end with exit 2 and a message naming the option.

mod common;
use common::{deasim, tempdir};
use deasim::material::homogeneous::Mode;
use deasim::material::point_history::{run, Control};
use deasim::material::registry::{build, preset};

fn csv(path: &std::path::Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(2)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect()
}

#[test]
fn relaxation_test_matches_the_library_and_the_reference() {
    let dir = tempdir("material-relax");
    let o = deasim(
        &[
            "material",
            "vhb4910-wang2016",
            "--test",
            "relaxation",
            "--stretch",
            "1.5",
            "--ramp-time",
            "0.1",
            "--hold",
            "9.9",
            "--steps",
            "4000",
            "--out",
            "out",
        ],
        &dir,
    );
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    for f in [
        "relaxation.csv",
        "relaxation_stress_stretch.png",
        "relaxation_stress_time.png",
    ] {
        assert!(dir.join("out").join(f).exists(), "{f}");
    }
    let rows = csv(&dir.join("out/relaxation.csv"));
    assert_eq!(rows.len(), 8000);
    // the library at the same times
    let (m, p) = preset("vhb4910-wang2016").unwrap();
    let mat = build(m, &p).unwrap().0;
    let times: Vec<f64> = rows.iter().map(|r| r[1]).collect();
    let l = |t: f64| 1.0 + 0.5 * (t / 0.1).min(1.0);
    let lib = run(mat.as_ref(), Mode::Uniaxial, &Control::Stretch(&l), &times).unwrap();
    for (r, p) in rows.iter().zip(&lib) {
        assert_eq!(r[4], p.nominal);
        assert_eq!(r[3], p.lateral);
    }
    // the converged incompressible reference at 0.1 s and 10 s
    let g0 = 15.36e3;
    let lm = 5.99;
    // the eight-chain ∂W/∂I₁ = (G₀/6)(λ_L/λ̄) L⁻¹(λ̄/λ_L), Padé L⁻¹(x) = x(3 − x²)/(1 − x²)
    let w1 = |i1: f64| {
        let lb = (i1 / 3.0f64).sqrt();
        let x = lb / lm;
        g0 / 6.0 * lm / lb * x * (3.0 - x * x) / (1.0 - x * x)
    };
    let branches = [(26.06e3, 0.6074), (26.53e3, 6.56), (10.83e3, 61.25)];
    let reference = deasim::analytic::viscoelastic_uniaxial(w1, &branches, l, &[0.1, 10.0], 2e4);
    let at = |t: f64| rows.iter().find(|r| (r[1] - t).abs() < 1e-9).unwrap()[4];
    for (t, r) in [0.1, 10.0].into_iter().zip(reference) {
        let s = at(t);
        eprintln!(
            "t = {t} s: {s:.1} Pa, reference {r:.1} Pa ({:+.3} %)",
            100.0 * (s / r - 1.0)
        );
        assert!((s / r - 1.0).abs() < 5e-3, "{s} vs {r}");
    }
}

#[test]
fn cycles_creep_and_other_modes_write_their_results() {
    let dir = tempdir("material-cycles");
    let ok = |args: &[&str]| {
        let o = deasim(args, &dir);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8_lossy(&o.stdout).to_string()
    };
    ok(&[
        "material",
        "vhb4910-hossain2012",
        "--test",
        "cyclic",
        "--cycles",
        "2",
        "--out",
        "c",
    ]);
    let rows = csv(&dir.join("c/cyclic.csv"));
    for rate in [0.01, 0.03, 0.05] {
        let r: Vec<&Vec<f64>> = rows.iter().filter(|r| r[0] == rate).collect();
        assert_eq!(r.len(), 4 * 200);
        let last = r.last().unwrap();
        assert!((last[2] - 1.0).abs() < 1e-12, "back to λ = 1: {}", last[2]);
        assert!(last[6] > 0.0);
        let peak = r.iter().map(|x| x[2]).fold(0.0, f64::max);
        assert!((peak - 2.5).abs() < 1e-12);
    }
    assert!(dir.join("c/cyclic_stress_stretch.png").exists());
    let out = ok(&[
        "material",
        "vhb4910-wang2016",
        "--test",
        "creep",
        "--stress",
        "2e4",
        "--hold",
        "100",
        "--out",
        "k",
    ]);
    assert!(out.contains("creep test"), "{out}");
    let k = csv(&dir.join("k/creep.csv"));
    // the stress is held; the stretch creeps
    let held: Vec<&Vec<f64>> = k.iter().filter(|r| r[1] >= 0.1 - 1e-12).collect();
    assert!(held.iter().all(|r| (r[4] - 2e4).abs() < 1e-6));
    assert!(held.last().unwrap()[2] > held[0][2] + 0.05);
    assert!(dir.join("k/creep_stretch_time.png").exists());
    for mode in ["equibiaxial", "pure-shear"] {
        ok(&[
            "material",
            "vhb4910-ab-wang",
            "--test",
            mode,
            "--rate",
            "0.1",
            "--out",
            mode,
        ]);
        let r = csv(&dir.join(mode).join(format!("{mode}.csv")));
        assert!((r.last().unwrap()[2] - 2.5).abs() < 1e-12);
    }
}

#[test]
fn bad_arguments_are_refused() {
    let dir = tempdir("material-bad");
    for (args, expect) in [
        (vec!["material", "vhb9999"], "neither a preset"),
        (
            vec!["material", "vhb4910-wang2016", "--test", "torsion"],
            "--test",
        ),
        (
            vec!["material", "vhb4910-wang2016", "--stretch=-1"],
            "--stretch",
        ),
        (
            vec!["material", "vhb4910-wang2016", "--test", "creep"],
            "--stress",
        ),
        (
            vec!["material", "vhb4910-wang2016", "--rate", "0"],
            "--rate",
        ),
        (
            vec![
                "material",
                "vhb4910-wang2016",
                "--test",
                "cyclic",
                "--mode",
                "shear",
            ],
            "--mode",
        ),
    ] {
        let o = deasim(&args, &dir);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expect), "{args:?}: {err}");
    }
}

/// `deasim materials` lists the models and presets; with a preset's name it prints the resolved
/// values (the branches included); an unknown name is exit 2 with a suggestion.
#[test]
fn materials_command_lists_and_resolves_presets() {
    let dir = common::tempdir("materials-cmd");
    let list = common::deasim(&["materials"], &dir);
    assert_eq!(list.status.code(), Some(0));
    let text = String::from_utf8_lossy(&list.stdout);
    assert!(
        text.contains("gent") && text.contains("vhb4910-wang2016"),
        "{text}"
    );
    let one = common::deasim(&["materials", "vhb4910-gent"], &dir);
    let text = String::from_utf8_lossy(&one.stdout);
    assert!(
        text.contains("mu = 25400 Pa") && text.contains("jm = 120"),
        "{text}"
    );
    assert!(
        text.contains("small-strain shear modulus 2.540000e4 Pa"),
        "{text}"
    );
    let visco = common::deasim(&["materials", "vhb4910-wang2016"], &dir);
    let text = String::from_utf8_lossy(&visco.stdout);
    assert!(
        text.contains("branch 3: g = 10830 Pa, tau = 61.25 s"),
        "{text}"
    );
    let bad = common::deasim(&["materials", "vhb4910-wang"], &dir);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("did you mean `vhb4910-ab-wang`?"));
}
