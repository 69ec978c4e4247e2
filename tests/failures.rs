//! Runs that cannot reach their end stop honestly: `converged: false` in summary.json,
//! exit status 1, the reason and the time in the error, and only converged states in the outputs.
//! (Pull-in is covered by `cli.rs::pull_in_example_exits_1_and_names_the_instability`.)

mod common;

use common::vtu::read_vtu;
use common::{deasim, tempdir};

/// The 1 mm film without voltage, its top face pushed down by 2 mm: the cells invert (J ≤ 0)
/// near half of the ramp. The run ends with exit 1, `converged: false`, an error naming the
/// inverted cell's volume ratio, and every written field file has J > 0 in every cell.
#[test]
fn inverted_elements_stop_the_run_with_the_reason() {
    let dir = tempdir("invert");
    let mut text = String::from_utf8(deasim(&["example", "film"], &dir).stdout).unwrap();
    text.push_str("\n[[constraints]]\nset = \"z1\"\nfix = [\"z\"]\nvalue = -2e-3\n");
    std::fs::write(dir.join("inv.toml"), text).unwrap();
    let out = deasim(
        &[
            "run",
            "inv.toml",
            "--out",
            "o",
            "--set",
            "electrodes.top.voltage.amplitude=0",
            "--set",
            "output.plots=false",
        ],
        &dir,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("o/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["converged"], false);
    assert_eq!(summary["stages"][0]["converged"], false);
    let error = summary["error"].as_str().unwrap();
    assert!(error.contains("non-positive volume ratio J"), "{error}");
    assert!(error.contains("at t = "), "{error}");
    assert!(err.contains("non-positive volume ratio"), "{err}");
    // the last recorded state is a converged one short of full compression (thickness > 0)
    let t = summary["probes"]["thickness_stretch"].as_f64().unwrap();
    assert!(t > 0.0 && t < 0.5, "{t}");
    // every field file: J > 0 in every cell
    let pvd = std::fs::read_to_string(dir.join("o/fields.pvd")).unwrap();
    let files: Vec<&str> = pvd
        .split("file=\"")
        .skip(1)
        .map(|s| s.split('"').next().unwrap())
        .collect();
    assert!(!files.is_empty());
    for f in files {
        let v = read_vtu(&dir.join("o").join(f)).unwrap();
        let j = &v.cell_data["J"].1;
        assert!(
            j.iter().all(|&x| x > 0.0),
            "{f}: min J {:?}",
            j.iter().cloned().fold(f64::INFINITY, f64::min)
        );
    }
}

/// Failures are named by their cause, and "pull-in" only for a limit point with a voltage on:
/// a film without any support (a free rigid-body motion) stops at its first step with a
/// singular tangent and says the body is not supported; the pull-in ramp still says pull-in.
/// (The classification of every Newton failure is tested in `solve::stepping`.)
#[test]
fn failures_name_their_cause() {
    let dir = tempdir("causes");
    let film = String::from_utf8(deasim(&["example", "film"], &dir).stdout).unwrap();
    let run = |name: &str, text: &str| -> String {
        std::fs::write(dir.join(format!("{name}.toml")), text).unwrap();
        let out = deasim(
            &[
                "run",
                &format!("{name}.toml"),
                "--out",
                name,
                "--set",
                "output.plots=false",
                "--set",
                "mesh.divisions=[2, 2, 1]",
            ],
            &dir,
        );
        assert_eq!(out.status.code(), Some(1), "{name}");
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    // no constraints at all
    let mut free = String::new();
    let mut skip = false;
    for line in film.lines() {
        if line.starts_with("[[constraints]]") {
            skip = true;
            continue;
        }
        if skip && (line.starts_with('[') || line.is_empty()) {
            skip = line.starts_with("set") || line.starts_with("fix");
        }
        if skip && (line.starts_with("set") || line.starts_with("fix")) {
            continue;
        }
        skip = false;
        free.push_str(line);
        free.push('\n');
    }
    assert!(!free.contains("[[constraints]]"));
    let err = run("free", &free);
    assert!(err.contains("not fully supported"), "{err}");
    assert!(!err.contains("pull-in"), "{err}");
    // the pull-in example is still pull-in
    let pull = String::from_utf8(deasim(&["example", "film-pull-in"], &dir).stdout).unwrap();
    let err = run("pull", &pull);
    assert!(err.contains("pull-in"), "{err}");
}

/// The longest run of digits in `text`.
fn longest_digits(text: &str) -> usize {
    text.split(|c: char| !c.is_ascii_digit())
        .map(str::len)
        .max()
        .unwrap_or(0)
}

/// A failure is named by what the evidence supports: a Gent network at its locking limit is a
/// material limit (with the material and its key), not pull-in; a permittivity of 1e30, a shear
/// modulus of 1e-300 Pa or a 1e-15 m film (all supported) are ill-conditioned or non-physical
/// input naming the quantity, not "add constraints" nor pull-in; a 1e300 V drive prints no
/// 300-digit voltage.
#[test]
fn failures_name_the_evidence() {
    let dir = tempdir("evidence");
    let film = String::from_utf8(deasim(&["example", "film"], &dir).stdout).unwrap();
    let run = |name: &str, text: &str, sets: &[&str]| -> String {
        std::fs::write(dir.join(format!("{name}.toml")), text).unwrap();
        let file = format!("{name}.toml");
        let mut args = vec![
            "run",
            &file,
            "--out",
            name,
            "--set",
            "output.plots=false",
            "--set",
            "mesh.divisions=[2, 2, 1]",
        ];
        for s in sets {
            args.extend(["--set", s]);
        }
        let out = deasim(&args, &dir);
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert_eq!(out.status.code(), Some(1), "{name}: {err}");
        err
    };
    // J_m = 1e-6 locks the film before the end of its 30 kV ramp. (With 1e-12 the limit lies a
    // few hundred ulps of Ī₁ ≈ 3 from the stress-free state: the stress's round-off there is
    // about 1e-3 of it, no Newton iteration reaches its tolerance, and round-off decides where
    // the ramp stops.)
    let gent = film
        .replace("model = \"neo-hooke\"", "model = \"gent\"\njm = 1e-6")
        .replace("lambda = 1e7", "kappa = 1e7");
    let err = run("gent", &gent, &[]);
    assert!(err.contains("material limit"), "{err}");
    assert!(err.contains("materials.elastomer.jm"), "{err}");
    assert!(!err.contains("pull-in"), "{err}");
    // the eight-chain model's chains lock where λ̄ reaches λ_L (Ī₁ = 3.31 for λ_L = 1.05): a
    // 10 MV ramp drives the film there
    let ab = film
        .replace(
            "model = \"neo-hooke\"",
            "model = \"arruda-boyce\"\nlambda_m = 1.05",
        )
        .replace("lambda = 1e7", "kappa = 1e7");
    let err = run("ab", &ab, &["electrodes.top.voltage.amplitude=1e7"]);
    assert!(err.contains("material limit"), "{err}");
    assert!(err.contains("materials.elastomer.lambda_m"), "{err}");
    assert!(!err.contains("pull-in"), "{err}");
    for (name, set, quantity) in [
        ("eps", "materials.elastomer.permittivity=1e30", "εE²"),
        ("mu", "materials.elastomer.mu=1e-300", "μ = 1e-300 Pa"),
    ] {
        let err = run(name, &film, &[set]);
        assert!(
            err.contains("ill-conditioned or non-physical input"),
            "{err}"
        );
        assert!(err.contains(quantity), "{err}");
        assert!(
            !err.contains("add constraints") && !err.contains("pull-in"),
            "{err}"
        );
    }
    // the 1e-15 m film without the point probe at (10, 10, 1) mm
    let start = film.find("[probes.inplane_stretch]").unwrap();
    let end = film.find("[probes.charge]").unwrap();
    let tiny = format!("{}{}", &film[..start], &film[end..]);
    let err = run("tiny", &tiny, &["mesh.size=[1e-14, 1e-14, 1e-15]"]);
    assert!(
        err.contains("ill-conditioned or non-physical input"),
        "{err}"
    );
    assert!(err.contains("1e-15 m thick"), "{err}");
    assert!(
        !err.contains("add constraints") && !err.contains("pull-in"),
        "{err}"
    );
    let err = run("huge", &film, &["electrodes.top.voltage.amplitude=1e300"]);
    assert!(longest_digits(&err) < 20, "{err}");
}
