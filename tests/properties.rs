//! Property tests (proptest): on random box meshes (hex8, tet4, tet10; random dimensions,
//! divisions and node perturbations that keep the cells valid), random material models of the
//! registry with random parameters in physical ranges, and random small states (displacement
//! gradients up to ~0.05, fields up to ~0.3√(μ/ε)):
//! - nothing panics, and the residual and tangent evaluate;
//! - the assembled residual is the derivative of the total energy Π = Σ(mechanical − electric)
//!   (central differences on sampled dofs; tolerance 1e-6 of the largest force: truncation
//!   O(step²) ≈ 1e-10 relative, round-off ε·|Π|/step ≈ 1e-10 relative; measured largest over
//!   the cases below 1e-7, typical 4e-10);
//! - the assembled tangent is the derivative of the residual (all columns; tolerance 1e-6 of the
//!   largest entry as `global_tangent.rs`, with random materials; measured below 1e-7, typical
//!   3e-9).
//!
//! 24 cases per property keep the file at a few seconds.

mod common;

use common::tangent_fd_error;
use deasim::material::registry::{build, MaterialParams, MODELS};
use deasim::material::EPSILON_0;
use deasim::mesh::{generate::box_mesh, ElementKind};
use deasim::problem::dofs::FIELDS;
use deasim::problem::model::Model;
use deasim::problem::statics::{energies, nodal_reactions, StaticProblem};
use proptest::prelude::*;
use proptest::test_runner::Config;

/// A random problem: mesh, material and state.
#[derive(Debug, Clone)]
struct Case {
    kind: ElementKind,
    size: [f64; 3],
    divisions: [usize; 3],
    /// Node perturbation as a fraction of the smallest cell edge.
    perturb: f64,
    model: usize,
    /// Parameters in [0, 1) mapped onto physical ranges per model.
    p: [f64; 6],
    eps_r: f64,
    seed: u64,
}

fn case() -> impl Strategy<Value = Case> {
    (
        0..3usize,
        [0.5e-3..2e-3f64, 0.5e-3..2e-3f64, 0.2e-3..1e-3f64],
        [1..3usize, 1..3usize, 1..3usize],
        0.0..1.0f64,
        0..MODELS.len(),
        prop::array::uniform6(0.0..1.0f64),
        1.0..10.0f64,
        any::<u64>(),
    )
        .prop_map(|(k, size, divisions, perturb, model, p, eps_r, seed)| {
            let kind = [ElementKind::Hex8, ElementKind::Tet4, ElementKind::Tet10][k];
            // tet10 mid-edge nodes are half a cell apart: smaller perturbations keep them valid
            let max = if kind == ElementKind::Tet10 {
                0.05
            } else {
                0.15
            };
            Case {
                kind,
                size,
                divisions,
                perturb: perturb * max,
                model,
                p,
                eps_r,
                seed,
            }
        })
}

/// Log-uniform in [lo, hi] from u ∈ [0, 1).
fn logu(u: f64, lo: f64, hi: f64) -> f64 {
    lo * (hi / lo).powf(u)
}

/// Parameters of `model` in physical ranges: shear moduli 10 kPa – 1 MPa, bulk/shear 10 – 1000,
/// locking parameters away from the small-strain state, permittivity 1 – 10 with electrostriction
/// up to 20 % of ε.
fn params(model: &str, p: &[f64; 6], eps_r: f64) -> MaterialParams {
    let mu = logu(p[0], 1e4, 1e6);
    let kappa = mu * logu(p[1], 10.0, 1e3);
    let eps = eps_r * EPSILON_0;
    let base = MaterialParams {
        permittivity: Some(eps_r),
        c1: Some(0.1 * p[5] * eps),
        c2: Some(0.1 * p[4] * eps),
        ..Default::default()
    };
    match model {
        "neo-hooke" => MaterialParams {
            mu: vec![mu],
            lambda: Some(kappa - 2.0 * mu / 3.0),
            ..base
        },
        "neo-hooke-split" => MaterialParams {
            mu: vec![mu],
            kappa: Some(kappa),
            ..base
        },
        "yeoh" => MaterialParams {
            c10: Some(mu / 2.0),
            c20: Some(mu * 0.01 * (p[2] - 0.5)),
            c30: Some(mu * 1e-3 * p[3]),
            d1: Some(2.0 / kappa),
            ..base
        },
        "mooney-rivlin" => MaterialParams {
            c10: Some(mu / 2.0 * (1.0 - 0.4 * p[2])),
            c01: Some(mu / 2.0 * 0.4 * p[2]),
            d1: Some(2.0 / kappa),
            ..base
        },
        "gent" => MaterialParams {
            mu: vec![mu],
            jm: Some(10.0 + 90.0 * p[2]),
            kappa: Some(kappa),
            ..base
        },
        "ogden" => {
            // μ₀ = ½ Σ μₚαₚ = μ with a second, negative-exponent term of up to 20 %
            let a1 = 1.0 + 3.0 * p[2];
            let a2 = -1.0 - 2.0 * p[3];
            let share = 0.2 * p[4];
            MaterialParams {
                mu: vec![2.0 * mu * (1.0 - share) / a1, 2.0 * mu * share / a2],
                alpha: vec![a1, a2],
                kappa: Some(kappa),
                ..base
            }
        }
        "arruda-boyce" | "arruda-boyce-series" => MaterialParams {
            mu: vec![mu],
            lambda_m: Some(2.0 + 8.0 * p[2]),
            kappa: Some(kappa),
            ..base
        },
        other => panic!("the property test has no parameter ranges for model `{other}`"),
    }
}

