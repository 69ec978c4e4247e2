//! Modes of circumferential harmonic n of axisymmetric models (`time::harmonic`).
//!
//! Reference: a circular membrane of radius a under the uniform in-plane Cauchy stress σ, of
//! current density ρ, clamped on its rim, vibrates out of plane at f_n1 = j_n1/(2πa) √(σ/ρ) in
//! its lowest mode of n nodal diameters (j_01 = 2.4048, j_11 = 3.8317, j_21 = 5.1356, the first
//! zeros of the Bessel functions J_n). The membrane is a neo-Hookean disc (μ = 100 kPa,
//! λ_Lamé = 100 μ, ρ₀ = 1000 kg/m³) of radius 10 mm and thickness 0.1 mm stretched
//! equibiaxially by 1.5 with its rim face held (thickness free, so the state is homogeneous:
//! σ and ρ = ρ₀/J from F = diag(λ, λ_z, λ) of the solved state), both faces grounded.

mod common;

use deasim::api::{loaded_modes_of_harmonics, modes_plan, RunOptions};
use deasim::element::harmonic::harmonic_factor;
use deasim::io::build::build;
use deasim::io::examples::example;
use deasim::io::scenario::parse;
use deasim::job::statics::solve_static;
use deasim::material::{ElectroNeoHooke, Mat3, Material, Vec3};
use deasim::mesh::meridian::rectangle_mesh;
use deasim::mesh::MeridianKind;
use deasim::problem::dofs::{Dirichlet, Field};
use deasim::problem::model::Model;
use deasim::solve::newton::NewtonSettings;
use deasim::solve::stepping::StepControl;
use deasim::time::harmonic::harmonic_modes;
use deasim::time::mass::{MassKind, NodalMass};
use deasim::time::modal::{modes, Mode, ModeSettings};
use std::sync::Arc;

const RADIUS: f64 = 10e-3;
const THICKNESS: f64 = 0.1e-3;
const STRETCH: f64 = 1.5;
const MU: f64 = 1e5;
const RHO0: f64 = 1000.0;

/// The stretched membrane on `nr` quad8 cells across the radius: its model, state, mass and
/// √(σ/ρ) (m/s).
fn membrane(nr: usize) -> (Model, Vec<f64>, NodalMass, f64) {
    let mesh = rectangle_mesh(0.0, RADIUS, THICKNESS, nr, 1, MeridianKind::Quad8).unwrap();
    let material = Arc::new(ElectroNeoHooke::new(MU, 100.0 * MU, 4.7));
    let mut model = Model::new(mesh, material.clone()).unwrap();
    model
        .fix("outer", Field::Ux, (STRETCH - 1.0) * RADIUS)
        .unwrap();
    let corner: Vec<usize> = model.mesh.node_sets["outer"]
        .iter()
        .copied()
        .filter(|&a| model.mesh.nodes[a][1] == 0.0)
        .collect();
    model.dirichlet.push(Dirichlet {
        nodes: corner,
        field: Field::Uy,
        value: 0.0,
    });
    model.fix("bottom", Field::Phi, 0.0).unwrap();
    model.fix("top", Field::Phi, 0.0).unwrap();
    let out = solve_static(
        &model,
        None,
        &StepControl {
            steps: 2,
            ..Default::default()
        },
        &NewtonSettings::default(),
        |_, _| {},
    );
    out.result.as_ref().expect("the pre-stretch converges");
    let state = out.state;
    let top = model.mesh.node_sets["top"][0];
    let lz = 1.0 + state[top * 4 + 1] / THICKNESS;
    let f = Mat3::from_diagonal(&Vec3::new(STRETCH, lz, STRETCH));
    let j = f.determinant();
    let p = material.stress(&f, &Vec3::zeros()).unwrap().p;
    let sigma = p[(0, 0)] * STRETCH / j;
    let rho = RHO0 / j;
    let mass = NodalMass::new(&model, &[RHO0], MassKind::Consistent);
    (model, state, mass, (sigma / rho).sqrt())
}

