//! The command line as a user and a script see it: examples print, check and run;
//! the film's history matches the closed form; bad input exits 2 with a message naming the problem;
//! pull-in exits 1 with `converged: false`; VTU files read back with the expected arrays; `--set`
//! changes what it names and rejects unknown paths.

mod common;

use common::vtu::read_vtu;
use common::{deasim, tempdir};
use deasim::analytic::Film;
use deasim::material::EPSILON_0;
use deasim::problem::examples::{FILM_EPS_R, FILM_LAMBDA, FILM_MU};
use std::path::Path;
use std::process::{Command, Output};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned() + &String::from_utf8_lossy(&o.stdout)
}

/// Parses history.csv into (header, rows).
fn history(dir: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    (header, rows)
}

#[test]
fn every_example_prints_checks_and_the_small_ones_run() {
    let dir = tempdir("examples");
    let list = deasim(&["example"], &dir);
    assert!(list.status.success());
    let names: Vec<String> = String::from_utf8_lossy(&list.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(String::from))
        .collect();
    assert!(
        names.contains(&"film".to_string()) && names.contains(&"film-pull-in".to_string()),
        "{names:?}"
    );
    for name in &names {
        let out = deasim(&["example", name], &dir);
        assert!(out.status.success());
        let file = dir.join(format!("{name}.toml"));
        std::fs::write(&file, &out.stdout).unwrap();
        let check = deasim(&["check", file.to_str().unwrap()], &dir);
        assert!(check.status.success(), "{name}: {}", stderr(&check));
        let said = String::from_utf8_lossy(&check.stdout);
        assert!(said.contains("problems: none"), "{said}");
        assert!(said.contains("extents: x "), "{said}");
        // the resolved material parameters and the trial's time and disk estimate
        assert!(said.contains("small-strain shear modulus"), "{said}");
        assert!(
            said.contains(" on disk: ") && said.contains(" steps (each stage's steps"),
            "{name}: {said}"
        );
    }
    // a preset's parameters are shown resolved
    let visco =
        String::from_utf8_lossy(&deasim(&["check", "diaphragm-visco", "--no-trial"], &dir).stdout)
            .into_owned();
    assert!(visco.contains("branch 1: g = "), "{visco}");
    assert!(!visco.contains("estimate:"), "{visco}");
    let film = String::from_utf8_lossy(&deasim(&["check", "film.toml"], &dir).stdout).into_owned();
    assert!(
        film.contains(
            "extents: x 0.0000e0 … 1.0000e-2 m, y 0.0000e0 … 1.0000e-2 m, z 0.0000e0 … 1.0000e-3 m"
        ),
        "{film}"
    );
    // an example's name and standard input are scenarios too
    let by_name = deasim(&["check", "film-modes"], &dir);
    assert!(by_name.status.success(), "{}", stderr(&by_name));
    assert!(String::from_utf8_lossy(&by_name.stdout).contains("scenario `film-modes` is valid"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args(["check", "-"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    {
        use std::io::Write as _;
        let text = std::fs::read(dir.join("film.toml")).unwrap();
        child.stdin.take().unwrap().write_all(&text).unwrap();
    }
    let piped = child.wait_with_output().unwrap();
    assert!(piped.status.success());
    assert!(String::from_utf8_lossy(&piped.stdout).contains("scenario `film` is valid"));
    let unknown = deasim(&["example", "flim"], &dir);
    assert_eq!(unknown.status.code(), Some(2));
    assert!(
        stderr(&unknown).contains("did you mean `film`"),
        "{}",
        stderr(&unknown)
    );
}

#[test]
fn film_run_matches_the_closed_form_and_writes_every_output() {
    let dir = tempdir("film");
    let scenario = dir.join("film.toml");
    std::fs::write(&scenario, deasim(&["example", "film"], &dir).stdout).unwrap();
    let out = deasim(&["run", "film.toml", "--out", "out"], &dir);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let out_dir = dir.join("out");
    let (header, rows) = history(&out_dir);
    let fixed = [
        "time",
        "stage",
        "step",
        "voltage",
        "newton_iterations",
        "kinetic",
        "stored",
        "electric",
        "gravity",
        "dissipated",
        "energy_error",
    ];
    assert_eq!(&header[..fixed.len()], &fixed.map(String::from));
    assert!(header.contains(&"probe:thickness_stretch".to_string()));
    assert_eq!(rows.len(), 16, "initial state + 15 load steps");
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let reference = Film {
        mu: FILM_MU,
        lambda: FILM_LAMBDA,
        eps: FILM_EPS_R * EPSILON_0,
        c2: 0.0,
    };
    for row in &rows {
        assert_eq!(row.len(), header.len(), "no missing column");
        let v: f64 = row[col("voltage")].parse().unwrap();
        let s = reference.state(v / 1e-3).unwrap();
        let t: f64 = row[col("probe:thickness_stretch")].parse().unwrap();
        let l: f64 = row[col("probe:inplane_stretch")].parse().unwrap();
        assert!(
            (t - s.t).abs() < 1e-8 && (l - s.lambda).abs() < 1e-8,
            "V = {v}: {t} {l} vs {s:?}"
        );
    }
    assert_eq!(
        rows.last().unwrap()[col("voltage")].parse::<f64>().unwrap(),
        30e3
    );
    // summary.json
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
            .unwrap();
    for key in [
        "scenario",
        "dofs",
        "nodes",
        "elements",
        "converged",
        "wall_s",
        "stages",
        "probes",
        "max_electric_field",
        "energy",
        "warnings",
    ] {
        assert!(summary.get(key).is_some(), "summary lacks {key}");
    }
    assert_eq!(summary["converged"], true);
    assert!(summary.get("error").is_none());
    assert_eq!(summary["stages"][0]["name"], "charge");
    assert_eq!(summary["stages"][0]["steps"], 15);
    let e = &summary["energy"];
    for key in [
        "kinetic",
        "stored",
        "electric",
        "gravity",
        "dissipated",
        "energy_error",
    ] {
        assert!(e[key].is_number(), "energy.{key}");
    }
    // the discrete energy balance closes to the quadrature error of 15 load steps
    let err = e["energy_error"].as_f64().unwrap().abs();
    assert!(
        err < 5e-3 * e["electric"].as_f64().unwrap(),
        "energy_error {err}"
    );
    // fields: pvd + one VTU per step with the expected arrays and sizes
    let pvd = std::fs::read_to_string(out_dir.join("fields.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 16);
    let last = read_vtu(&out_dir.join("fields").join("step_00015.vtu")).unwrap();
    let nodes = summary["nodes"].as_u64().unwrap() as usize;
    let cells = summary["elements"].as_u64().unwrap() as usize;
    assert_eq!(last.points.len(), nodes);
    assert_eq!(last.types.len(), cells);
    assert_eq!(last.point_data["displacement"].0, 3);
    assert_eq!(last.point_data["displacement"].1.len(), 3 * nodes);
    assert_eq!(last.point_data["potential"].1.len(), nodes);
    assert_eq!(last.cell_data["electric_field"].1.len(), 3 * cells);
    assert_eq!(last.cell_data["cauchy_stress"].0, 9);
    assert_eq!(last.cell_data["J"].1.len(), cells);
    let s = reference.state(30e6).unwrap();
    for j in &last.cell_data["J"].1 {
        assert!((j - s.lambda * s.lambda * s.t).abs() < 1e-8);
    }
    // the in-plane Cauchy stress of the free film vanishes: σ₁₁ ≈ 0 relative to the Maxwell stress
    let maxwell = FILM_EPS_R * EPSILON_0 * (30e6 / s.t).powi(2);
    for c in last.cell_data["cauchy_stress"].1.chunks(9) {
        assert!(
            c[0].abs() < 1e-6 * maxwell && c[8].abs() < 1e-6 * maxwell,
            "{c:?}"
        );
    }
    // the two parts: the Maxwell stress of the ideal dielectric ε(e⊗e − ½|e|²I), and the
    // mechanical stress that balances it (total = mechanical + Maxwell)
    let eps = FILM_EPS_R * EPSILON_0;
    let cell = |name: &str| {
        last.cell_data[name]
            .1
            .chunks(9)
            .map(<[f64]>::to_vec)
            .collect::<Vec<_>>()
    };
    let (total, mech, mw) = (
        cell("cauchy_stress"),
        cell("mechanical_stress"),
        cell("maxwell_stress"),
    );
    for (k, e) in last.cell_data["electric_field"].1.chunks(3).enumerate() {
        let e2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
        for i in 0..3 {
            for j in 0..3 {
                let expected = eps * (e[i] * e[j] - if i == j { 0.5 * e2 } else { 0.0 });
                let a = i * 3 + j;
                assert!(
                    (mw[k][a] - expected).abs() < 1e-9 * maxwell,
                    "{k} {a}: {} vs {expected}",
                    mw[k][a]
                );
                assert!((total[k][a] - mech[k][a] - mw[k][a]).abs() < 1e-9 * maxwell);
            }
        }
        // through the thickness the film is pressed by ½εe²: the mechanical stress carries it
        assert!(
            (mech[k][8] + 0.5 * eps * e2).abs() < 1e-6 * maxwell,
            "{:?}",
            mech[k]
        );
    }
    for plot in [
        "thickness_stretch.png",
        "inplane_stretch.png",
        "voltage.png",
    ] {
        let bytes = std::fs::read(out_dir.join("plots").join(plot)).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{plot}");
    }
    // no temporary files left behind
    for entry in std::fs::read_dir(&out_dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.contains(".tmp"), "{name}");
    }
}

#[test]
fn pull_in_example_exits_1_and_names_the_instability() {
    let dir = tempdir("pullin");
    std::fs::write(
        dir.join("p.toml"),
        deasim(&["example", "film-pull-in"], &dir).stdout,
    )
    .unwrap();
    let out = deasim(&["run", "p.toml", "--out", "out"], &dir);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["converged"], false);
    let error = summary["error"].as_str().unwrap();
    assert!(
        error.contains("electromechanical instability (pull-in)"),
        "{error}"
    );
    // the last converged voltage, within 0.5 % below the closed-form 33.695 kV
    let v: f64 = error
        .split("last converged voltage ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap();
    assert!((0.995 * 33695.33..=33695.34).contains(&v), "{v}");
    // history holds converged steps only: its last voltage is the last converged one
    let (header, rows) = history(&dir.join("out"));
    let vcol = header.iter().position(|h| h == "voltage").unwrap();
    let last: f64 = rows.last().unwrap()[vcol].parse().unwrap();
    assert!((last - v).abs() < 0.01, "{last} vs {v}");
}

#[test]
fn set_overrides_change_values_and_reject_unknown_paths() {
    let dir = tempdir("set");
    std::fs::write(
        dir.join("film.toml"),
        deasim(&["example", "film"], &dir).stdout,
    )
    .unwrap();
    let out = deasim(
        &[
            "run",
            "film.toml",
            "--out",
            "o",
            "--set",
            "stages.0.steps=3",
            "--set",
            "electrodes.top.voltage.amplitude=9000",
            "--set",
            "mesh.divisions=[2,2,1]",
        ],
        &dir,
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let (header, rows) = history(&dir.join("o"));
    assert_eq!(rows.len(), 4);
    let vcol = header.iter().position(|h| h == "voltage").unwrap();
    assert_eq!(rows[3][vcol].parse::<f64>().unwrap(), 9000.0);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("o/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["nodes"], 18);
    for (set, fragment) in [
        ("materials.elastomer.muu=1", "did you mean `mu`"),
        ("stages.5.steps=1", "past the end"),
        ("mesh.divisons=[1,1,1]", "did you mean `divisions`"),
        ("electrodes.top.voltage.amplitude=high", "amplitude"),
        ("novalue", "KEY=VALUE"),
    ] {
        let out = deasim(&["check", "film.toml", "--set", set], &dir);
        assert_eq!(out.status.code(), Some(2), "{set}");
        assert!(stderr(&out).contains(fragment), "{set}: {}", stderr(&out));
    }
}

/// Bad inputs: each exits 2 (never a panic) with a message naming the problem.
#[test]
fn bad_inputs_exit_2_with_a_message() {
    let dir = tempdir("bad");
    let film = String::from_utf8(deasim(&["example", "film"], &dir).stdout).unwrap();
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "missing key",
            film.replace("name = \"film\"\n", "").into_bytes(),
            "missing field `name`",
        ),
        (
            "wrong type",
            film.replace("steps = 15", "steps = \"many\"").into_bytes(),
            "stages",
        ),
        (
            "negative modulus",
            film.replace("mu = 1e5", "mu = -1e5").into_bytes(),
            "materials.elastomer.mu",
        ),
        (
            "unknown material model",
            film.replace("model = \"neo-hooke\"", "model = \"neo-hook\"")
                .into_bytes(),
            "did you mean `neo-hooke`",
        ),
        (
            "unknown region material",
            film.replace(
                "[[constraints]]\nset = \"x0\"",
                "[regions]\nall = \"rubber\"\n\n[[constraints]]\nset = \"x0\"",
            )
            .into_bytes(),
            "unknown material `rubber`",
        ),
        (
            "unknown set name",
            film.replace("set = \"z1\"\nvoltage", "set = \"z2\"\nvoltage")
                .into_bytes(),
            "unknown set `z2`",
        ),
        ("empty file", Vec::new(), "empty"),
        (
            "non-TOML bytes",
            vec![0x00, 0xff, 0xfe, 0x13, 0x37, 0x80],
            "UTF-8",
        ),
        (
            "binary but UTF-8",
            "\u{1}\u{2}\u{3} = = [".as_bytes().to_vec(),
            "invalid TOML",
        ),
        (
            "permittivity below 1",
            film.replace("permittivity = 4.7", "permittivity = 0.5")
                .into_bytes(),
            "permittivity",
        ),
        (
            "zero steps",
            film.replace("steps = 15", "steps = 0").into_bytes(),
            "steps",
        ),
        (
            "NaN modulus",
            film.replace("mu = 1e5", "mu = nan").into_bytes(),
            "mu",
        ),
        (
            "huge mesh",
            film.replace(
                "divisions = [4, 4, 2]",
                "divisions = [100000, 100000, 100000]",
            )
            .into_bytes(),
            "too large",
        ),
        (
            "unknown key",
            film.replace("plots = true", "plot = true").into_bytes(),
            "did you mean `plots`",
        ),
        (
            "unknown waveform",
            film.replace("waveform = \"ramp\"", "waveform = \"rampe\"")
                .into_bytes(),
            "did you mean `ramp`",
        ),
    ];
    for (what, bytes, fragment) in cases {
        let file = dir.join("bad.toml");
        std::fs::write(&file, &bytes).unwrap();
        let out = deasim(&["run", "bad.toml", "--out", "o"], &dir);
        let msg = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{what}: {msg}");
        assert!(
            msg.contains(fragment),
            "{what}: expected `{fragment}` in: {msg}"
        );
        assert!(
            msg.contains("bad.toml"),
            "{what}: the message names the file: {msg}"
        );
        assert!(!msg.contains("panicked"), "{what}: {msg}");
    }
    let missing = deasim(&["run", "nonexistent.toml"], &dir);
    assert_eq!(missing.status.code(), Some(2));
    assert!(stderr(&missing).contains("nonexistent.toml"));
}

/// The `film-vibration` example: at least 500 steps over at least five periods of the breathing
/// mode; undamped it oscillates about the static 20 kV state with kinetic + stored − electric
/// conserved; with `--set materials.elastomer.viscosity=100` it settles on the static state
/// (λ = 1.033231, closed form of docs/theory.md) and dissipates energy.
#[test]
fn film_vibration_runs_undamped_and_damped() {
    let dir = tempdir("vibration");
    std::fs::write(
        dir.join("v.toml"),
        deasim(&["example", "film-vibration"], &dir).stdout,
    )
    .unwrap();
    let out = deasim(&["run", "v.toml", "--out", "u"], &dir);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let (header, rows) = history(&dir.join("u"));
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    assert!(rows.len() > 500, "{} rows", rows.len());
    assert!(header.contains(&"dt".to_string()));
    let value = |r: &Vec<String>, c: &str| r[col(c)].parse::<f64>().unwrap();
    let stretch: Vec<f64> = rows[1..]
        .iter()
        .map(|r| value(r, "probe:inplane_stretch"))
        .collect();
    let times: Vec<f64> = rows[1..].iter().map(|r| value(r, "time")).collect();
    let mean = stretch.iter().sum::<f64>() / stretch.len() as f64;
    let upcrossings = stretch
        .windows(2)
        .filter(|w| w[0] < mean && w[1] >= mean)
        .count();
    assert!(upcrossings >= 5, "{upcrossings} periods");
    assert!(
        (mean - 1.033231).abs() < 0.005,
        "oscillates about the static state: mean {mean}"
    );
    assert!((times.last().unwrap() - 0.01).abs() < 1e-12);
    // the dynamic stage reports its linear work: a solve per Newton iteration at least, and the
    // modified Newton iteration reuses its factorisations
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("u/summary.json")).unwrap())
            .unwrap();
    let stage = summary["stages"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["kind"] == "dynamic")
        .expect("a dynamic stage");
    let count = |key: &str| stage["linear"][key].as_u64().unwrap();
    let newton = stage["newton_iterations"].as_u64().unwrap();
    assert!(newton > 0 && count("solves") >= newton, "{stage}");
    assert!(
        count("factorizations") >= 1 && count("factorizations") < count("solves"),
        "{stage}"
    );
    let energy: Vec<f64> = rows[1..]
        .iter()
        .map(|r| value(r, "kinetic") + value(r, "stored") - value(r, "electric"))
        .collect();
    let spread = energy.iter().fold(f64::MIN, |a, &b| a.max(b))
        - energy.iter().fold(f64::MAX, |a, &b| a.min(b));
    assert!(
        spread < 1e-4 * energy[0].abs(),
        "conserved: spread {spread:e} of {:e}",
        energy[0]
    );
    let damped = deasim(
        &[
            "run",
            "v.toml",
            "--out",
            "d",
            "--set",
            "materials.elastomer.viscosity=100",
        ],
        &dir,
    );
    assert_eq!(damped.status.code(), Some(0), "{}", stderr(&damped));
    let (_, rows) = history(&dir.join("d"));
    let last = rows.last().unwrap();
    assert!((value(last, "probe:inplane_stretch") - 1.033231).abs() < 1e-5);
    assert!(value(last, "dissipated") > 0.0);
    assert!(value(last, "kinetic") < 1e-12);
}

/// Materials by model and by preset: the Yeoh preset of the experimental study runs the film (and
/// its load-time checks are reported as warnings), a model with its own parameters runs, and a wrong
/// preset, a parameter the model does not use, or a missing parameter exit 2 naming the key.
#[test]
fn material_models_and_presets_in_scenarios() {
    let dir = tempdir("materials");
    let film = String::from_utf8(deasim(&["example", "film"], &dir).stdout).unwrap();
    let mech = "model = \"neo-hooke\"           # Ω = μ/2 (tr C − 3) − μ ln J + Λ/2 (ln J)² − ε/2 J E₀·C⁻¹E₀\nmu = 1e5                      # shear modulus μ, Pa\nlambda = 1e7                  # Lamé constant Λ, Pa\npermittivity = 4.7            # relative permittivity εᵣ";
    assert!(
        film.contains(mech),
        "the film example's material block changed"
    );
    let with = |block: &str| film.replace(mech, block);
    let run = |name: &str, text: String, extra: &[&str]| {
        std::fs::write(dir.join(format!("{name}.toml")), text).unwrap();
        let mut args = vec![
            "run".to_string(),
            format!("{name}.toml"),
            "--out".into(),
            name.to_string(),
        ];
        args.extend(extra.iter().map(|s| s.to_string()));
        let a: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        deasim(&a, &dir)
    };
    let out = run(
        "yeoh",
        with("preset = \"vhb4910-yeoh\""),
        &[
            "--set",
            "electrodes.top.voltage.amplitude=20e3",
            "--set",
            "stages.0.steps=5",
        ],
    );
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("yeoh/summary.json")).unwrap())
            .unwrap();
    let t = summary["probes"]["thickness_stretch"].as_f64().unwrap();
    // C10 = 0.2019 MPa (μ₀ ≈ 0.40 MPa): at 20 kV the film thins by a few per cent only
    assert!(t < 1.0 && t > 0.95, "{t}");
    assert!(
        summary["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("yeoh")),
        "{summary}"
    );
    let out = run(
        "gent",
        with("model = \"gent\"\nmu = 1e5\njm = 100\nkappa = 1e7\npermittivity = 4.7"),
        &["--set", "stages.0.steps=5"],
    );
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    for (name, block, fragment) in [
        (
            "badpreset",
            "preset = \"vhb4910-yeo\"",
            "did you mean `vhb4910-yeoh`",
        ),
        (
            "unused",
            "model = \"gent\"\nmu = 1e5\njm = 100\nkappa = 1e7\nlambda = 3\npermittivity = 4.7",
            "materials.elastomer.lambda",
        ),
        (
            "missing",
            "model = \"yeoh\"\nc10 = 1e5\npermittivity = 4.7",
            "materials.elastomer.d1",
        ),
    ] {
        let out = run(name, with(block), &[]);
        assert_eq!(out.status.code(), Some(2), "{name}: {}", stderr(&out));
        assert!(stderr(&out).contains(fragment), "{name}: {}", stderr(&out));
    }
}

/// `mesh.formulation` and `tractions` from a scenario: a block in uniaxial tension under a dead
/// traction reaches the stretch at which the homogeneous uniaxial nominal stress of the material
/// (`material::homogeneous`, lateral stresses zero) equals the traction, with either formulation;
/// an unknown formulation exits 2.
#[test]
fn tractions_and_formulation_from_the_scenario() {
    let dir = tempdir("traction");
    let text = r#"
name = "tension"
[mesh]
generator = "box"
size = [0.01, 0.01, 0.01]
divisions = [2, 2, 2]
formulation = "mean-dilatation"
[materials.rubber]
model = "neo-hooke-split"
mu = 1e5
kappa = 1e8
permittivity = 3.0
[[constraints]]
set = "x0"
fix = ["x"]
[[constraints]]
set = "y0"
fix = ["y"]
[[constraints]]
set = "z0"
fix = ["z"]
[[tractions]]
set = "x1"
value = [5e4, 0.0, 0.0]
[[stages]]
kind = "static"
steps = 5
[probes.stretch]
kind = "mean"
quantity = "ux"
set = "x1"
scale = 100.0
offset = 1.0
"#;
    std::fs::write(dir.join("t.toml"), text).unwrap();
    let params = deasim::material::registry::MaterialParams {
        mu: vec![1e5],
        kappa: Some(1e8),
        permittivity: Some(3.0),
        ..Default::default()
    };
    let (mat, _) = deasim::material::registry::build("neo-hooke-split", &params).unwrap();
    for formulation in ["mean-dilatation", "standard"] {
        let out = deasim(
            &[
                "run",
                "t.toml",
                "--out",
                formulation,
                "--set",
                &format!("mesh.formulation={formulation}"),
            ],
            &dir,
        );
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.join(formulation).join("summary.json")).unwrap(),
        )
        .unwrap();
        let stretch = summary["probes"]["stretch"].as_f64().unwrap();
        let state = deasim::material::homogeneous::solve(
            mat.as_ref(),
            deasim::material::homogeneous::Mode::Uniaxial,
            stretch,
        )
        .unwrap();
        assert!(
            (state.p11 - 5e4).abs() < 1e-6 * 5e4,
            "{formulation}: λ = {stretch}, P11 = {}",
            state.p11
        );
        assert!(stretch > 1.1, "{stretch}");
    }
    // a second static stage keeps the traction applied: nothing changes
    let two_stages = text.replace(
        "[probes.stretch]",
        "[[stages]]\nkind = \"static\"\nsteps = 2\n\n[probes.stretch]",
    );
    std::fs::write(dir.join("t2.toml"), two_stages).unwrap();
    let two = deasim(&["run", "t2.toml", "--out", "two"], &dir);
    assert_eq!(two.status.code(), Some(0), "{}", stderr(&two));
    let (header, rows) = history(&dir.join("two"));
    let col = header.iter().position(|h| h == "probe:stretch").unwrap();
    let scol = header.iter().position(|h| h == "stage").unwrap();
    let first_end: f64 = rows.iter().rev().find(|r| r[scol] == "stage0").unwrap()[col]
        .parse()
        .unwrap();
    let second_end: f64 = rows.last().unwrap()[col].parse().unwrap();
    assert_eq!(
        rows.iter().filter(|r| r[scol] == "stage1").count(),
        2,
        "two steps in the second stage"
    );
    assert!(
        (first_end - second_end).abs() < 1e-10,
        "{first_end} vs {second_end}"
    );
    let ecol = header.iter().position(|h| h == "energy_error").unwrap();
    let stored: f64 = rows.last().unwrap()[header.iter().position(|h| h == "stored").unwrap()]
        .parse()
        .unwrap();
    let err: f64 = rows.last().unwrap()[ecol].parse().unwrap();
    assert!(
        err.abs() < 1e-2 * stored,
        "energy balance with tractions: {err} of {stored}"
    );
    let bad = deasim(&["check", "t.toml", "--set", "mesh.formulation=q2"], &dir);
    assert_eq!(bad.status.code(), Some(2));
    assert!(stderr(&bad).contains("mesh.formulation"));
}

