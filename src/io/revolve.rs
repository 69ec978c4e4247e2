//! The revolved view of an axisymmetric model: its meridian section swept about the axis into a
//! 3-D mesh, so that ParaView shows the real shape of the body. Output only: it is built from the
//! written state and never read back.
//!
//! A section point (R, Z) at angle θ becomes (R cos θ, R sin θ, Z): the model's axis (y in the
//! section files) is the z axis of the view. The sector is cut into wedges between the angles
//! θ_k = kΔθ, and every section cell sweeps one linear cell per wedge, its sides straight chords:
//! a quadrilateral a hexahedron (`VTK_HEXAHEDRON`), a triangle a wedge (`VTK_WEDGE`), both with
//! their first face pointing towards the opposite one, for which VTK 9.7 computes positive
//! volumes (VTK 9.6 and older read wedges the other way round: the same picture, negative
//! volumes). A quadratic cell is first split at its mid-side nodes — quad8 and quad9 into four
//! quadrilaterals through the centre (interpolated for the quad8), tri6 into four triangles — so
//! that every nodal value is shown and a curved side is followed by two chords. Points on the axis are repeated at every
//! angle: the cells touching the axis are degenerate there, which ParaView draws as they are.
//!
//! Components: vectors in the section's basis (e_R, e_Z, e_Θ) become Cartesian,
//! v_x = v_R cos θ − v_Θ sin θ, v_y = v_R sin θ + v_Θ cos θ, v_z = v_Z; tensors (9 components,
//! row-major) become Q T Qᵀ with the columns of Q the vectors e_R, e_Z, e_Θ at θ. A point value
//! is rotated to its own angle, a cell value to the middle angle of its wedge; scalars are copied.

use super::vtu::CellType;
use crate::job::plan::Revolve;
use crate::mesh::{ElementKind, MeridianKind, Mesh};

/// What a data array holds, which decides how it is turned with the angle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Components {
    /// One value, copied.
    Scalar,
    /// (R, Z, Θ) components, rotated to (x, y, z).
    Vector,
    /// Nine components, row-major in the basis (e_R, e_Z, e_Θ), rotated to (x, y, z).
    Tensor,
}

impl Components {
    /// Values per entity.
    pub fn size(self) -> usize {
        match self {
            Components::Scalar => 1,
            Components::Vector => 3,
            Components::Tensor => 9,
        }
    }
}

/// The swept mesh of a meridian section, and what is needed to sweep its data.
#[derive(Debug, Clone)]
pub struct RevolvedMesh {
    /// Point coordinates (m): section point `p` on ring `j` is point `j · section_points + p`.
    pub points: Vec<[f64; 3]>,
    /// `Hex8` (from quadrilaterals) or `Wedge6` (from triangles).
    pub cell_type: CellType,
    /// VTK node order, `nodes_per_cell` per cell.
    pub connectivity: Vec<usize>,
    /// The points of the section: its nodes, then (quad8) the centre of every cell.
    section_points: usize,
    /// The node count of the section mesh.
    nodes: usize,
    /// The angle (rad) of each ring of points.
    angles: Vec<f64>,
    /// Per revolved cell: its section cell and the middle angle (rad) of its wedge.
    cells: Vec<(usize, f64)>,
    /// quad8 only: the nodes of every section cell, whose centres are the extra section points.
    centres: Vec<[usize; 8]>,
}

/// The sub-cells of a section cell (local indices; index 8 of a quad8 is its centre), counter-
/// clockwise like the cell.
fn sub_cells(kind: MeridianKind) -> &'static [&'static [usize]] {
    match kind {
        MeridianKind::Quad4 => &[&[0, 1, 2, 3]],
        MeridianKind::Quad8 | MeridianKind::Quad9 => {
            &[&[0, 4, 8, 7], &[4, 1, 5, 8], &[8, 5, 2, 6], &[7, 8, 6, 3]]
        }
        MeridianKind::Tri3 => &[&[0, 1, 2]],
        MeridianKind::Tri6 => &[&[0, 3, 5], &[3, 1, 4], &[5, 4, 2], &[3, 4, 5]],
    }
}

/// The quad8 shape functions at the centre: −¼ at the corners, ½ at the mid-side nodes.
const QUAD8_CENTRE: [f64; 8] = [-0.25, -0.25, -0.25, -0.25, 0.5, 0.5, 0.5, 0.5];

