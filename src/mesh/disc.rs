//! Circular membrane (disc) meshes for the circular dielectric elastomer actuator: an O-grid of
//! hexahedra (or tetrahedra, six per hexahedron) with a rigid central pad and electrode discs.
//!
//! # Topology
//!
//! The in-plane (x, y) mesh is an O-grid, extruded uniformly through the thickness
//! (`layers` cells, z ∈ [0, thickness]):
//!
//! * a **central block**: a structured `m × m` grid per quadrant (`2m × 2m` for the full disc)
//!   covering the parameter square `[-1, 1]²`, mapped onto a rounded square of half-width
//!   `0.5·pad_radius` by a blend (70 % square, 30 % disc) of the identity and the elliptical
//!   square-to-disc map, so that its corners stay well shaped;
//! * an **inner ring**: `q = ⌈m/2⌉` layers of cells from the block boundary out to the pad circle
//!   `r = pad_radius`, each ring line a linear blend of the (rounded) block boundary and the circle;
//! * an **annulus**: `radial` layers of cells on straight rays from `pad_radius` to `radius`,
//!   graded geometrically (cell size ratio ≈ `grading` between the rim and the pad), with one
//!   ring of nodes exactly at `electrode_radius`.
//!
//! Circumferentially there are `2m` cells per quarter circle (`8m` around the full disc), equally
//! spaced in angle on every ring line outside the block. `m` is chosen so that the cells are
//! roughly square at the electrode edge:
//! `m = max(2, ⌈radial · (π/4) · electrode_radius / (radius − pad_radius)⌉)`.
//! See [`DiscSpec::layout`]; hexahedra per layer = `m² + 2m(q + radial)` for a quarter disc and
//! four times that for the full disc.
//!
//! # Sets
//!
//! Node and face sets `rim`, `top`, `bottom`, `electrode_top`, `electrode_bottom` and, for a
//! quarter disc, `symmetry_x` (x = 0) and `symmetry_y` (y = 0); node sets `pad` (r ≤ pad_radius)
//! and `rim_bottom` (the rim's bottom edge, where the clamp holds the membrane vertically);
//! cell sets `all`, `pad` (block and inner ring) and `annulus` (the rest). Set membership uses a
//! tolerance of `1e-9 · radius`.

use super::{ElementKind, FaceRef, Mesh};
use std::collections::{BTreeMap, HashMap};

/// Half-width of the central block, as a fraction of the pad radius.
const BLOCK_HALF_WIDTH: f64 = 0.5;
/// Weight of the square-to-disc map in the central block's blend (0: square, 1: disc).
const BLOCK_ROUNDING: f64 = 0.3;

/// Parameters of a disc mesh (reference configuration, metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiscSpec {
    /// Outer (clamped rim) radius, m.
    pub radius: f64,
    /// Thickness, m; the disc spans z ∈ [0, thickness].
    pub thickness: f64,
    /// Radius of the central rigid pad, m (0 < pad_radius < electrode_radius).
    pub pad_radius: f64,
    /// Radius of the electrode discs, m (< radius).
    pub electrode_radius: f64,
    /// Cells across the annulus between the pad and the rim (≥ 2).
    pub radial: usize,
    /// Cells through the thickness (≥ 1).
    pub layers: usize,
    /// A quarter disc (x ≥ 0, y ≥ 0) with symmetry faces, or the full disc.
    pub quarter: bool,
    /// Ratio (≥ 1) of the outermost to the innermost radial cell size of the annulus (1: uniform).
    pub grading: f64,
    /// Hex8, or Tet4 (each hexahedron split into six tetrahedra).
    pub kind: ElementKind,
}

/// The resolution [`disc_mesh`] derives from a [`DiscSpec`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DiscLayout {
    /// `m`: cells along the half-width of the central block (2m cells per quarter circle).
    pub block: usize,
    /// `q`: ring layers between the central block and the pad circle.
    pub inner_rings: usize,
    /// Annulus layers between the pad circle and the electrode edge (the rest reach the rim).
    pub electrode_rings: usize,
    /// Cells around the mesh circumferentially (2m for a quarter, 8m for the full disc).
    pub circumferential: usize,
    /// Hexahedra in the mesh (tetrahedral meshes have six times as many cells).
    pub hexahedra: usize,
    /// Nodes in the mesh.
    pub nodes: usize,
}