/// Builds the model and a random state; panics (failing the property) on any error.
fn setup(c: &Case) -> (Model, Vec<f64>, f64, f64) {
    let mut mesh = box_mesh(c.size, c.divisions, c.kind);
    let h = (0..3)
        .map(|i| c.size[i] / c.divisions[i] as f64)
        .fold(f64::INFINITY, f64::min);
    let mut rng = common::Rng::new(c.seed);
    common::distort(&mut mesh, h, c.perturb, &mut rng);
    let name = MODELS[c.model];
    let (mat, _warnings) =
        build(name, &params(name, &c.p, c.eps_r)).unwrap_or_else(|e| panic!("{name}: {e:?}"));
    let mu = mat.shear_modulus();
    let eps = mat.permittivity();
    let model = Model::new(mesh, mat).expect("model");
    let e_scale = (mu / eps).sqrt();
    let state: Vec<f64> = (0..model.mesh.n_nodes() * FIELDS)
        .map(|i| {
            if i % FIELDS == 3 {
                0.3 * e_scale * h * rng.next()
            } else {
                0.05 * h * rng.next()
            }
        })
        .collect();
    (model, state, h, e_scale)
}

proptest! {
    #![proptest_config(Config { cases: 24, failure_persistence: None, ..Config::default() })]

    /// Residual = ∂Π/∂x on sampled dofs (every field), Π = Σ(mechanical − electric).
    #[test]
    fn residual_is_the_energy_gradient(c in case()) {
        let (model, state, h, e_scale) = setup(&c);
        let r = nodal_reactions(&model, &state).expect("residual");
        let rmax = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let pi = |s: &[f64]| {
            let (m, e) = energies(&model, s).expect("energy");
            m - e
        };
        let n = state.len();
        let mut rng = common::Rng::new(c.seed ^ 0x9e37);
        let mut worst = 0.0f64;
        for k in 0..12 {
            // four dofs of each kind: ux, uy, uz, Φ spread over the mesh
            let node = ((rng.next() + 1.0) * 0.5 * (n / FIELDS) as f64) as usize % (n / FIELDS);
            let d = node * FIELDS + k % FIELDS;
            let step = if d % FIELDS == 3 { 1e-6 * e_scale * h } else { 1e-6 * h };
            let mut s = state.clone();
            s[d] += step;
            let up = pi(&s);
            s[d] -= 2.0 * step;
            let down = pi(&s);
            let fd = (up - down) / (2.0 * step);
            // compare in units of force per unit of the dof: Φ rows scaled by e_scale·h
            let scale = if d % FIELDS == 3 { rmax.max(1e-300) } else { rmax };
            worst = worst.max((fd - r[d]).abs() / scale);
        }
        prop_assert!(worst < 1e-6, "{:?} {}: {worst:e}", c.kind, MODELS[c.model]);
    }

    /// Tangent = ∂(residual)/∂x, every column.
    #[test]
    fn tangent_is_the_residual_derivative(c in case()) {
        let (model, state, h, _) = setup(&c);
        let mut p = StaticProblem::new(&model, Some(state));
        let worst = tangent_fd_error(&mut p, 1e-7 * h);
        prop_assert!(worst < 1e-6, "{:?} {}: {worst:e}", c.kind, MODELS[c.model]);
    }
}
