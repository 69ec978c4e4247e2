//! The transposed derivative of a kernel's point deformations: given a cotangent (F̄_q, Ē_q) of
//! the deformation gradient and the field E₀ each quadrature point sees
//! ([`CellKernel::point_deformations`]), the nodal cotangent
//!
//! ```text
//! x̄ = Σ_q F̄_q : ∂F_q/∂x + Ē_q · ∂E₀_q/∂x.
//! ```
//!
//! What an adjoint needs where something is computed from the points' deformations after the
//! solve: the update of the Maxwell branches' internal variables. Every kernel's residual is
//! r = Σ_q w_q (P_q : ∂F_q/∂x − D₀_q · ∂E₀_q/∂x) with the stresses its material gives at fixed
//! kinematics (D₀ = −∂Ψ/∂E₀), so the kernel's own residual with a material whose stress at
//! point q is P_q = F̄_q / w_q and D₀_q = −Ē_q / w_q is x̄: exact for every kernel (standard,
//! mean-dilatation, axisymmetric) with no kinematics written twice.

use super::{CellHistory, CellInput, CellKernel, PointFailure};
use crate::fem::MAX_QP;
use crate::material::{Mat3, Material, MaterialError, PointHistory, Stress, Tangent, Vec3};

/// Values per point of [`GivenStress`]'s history: P (9, row-major) and D₀ (3).
const SIZE: usize = 12;

/// A "material" whose stress at a point is read from the point's history: the stresses of the
/// transposed product. It has no energy and no tangent.
#[derive(Debug)]
struct GivenStress;

impl GivenStress {
    fn read(h: &PointHistory) -> Stress {
        let s = h.state;
        Stress {
            energy: 0.0,
            p: Mat3::from_row_slice(&s[..9]),
            d0: Vec3::new(s[9], s[10], s[11]),
        }
    }

    fn no_tangent() -> MaterialError {
        MaterialError::OutOfDomain("a given stress has no tangent".into())
    }
}

impl Material for GivenStress {
    fn energy(&self, _f: &Mat3, _e0: &Vec3) -> Result<f64, MaterialError> {
        Ok(0.0)
    }
    fn stress(&self, _f: &Mat3, _e0: &Vec3) -> Result<Stress, MaterialError> {
        Err(MaterialError::OutOfDomain(
            "a given stress needs its point's values".into(),
        ))
    }
    fn tangent(&self, _f: &Mat3, _e0: &Vec3) -> Result<Tangent, MaterialError> {
        Err(Self::no_tangent())
    }
    fn shear_modulus(&self) -> f64 {
        0.0
    }
    fn bulk_modulus(&self) -> f64 {
        0.0
    }
    fn permittivity(&self) -> f64 {
        0.0
    }
    fn energy_split(&self, _f: &Mat3, _e0: &Vec3) -> Result<(f64, f64), MaterialError> {
        Ok((0.0, 0.0))
    }
    fn state_size(&self) -> usize {
        SIZE
    }
    fn stress_at(&self, _f: &Mat3, _e0: &Vec3, h: PointHistory) -> Result<Stress, MaterialError> {
        Ok(Self::read(&h))
    }
    fn electric_displacement_at(
        &self,
        _f: &Mat3,
        _e0: &Vec3,
        h: PointHistory,
    ) -> Result<Vec3, MaterialError> {
        Ok(Self::read(&h).d0)
    }
    fn tangent_at(
        &self,
        _f: &Mat3,
        _e0: &Vec3,
        _h: PointHistory,
    ) -> Result<Tangent, MaterialError> {
        Err(Self::no_tangent())
    }
}