/// Output safety: a directory holding another scenario's results is refused (exit 2) unless
/// `--overwrite`; re-running the same scenario replaces its results without stale field files;
/// files of the user in the directory are never deleted.
#[test]
fn output_directory_of_another_scenario_is_refused_without_overwrite() {
    let dir = tempdir("outdir");
    std::fs::write(
        dir.join("film.toml"),
        deasim(&["example", "film"], &dir).stdout,
    )
    .unwrap();
    std::fs::write(
        dir.join("v.toml"),
        deasim(&["example", "film-vibration"], &dir).stdout,
    )
    .unwrap();
    let first = deasim(&["run", "film.toml", "--out", "o"], &dir);
    assert_eq!(first.status.code(), Some(0), "{}", stderr(&first));
    std::fs::write(dir.join("o/notes.txt"), "mine").unwrap();
    // the same scenario again, with fewer steps: no stale step files remain
    let again = deasim(
        &[
            "run",
            "film.toml",
            "--out",
            "o",
            "--set",
            "stages.0.steps=3",
        ],
        &dir,
    );
    assert_eq!(again.status.code(), Some(0), "{}", stderr(&again));
    let vtus = std::fs::read_dir(dir.join("o/fields")).unwrap().count();
    assert_eq!(vtus, 4, "initial state + 3 steps");
    // another scenario is refused
    let other = deasim(
        &[
            "run",
            "v.toml",
            "--out",
            "o",
            "--set",
            "stages.0.duration=1e-4",
        ],
        &dir,
    );
    assert_eq!(other.status.code(), Some(2));
    assert!(stderr(&other).contains("--overwrite"), "{}", stderr(&other));
    let forced = deasim(
        &[
            "run",
            "v.toml",
            "--out",
            "o",
            "--set",
            "stages.0.duration=1e-4",
            "--overwrite",
        ],
        &dir,
    );
    assert_eq!(forced.status.code(), Some(0), "{}", stderr(&forced));
    assert_eq!(
        std::fs::read_to_string(dir.join("o/notes.txt")).unwrap(),
        "mine"
    );
}

