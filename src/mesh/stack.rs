//! Multilayer stack actuator meshes: `films` elastomer films stacked in z with compliant electrodes
//! on every interface and on the top and bottom faces, the electrodes stopping short of the lateral
//! faces by a passive `border` (the realistic geometry of multilayer dielectric elastomer
//! actuators), with cells graded toward the electrode edges.
//!
//! # Geometry
//!
//! The device occupies `[-Lx/2, Lx/2] × [-Ly/2, Ly/2] × [0, N·t]` (`side = [Lx, Ly]`, N films of
//! thickness t); a quarter model (the default) meshes `x ≥ 0, y ≥ 0` and has symmetry faces at
//! x = 0 and y = 0. Electrode k (k = 0..N) is the plane z = k·t restricted to the active area
//! `|x| ≤ Lx/2 − border, |y| ≤ Ly/2 − border`: electrodes with odd k are meant for the high voltage
//! and those with even k for ground, so that neighbouring films see opposite fields and every film
//! is driven by the full voltage.
//!
//! # Cells
//!
//! A tensor-product grid. Through the thickness, `layers_per_film` equal cells per film, so every
//! interface z = k·t is a plane of nodes. In-plane, along x and along y alike, `active_cells` cells
//! run from the centre (x = 0) to the electrode edge with geometrically growing size away from the
//! edge (largest/smallest = `grading`; 1: uniform), and the passive border continues the same
//! geometric progression outward from a first cell of (about) the edge cell's size, with as many
//! cells as that takes (at least one; see [`StackSpec::layout`]). So the cells on both sides of the
//! electrode edge line, where the field is singular, are the smallest of the mesh. The full model
//! mirrors the quarter's node lines about x = 0 and y = 0. Hexahedra, or tetrahedra (each
//! hexahedron split into six, as the `box` generator; tet10 adds straight-edged mid-edge nodes).
//!
//! # Sets
//!
//! Node and face sets `electrode_0` … `electrode_N` (the faces on z = k·t inside the active area;
//! the interfaces are internal surfaces, their faces are taken from the cells below, from the
//! cells above for k = 0), `bottom`, `top`, `side` (the outer lateral faces), and for a quarter
//! `symmetry_x` (x = 0) and `symmetry_y` (y = 0); node sets `high_voltage` (the electrodes with odd
//! k) and `ground` (even k); cell sets `all`, `active` (cells under the electrodes,
//! |x|, |y| ≤ edge) and `border` (the passive border, empty when `border = 0`). Set membership uses
//! a tolerance of `1e-9 · max(Lx, Ly)`.

use super::generate::{hex_corners, HEX_TO_TETS};
use super::{ElementKind, FaceRef, Mesh};
use std::collections::BTreeMap;

/// Parameters of a stack mesh (reference configuration, metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StackSpec {
    /// In-plane edge lengths [Lx, Ly] of the whole device, m.
    pub side: [f64; 2],
    /// Number of elastomer films N (≥ 1); there are N + 1 electrodes.
    pub films: usize,
    /// Thickness t of one film, m.
    pub film_thickness: f64,
    /// Width of the passive border between the electrode edges and the lateral faces, m
    /// (0 ≤ border < min(Lx, Ly)/2).
    pub border: f64,
    /// Cells through each film (≥ 1).
    pub layers_per_film: usize,
    /// Cells from the centre to the electrode edge along each in-plane axis (≥ 1).
    pub active_cells: usize,
    /// Largest/smallest cell size across the active half-width (≥ 1; the smallest cells sit at
    /// the electrode edge).
    pub grading: f64,
    /// Quarter model (x ≥ 0, y ≥ 0) with symmetry faces, or the full device.
    pub quarter: bool,
    pub kind: ElementKind,
}

/// The resolution [`stack_mesh`] derives from a [`StackSpec`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StackLayout {
    /// Cells across the passive border along each axis (x, y).
    pub border_cells: [usize; 2],
    /// Cells along x, y and z of the meshed part.
    pub cells: [usize; 3],
    /// Hexahedra of the mesh (tetrahedral meshes have six times as many cells).
    pub hexahedra: usize,
    /// Nodes of the mesh (hex8 and tet4).
    pub nodes: usize,
}