/// The basis change at θ: the columns are e_R, e_Z, e_Θ in Cartesian components.
fn basis(theta: f64) -> [[f64; 3]; 3] {
    let (s, c) = theta.sin_cos();
    [[c, 0.0, -s], [s, 0.0, c], [0.0, 1.0, 0.0]]
}

/// Writes the Cartesian components of `v` (given in (R, Z, Θ), `kind.size()` values) at θ into
/// `out`.
pub fn rotate(kind: Components, theta: f64, v: &[f64], out: &mut [f64]) {
    match kind {
        Components::Scalar => out[0] = v[0],
        Components::Vector => {
            let q = basis(theta);
            for i in 0..3 {
                out[i] = (0..3).map(|j| q[i][j] * v[j]).sum();
            }
        }
        Components::Tensor => {
            let q = basis(theta);
            for i in 0..3 {
                for l in 0..3 {
                    let mut sum = 0.0;
                    for j in 0..3 {
                        for k in 0..3 {
                            sum += q[i][j] * v[j * 3 + k] * q[l][k];
                        }
                    }
                    out[i * 3 + l] = sum;
                }
            }
        }
    }
}

impl RevolvedMesh {
    /// Sweeps the section `mesh` (meridian cells) as `revolve` says; `None` for a 3-D mesh.
    pub fn new(mesh: &Mesh, revolve: Revolve) -> Option<Self> {
        let ElementKind::Meridian(kind) = mesh.kind else {
            return None;
        };
        let wedges = revolve.wedges.max(1);
        let full = revolve.sector_deg >= 360.0;
        let step = revolve.sector_deg.to_radians() / wedges as f64;
        let rings = if full { wedges } else { wedges + 1 };
        let angles: Vec<f64> = (0..rings).map(|j| j as f64 * step).collect();
        let nodes = mesh.n_nodes();
        let centres: Vec<[usize; 8]> = if kind == MeridianKind::Quad8 {
            (0..mesh.n_cells())
                .map(|c| {
                    let mut n = [0; 8];
                    n.copy_from_slice(mesh.cell(c));
                    n
                })
                .collect()
        } else {
            Vec::new()
        };
        let mut section: Vec<[f64; 3]> = mesh.nodes.clone();
        section.extend(centres.iter().map(|n| {
            let mut x = [0.0; 3];
            for (a, w) in n.iter().zip(QUAD8_CENTRE) {
                for (xi, ni) in x.iter_mut().zip(mesh.nodes[*a]) {
                    *xi += w * ni;
                }
            }
            x
        }));
        let section_points = section.len();
        let mut points = Vec::with_capacity(rings * section_points);
        for &theta in &angles {
            let (s, c) = theta.sin_cos();
            points.extend(section.iter().map(|p| [p[0] * c, p[0] * s, p[1]]));
        }
        let subs = sub_cells(kind);
        let quads = subs[0].len() == 4;
        let cell_type = if quads {
            CellType::Hex8
        } else {
            CellType::Wedge6
        };
        let n_cells = mesh.n_cells() * subs.len() * wedges;
        let mut connectivity = Vec::with_capacity(n_cells * 2 * subs[0].len());
        let mut cells = Vec::with_capacity(n_cells);
        for k in 0..wedges {
            let (j0, j1) = (k, (k + 1) % rings);
            let mid = (k as f64 + 0.5) * step;
            for c in 0..mesh.n_cells() {
                let cell = mesh.cell(c);
                let local = |a: usize| {
                    if a < cell.len() {
                        cell[a]
                    } else {
                        nodes + c
                    }
                };
                for sub in subs {
                    let at = |j: usize, a: usize| j * section_points + local(a);
                    // the counter-clockwise section (its normal −e_Θ) at the far angle first: the
                    // first face of a VTK hexahedron or wedge points towards the opposite one
                    connectivity.extend(sub.iter().map(|&a| at(j1, a)));
                    connectivity.extend(sub.iter().map(|&a| at(j0, a)));
                    cells.push((c, mid));
                }
            }
        }
        Some(RevolvedMesh {
            points,
            cell_type,
            connectivity,
            section_points,
            nodes,
            angles,
            cells,
            centres,
        })
    }

