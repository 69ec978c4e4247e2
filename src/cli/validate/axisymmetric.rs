//! Axisymmetric: the film as a disc with full electrodes, solved with the meridian kernel
//! (`element::AxisymmetricKernel`) on every cell kind against the closed form of the homogeneous
//! film. The disc is solved by a small dense Newton over the assembled kernel (constrained dofs
//! eliminated), independent of the sparse 3-D machinery.

use super::Case;
use crate::element::{AxisymmetricKernel, CellHistory, CellInput, CellKernel};
use crate::fem::axisymmetric::{meridian_geometry, MeridianKind};
use crate::fem::CellGeometry;
use crate::material::{ElectroNeoHooke, Material};
use crate::problem::examples::{film_closed_form, FILM_EPS_R, FILM_LAMBDA, FILM_MU, FILM_SIZE};
use nalgebra::{DMatrix, DVector};

/// A meridian mesh of [r1, r2] × [0, h] with `nr` × `nz` cells of `kind`; interior corner nodes
/// moved by `perturb` (fraction of a cell), mid-side nodes at the midpoints of straight sides,
/// so the isoparametric map is bilinear (quadrilaterals) or affine (triangles).
#[derive(Debug, Clone)]
pub struct MeridianMesh {
    /// (R, Z) of every node.
    pub nodes: Vec<[f64; 2]>,
    /// The nodes of every cell.
    pub cells: Vec<Vec<usize>>,
    /// The geometry of every cell.
    pub geom: Vec<CellGeometry>,
}

