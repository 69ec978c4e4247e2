//! The residual of a 3-D mean-dilatation cell evaluated on lanes of quadrature points: the
//! kinematics, the material's stresses ([`Material::stress_known_lanes`]) and the nodal
//! forces of [`LANES`] points at once, compiled for AVX2 where the processor has it.
//!
//! Every lane runs the scalar kernel's operations in its order (the sums over points are
//! added point by point, in the scalar order), so the residual is the same bits as that of
//! [`super::mean_dilatation`]'s scalar path, whatever the processor and the number of threads.
//! A material without a lane form is evaluated point by point from the lanes' kinematics.

use crate::algebra::lanes::{with_wide_vectors, Wide, F4, LANES};
use crate::element::md_point::{cbrt_near_one, cofactor, viscous_stress};
use crate::element::{CellHistory, KelvinVoigtKernel, PointFailure};
use crate::fem::{CellGeometry, FIELDS, MAX_NODES, MAX_QP};
use crate::material::{Known, KnownDeformation, Material, MaterialError, Stress};
use nalgebra::{Matrix3, Vector3};

/// Batches of [`LANES`] points a cell can have.
const BATCHES: usize = MAX_QP.div_ceil(LANES);

/// The quadrature points of a cell in batches of [`LANES`], a partial batch filled with its
/// last point.
struct Batches<'a> {
    geom: &'a CellGeometry,
    /// Batches.
    nb: usize,
}

impl<'a> Batches<'a> {
    #[inline(always)]
    fn new(geom: &'a CellGeometry) -> Self {
        Batches {
            geom,
            nb: geom.n_qp.div_ceil(LANES),
        }
    }

    /// The point of lane `l` of batch `b`.
    #[inline(always)]
    fn qp(&self, b: usize, l: usize) -> usize {
        (b * LANES + l).min(self.geom.n_qp - 1)
    }

    /// The points batch `b` holds (its first lanes).
    #[inline(always)]
    fn valid(&self, b: usize) -> usize {
        (self.geom.n_qp - b * LANES).min(LANES)
    }

    /// ∂N_a/∂X_k at the points of batch `b`.
    #[inline(always)]
    fn grad(&self, b: usize, a: usize, k: usize) -> F4 {
        F4::from_fn(|l| self.geom.grad[self.qp(b, l)][a][k])
    }

    /// F = I + Σ u_a ⊗ ∇N_a and E₀ = −Σ Φ_a ∇N_a at the points of batch `b`, in the order of
    /// [`crate::fem::kinematics`].
    #[inline(always)]
    fn kinematics(&self, b: usize, local: &[f64]) -> (Matrix3<F4>, Vector3<F4>) {
        let one = F4::splat(1.0);
        let mut fb = [[F4::splat(0.0); 3]; 3];
        for (i, row) in fb.iter_mut().enumerate() {
            row[i] = one;
        }
        let mut eb = [F4::splat(0.0); 3];
        for a in 0..self.geom.n_nodes {
            let g = [self.grad(b, a, 0), self.grad(b, a, 1), self.grad(b, a, 2)];
            let pa = F4::splat(local[a * FIELDS + 3]);
            for i in 0..3 {
                let ua = F4::splat(local[a * FIELDS + i]);
                for jj in 0..3 {
                    fb[i][jj] += ua * g[jj];
                }
                eb[i] -= pa * g[i];
            }
        }
        (
            Matrix3::from_fn(|i, jj| fb[i][jj]),
            Vector3::new(eb[0], eb[1], eb[2]),
        )
    }

    /// The nodal forces Σ f_r w (P ∇N_a, D₀·∇N_a) of the points' stresses into `r`: a node's
    /// four values (ux, uy, uz, Φ) as one lane value, its points' terms added point by point
    /// in the scalar order.
    #[inline(always)]
    fn forces(
        &self,
        p: &[Matrix3<F4>; BATCHES],
        d0: &[Vector3<F4>; BATCHES],
        f_r: f64,
        r: &mut [f64],
    ) {
        let n = self.geom.n_nodes;
        let mut forces = [F4::splat(0.0); MAX_NODES];
        for b in 0..self.nb {
            let w = F4::from_fn(|l| f_r * self.geom.weights[self.qp(b, l)]);
            let (pb, db) = (&p[b], &d0[b]);
            for (a, ra) in forces.iter_mut().enumerate().take(n) {
                let g = [self.grad(b, a, 0), self.grad(b, a, 1), self.grad(b, a, 2)];
                let t = transpose([
                    w * (pb[(0, 0)] * g[0] + pb[(0, 1)] * g[1] + pb[(0, 2)] * g[2]),
                    w * (pb[(1, 0)] * g[0] + pb[(1, 1)] * g[1] + pb[(1, 2)] * g[2]),
                    w * (pb[(2, 0)] * g[0] + pb[(2, 1)] * g[1] + pb[(2, 2)] * g[2]),
                    w * (db[0] * g[0] + db[1] * g[1] + db[2] * g[2]),
                ]);
                for tl in &t[..self.valid(b)] {
                    *ra += *tl;
                }
            }
        }
        for (ra, fa) in r.chunks_exact_mut(FIELDS).zip(&forces[..n]) {
            ra.copy_from_slice(&fa.0);
        }
    }
}

