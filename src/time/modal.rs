//! Small vibrations about a converged state: the natural frequencies and mode shapes of the
//! coupled problem with the electrodes held at their voltages.
//!
//! Linearising the dynamic equations about an equilibrium (u₀, Φ₀) gives
//! M ü + K_uu u + K_uΦ Φ = 0 and K_Φu u + K_ΦΦ Φ = 0 (Gauss's law has no inertia), so the potential
//! is condensed: the displacement vibrates with the Schur complement S = K_uu − K_uΦ K_ΦΦ⁻¹ K_Φu of
//! the coupled tangent, S φ = ω² M φ. The electric stiffness is in S: a voltage lowers the
//! frequencies of a pre-stretched membrane. Rigid regions and supports act through the dof map
//! (ties share one equation, supports have none).
//!
//! **Method**: shift-invert Lanczos in the M inner product (Ericsson & Ruhe, Math. Comp. 35 (1980);
//! Grimes, Lewis & Simon, SIAM J. Matrix Anal. Appl. 15 (1994)). The coupled matrix K − σM (mass
//! on the displacement rows only) is factored once by the symmetric indefinite LDLᵀ the solver
//! uses; one solve (K − σM) y = M x gives in its displacement part (S − σM)⁻¹ M x with the
//! potential condensed exactly, whose largest eigenvalues θ belong to the frequencies nearest to
//! the shift: ω² = σ + 1/θ. The Lanczos vectors are fully re-orthogonalised (the spaces are small),
//! and a Ritz pair is accepted when its residual is below the tolerance; the space grows until the
//! requested modes have converged.

use crate::algebra::csr::CsrMatrix;
use crate::algebra::system::NonlinearSystem;
use crate::problem::dofs::{DofMap, CONSTRAINED, FIELDS, PHI};
use crate::problem::model::Model;
use crate::problem::statics::StaticProblem;
use crate::solve::linear::{LinearSolver, SolverSettings};
use crate::time::mass::NodalMass;

/// One natural mode.
#[derive(Debug, Clone, PartialEq)]
pub struct Mode {
    /// Natural frequency (Hz).
    pub frequency: f64,
    /// ω² (rad²/s²): negative for an unstable state.
    pub eigenvalue: f64,
    /// Shape, `FIELDS` values per node (u in m, Φ in V; the potential is the condensed response),
    /// normalised to unit modal mass φᵀMφ = 1 kg.
    pub shape: Vec<f64>,
    /// Relative residual ‖(S − σM)⁻¹Mφ − θφ‖_M / |θ| of the shift-inverted pair (θ = 1/(ω² − σ)),
    /// computed by one more solve.
    pub residual: f64,
    /// Circumferential harmonic n of an axisymmetric model's mode (0: axisymmetric, and every
    /// mode of a 3-D model); its shape holds the amplitudes of cos nΘ (u_r, u_z, Φ) and sin nΘ
    /// (u_θ, slot 2) ([`crate::time::harmonic`]).
    pub harmonic: u32,
}

/// Settings of [`modes`].
#[derive(Debug, Clone, Copy)]
pub struct ModeSettings {
    /// Number of modes, the ones nearest to the shift.
    pub count: usize,
    /// Shift σ as a frequency (Hz): 0 gives the lowest modes.
    pub shift_hz: f64,
    /// Relative residual at which a Ritz pair is accepted.
    pub tolerance: f64,
    /// Circumferential harmonic n of an axisymmetric model (0: the axisymmetric modes).
    pub harmonic: u32,
}

impl Default for ModeSettings {
    fn default() -> Self {
        ModeSettings {
            count: 6,
            shift_hz: 0.0,
            tolerance: 1e-9,
            harmonic: 0,
        }
    }
}

