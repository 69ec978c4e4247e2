//! Meshes of the meridian plane (R, Z) for axisymmetric models: structured grids of
//! quadrilaterals or triangles (linear or quadratic) on a rectangle R ∈ [R₀, R₁], Z ∈ [0, H],
//! and the circular actuator (disc) in meridian form.
//!
//! Nodes carry (R, Z, 0). Sets (tolerance `1e-9` of the largest extent):
//! * rectangle: node and face sets `inner` (R = R₀; also `axis` when R₀ = 0), `outer` (R = R₁),
//!   `bottom` (Z = 0), `top` (Z = H); cell set `all`;
//! * disc: as the 3-D disc generator, without the symmetry planes: node and face sets `rim`,
//!   `top`, `bottom`, `electrode_top`, `electrode_bottom`; node sets `pad` (R ≤ pad_radius),
//!   `rim_bottom` (the rim's bottom corner) and `axis`; cell sets `all`, `pad` and `annulus`.

use super::disc::DiscSpec;
use super::{ElementKind, FaceRef, MeridianKind, Mesh};
use std::collections::BTreeMap;

/// A structured meridian mesh on the grid lines `rs` (increasing R) × `zs` (increasing Z):
/// one quadrilateral per grid cell, or two triangles (split along the diagonal from the lower
/// left corner); quadratic kinds get their mid-side (and centre) nodes at the midpoints of the
/// grid lines. Face sets `inner`, `outer`, `bottom`, `top` (and the node sets of the same names,
/// plus `axis` when rs[0] = 0) and the cell set `all`.
pub fn structured(rs: &[f64], zs: &[f64], kind: MeridianKind) -> Result<Mesh, String> {
    let (nr, nz) = (rs.len().saturating_sub(1), zs.len().saturating_sub(1));
    if nr == 0 || nz == 0 {
        return Err("a meridian mesh needs at least one cell in R and in Z".into());
    }
    let increasing =
        |v: &[f64]| v.windows(2).all(|w| w[1] > w[0]) && v.iter().all(|x| x.is_finite());
    if !increasing(rs) || !increasing(zs) || rs[0] < 0.0 {
        return Err(format!(
            "meridian mesh: grid lines must increase and lie in R ≥ 0 (R from {} to {})",
            rs[0], rs[nr]
        ));
    }
    let quadratic = kind.is_quadratic();
    // the fine grid: every line, and for quadratic kinds the midlines between them
    let fine = |v: &[f64]| -> Vec<f64> {
        if !quadratic {
            return v.to_vec();
        }
        let mut out = Vec::with_capacity(2 * v.len() - 1);
        for w in v.windows(2) {
            out.push(w[0]);
            out.push(0.5 * (w[0] + w[1]));
        }
        out.push(v[v.len() - 1]);
        out
    };
    let (fr, fz) = (fine(rs), fine(zs));
    let s = if quadratic { 2 } else { 1 };
    let mut id = vec![usize::MAX; fr.len() * fz.len()];
    let mut nodes = Vec::new();
    let mut node = |i: usize, j: usize, nodes: &mut Vec<[f64; 3]>| -> usize {
        let k = j * fr.len() + i;
        if id[k] == usize::MAX {
            id[k] = nodes.len();
            nodes.push([fr[i], fz[j], 0.0]);
        }
        id[k]
    };
    let mut connectivity = Vec::new();
    let mut face_sets: BTreeMap<String, Vec<FaceRef>> = BTreeMap::new();
    for name in ["inner", "outer", "bottom", "top"] {
        face_sets.insert(name.into(), Vec::new());
    }
    let mut cell = 0;
    for j in 0..nz {
        for i in 0..nr {
            let (i0, j0) = (i * s, j * s);
            let mut n = |di: usize, dj: usize| node(i0 + di, j0 + dj, &mut nodes);
            // (cell, local side) of the sides on the boundary: bottom, outer, top, inner
            let sides: Vec<(usize, usize, &str)> = match kind {
                MeridianKind::Quad4 | MeridianKind::Quad8 | MeridianKind::Quad9 => {
                    let (a, b, c, d) = (n(0, 0), n(s, 0), n(s, s), n(0, s));
                    connectivity.extend([a, b, c, d]);
                    if quadratic {
                        connectivity.extend([n(1, 0), n(2, 1), n(1, 2), n(0, 1)]);
                        if kind == MeridianKind::Quad9 {
                            connectivity.push(n(1, 1));
                        }
                    }
                    cell += 1;
                    vec![
                        (cell - 1, 0, "bottom"),
                        (cell - 1, 1, "outer"),
                        (cell - 1, 2, "top"),
                        (cell - 1, 3, "inner"),
                    ]
                }
                MeridianKind::Tri3 | MeridianKind::Tri6 => {
                    // lower right triangle (a, b, c) and upper left (a, c, d)
                    let (a, b, c, d) = (n(0, 0), n(s, 0), n(s, s), n(0, s));
                    connectivity.extend([a, b, c]);
                    if quadratic {
                        connectivity.extend([n(1, 0), n(2, 1), n(1, 1)]);
                    }
                    connectivity.extend([a, c, d]);
                    if quadratic {
                        connectivity.extend([n(1, 1), n(1, 2), n(0, 1)]);
                    }
                    cell += 2;
                    vec![
                        (cell - 2, 0, "bottom"),
                        (cell - 2, 1, "outer"),
                        (cell - 1, 1, "top"),
                        (cell - 1, 2, "inner"),
                    ]
                }
            };
            for (c, side, name) in sides {
                let on = match name {
                    "bottom" => j == 0,
                    "top" => j + 1 == nz,
                    "inner" => i == 0,
                    _ => i + 1 == nr,
                };
                if on {
                    face_sets
                        .get_mut(name)
                        .expect("inserted above")
                        .push(FaceRef {
                            cell: c,
                            face: side,
                        });
                }
            }
        }
    }
    let mut mesh = Mesh {
        kind: ElementKind::Meridian(kind),
        nodes,
        connectivity,
        node_sets: BTreeMap::new(),
        face_sets,
        cell_sets: BTreeMap::from([("all".to_string(), (0..cell).collect())]),
    };
    mesh.insert_face_set_nodes();
    if rs[0] == 0.0 {
        let axis = mesh.node_sets["inner"].clone();
        mesh.node_sets.insert("axis".into(), axis);
    }
    Ok(mesh)
}

