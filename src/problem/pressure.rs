//! Follower pressure on a face set and the volume the faces enclose.
//!
//! A pressure p on the faces of a cavity (or the inside of a membrane) does the work p·V, V the
//! volume the faces enclose, V = −⅓ ∮ x·n da with n the body's outward normal (pointing into the
//! cavity). Written as the potential −p·V(x) of the current positions, the load follows the
//! deforming surface (its force on a face is −p n da) and its stiffness −p ∂²V/∂x∂x is symmetric,
//! so the symmetric solvers keep working. On a closed surface, or on an open one whose boundary
//! is held (a membrane clamped at its rim), V differs from the true enclosed volume by a constant,
//! so forces and stiffness are exact; the volume is exact when the faces close the cavity or
//! meet at symmetry planes through the origin (x·n = 0 there).
//!
//! Per face, with x(ξ, η) = Σ N_a x_a on the reference face,
//! v = ∫ x·(x_ξ × x_η) dξdη (oriented by the body's normal),
//! ∂v/∂x_a = ∫ N_a (x_ξ × x_η) + N_a,ξ (x_η × x) + N_a,η (x × x_ξ),
//! and the second derivative follows by differentiating each cross product once more. The
//! integrand is a polynomial of the face's shape functions: 2×2 Gauss points (quad4), 3 points
//! (tri3) and the 6-point degree-4 rule (tri6) integrate it exactly.
//!
//! Axisymmetric models: a face is a side (r(ξ), z(ξ)) of a meridian cell sweeping a ring, and the
//! volume of revolution is V = −s ∫ π r² z_ξ dξ (s orients (z_ξ, −r_ξ) along the body's outward
//! normal), so ∂V/∂r_a = −s ∫ 2π r N_a z_ξ, ∂V/∂z_a = −s ∫ π r² N_a,ξ, and the second derivatives
//! −s ∫ 2π N_a N_b z_ξ (r r), −s ∫ 2π r N_a N_b,ξ (r z); Gauss rules of 2 and 4 points integrate
//! them exactly on 2- and 3-node sides. The axis closes the volume (r = 0 there).

use crate::mesh::{FaceRef, Mesh};
use crate::problem::dofs::FIELDS;
use crate::problem::faces::{cross, dot, points, shape, side_points, side_shape};

/// A pressure (Pa, positive pushing the faces away from the cavity) on faces of the mesh.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pressure {
    pub faces: Vec<SurfaceFace>,
    pub value: f64,
    /// Volume control: the volume (m³, of the meshed part) the faces enclose at the end of the
    /// current stage, reached linearly from the stage's start; the pressure's fraction is then an
    /// unknown of the static problem (`None`: the pressure follows its stage's drive).
    pub volume: Option<f64>,
}

impl Pressure {
    /// A pressure of `value` (Pa) on `faces`.
    pub fn new(faces: Vec<SurfaceFace>, value: f64) -> Self {
        Pressure {
            faces,
            value,
            volume: None,
        }
    }
}

/// The skew matrix [a]× with [a]× b = a × b.
fn skew(a: [f64; 3]) -> [[f64; 3]; 3] {
    [[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]]
}

/// A face of a loaded or measured surface: its cell and nodes (in the mesh of the model that
/// holds it), their reference positions (m) and the sign that turns (x_ξ × x_η) into the body's
/// outward normal. The cell decides which rank's part holds the face.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceFace {
    pub cell: usize,
    pub nodes: Vec<usize>,
    pub reference: Vec<[f64; 3]>,
    pub sign: f64,
    /// A side of a meridian cell (a ring surface of an axisymmetric model).
    pub ring: bool,
}

/// The faces of `faces` whose cells a rank's part holds, renumbered into the part:
/// `cell_at` and `node_at` give each whole-mesh cell's and node's number in the part
/// (`usize::MAX`: not in it). Each face is held by the rank of its cell only, so that it counts
/// once over the ranks.
pub fn faces_on_part(
    faces: &[SurfaceFace],
    cell_at: &[usize],
    node_at: &[usize],
) -> Vec<SurfaceFace> {
    faces
        .iter()
        .filter(|f| cell_at[f.cell] != usize::MAX)
        .map(|f| SurfaceFace {
            cell: cell_at[f.cell],
            nodes: f.nodes.iter().map(|&n| node_at[n]).collect(),
            ..f.clone()
        })
        .collect()
}