    /// Number of cells.
    pub fn n_cells(&self) -> usize {
        self.cells.len()
    }

    /// The angles (rad) of the rings of points, ascending from 0.
    pub fn angles(&self) -> &[f64] {
        &self.angles
    }

    /// The values of the section points (`n` per node, then the quad8 cells' centres,
    /// interpolated).
    fn section_values(&self, n: usize, values: &[f64]) -> Vec<f64> {
        let mut section = values[..self.nodes * n].to_vec();
        for nodes in &self.centres {
            for i in 0..n {
                section.push(
                    nodes
                        .iter()
                        .zip(QUAD8_CENTRE)
                        .map(|(&a, w)| w * values[a * n + i])
                        .sum(),
                );
            }
        }
        section
    }

    /// A point array of the section (`kind.size()` values per section node) on the revolved
    /// points.
    pub fn point_array(&self, kind: Components, values: &[f64]) -> Vec<f64> {
        let n = kind.size();
        let section = self.section_values(n, values);
        let mut out = vec![0.0; self.angles.len() * self.section_points * n];
        for (j, &theta) in self.angles.iter().enumerate() {
            for p in 0..self.section_points {
                let at = (j * self.section_points + p) * n;
                rotate(
                    kind,
                    theta,
                    &section[p * n..(p + 1) * n],
                    &mut out[at..at + n],
                );
            }
        }
        out
    }

    /// A point array of a shape of circumferential harmonic `n` (the amplitudes, `kind.size()`
    /// values per section node; a scalar or a vector) on the revolved points: a scalar and the
    /// (R, Z) components vary as cos nθ, the Θ component as sin nθ
    /// ([`crate::time::harmonic`]).
    pub fn harmonic_point_array(&self, kind: Components, values: &[f64], n: u32) -> Vec<f64> {
        debug_assert!(kind != Components::Tensor);
        let size = kind.size();
        let section = self.section_values(size, values);
        let mut out = vec![0.0; self.angles.len() * self.section_points * size];
        let mut v = [0.0; 3];
        for (j, &theta) in self.angles.iter().enumerate() {
            let (s, c) = (f64::from(n) * theta).sin_cos();
            for p in 0..self.section_points {
                let at = (j * self.section_points + p) * size;
                for (k, x) in v.iter_mut().enumerate().take(size) {
                    *x = section[p * size + k] * if k == 2 { s } else { c };
                }
                rotate(kind, theta, &v[..size], &mut out[at..at + size]);
            }
        }
        out
    }

    /// A cell array of the section (`kind.size()` values per section cell) on the revolved cells.
    pub fn cell_array(&self, kind: Components, values: &[f64]) -> Vec<f64> {
        let n = kind.size();
        let mut out = vec![0.0; self.cells.len() * n];
        for (r, &(c, theta)) in self.cells.iter().enumerate() {
            rotate(
                kind,
                theta,
                &values[c * n..(c + 1) * n],
                &mut out[r * n..(r + 1) * n],
            );
        }
        out
    }