/// `n` equal cells from `a` to `b`: the `n + 1` grid lines.
pub fn uniform(a: f64, b: f64, n: usize) -> Vec<f64> {
    (0..=n).map(|k| a + (b - a) * k as f64 / n as f64).collect()
}

/// The rectangle R ∈ [r0, r1], Z ∈ [0, height] with `nr × nz` equal cells.
pub fn rectangle_mesh(
    r0: f64,
    r1: f64,
    height: f64,
    nr: usize,
    nz: usize,
    kind: MeridianKind,
) -> Result<Mesh, String> {
    if !(r0 >= 0.0 && r1 > r0 && height > 0.0 && r1.is_finite() && height.is_finite()) {
        return Err(format!(
            "rectangle mesh: need 0 ≤ inner radius ({r0}) < outer radius ({r1}) and a positive \
             height ({height})"
        ));
    }
    if nr == 0 || nz == 0 {
        return Err(format!(
            "rectangle mesh: divisions [{nr}, {nz}] (need at least one cell in R and in Z)"
        ));
    }
    structured(&uniform(r0, r1, nr), &uniform(0.0, height, nz), kind)
}

/// Most radial cells of the pad region of a meridian disc: a strongly graded annulus (tiny
/// cells at the pad) would ask for more than any machine holds.
const MAX_PAD_CELLS: usize = 100_000;

/// Radial cells of the pad region of a meridian disc: as many as make them about the size of
/// the annulus cells at the pad, at least 2.
fn pad_cells(spec: &DiscSpec, annulus: &[f64]) -> usize {
    let h = annulus[1] - annulus[0];
    ((spec.pad_radius / h).round() as usize).max(2)
}

