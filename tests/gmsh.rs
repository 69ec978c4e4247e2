//! Meshes written by Gmsh (examples/film.geo → tests/data/gmsh/, tet4, tet10 and hex8 in MSH 4.1
//! ASCII, 4.1 binary and 2.2 ASCII) carry the homogeneous film (docs/theory.md).
//!
//! Reference: the closed-form homogeneous film state (`deasim::analytic::Film`); at 20 kV across
//! H = 1 mm (μ = 1e5 Pa, Λ = 1e7 Pa, εᵣ = 4.7) λ = 1.033231, t = 0.936966. All three kinds
//! interpolate the homogeneous state (linear in X) exactly and their quadrature integrates its
//! constant stress exactly, so on the unstructured Gmsh meshes too every node must sit where the
//! closed form puts it, to the Newton tolerance: |Δu|/X < 1e-8 and |ΔΦ| < 1e-9 V₀.
//! The scenario path (`mesh.file`, `mesh.scale`, physical groups as sets) is run through the binary,
//! for 3-D meshes and for the meridian meshes of axisymmetric models (tests/data/gmsh/meridian.geo).
//! An internal surface (the embedded electrode of tests/data/gmsh/bilayer.geo) is a face set and an
//! electrode like any other.

mod common;

use common::tempdir;
use deasim::analytic::Film;
use deasim::job::statics::solve_static;
use deasim::material::{ElectroNeoHooke, EPSILON_0};
use deasim::mesh::gmsh::read_msh;
use deasim::mesh::ElementKind;
use deasim::problem::dofs::Field;
use deasim::problem::examples::{FILM_EPS_R, FILM_LAMBDA, FILM_MU};
use deasim::problem::model::Model;
use deasim::solve::newton::NewtonSettings;
use deasim::solve::stepping::StepControl;
use deasim::time::mass::{MassKind, NodalMass};
use std::path::{Path, PathBuf};
use std::sync::Arc;

const H: f64 = 1e-3;
const VOLTAGE: f64 = 20e3;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/gmsh")
        .join(name)
}

fn files() -> Vec<(ElementKind, String)> {
    let mut v = Vec::new();
    for (kind, k) in [
        (ElementKind::Hex8, "hex8"),
        (ElementKind::Tet4, "tet4"),
        (ElementKind::Tet10, "tet10"),
    ] {
        for f in ["msh41", "msh41-bin", "msh22"] {
            v.push((kind, format!("film-{k}-{f}.msh")));
        }
    }
    v
}

fn film_model(file: &str) -> Model {
    let g = read_msh(&data(file), 1e-3).unwrap();
    let mat = Arc::new(ElectroNeoHooke::new(FILM_MU, FILM_LAMBDA, FILM_EPS_R));
    let mut model = Model::new(g.mesh, mat).unwrap();
    model.fix("x0", Field::Ux, 0.0).unwrap();
    model.fix("y0", Field::Uy, 0.0).unwrap();
    model.fix("bottom", Field::Uz, 0.0).unwrap();
    model.fix("bottom", Field::Phi, 0.0).unwrap();
    model.fix("top", Field::Phi, VOLTAGE).unwrap();
    model
}

#[test]
fn film_on_gmsh_meshes_matches_the_closed_form() {
    let reference = Film {
        mu: FILM_MU,
        lambda: FILM_LAMBDA,
        eps: FILM_EPS_R * EPSILON_0,
        c2: 0.0,
    };
    let s = reference.state(VOLTAGE / H).unwrap();
    assert!((s.lambda - 1.033231).abs() < 1e-6 && (s.t - 0.936966).abs() < 1e-6);
    for (kind, file) in files() {
        let model = film_model(&file);
        assert_eq!(model.mesh.kind, kind);
        let out = solve_static(
            &model,
            None,
            &StepControl {
                steps: 4,
                ..Default::default()
            },
            &NewtonSettings::default(),
            |_, _| {},
        );
        out.result.expect("20 kV is below pull-in");
        let (mut du, mut dphi) = (0.0f64, 0.0f64);
        for (n, x) in model.mesh.nodes.iter().enumerate() {
            for i in 0..3 {
                let stretch = if i == 2 { s.t } else { s.lambda };
                if x[i] > 0.0 {
                    let got = out.state[n * 4 + i];
                    du = du.max((got - (stretch - 1.0) * x[i]).abs() / x[i]);
                }
            }
            dphi = dphi.max((out.state[n * 4 + 3] - VOLTAGE * x[2] / H).abs() / VOLTAGE);
        }
        eprintln!(
            "{file}: {} cells, {} nodes: max |Δu|/X = {du:.2e}, max |ΔΦ|/V = {dphi:.2e}",
            model.mesh.n_cells(),
            model.mesh.n_nodes()
        );
        assert!(du < 1e-8 && dphi < 1e-9, "{file}: {du:e} {dphi:e}");
    }
}