impl DiscSpec {
    /// The circular actuator of the experimental study in its reference (un-pre-stretched)
    /// state: R = 17.5 mm, t = 1 mm, pad 3.75 mm, electrodes 7.5 mm; a coarse quarter disc.
    pub fn reference_actuator(kind: ElementKind) -> Self {
        DiscSpec {
            radius: 17.5e-3,
            thickness: 1.0e-3,
            pad_radius: 3.75e-3,
            electrode_radius: 7.5e-3,
            radial: 8,
            layers: 1,
            quarter: true,
            grading: 1.0,
            kind,
        }
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), String> {
        let finite_pos = |v: f64| v.is_finite() && v > 0.0;
        if !finite_pos(self.radius) || !finite_pos(self.thickness) {
            return Err(format!(
                "disc mesh: radius ({}) and thickness ({}) must be positive",
                self.radius, self.thickness
            ));
        }
        if !(finite_pos(self.pad_radius)
            && self.pad_radius < self.electrode_radius
            && self.electrode_radius < self.radius)
        {
            return Err(format!(
                "disc mesh: need 0 < pad_radius ({}) < electrode_radius ({}) < radius ({})",
                self.pad_radius, self.electrode_radius, self.radius
            ));
        }
        if self.radial < 2 {
            return Err(format!(
                "disc mesh: radial = {} (need at least 2 cells across the annulus)",
                self.radial
            ));
        }
        if self.layers < 1 {
            return Err("disc mesh: layers must be at least 1".to_string());
        }
        if !(self.grading.is_finite() && self.grading >= 1.0) {
            return Err(format!(
                "disc mesh: grading = {} (need a finite ratio ≥ 1)",
                self.grading
            ));
        }
        Ok(())
    }

    /// The resolution the generator uses for this spec (see the module documentation).
    pub fn layout(&self) -> Result<DiscLayout, String> {
        self.validate()?;
        let ideal = self.radial as f64 * std::f64::consts::FRAC_PI_4 * self.electrode_radius
            / (self.radius - self.pad_radius);
        let m = (ideal.ceil() as usize).max(2);
        let q = m.div_ceil(2);
        let (_, n1) = annulus_radii(self);
        let quadrants = if self.quarter { 1 } else { 4 };
        let per_layer = quadrants * (m * m + 2 * m * (q + self.radial));
        let nodes_2d = if self.quarter {
            (m + 1) * (m + 1) + (2 * m + 1) * (q + self.radial)
        } else {
            (2 * m + 1) * (2 * m + 1) + 8 * m * (q + self.radial)
        };
        Ok(DiscLayout {
            block: m,
            inner_rings: q,
            electrode_rings: n1,
            circumferential: quadrants * 2 * m,
            hexahedra: per_layer * self.layers,
            nodes: nodes_2d * (self.layers + 1),
        })
    }
}

/// Maps [0, 1] onto [0, 1] so that the derivative grows by the factor `g` along the interval.
fn graded(xi: f64, g: f64) -> f64 {
    if (g - 1.0).abs() < 1e-12 {
        xi
    } else {
        (g.powf(xi) - 1.0) / (g - 1.0)
    }
}

/// Inverse of [`graded`].
fn graded_inv(y: f64, g: f64) -> f64 {
    if (g - 1.0).abs() < 1e-12 {
        y
    } else {
        (1.0 + y * (g - 1.0)).ln() / g.ln()
    }
}

/// Radii of the annulus node rings (`radial + 1` values from pad_radius to radius) and the index
/// of the ring at the electrode radius.
pub(crate) fn annulus_radii(spec: &DiscSpec) -> (Vec<f64>, usize) {
    let n = spec.radial;
    let width = spec.radius - spec.pad_radius;
    let xi_e = graded_inv(
        (spec.electrode_radius - spec.pad_radius) / width,
        spec.grading,
    );
    let n1 = ((xi_e * n as f64).round() as usize).clamp(1, n - 1);
    let mut radii: Vec<f64> = (0..=n)
        .map(|k| {
            let xi = if k <= n1 {
                xi_e * k as f64 / n1 as f64
            } else {
                xi_e + (1.0 - xi_e) * (k - n1) as f64 / (n - n1) as f64
            };
            spec.pad_radius + width * graded(xi, spec.grading)
        })
        .collect();
    radii[0] = spec.pad_radius;
    radii[n1] = spec.electrode_radius;
    radii[n] = spec.radius;
    (radii, n1)
}