/// The circular actuator of [`DiscSpec`] in meridian form: the pad region R ≤ pad_radius in
/// equal cells, the annulus on the 3-D generator's graded radii (a grid line at the electrode
/// radius), `layers` cells through the thickness. `spec.quarter` and `spec.kind` are not read.
pub fn disc_meridian(spec: &DiscSpec, kind: MeridianKind) -> Result<Mesh, String> {
    spec.validate()?;
    let (annulus, _) = super::disc::annulus_radii(spec);
    let np = pad_cells(spec, &annulus);
    if np > MAX_PAD_CELLS {
        return Err(format!(
            "disc mesh: the pad would take {np} radial cells of the size of the annulus's first \
             cell (more than {MAX_PAD_CELLS}): lower `grading` or `radial`, or give the annulus \
             more room (pad_radius {} of radius {})",
            spec.pad_radius, spec.radius
        ));
    }
    let mut rs = uniform(0.0, spec.pad_radius, np);
    rs.extend_from_slice(&annulus[1..]);
    let zs = uniform(0.0, spec.thickness, spec.layers);
    let mut mesh = structured(&rs, &zs, kind)?;
    let tol = 1e-9 * spec.radius;
    // rename the rectangle's sets to the disc's
    let faces = mesh
        .face_sets
        .remove("outer")
        .expect("made by `structured`");
    mesh.face_sets.insert("rim".into(), faces);
    let nodes = mesh
        .node_sets
        .remove("outer")
        .expect("made by `structured`");
    mesh.node_sets.insert("rim".into(), nodes);
    mesh.face_sets.remove("inner");
    mesh.node_sets.remove("inner");
    let r_of = |m: &Mesh, f: &FaceRef| {
        let cell = m.cell(f.cell);
        m.kind.faces()[f.face]
            .iter()
            .map(|&l| m.nodes[cell[l]][0])
            .fold(0.0, f64::max)
    };
    for (side, name) in [("top", "electrode_top"), ("bottom", "electrode_bottom")] {
        let faces: Vec<FaceRef> = mesh.face_sets[side]
            .iter()
            .filter(|f| r_of(&mesh, f) <= spec.electrode_radius + tol)
            .copied()
            .collect();
        mesh.face_sets.insert(name.into(), faces);
        let nodes = mesh.face_set_nodes(name).expect("inserted");
        mesh.node_sets.insert(name.into(), nodes);
    }
    let pad: Vec<usize> = (0..mesh.n_nodes())
        .filter(|&n| mesh.nodes[n][0] <= spec.pad_radius + tol)
        .collect();
    mesh.node_sets.insert("pad".into(), pad);
    let rim_bottom: Vec<usize> = mesh.node_sets["rim"]
        .iter()
        .copied()
        .filter(|&n| mesh.nodes[n][1].abs() <= tol)
        .collect();
    mesh.node_sets.insert("rim_bottom".into(), rim_bottom);
    let (mut pad_cells, mut annulus_cells) = (Vec::new(), Vec::new());
    for c in 0..mesh.n_cells() {
        if mesh.cell_centroid(c)[0] < spec.pad_radius {
            pad_cells.push(c);
        } else {
            annulus_cells.push(c);
        }
    }
    mesh.cell_sets.insert("pad".into(), pad_cells);
    mesh.cell_sets.insert("annulus".into(), annulus_cells);
    Ok(mesh)
}