/// What the lane residual needs besides the cell's geometry and values.
pub(crate) struct LaneResidual<'a> {
    pub geom: &'a CellGeometry,
    pub mat: &'a dyn Material,
    pub hist: CellHistory<'a>,
    /// The cell's local values (node-major ux, uy, uz, Φ).
    pub local: &'a [f64],
    /// The Kelvin–Voigt kernel and the nodal velocities, for a dynamic residual.
    pub viscous: Option<(KelvinVoigtKernel, &'a [f64])>,
    /// The factor of the nodal forces (1 for a static residual).
    pub f_r: f64,
    pub r: &'a mut [f64],
}

/// The outcome of [`LaneResidual`]: `None` when a point's J (or the cell's θ̄) is not positive
/// and finite, for the scalar path to report; else the cell's energy and viscous power, or a
/// material's failure at a point.
type Outcome = Option<Result<(f64, f64), PointFailure>>;

impl LaneResidual<'_> {
    /// The residual into `r` (zeroed first); see [`Outcome`].
    pub fn evaluate(self) -> Outcome {
        with_wide_vectors(self)
    }
}

impl Wide for LaneResidual<'_> {
    type Output = Outcome;

    #[inline(always)]
    fn run(self) -> Outcome {
        let LaneResidual {
            geom,
            mat,
            hist,
            local,
            viscous,
            f_r,
            r,
        } = self;
        let cell = Batches::new(geom);
        let (n, nb) = (geom.n_nodes, cell.nb);
        let valid = |b: usize| cell.valid(b);
        let grad = |b: usize, a: usize, k: usize| cell.grad(b, a, k);

        // kinematics: F = I + Σ u_a ⊗ ∇N_a, E₀ = −Σ Φ_a ∇N_a, J and F⁻ᵀ from the cofactors
        let one = F4::splat(1.0);
        let mut f = [Matrix3::<F4>::identity(); BATCHES];
        let mut e0 = [Vector3::<F4>::zeros(); BATCHES];
        let mut j = [one; BATCHES];
        let mut finv_t = [Matrix3::<F4>::identity(); BATCHES];
        let (mut v, mut volume) = (0.0, 0.0);
        for b in 0..nb {
            (f[b], e0[b]) = cell.kinematics(b, local);
            let cof = cofactor(&f[b]);
            let fb = &f[b];
            j[b] = fb[(0, 0)] * cof[(0, 0)] + fb[(0, 1)] * cof[(0, 1)] + fb[(0, 2)] * cof[(0, 2)];
            if !j[b].0[..valid(b)].iter().all(|&x| x > 0.0 && x.is_finite()) {
                return None;
            }
            finv_t[b] = cof * (one / j[b]);
            for l in 0..valid(b) {
                let w = geom.weights[b * LANES + l];
                v += w * j[b].0[l];
                volume += w;
            }
        }
        let theta = v / volume;
        if !(theta > 0.0 && theta.is_finite()) {
            return None;
        }
        let r3 = theta.cbrt();
        let theta_m23 = 1.0 / (r3 * r3);

        // the stresses P̄, D₀ at F̄ = (θ̄/J)^{1/3} F, and s = P̄ : F̄
        let mut alpha = [one; BATCHES];
        let mut p = [Matrix3::<F4>::zeros(); BATCHES];
        let mut d0 = [Vector3::<F4>::zeros(); BATCHES];
        let mut s = [F4::splat(0.0); BATCHES];
        let mut energy = 0.0;
        for b in 0..nb {
            alpha[b] = (F4::splat(theta) / j[b]).map(cbrt_near_one);
            let known = Known {
                f: f[b] * alpha[b],
                f_inv_t: finv_t[b] * (one / alpha[b]),
                j: F4::splat(theta),
                jm23: F4::splat(theta_m23),
            };
            let lanes = if hist.size == 0 {
                mat.stress_known_lanes(&known, &e0[b], hist.at(b * LANES))
            } else {
                None
            };
            let (en, pb, db) = match lanes {
                Some(st) => (st.energy, st.p, st.d0),
                None => {
                    let points = point_by_point(b, valid(b), |l, q| {
                        let kd = KnownDeformation {
                            f: lane(&known.f, l),
                            f_inv_t: lane(&known.f_inv_t, l),
                            j: known.j.0[l],
                            jm23: known.jm23.0[l],
                        };
                        mat.stress_known(&kd, &lane_vec(&e0[b], l), hist.at(q))
                    });
                    match points {
                        Ok(st) => st,
                        Err(e) => return Some(Err(e)),
                    }
                }
            };
            for l in 0..valid(b) {
                energy += geom.weights[b * LANES + l] * en.0[l];
            }
            s[b] = pb.dot(&known.f);
            p[b] = pb;
            d0[b] = db;
        }

        // the effective stresses αP̄ − (s/3)F⁻ᵀ + p̄ cof F, p̄ = Σ w s / (3θ̄V)
        let mut h = 0.0;
        for (b, sb) in s.iter().enumerate().take(nb) {
            for l in 0..valid(b) {
                h += geom.weights[b * LANES + l] * sb.0[l] / (3.0 * theta);
            }
        }
        let pm = F4::splat(h / volume);
        for b in 0..nb {
            p[b] = p[b] * alpha[b] + finv_t[b] * (pm * j[b] - s[b] / F4::splat(3.0));
        }

        // the Kelvin–Voigt stresses of the compatible F
        let mut power = 0.0;
        if let Some((kv, vel)) = viscous {
            for b in 0..nb {
                let mut fd = [[F4::splat(0.0); 3]; 3];
                for a in 0..n {
                    let g = [grad(b, a, 0), grad(b, a, 1), grad(b, a, 2)];
                    for (i, row) in fd.iter_mut().enumerate() {
                        let va = F4::splat(vel[a * FIELDS + i]);
                        for (m, x) in row.iter_mut().enumerate() {
                            *x += va * g[m];
                        }
                    }
                }
                let (pv, dd) = viscous_stress(&fd, &finv_t[b], j[b] * F4::splat(kv.eta));
                for l in 0..valid(b) {
                    power += geom.weights[b * LANES + l] * dd.0[l];
                }
                p[b] += pv;
            }
        }

        cell.forces(&p, &d0, f_r, r);
        Some(Ok((energy, power)))
    }
}