/// SIGINT during a run: deasim finishes the current step, writes valid outputs holding the last
/// accepted step (`converged: false`, an error naming the interruption) and exits 130.
#[test]
fn sigint_stops_cleanly_with_valid_outputs() {
    let dir = tempdir("sigint");
    std::fs::write(
        dir.join("v.toml"),
        deasim(&["example", "film-vibration"], &dir).stdout,
    )
    .unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args([
            "run",
            "v.toml",
            "--out",
            "o",
            "--set",
            "stages.0.duration=10.0",
            "--set",
            "output.fields_every=50",
        ])
        .current_dir(&dir)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // wait until the run has accepted steps (history.csv is flushed every 2 s)
    let start = std::time::Instant::now();
    while !dir.join("o/history.csv").exists() && start.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    std::thread::sleep(std::time::Duration::from_millis(500));
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(130),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("o/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["converged"], false);
    assert!(
        summary["error"].as_str().unwrap().contains("interrupted"),
        "{summary}"
    );
    let (header, rows) = history(&dir.join("o"));
    assert!(rows.len() > 2);
    let tcol = header.iter().position(|h| h == "time").unwrap();
    let t_last: f64 = rows.last().unwrap()[tcol].parse().unwrap();
    assert!(t_last > 0.0 && t_last < 10.0, "{t_last}");
    assert!(rows.iter().all(|r| r.len() == header.len()));
    // the pvd's last entry is the last accepted state
    let pvd = std::fs::read_to_string(dir.join("o/fields.pvd")).unwrap();
    assert!(pvd.trim_end().ends_with("</VTKFile>"));
}

/// The `disc` generator and `prestretch` from a scenario: a quarter disc (O-grid, mean dilatation)
/// whose rim is moved to λ = 2 on a bottom held on rollers is in the homogeneous equibiaxial state,
/// so its thickness stretch equals the lateral stretch of the material's homogeneous equibiaxial
/// path (`material::homogeneous`) to 1e-8.
#[test]
fn prestretched_disc_is_homogeneous() {
    let dir = tempdir("disc");
    let scenario =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/disc_prestretch.toml");
    let out = deasim(&["run", scenario.to_str().unwrap(), "--out", "d"], &dir);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("d/summary.json")).unwrap())
            .unwrap();
    let t = summary["probes"]["thickness_stretch"].as_f64().unwrap();
    let params = deasim::material::registry::MaterialParams {
        mu: vec![5e4],
        kappa: Some(5e7),
        permittivity: Some(4.7),
        ..Default::default()
    };
    let (mat, _) = deasim::material::registry::build("neo-hooke-split", &params).unwrap();
    let state = deasim::material::homogeneous::solve(
        mat.as_ref(),
        deasim::material::homogeneous::Mode::Equibiaxial,
        2.0,
    )
    .unwrap();
    assert!((t - state.lateral).abs() < 1e-8, "{t} vs {}", state.lateral);
    let check = deasim(&["check", scenario.to_str().unwrap()], &dir);
    let text = String::from_utf8_lossy(&check.stdout);
    assert!(text.contains("electrode `top`"), "{text}");
}

