//! Objectivity of the discrete body: superposing a rigid rotation Q on a deformed state (x → Qx,
//! Φ unchanged) leaves the stored energy unchanged and rotates the nodal forces (f → Qf, so their
//! magnitudes are unchanged); the nodal charges are unchanged. Distorted mesh, random state, coupling
//! terms on. Tolerance 1e-10 relative (round-off of the element sums).

mod common;

use common::{distort, Rng};
use deasim::material::{ElectroNeoHooke, Mat3, EPSILON_0};
use deasim::mesh::{generate::box_mesh, ElementKind};
use deasim::problem::model::Model;
use deasim::problem::statics::StaticProblem;
use std::sync::Arc;

#[test]
fn rotation_leaves_energy_and_force_magnitudes_unchanged() {
    for kind in [ElementKind::Hex8, ElementKind::Tet4] {
        let mut rng = Rng::new(3);
        let h = 1e-3;
        let mut mesh = box_mesh([2.0 * h, h, h], [2, 1, 1], kind);
        distort(&mut mesh, h, 0.15, &mut rng);
        let eps = 4.7 * EPSILON_0;
        let mat = ElectroNeoHooke::new(1e5, 1e6, 4.7).with_coupling(0.2 * eps, 0.1 * eps);
        let model = Model::new(mesh, Arc::new(mat)).unwrap();
        let mut p = StaticProblem::new(&model, None);
        for (i, v) in p.state.iter_mut().enumerate() {
            *v = if i % 4 == 3 {
                2e4 * h * rng.next() * 1e3
            } else {
                0.1 * h * rng.next()
            };
        }
        let e1 = p.energies().unwrap();
        let f1 = p.nodal_reactions().unwrap();
        let q = nalgebra::Rotation3::from_euler_angles(0.7, -1.1, 2.3).into_inner();
        let q: Mat3 = q;
        let original = p.state.clone();
        for (n, x) in model.mesh.nodes.iter().enumerate() {
            let pos = nalgebra::Vector3::new(
                x[0] + original[n * 4],
                x[1] + original[n * 4 + 1],
                x[2] + original[n * 4 + 2],
            );
            let rotated = q * pos;
            for i in 0..3 {
                p.state[n * 4 + i] = rotated[i] - x[i];
            }
        }
        let e2 = p.energies().unwrap();
        let f2 = p.nodal_reactions().unwrap();
        assert!(
            (e1.0 - e2.0).abs() <= 1e-10 * e1.0.abs(),
            "{kind:?} mechanical energy"
        );
        assert!(
            (e1.1 - e2.1).abs() <= 1e-10 * e1.1.abs(),
            "{kind:?} electric energy"
        );
        let fmax = f1.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for n in 0..model.mesh.n_nodes() {
            let a = nalgebra::Vector3::new(f1[n * 4], f1[n * 4 + 1], f1[n * 4 + 2]);
            let b = nalgebra::Vector3::new(f2[n * 4], f2[n * 4 + 1], f2[n * 4 + 2]);
            assert!(
                ((q * a) - b).norm() <= 1e-10 * fmax,
                "{kind:?} node {n} force"
            );
            assert!((a.norm() - b.norm()).abs() <= 1e-10 * fmax);
            assert!(
                (f1[n * 4 + 3] - f2[n * 4 + 3]).abs()
                    <= 1e-10
                        * f1.iter()
                            .skip(3)
                            .step_by(4)
                            .fold(0.0f64, |m, v| m.max(v.abs()))
            );
        }
    }
}