/// The upper half (Z ≥ 0) of a spherical shell of inner radius `r1` and outer radius `r2` in
/// meridian form: `layers` cells through the wall, `arc` cells along the quarter meridian from
/// the equator (Z = 0) to the axis. Node and face sets `inner`, `outer`, `equator` (Z = 0), and
/// the node set `axis`; cell set `all`.
pub fn sphere_meridian(
    r1: f64,
    r2: f64,
    arc: usize,
    layers: usize,
    kind: MeridianKind,
) -> Result<Mesh, String> {
    if !(r1 > 0.0 && r2 > r1 && r2.is_finite()) {
        return Err(format!(
            "sphere mesh: need 0 < inner radius ({r1}) < outer radius ({r2})"
        ));
    }
    // a grid in (ρ, φ), φ the latitude (0 at the equator, π/2 on the axis), mapped to
    // R = ρ cos φ, Z = ρ sin φ (positive Jacobian ρ)
    let half_pi = std::f64::consts::FRAC_PI_2;
    let mut mesh = structured(&uniform(r1, r2, layers), &uniform(0.0, half_pi, arc), kind)?;
    for x in mesh.nodes.iter_mut() {
        let (rho, phi) = (x[0], x[1]);
        let on_axis = (phi - half_pi).abs() < 1e-12;
        *x = [
            if on_axis { 0.0 } else { rho * phi.cos() },
            if on_axis { rho } else { rho * phi.sin() },
            0.0,
        ];
    }
    for (from, to) in [("bottom", "equator"), ("top", "axis")] {
        if let Some(v) = mesh.face_sets.remove(from) {
            if to != "axis" {
                mesh.face_sets.insert(to.into(), v);
            }
        }
        if let Some(v) = mesh.node_sets.remove(from) {
            mesh.node_sets.insert(to.into(), v);
        }
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::axisymmetric::meridian_geometry;

    fn ring_volume(m: &Mesh) -> f64 {
        let kind = m.kind.meridian().expect("a meridian mesh");
        (0..m.n_cells())
            .map(|c| {
                let x: Vec<[f64; 2]> = m
                    .cell(c)
                    .iter()
                    .map(|&n| [m.nodes[n][0], m.nodes[n][1]])
                    .collect();
                let g = meridian_geometry(kind, &x).expect("valid cell");
                g.weights[..g.n_qp].iter().sum::<f64>()
            })
            .sum()
    }

    /// Every kind: valid cells, the annulus's volume exactly, boundary sides counted once and
    /// interior ones twice, the sets where they should be.
    #[test]
    fn rectangles_of_every_kind_are_valid_and_their_sets_lie_on_the_sides() {
        for kind in MeridianKind::ALL {
            let (r0, r1, h) = (1e-3, 5e-3, 2e-3);
            let m = rectangle_mesh(r0, r1, h, 4, 3, kind).unwrap();
            let v = std::f64::consts::PI * (r1 * r1 - r0 * r0) * h;
            assert!((ring_volume(&m) - v).abs() < 1e-13 * v, "{kind:?}");
            let counts = m.face_use_counts();
            let boundary = counts.values().filter(|&&c| c == 1).count();
            assert!(counts.values().all(|&c| c <= 2));
            let sides: usize = ["inner", "outer", "bottom", "top"]
                .iter()
                .map(|s| m.face_sets[*s].len())
                .sum();
            assert_eq!(boundary, sides, "{kind:?}");
            assert_eq!(sides, 2 * (4 + 3));
            for (name, coord, value) in [
                ("inner", 0, r0),
                ("outer", 0, r1),
                ("bottom", 1, 0.0),
                ("top", 1, h),
            ] {
                for &n in &m.node_sets[name] {
                    assert!((m.nodes[n][coord] - value).abs() < 1e-15, "{kind:?} {name}");
                }
                let per_side = if kind.is_quadratic() { 2 } else { 1 };
                let cells = if coord == 0 { 3 } else { 4 };
                assert_eq!(
                    m.node_sets[name].len(),
                    per_side * cells + 1,
                    "{kind:?} {name}"
                );
            }
            assert!(!m.node_sets.contains_key("axis"));
            let expected_nodes = match kind {
                MeridianKind::Quad4 | MeridianKind::Tri3 => 5 * 4,
                MeridianKind::Quad9 | MeridianKind::Tri6 => 9 * 7,
                MeridianKind::Quad8 => 9 * 7 - 4 * 3,
            };
            assert_eq!(m.n_nodes(), expected_nodes, "{kind:?}");
        }
        let m = rectangle_mesh(0.0, 1.0, 1.0, 2, 2, MeridianKind::Quad4).unwrap();
        assert_eq!(m.node_sets["axis"], m.node_sets["inner"]);
        assert!(rectangle_mesh(0.5, 0.2, 1.0, 2, 2, MeridianKind::Quad4).is_err());
        assert!(rectangle_mesh(0.0, 1.0, 1.0, 0, 2, MeridianKind::Quad4).is_err());
    }

    /// A disc graded so steeply that its pad would need more cells than any machine holds is
    /// refused with a message, not a failed allocation (found by the scenario fuzz test with
    /// `grading = 9223372036854775807`).
    #[test]
    fn a_disc_whose_pad_needs_too_many_cells_is_refused() {
        let spec = |grading: f64| crate::mesh::disc::DiscSpec {
            radius: 17.5e-3,
            thickness: 1e-3,
            pad_radius: 3.75e-3,
            electrode_radius: 7.5e-3,
            radial: 12,
            layers: 2,
            quarter: true,
            grading,
            kind: crate::mesh::ElementKind::Hex8,
        };
        assert!(disc_meridian(&spec(2.0), MeridianKind::Quad4).is_ok());
        let e = disc_meridian(&spec(9.223372036854776e18), MeridianKind::Quad4).unwrap_err();
        assert!(e.contains("lower `grading`"), "{e}");
    }

    /// The half shell: its volume to the discretisation of the arc (quadratic kinds closer),
    /// the axis nodes exactly on R = 0, the sets on their surfaces.
    #[test]
    fn the_meridian_sphere_is_a_half_shell() {
        let (r1, r2): (f64, f64) = (10e-3, 10.5e-3);
        let exact = 2.0 / 3.0 * std::f64::consts::PI * (r2.powi(3) - r1.powi(3));
        for kind in MeridianKind::ALL {
            let m = sphere_meridian(r1, r2, 16, 2, kind).unwrap();
            let err = (ring_volume(&m) - exact).abs() / exact;
            let bound = if kind.is_quadratic() { 1e-6 } else { 5e-3 };
            assert!(err < bound, "{kind:?}: {err}");
            for &n in &m.node_sets["axis"] {
                assert_eq!(m.nodes[n][0], 0.0);
            }
            for (name, r) in [("inner", r1), ("outer", r2)] {
                for &n in &m.node_sets[name] {
                    let x = m.nodes[n];
                    assert!(((x[0] * x[0] + x[1] * x[1]).sqrt() - r).abs() < 1e-15);
                }
            }
            for &n in &m.node_sets["equator"] {
                assert_eq!(m.nodes[n][1], 0.0);
            }
        }
    }

    /// The meridian disc: the disc's volume, grid lines at the pad and electrode radii, the sets.
    #[test]
    fn the_meridian_disc_has_the_disc_sets() {
        let spec = DiscSpec::reference_actuator(ElementKind::Hex8);
        for kind in MeridianKind::ALL {
            let m = disc_meridian(&spec, kind).unwrap();
            let v = std::f64::consts::PI * spec.radius.powi(2) * spec.thickness;
            assert!((ring_volume(&m) - v).abs() < 1e-12 * v, "{kind:?}");
            let tol = 1e-12;
            for &n in &m.node_sets["electrode_top"] {
                assert!(m.nodes[n][0] <= spec.electrode_radius + tol);
                assert!((m.nodes[n][1] - spec.thickness).abs() < tol);
            }
            assert!(m.node_sets["electrode_top"]
                .iter()
                .any(|&n| (m.nodes[n][0] - spec.electrode_radius).abs() < tol));
            assert!(m.node_sets["pad"]
                .iter()
                .any(|&n| (m.nodes[n][0] - spec.pad_radius).abs() < tol));
            assert_eq!(m.node_sets["rim_bottom"].len(), 1);
            assert_eq!(
                m.cell_sets["pad"].len() + m.cell_sets["annulus"].len(),
                m.n_cells()
            );
            for &n in &m.node_sets["axis"] {
                assert_eq!(m.nodes[n][0], 0.0);
            }
        }
    }
}
