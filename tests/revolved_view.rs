//! The revolved view of an axisymmetric run, end to end: `deasim run` writes
//! `fields/revolved_NNNNN.vtu` and `fields_revolved.pvd` beside the meridian section's files, with
//! the section swept about the z axis (a ring of points per angle: one more than the wedges for a
//! partial sector, as many as the wedges for a full turn), the displacement and the fields turned
//! to Cartesian components; `output.revolve = false` writes none and clears those of an earlier
//! run.

mod common;

use common::vtu::{read_vtu, VtuData};
use common::{deasim, tempdir};
use std::path::Path;
use std::process::Output;

/// A charged film disc: a quad4 meridian section of 4 × 2 cells (15 nodes, 5 of them on the
/// axis), two static steps.
const SCENARIO: &str = r#"name = "ring"
[mesh]
geometry = "axisymmetric"
generator = "rectangle"
radius = 10e-3
thickness = 1e-3
radial = 4
layers = 2
element = "quad4"

[materials.elastomer]
model = "neo-hooke"
mu = 1e5
lambda = 1e7
permittivity = 4.7

[[constraints]]
set = "bottom"
fix = ["z"]

[electrodes.bottom]
set = "bottom"
voltage = 0.0

[electrodes.top]
set = "top"
voltage = { waveform = "ramp", amplitude = 20e3 }

[[stages]]
name = "charge"
kind = "static"
steps = 2

[output]
plots = false
"#;

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned() + &String::from_utf8_lossy(&o.stdout)
}

/// Runs the scenario with `output` appended to its `[output]` table (and `element` as its cell
/// kind) into `dir/out`.
fn run(dir: &Path, element: &str, output: &str) {
    let scenario = SCENARIO.replace("\"quad4\"", &format!("\"{element}\"")) + output;
    std::fs::write(dir.join("ring.toml"), scenario).unwrap();
    let o = deasim(&["run", "ring.toml", "--out", "out"], dir);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
}

/// The (time, file) entries of a `.pvd` file.
fn pvd(path: &Path) -> Vec<(String, String)> {
    let text = std::fs::read_to_string(path).unwrap();
    let attr = |line: &str, name: &str| {
        let start = line.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
        line[start..].split('"').next().unwrap().to_string()
    };
    text.lines()
        .filter(|l| l.contains("<DataSet"))
        .map(|l| (attr(l, "timestep"), attr(l, "file")))
        .collect()
}

fn array<'a>(data: &'a VtuData, name: &str, cells: bool) -> &'a [f64] {
    let arrays = if cells {
        &data.cell_data
    } else {
        &data.point_data
    };
    &arrays
        .get(name)
        .unwrap_or_else(|| panic!("no array {name}"))
        .1
}

fn sorted(mut v: Vec<f64>) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    v
}