/// The faces with their orientation, taken from the reference geometry: the body's outward
/// normal points away from the cell's centroid.
pub fn surface(mesh: &Mesh, list: &[FaceRef]) -> Vec<SurfaceFace> {
    list.iter()
        .map(|f| {
            let cell = mesh.cell(f.cell);
            let local = mesh.kind.faces()[f.face];
            let nodes: Vec<usize> = local.iter().map(|&l| cell[l]).collect();
            let x: Vec<[f64; 3]> = nodes.iter().map(|&n| mesh.nodes[n]).collect();
            let centroid = |pts: &mut dyn Iterator<Item = [f64; 3]>| {
                let (mut c, mut k) = ([0.0; 3], 0.0);
                for p in pts {
                    (0..3).for_each(|i| c[i] += p[i]);
                    k += 1.0;
                }
                c.map(|v| v / k)
            };
            let cc = centroid(&mut cell.iter().map(|&n| mesh.nodes[n]));
            let fc = centroid(&mut x.iter().copied());
            let out = [fc[0] - cc[0], fc[1] - cc[1], fc[2] - cc[2]];
            if mesh.kind.meridian().is_some() {
                // the side's tangent at its middle, turned clockwise: (z_ξ, −r_ξ)
                let (_, d) = side_shape(nodes.len(), 0.0);
                let t: [f64; 2] =
                    std::array::from_fn(|i| (0..x.len()).map(|a| d[a] * x[a][i]).sum());
                let sign = if t[1] * out[0] - t[0] * out[1] >= 0.0 {
                    1.0
                } else {
                    -1.0
                };
                return SurfaceFace {
                    cell: f.cell,
                    nodes,
                    reference: x,
                    sign,
                    ring: true,
                };
            }
            let (xi, eta) = if nodes.len() == 4 {
                (0.0, 0.0)
            } else {
                (1.0 / 3.0, 1.0 / 3.0)
            };
            let (_, d) = shape(nodes.len(), xi, eta);
            let (mut t1, mut t2) = ([0.0; 3], [0.0; 3]);
            for (a, p) in x.iter().enumerate() {
                for i in 0..3 {
                    t1[i] += d[a][0] * p[i];
                    t2[i] += d[a][1] * p[i];
                }
            }
            let sign = if dot(cross(t1, t2), out) >= 0.0 {
                1.0
            } else {
                -1.0
            };
            SurfaceFace {
                cell: f.cell,
                nodes,
                reference: x,
                sign,
                ring: false,
            }
        })
        .collect()
}

/// Current positions X + u of the nodes of a face (state: `FIELDS` values per node).
fn positions(f: &SurfaceFace, state: &[f64]) -> Vec<[f64; 3]> {
    f.nodes
        .iter()
        .zip(&f.reference)
        .map(|(&n, x)| std::array::from_fn(|i| x[i] + state[n * FIELDS + i]))
        .collect()
}

/// The volume (m³) the faces enclose in the state (`FIELDS` values per node): −⅓ ∮ x·n da.
pub fn enclosed_volume(faces: &[SurfaceFace], state: &[f64]) -> f64 {
    let mut v = 0.0;
    for f in faces {
        let x = positions(f, state);
        if f.ring {
            for (xi, w) in side_points(x.len()) {
                let (s, d) = side_shape(x.len(), xi);
                let (r, zx) = x.iter().enumerate().fold((0.0, 0.0), |(r, z), (a, p)| {
                    (r + s[a] * p[0], z + d[a] * p[1])
                });
                v -= f.sign * w * std::f64::consts::PI * r * r * zx;
            }
            continue;
        }
        for (xi, eta, w) in points(f.nodes.len()) {
            let (s, d) = shape(f.nodes.len(), xi, eta);
            let (mut p, mut t1, mut t2) = ([0.0; 3], [0.0; 3], [0.0; 3]);
            for (a, xa) in x.iter().enumerate() {
                for i in 0..3 {
                    p[i] += s[a] * xa[i];
                    t1[i] += d[a][0] * xa[i];
                    t2[i] += d[a][1] * xa[i];
                }
            }
            v -= f.sign * w * dot(p, cross(t1, t2)) / 3.0;
        }
    }
    v
}