/// Whether a mode moves mostly out of plane (u_z) rather than in plane.
fn transverse(m: &Mode) -> bool {
    let (mut z, mut plane) = (0.0, 0.0);
    for node in m.shape.chunks(4) {
        z += node[1] * node[1];
        plane += node[0] * node[0] + node[2] * node[2];
    }
    z > plane
}

/// The lowest out-of-plane mode of harmonic n (n = 0 by the axisymmetric analysis).
fn lowest_transverse(model: &Model, state: &[f64], mass: &NodalMass, n: u32) -> Mode {
    let settings = ModeSettings {
        count: 4,
        ..Default::default()
    };
    let found = if n == 0 {
        modes(model, state, mass, &Default::default(), &settings).unwrap()
    } else {
        harmonic_modes(model, state, mass, &settings, n, &[]).unwrap()
    };
    assert!(found.iter().all(|m| m.harmonic == n));
    found
        .into_iter()
        .find(transverse)
        .expect("a transverse mode")
}

/// The lowest out-of-plane frequencies of harmonics 0, 1 and 2 approach j_n1/(2πa)√(σ/ρ) under
/// refinement (quad8, 8, 16 and 32 cells across the radius, one through the thickness).
#[test]
fn stretched_membrane_harmonics_follow_the_bessel_zeros() {
    let zeros = [2.4048, 3.8317, 5.1356];
    let mut errors = vec![Vec::new(); 3];
    for nr in [8, 16, 32] {
        let (model, state, mass, c) = membrane(nr);
        for (n, j) in zeros.iter().enumerate() {
            let exact = j / (2.0 * std::f64::consts::PI * STRETCH * RADIUS) * c;
            let f = lowest_transverse(&model, &state, &mass, n as u32).frequency;
            let e = f / exact - 1.0;
            println!("nr = {nr}, n = {n}: {f:.4} Hz against {exact:.4} Hz ({e:+.3e})");
            errors[n].push(e.abs());
        }
    }
    for (n, e) in errors.iter().enumerate() {
        assert!(e[2] < 2e-3, "n = {n}: {e:?}");
        assert!(
            e[1] < 0.6 * e[0] && e[2] < 0.6 * e[1],
            "n = {n} does not converge: {e:?}"
        );
    }
}

/// Axis conditions: the modes of harmonic 2 do not move the axis; those of harmonic 1 translate
/// it laterally only (u_z = Φ = 0, u_θ = −u_r), and some do.
#[test]
fn axis_nodes_follow_the_regularity_conditions() {
    let (model, state, mass, _) = membrane(8);
    let axis: Vec<usize> = (0..model.mesh.n_nodes())
        .filter(|&a| model.mesh.nodes[a][0] == 0.0)
        .collect();
    assert!(!axis.is_empty());
    let settings = ModeSettings {
        count: 6,
        ..Default::default()
    };
    for m in harmonic_modes(&model, &state, &mass, &settings, 2, &[]).unwrap() {
        let largest = m.shape.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        assert!(largest > 0.0);
        for &a in &axis {
            assert!(m.shape[a * 4..a * 4 + 4].iter().all(|&v| v == 0.0));
        }
    }
    let mut lateral = 0.0f64;
    for m in harmonic_modes(&model, &state, &mass, &settings, 1, &[]).unwrap() {
        for &a in &axis {
            let u = &m.shape[a * 4..a * 4 + 4];
            assert_eq!((u[1], u[3]), (0.0, 0.0));
            assert_eq!(u[2], -u[0]);
            lateral = lateral.max(u[0].abs());
        }
    }
    assert!(lateral > 0.0);
    assert_eq!(harmonic_factor(1), 0.5);
}