/// Unit direction of ring position `s` out of `8m` around the circle (exact on the axes).
fn direction(s: usize, m: usize) -> [f64; 2] {
    let s = s % (8 * m);
    if s.is_multiple_of(2 * m) {
        match s / (2 * m) {
            0 => [1.0, 0.0],
            1 => [0.0, 1.0],
            2 => [-1.0, 0.0],
            _ => [0.0, -1.0],
        }
    } else {
        let theta = std::f64::consts::PI * s as f64 / (4 * m) as f64;
        [theta.cos(), theta.sin()]
    }
}

/// Block grid indices (i, j ∈ −m..=m) of the block boundary node at ring position `s` (0..8m,
/// counter-clockwise from the +x axis).
fn boundary_ij(s: usize, m: usize) -> (i64, i64) {
    let (s, m) = ((s % (8 * m)) as i64, m as i64);
    if s <= m {
        (m, s)
    } else if s <= 3 * m {
        (2 * m - s, m)
    } else if s <= 5 * m {
        (-m, 4 * m - s)
    } else if s <= 7 * m {
        (s - 6 * m, -m)
    } else {
        (m, s - 8 * m)
    }
}

/// Position of block grid node (i, j): the parameter square blended with the elliptical
/// square-to-disc map, scaled to the block half-width `a`.
fn block_point(i: i64, j: i64, m: usize, a: f64) -> [f64; 2] {
    let u = i as f64 / m as f64;
    let v = j as f64 / m as f64;
    let du = u * (1.0 - 0.5 * v * v).sqrt();
    let dv = v * (1.0 - 0.5 * u * u).sqrt();
    let b = BLOCK_ROUNDING;
    [a * ((1.0 - b) * u + b * du), a * ((1.0 - b) * v + b * dv)]
}

/// The in-plane O-grid: node positions, counter-clockwise quads and whether each lies in the pad.
struct Plane {
    points: Vec<[f64; 2]>,
    quads: Vec<[usize; 4]>,
    in_pad: Vec<bool>,
}

fn plane_mesh(spec: &DiscSpec, lay: &DiscLayout) -> Plane {
    let m = lay.block;
    let q = lay.inner_rings;
    let (radii, _) = annulus_radii(spec);
    let rings = q + spec.radial;
    let a = BLOCK_HALF_WIDTH * spec.pad_radius;
    let lo: i64 = if spec.quarter { 0 } else { -(m as i64) };
    let hi = m as i64;
    let width = (hi - lo + 1) as usize;
    let block_id = |i: i64, j: i64| (j - lo) as usize * width + (i - lo) as usize;

    let mut points = Vec::new();
    for j in lo..=hi {
        for i in lo..=hi {
            points.push(block_point(i, j, m, a));
        }
    }
    let n_block = points.len();
    // Ring positions: 0..=2m (open) for a quarter, 0..8m (periodic) for the full disc.
    let (ring_nodes, ring_cells) = if spec.quarter {
        (2 * m + 1, 2 * m)
    } else {
        (8 * m, 8 * m)
    };
    let ring_id = |s: usize, l: usize| {
        if l == 0 {
            let (i, j) = boundary_ij(s, m);
            block_id(i, j)
        } else {
            n_block + (l - 1) * ring_nodes + s % ring_nodes
        }
    };
    for l in 1..=rings {
        for s in 0..ring_nodes {
            let d = direction(s, m);
            let p = if l < q {
                let (i, j) = boundary_ij(s, m);
                let b = block_point(i, j, m, a);
                let t = l as f64 / q as f64;
                let c = [spec.pad_radius * d[0], spec.pad_radius * d[1]];
                [(1.0 - t) * b[0] + t * c[0], (1.0 - t) * b[1] + t * c[1]]
            } else {
                let r = radii[l - q];
                [r * d[0], r * d[1]]
            };
            points.push(p);
        }
    }

    let mut quads = Vec::new();
    let mut in_pad = Vec::new();
    for j in lo..hi {
        for i in lo..hi {
            quads.push([
                block_id(i, j),
                block_id(i + 1, j),
                block_id(i + 1, j + 1),
                block_id(i, j + 1),
            ]);
            in_pad.push(true);
        }
    }
    for l in 0..rings {
        for s in 0..ring_cells {
            // Outwards, then counter-clockwise: e_r × e_θ = +z.
            quads.push([
                ring_id(s, l),
                ring_id(s, l + 1),
                ring_id(s + 1, l + 1),
                ring_id(s + 1, l),
            ]);
            in_pad.push(l < q);
        }
    }
    Plane {
        points,
        quads,
        in_pad,
    }
}