/// Adds the pressure's contribution to the residual (−p ∂V/∂x, the negative of its nodal forces)
/// and, with `tangent`, calls `tangent(row_dof, col_dof, value)` with its stiffness −p ∂²V/∂x∂x
/// (symmetric) for every pair of displacement dofs of a face. `factor` scales the pressure (the
/// load factor).
pub fn add_pressure(
    load: &Pressure,
    factor: f64,
    state: &[f64],
    residual: &mut [f64],
    mut tangent: Option<&mut dyn FnMut(usize, usize, f64)>,
) {
    let p = factor * load.value;
    for f in &load.faces {
        let n = f.nodes.len();
        let x = positions(f, state);
        if f.ring {
            add_ring_pressure(f, p, &x, residual, &mut tangent);
            continue;
        }
        // ∂V/∂x = −(s/3) ∂v/∂x; the residual gets −p ∂V/∂x = p s/3 ∂v/∂x
        let c = p * f.sign / 3.0;
        let mut k = vec![[[0.0; 3]; 3]; n * n];
        for (xi, eta, w) in points(n) {
            let (s, d) = shape(n, xi, eta);
            let (mut q, mut t1, mut t2) = ([0.0; 3], [0.0; 3], [0.0; 3]);
            for (a, xa) in x.iter().enumerate() {
                for i in 0..3 {
                    q[i] += s[a] * xa[i];
                    t1[i] += d[a][0] * xa[i];
                    t2[i] += d[a][1] * xa[i];
                }
            }
            let (n12, n2q, nq1) = (cross(t1, t2), cross(t2, q), cross(q, t1));
            for a in 0..n {
                let base = f.nodes[a] * FIELDS;
                for i in 0..3 {
                    residual[base + i] +=
                        c * w * (s[a] * n12[i] + d[a][0] * n2q[i] + d[a][1] * nq1[i]);
                }
            }
            if tangent.is_some() {
                let (k1, k2, kq) = (skew(t1), skew(t2), skew(q));
                for a in 0..n {
                    for b in 0..n {
                        let m = &mut k[a * n + b];
                        for i in 0..3 {
                            for j in 0..3 {
                                // ∂/∂x_b of N_a (t1 × t2) + N_a,ξ (t2 × q) + N_a,η (q × t1)
                                let v = s[a] * (-d[b][0] * k2[i][j] + d[b][1] * k1[i][j])
                                    + d[a][0] * (s[b] * k2[i][j] - d[b][1] * kq[i][j])
                                    + d[a][1] * (d[b][0] * kq[i][j] - s[b] * k1[i][j]);
                                m[i][j] += c * w * v;
                            }
                        }
                    }
                }
            }
        }
        if let Some(t) = tangent.as_deref_mut() {
            for a in 0..n {
                for b in 0..n {
                    for i in 0..3 {
                        for j in 0..3 {
                            t(
                                f.nodes[a] * FIELDS + i,
                                f.nodes[b] * FIELDS + j,
                                k[a * n + b][i][j],
                            );
                        }
                    }
                }
            }
        }
    }
}