/// `deasim sweep` with a value that pulls in and a breakdown warning: the failed run is marked
/// (`converged` false, `status` naming pull-in) with empty value cells instead of its last
/// converged state, the breakdown warning reaches `sweep.csv` and the console, every
/// `runs/NNN/sweep-value.json` records its value, and the exit status is 1.
#[test]
fn sweep_marks_failed_runs_and_carries_warnings() {
    let dir = tempdir("sweep-failures");
    let film = deasim(&["example", "film"], &dir);
    std::fs::write(dir.join("film.toml"), film.stdout).unwrap();
    let o = deasim(
        &[
            "sweep",
            "film.toml",
            "--set-range",
            "electrodes.top.voltage.amplitude=20e3,40e3",
            "--set",
            "mesh.divisions=[2, 2, 1]",
            "--set",
            "materials.elastomer.breakdown_field=1e7",
            "--out",
            "sw",
        ],
        &dir,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("pull-in") && err.contains("warning:"), "{err}");
    let csv = std::fs::read_to_string(dir.join("sw/sweep.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(
        lines[0].starts_with("electrodes.top.voltage.amplitude,converged,status,warnings,"),
        "{}",
        lines[0]
    );
    assert!(
        lines[1].starts_with("2e4,true,\"converged\",\""),
        "{}",
        lines[1]
    );
    assert!(
        lines[1].contains("breakdown") || lines[1].contains("dielectric"),
        "{}",
        lines[1]
    );
    assert!(lines[2].starts_with("4e4,false,\"failed: "), "{}", lines[2]);
    assert!(lines[2].contains("pull-in"), "{}", lines[2]);
    assert!(
        lines[2].ends_with(",,,"),
        "a failed run has no values: {}",
        lines[2]
    );
    for (i, v) in [(0, 20e3), (1, 40e3)] {
        let j: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.join(format!("sw/runs/{i:03}/sweep-value.json"))).unwrap(),
        )
        .unwrap();
        assert_eq!(j["electrodes.top.voltage.amplitude"].as_f64(), Some(v));
    }
}