/// Adds `scale`·M to `a` (a tangent of `problem`'s pattern) on the rows of the process's non-cell
/// terms (every row without a share), so that processes that share the cells add the mass once
/// between them.
pub fn add_mass_on_term_rows(
    problem: &StaticProblem,
    mass: &NodalMass,
    scale: f64,
    a: &mut CsrMatrix,
) {
    let mut terms = problem
        .assembler()
        .global_terms(Some(a))
        .expect("a matrix was given");
    let positions = mass.positions_in(&problem.dofs, |i, j| terms.position(i, j));
    let values = terms.values_mut();
    for (pos, p) in positions {
        values[pos] += scale * mass.values[p];
    }
}

/// M x in the equation space of `dofs` (PᵀMP x, P the map from equations to dofs: tied dofs
/// share an equation), from the nodal mass itself: no matrix is built, so a distributed run,
/// whose processes hold the tangent of their own cells only, multiplies by the whole mass.
/// The same operator as the matrix of [`add_mass_on_term_rows`] on a pattern that holds every
/// mass coupling.
pub struct EquationMass<'a> {
    mass: &'a NodalMass,
    dofs: &'a DofMap,
    x: Vec<f64>,
    y: Vec<f64>,
}

impl<'a> EquationMass<'a> {
    pub fn new(mass: &'a NodalMass, dofs: &'a DofMap) -> Self {
        let n = dofs.eq.len();
        EquationMass {
            mass,
            dofs,
            x: vec![0.0; n],
            y: vec![0.0; n],
        }
    }

    /// y = M x (equation space; the potential rows of y are 0).
    pub fn mul(&mut self, x: &[f64], y: &mut [f64]) {
        let eq = &self.dofs.eq;
        for (d, v) in self.x.iter_mut().enumerate() {
            *v = if d % FIELDS != PHI && eq[d] != CONSTRAINED {
                x[eq[d]]
            } else {
                0.0
            };
        }
        self.mass.mul(&self.x, &mut self.y);
        y.iter_mut().for_each(|v| *v = 0.0);
        for (d, &v) in self.y.iter().enumerate() {
            if d % FIELDS != PHI && eq[d] != CONSTRAINED {
                y[eq[d]] += v;
            }
        }
    }
}

/// The natural modes of `model` (its Dirichlet conditions hold the supports and the electrode
/// voltages) about the equilibrium `state` (`FIELDS` values per node), with the mass `mass`.
///
/// With a distributed solver and a model whose cells are shared between processes, each process
/// assembles the tangent of its own cells only and adds the mass on the rows it takes the
/// non-cell terms of; the solver sums the parts. The Lanczos vectors are whole on every process
/// (the solver returns the whole solution), so every process computes the same modes.
pub fn modes(
    model: &Model,
    state: &[f64],
    mass: &NodalMass,
    solver: &SolverSettings,
    settings: &ModeSettings,
) -> Result<Vec<Mode>, String> {
    let mut problem = StaticProblem::new(model, Some(state.to_vec()));
    problem.set_drive(crate::problem::drive::Drive::held(model));
    let mut lin = solver.build();
    if !lin.sums_shared_entries() {
        // this solver takes the whole tangent
        problem.assemble_every_cell();
    }
    let n = problem.n();
    let mut a = problem.new_matrix();
    let mut r = vec![0.0; n];
    problem.evaluate(&mut r, Some(&mut a))?;
    drop(r);
    if lin.needs_layout(n) {
        if let Some(layout) = problem.layout() {
            lin.set_layout(layout);
        }
    }
    // K − σM, the mass once between the processes (on the rows of the non-cell terms)
    let sigma = shift(settings);
    if sigma != 0.0 {
        add_mass_on_term_rows(&problem, mass, -sigma, &mut a);
    }
    factor_shifted(lin.as_mut(), &a, settings)?;
    drop(a);
    let mut m = EquationMass::new(mass, &problem.dofs);
    lanczos_modes(lin, &mut |x, y| m.mul(x, y), &problem.dofs, sigma, settings)
}

/// σ = (2π f_shift)² (rad²/s²).
fn shift(settings: &ModeSettings) -> f64 {
    let omega_s = 2.0 * std::f64::consts::PI * settings.shift_hz;
    omega_s * omega_s
}