/// Mass of the film from each file: ρV in total, consistent and lumped; lumped masses positive
/// (HRZ for tet10, whose row sums are negative at the corners).
#[test]
fn film_mass_from_gmsh_meshes() {
    let rho = 1000.0;
    let mass = rho * 10e-3 * 10e-3 * H;
    for (kind, file) in files() {
        let model = film_model(&file);
        for mk in [MassKind::Consistent, MassKind::Lumped] {
            let m = NodalMass::new(&model, &[rho], mk);
            assert!((m.total() - mass).abs() < 1e-12 * mass, "{file} {mk:?}");
            if mk == MassKind::Lumped {
                assert!(m.values.iter().all(|&v| v > 0.0), "{file}");
            }
        }
        if kind == ElementKind::Tet10 {
            // row sums of the consistent tet10 mass: negative at corner nodes
            let m = NodalMass::new(&model, &[rho], MassKind::Consistent);
            let negative = (0..model.mesh.n_nodes())
                .filter(|&a| m.values[m.row_ptr[a]..m.row_ptr[a + 1]].iter().sum::<f64>() < 0.0)
                .count();
            assert!(negative > 0, "{file}: row-sum lumping would be valid");
        }
    }
}

/// `deasim run` on tests/data/gmsh/film.toml (tet10 file, physical groups `top`/`bottom`, scale
/// 1e-3), and with `--set mesh.file=` switched to the hex8 MSH 2.2 file: the probes reach the closed
/// form and the VTU cells are VTK quadratic tetrahedra (24) or hexahedra (12).
#[test]
fn scenario_with_a_gmsh_file_runs() {
    let reference = Film {
        mu: FILM_MU,
        lambda: FILM_LAMBDA,
        eps: FILM_EPS_R * EPSILON_0,
        c2: 0.0,
    };
    let s = reference.state(VOLTAGE / H).unwrap();
    for (file, vtk) in [(None, 24u8), (Some("film-hex8-msh22.msh"), 12)] {
        let out_dir = tempdir(&format!("run-{vtk}"));
        let mut args = vec![
            "run".to_string(),
            data("film.toml").display().to_string(),
            "--out".into(),
            out_dir.display().to_string(),
        ];
        if let Some(f) = file {
            args.push("--set".into());
            args.push(format!("mesh.file={f}"));
        }
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_deasim"))
            .args(&args)
            .output()
            .unwrap();
        let msg = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{msg}");
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
                .unwrap();
        let t = summary["probes"]["thickness_stretch"].as_f64().unwrap();
        let l = summary["probes"]["inplane_stretch"].as_f64().unwrap();
        assert!(
            (t - s.t).abs() < 1e-8 && (l - s.lambda).abs() < 1e-8,
            "{t} {l}"
        );
        let fields = out_dir.join("fields");
        let vtu = std::fs::read_dir(&fields).unwrap().next().unwrap().unwrap();
        let d = common::vtu::read_vtu(&vtu.path()).unwrap();
        assert!(d.types.iter().all(|&t| t == vtk), "{:?}", d.types);
    }
}