impl StackSpec {
    /// A small quarter stack: 4 films of 50 µm, 4 mm square, 0.4 mm border.
    pub fn example(kind: ElementKind) -> Self {
        StackSpec {
            side: [4e-3, 4e-3],
            films: 4,
            film_thickness: 50e-6,
            border: 0.4e-3,
            layers_per_film: 2,
            active_cells: 8,
            grading: 4.0,
            quarter: true,
            kind,
        }
    }

    /// Total thickness N·t, m.
    pub fn thickness(&self) -> f64 {
        self.films as f64 * self.film_thickness
    }

    /// Half-widths of the electrodes (distance of the electrode edges from the centre), m.
    pub fn electrode_half_width(&self) -> [f64; 2] {
        self.side.map(|l| 0.5 * l - self.border)
    }

    /// Electroded (active) area of one electrode of the whole device, m².
    pub fn active_area(&self) -> f64 {
        let [ex, ey] = self.electrode_half_width();
        4.0 * ex * ey
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), String> {
        let finite_pos = |v: f64| v.is_finite() && v > 0.0;
        if !finite_pos(self.side[0]) || !finite_pos(self.side[1]) {
            return Err(format!(
                "stack mesh: side lengths {:?} must be positive",
                self.side
            ));
        }
        if !finite_pos(self.film_thickness) {
            return Err(format!(
                "stack mesh: film_thickness = {} (need a positive thickness)",
                self.film_thickness
            ));
        }
        if self.films < 1 {
            return Err("stack mesh: films must be at least 1".to_string());
        }
        let min_half = 0.5 * self.side[0].min(self.side[1]);
        if !(self.border.is_finite() && self.border >= 0.0 && self.border < min_half) {
            return Err(format!(
                "stack mesh: border = {} (need 0 ≤ border < half the shorter side, {min_half})",
                self.border
            ));
        }
        if self.layers_per_film < 1 {
            return Err("stack mesh: layers_per_film must be at least 1".to_string());
        }
        if self.active_cells < 1 {
            return Err("stack mesh: active_cells must be at least 1".to_string());
        }
        if !(self.grading.is_finite() && self.grading >= 1.0) {
            return Err(format!(
                "stack mesh: grading = {} (need a finite ratio ≥ 1)",
                self.grading
            ));
        }
        Ok(())
    }

    /// The resolution the generator uses for this spec (see the module documentation).
    pub fn layout(&self) -> Result<StackLayout, String> {
        self.validate()?;
        let half = self.side.map(|l| 0.5 * l);
        let border_cells = [0, 1].map(|a| axis_sizes(self, half[a]).1.len());
        let copies = if self.quarter { 1 } else { 2 };
        let cells = [
            copies * (self.active_cells + border_cells[0]),
            copies * (self.active_cells + border_cells[1]),
            self.films * self.layers_per_film,
        ];
        Ok(StackLayout {
            border_cells,
            cells,
            hexahedra: cells[0] * cells[1] * cells[2],
            nodes: (cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1),
        })
    }
}

/// Cell sizes along one half-axis of half-width `half`: the active part from the electrode edge
/// toward the centre (first entry at the edge) and the border from the edge outward.
fn axis_sizes(spec: &StackSpec, half: f64) -> (Vec<f64>, Vec<f64>) {
    let n = spec.active_cells;
    let edge = half - spec.border;
    let r = if n > 1 {
        spec.grading.powf(1.0 / (n - 1) as f64)
    } else {
        1.0
    };
    let series = |first_ratio: f64, count: usize, length: f64| -> Vec<f64> {
        let weights: Vec<f64> = (0..count).map(|k| first_ratio.powi(k as i32)).collect();
        let total: f64 = weights.iter().sum();
        weights.iter().map(|w| length * w / total).collect()
    };
    let active = series(r, n, edge);
    let h0 = active[0];
    let border = if spec.border <= 0.0 {
        Vec::new()
    } else {
        // cells needed to cover the border continuing the progression h0, h0 r, h0 r², …
        let exact = if r > 1.0 + 1e-12 {
            (1.0 + spec.border * (r - 1.0) / h0).ln() / r.ln()
        } else {
            spec.border / h0
        };
        let count = (exact.round() as usize).clamp(1, 100_000);
        series(r, count, spec.border)
    };
    (active, border)
}