/// x̄ (4 values per node of the cell, into `out`) of the cotangents `f_bar[q]`, `e0_bar[q]` of
/// the deformation and field of the cell's points, at the cell's configuration `cell.local`.
pub fn deformation_vjp(
    kernel: &dyn CellKernel,
    cell: &CellInput,
    f_bar: &[Mat3],
    e0_bar: &[Vec3],
    out: &mut [f64],
) -> Result<(), PointFailure> {
    let n_qp = cell.geom.n_qp;
    let mut given = [0.0; MAX_QP * SIZE];
    for q in 0..n_qp {
        let w = cell.geom.weights[q];
        let s = &mut given[q * SIZE..(q + 1) * SIZE];
        for r in 0..3 {
            for c in 0..3 {
                s[r * 3 + c] = f_bar[q][(r, c)] / w;
            }
            s[9 + r] = -e0_bar[q][r] / w;
        }
    }
    out.fill(0.0);
    kernel.residual_tangent(
        &CellInput {
            geom: cell.geom,
            mat: &GivenStress,
            hist: CellHistory {
                state: &given[..n_qp * SIZE],
                size: SIZE,
                dt: 0.0,
            },
            local: cell.local,
        },
        out,
        None,
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::ElectroNeoHooke;
    use crate::mesh::meridian::rectangle_mesh;
    use crate::mesh::{ElementKind, MeridianKind};
    use crate::problem::model::Model;
    use std::sync::Arc;

    /// x̄ against central differences of Σ_q F̄_q : F_q + Ē_q · E₀_q, with random cotangents,
    /// on the first cell of a model.
    fn check(model: &Model) {
        let state = crate::problem::examples::wavy_state(model, 3e-2, 2e-6, 800.0);
        let c = 0;
        let nodes = model.mesh.cell(c);
        let nl = nodes.len() * crate::fem::FIELDS;
        let mut local = vec![0.0; nl];
        for (a, &n) in nodes.iter().enumerate() {
            local[a * 4..a * 4 + 4].copy_from_slice(&state[n * 4..n * 4 + 4]);
        }
        let g = model.geometry(c);
        let mat = model.materials[0].as_ref();
        let kernel = model.kernel();
        let mut seed = 7u64;
        let mut rand = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let f_bar: Vec<Mat3> = (0..g.n_qp).map(|_| Mat3::from_fn(|_, _| rand())).collect();
        let e_bar: Vec<Vec3> = (0..g.n_qp)
            .map(|_| Vec3::new(rand(), rand(), rand()) * 1e-3)
            .collect();
        let product = |x: &[f64]| {
            let mut at = [(Mat3::identity(), Vec3::zeros()); MAX_QP];
            kernel
                .point_deformations(
                    &CellInput {
                        geom: &g,
                        mat,
                        hist: CellHistory::NONE,
                        local: x,
                    },
                    &mut at,
                )
                .unwrap();
            (0..g.n_qp)
                .map(|q| at[q].0.dot(&f_bar[q]) + at[q].1.dot(&e_bar[q]))
                .sum::<f64>()
        };
        let mut out = vec![0.0; nl];
        deformation_vjp(
            kernel,
            &CellInput {
                geom: &g,
                mat,
                hist: CellHistory::NONE,
                local: &local,
            },
            &f_bar,
            &e_bar,
            &mut out,
        )
        .unwrap();
        let scale = out.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(scale > 0.0);
        for j in 0..nl {
            let h = if j % 4 == 3 { 1e-2 } else { 1e-9 };
            let (mut p, mut m) = (local.clone(), local.clone());
            p[j] += h;
            m[j] -= h;
            let fd = (product(&p) - product(&m)) / (2.0 * h);
            // the potential's entries have their own scale (1/m against 1/V)
            let tol = if j % 4 == 3 {
                1e-7 * fd.abs().max(1e-6)
            } else {
                1e-6 * scale
            };
            assert!(
                (out[j] - fd).abs() <= tol,
                "{:?}, dof {j}: {} against {fd}",
                model.mesh.kind,
                out[j]
            );
        }
    }

    #[test]
    fn the_transposed_deformation_of_every_kernel_matches_differences() {
        for kind in [ElementKind::Hex8, ElementKind::Tet10] {
            let model = crate::problem::examples::film([2, 2, 1], kind, 1000.0).unwrap();
            check(&model);
        }
        let mut md = crate::problem::examples::film([2, 2, 1], ElementKind::Hex8, 1000.0).unwrap();
        md.formulation = crate::element::Formulation::MeanDilatation;
        check(&md);
        for kind in [MeridianKind::Quad4, MeridianKind::Quad8] {
            let mesh = rectangle_mesh(0.0, 2e-3, 1e-3, 3, 2, kind).unwrap();
            let material = Arc::new(ElectroNeoHooke::new(1e5, 1e7, 4.7));
            let mut model = Model::new(mesh, material).unwrap();
            check(&model);
            model.formulation = crate::element::Formulation::MeanDilatation;
            check(&model);
        }
    }
}