/// `current` and `power` probes: the current is the backward difference of the electrode's charge
/// over each step (at the first step of a slow sinusoid from 0 V the film is still a parallel-plate
/// capacitor, I = ε₀εᵣA/h · ΔV/Δt), the power is the voltage times the current.
#[test]
fn current_and_power_probes_follow_the_charge() {
    let dir = tempdir("current");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/film-current.toml"),
        dir.join("c.toml"),
    )
    .unwrap();
    let out = deasim(&["run", "c.toml", "--out", "o"], &dir);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let (header, rows) = history(&dir.join("o"));
    let rows: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| r.iter().map(|x| x.parse().unwrap_or(f64::NAN)).collect())
        .collect();
    let col = |n: &str| header.iter().position(|h| h == n).unwrap();
    let (t, v, q, i, p) = (
        col("time"),
        col("voltage"),
        col("probe:charge"),
        col("probe:current"),
        col("probe:power"),
    );
    assert_eq!(rows[0][i], 0.0);
    for w in rows.windows(2) {
        let expected = (w[1][q] - w[0][q]) / (w[1][t] - w[0][t]);
        assert!(
            (w[1][i] - expected).abs() <= 1e-9 * expected.abs().max(1e-12),
            "{w:?}"
        );
        assert!((w[1][p] - w[1][v] * w[1][i]).abs() <= 1e-12 * w[1][p].abs().max(1e-30));
    }
    let c0 = FILM_EPS_R * EPSILON_0 * 1e-4 / 1e-3;
    let first = c0 * rows[1][v] / (rows[1][t] - rows[0][t]);
    assert!(
        (rows[1][i] / first - 1.0).abs() < 1e-6,
        "{} vs {first}",
        rows[1][i]
    );
}