    /// Named scalar cell arrays on the revolved cells: nine consecutive arrays `<name>_xx`,
    /// `<name>_xy`, … `<name>_zz` (a tensor's components in the section's basis, such as an
    /// internal variable's) are rotated together and keep their names, now meaning Cartesian
    /// components; any other array is copied.
    pub fn named_cell_scalars(&self, arrays: &[(String, Vec<f64>)]) -> Vec<(String, Vec<f64>)> {
        const SUFFIXES: [&str; 9] = ["xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz"];
        let mut out = Vec::with_capacity(arrays.len());
        let mut i = 0;
        while i < arrays.len() {
            let stem = arrays[i].0.strip_suffix("_xx");
            let tensor = stem.filter(|stem| {
                arrays.len() >= i + 9
                    && SUFFIXES.iter().enumerate().all(|(k, s)| {
                        arrays[i + k].0 == format!("{stem}_{s}")
                            && arrays[i + k].1.len() == arrays[i].1.len()
                    })
            });
            if tensor.is_some() {
                let cells = arrays[i].1.len();
                let packed: Vec<f64> = (0..cells)
                    .flat_map(|c| (0..9).map(move |k| (c, k)))
                    .map(|(c, k)| arrays[i + k].1[c])
                    .collect();
                let turned = self.cell_array(Components::Tensor, &packed);
                for (k, (name, _)) in arrays[i..i + 9].iter().enumerate() {
                    out.push((
                        name.clone(),
                        turned.iter().skip(k).step_by(9).copied().collect(),
                    ));
                }
                i += 9;
            } else {
                out.push((
                    arrays[i].0.clone(),
                    self.cell_array(Components::Scalar, &arrays[i].1),
                ));
                i += 1;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;
    use std::collections::BTreeMap;
    use std::f64::consts::PI;

    /// A meridian mesh of one kind from its nodes and cells.
    fn section(kind: MeridianKind, nodes: Vec<[f64; 3]>, connectivity: Vec<usize>) -> Mesh {
        Mesh {
            kind: ElementKind::Meridian(kind),
            nodes,
            connectivity,
            node_sets: BTreeMap::new(),
            face_sets: BTreeMap::new(),
            cell_sets: BTreeMap::new(),
        }
    }

    /// One quad4 ring section r1 ≤ R ≤ r2, 0 ≤ Z ≤ h.
    fn ring(r1: f64, r2: f64, h: f64) -> Mesh {
        section(
            MeridianKind::Quad4,
            vec![[r1, 0.0, 0.0], [r2, 0.0, 0.0], [r2, h, 0.0], [r1, h, 0.0]],
            vec![0, 1, 2, 3],
        )
    }

    fn sweep(mesh: &Mesh, sector_deg: f64, wedges: usize) -> RevolvedMesh {
        RevolvedMesh::new(mesh, Revolve { sector_deg, wedges }).unwrap()
    }

    /// A shape of harmonic n shows its pattern around the axis: at every ring the Cartesian
    /// vector is the section's (a cos nθ, b cos nθ, c sin nθ) in (e_R, e_Z, e_Θ), a scalar p cos nθ.
    #[test]
    fn harmonic_shapes_vary_around_the_axis() {
        let mesh = ring(1.0, 2.0, 0.5);
        let r = sweep(&mesh, 360.0, 12);
        let amplitudes: Vec<f64> = (0..4)
            .flat_map(|a| [0.3 + a as f64, -0.7, 1.1 * a as f64 - 0.4])
            .collect();
        let potentials = [0.5, -1.0, 2.0, 0.25];
        for n in [0, 1, 2, 5] {
            let v = r.harmonic_point_array(Components::Vector, &amplitudes, n);
            let p = r.harmonic_point_array(Components::Scalar, &potentials, n);
            for (j, &theta) in r.angles().iter().enumerate() {
                let (sn, cn) = (f64::from(n) * theta).sin_cos();
                let (st, ct) = theta.sin_cos();
                for a in 0..4 {
                    let at = j * 4 + a;
                    let [ar, az, at_] = [0, 1, 2].map(|k| amplitudes[a * 3 + k]);
                    let (ur, ut) = (ar * cn, at_ * sn);
                    let want = [ur * ct - ut * st, ur * st + ut * ct, az * cn];
                    for k in 0..3 {
                        assert!((v[at * 3 + k] - want[k]).abs() < 1e-14, "n {n}, θ {theta}");
                    }
                    assert!((p[at] - potentials[a] * cn).abs() < 1e-14);
                }
            }
        }
    }

    fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }

    fn det(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
        a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0])
    }

    /// The volume of a VTK hexahedron (trilinear map, 2 × 2 × 2 Gauss points: exact): positive
    /// when its nodes are in VTK's order (face 0-1-2-3 pointing towards face 4-5-6-7).
    fn hex_volume(x: &[[f64; 3]]) -> f64 {
        let g = 0.5 / 3f64.sqrt();
        let mut v = 0.0;
        for r in [0.5 - g, 0.5 + g] {
            for s in [0.5 - g, 0.5 + g] {
                for t in [0.5 - g, 0.5 + g] {
                    // VTK's parametric corners: (0,0,0) (1,0,0) (1,1,0) (0,1,0), then t = 1
                    let pc = [[0., 0.], [1., 0.], [1., 1.], [0., 1.]];
                    let mut jac = [[0.0; 3]; 3];
                    for (a, xa) in x.iter().enumerate() {
                        let [pr, ps] = pc[a % 4];
                        let pt = (a / 4) as f64;
                        let fr = if pr == 1.0 { r } else { 1.0 - r };
                        let fs = if ps == 1.0 { s } else { 1.0 - s };
                        let ft = if pt == 1.0 { t } else { 1.0 - t };
                        let sr = if pr == 1.0 { 1.0 } else { -1.0 };
                        let ss = if ps == 1.0 { 1.0 } else { -1.0 };
                        let st = if pt == 1.0 { 1.0 } else { -1.0 };
                        let d = [sr * fs * ft, fr * ss * ft, fr * fs * st];
                        for i in 0..3 {
                            for k in 0..3 {
                                jac[k][i] += xa[i] * d[k];
                            }
                        }
                    }
                    v += 0.125 * det(jac[0], jac[1], jac[2]);
                }
            }
        }
        v
    }

