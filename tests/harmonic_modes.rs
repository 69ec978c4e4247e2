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

use deasim::api::{loaded_modes_of_harmonics, modes_plan, FieldsKept, RunOptions, Simulation};
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
use deasim::problem::statics::nodal_reactions;
use deasim::solve::newton::NewtonSettings;
use deasim::solve::stepping::StepControl;
use deasim::time::harmonic::harmonic_modes;
use deasim::time::mass::{MassKind, NodalMass};
use deasim::time::modal::{modes, Mode, ModeSettings};
use std::collections::BTreeMap;
use std::sync::Arc;

const RADIUS: f64 = 10e-3;
const THICKNESS: f64 = 0.1e-3;
const STRETCH: f64 = 1.5;
const MU: f64 = 1e5;
const RHO0: f64 = 1000.0;

/// The stretched membrane on `nr` quad8 cells across the radius, its bottom face grounded and
/// its top face at `volts`, solved.
struct Membrane {
    model: Model,
    state: Vec<f64>,
    mass: NodalMass,
    /// In-plane Cauchy stress (Pa) from the material's total stress at the solved state.
    sigma: f64,
    /// In-plane Cauchy stress (Pa) from the radial reaction of the held rim.
    sigma_rim: f64,
    /// Current density (kg/m³).
    rho: f64,
}