/// `area_strain` of an electrode (or its face set) on the homogeneous film: A/A₀ − 1 = λ² − 1 with
/// λ the in-plane stretch of the corner, for linear (hex8) and quadratic (tet10) faces.
#[test]
fn area_strain_probe_is_the_square_of_the_inplane_stretch() {
    let dir = tempdir("area-strain");
    let scenario = format!(
        "{}\n[probes.area]\nkind = \"area_strain\"\nelectrode = \"top\"\n\
         [probes.area_set]\nkind = \"area_strain\"\nset = \"z1\"\n",
        deasim::io::examples::example("film").unwrap()
    );
    std::fs::write(dir.join("a.toml"), scenario).unwrap();
    for element in ["hex8", "tet10"] {
        let out = deasim(
            &[
                "run",
                "a.toml",
                "--out",
                element,
                "--set",
                &format!("mesh.element=\"{element}\""),
            ],
            &dir,
        );
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        let (header, rows) = history(&dir.join(element));
        let col = |n: &str| header.iter().position(|h| h == n).unwrap();
        let (l, a, b) = (
            col("probe:inplane_stretch"),
            col("probe:area"),
            col("probe:area_set"),
        );
        let last = rows.last().unwrap();
        let v = |c: usize| last[c].parse::<f64>().unwrap();
        let expected = v(l) * v(l) - 1.0;
        assert!(expected > 0.1, "{element}: the film spreads ({expected})");
        assert!(
            (v(a) - expected).abs() < 1e-10,
            "{element}: {} vs {expected}",
            v(a)
        );
        assert_eq!(v(a), v(b));
        assert_eq!(rows[0][a].parse::<f64>().unwrap(), 0.0);
    }
}