/// The diaphragm's lowest modes of harmonic 1 (the pad translating sideways: rigid regions
/// carry no rotation) against the same device meshed in 3-D as a full disc: the modes whose pad
/// moves most sideways.
#[test]
fn diaphragm_harmonic_one_matches_the_full_3d_disc() {
    let sets: Vec<String> = [
        "mesh.radial=12",
        "mesh.layers=2",
        "materials.vhb.viscosity=0",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let settings = ModeSettings {
        count: 6,
        ..Default::default()
    };
    let pad_mode = |text: &str, harmonic: u32| -> (f64, Vec<f64>) {
        let mut scenario = parse(text, "t.toml", &sets).unwrap();
        scenario.stages.truncate(1);
        let plan = build(&scenario, "t.toml", None).unwrap();
        let plan = modes_plan(plan, &settings).unwrap();
        let loaded =
            loaded_modes_of_harmonics(&plan, &settings, &[harmonic], RunOptions::default())
                .unwrap();
        let pad = plan.rigid[0].nodes[0];
        let side =
            |m: &Mode| m.shape[pad * 4].hypot(m.shape[pad * 4 + if harmonic > 0 { 2 } else { 1 }]);
        let best = loaded
            .modes
            .iter()
            .max_by(|a, b| side(a).total_cmp(&side(b)))
            .unwrap();
        (
            best.frequency,
            loaded.modes.iter().map(|m| m.frequency).collect(),
        )
    };
    let (f_ax, all_ax) = pad_mode(example("diaphragm").unwrap(), 1);
    let full = example("diaphragm-3d")
        .unwrap()
        .replace("quarter = true", "quarter = false")
        .replace(
            "[[constraints]]\nset = \"symmetry_x\"\nfix = [\"x\"]\n\n[[constraints]]\nset = \"symmetry_y\"\nfix = [\"y\"]\n",
            "",
        );
    let (f_3d, all_3d) = pad_mode(&full, 0);
    println!(
        "harmonic 1: {all_ax:.4?} Hz; 3-D: {all_3d:.4?} Hz; pad sideways: {f_ax:.4} Hz against \
         {f_3d:.4} Hz ({:+.3e})",
        f_ax / f_3d - 1.0
    );
    assert!((f_ax / f_3d - 1.0).abs() < 5e-3);
}

/// The `diaphragm` with its dynamic stage replaced by `stage` (TOML lines of a `[[stages]]`).
fn diaphragm_with(stage: &str) -> String {
    with_stage(example("diaphragm").unwrap(), stage)
}

/// The example `text` (a diaphragm) with its dynamic stage replaced by `stage`.
fn with_stage(text: &str, stage: &str) -> String {
    let start = text.find("[[stages]]\nname = \"actuate\"").unwrap();
    let end = text.find("[probes.center_deflection]").unwrap();
    format!(
        "{}[[stages]]\nname = \"vibrate\"\n{stage}\n\n{}",
        &text[..start],
        &text[end..]
    )
}

/// A `modes` stage with `harmonic = [0, 1]` and `deasim modes --harmonic 0,1` write `count`
/// modes of each harmonic with the `harmonic` column, the same numbers; harmonic 0 is the
/// stage's own modes without the key. Bad values, the key on other stages and harmonics of a
/// 3-D model are refused with the key.
#[test]
fn stage_key_and_command_option() {
    let dir = common::tempdir("harmonic-stage");
    let sets = [
        "--set",
        "mesh.radial=6",
        "--set",
        "materials.vhb.viscosity=0",
    ];
    let read = |path: &str| -> Vec<(f64, u32)> {
        let text = std::fs::read_to_string(dir.join(path)).unwrap();
        let mut lines = text.lines();
        assert_eq!(
            lines.next().unwrap(),
            "mode,frequency_hz,eigenvalue_rad2_per_s2,residual,harmonic"
        );
        lines
            .map(|l| {
                let c: Vec<&str> = l.split(',').collect();
                (c[1].parse().unwrap(), c[4].parse().unwrap())
            })
            .collect()
    };
    std::fs::write(
        dir.join("h.toml"),
        diaphragm_with("kind = \"modes\"\ncount = 2\nharmonic = [0, 1]"),
    )
    .unwrap();
    let mut args = vec!["run", "h.toml", "--out", "run"];
    args.extend(sets);
    let o = common::deasim(&args, &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let stage = read("run/modes.csv");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("run/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["modes_harmonic"], serde_json::json!([0, 0, 1, 1]));
    assert_eq!(summary["modes"].as_array().unwrap().len(), 4);
    assert_eq!(stage.iter().map(|m| m.1).collect::<Vec<_>>(), [0, 0, 1, 1]);
    std::fs::write(
        dir.join("z.toml"),
        diaphragm_with("kind = \"modes\"\ncount = 2"),
    )
    .unwrap();
    let mut args = vec!["run", "z.toml", "--out", "zero"];
    args.extend(sets);
    let o = common::deasim(&args, &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(read("zero/modes.csv"), stage[..2]);
    let mut args = vec![
        "modes",
        "h.toml",
        "--count",
        "2",
        "--harmonic",
        "0,1",
        "--out",
        "cmd",
    ];
    args.extend(sets);
    let o = common::deasim(&args, &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("harmonic"), "{stdout}");
    let cmd = read("cmd/modes.csv");
    assert_eq!(cmd.len(), 4);
    for (a, b) in stage.iter().zip(&cmd) {
        assert!((a.0 / b.0 - 1.0).abs() < 1e-9 && a.1 == b.1, "{a:?} {b:?}");
    }
    // bad values, and a 3-D model
    for (name, text, key) in [
        (
            "bad.toml",
            diaphragm_with("kind = \"modes\"\nharmonic = 1.5"),
            "stages.1.harmonic",
        ),
        (
            "neg.toml",
            diaphragm_with("kind = \"modes\"\nharmonic = [1, -2]"),
            "stages.1.harmonic",
        ),
        (
            "resp.toml",
            diaphragm_with("kind = \"frequency-response\"\nharmonic = 1\nfrom = 1.0\nto = 10.0"),
            "stages.1.harmonic",
        ),
        (
            "static.toml",
            diaphragm_with("kind = \"static\"\nharmonic = 1"),
            "stages.1.harmonic",
        ),
        (
            "3d.toml",
            with_stage(
                example("diaphragm-3d").unwrap(),
                "kind = \"modes\"\nharmonic = 1",
            ),
            "stages.1.harmonic",
        ),
    ] {
        std::fs::write(dir.join(name), text).unwrap();
        let o = common::deasim(&["check", name, "--no-trial"], &dir);
        let said = format!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        assert_eq!(o.status.code(), Some(2), "{name}: {said}");
        assert!(said.contains(key), "{name}: {said}");
    }
    let o = common::deasim(
        &["modes", "diaphragm-3d", "--harmonic", "1", "--out", "x"],
        &dir,
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--harmonic"));
}

/// The `diaphragm` whose pad has the rotary inertia `inertia` (kg·m²) about a diameter.
fn tilting_diaphragm(inertia: f64) -> String {
    let text = example("diaphragm").unwrap();
    let old = "mass = 0.04622                # kg, the whole attached mass";
    assert!(text.contains(old));
    text.replace(
        old,
        &format!("mass = 0.04622\nrotary_inertia = {inertia:e}"),
    )
}

/// A pad with a rotary inertia tilts in harmonic 1: a rocking mode appears (u_z = −α r over the
/// pad) and, the tilt being one more freedom, no frequency rises (interlacing); with a rotary
/// inertia far above the membrane's the rocking is the lowest mode and its frequency falls as
/// 1/√I (the inertia enters the mass as I α̇²). The pad has the thin-disc inertia m a²/4 (a
/// the pad's 7.5 mm radius). A 3-D model refuses the key.
#[test]
fn a_pad_with_rotary_inertia_rocks_in_harmonic_one() {
    let sets: Vec<String> = [
        "mesh.radial=12",
        "mesh.layers=2",
        "materials.vhb.viscosity=0",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let settings = ModeSettings {
        count: 3,
        ..Default::default()
    };
    let lowest = |text: &str| -> (Vec<Mode>, Vec<usize>, Vec<f64>) {
        let mut scenario = parse(text, "t.toml", &sets).unwrap();
        scenario.stages.truncate(1);
        let plan = build(&scenario, "t.toml", None).unwrap();
        let plan = modes_plan(plan, &settings).unwrap();
        let loaded =
            loaded_modes_of_harmonics(&plan, &settings, &[1], RunOptions::default()).unwrap();
        let pad = plan.rigid[0].nodes.clone();
        let state = loaded.state.clone();
        (loaded.modes, pad, state)
    };
    let plain = lowest(example("diaphragm").unwrap()).0;
    let disc = 0.04622 * 7.5e-3f64.powi(2) / 4.0;
    let (tilting, pad, state) = lowest(&tilting_diaphragm(disc));
    for (a, b) in tilting.iter().zip(&plain) {
        assert!(
            a.frequency <= b.frequency * (1.0 + 1e-9),
            "{} {}",
            a.frequency,
            b.frequency
        );
    }
    // the rocking mode: the one whose pad tilts most per unit modal mass
    let tilt_of = |m: &Mode| {
        let a = *pad
            .iter()
            .max_by(|&&a, &&b| state[a * 4].total_cmp(&state[b * 4]))
            .unwrap();
        m.shape[a * 4 + 1].abs()
    };
    let rock = tilting
        .iter()
        .max_by(|a, b| tilt_of(a).total_cmp(&tilt_of(b)))
        .unwrap();
    assert!(plain
        .iter()
        .all(|p| (p.frequency / rock.frequency - 1.0).abs() > 0.1));
    // u_z = −α r on the pad: the same α at every pad node off the axis
    let mut alphas = Vec::new();
    let plan = build(
        &parse(&tilting_diaphragm(disc), "t.toml", &sets).unwrap(),
        "t.toml",
        None,
    )
    .unwrap();
    for &a in &pad {
        let r = plan.model.mesh.nodes[a][0] + state[a * 4];
        if r > 0.0 {
            alphas.push(-rock.shape[a * 4 + 1] / r);
        }
    }
    assert!(alphas[0].abs() > 0.0);
    for a in &alphas {
        assert!((a / alphas[0] - 1.0).abs() < 1e-9, "{alphas:?}");
    }
    let heavy = lowest(&tilting_diaphragm(1e-2)).0[0].frequency;
    let heavier = lowest(&tilting_diaphragm(4e-2)).0[0].frequency;
    let hz = |m: &[Mode]| m.iter().map(|m| m.frequency).collect::<Vec<_>>();
    println!(
        "harmonic 1: no tilt {:.4?} Hz; I = {disc:.3e} kg·m² {:.4?} Hz, rocking {:.4} Hz; \
         lowest with I = 1e-2 {heavy:.5} Hz, 4e-2 {heavier:.5} Hz (ratio {:.5})",
        hz(&plain),
        hz(&tilting),
        rock.frequency,
        heavier / heavy
    );
    assert!((heavier / heavy - 0.5).abs() < 5e-3);
    // a 3-D model's rigid regions do not rotate
    let dir = common::tempdir("harmonic-tilt");
    let text = example("diaphragm-3d").unwrap().replace(
        "mass = 0.04622                # kg, the whole attached mass",
        "mass = 0.04622\nrotary_inertia = 1e-6",
    );
    std::fs::write(dir.join("t.toml"), text).unwrap();
    let o = common::deasim(&["check", "t.toml", "--no-trial"], &dir);
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(o.status.code(), Some(2), "{said}");
    assert!(said.contains("loads.rigid.0.rotary_inertia"), "{said}");
}