/// Rows of lanes to lanes of rows: entry l of the result holds lane l of every row.
#[inline(always)]
fn transpose(rows: [F4; LANES]) -> [F4; LANES] {
    std::array::from_fn(|l| F4::from_fn(|i| rows[i].0[l]))
}

/// The stresses of the first `valid` points of batch `b` one by one, `eval(l, q)` that of lane
/// l (point q), as lanes: a material without a lane form, or one with internal variables.
#[inline(never)]
fn point_by_point(
    b: usize,
    valid: usize,
    eval: impl Fn(usize, usize) -> Result<Stress, MaterialError>,
) -> Result<(F4, Matrix3<F4>, Vector3<F4>), PointFailure> {
    let mut out: [Stress; LANES] = Default::default();
    for (l, st) in out.iter_mut().enumerate().take(valid) {
        let q = b * LANES + l;
        *st = eval(l, q).map_err(|error| PointFailure { qp: q, error })?;
    }
    Ok((
        F4::from_fn(|l| out[l].energy),
        Matrix3::from_fn(|i, k| F4::from_fn(|l| out[l].p[(i, k)])),
        Vector3::from_fn(|i, _| F4::from_fn(|l| out[l].d0[i])),
    ))
}

/// Lane `l` of a matrix of lanes.
#[inline(always)]
fn lane(m: &Matrix3<F4>, l: usize) -> Matrix3<f64> {
    m.map(|x| x.0[l])
}