    /// The volume of a VTK wedge (three tetrahedra): positive when its base 0-1-2 points towards
    /// 3-4-5, the orientation VTK 9.7 computes a positive volume for (9.6 and older: negative).
    fn wedge_volume(x: &[[f64; 3]]) -> f64 {
        let tet = |a: usize, b: usize, c: usize, d: usize| {
            det(sub(x[b], x[a]), sub(x[c], x[a]), sub(x[d], x[a])) / 6.0
        };
        tet(0, 1, 2, 5) + tet(0, 1, 5, 4) + tet(0, 4, 5, 3)
    }

    fn volumes(r: &RevolvedMesh) -> Vec<f64> {
        let n = r.cell_type.nodes_per_cell();
        r.connectivity
            .chunks(n)
            .map(|c| {
                let x: Vec<[f64; 3]> = c.iter().map(|&p| r.points[p]).collect();
                match r.cell_type {
                    CellType::Hex8 => hex_volume(&x),
                    _ => wedge_volume(&x),
                }
            })
            .collect()
    }

    #[test]
    fn the_volume_checks_agree_with_vtk_orientation_on_unit_cells() {
        let cube = [
            [0., 0., 0.],
            [1., 0., 0.],
            [1., 1., 0.],
            [0., 1., 0.],
            [0., 0., 1.],
            [1., 0., 1.],
            [1., 1., 1.],
            [0., 1., 1.],
        ];
        assert!((hex_volume(&cube) - 1.0).abs() < 1e-14);
        // VTK's parametric wedge: base (0, 1, 2) with its normal towards (3, 4, 5)
        let wedge = [
            [0., 0., 0.],
            [1., 0., 0.],
            [0., 1., 0.],
            [0., 0., 1.],
            [1., 0., 1.],
            [0., 1., 1.],
        ];
        assert!((wedge_volume(&wedge) - 0.5).abs() < 1e-14);
        let mut flipped = wedge;
        flipped.swap(1, 2);
        flipped.swap(4, 5);
        assert!((wedge_volume(&flipped) + 0.5).abs() < 1e-14);
        let mut flipped = cube;
        flipped.rotate_left(4);
        assert!((hex_volume(&flipped) + 1.0).abs() < 1e-14);
    }

    #[test]
    fn points_lie_on_circles_about_the_z_axis() {
        let m = ring(1.0, 2.0, 0.5);
        for (sector, wedges, rings) in [(360.0, 8, 8), (270.0, 9, 10), (30.0, 1, 2)] {
            let r = sweep(&m, sector, wedges);
            assert_eq!(r.points.len(), 4 * rings);
            assert_eq!(r.n_cells(), wedges);
            let step = f64::to_radians(sector) / wedges as f64;
            for (j, theta) in r.angles().iter().enumerate() {
                assert!((theta - j as f64 * step).abs() < 1e-15);
                for (p, x) in m.nodes.iter().enumerate() {
                    let y = r.points[j * 4 + p];
                    assert!(((y[0] * y[0] + y[1] * y[1]).sqrt() - x[0]).abs() < 1e-14);
                    assert_eq!(y[2], x[1]);
                    assert!((y[1].atan2(y[0]).rem_euclid(2.0 * PI) - theta).abs() < 1e-12);
                }
            }
        }
        // the closing wedge of a full turn reuses the first ring
        let r = sweep(&m, 360.0, 8);
        let last = &r.connectivity[7 * 8..8 * 8];
        assert!(last[..4].iter().all(|&p| p < 4), "{last:?}");
    }