/// Node coordinates along one axis: 0 (or −half for the full model) to half, with exact values
/// at the centre, the electrode edges and the lateral faces.
fn axis_nodes(spec: &StackSpec, half: f64) -> Vec<f64> {
    let (active, border) = axis_sizes(spec, half);
    let edge = half - spec.border;
    // the quarter axis from 0 to half
    let mut q = vec![0.0];
    let mut x = 0.0;
    for s in active.iter().rev() {
        x += s;
        q.push(x);
    }
    *q.last_mut().expect("at least one cell") = edge;
    for s in &border {
        x += s;
        q.push(x);
    }
    *q.last_mut().expect("at least one cell") = half;
    if spec.quarter {
        q
    } else {
        let mut full: Vec<f64> = q[1..].iter().rev().map(|v| -v).collect();
        full.extend(q);
        full
    }
}

/// A stack mesh (see the module documentation for the geometry and the sets).
pub fn stack_mesh(spec: &StackSpec) -> Result<Mesh, String> {
    if spec.kind.meridian().is_some() {
        return Err("the stack generator makes 3-D cells (hex8, tet4, tet10)".into());
    }
    if spec.kind == ElementKind::Tet10 {
        let linear = StackSpec {
            kind: ElementKind::Tet4,
            ..*spec
        };
        // node sets again from the faces: the mid-edge rule of `to_tet10` would also add the
        // midpoints of the corner cells' diagonals between the two planes of `side`
        let mut mesh = super::quadratic::to_tet10(&stack_mesh(&linear)?);
        node_sets_from_faces(&mut mesh, spec.films);
        return Ok(mesh);
    }
    let lay = spec.layout()?;
    let half = spec.side.map(|l| 0.5 * l);
    let xs = axis_nodes(spec, half[0]);
    let ys = axis_nodes(spec, half[1]);
    let nl = spec.layers_per_film;
    let zs: Vec<f64> = (0..=spec.films * nl)
        .map(|k| {
            let (film, sub) = (k / nl, k % nl);
            spec.film_thickness * (film as f64 + sub as f64 / nl as f64)
        })
        .collect();
    let [nx, ny, nz] = lay.cells;
    debug_assert_eq!((xs.len(), ys.len(), zs.len()), (nx + 1, ny + 1, nz + 1));
    let node_id = |i: usize, j: usize, k: usize| (k * (ny + 1) + j) * (nx + 1) + i;
    let mut nodes = Vec::with_capacity(lay.nodes);
    for &z in &zs {
        for &y in &ys {
            for &x in &xs {
                nodes.push([x, y, z]);
            }
        }
    }
    let [ex, ey] = spec.electrode_half_width();
    let tol = 1e-9 * spec.side[0].max(spec.side[1]);
    let mut connectivity = Vec::new();
    let (mut active, mut border) = (Vec::new(), Vec::new());
    let mut cell = 0usize;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let h = hex_corners(node_id, i, j, k);
                let first = cell;
                match spec.kind {
                    ElementKind::Hex8 => {
                        connectivity.extend_from_slice(&h);
                        cell += 1;
                    }
                    ElementKind::Meridian(_) => unreachable!("meridian kinds return above"),
                    ElementKind::Tet4 | ElementKind::Tet10 => {
                        for t in HEX_TO_TETS {
                            connectivity.extend(t.iter().map(|&l| h[l]));
                            cell += 1;
                        }
                    }
                }
                let cx = 0.5 * (xs[i] + xs[i + 1]);
                let cy = 0.5 * (ys[j] + ys[j + 1]);
                let target = if cx.abs() < ex && cy.abs() < ey {
                    &mut active
                } else {
                    &mut border
                };
                target.extend(first..cell);
            }
        }
    }
    let mut mesh = Mesh::new(spec.kind, nodes, connectivity);
    mesh.face_sets = classify_faces(&mesh, spec, tol);
    node_sets_from_faces(&mut mesh, spec.films);
    mesh.cell_sets
        .insert("all".to_string(), (0..mesh.n_cells()).collect());
    mesh.cell_sets.insert("active".to_string(), active);
    mesh.cell_sets.insert("border".to_string(), border);
    Ok(mesh)
}

/// Node sets: those of every face set, and `high_voltage` (odd electrodes) and `ground` (even).
fn node_sets_from_faces(mesh: &mut Mesh, films: usize) {
    mesh.insert_face_set_nodes();
    let (mut high, mut ground) = (Vec::new(), Vec::new());
    for k in 0..=films {
        let set = &mesh.node_sets[&format!("electrode_{k}")];
        if k % 2 == 1 {
            high.extend_from_slice(set);
        } else {
            ground.extend_from_slice(set);
        }
    }
    high.sort_unstable();
    ground.sort_unstable();
    mesh.node_sets.insert("high_voltage".to_string(), high);
    mesh.node_sets.insert("ground".to_string(), ground);
}