/// Lane `l` of a vector of lanes.
#[inline(always)]
fn lane_vec(v: &Vector3<F4>, l: usize) -> Vector3<f64> {
    v.map(|x| x.0[l])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::mean_dilatation::cell_residual_tangent_md;
    use crate::element::mean_dilatation::{cell_dynamic_residual_md, dynamic_residual_points};
    use crate::fem::ReferenceElement;
    use crate::material::registry::{
        build, parameter_names, preset, MaterialParams, MODELS, PRESETS,
    };
    use crate::mesh::{ElementKind, TET10_EDGES};
    use std::sync::Arc;

    /// Every model of the registry (with the electrostrictive terms) and every preset (the
    /// viscoelastic ones with their branches).
    fn every_material() -> Vec<(String, Arc<dyn Material>)> {
        let mut out = Vec::new();
        for model in MODELS {
            let names = parameter_names(model).expect("a model's names");
            let has = |k: &str| names.contains(&k);
            let some = |k: &str, v: f64| has(k).then_some(v);
            let p = MaterialParams {
                mu: match *model {
                    "ogden" => vec![6e4, 1e3],
                    "yeoh" | "mooney-rivlin" => Vec::new(),
                    _ => vec![1e5],
                },
                alpha: if has("alpha") {
                    vec![1.5, 5.0]
                } else {
                    Vec::new()
                },
                lambda: some("lambda", 4e5),
                kappa: some("kappa", 5e7),
                c10: some("c10", 5e4),
                c20: some("c20", -400.0),
                c30: some("c30", 20.0),
                c01: some("c01", 1e4),
                d1: some("d1", 4e-8),
                d2: some("d2", 1e-9),
                d3: some("d3", 0.0),
                jm: some("jm", 60.0),
                lambda_m: some("lambda_m", 4.0),
                permittivity: Some(4.7),
                c1: Some(1e-12),
                c2: Some(-2e-12),
                ..Default::default()
            };
            let (m, _) = build(model, &p).unwrap_or_else(|e| panic!("{model}: {e:?}"));
            out.push((model.to_string(), m));
        }
        for name in PRESETS {
            let (model, p) = preset(name).expect("a preset");
            let (m, _) = build(model, &p).expect("the preset builds");
            out.push((name.to_string(), m));
        }
        out
    }

    /// A distorted cell of each 3-D kind (8, 1 and 4 quadrature points: full batches and
    /// partial ones) about 1 mm in size.
    fn cells() -> Vec<(ElementKind, CellGeometry, Vec<[f64; 3]>)> {
        let corners = [
            [0.0, 0.0, 0.0],
            [1.1, 0.1, 0.0],
            [0.2, 0.9, 0.1],
            [0.1, 0.2, 1.2],
        ];
        let mut tet10 = corners.to_vec();
        for [i, j] in TET10_EDGES {
            tet10.push(std::array::from_fn(|k| {
                0.5 * (corners[i][k] + corners[j][k])
            }));
        }
        let mm = |x: &[[f64; 3]]| x.iter().map(|p| p.map(|c| c * 1e-3)).collect::<Vec<_>>();
        [
            (
                ElementKind::Hex8,
                crate::element::mean_dilatation::tests::cell_coords().to_vec(),
            ),
            (ElementKind::Tet4, mm(&corners)),
            (ElementKind::Tet10, mm(&tet10)),
        ]
        .into_iter()
        .map(|(kind, x)| (kind, ReferenceElement::new(kind).geometry(&x).unwrap(), x))
        .collect()
    }

    /// Displacement gradients of order `size`, a field of order 0.3√(μ/ε), and velocities.
    fn values(n: usize, size: f64, seed: f64) -> (Vec<f64>, Vec<f64>) {
        let e_scale = (1e5f64 / (4.7 * crate::material::EPSILON_0)).sqrt();
        let rand = |i: usize| ((i as f64 * 12.9898 + seed).sin() * 43758.5453).fract();
        let local = (0..4 * n)
            .map(|i| {
                if i % 4 == 3 {
                    0.3 * e_scale * 1e-3 * rand(i)
                } else {
                    size * 1e-3 * rand(i)
                }
            })
            .collect();
        let vel = (0..4 * n).map(|i| 1e-2 * rand(i + 100)).collect();
        (local, vel)
    }

    /// The kernel's residual (lanes) and the point-by-point reference, each with its
    /// outcome: the same bits, or the same failure.
    #[test]
    fn lanes_are_the_point_by_point_residual_bit_for_bit() {
        let kv = crate::element::KelvinVoigtKernel { eta: 30.0 };
        let mut compared = 0;
        for (name, mat) in every_material() {
            let mut state = vec![0.0; mat.state_size() * MAX_QP];
            for q in 0..MAX_QP {
                let s = mat.state_size();
                mat.initial_state(&mut state[q * s..(q + 1) * s]);
            }
            let hist = CellHistory {
                state: &state,
                size: mat.state_size(),
                dt: 1e-3,
            };
            for (kind, geom, _) in cells() {
                let n = geom.n_nodes;
                for (size, seed) in [(0.1, 0.0), (0.3, 1.0), (0.01, 2.0)] {
                    let (local, vel) = values(n, size, seed);
                    for viscous in [None, Some((kv, &vel[..]))] {
                        let mut r = vec![0.0; 4 * n];
                        let mut reference = vec![0.0; 4 * n];
                        let f_r = if viscous.is_some() { 0.7 } else { 1.0 };
                        let got = if viscous.is_some() {
                            cell_dynamic_residual_md(
                                &geom, &*mat, hist, &local, viscous, f_r, &mut r,
                            )
                        } else {
                            cell_residual_tangent_md(&geom, &*mat, hist, &local, &mut r, None)
                                .map(|e| (e, 0.0))
                        };
                        let want = dynamic_residual_points(
                            &geom,
                            &*mat,
                            hist,
                            &local,
                            viscous,
                            f_r,
                            &mut reference,
                        );
                        // the lanes as compiled for every x86-64 (no AVX2), run directly
                        let mut baseline = vec![0.0; 4 * n];
                        let narrow = LaneResidual {
                            geom: &geom,
                            mat: &*mat,
                            hist,
                            local: &local,
                            viscous,
                            f_r,
                            r: &mut baseline,
                        }
                        .run();
                        let case = format!("{name}, {kind:?}, size {size}, {viscous:?}");
                        match (got, want) {
                            (Ok(a), Ok(b)) => {
                                assert_eq!(a.0.to_bits(), b.0.to_bits(), "{case}: energy");
                                assert_eq!(a.1.to_bits(), b.1.to_bits(), "{case}: power");
                                for ((x, y), z) in r.iter().zip(&reference).zip(&baseline) {
                                    assert_eq!(x.to_bits(), y.to_bits(), "{case}: residual");
                                    assert_eq!(x.to_bits(), z.to_bits(), "{case}: without AVX2");
                                }
                                let c = narrow.expect("lanes").expect("no failure");
                                assert_eq!(
                                    (c.0.to_bits(), c.1.to_bits()),
                                    (a.0.to_bits(), a.1.to_bits())
                                );
                                compared += 1;
                            }
                            (Err(a), Err(b)) => assert_eq!(a, b, "{case}"),
                            (a, b) => panic!("{case}: {a:?} against {b:?}"),
                        }
                    }
                }
            }
        }
        // every material and kind compared at least at the small deformation
        assert!(
            compared >= (MODELS.len() + PRESETS.len()) * 3 * 2,
            "{compared}"
        );
    }

    /// A cell turned inside out fails at the same point with the same error on both paths,
    /// and a field that is not finite is the material's error at its point.
    #[test]
    fn failures_are_the_point_by_point_ones() {
        let (_, mat) = &every_material()[2];
        for (kind, geom, x) in cells() {
            let n = geom.n_nodes;
            let (local, _) = values(n, 0.1, 0.0);
            let inverted = |local: &[f64]| {
                let mut r = vec![0.0; 4 * n];
                let mut reference = vec![0.0; 4 * n];
                (
                    cell_residual_tangent_md(&geom, &**mat, CellHistory::NONE, local, &mut r, None)
                        .map(|_| ()),
                    dynamic_residual_points(
                        &geom,
                        &**mat,
                        CellHistory::NONE,
                        local,
                        None,
                        1.0,
                        &mut reference,
                    )
                    .map(|_| ()),
                )
            };
            // u_x = −3x: F₁₁ = −2, J < 0 at every point
            let mut flipped = local.clone();
            for (a, xa) in x.iter().enumerate() {
                flipped[4 * a] = -3.0 * xa[0];
            }
            let (a, b) = inverted(&flipped);
            assert!(a.is_err(), "{kind:?}");
            assert_eq!(a, b, "{kind:?}");
            let mut bad = local.clone();
            bad[3] = f64::NAN;
            let (a, b) = inverted(&bad);
            assert!(a.is_err(), "{kind:?}");
            assert_eq!(a, b, "{kind:?}");
        }
    }
}