/// Factors K − σM with the message of a failure.
fn factor_shifted(
    lin: &mut dyn LinearSolver,
    a: &CsrMatrix,
    settings: &ModeSettings,
) -> Result<(), String> {
    lin.factor(a).map_err(|e| {
        format!(
            "factoring K − σM at the shift {} Hz: {e}",
            settings.shift_hz
        )
    })?;
    Ok(())
}

/// [`modes`] of an assembled coupled tangent `k` and mass `m` (same pattern, equation space of
/// `dofs`; whole, or a process's parts when `lin` sums them), factored by `lin`, with
/// `mass_product` the whole product y = M x.
pub fn modes_of(
    k: &CsrMatrix,
    m: &CsrMatrix,
    dofs: &DofMap,
    mut lin: Box<dyn LinearSolver>,
    mass_product: &mut dyn FnMut(&[f64], &mut [f64]),
    settings: &ModeSettings,
) -> Result<Vec<Mode>, String> {
    let sigma = shift(settings);
    let mut a = k.clone();
    for (v, mv) in a.values.iter_mut().zip(&m.values) {
        *v -= sigma * mv;
    }
    factor_shifted(lin.as_mut(), &a, settings)?;
    drop(a);
    lanczos_modes(lin, mass_product, dofs, sigma, settings)
}

/// The modes nearest to the shift σ by shift-invert Lanczos, with `lin` holding the factored
/// K − σM and `m` the product with the mass (equation space of `dofs`).
fn lanczos_modes(
    mut lin: Box<dyn LinearSolver>,
    m: &mut dyn FnMut(&[f64], &mut [f64]),
    dofs: &DofMap,
    sigma: f64,
    settings: &ModeSettings,
) -> Result<Vec<Mode>, String> {
    let n = dofs.n_free;
    let is_u: Vec<bool> = dofs.field_of_equation().iter().map(|&f| f != PHI).collect();
    let n_u = is_u.iter().filter(|&&u| u).count();
    if settings.count == 0 || settings.count > n_u {
        return Err(format!(
            "{} modes asked of a model with {n_u} free displacements",
            settings.count
        ));
    }
    // the products with M share one closure: interior mutability through a cell
    let m = std::cell::RefCell::new(m);
    let op = |x: &[f64], y: &mut [f64], lin: &mut Box<dyn LinearSolver>| -> Result<(), String> {
        (m.borrow_mut())(x, y);
        lin.solve_in_place(y).map_err(|e| e.to_string())?;
        // the potential part is the condensed response: the vectors live on the displacements
        for (v, &u) in y.iter_mut().zip(&is_u) {
            if !u {
                *v = 0.0;
            }
        }
        Ok(())
    };
    let m_dot = |x: &[f64], y: &[f64], work: &mut [f64]| -> f64 {
        (m.borrow_mut())(y, work);
        x.iter().zip(work.iter()).map(|(a, b)| a * b).sum()
    };
    // deterministic start vector in the range of the operator
    let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
    let mut start: Vec<f64> = (0..n)
        .map(|i| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            if is_u[i] {
                (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            } else {
                0.0
            }
        })
        .collect();
    let mut work = vec![0.0; n];
    let mut v0 = vec![0.0; n];
    op(&start, &mut v0, &mut lin)?;
    start.clone_from(&v0);
    let mut max_steps = (2 * settings.count + 20).min(n_u);
    loop {
        let result = lanczos(&op, &m_dot, &start, max_steps, &mut lin, &mut work)?;
        let (basis, alpha, beta) = result;
        let steps = alpha.len();
        let t = nalgebra::DMatrix::from_fn(steps, steps, |i, j| {
            if i == j {
                alpha[i]
            } else if i + 1 == j {
                beta[i]
            } else if j + 1 == i {
                beta[j]
            } else {
                0.0
            }
        });
        let eig = nalgebra::SymmetricEigen::new(t);
        // θ by decreasing magnitude: nearest to the shift first
        let mut order: Vec<usize> = (0..steps).collect();
        order.sort_by(|&i, &j| {
            eig.eigenvalues[j]
                .abs()
                .total_cmp(&eig.eigenvalues[i].abs())
        });
        let beta_last = beta.last().copied().unwrap_or(0.0);
        let mut out = Vec::new();
        for &i in order.iter().take(settings.count) {
            let theta = eig.eigenvalues[i];
            // Ritz residual of the shift-inverted problem: |β_m s_m|/|θ|
            let residual = (beta_last * eig.eigenvectors[(steps - 1, i)]).abs() / theta.abs();
            if residual > settings.tolerance && steps < n_u {
                break;
            }
            let mut x = vec![0.0; n];
            for (j, b) in basis.iter().enumerate() {
                let s = eig.eigenvectors[(j, i)];
                for (xe, be) in x.iter_mut().zip(b) {
                    *xe += s * be;
                }
            }
            let norm = m_dot(&x, &x, &mut work).sqrt();
            x.iter_mut().for_each(|v| *v /= norm);
            out.push((theta, x, residual));
        }
        if out.len() == settings.count {
            let mut modes = out
                .into_iter()
                .map(|(theta, x, _)| {
                    let eigenvalue = sigma + 1.0 / theta;
                    let (shape, residual) =
                        shape_of(dofs, &mut **m.borrow_mut(), &x, theta, &mut lin)?;
                    Ok(Mode {
                        frequency: eigenvalue.max(0.0).sqrt() / (2.0 * std::f64::consts::PI),
                        eigenvalue,
                        shape,
                        residual,
                        harmonic: 0,
                    })
                })
                .collect::<Result<Vec<Mode>, String>>()?;
            modes.sort_by(|a, b| a.eigenvalue.total_cmp(&b.eigenvalue));
            return Ok(modes);
        }
        if max_steps >= n_u {
            return Err(format!(
                "the Lanczos iteration did not converge {} modes in {max_steps} steps",
                settings.count
            ));
        }
        max_steps = (2 * max_steps).min(n_u);
    }
}