    /// A linear sweep cuts every wedge's arc by a chord: N hexahedra of a rectangular section
    /// hold N · ½ sin Δθ (r₂² − r₁²) h, which tends to the ring's π (r₂² − r₁²) h.
    #[test]
    fn a_quad4_ring_sweeps_into_hexahedra_of_the_chord_volume() {
        let (r1, r2, h) = (0.3, 1.1, 0.2);
        let m = ring(r1, r2, h);
        let ring_volume = PI * (r2 * r2 - r1 * r1) * h;
        let mut last_error = f64::INFINITY;
        for wedges in [3, 6, 12, 36, 360] {
            let r = sweep(&m, 360.0, wedges);
            assert_eq!(r.cell_type, CellType::Hex8);
            let v = volumes(&r);
            assert!(v.iter().all(|&v| v > 0.0), "{v:?}");
            let dt = 2.0 * PI / wedges as f64;
            let expected = wedges as f64 * 0.5 * dt.sin() * (r2 * r2 - r1 * r1) * h;
            let total: f64 = v.iter().sum();
            assert!(
                (total - expected).abs() < 1e-12 * expected,
                "{total} {expected}"
            );
            assert!((expected - ring_volume * dt.sin() / dt).abs() < 1e-12 * ring_volume);
            let error = (ring_volume - total) / ring_volume;
            assert!(error > 0.0 && error < last_error);
            last_error = error;
        }
        // 1 − sin Δθ/Δθ ≈ Δθ²/6 = 5.1e-5 at 1°
        assert!(last_error < 6e-5);
        // a partial sector: the same chord volume per wedge
        let r = sweep(&m, 90.0, 5);
        let dt = PI / 2.0 / 5.0;
        let total: f64 = volumes(&r).iter().sum();
        let expected = 5.0 * 0.5 * dt.sin() * (r2 * r2 - r1 * r1) * h;
        assert!((total - expected).abs() < 1e-12 * expected);
    }