/// Sorts faces into the named face sets by where their nodes lie: the outer planes (boundary
/// faces: every face on them is one) and the electroded parts of the planes z = k·t (internal
/// faces once, from the cell below; from the cell above for k = 0).
fn classify_faces(mesh: &Mesh, spec: &StackSpec, tol: f64) -> BTreeMap<String, Vec<FaceRef>> {
    let half = spec.side.map(|l| 0.5 * l);
    let [ex, ey] = spec.electrode_half_width();
    let height = spec.thickness();
    let mut names: Vec<String> = ["bottom", "top", "side"].map(String::from).to_vec();
    if spec.quarter {
        names.extend(["symmetry_x", "symmetry_y"].map(String::from));
    }
    names.extend((0..=spec.films).map(|k| format!("electrode_{k}")));
    let mut sets: BTreeMap<String, Vec<FaceRef>> =
        names.into_iter().map(|n| (n, Vec::new())).collect();
    let mut push = |name: &str, f: FaceRef| sets.get_mut(name).expect("created above").push(f);
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        let centroid = mesh.cell_centroid(c);
        for (f, local) in mesh.kind.faces().iter().enumerate() {
            let pts: Vec<[f64; 3]> = local.iter().map(|&l| mesh.nodes[cell[l]]).collect();
            let all = |pred: &dyn Fn(&[f64; 3]) -> bool| pts.iter().all(pred);
            let face = FaceRef { cell: c, face: f };
            if all(&|p| p[2] <= tol) {
                push("bottom", face);
            }
            if all(&|p| p[2] >= height - tol) {
                push("top", face);
            }
            for axis in 0..2 {
                if all(&|p| p[axis] >= half[axis] - tol)
                    || (!spec.quarter && all(&|p| p[axis] <= -half[axis] + tol))
                {
                    push("side", face);
                }
                if spec.quarter && all(&|p| p[axis].abs() <= tol) {
                    push(["symmetry_x", "symmetry_y"][axis], face);
                }
            }
            // an electrode face: on a plane z = k t, inside the active area, seen from below
            let z = pts[0][2];
            let k = (z / spec.film_thickness).round();
            let on_plane = (z - k * spec.film_thickness).abs() <= tol;
            if on_plane
                && all(&|p| (p[2] - z).abs() <= tol)
                && all(&|p| p[0].abs() <= ex + tol && p[1].abs() <= ey + tol)
                && ((k == 0.0 && centroid[2] > z) || (k > 0.0 && centroid[2] < z))
            {
                push(&format!("electrode_{}", k as usize), face);
            }
        }
    }
    sets
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::ReferenceElement;
    use crate::mesh::test_geometry::{dot, sub, volume};
    use std::collections::BTreeSet;

    const KINDS: [ElementKind; 3] = [ElementKind::Hex8, ElementKind::Tet4, ElementKind::Tet10];

    fn variants() -> Vec<StackSpec> {
        let mut v = Vec::new();
        for kind in KINDS {
            for quarter in [true, false] {
                let base = StackSpec {
                    films: 3,
                    active_cells: 4,
                    quarter,
                    ..StackSpec::example(kind)
                };
                v.push(base);
                v.push(StackSpec {
                    side: [4e-3, 3e-3],
                    grading: 1.0,
                    layers_per_film: 1,
                    ..base
                });
            }
        }
        v
    }

    /// Area vector of a face (corners only: the faces are planar).
    fn area_vector(m: &Mesh, f: &FaceRef) -> [f64; 3] {
        let cell = m.cell(f.cell);
        let local = m.kind.faces()[f.face];
        let p: Vec<[f64; 3]> = local[..m.kind.face_corners()]
            .iter()
            .map(|&l| m.nodes[cell[l]])
            .collect();
        crate::mesh::test_geometry::area_vector(&p)
    }

    fn copies(s: &StackSpec) -> f64 {
        if s.quarter {
            4.0
        } else {
            1.0
        }
    }

    #[test]
    fn volume_counts_and_layout() {
        for s in variants() {
            let m = stack_mesh(&s).unwrap();
            let lay = s.layout().unwrap();
            let per_hex = if s.kind == ElementKind::Hex8 { 1 } else { 6 };
            assert_eq!(m.n_cells(), lay.hexahedra * per_hex, "{s:?}");
            if s.kind != ElementKind::Tet10 {
                assert_eq!(m.n_nodes(), lay.nodes, "{s:?}");
            }
            let exact = s.side[0] * s.side[1] * s.thickness() / copies(&s);
            assert!(
                (volume(&m) - exact).abs() < 1e-12 * exact,
                "{s:?}: {} vs {exact}",
                volume(&m)
            );
            let mut cells: Vec<usize> = m.cell_sets["active"].clone();
            cells.extend(&m.cell_sets["border"]);
            cells.sort_unstable();
            assert_eq!(cells, m.cell_sets["all"], "active ∪ border = all, disjoint");
            // the active cells fill the electroded prism, the border the rest
            let mut active = m.clone();
            active.connectivity = m.cell_sets["active"]
                .iter()
                .flat_map(|&c| m.cell(c).to_vec())
                .collect();
            let exact_active = s.active_area() * s.thickness() / copies(&s);
            assert!((volume(&active) - exact_active).abs() < 1e-12 * exact_active);
        }
    }

    #[test]
    fn grading_puts_the_smallest_cells_at_the_electrode_edge() {
        let s = StackSpec {
            active_cells: 10,
            grading: 5.0,
            ..StackSpec::example(ElementKind::Hex8)
        };
        let xs = axis_nodes(&s, 0.5 * s.side[0]);
        let sizes: Vec<f64> = xs.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(sizes.iter().all(|&h| h > 0.0));
        let (edge_index, _) = xs
            .iter()
            .enumerate()
            .find(|(_, &x)| x == 0.5 * s.side[0] - s.border)
            .expect("a node line at the electrode edge");
        assert_eq!(edge_index, 10);
        let (inner, outer) = (sizes[9], sizes[10]);
        assert!((sizes[0] / inner - 5.0).abs() < 1e-9, "{sizes:?}");
        // the border starts at (about) the edge cell's size and grows outward
        assert!((outer / inner - 1.0).abs() < 0.5, "{sizes:?}");
        assert!(sizes[10..].windows(2).all(|w| w[1] >= w[0]));
        assert!(sizes[..10].windows(2).all(|w| w[1] <= w[0]));
        assert_eq!(
            *sizes.iter().min_by(|a, b| a.total_cmp(b)).unwrap(),
            inner.min(outer)
        );
        // full model: mirror image about 0
        let full = axis_nodes(
            &StackSpec {
                quarter: false,
                ..s
            },
            0.5 * s.side[0],
        );
        assert_eq!(full.len(), 2 * xs.len() - 1);
        for (a, b) in full.iter().zip(full.iter().rev()) {
            assert_eq!(*a, -*b);
        }
    }

    #[test]
    fn electrode_sets_cover_the_active_area_on_every_interface() {
        for s in variants() {
            let m = stack_mesh(&s).unwrap();
            let [ex, ey] = s.electrode_half_width();
            let tol = 1e-9 * s.side[0];
            let mut hv: Vec<usize> = Vec::new();
            let mut gnd: Vec<usize> = Vec::new();
            for k in 0..=s.films {
                let name = format!("electrode_{k}");
                let z = k as f64 * s.film_thickness;
                let faces = &m.face_sets[&name];
                let area: f64 = faces.iter().map(|f| area_vector(&m, f)[2].abs()).sum();
                let exact = s.active_area() / copies(&s);
                assert!((area - exact).abs() < 1e-12 * exact, "{s:?}: {name} {area}");
                // normals: −z on the bottom electrode, +z (from the cell below) elsewhere
                for f in faces {
                    let n = area_vector(&m, f);
                    assert!(if k == 0 { n[2] < 0.0 } else { n[2] > 0.0 }, "{name}");
                }
                let nodes = &m.node_sets[&name];
                assert_eq!(*nodes, m.face_set_nodes(&name).unwrap());
                let expected: Vec<usize> = (0..m.n_nodes())
                    .filter(|&n| {
                        let p = m.nodes[n];
                        (p[2] - z).abs() <= tol && p[0].abs() <= ex + tol && p[1].abs() <= ey + tol
                    })
                    .collect();
                assert_eq!(*nodes, expected, "{s:?}: {name}");
                // the edge line is a line of nodes
                assert!(nodes
                    .iter()
                    .any(|&n| (m.nodes[n][0].abs() - ex).abs() <= tol));
                if k % 2 == 1 {
                    hv.extend(nodes);
                } else {
                    gnd.extend(nodes);
                }
            }
            hv.sort_unstable();
            gnd.sort_unstable();
            assert_eq!(m.node_sets["high_voltage"], hv);
            assert_eq!(m.node_sets["ground"], gnd);
            assert!(hv.iter().all(|n| gnd.binary_search(n).is_err()));
            assert!(!m
                .face_sets
                .contains_key(&format!("electrode_{}", s.films + 1)));
        }
    }

    #[test]
    fn boundary_is_the_named_sets_and_normals_point_outwards() {
        for s in variants() {
            let m = stack_mesh(&s).unwrap();
            let count = m.face_use_counts();
            assert!(count.values().all(|&k| k == 1 || k == 2), "{s:?}");
            let boundary: BTreeSet<Vec<usize>> = count
                .iter()
                .filter(|(_, &k)| k == 1)
                .map(|(f, _)| f.clone())
                .collect();
            let mut names = vec!["bottom", "top", "side"];
            if s.quarter {
                names.extend(["symmetry_x", "symmetry_y"]);
            } else {
                assert!(!m.face_sets.contains_key("symmetry_x"));
            }
            let (mut union, mut total) = (BTreeSet::new(), 0);
            for name in names {
                assert!(!m.face_sets[name].is_empty(), "{s:?}: {name}");
                for f in &m.face_sets[name] {
                    let cell = m.cell(f.cell);
                    let mut key: Vec<usize> =
                        m.kind.faces()[f.face].iter().map(|&l| cell[l]).collect();
                    key.sort_unstable();
                    union.insert(key);
                    total += 1;
                    // outward: from the cell centroid toward the face
                    let c = m.cell_centroid(f.cell);
                    let p = m.nodes[cell[m.kind.faces()[f.face][0]]];
                    assert!(dot(area_vector(&m, f), sub(p, c)) > 0.0, "{s:?}: {name}");
                }
            }
            assert_eq!(total, union.len(), "{s:?}: face sets overlap");
            assert_eq!(union, boundary, "{s:?}");
            let mut used = vec![false; m.n_nodes()];
            m.connectivity.iter().for_each(|&n| used[n] = true);
            assert!(used.iter().all(|&u| u), "{s:?}: orphan nodes");
            let half = s.side.map(|l| 0.5 * l);
            for &n in &m.node_sets["side"] {
                let p = m.nodes[n];
                assert!(p[0].abs() == half[0] || p[1].abs() == half[1]);
            }
            for &n in &m.node_sets["top"] {
                assert_eq!(m.nodes[n][2], s.thickness());
            }
        }
    }

    #[test]
    fn every_cell_has_a_positive_jacobian() {
        for s in variants() {
            let m = stack_mesh(&s).unwrap();
            let el = ReferenceElement::new(s.kind);
            let mut coords = vec![[0.0; 3]; s.kind.nodes_per_cell()];
            for c in 0..m.n_cells() {
                m.cell_coords_into(c, &mut coords);
                assert!(el.geometry(&coords).is_ok(), "{s:?}: cell {c}");
            }
        }
    }

    #[test]
    fn zero_border_and_rejected_specs() {
        let s = StackSpec {
            border: 0.0,
            ..StackSpec::example(ElementKind::Hex8)
        };
        let m = stack_mesh(&s).unwrap();
        assert!(m.cell_sets["border"].is_empty());
        assert_eq!(s.layout().unwrap().border_cells, [0, 0]);
        assert_eq!(m.node_sets["electrode_4"], m.node_sets["top"]);
        let good = StackSpec::example(ElementKind::Hex8);
        let bad = [
            StackSpec { films: 0, ..good },
            StackSpec {
                layers_per_film: 0,
                ..good
            },
            StackSpec {
                active_cells: 0,
                ..good
            },
            StackSpec {
                grading: 0.5,
                ..good
            },
            StackSpec {
                border: 2e-3,
                ..good
            },
            StackSpec {
                border: -1e-4,
                ..good
            },
            StackSpec {
                film_thickness: 0.0,
                ..good
            },
            StackSpec {
                side: [f64::NAN, 1e-3],
                ..good
            },
        ];
        for s in bad {
            assert!(stack_mesh(&s).is_err(), "{s:?}");
        }
    }
}