/// The Lanczos process on the operator `op` in the `m_dot` inner product from `start`, with full
/// re-orthogonalisation: the basis and the tridiagonal (α, β).
#[allow(clippy::type_complexity)]
fn lanczos(
    op: &dyn Fn(&[f64], &mut [f64], &mut Box<dyn LinearSolver>) -> Result<(), String>,
    m_dot: &dyn Fn(&[f64], &[f64], &mut [f64]) -> f64,
    start: &[f64],
    steps: usize,
    lin: &mut Box<dyn LinearSolver>,
    work: &mut [f64],
) -> Result<(Vec<Vec<f64>>, Vec<f64>, Vec<f64>), String> {
    let n = start.len();
    let norm = m_dot(start, start, work).sqrt();
    if !(norm > 0.0 && norm.is_finite()) {
        return Err("no free displacement carries mass".into());
    }
    let mut basis: Vec<Vec<f64>> = vec![start.iter().map(|v| v / norm).collect()];
    let (mut alpha, mut beta) = (Vec::new(), Vec::new());
    let mut w = vec![0.0; n];
    for j in 0..steps {
        op(&basis[j], &mut w, lin)?;
        let a = m_dot(&basis[j], &w, work);
        alpha.push(a);
        // full re-orthogonalisation (twice, classical Gram–Schmidt in the M product)
        for _ in 0..2 {
            for b in &basis {
                let c = m_dot(b, &w, work);
                for (wi, bi) in w.iter_mut().zip(b) {
                    *wi -= c * bi;
                }
            }
        }
        let bnorm = m_dot(&w, &w, work).sqrt();
        if j + 1 == steps {
            beta.push(bnorm);
            break;
        }
        if bnorm <= 1e-14 * a.abs().max(f64::MIN_POSITIVE) {
            // an invariant subspace: the Ritz values are exact
            beta.push(0.0);
            break;
        }
        beta.push(bnorm);
        basis.push(w.iter().map(|v| v / bnorm).collect());
    }
    Ok((basis, alpha, beta))
}