    /// Every kind sweeps cells of positive volume (or zero at the axis: a triangle with a side on
    /// it), whose total is the chord volume of the section.
    #[test]
    fn every_kind_sweeps_positive_cells_and_the_chord_volume() {
        let (r2, h) = (1.0, 0.4);
        // a section of two cells touching the axis: [0, r2] × [0, h]
        let quad = |kind: MeridianKind| {
            let mut nodes = vec![
                [0.0, 0.0, 0.0],
                [0.5, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, h, 0.0],
                [0.5, h, 0.0],
                [0.0, h, 0.0],
            ];
            let mut conn = vec![0, 1, 4, 5, 1, 2, 3, 4];
            if kind != MeridianKind::Quad4 {
                // mid-sides of both cells, then (quad9) the centres
                let mids = [
                    [0.25, 0.0],
                    [0.5, h / 2.0],
                    [0.25, h],
                    [0.0, h / 2.0],
                    [0.75, 0.0],
                    [1.0, h / 2.0],
                    [0.75, h],
                ];
                nodes.extend(mids.iter().map(|p| [p[0], p[1], 0.0]));
                conn = vec![0, 1, 4, 5, 6, 7, 8, 9, 1, 2, 3, 4, 10, 11, 12, 7];
                if kind == MeridianKind::Quad9 {
                    nodes.push([0.25, h / 2.0, 0.0]);
                    nodes.push([0.75, h / 2.0, 0.0]);
                    conn.insert(8, 13);
                    conn.push(14);
                }
            }
            section(kind, nodes, conn)
        };
        let tri = |kind: MeridianKind| {
            let mut nodes = vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, h, 0.0],
                [0.0, h, 0.0],
            ];
            let mut conn = vec![0, 1, 2, 0, 2, 3];
            if kind == MeridianKind::Tri6 {
                nodes.extend([
                    [0.5, 0.0, 0.0],
                    [1.0, h / 2.0, 0.0],
                    [0.5, h / 2.0, 0.0],
                    [0.5, h, 0.0],
                    [0.0, h / 2.0, 0.0],
                ]);
                conn = vec![0, 1, 2, 4, 5, 6, 0, 2, 3, 6, 7, 8];
            }
            section(kind, nodes, conn)
        };
        let wedges = 12;
        let dt = 2.0 * PI / wedges as f64;
        let expected = wedges as f64 * 0.5 * dt.sin() * r2 * r2 * h;
        for kind in MeridianKind::ALL {
            let m = match kind {
                MeridianKind::Tri3 | MeridianKind::Tri6 => tri(kind),
                _ => quad(kind),
            };
            let r = sweep(&m, 360.0, wedges);
            let subs = if kind.is_quadratic() { 4 } else { 1 };
            assert_eq!(r.n_cells(), m.n_cells() * subs * wedges, "{kind:?}");
            let extra = if kind == MeridianKind::Quad8 { 2 } else { 0 };
            assert_eq!(r.points.len(), (m.n_nodes() + extra) * wedges, "{kind:?}");
            let v = volumes(&r);
            assert!(v.iter().all(|&v| v > -1e-15), "{kind:?}: {v:?}");
            let total: f64 = v.iter().sum();
            assert!(
                (total - expected).abs() < 1e-12 * expected,
                "{kind:?}: {total} vs {expected}"
            );
        }
    }

    #[test]
    fn quad8_centres_interpolate_points_and_values() {
        let nodes = vec![
            [1.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [3.0, 2.0, 0.0],
            [1.0, 2.0, 0.0],
            [2.0, 0.0, 0.0],
            [3.0, 1.0, 0.0],
            [2.0, 2.0, 0.0],
            [1.0, 1.0, 0.0],
        ];
        let m = section(MeridianKind::Quad8, nodes.clone(), (0..8).collect());
        let r = sweep(&m, 90.0, 1);
        assert_eq!(r.points.len(), 9 * 2);
        assert_eq!(r.points[8], [2.0, 0.0, 1.0]);
        // a field linear in (R, Z) is reproduced at the centre
        let f: Vec<f64> = nodes.iter().map(|p| 3.0 * p[0] - p[1] + 0.5).collect();
        let out = r.point_array(Components::Scalar, &f);
        assert!((out[8] - (3.0 * 2.0 - 1.0 + 0.5)).abs() < 1e-14);
        assert_eq!(&out[..8], &f[..]);
        assert_eq!(&out[9..17], &f[..]);
    }

    #[test]
    fn displacements_turn_with_the_angle() {
        let m = ring(1.0, 2.0, 1.0);
        let r = sweep(&m, 360.0, 4);
        // (u_r, u_z, u_θ) = (a, b, 0) at every node
        let u: Vec<f64> = (0..4).flat_map(|p| [0.1 + p as f64, -0.2, 0.0]).collect();
        let out = r.point_array(Components::Vector, &u);
        for (j, &theta) in r.angles().iter().enumerate() {
            for p in 0..4 {
                let v = &out[(j * 4 + p) * 3..(j * 4 + p) * 3 + 3];
                let ur = 0.1 + p as f64;
                assert!((v[0] - ur * theta.cos()).abs() < 1e-15);
                assert!((v[1] - ur * theta.sin()).abs() < 1e-15);
                assert_eq!(v[2], -0.2);
                // the displaced point stays on its meridian plane
                let x = r.points[j * 4 + p];
                let moved = [x[0] + v[0], x[1] + v[1]];
                assert!((moved[0] * x[1] - moved[1] * x[0]).abs() < 1e-14);
            }
        }
        // a hoop component turns into the tangent direction
        let mut w = [0.0; 3];
        rotate(Components::Vector, PI / 2.0, &[0.0, 0.0, 1.0], &mut w);
        assert!((w[0] + 1.0).abs() < 1e-15 && w[1].abs() < 1e-15 && w[2] == 0.0);
    }

    fn von_mises(t: &[f64]) -> f64 {
        let (xx, yy, zz) = (t[0], t[4], t[8]);
        let (xy, yz, zx) = (t[1], t[5], t[6]);
        (0.5 * ((xx - yy).powi(2) + (yy - zz).powi(2) + (zz - xx).powi(2))
            + 3.0 * (xy * xy + yz * yz + zx * zx))
            .sqrt()
    }

    #[test]
    fn tensors_keep_their_invariants_and_radial_stress_turns_with_the_angle() {
        // σ_RR = 1, σ_ZZ = 2, σ_ΘΘ = 3 and a shear σ_RZ = 0.5
        let s = [1.0, 0.5, 0.0, 0.5, 2.0, 0.0, 0.0, 0.0, 3.0];
        let mut t = [0.0; 9];
        rotate(Components::Tensor, 0.0, &s, &mut t);
        // at θ = 0: x = R, y = Θ, z = Z
        assert_eq!(t, [1.0, 0.0, 0.5, 0.0, 3.0, 0.0, 0.5, 0.0, 2.0]);
        rotate(Components::Tensor, PI / 2.0, &s, &mut t);
        // at θ = 90°: y = R, x = −Θ
        let expect = [3.0, 0.0, 0.0, 0.0, 1.0, 0.5, 0.0, 0.5, 2.0];
        for (a, b) in t.iter().zip(expect) {
            assert!((a - b).abs() < 1e-15, "{t:?}");
        }
        let vm = von_mises(&s);
        for theta in [0.3, 1.0, 2.5, -0.7, 4.0] {
            rotate(Components::Tensor, theta, &s, &mut t);
            assert!((t[0] + t[4] + t[8] - 6.0).abs() < 1e-14);
            assert!((von_mises(&t) - vm).abs() < 1e-14);
            for i in 0..3 {
                for j in 0..3 {
                    assert!((t[i * 3 + j] - t[j * 3 + i]).abs() < 1e-15);
                }
            }
            // the radial direction carries σ_RR
            let n = [theta.cos(), theta.sin(), 0.0];
            let nn: f64 = (0..3)
                .flat_map(|i| (0..3).map(move |j| (i, j)))
                .map(|(i, j)| n[i] * t[i * 3 + j] * n[j])
                .sum();
            assert!((nn - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn cell_values_take_the_middle_angle_of_their_wedge() {
        let m = ring(1.0, 2.0, 1.0);
        let r = sweep(&m, 180.0, 2);
        // a radial field: at the middles 45° and 135°
        let out = r.cell_array(Components::Vector, &[2.0, 1.0, 0.0]);
        let c = 2f64.sqrt();
        let expect = [c, c, 1.0, -c, c, 1.0];
        for (a, b) in out.iter().zip(expect) {
            assert!((a - b).abs() < 1e-14, "{out:?}");
        }
        assert_eq!(r.cell_array(Components::Scalar, &[7.0]), vec![7.0, 7.0]);
    }

    #[test]
    fn internal_variable_tensors_are_turned_and_other_scalars_copied() {
        let m = ring(1.0, 2.0, 1.0);
        let r = sweep(&m, 180.0, 1);
        let names = ["xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz"];
        // A_RR = 2, A_ZZ = 3, A_ΘΘ = 5: at 90° A_xx = 5, A_yy = 2
        let values = [2.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 5.0];
        let mut arrays: Vec<(String, Vec<f64>)> = vec![("k".into(), vec![4.0])];
        arrays.extend(
            names
                .iter()
                .zip(values)
                .map(|(n, v)| (format!("A1_{n}"), vec![v])),
        );
        let out = r.named_cell_scalars(&arrays);
        assert_eq!(out.len(), 10);
        assert_eq!(out[0], ("k".to_string(), vec![4.0]));
        let get = |n: &str| out.iter().find(|(m, _)| m == n).unwrap().1[0];
        assert!((get("A1_xx") - 5.0).abs() < 1e-14);
        assert!((get("A1_yy") - 2.0).abs() < 1e-14);
        assert!((get("A1_zz") - 3.0).abs() < 1e-14);
        assert!(get("A1_xy").abs() < 1e-14);
        // an incomplete group is copied as it is
        let out = r.named_cell_scalars(&arrays[..5]);
        assert_eq!(out, arrays[..5].to_vec());
    }

    #[test]
    fn a_3d_mesh_has_no_revolved_view() {
        let m = Mesh {
            kind: ElementKind::Tet4,
            nodes: vec![[0.0; 3]; 4],
            connectivity: vec![0, 1, 2, 3],
            node_sets: BTreeMap::new(),
            face_sets: BTreeMap::new(),
            cell_sets: BTreeMap::new(),
        };
        let revolve = Revolve {
            sector_deg: 360.0,
            wedges: 4,
        };
        assert!(RevolvedMesh::new(&m, revolve).is_none());
    }
}