#[test]
fn a_partial_sector_sweeps_the_section_into_rings_of_hexahedra() {
    let dir = tempdir("revolved-partial");
    run(&dir, "quad4", "revolve_sector = 90\nrevolve_wedges = 3\n");
    let out = dir.join("out");
    let section = pvd(&out.join("fields.pvd"));
    let revolved = pvd(&out.join("fields_revolved.pvd"));
    assert_eq!(section.len(), 3, "{section:?}");
    assert_eq!(revolved.len(), section.len());
    for (k, ((ts, fs), (tr, fr))) in section.iter().zip(&revolved).enumerate() {
        assert_eq!(ts, tr);
        assert_eq!(fs, &format!("fields/step_{k:05}.vtu"));
        assert_eq!(fr, &format!("fields/revolved_{k:05}.vtu"));
    }
    let s = read_vtu(&out.join(&section[2].1)).unwrap();
    let r = read_vtu(&out.join(&revolved[2].1)).unwrap();
    let (nodes, cells, wedges) = (s.points.len(), s.types.len(), 3);
    assert_eq!((nodes, cells), (15, 8));
    assert_eq!(r.points.len(), nodes * (wedges + 1));
    assert_eq!(r.types, vec![12u8; cells * wedges]);
    assert_eq!(r.connectivity.len(), 8 * cells * wedges);
    // the same arrays, as many components
    for (cells, a, b) in [
        (false, &s.point_data, &r.point_data),
        (true, &s.cell_data, &r.cell_data),
    ] {
        let names: Vec<(&String, usize)> = a.iter().map(|(n, (c, _))| (n, *c)).collect();
        let other: Vec<(&String, usize)> = b.iter().map(|(n, (c, _))| (n, *c)).collect();
        assert_eq!(names, other, "cell data: {cells}");
    }
    let (u, ur) = (
        array(&s, "displacement", false),
        array(&r, "displacement", false),
    );
    let (phi, phir) = (array(&s, "potential", false), array(&r, "potential", false));
    assert!(u.iter().any(|&v| v.abs() > 1e-7), "the film deforms");
    for j in 0..=wedges {
        let (sin, cos) = (j as f64 * 30f64.to_radians()).sin_cos();
        for p in 0..nodes {
            let (x, y) = (s.points[p], r.points[j * nodes + p]);
            let want = [x[0] * cos, x[0] * sin, x[1]];
            assert!(
                (0..3).all(|i| (y[i] - want[i]).abs() < 1e-15),
                "{y:?} {want:?}"
            );
            let (a, b) = (
                &u[p * 3..p * 3 + 3],
                &ur[(j * nodes + p) * 3..(j * nodes + p) * 3 + 3],
            );
            let want = [a[0] * cos, a[0] * sin, a[1]];
            assert!(
                (0..3).all(|i| (b[i] - want[i]).abs() < 1e-18),
                "{b:?} {want:?}"
            );
            assert_eq!(phir[j * nodes + p], phi[p]);
        }
    }
    // scalars are copied to every wedge; a field keeps its magnitude and axial component
    let j = array(&s, "J", true);
    let repeated: Vec<f64> = (0..wedges).flat_map(|_| j.iter().copied()).collect();
    assert_eq!(sorted(array(&r, "J", true).to_vec()), sorted(repeated));
    let norms = |e: &[f64]| -> Vec<f64> {
        e.chunks(3)
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .collect()
    };
    let (e, er) = (
        array(&s, "electric_field", true),
        array(&r, "electric_field", true),
    );
    let ns = norms(e);
    let nr = sorted(norms(er));
    let want = sorted((0..wedges).flat_map(|_| ns.iter().copied()).collect());
    assert!(nr.iter().zip(&want).all(|(a, b)| (a - b).abs() <= 1e-9 * b));
    assert!(ns.iter().any(|&n| n > 1e6), "a field through the film");
    // the trace of every stress is kept
    let traces = |t: &[f64]| -> Vec<f64> { t.chunks(9).map(|t| t[0] + t[4] + t[8]).collect() };
    let tr = sorted(traces(array(&r, "mechanical_stress", true)));
    let ts = traces(array(&s, "mechanical_stress", true));
    let want = sorted((0..wedges).flat_map(|_| ts.iter().copied()).collect());
    let scale = want.iter().fold(0f64, |m, v| m.max(v.abs()));
    assert!(scale > 0.0);
    assert!(tr
        .iter()
        .zip(&want)
        .all(|(a, b)| (a - b).abs() <= 1e-12 * scale));
}

#[test]
fn a_full_turn_of_triangles_closes_into_wedges_and_can_be_switched_off() {
    let dir = tempdir("revolved-full");
    run(&dir, "tri3", "revolve_sector = 360\nrevolve_wedges = 6\n");
    let out = dir.join("out");
    let s = read_vtu(&out.join("fields/step_00002.vtu")).unwrap();
    let r = read_vtu(&out.join("fields/revolved_00002.vtu")).unwrap();
    // a full turn: the last wedge closes onto the first ring
    assert_eq!(r.points.len(), s.points.len() * 6);
    assert_eq!(r.types, vec![13u8; s.types.len() * 6]);
    assert!(r.connectivity.iter().all(|&p| p < r.points.len()));
    // the default: revolved; switched off, a new run leaves none of the earlier files
    run(&dir, "tri3", "revolve = false\n");
    assert!(!out.join("fields_revolved.pvd").exists());
    let mut left: Vec<String> = std::fs::read_dir(out.join("fields"))
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["step_00000.vtu", "step_00001.vtu", "step_00002.vtu"]);
    // and on by default, with 27 wedges over 270°: 28 rings
    run(&dir, "quad4", "");
    let r = read_vtu(&out.join("fields/revolved_00000.vtu")).unwrap();
    assert_eq!(r.points.len(), 15 * 28);
    assert_eq!(r.types.len(), 8 * 27);
}