/// The shape in dof space: the displacements of `x` (equation space, unit modal mass) and their
/// condensed potential. The potential rows of one solve (K − σM) y = M x hold the potential in
/// equilibrium with y's displacements, and y = θ x for a Ritz pair, so Φ(x) = y_Φ/θ. Also returns
/// the true relative residual ‖y_u − θ x_u‖_M / |θ| of the pair.
fn shape_of(
    dofs: &DofMap,
    m: &mut dyn FnMut(&[f64], &mut [f64]),
    x: &[f64],
    theta: f64,
    lin: &mut Box<dyn LinearSolver>,
) -> Result<(Vec<f64>, f64), String> {
    let mut y = vec![0.0; x.len()];
    m(x, &mut y);
    lin.solve_in_place(&mut y).map_err(|e| e.to_string())?;
    let fields = dofs.field_of_equation();
    let diff: Vec<f64> = (0..x.len())
        .map(|e| {
            if fields[e] == PHI {
                0.0
            } else {
                y[e] - theta * x[e]
            }
        })
        .collect();
    let mut md = vec![0.0; x.len()];
    m(&diff, &mut md);
    let residual = diff
        .iter()
        .zip(&md)
        .map(|(a, b)| a * b)
        .sum::<f64>()
        .max(0.0)
        .sqrt()
        / theta.abs();
    let mut out = vec![0.0; dofs.eq.len()];
    for (d, &e) in dofs.eq.iter().enumerate() {
        if e != CONSTRAINED {
            out[d] = if d % FIELDS == PHI {
                y[e] / theta * dofs.scale[PHI]
            } else {
                x[e]
            };
        }
    }
    Ok((out, residual))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::ElectroNeoHooke;
    use crate::mesh::{generate::box_mesh, ElementKind};
    use crate::problem::dofs::{Dirichlet, Field, Tie};
    use crate::time::mass::MassKind;
    use std::sync::Arc;

    /// The mass product from the nodal mass equals the assembled equation-space mass matrix,
    /// with held displacements and potentials and a tie (a rigid region's translation).
    #[test]
    fn the_equation_mass_is_the_assembled_mass_matrix() {
        let mesh = box_mesh([2.0, 1.0, 0.5], [3, 2, 2], ElementKind::Hex8);
        let mut model = Model::new(mesh, Arc::new(ElectroNeoHooke::new(1.0, 1.0, 1.0))).unwrap();
        let x0 = model.mesh.set_nodes("x0").unwrap();
        let x1 = model.mesh.set_nodes("x1").unwrap();
        for field in [Field::Ux, Field::Phi] {
            model.dirichlet.push(Dirichlet {
                nodes: x0.clone(),
                field,
                value: 0.0,
            });
        }
        model.ties.push(Tie {
            nodes: x1.clone(),
            field: Field::Uz,
            held: false,
        });
        let problem = StaticProblem::new(&model, None);
        let dofs = &problem.dofs;
        for kind in [MassKind::Consistent, MassKind::Lumped] {
            let mass = NodalMass::new(&model, &[7.0], kind);
            let mut m = problem.new_matrix();
            add_mass_on_term_rows(&problem, &mass, 1.0, &mut m);
            let x: Vec<f64> = (0..dofs.n_free)
                .map(|e| ((e * 7) % 13) as f64 - 6.0)
                .collect();
            let (mut assembled, mut nodal) = (vec![0.0; x.len()], vec![0.0; x.len()]);
            m.mul_vec(&x, &mut assembled);
            EquationMass::new(&mass, dofs).mul(&x, &mut nodal);
            let scale = assembled.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
            assert!(scale > 0.0);
            for (e, (a, b)) in assembled.iter().zip(&nodal).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-14 * scale,
                    "{kind:?} equation {e}: {a} {b}"
                );
            }
        }
    }
}