/// An error caused by a `--set` names the override; key paths have one style (`stages.0.steps`)
/// whether the error comes from the file or from an override.
#[test]
fn errors_name_the_override_and_use_one_key_style() {
    let dir = tempdir("blame");
    let out = deasim(&["check", "film", "--set", "stages.0.steps=0"], &dir);
    assert_eq!(out.status.code(), Some(2));
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains("key `stages.0.steps`")
            && said.contains("(the value comes from `--set stages.0.steps=0`)"),
        "{said}"
    );
    let text = String::from_utf8_lossy(&deasim(&["example", "film"], &dir).stdout)
        .replace("steps = 15", "steps = 15\nstepz = 3");
    std::fs::write(dir.join("f.toml"), text).unwrap();
    let out = deasim(&["check", "f.toml"], &dir);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("key `stages.0.stepz`"), "{said}");
    assert!(!said.contains("[0]") && !said.contains("--set"), "{said}");
}

/// Under an MPI launcher that started several processes (its variables set here by hand), a
/// command that runs in one process, and a run whose solver is not PETSc's, refuse with a message
/// from the first process only, before writing anything: each process would otherwise do the
/// whole work and write the same files.
#[test]
fn several_mpi_processes_are_refused_where_they_would_repeat_the_work() {
    let dir = common::tempdir("cli-mpi-refusal");
    std::fs::write(
        dir.join("film.toml"),
        deasim::io::examples::example("film").unwrap(),
    )
    .unwrap();
    let launched = |rank: &str, args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_deasim"))
            .args(args)
            .current_dir(&dir)
            .env("OMPI_COMM_WORLD_SIZE", "2")
            .env("OMPI_COMM_WORLD_RANK", rank)
            .output()
            .unwrap()
    };
    for args in [
        &["response", "film.toml", "--out", "r"][..],
        &["modes", "film.toml"][..],
        &["run", "film.toml", "--out", "o"][..],
    ] {
        let first = launched("0", args);
        let other = launched("1", args);
        let message = stderr(&first);
        // exit 2, bad input, on every process
        assert!(
            first.status.code() == Some(2) && other.status.code() == Some(2),
            "{args:?}: {message}"
        );
        assert!(stderr(&other).is_empty(), "{args:?}: {}", stderr(&other));
        let expected = if args[0] == "run" {
            "an MPI launcher started 2 processes, but `[solver] kind = \"auto\"`"
        } else {
            "runs in one process, but an MPI launcher started 2"
        };
        assert!(message.contains(expected), "{args:?}: {message}");
    }
    assert!(!dir.join("r").exists() && !dir.join("o").exists());
    // one process under a launcher is a plain run
    let one = Command::new(env!("CARGO_BIN_EXE_deasim"))
        .args(["check", "film.toml"])
        .current_dir(&dir)
        .env("OMPI_COMM_WORLD_SIZE", "1")
        .env("OMPI_COMM_WORLD_RANK", "0")
        .output()
        .unwrap();
    assert!(one.status.success(), "{}", stderr(&one));
}