/// `deasim run` on tests/data/gmsh/meridian.toml (an axisymmetric model on a Gmsh meridian mesh,
/// physical curves `top`/`bottom` as electrodes and supports), with `--set mesh.file=` switched to
/// every meridian kind and format: the probes reach the closed form of the film (the homogeneous
/// state is exact on every kind: u_r = (λ − 1)R, u_z = (t − 1)Z).
#[test]
fn axisymmetric_scenario_with_a_gmsh_meridian_file_runs() {
    let reference = Film {
        mu: FILM_MU,
        lambda: FILM_LAMBDA,
        eps: FILM_EPS_R * EPSILON_0,
        c2: 0.0,
    };
    let s = reference.state(VOLTAGE / H).unwrap();
    for kind in ["quad4", "quad8", "quad9", "tri3", "tri6"] {
        for format in ["msh41", "msh22", "msh41-bin"] {
            let file = format!("meridian-{kind}-{format}.msh");
            let out_dir = tempdir(&format!("meridian-{kind}-{format}"));
            let o = std::process::Command::new(env!("CARGO_BIN_EXE_deasim"))
                .arg("run")
                .arg(data("meridian.toml"))
                .arg("--out")
                .arg(&out_dir)
                .args(["--set", &format!("mesh.file={file}")])
                .output()
                .unwrap();
            let msg = String::from_utf8_lossy(&o.stderr).into_owned();
            assert!(o.status.success(), "{file}: {msg}");
            let summary: serde_json::Value = serde_json::from_str(
                &std::fs::read_to_string(out_dir.join("summary.json")).unwrap(),
            )
            .unwrap();
            let t = summary["probes"]["thickness_stretch"].as_f64().unwrap();
            let l = summary["probes"]["radial_stretch"].as_f64().unwrap();
            assert!(
                (t - s.t).abs() < 1e-8 && (l - s.lambda).abs() < 1e-8,
                "{file}: {t} {l}"
            );
        }
    }
}

/// Two 0.5 mm layers with the internal surface `middle` at 10 kV and the outer faces grounded: each
/// layer carries 2e7 V/m (opposite directions), so the whole body takes the homogeneous state of the
/// film at 20 kV across 1 mm, and Φ is the tent 10 kV·(1 − |z − 0.5 mm|/0.5 mm): exact for tet4 and
/// tet10 on meshes written by Gmsh (the kink lies on the mesh's internal surface).
#[test]
fn internal_surface_electrode_on_a_gmsh_bilayer() {
    let reference = Film {
        mu: FILM_MU,
        lambda: FILM_LAMBDA,
        eps: FILM_EPS_R * EPSILON_0,
        c2: 0.0,
    };
    let v = 10e3;
    let half = 0.5e-3;
    let s = reference.state(v / half).unwrap();
    for file in ["bilayer-tet10-msh41.msh", "bilayer-tet4-msh22.msh"] {
        let g = read_msh(&data(file), 1e-3).unwrap();
        let m = &g.mesh;
        let (lower, upper) = (&m.cell_sets["lower"], &m.cell_sets["upper"]);
        assert_eq!(lower.len() + upper.len(), m.n_cells(), "{file}");
        assert!(lower.iter().all(|c| upper.binary_search(c).is_err()));
        let on_middle: Vec<usize> = (0..m.n_nodes())
            .filter(|&n| (m.nodes[n][2] - half).abs() < 1e-12)
            .collect();
        assert_eq!(m.node_sets["middle"], on_middle, "{file}");
        assert_eq!(m.face_set_nodes("middle").unwrap(), on_middle, "{file}");
        let mat = Arc::new(ElectroNeoHooke::new(FILM_MU, FILM_LAMBDA, FILM_EPS_R));
        let mut model = Model::new(g.mesh, mat).unwrap();
        model.fix("x0", Field::Ux, 0.0).unwrap();
        model.fix("y0", Field::Uy, 0.0).unwrap();
        model.fix("bottom", Field::Uz, 0.0).unwrap();
        model.fix("bottom", Field::Phi, 0.0).unwrap();
        model.fix("top", Field::Phi, 0.0).unwrap();
        model.fix("middle", Field::Phi, v).unwrap();
        let out = solve_static(
            &model,
            None,
            &StepControl {
                steps: 4,
                ..Default::default()
            },
            &NewtonSettings::default(),
            |_, _| {},
        );
        out.result.expect("below pull-in");
        let (mut du, mut dphi) = (0.0f64, 0.0f64);
        for (n, x) in model.mesh.nodes.iter().enumerate() {
            for i in 0..3 {
                let stretch = if i == 2 { s.t } else { s.lambda };
                if x[i] > 0.0 {
                    let got = out.state[n * 4 + i];
                    du = du.max((got - (stretch - 1.0) * x[i]).abs() / x[i]);
                }
            }
            let phi = v * (1.0 - (x[2] - half).abs() / half);
            dphi = dphi.max((out.state[n * 4 + 3] - phi).abs() / v);
        }
        eprintln!(
            "{file}: {} cells, {} internal faces: max |Δu|/X = {du:.2e}, max |ΔΦ|/V = {dphi:.2e}",
            model.mesh.n_cells(),
            model.mesh.face_sets["middle"].len()
        );
        assert!(du < 1e-8 && dphi < 1e-9, "{file}: {du:e} {dphi:e}");
    }
}