fn signed_volume(p: [[f64; 3]; 4]) -> f64 {
    let d = |k: usize| [p[k][0] - p[0][0], p[k][1] - p[0][1], p[k][2] - p[0][2]];
    let (a, b, c) = (d(1), d(2), d(3));
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// A 3-D disc mesh (see the module documentation for the topology and the sets); the meridian
/// form of the same actuator is [`crate::mesh::meridian::disc_meridian`].
pub fn disc_mesh(spec: &DiscSpec) -> Result<Mesh, String> {
    if let ElementKind::Meridian(_) = spec.kind {
        return Err(
            "a meridian element kind: the axisymmetric disc is built by `disc_meridian`".into(),
        );
    }
    if spec.kind == ElementKind::Tet10 {
        let linear = DiscSpec {
            kind: ElementKind::Tet4,
            ..*spec
        };
        return Ok(super::quadratic::to_tet10(&disc_mesh(&linear)?));
    }
    let lay = spec.layout()?;
    let plane = plane_mesh(spec, &lay);
    for (c, quad) in plane.quads.iter().enumerate() {
        let p: Vec<[f64; 2]> = quad.iter().map(|&n| plane.points[n]).collect();
        // Every corner of a bilinear quad must turn left for a positive Jacobian everywhere.
        for k in 0..4 {
            let (a, b, o) = (p[(k + 1) % 4], p[(k + 3) % 4], p[k]);
            let cross = (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
            if cross <= 0.0 {
                return Err(format!(
                    "disc mesh: in-plane cell {c} is not convex (spec {spec:?})"
                ));
            }
        }
    }
    let n2 = plane.points.len();
    let nl = spec.layers;
    let mut nodes = Vec::with_capacity(n2 * (nl + 1));
    for k in 0..=nl {
        let z = if k == nl {
            spec.thickness
        } else {
            spec.thickness * k as f64 / nl as f64
        };
        nodes.extend(plane.points.iter().map(|p| [p[0], p[1], z]));
    }

    let mut connectivity = Vec::new();
    let mut pad_cells = Vec::new();
    let mut annulus_cells = Vec::new();
    let mut cell = 0usize;
    for k in 0..nl {
        let (lo, up) = (k * n2, (k + 1) * n2);
        for (quad, &in_pad) in plane.quads.iter().zip(&plane.in_pad) {
            let first = cell;
            match spec.kind {
                ElementKind::Hex8 => {
                    connectivity.extend(quad.iter().map(|&n| lo + n));
                    connectivity.extend(quad.iter().map(|&n| up + n));
                    cell += 1;
                }
                ElementKind::Meridian(_) => unreachable!("meridian kinds return above"),
                ElementKind::Tet4 | ElementKind::Tet10 => {
                    // Two triangles along the shorter diagonal; each triangular prism into three
                    // tetrahedra whose vertical face diagonals run from the lower-numbered bottom
                    // node to the higher-numbered top node, a rule that depends only on the face,
                    // so neighbouring cells agree (conforming).
                    let d2 = |a: usize, b: usize| {
                        let (p, r) = (plane.points[a], plane.points[b]);
                        (p[0] - r[0]).powi(2) + (p[1] - r[1]).powi(2)
                    };
                    let [a, b, c, d] = *quad;
                    let tris = if d2(a, c) <= d2(b, d) {
                        [[a, b, c], [a, c, d]]
                    } else {
                        [[a, b, d], [b, c, d]]
                    };
                    for mut tri in tris {
                        tri.sort_unstable();
                        let [x, y, z] = tri;
                        for t in [
                            [lo + x, lo + y, lo + z, up + z],
                            [lo + x, lo + y, up + y, up + z],
                            [lo + x, up + x, up + y, up + z],
                        ] {
                            let mut t = t;
                            if signed_volume(t.map(|n| nodes[n])) < 0.0 {
                                t.swap(1, 2);
                            }
                            connectivity.extend_from_slice(&t);
                            cell += 1;
                        }
                    }
                }
            }
            let target = if in_pad {
                &mut pad_cells
            } else {
                &mut annulus_cells
            };
            target.extend(first..cell);
        }
    }

    let mut mesh = Mesh::new(spec.kind, nodes, connectivity);
    mesh.face_sets = classify_boundary(&mesh, spec)?;
    mesh.insert_face_set_nodes();
    let tol = 1e-9 * spec.radius;
    let pad_nodes: Vec<usize> = (0..mesh.n_nodes())
        .filter(|&n| radius_of(mesh.nodes[n]) <= spec.pad_radius + tol)
        .collect();
    mesh.node_sets.insert("pad".to_string(), pad_nodes);
    // the clamp line: held vertically while the clamped edge may still thin
    let rim_bottom: Vec<usize> = mesh.node_sets["rim"]
        .iter()
        .copied()
        .filter(|n| mesh.node_sets["bottom"].binary_search(n).is_ok())
        .collect();
    mesh.node_sets.insert("rim_bottom".to_string(), rim_bottom);
    mesh.cell_sets
        .insert("all".to_string(), (0..mesh.n_cells()).collect());
    mesh.cell_sets.insert("pad".to_string(), pad_cells);
    mesh.cell_sets.insert("annulus".to_string(), annulus_cells);
    Ok(mesh)
}

fn radius_of(p: [f64; 3]) -> f64 {
    p[0].hypot(p[1])
}

/// Finds the faces that belong to one cell only and sorts them into the named face sets; every
/// boundary face must land in one of rim, top, bottom (or the symmetry planes).
fn classify_boundary(
    mesh: &Mesh,
    spec: &DiscSpec,
) -> Result<BTreeMap<String, Vec<FaceRef>>, String> {
    let mut seen: HashMap<[usize; 4], (FaceRef, usize)> = HashMap::new();
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        for (f, local) in mesh.kind.faces().iter().enumerate() {
            let mut key = [usize::MAX; 4];
            for (k, &l) in local.iter().enumerate() {
                key[k] = cell[l];
            }
            key.sort_unstable();
            seen.entry(key)
                .and_modify(|e| e.1 += 1)
                .or_insert((FaceRef { cell: c, face: f }, 1));
        }
    }
    let mut boundary: Vec<FaceRef> = seen
        .values()
        .filter(|(_, count)| *count == 1)
        .map(|(f, _)| *f)
        .collect();
    boundary.sort_unstable();

    let tol = 1e-9 * spec.radius;
    let mut names = vec!["rim", "top", "bottom", "electrode_top", "electrode_bottom"];
    if spec.quarter {
        names.extend(["symmetry_x", "symmetry_y"]);
    }
    let mut sets: BTreeMap<String, Vec<FaceRef>> =
        names.iter().map(|n| (n.to_string(), Vec::new())).collect();
    for f in boundary {
        let cell = mesh.cell(f.cell);
        let pts: Vec<[f64; 3]> = mesh.kind.faces()[f.face]
            .iter()
            .map(|&l| mesh.nodes[cell[l]])
            .collect();
        let all = |pred: &dyn Fn(&[f64; 3]) -> bool| pts.iter().all(pred);
        let in_electrode = all(&|p| radius_of(*p) <= spec.electrode_radius + tol);
        let name = if all(&|p| p[2] >= spec.thickness - tol) {
            if in_electrode {
                sets.get_mut("electrode_top").expect("created").push(f);
            }
            "top"
        } else if all(&|p| p[2] <= tol) {
            if in_electrode {
                sets.get_mut("electrode_bottom").expect("created").push(f);
            }
            "bottom"
        } else if all(&|p| radius_of(*p) >= spec.radius - tol) {
            "rim"
        } else if spec.quarter && all(&|p| p[0].abs() <= tol) {
            "symmetry_x"
        } else if spec.quarter && all(&|p| p[1].abs() <= tol) {
            "symmetry_y"
        } else {
            return Err(format!(
                "disc mesh: internal error, unclassified boundary face {f:?} at {pts:?}"
            ));
        };
        sets.get_mut(name).expect("created").push(f);
    }
    Ok(sets)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::ReferenceElement;
    use crate::mesh::test_geometry::{area_vector, cross, dot, sub, volume};
    use std::collections::BTreeSet;
    use std::f64::consts::PI;

    const KINDS: [ElementKind; 2] = [ElementKind::Hex8, ElementKind::Tet4];

    fn spec(kind: ElementKind, quarter: bool, radial: usize) -> DiscSpec {
        DiscSpec {
            radial,
            layers: 2,
            quarter,
            ..DiscSpec::reference_actuator(kind)
        }
    }

    fn variants() -> Vec<DiscSpec> {
        let mut v = Vec::new();
        for kind in KINDS {
            for quarter in [true, false] {
                v.push(spec(kind, quarter, 8));
                v.push(DiscSpec {
                    grading: 3.0,
                    layers: 1,
                    ..spec(kind, quarter, 5)
                });
            }
        }
        v
    }

    fn norm(a: [f64; 3]) -> f64 {
        dot(a, a).sqrt()
    }

    fn face_points(m: &Mesh, f: &FaceRef) -> Vec<[f64; 3]> {
        let cell = m.cell(f.cell);
        m.kind.faces()[f.face]
            .iter()
            .map(|&l| m.nodes[cell[l]])
            .collect()
    }

    #[test]
    fn every_cell_has_positive_jacobian_and_reasonable_shape() {
        const HEX_CORNER_EDGES: [[usize; 3]; 8] = [
            [1, 3, 4],
            [2, 0, 5],
            [3, 1, 6],
            [0, 2, 7],
            [7, 5, 0],
            [4, 6, 1],
            [5, 7, 2],
            [6, 4, 3],
        ];
        for s in variants() {
            let m = disc_mesh(&s).unwrap();
            let el = ReferenceElement::new(s.kind);
            let mut coords = vec![[0.0; 3]; s.kind.nodes_per_cell()];
            let mut worst = f64::INFINITY;
            for c in 0..m.n_cells() {
                m.cell_coords_into(c, &mut coords);
                assert!(el.geometry(&coords).is_ok(), "{s:?}: cell {c}");
                // Scaled Jacobian at every corner (hexahedra) or of the tetrahedron.
                let corners: Vec<[usize; 4]> = match s.kind {
                    ElementKind::Hex8 => HEX_CORNER_EDGES
                        .iter()
                        .enumerate()
                        .map(|(k, e)| [k, e[0], e[1], e[2]])
                        .collect(),
                    ElementKind::Tet4 | ElementKind::Tet10 => vec![[0, 1, 2, 3]],
                    ElementKind::Meridian(_) => unreachable!("3-D variants only"),
                };
                for [o, a, b, d] in corners {
                    let (ea, eb, ed) = (
                        sub(coords[a], coords[o]),
                        sub(coords[b], coords[o]),
                        sub(coords[d], coords[o]),
                    );
                    let det = dot(cross(ea, eb), ed);
                    assert!(det > 0.0, "{s:?}: cell {c} corner {o}");
                    worst = worst.min(det / (norm(ea) * norm(eb) * norm(ed)));
                }
            }
            // Hexahedra: every corner angle well away from 0° and 180°.
            let bound = if s.kind == ElementKind::Hex8 {
                0.6
            } else {
                0.02
            };
            assert!(worst > bound, "{s:?}: worst scaled Jacobian {worst}");
        }
    }

    #[test]
    fn volume_matches_the_disc_and_converges() {
        for kind in KINDS {
            for quarter in [true, false] {
                let exact = |s: &DiscSpec| {
                    PI * s.radius * s.radius * s.thickness / if quarter { 4.0 } else { 1.0 }
                };
                let mut errors = Vec::new();
                for radial in [8, 16, 32] {
                    let s = spec(kind, quarter, radial);
                    let m = disc_mesh(&s).unwrap();
                    let err = (volume(&m) - exact(&s)).abs() / exact(&s);
                    errors.push(err);
                }
                assert!(errors[0] < 1e-2, "{kind:?} quarter={quarter}: {errors:?}");
                assert!(
                    errors[1] < 0.5 * errors[0] && errors[2] < 0.5 * errors[1],
                    "{kind:?} quarter={quarter}: {errors:?}"
                );
                // Graded meshes fill the same polygon.
                let s = DiscSpec {
                    grading: 4.0,
                    ..spec(kind, quarter, 8)
                };
                let err = (volume(&disc_mesh(&s).unwrap()) - exact(&s)).abs() / exact(&s);
                assert!((err - errors[0]).abs() < 1e-12, "{err} vs {}", errors[0]);
            }
        }
    }

    #[test]
    fn sets_exist_and_lie_where_they_should() {
        for s in variants() {
            let m = disc_mesh(&s).unwrap();
            let tol = 1e-9 * s.radius;
            let r = |n: usize| radius_of(m.nodes[n]);
            let mut names = vec!["rim", "top", "bottom", "electrode_top", "electrode_bottom"];
            if s.quarter {
                names.extend(["symmetry_x", "symmetry_y"]);
            } else {
                assert!(!m.face_sets.contains_key("symmetry_x"));
            }
            for name in &names {
                assert!(!m.face_sets[*name].is_empty(), "{s:?}: face set {name}");
                assert_eq!(
                    m.node_sets[*name],
                    m.face_set_nodes(name).unwrap(),
                    "{name}"
                );
            }
            assert!(!m.node_sets["pad"].is_empty());
            for name in ["all", "pad", "annulus"] {
                assert!(!m.cell_sets[name].is_empty(), "{s:?}: cell set {name}");
            }
            let mut cells: Vec<usize> = m.cell_sets["pad"].clone();
            cells.extend(&m.cell_sets["annulus"]);
            cells.sort_unstable();
            assert_eq!(cells, m.cell_sets["all"], "pad ∪ annulus = all, disjoint");

            for &n in &m.node_sets["rim"] {
                assert!((r(n) - s.radius).abs() <= 1e-12 * s.radius, "rim node {n}");
            }
            for &n in &m.node_sets["top"] {
                assert_eq!(m.nodes[n][2], s.thickness);
            }
            for &n in &m.node_sets["bottom"] {
                assert_eq!(m.nodes[n][2], 0.0);
            }
            let pad = &m.node_sets["pad"];
            for &n in pad {
                assert!(r(n) <= s.pad_radius + tol);
            }
            // The pad circle exists as a ring of nodes, and the pad set holds every node inside.
            assert!(pad
                .iter()
                .any(|&n| (r(n) - s.pad_radius).abs() <= 1e-12 * s.radius));
            let inside = (0..m.n_nodes())
                .filter(|&n| r(n) <= s.pad_radius + tol)
                .count();
            assert_eq!(pad.len(), inside);
            for &c in &m.cell_sets["pad"] {
                assert!(m.cell(c).iter().all(|&n| r(n) <= s.pad_radius + tol));
            }
            for &c in &m.cell_sets["annulus"] {
                assert!(m.cell(c).iter().all(|&n| r(n) >= s.pad_radius - tol));
            }
            for (name, z) in [("electrode_top", s.thickness), ("electrode_bottom", 0.0)] {
                let nodes = &m.node_sets[name];
                assert!(nodes
                    .iter()
                    .all(|&n| r(n) <= s.electrode_radius + tol && m.nodes[n][2] == z));
                let at_edge = nodes
                    .iter()
                    .filter(|&&n| (r(n) - s.electrode_radius).abs() <= 1e-12 * s.radius)
                    .count();
                assert!(
                    at_edge >= 3,
                    "{s:?}: {name} has {at_edge} nodes at the edge"
                );
                // Every surface node inside the electrode radius belongs to the electrode.
                let expected = (0..m.n_nodes())
                    .filter(|&n| m.nodes[n][2] == z && r(n) <= s.electrode_radius + tol)
                    .count();
                assert_eq!(nodes.len(), expected, "{name}");
            }
            if s.quarter {
                for (name, axis) in [("symmetry_x", 0), ("symmetry_y", 1)] {
                    for &n in &m.node_sets[name] {
                        assert_eq!(m.nodes[n][axis], 0.0, "{name}");
                    }
                }
                assert!(m.nodes.iter().all(|p| p[0] >= 0.0 && p[1] >= 0.0));
            }
        }
    }

    /// The outward direction of a face set at a face centre.
    type Outward = fn([f64; 3]) -> [f64; 3];

    #[test]
    fn boundary_face_normals_point_outwards() {
        for s in variants() {
            let m = disc_mesh(&s).unwrap();
            let mut sets: Vec<(&str, Outward)> = vec![
                ("top", (|_| [0.0, 0.0, 1.0])),
                ("electrode_top", (|_| [0.0, 0.0, 1.0])),
                ("bottom", (|_| [0.0, 0.0, -1.0])),
                ("electrode_bottom", (|_| [0.0, 0.0, -1.0])),
                ("rim", (|c| [c[0], c[1], 0.0])),
            ];
            if s.quarter {
                sets.push(("symmetry_x", (|_| [-1.0, 0.0, 0.0])));
                sets.push(("symmetry_y", (|_| [0.0, -1.0, 0.0])));
            }
            for (name, outward) in sets {
                for f in &m.face_sets[name] {
                    let p = face_points(&m, f);
                    let mut centre = [0.0; 3];
                    for q in &p {
                        for i in 0..3 {
                            centre[i] += q[i] / p.len() as f64;
                        }
                    }
                    let a = area_vector(&p);
                    let n = outward(centre);
                    let cos = dot(a, n) / (norm(a) * norm(n));
                    assert!(cos > 0.99, "{s:?}: {name} face {f:?}, cos = {cos}");
                }
            }
        }
    }

    #[test]
    fn mesh_is_conforming_and_boundary_is_the_named_sets() {
        for s in variants() {
            let m = disc_mesh(&s).unwrap();
            let count = m.face_use_counts();
            assert!(count.values().all(|&k| k == 1 || k == 2), "{s:?}");
            let boundary: BTreeSet<Vec<usize>> = count
                .iter()
                .filter(|(_, &k)| k == 1)
                .map(|(f, _)| f.clone())
                .collect();
            let mut names = vec!["rim", "top", "bottom"];
            if s.quarter {
                names.extend(["symmetry_x", "symmetry_y"]);
            }
            let mut union = BTreeSet::new();
            let mut total = 0;
            for name in names {
                for f in &m.face_sets[name] {
                    let cell = m.cell(f.cell);
                    let mut key: Vec<usize> =
                        m.kind.faces()[f.face].iter().map(|&l| cell[l]).collect();
                    key.sort_unstable();
                    union.insert(key);
                    total += 1;
                }
            }
            assert_eq!(total, union.len(), "{s:?}: face sets overlap");
            assert_eq!(union, boundary, "{s:?}");
            // Every node is used by some cell.
            let mut used = vec![false; m.n_nodes()];
            m.connectivity.iter().for_each(|&n| used[n] = true);
            assert!(used.iter().all(|&u| u), "{s:?}: orphan nodes");
        }
    }

    #[test]
    fn electrode_area_matches_the_disc() {
        for s in variants() {
            let m = disc_mesh(&s).unwrap();
            for name in ["electrode_top", "electrode_bottom"] {
                let area: f64 = m.face_sets[name]
                    .iter()
                    .map(|f| norm(area_vector(&face_points(&m, f))))
                    .sum();
                let exact = PI * s.electrode_radius.powi(2) / if s.quarter { 4.0 } else { 1.0 };
                assert!(
                    (area - exact).abs() < 0.02 * exact,
                    "{s:?}: {name} area {area} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn layout_counts_match_the_mesh() {
        for s in variants() {
            let lay = s.layout().unwrap();
            let m = disc_mesh(&s).unwrap();
            let per_hex = if s.kind == ElementKind::Hex8 { 1 } else { 6 };
            assert_eq!(m.n_cells(), lay.hexahedra * per_hex, "{s:?}");
            assert_eq!(m.n_nodes(), lay.nodes, "{s:?}");
            let (radii, n1) = annulus_radii(&s);
            assert_eq!(n1, lay.electrode_rings);
            assert!(radii.windows(2).all(|w| w[1] > w[0]));
            if s.grading > 1.0 {
                let first = radii[1] - radii[0];
                let last = radii[s.radial] - radii[s.radial - 1];
                assert!(last > first, "graded outwards: {radii:?}");
            }
        }
        let lay = DiscSpec::reference_actuator(ElementKind::Hex8)
            .layout()
            .unwrap();
        assert_eq!((lay.block, lay.inner_rings, lay.circumferential), (4, 2, 8));
        assert_eq!(lay.hexahedra, 16 + 8 * (2 + 8));
    }

    #[test]
    fn rejects_bad_specs() {
        let good = DiscSpec::reference_actuator(ElementKind::Hex8);
        assert!(disc_mesh(&good).is_ok());
        let bad = [
            DiscSpec { radial: 1, ..good },
            DiscSpec { layers: 0, ..good },
            DiscSpec {
                grading: 0.5,
                ..good
            },
            DiscSpec {
                pad_radius: 8e-3,
                ..good
            },
            DiscSpec {
                electrode_radius: 20e-3,
                ..good
            },
            DiscSpec {
                thickness: 0.0,
                ..good
            },
            DiscSpec {
                pad_radius: f64::NAN,
                ..good
            },
        ];
        for s in bad {
            assert!(disc_mesh(&s).is_err(), "{s:?}");
        }
    }
}