/// Builds the [`MeridianMesh`] described above.
pub fn meridian_mesh(
    kind: MeridianKind,
    r1: f64,
    r2: f64,
    h: f64,
    nr: usize,
    nz: usize,
    perturb: f64,
) -> Result<MeridianMesh, String> {
    let quadratic = matches!(
        kind,
        MeridianKind::Quad8 | MeridianKind::Quad9 | MeridianKind::Tri6
    );
    let tri = matches!(kind, MeridianKind::Tri3 | MeridianKind::Tri6);
    let s = if quadratic { 2 } else { 1 };
    let (mr, mz) = (s * nr + 1, s * nz + 1);
    let id = |i: usize, j: usize| j * mr + i;
    let mut x = vec![[0.0; 2]; mr * mz];
    // corners
    for j in (0..mz).step_by(s) {
        for i in (0..mr).step_by(s) {
            let (ci, cj) = (i / s, j / s);
            let mut p = [
                r1 + (r2 - r1) * ci as f64 / nr as f64,
                h * cj as f64 / nz as f64,
            ];
            if ci > 0 && ci < nr && cj > 0 && cj < nz {
                let sgn = if (ci + cj) % 2 == 0 { 1.0 } else { -1.0 };
                p[0] += sgn * perturb * (r2 - r1) / nr as f64;
                p[1] -= 0.7 * sgn * perturb * h / nz as f64;
            }
            x[id(i, j)] = p;
        }
    }
    let mid = |a: [f64; 2], b: [f64; 2]| [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
    if quadratic {
        for j in 0..mz {
            for i in 0..mr {
                match (i % 2, j % 2) {
                    (1, 0) => x[id(i, j)] = mid(x[id(i - 1, j)], x[id(i + 1, j)]),
                    (0, 1) => x[id(i, j)] = mid(x[id(i, j - 1)], x[id(i, j + 1)]),
                    _ => {}
                }
            }
        }
        for j in (1..mz).step_by(2) {
            for i in (1..mr).step_by(2) {
                let (c0, c2) = (x[id(i - 1, j - 1)], x[id(i + 1, j + 1)]);
                let (c1, c3) = (x[id(i + 1, j - 1)], x[id(i - 1, j + 1)]);
                x[id(i, j)] = if tri {
                    mid(c0, c2) // the diagonal's midpoint
                } else {
                    mid(mid(c0, c2), mid(c1, c3))
                };
            }
        }
    }
    let mut cells = Vec::new();
    for cj in 0..nz {
        for ci in 0..nr {
            let (i, j) = (s * ci, s * cj);
            let c = [id(i, j), id(i + s, j), id(i + s, j + s), id(i, j + s)];
            match kind {
                MeridianKind::Quad4 => cells.push(c.to_vec()),
                MeridianKind::Quad8 | MeridianKind::Quad9 => {
                    let mut v = c.to_vec();
                    v.extend([
                        id(i + 1, j),
                        id(i + 2, j + 1),
                        id(i + 1, j + 2),
                        id(i, j + 1),
                    ]);
                    if kind == MeridianKind::Quad9 {
                        v.push(id(i + 1, j + 1));
                    }
                    cells.push(v);
                }
                MeridianKind::Tri3 => {
                    cells.push(vec![c[0], c[1], c[2]]);
                    cells.push(vec![c[0], c[2], c[3]]);
                }
                MeridianKind::Tri6 => {
                    let d = id(i + 1, j + 1);
                    cells.push(vec![c[0], c[1], c[2], id(i + 1, j), id(i + 2, j + 1), d]);
                    cells.push(vec![c[0], c[2], c[3], d, id(i + 1, j + 2), id(i, j + 1)]);
                }
            }
        }
    }
    // keep only the nodes used by cells (the quad8 centres are not)
    let mut used = vec![false; x.len()];
    cells.iter().flatten().for_each(|&a| used[a] = true);
    let mut new_id = vec![usize::MAX; x.len()];
    let mut nodes = Vec::new();
    for (a, p) in x.iter().enumerate() {
        if used[a] {
            new_id[a] = nodes.len();
            nodes.push(*p);
        }
    }
    for c in cells.iter_mut() {
        c.iter_mut().for_each(|a| *a = new_id[*a]);
    }
    let geom = cells
        .iter()
        .map(|c| {
            let xc: Vec<[f64; 2]> = c.iter().map(|&a| nodes[a]).collect();
            meridian_geometry(kind, &xc).map_err(|e| e.to_string())
        })
        .collect::<Result<_, _>>()?;
    Ok(MeridianMesh { nodes, cells, geom })
}

/// Global energy, residual and (dense) tangent of the mesh at nodal values `x` (4 per node).
pub fn try_assemble(
    m: &MeridianMesh,
    mat: &dyn Material,
    x: &[f64],
) -> Option<(f64, DVector<f64>, DMatrix<f64>)> {
    let nd = 4 * m.nodes.len();
    let mut r = DVector::zeros(nd);
    let mut k = DMatrix::zeros(nd, nd);
    let mut energy = 0.0;
    for (c, g) in m.cells.iter().zip(&m.geom) {
        let nl = 4 * c.len();
        let local: Vec<f64> = c
            .iter()
            .flat_map(|&a| x[4 * a..4 * a + 4].to_vec())
            .collect();
        let mut rl = vec![0.0; nl];
        let mut kl = vec![0.0; nl * nl];
        let input = CellInput {
            geom: g,
            mat,
            hist: CellHistory::NONE,
            local: &local,
        };
        energy += AxisymmetricKernel
            .residual_tangent(&input, &mut rl, Some(&mut kl))
            .ok()?;
        for (la, &a) in c.iter().enumerate() {
            for i in 0..4 {
                r[4 * a + i] += rl[4 * la + i];
                for (lb, &b) in c.iter().enumerate() {
                    for kk in 0..4 {
                        k[(4 * a + i, 4 * b + kk)] += kl[(4 * la + i) * nl + 4 * lb + kk];
                    }
                }
            }
        }
    }
    Some((energy, r, k))
}

/// Dense Newton with the dofs `fixed` held at the values in `x`; false if it does not converge
/// in 40 iterations or a point is inadmissible. Scaled as the solver does (Φ by √(μ/ε)).
pub fn dense_newton(m: &MeridianMesh, mat: &dyn Material, x: &mut [f64], fixed: &[bool]) -> bool {
    let free: Vec<usize> = (0..x.len()).filter(|&i| !fixed[i]).collect();
    let nf = free.len();
    let mut first = None;
    for _ in 0..40 {
        let Some((_, r, k)) = try_assemble(m, mat, x) else {
            return false;
        };
        let rf = DVector::from_iterator(nf, free.iter().map(|&i| r[i]));
        let norm = rf.norm();
        if !norm.is_finite() {
            return false;
        }
        let r0 = *first.get_or_insert(norm.max(1e-30));
        let kf = DMatrix::from_fn(nf, nf, |a, b| k[(free[a], free[b])]);
        let Some(dx) = kf.lu().solve(&rf) else {
            return false;
        };
        for (a, &i) in free.iter().enumerate() {
            x[i] -= dx[a];
        }
        // update relative to the scales 1 mm and 1 kV
        let du = free
            .iter()
            .zip(dx.iter())
            .map(|(&i, d)| d.abs() / if i % 4 == 3 { 1e3 } else { 1e-3 })
            .fold(0.0f64, f64::max);
        if norm < 1e-13 * r0 || du < 1e-14 {
            return true;
        }
    }
    false
}

/// The film's material.
pub fn film_material() -> ElectroNeoHooke {
    ElectroNeoHooke::new(FILM_MU, FILM_LAMBDA, FILM_EPS_R)
}

/// The disc of radius 10 mm and thickness 1 mm (the 3-D film's thickness) on 3 × 2 slightly
/// distorted cells of `kind`, with full electrodes (Φ fixed on the bottom and the top),
/// u_z = 0 on the bottom, u_r = 0 on the axis (R = 0), radially free: the mesh and the fixed
/// dofs (4 per node; slot 2 is unused and fixed).
pub fn film_disc(kind: MeridianKind) -> Result<(MeridianMesh, Vec<bool>), String> {
    let h = FILM_SIZE[2];
    let m = meridian_mesh(kind, 0.0, 10e-3, h, 3, 2, 0.1)?;
    let mut fixed = vec![false; 4 * m.nodes.len()];
    for (a, p) in m.nodes.iter().enumerate() {
        fixed[4 * a + 2] = true;
        if p[0] == 0.0 {
            fixed[4 * a] = true;
        }
        if p[1] == 0.0 {
            fixed[4 * a + 1] = true;
        }
        if p[1] == 0.0 || p[1] == h {
            fixed[4 * a + 3] = true;
        }
    }
    Ok((m, fixed))
}

/// Sets the potential of the disc's top face to `v`.
pub fn set_voltage(m: &MeridianMesh, x: &mut [f64], v: f64) {
    for (a, p) in m.nodes.iter().enumerate() {
        if p[1] == FILM_SIZE[2] {
            x[4 * a + 3] = v;
        }
    }
}

/// One row per cell kind: 15 steps to 30 kV; expected the closed-form in-plane stretch at 30 kV,
/// computed that of the rim, error the largest deviation of the stretches 1 + u_r/R and
/// 1 + u_z/Z at every node and step from the closed form's λ and t (Newton to 1e-13 of the first
/// residual: 1e-10).
pub fn cases() -> Result<Vec<Case>, String> {
    let mat = film_material();
    let reference = film_closed_form();
    let h = FILM_SIZE[2];
    let v_end = 30e3;
    let mut out = Vec::new();
    for kind in MeridianKind::ALL {
        let (m, fixed) = film_disc(kind)?;
        let mut x = vec![0.0; 4 * m.nodes.len()];
        let (mut worst, mut rim): (f64, f64) = (0.0, f64::NAN);
        for step in 1..=15 {
            let v = v_end * step as f64 / 15.0;
            set_voltage(&m, &mut x, v);
            if !dense_newton(&m, &mat, &mut x, &fixed) {
                return Err(format!("{kind:?} disc: no convergence at {v} V"));
            }
            let s = reference.state(v / h).ok_or("closed form beyond pull-in")?;
            for (a, p) in m.nodes.iter().enumerate() {
                if p[0] > 0.0 {
                    let l = 1.0 + x[4 * a] / p[0];
                    worst = worst.max((l - s.lambda).abs());
                    if p[0] == 10e-3 && p[1] == h {
                        rim = l;
                    }
                }
                if p[1] > 0.0 {
                    worst = worst.max((1.0 + x[4 * a + 1] / p[1] - s.t).abs());
                }
            }
        }
        let s = reference
            .state(v_end / h)
            .ok_or("closed form beyond pull-in")?;
        out.push(
            Case::new(
                format!("{kind:?} disc, 15 steps to 30 kV: stretches"),
                "closed form, docs/theory.md".into(),
                s.lambda,
                rim,
                1e-10,
            )
            .with_deviation(worst),
        );
    }
    Ok(out)
}