/// `check` reports a trial that failed as a problem (exit 2): a disc 1e-300 m thick cannot take
/// its pre-stretch. It prints an axisymmetric model's gravity in the scenario's order.
#[test]
fn check_reports_a_failed_trial_and_gravity_as_given() {
    let dir = tempdir("check-trial");
    let out = deasim(
        &["check", "diaphragm", "--set", "mesh.thickness=1e-300"],
        &dir,
    );
    let text = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{text}");
    assert!(!text.contains("problems: none"), "{text}");
    assert!(text.contains("the trial run failed"), "{text}");
    let out = deasim(&["check", "diaphragm"], &dir);
    let text = stderr(&out);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(text.contains("gravity: [0, 0, -9.81] m/s²"), "{text}");
}

/// A generated mesh typed in mm (10 m across) gets the warning a Gmsh file gets, naming the key.
#[test]
fn generated_mesh_in_mm_is_warned_about() {
    let dir = tempdir("mm-box");
    let out = deasim(
        &["check", "film", "--set", "mesh.size=[10.0, 10.0, 1.0]"],
        &dir,
    );
    let text = stderr(&out);
    assert!(
        text.contains("`mesh.size`") && text.contains("in mm"),
        "{text}"
    );
    let out = deasim(&["check", "film"], &dir);
    assert!(!stderr(&out).contains("in mm"), "{}", stderr(&out));
}

/// `run` names the `--set` that gave a wrong value, as `check` does, and prints no 300-digit
/// number.
#[test]
fn run_names_the_override_of_an_error() {
    let dir = tempdir("run-blame");
    let out = deasim(
        &[
            "run",
            "diaphragm",
            "--out",
            "o",
            "--set",
            "stages.1.dt=1e-300",
        ],
        &dir,
    );
    let text = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{text}");
    assert!(text.contains("`--set stages.1.dt=1e-300`"), "{text}");
    assert!(text.contains("steps of 1e-300 s"), "{text}");
}

/// A `--set` of the swept path is refused (exit 2) rather than silently overridden, and
/// `sweep.csv` has a `min` column beside `max`.
#[test]
fn sweep_refuses_a_set_of_its_path_and_tabulates_the_minimum() {
    let dir = tempdir("sweep-min");
    let o = deasim(
        &[
            "sweep",
            "film",
            "--set-range",
            "electrodes.top.voltage.amplitude=1e3,2e3",
            "--set",
            "electrodes.top.voltage.amplitude=5e3",
            "--out",
            "bad",
        ],
        &dir,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("which the sweep varies"), "{err}");
    let o = deasim(
        &[
            "sweep",
            "film",
            "--set-range",
            "electrodes.top.voltage.amplitude=1e3,2e3",
            "--set",
            "mesh.divisions=[1, 1, 1]",
            "--set",
            "stages.0.steps=2",
            "--out",
            "sw",
        ],
        &dir,
    );
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let csv = std::fs::read_to_string(dir.join("sw/sweep.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(
        header.contains("thickness_stretch:final,thickness_stretch:min,thickness_stretch:max"),
        "{header}"
    );
}

/// The lumped report says "linearised about" once and explains its C(x₀) against the finite
/// element capacitance.
#[test]
fn lumped_report_reads_once_and_explains_its_capacitance() {
    let dir = tempdir("lumped-report");
    let out = deasim(&["lumped", "diaphragm", "--out", "lp"], &dir);
    let text = stderr(&out);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert_eq!(text.matches("linearised about").count(), 1, "{text}");
    assert!(
        text.contains("C(x0) is the lumped model's parallel-plate"),
        "{text}"
    );
    assert!(text.contains("fringing"), "{text}");
}