/// [`Membrane`] on `nr` cells with its top face at `volts`.
fn membrane(nr: usize, volts: f64) -> Membrane {
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
    model.fix("top", Field::Phi, volts).unwrap();
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
    // the homogeneous state: F = diag(λ, λ_z, λ) and E₀ = −∂Φ/∂Z in (R, Z, Θ)
    let f = Mat3::from_diagonal(&Vec3::new(STRETCH, lz, STRETCH));
    let e0 = Vec3::new(0.0, -volts / THICKNESS, 0.0);
    let j = f.determinant();
    let p = material.stress(&f, &e0).unwrap().p;
    let sigma = p[(0, 0)] * STRETCH / j;
    // the rim's radial reactions sum to σ times the current rim area 2π λa λ_z H (the ring
    // weights carry 2π)
    let reactions = nodal_reactions(&model, &state).unwrap();
    let force: f64 = model.mesh.node_sets["outer"]
        .iter()
        .map(|&a| reactions[a * 4])
        .sum();
    let sigma_rim = force / (2.0 * std::f64::consts::PI * STRETCH * RADIUS * lz * THICKNESS);
    let mass = NodalMass::new(&model, &[RHO0], MassKind::Consistent);
    Membrane {
        model,
        state,
        mass,
        sigma,
        sigma_rim,
        rho: RHO0 / j,
    }
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
        let m = membrane(nr, 0.0);
        let c = (m.sigma / m.rho).sqrt();
        for (n, j) in zeros.iter().enumerate() {
            let exact = j / (2.0 * std::f64::consts::PI * STRETCH * RADIUS) * c;
            let f = lowest_transverse(&m.model, &m.state, &m.mass, n as u32).frequency;
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

/// The top face's bias (V): the Maxwell stress εE² takes about 30 % off the in-plane stress.
const BIAS: f64 = 1700.0;

/// At a voltage bias (top face at [`BIAS`], bottom grounded, both held at their voltages in the
/// perturbation) the membrane's tension is its total in-plane Cauchy stress σ (mechanical plus
/// Maxwell), taken from the solved state: the rim's radial reaction over the current rim area,
/// which equals the material's total stress at a point. The lowest out-of-plane frequencies of
/// harmonics 0, 1 and 2 approach j_n1/(2πa)√(σ/ρ) under refinement (8, 16, 32 cells), and lie
/// well below those of the grounded membrane's stress.
#[test]
fn membrane_harmonics_at_a_voltage_bias_follow_the_total_stress() {
    let zeros = [2.4048, 3.8317, 5.1356];
    let grounded = membrane(8, 0.0);
    assert!((grounded.sigma_rim / grounded.sigma - 1.0).abs() < 1e-8);
    let mut errors = vec![Vec::new(); 3];
    for nr in [8, 16, 32] {
        let m = membrane(nr, BIAS);
        assert!(
            (m.sigma_rim / m.sigma - 1.0).abs() < 1e-8,
            "rim {} Pa against the material {} Pa",
            m.sigma_rim,
            m.sigma
        );
        let drop = 1.0 - m.sigma_rim / grounded.sigma_rim;
        println!(
            "nr = {nr}: σ = {:.2} Pa at {BIAS} V against {:.2} Pa grounded ({:.1} % less), \
             ρ = {:.3} kg/m³",
            m.sigma_rim,
            grounded.sigma_rim,
            100.0 * drop,
            m.rho
        );
        assert!((0.25..0.35).contains(&drop), "{drop}");
        let c = (m.sigma_rim / m.rho).sqrt();
        for (n, j) in zeros.iter().enumerate() {
            let exact = j / (2.0 * std::f64::consts::PI * STRETCH * RADIUS) * c;
            let f = lowest_transverse(&m.model, &m.state, &m.mass, n as u32).frequency;
            let e = f / exact - 1.0;
            let unbiased = exact * (grounded.sigma_rim / m.sigma_rim).sqrt();
            println!(
                "nr = {nr}, n = {n}: {f:.4} Hz against {exact:.4} Hz ({e:+.3e}); \
                 with the grounded stress {unbiased:.4} Hz"
            );
            assert!(f < 0.9 * unbiased);
            errors[n].push(e.abs());
        }
    }
    // from above, falling by about 0.55–0.6 per halving (a little slower than grounded: the
    // biased membrane's differences are about 3e-4 larger at every nr)
    for (n, e) in errors.iter().enumerate() {
        assert!(e[2] < 1e-3, "n = {n}: {e:?}");
        assert!(
            e[1] < 0.65 * e[0] && e[2] < 0.65 * e[1],
            "n = {n} does not converge: {e:?}"
        );
    }
}

/// Axis conditions: the modes of harmonic 2 do not move the axis; those of harmonic 1 translate
/// it laterally only (u_z = Φ = 0, u_θ = −u_r), and some do.
#[test]
fn axis_nodes_follow_the_regularity_conditions() {
    let Membrane {
        model, state, mass, ..
    } = membrane(8, 0.0);
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
    // a frequency response takes harmonic 0, the only one an electrode's voltage drives
    std::fs::write(
        dir.join("resp0.toml"),
        diaphragm_with("kind = \"frequency-response\"\nharmonic = 0\nfrom = 1.0\nto = 10.0"),
    )
    .unwrap();
    let o = common::deasim(&["check", "resp0.toml", "--no-trial"], &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let o = common::deasim(&["check", "resp.toml", "--no-trial"], &dir);
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(said.contains("every angle"), "{said}");
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
/// the pad's 7.5 mm radius). A quarter 3-D model refuses the key.
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
    // a quarter 3-D disc's symmetry planes hold the tilt
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

/// The harmonic (0…`max`) whose cos nθ/sin nθ components hold most of a 3-D mode's displacement
/// on the annulus (nodes at R ≥ `inner`, grouped in rings of equal (R, Z), each with its nodes
/// equally spaced in θ), and the fraction of the displacement it holds.
fn angular_harmonic(nodes: &[[f64; 3]], shape: &[f64], inner: f64, max: u32) -> (u32, f64) {
    let mut rings: BTreeMap<(i64, i64), Vec<usize>> = BTreeMap::new();
    for (a, x) in nodes.iter().enumerate() {
        let r = x[0].hypot(x[1]);
        if r >= inner {
            rings
                .entry(((r * 1e8).round() as i64, (x[2] * 1e8).round() as i64))
                .or_default()
                .push(a);
        }
    }
    let mut energy = vec![0.0; max as usize + 1];
    let mut total = 0.0;
    for ring in rings.values() {
        let mut cyl = Vec::new();
        for &a in ring {
            let th = nodes[a][1].atan2(nodes[a][0]);
            let (c, s) = (th.cos(), th.sin());
            let (ux, uy, uz) = (shape[a * 4], shape[a * 4 + 1], shape[a * 4 + 2]);
            let u = [c * ux + s * uy, -s * ux + c * uy, uz];
            total += u.iter().map(|v| v * v).sum::<f64>();
            cyl.push((th, u));
        }
        let k = ring.len() as f64;
        for (n, e) in energy.iter_mut().enumerate() {
            let nf = n as f64;
            for comp in 0..3 {
                let (mut pc, mut ps) = (0.0, 0.0);
                for (th, u) in &cyl {
                    pc += u[comp] * (nf * th).cos();
                    ps += u[comp] * (nf * th).sin();
                }
                // Parseval on k equally spaced angles: Σu² = (a₀² k) + Σ_n (a_n² + b_n²) k/2
                *e += if n == 0 {
                    pc * pc / k
                } else {
                    2.0 * (pc * pc + ps * ps) / k
                };
            }
        }
    }
    let (n, e) = energy
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap();
    (n as u32, e / total)
}

/// The modes of `diaphragm-3d` as a full disc (`quarter = false`, no symmetry planes) after its
/// `load` stage, with `sets`: the `count` lowest, grouped by their harmonic
/// ([`angular_harmonic`], 0…6) as (frequency, fraction) lowest first, and the cells around.
struct FullDisc {
    family: Vec<Vec<(f64, f64)>>,
    around: usize,
}

fn full_disc_modes(sets: &[String], count: usize) -> FullDisc {
    let full = example("diaphragm-3d")
        .unwrap()
        .replace("quarter = true", "quarter = false")
        .replace(
            "[[constraints]]\nset = \"symmetry_x\"\nfix = [\"x\"]\n\n[[constraints]]\nset = \"symmetry_y\"\nfix = [\"y\"]\n",
            "",
        );
    assert!(!full.contains("symmetry_"));
    let settings = ModeSettings {
        count,
        ..Default::default()
    };
    let mut scenario = parse(&full, "t.toml", sets).unwrap();
    scenario.stages.truncate(1);
    let plan = modes_plan(build(&scenario, "t.toml", None).unwrap(), &settings).unwrap();
    let loaded = loaded_modes_of_harmonics(&plan, &settings, &[0], RunOptions::default()).unwrap();
    let nodes = &plan.model.mesh.nodes;
    // the annulus, outside the pad's radius
    let inner = 1.001 * 3.75e-3;
    let mut family: Vec<Vec<(f64, f64)>> = vec![Vec::new(); 7];
    let mut described = Vec::new();
    for m in &loaded.modes {
        let (n, fraction) = angular_harmonic(nodes, &m.shape, inner, 6);
        described.push(format!("{:.3} Hz n = {n} ({fraction:.3})", m.frequency));
        family[n as usize].push((m.frequency, fraction));
    }
    println!("3-D {sets:?}: {}", described.join(", "));
    // the rim's nodes over its node layers
    let rim = &plan.model.mesh.node_sets["rim"];
    let mut heights: Vec<i64> = rim
        .iter()
        .map(|&a| (nodes[a][2] * 1e8).round() as i64)
        .collect();
    heights.sort_unstable();
    heights.dedup();
    FullDisc {
        family,
        around: rim.len() / heights.len(),
    }
}

/// The diaphragm (η = 0) after `load`, harmonics 0…3 of the axisymmetric model against the same
/// device meshed in 3-D as a full disc (`quarter = false`, no symmetry planes): each harmonic's
/// lowest frequency against the lowest 3-D mode whose displacement on the annulus varies as
/// cos nθ, sin nθ (a degenerate pair for n ≥ 1). Both meshes refined alike (radial 8, 12, 16
/// cells; 32, 48, 56 cells around the 3-D disc): the difference falls, for n = 2, 3 as 1/N² of
/// the N cells around (the 3-D disc's polygon). Harmonic 0 of a `modes` stage with
/// `harmonic = [0, 1, 2, 3]` is the stage without the key, to 1e-12.
#[test]
fn diaphragm_harmonics_zero_to_three_match_the_full_3d_disc() {
    const COUNT: usize = 3;
    let start = std::time::Instant::now();
    let mut differences = vec![Vec::new(); 4];
    let mut circumferential = Vec::new();
    for radial in [8, 12, 16] {
        let sets: Vec<String> = [
            format!("mesh.radial={radial}"),
            "mesh.layers=2".into(),
            "materials.vhb.viscosity=0".into(),
        ]
        .to_vec();
        // the axisymmetric model: two modes stages about the loaded state
        let text = with_stage(
            example("diaphragm").unwrap(),
            &format!(
                "kind = \"modes\"\ncount = {COUNT}\nharmonic = [0, 1, 2, 3]\n\n[[stages]]\n\
                 name = \"plain\"\nkind = \"modes\"\ncount = {COUNT}"
            ),
        );
        let results = Simulation::from_toml(&text, None)
            .with_overrides(&sets)
            .run(RunOptions {
                fields: FieldsKept::None,
                ..Default::default()
            })
            .unwrap();
        let stages = &results.summary.stages;
        let (all, plain) = (&stages[1], &stages[2]);
        assert_eq!(
            all.modes_harmonic,
            (0..4u32).flat_map(|n| [n; COUNT]).collect::<Vec<_>>()
        );
        assert_eq!(plain.modes_hz.len(), COUNT);
        for (a, b) in all.modes_hz.iter().zip(&plain.modes_hz) {
            assert!((a / b - 1.0).abs() <= 1e-12, "harmonic 0: {a} against {b}");
        }
        let axisymmetric: Vec<f64> = (0..4).map(|n| all.modes_hz[n * COUNT]).collect();
        // the full 3-D disc
        let disc = full_disc_modes(&sets, 28);
        circumferential.push(disc.around as f64);
        let family = disc.family;
        for n in 0..4 {
            let found = &family[n];
            assert!(found.len() > usize::from(n > 0), "n = {n}: {found:?}");
            let (f3, fraction) = found[0];
            assert!(fraction > 0.9, "n = {n}: {found:?}");
            if n > 0 {
                // its degenerate partner
                let (g3, other) = found[1];
                assert!(
                    (g3 / f3 - 1.0).abs() < 1e-3 && other > 0.9,
                    "n = {n}: {found:?}"
                );
            }
            let d = axisymmetric[n] / f3 - 1.0;
            println!(
                "radial {radial}, n = {n}: axisymmetric {:.4} Hz, 3-D {f3:.4} Hz ({d:+.3e})",
                axisymmetric[n]
            );
            differences[n].push(d.abs());
        }
    }
    println!("{:.1} s in all", start.elapsed().as_secs_f64());
    for (n, d) in differences.iter().enumerate() {
        assert!(d[2] < d[1] && d[1] < d[0], "n = {n}: {d:?}");
        assert!(d[2] < 5e-3, "n = {n}: {d:?}");
    }
    // what is left of n = 2, 3 is mostly the 3-D disc's polygon of N cells around: ∝ 1/N²
    for n in [2, 3] {
        let scaled: Vec<f64> = differences[n]
            .iter()
            .zip(&circumferential)
            .map(|(d, c)| d * c * c)
            .collect();
        println!("n = {n}: |difference| N² = {scaled:.3?} (N = {circumferential:?})");
        assert!(
            scaled.iter().all(|v| (v / scaled[2] - 1.0).abs() < 0.1),
            "n = {n}: {scaled:?}"
        );
    }
}

/// The example `diaphragm-modes` run through the library: `modes.csv` has three modes of each of
/// harmonics 0, 1 and 2 in its `harmonic` column. Every mode but the pad's rocking is within
/// 0.6 % of the nearest mode of its harmonic of the same actuator meshed in 3-D as a full disc
/// (the lowest of n = 0, 1, 2 within 0.1, 0.2 and 0.4 %: the differences of radial 12 above).
/// The pad's inertia is m a²/4 of a thin disc (a = 7.5 mm), and the rocking mode is the one mode
/// of harmonic 1 that the pad without it lacks, between that pad's first two (interlacing).
#[test]
fn the_diaphragm_modes_example() {
    let dir = common::tempdir("diaphragm-modes");
    let sim = Simulation::from_example("diaphragm-modes").unwrap();
    let plan = sim.plan().unwrap();
    let disc = 0.04622 * 7.5e-3f64.powi(2) / 4.0;
    let inertia = plan.rigid[0].rotary_inertia.unwrap();
    assert!(
        (inertia / disc - 1.0).abs() < 1e-4,
        "{inertia} against {disc}"
    );
    sim.run(RunOptions {
        out: Some(dir.join("run")),
        ..Default::default()
    })
    .unwrap();
    let text = std::fs::read_to_string(dir.join("run/modes.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "mode,frequency_hz,eigenvalue_rad2_per_s2,residual,harmonic"
    );
    let modes: Vec<(f64, u32)> = lines
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (c[1].parse().unwrap(), c[4].parse().unwrap())
        })
        .collect();
    assert_eq!(
        modes.iter().map(|m| m.1).collect::<Vec<_>>(),
        [0, 0, 0, 1, 1, 1, 2, 2, 2]
    );
    let of = |n: u32| -> Vec<f64> { modes.iter().filter(|m| m.1 == n).map(|m| m.0).collect() };
    // the pad without rotary inertia: its harmonic-1 modes
    let stiff = sim
        .text()
        .lines()
        .filter(|l| !l.starts_with("rotary_inertia"))
        .collect::<Vec<_>>()
        .join("\n");
    assert_ne!(stiff.len(), sim.text().len());
    let plain = Simulation::from_toml(&stiff, None)
        .run(RunOptions::default())
        .unwrap();
    let plain = &plain.summary.stages[1];
    let plain1: Vec<f64> = plain
        .modes_hz
        .iter()
        .zip(&plain.modes_harmonic)
        .filter(|m| *m.1 == 1)
        .map(|m| *m.0)
        .collect();
    let rocking: Vec<f64> = of(1)
        .into_iter()
        .filter(|f| plain1.iter().all(|p| (f / p - 1.0).abs() > 0.01))
        .collect();
    println!(
        "harmonic 1: {:.4?} Hz; without rotary inertia {plain1:.4?} Hz",
        of(1)
    );
    assert_eq!(rocking.len(), 1, "{rocking:?}");
    assert!(plain1[0] < rocking[0] && rocking[0] < plain1[1]);
    // against the full 3-D disc of the same mesh
    let full = full_disc_modes(&[], 28);
    for (n, lowest) in [(0u32, 1e-3), (1, 2e-3), (2, 4e-3)] {
        let three_d: Vec<f64> = full.family[n as usize].iter().map(|m| m.0).collect();
        for (i, f) in of(n).into_iter().enumerate() {
            if n == 1 && f == rocking[0] {
                continue;
            }
            let near = three_d
                .iter()
                .copied()
                .min_by(|a, b| (a - f).abs().total_cmp(&(b - f).abs()))
                .unwrap();
            let d = f / near - 1.0;
            println!("n = {n}: {f:.4} Hz against 3-D {near:.4} Hz ({d:+.3e})");
            assert!(
                d.abs() < if i == 0 { lowest } else { 6e-3 },
                "n = {n}: {f} {near}"
            );
        }
    }
}

/// The pad's rocking against the full 3-D disc: the 3-D modes with the pad's region rotating
/// (`time::rigid_tilt`, the same rotary inertia m a²/4) give a degenerate pair at the
/// axisymmetric model's harmonic-1 rocking frequency, and their pads tilt (u_z linear across
/// the pad).
#[test]
fn the_rocking_pad_matches_the_full_3d_disc() {
    let sets: Vec<String> = [
        "mesh.radial=12",
        "mesh.layers=2",
        "materials.vhb.viscosity=0",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let disc = 0.04622 * 7.5e-3f64.powi(2) / 4.0;
    let settings = ModeSettings {
        count: 3,
        ..Default::default()
    };
    // the axisymmetric rocking: harmonic 1 with the tilt
    let mut scenario = parse(&tilting_diaphragm(disc), "t.toml", &sets).unwrap();
    scenario.stages.truncate(1);
    let plan = modes_plan(build(&scenario, "t.toml", None).unwrap(), &settings).unwrap();
    let loaded = loaded_modes_of_harmonics(&plan, &settings, &[1], RunOptions::default()).unwrap();
    let plain = {
        let mut s = parse(example("diaphragm").unwrap(), "t.toml", &sets).unwrap();
        s.stages.truncate(1);
        let p = modes_plan(build(&s, "t.toml", None).unwrap(), &settings).unwrap();
        loaded_modes_of_harmonics(&p, &settings, &[1], RunOptions::default())
            .unwrap()
            .modes
    };
    // the mode without a counterpart in the pad that cannot tilt
    let rock_axi = loaded
        .modes
        .iter()
        .map(|m| m.frequency)
        .max_by(|a, b| {
            let gap = |f: &f64| {
                plain
                    .iter()
                    .map(|p| (p.frequency / f - 1.0).abs())
                    .fold(f64::MAX, f64::min)
            };
            gap(a).total_cmp(&gap(b))
        })
        .unwrap();
    // the full 3-D disc after its load stage, its pad rotating (`rotary_inertia` in 3-D)
    let full = example("diaphragm-3d")
        .unwrap()
        .replace("quarter = true", "quarter = false")
        .replace(
            "[[constraints]]\nset = \"symmetry_x\"\nfix = [\"x\"]\n\n[[constraints]]\nset = \"symmetry_y\"\nfix = [\"y\"]\n",
            "",
        )
        .replace(
            "mass = 0.04622                # kg, the whole attached mass",
            &format!("mass = 0.04622\nrotary_inertia = {disc:e}"),
        );
    assert!(full.contains("rotary_inertia"));
    let mut s3 = parse(&full, "t.toml", &sets).unwrap();
    s3.stages.truncate(1);
    let eight = ModeSettings {
        count: 8,
        ..Default::default()
    };
    let plan3 = modes_plan(build(&s3, "t.toml", None).unwrap(), &eight).unwrap();
    let loaded3 = loaded_modes_of_harmonics(&plan3, &eight, &[0], RunOptions::default()).unwrap();
    let found = &loaded3.modes;
    let pad = plan3.rigid[0].nodes.clone();
    // a mode's tilt of the pad: the slope of u_z across the pad (least squares in x and y)
    let x = |a: usize| {
        let p = plan3.model.mesh.nodes[a];
        [0, 1].map(|i| p[i] + loaded3.state[a * 4 + i])
    };
    let tilt = |m: &Mode| -> f64 {
        let k = pad.len() as f64;
        let c = [0, 1].map(|i| pad.iter().map(|&a| x(a)[i]).sum::<f64>() / k);
        let uz0 = pad.iter().map(|&a| m.shape[a * 4 + 2]).sum::<f64>() / k;
        let (mut sxx, mut sxz, mut syy, mut syz) = (0.0, 0.0, 0.0, 0.0);
        for &a in &pad {
            let p = x(a);
            let (dx, dy, uz) = (p[0] - c[0], p[1] - c[1], m.shape[a * 4 + 2] - uz0);
            sxx += dx * dx;
            sxz += dx * uz;
            syy += dy * dy;
            syz += dy * uz;
        }
        (sxz / sxx).hypot(syz / syy)
    };
    let rocking: Vec<&Mode> = found
        .iter()
        .filter(|m| tilt(m) > 0.2 * found.iter().map(tilt).fold(0.0, f64::max))
        .collect();
    println!(
        "axisymmetric rocking {rock_axi:.4} Hz; 3-D with the pad rotating: {:?} Hz, rocking {:?}",
        found.iter().map(|m| m.frequency).collect::<Vec<_>>(),
        rocking.iter().map(|m| m.frequency).collect::<Vec<_>>()
    );
    assert_eq!(rocking.len(), 2, "a degenerate pair of rocking modes");
    for m in rocking {
        assert!(
            (rock_axi / m.frequency - 1.0).abs() < 5e-3,
            "{rock_axi} against {}",
            m.frequency
        );
    }
}