/// The contribution of one meridian side (module docs): residual −p ∂V/∂x and stiffness
/// −p ∂²V/∂x∂x on the (r, z) slots of its nodes at current positions `x`.
fn add_ring_pressure(
    f: &SurfaceFace,
    p: f64,
    x: &[[f64; 3]],
    residual: &mut [f64],
    tangent: &mut Option<&mut dyn FnMut(usize, usize, f64)>,
) {
    let n = x.len();
    let pi = std::f64::consts::PI;
    // −p ∂V/∂x = p s ∫ (2π r N_a z_ξ, π r² N_a,ξ)
    let c = p * f.sign;
    let mut k = [[[0.0; 2]; 2]; 9];
    for (xi, w) in side_points(n) {
        let (s, d) = side_shape(n, xi);
        let (mut r, mut zx) = (0.0, 0.0);
        for (a, pa) in x.iter().enumerate() {
            r += s[a] * pa[0];
            zx += d[a] * pa[1];
        }
        for a in 0..n {
            let base = f.nodes[a] * FIELDS;
            residual[base] += c * w * 2.0 * pi * r * s[a] * zx;
            residual[base + 1] += c * w * pi * r * r * d[a];
        }
        for a in 0..n {
            for b in 0..n {
                let m = &mut k[a * n + b];
                m[0][0] += c * w * 2.0 * pi * s[a] * s[b] * zx;
                m[0][1] += c * w * 2.0 * pi * r * s[a] * d[b];
                m[1][0] += c * w * 2.0 * pi * r * s[b] * d[a];
            }
        }
    }
    if let Some(t) = tangent.as_deref_mut() {
        for a in 0..n {
            for b in 0..n {
                for i in 0..2 {
                    for j in 0..2 {
                        t(
                            f.nodes[a] * FIELDS + i,
                            f.nodes[b] * FIELDS + j,
                            k[a * n + b][i][j],
                        );
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::box_mesh;
    use crate::mesh::ElementKind;

    /// Every outer face of a box mesh.
    fn outer(mesh: &Mesh) -> Vec<FaceRef> {
        ["x0", "x1", "y0", "y1", "z0", "z1"]
            .iter()
            .flat_map(|s| mesh.face_sets[*s].iter().copied())
            .collect()
    }

    /// A pseudo-random displacement field (a fixed linear congruential sequence) of size `amp`.
    fn wiggle(mesh: &Mesh, amp: f64) -> Vec<f64> {
        let mut seed: u64 = 0x2545_f491_4f6c_dd1d;
        let mut state = vec![0.0; mesh.n_nodes() * FIELDS];
        for (i, v) in state.iter_mut().enumerate() {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            if i % FIELDS < 3 {
                *v = amp * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
            }
        }
        state
    }

    fn kinds() -> [ElementKind; 3] {
        [ElementKind::Hex8, ElementKind::Tet4, ElementKind::Tet10]
    }

    /// The outward normals of a solid box make its "enclosed" volume minus its volume; under an
    /// affine deformation x = F X the volume is det F times that, for every face kind.
    #[test]
    fn volume_of_a_box_and_of_its_affine_image() {
        let f = [[1.2, 0.1, -0.05], [0.02, 0.9, 0.1], [0.03, -0.04, 1.1]];
        let det = f[0][0] * (f[1][1] * f[2][2] - f[1][2] * f[2][1])
            - f[0][1] * (f[1][0] * f[2][2] - f[1][2] * f[2][0])
            + f[0][2] * (f[1][0] * f[2][1] - f[1][1] * f[2][0]);
        for kind in kinds() {
            let mesh = box_mesh([2e-3, 3e-3, 1e-3], [2, 3, 2], kind);
            let faces = surface(&mesh, &outer(&mesh));
            let zero = vec![0.0; mesh.n_nodes() * FIELDS];
            let v0 = enclosed_volume(&faces, &zero);
            assert!((v0 + 6e-9).abs() < 1e-12 * 6e-9, "{kind:?}: {v0}");
            let mut state = zero.clone();
            for (n, x) in mesh.nodes.iter().enumerate() {
                for i in 0..3 {
                    let y: f64 = (0..3).map(|j| f[i][j] * x[j]).sum();
                    state[n * FIELDS + i] = y - x[i];
                }
            }
            let v = enclosed_volume(&faces, &state);
            assert!((v + det * 6e-9).abs() < 1e-12 * 6e-9, "{kind:?}: {v}");
        }
    }

    /// A tet4 mesh with every node moved at random: the enclosed volume of its outer faces is
    /// minus the sum of its tetrahedra's volumes (the faces are exactly the cells' boundary).
    #[test]
    fn volume_of_a_distorted_mesh_is_the_sum_of_its_cells() {
        let mesh = box_mesh([1.0, 1.0, 1.0], [3, 2, 2], ElementKind::Tet4);
        let state = wiggle(&mesh, 0.1);
        let x = |n: usize| -> [f64; 3] {
            std::array::from_fn(|i| mesh.nodes[n][i] + state[n * FIELDS + i])
        };
        let mut cells = 0.0;
        for c in 0..mesh.n_cells() {
            let n = mesh.cell(c);
            let (a, b, cc, d) = (x(n[0]), x(n[1]), x(n[2]), x(n[3]));
            let e = |p: [f64; 3]| [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
            cells += dot(e(b), cross(e(cc), e(d))).abs() / 6.0;
        }
        let v = enclosed_volume(&surface(&mesh, &outer(&mesh)), &state);
        assert!((v + cells).abs() < 1e-13, "{v} vs {cells}");
    }

    /// The residual is −p ∂V/∂x and the stiffness its derivative (symmetric): central differences
    /// of the volume and of the residual, on an open face set of a distorted mesh of every kind.
    #[test]
    fn residual_and_stiffness_match_finite_differences() {
        for kind in kinds() {
            let mesh = box_mesh([1e-2, 1e-2, 2e-3], [2, 2, 1], kind);
            let load = Pressure::new(surface(&mesh, &mesh.face_sets["z1"]), 3e3);
            let state = wiggle(&mesh, 1e-3);
            let n = state.len();
            let mut r = vec![0.0; n];
            let mut k = vec![0.0; n * n];
            let mut put = |i: usize, j: usize, v: f64| k[i * n + j] += v;
            add_pressure(&load, 0.5, &state, &mut r, Some(&mut put));
            let p = 0.5 * load.value;
            let h = 1e-7;
            let scale_r = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let scale_k = k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(scale_r > 0.0 && scale_k > 0.0);
            for d in (0..n).filter(|d| d % FIELDS < 3) {
                let (mut plus, mut minus) = (state.clone(), state.clone());
                plus[d] += h;
                minus[d] -= h;
                let dv = (enclosed_volume(&load.faces, &plus)
                    - enclosed_volume(&load.faces, &minus))
                    / (2.0 * h);
                assert!(
                    (r[d] + p * dv).abs() < 1e-6 * scale_r,
                    "{kind:?} dof {d}: {} vs {}",
                    r[d],
                    -p * dv
                );
                let (mut rp, mut rm) = (vec![0.0; n], vec![0.0; n]);
                add_pressure(&load, 0.5, &plus, &mut rp, None);
                add_pressure(&load, 0.5, &minus, &mut rm, None);
                for i in 0..n {
                    let fd = (rp[i] - rm[i]) / (2.0 * h);
                    assert!(
                        (k[i * n + d] - fd).abs() < 1e-6 * scale_k,
                        "{kind:?} K[{i}][{d}] = {} vs {fd}",
                        k[i * n + d]
                    );
                    assert!((k[i * n + d] - k[d * n + i]).abs() < 1e-9 * scale_k);
                }
            }
        }
    }

    /// Away from the edge of the face set the potential's forces are the follower forces
    /// −p ∫ N_a n da of the deformed surface (the edge terms of neighbouring faces cancel).
    #[test]
    fn forces_inside_the_set_are_the_follower_forces() {
        for kind in kinds() {
            let mesh = box_mesh([1e-2, 1e-2, 2e-3], [3, 3, 1], kind);
            let load = Pressure::new(surface(&mesh, &mesh.face_sets["z1"]), 2e3);
            let state = wiggle(&mesh, 1e-3);
            let mut r = vec![0.0; state.len()];
            add_pressure(&load, 1.0, &state, &mut r, None);
            let mut follower = vec![0.0; state.len()];
            for f in &load.faces {
                let x = positions(f, &state);
                for (xi, eta, w) in points(f.nodes.len()) {
                    let (s, d) = shape(f.nodes.len(), xi, eta);
                    let (mut t1, mut t2) = ([0.0; 3], [0.0; 3]);
                    for (a, xa) in x.iter().enumerate() {
                        for i in 0..3 {
                            t1[i] += d[a][0] * xa[i];
                            t2[i] += d[a][1] * xa[i];
                        }
                    }
                    let nda = cross(t1, t2);
                    for (a, &node) in f.nodes.iter().enumerate() {
                        for i in 0..3 {
                            // residual = −(force) = +p ∫ N_a n da
                            follower[node * FIELDS + i] += load.value * f.sign * w * s[a] * nda[i];
                        }
                    }
                }
            }
            let (lo, hi) = (1e-9, 1e-2 - 1e-9);
            let inside: Vec<usize> = load
                .faces
                .iter()
                .flat_map(|f| f.nodes.clone())
                .collect::<std::collections::BTreeSet<_>>()
                .into_iter()
                .filter(|&n| {
                    let p = mesh.nodes[n];
                    p[0] > lo && p[0] < hi && p[1] > lo && p[1] < hi
                })
                .collect();
            assert!(!inside.is_empty());
            let scale = follower.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for n in inside {
                for i in 0..3 {
                    let d = n * FIELDS + i;
                    assert!(
                        (r[d] - follower[d]).abs() < 1e-9 * scale,
                        "{kind:?} node {n}: {} vs {}",
                        r[d],
                        follower[d]
                    );
                }
            }
        }
    }

    /// Ring faces of an axisymmetric model: the outer sides of a solid cylinder enclose minus its
    /// volume (closed by the axis), and so does its image under a uniform stretch; the cavity
    /// of a half shell is the half ball, to the arc's discretisation.
    #[test]
    fn ring_volumes_of_a_cylinder_and_a_half_shell() {
        use crate::mesh::meridian::{rectangle_mesh, sphere_meridian};
        use crate::mesh::MeridianKind;
        for kind in MeridianKind::ALL {
            let (a, h) = (2e-3, 1e-3);
            let mesh = rectangle_mesh(0.0, a, h, 3, 2, kind).unwrap();
            let list: Vec<FaceRef> = ["outer", "top", "bottom"]
                .iter()
                .flat_map(|s| mesh.face_sets[*s].iter().copied())
                .collect();
            let faces = surface(&mesh, &list);
            assert!(faces.iter().all(|f| f.ring));
            let zero = vec![0.0; mesh.n_nodes() * FIELDS];
            let v = enclosed_volume(&faces, &zero);
            let exact = std::f64::consts::PI * a * a * h;
            assert!((v + exact).abs() < 1e-13 * exact, "{kind:?}: {v}");
            let (lr, lz) = (1.3, 0.8);
            let mut state = zero.clone();
            for (n, x) in mesh.nodes.iter().enumerate() {
                state[n * FIELDS] = (lr - 1.0) * x[0];
                state[n * FIELDS + 1] = (lz - 1.0) * x[1];
            }
            let v = enclosed_volume(&faces, &state);
            assert!((v + exact * lr * lr * lz).abs() < 1e-13 * exact, "{kind:?}");
            let shell = sphere_meridian(1e-2, 1.05e-2, 16, 1, kind).unwrap();
            let cavity = surface(&shell, &shell.face_sets["inner"]);
            let v = enclosed_volume(&cavity, &vec![0.0; shell.n_nodes() * FIELDS]);
            let ball = 2.0 / 3.0 * std::f64::consts::PI * 1e-6;
            let bound = if kind.is_quadratic() { 1e-6 } else { 5e-3 };
            assert!(((v - ball) / ball).abs() < bound, "{kind:?}: {v} vs {ball}");
        }
    }

    /// The ring pressure's residual is −p ∂V/∂x and its stiffness the derivative: central
    /// differences on the inner sides of a half shell with a random displacement, every kind.
    #[test]
    fn ring_pressure_matches_finite_differences() {
        use crate::mesh::meridian::sphere_meridian;
        use crate::mesh::MeridianKind;
        for kind in MeridianKind::ALL {
            let mesh = sphere_meridian(1e-2, 1.1e-2, 3, 1, kind).unwrap();
            let load = Pressure::new(surface(&mesh, &mesh.face_sets["inner"]), 2e3);
            let mut state = wiggle(&mesh, 1e-3);
            for v in state.iter_mut().skip(2).step_by(FIELDS) {
                *v = 0.0;
            }
            let n = state.len();
            let mut r = vec![0.0; n];
            let mut k = vec![0.0; n * n];
            let mut put = |i: usize, j: usize, v: f64| k[i * n + j] += v;
            add_pressure(&load, 1.0, &state, &mut r, Some(&mut put));
            let p = load.value;
            let h = 1e-7;
            let scale_r = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let scale_k = k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(scale_r > 0.0 && scale_k > 0.0);
            for d in (0..n).filter(|d| d % FIELDS < 2) {
                let (mut plus, mut minus) = (state.clone(), state.clone());
                plus[d] += h;
                minus[d] -= h;
                let dv = (enclosed_volume(&load.faces, &plus)
                    - enclosed_volume(&load.faces, &minus))
                    / (2.0 * h);
                assert!(
                    (r[d] + p * dv).abs() < 1e-6 * scale_r,
                    "{kind:?} dof {d}: {} vs {}",
                    r[d],
                    -p * dv
                );
                let (mut rp, mut rm) = (vec![0.0; n], vec![0.0; n]);
                add_pressure(&load, 1.0, &plus, &mut rp, None);
                add_pressure(&load, 1.0, &minus, &mut rm, None);
                for i in 0..n {
                    let fd = (rp[i] - rm[i]) / (2.0 * h);
                    assert!(
                        (k[i * n + d] - fd).abs() < 1e-6 * scale_k,
                        "{kind:?} K[{i}][{d}] = {} vs {fd}",
                        k[i * n + d]
                    );
                    assert!((k[i * n + d] - k[d * n + i]).abs() < 1e-9 * scale_k);
                }
            }
        }
    }
}
