//! Faces of the cells as surfaces: shape functions and quadrature of 3-, 4- and 6-node faces (in
//! the node order of [`crate::mesh::ElementKind::faces`]) and the vector algebra on them, shared
//! by the dead surface loads and the follower pressure; and the sides of meridian cells (2 or 3
//! nodes), each sweeping a ring surface.

/// Shape functions and their (ξ, η) derivatives of a face with `n` nodes (3, 4 or 6) at a point.
pub fn shape(n: usize, xi: f64, eta: f64) -> ([f64; 6], [[f64; 2]; 6]) {
    let mut s = [0.0; 6];
    let mut d = [[0.0; 2]; 6];
    match n {
        4 => {
            const C: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
            for a in 0..4 {
                s[a] = 0.25 * (1.0 + C[a][0] * xi) * (1.0 + C[a][1] * eta);
                d[a] = [
                    0.25 * C[a][0] * (1.0 + C[a][1] * eta),
                    0.25 * (1.0 + C[a][0] * xi) * C[a][1],
                ];
            }
        }
        3 | 6 => {
            let l = [1.0 - xi - eta, xi, eta];
            let dl = [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]];
            if n == 3 {
                s[..3].copy_from_slice(&l);
                d[..3].copy_from_slice(&dl);
            } else {
                for i in 0..3 {
                    s[i] = l[i] * (2.0 * l[i] - 1.0);
                    d[i] = dl[i].map(|v| (4.0 * l[i] - 1.0) * v);
                    let j = (i + 1) % 3;
                    s[3 + i] = 4.0 * l[i] * l[j];
                    for c in 0..2 {
                        d[3 + i][c] = 4.0 * (dl[i][c] * l[j] + l[i] * dl[j][c]);
                    }
                }
            }
        }
        k => unreachable!("faces have 3, 4 or 6 nodes, not {k}"),
    }
    (s, d)
}

/// Quadrature points (ξ, η, weight) of a face with `n` nodes, exact for the volume integrand.
pub fn points(n: usize) -> Vec<(f64, f64, f64)> {
    match n {
        4 => {
            let g = 1.0 / 3f64.sqrt();
            vec![(-g, -g, 1.0), (g, -g, 1.0), (g, g, 1.0), (-g, g, 1.0)]
        }
        3 => vec![
            (1.0 / 6.0, 1.0 / 6.0, 1.0 / 6.0),
            (2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0),
            (1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0),
        ],
        _ => {
            // Dunavant's degree-4 rule; weights sum to 1, times the reference area ½
            const ORBITS: [(f64, f64); 2] = [
                (0.223_381_589_678_011, 0.445_948_490_915_965),
                (0.109_951_743_655_322, 0.091_576_213_509_771),
            ];
            let mut p = Vec::new();
            for (w, a) in ORBITS {
                let b = 1.0 - 2.0 * a;
                for (x, y) in [(a, a), (b, a), (a, b)] {
                    p.push((x, y, 0.5 * w));
                }
            }
            p
        }
    }
}

pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// |a|.
pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// ∫ N_a dA (m²) of each node of a face with node positions `p` (3, 4 or 6 nodes); their sum is
/// the face's area. Exact on flat faces (and straight-sided 6-node ones).
pub fn node_areas(p: &[[f64; 3]]) -> [f64; 6] {
    let n = p.len();
    let mut out = [0.0; 6];
    for (xi, eta, w) in points(n) {
        let (s, d) = shape(n, xi, eta);
        let (mut t1, mut t2) = ([0.0; 3], [0.0; 3]);
        for (a, x) in p.iter().enumerate() {
            for i in 0..3 {
                t1[i] += d[a][0] * x[i];
                t2[i] += d[a][1] * x[i];
            }
        }
        let da = w * norm(cross(t1, t2));
        for a in 0..n {
            out[a] += s[a] * da;
        }
    }
    out
}

/// Shape functions and their derivative of a meridian side with `n` nodes (2: the corners;
/// 3: the corners and the mid-side node) at ξ ∈ [−1, 1].
pub fn side_shape(n: usize, xi: f64) -> ([f64; 3], [f64; 3]) {
    if n == 2 {
        ([0.5 * (1.0 - xi), 0.5 * (1.0 + xi), 0.0], [-0.5, 0.5, 0.0])
    } else {
        (
            [0.5 * xi * (xi - 1.0), 0.5 * xi * (xi + 1.0), 1.0 - xi * xi],
            [xi - 0.5, xi + 0.5, -2.0 * xi],
        )
    }
}

/// Gauss points (ξ, weight) on [−1, 1] for the sides of meridian cells: 2 points for 2-node
/// sides, 4 for 3-node ones (exact for the polynomial integrands of the ring area and of the
/// volume of revolution).
pub fn side_points(n: usize) -> Vec<(f64, f64)> {
    if n == 2 {
        let g = 1.0 / 3f64.sqrt();
        vec![(-g, 1.0), (g, 1.0)]
    } else {
        let a = (3.0 / 7.0 - 2.0 / 7.0 * (6.0f64 / 5.0).sqrt()).sqrt();
        let b = (3.0 / 7.0 + 2.0 / 7.0 * (6.0f64 / 5.0).sqrt()).sqrt();
        let wa = (18.0 + 30f64.sqrt()) / 36.0;
        let wb = (18.0 - 30f64.sqrt()) / 36.0;
        vec![(-b, wb), (-a, wa), (a, wa), (b, wb)]
    }
}

/// ∫ N_a dA (m²) of each node of a meridian side with node positions `p` = (R, Z, ·): the
/// area of the ring surface it sweeps, dA = 2πR ds. Exact on straight sides.
pub fn ring_node_areas(p: &[[f64; 3]]) -> [f64; 6] {
    let n = p.len();
    let mut out = [0.0; 6];
    for (xi, w) in side_points(n) {
        let (s, d) = side_shape(n, xi);
        let (mut r, mut t) = (0.0, [0.0; 2]);
        for (a, x) in p.iter().enumerate() {
            r += s[a] * x[0];
            t[0] += d[a] * x[0];
            t[1] += d[a] * x[1];
        }
        let da = w * 2.0 * std::f64::consts::PI * r * (t[0] * t[0] + t[1] * t[1]).sqrt();
        for a in 0..n {
            out[a] += s[a] * da;
        }
    }
    out
}
