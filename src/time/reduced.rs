//! A reduced state-space model for control: the first N modes about a biased state with a static
//! correction for the rest,
//!
//! ```text
//! ż = A z + B ṽ,   y = C z + D ṽ,   z = [η; η̇],
//! A = [[0, I], [−Ω², −Φᵀ C Φ]],   B = [0; Φᵀ f],
//! ```
//!
//! in generalised coordinates η along a basis of the N lowest modes and one more Ritz vector, the
//! static correction ψ (the static response K⁻¹f to the drive, less its part in the modes,
//! M-orthonormalised): A = [[0, I], [−K_r, −C_r]], B = [0; f_r] with K_r = VᵀKV, C_r = VᵀCV,
//! f_r = Vᵀf (VᵀMV = I), f the force per volt of the driven electrode and ṽ the voltage about the
//! bias. Every basis vector carries the potential condensed on its displacements, so the
//! projection of the coupled system is that of the condensed one. The outputs are the probes
//! linearised about the biased state: C holds their change along each basis vector, D along the
//! direct response of the voltage at fixed displacements (the potential field z = K_ΦΦ⁻¹f_Φ and
//! the electrode's own volt). With ψ in the basis the model is exact at ω → 0, and — unlike a
//! static correction added as a feed-through (the mode-acceleration method) — the truncated
//! part keeps its damping: a Kelvin–Voigt elastomer's fast modes are overdamped and relax in
//! η/E, milliseconds, which a feed-through would make instantaneous (the augmentation of modes
//! by static Ritz vectors: Wilson, Yuan & Dickens, Earthquake Eng. Struct. Dyn. 10 (1982);
//! Craig & Kurdila, Fundamentals of Structural Dynamics, 2006).

use super::frequency::Linearisation;
use super::modal::{modes_of, ModeSettings};
use crate::problem::dofs::{CONSTRAINED, FIELDS, PHI};
use crate::solve::linear::SolverSettings;
use nalgebra::{DMatrix, DVector};

/// The state-space model.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ReducedModel {
    /// Natural frequencies of the kept modes (Hz); the static correction is one more coordinate.
    pub frequencies_hz: Vec<f64>,
    /// Names of the outputs (probes).
    pub outputs: Vec<String>,
    /// Values of the outputs at the biased state (y is the change about them).
    pub output_offsets: Vec<f64>,
    /// The driven electrode and its bias (V).
    pub electrode: String,
    pub bias_v: f64,
    /// Row-major matrices: A (2N × 2N), B (2N × 1), C (P × 2N), D (P × 1).
    pub a: Vec<Vec<f64>>,
    pub b: Vec<Vec<f64>>,
    pub c: Vec<Vec<f64>>,
    pub d: Vec<Vec<f64>>,
}

/// The outputs' first-order change along a state perturbation (`FIELDS` values per node).
pub type OutputGradient<'a> = &'a dyn Fn(&[f64]) -> Result<Vec<f64>, String>;

/// What a reduced model is built from besides the linearisation: the number of modes and the
/// outputs' first-order change along a state perturbation (`FIELDS` values per node).
pub struct Outputs<'a> {
    pub names: Vec<String>,
    pub offsets: Vec<f64>,
    pub gradient: OutputGradient<'a>,
}

impl ReducedModel {
    /// Builds the model from the linearisation `lin` with `count` modes.
    pub fn build(
        lin: &Linearisation,
        count: usize,
        solver: &SolverSettings,
        outputs: &Outputs,
        electrode: &str,
        bias_v: f64,
    ) -> Result<Self, String> {
        // in a distributed run the matrices are this process's parts: the solvers sum them, and
        // products with them are summed (M's is whole on every process)
        let mut mass_product = lin.mass_product();
        let modes = modes_of(
            &lin.k,
            &lin.m,
            &lin.dofs,
            lin.new_solver(solver)?,
            &mut *mass_product,
            &ModeSettings {
                count,
                ..Default::default()
            },
        )?;
        let dofs = &lin.dofs;
        let n = lin.k.n;
        // mode shapes in the (scaled) equation space, potential included
        let eq = |shape: &[f64]| -> Vec<f64> {
            let mut x = vec![0.0; n];
            for (d, &e) in dofs.eq.iter().enumerate() {
                if e != CONSTRAINED {
                    x[e] = shape[d] / dofs.scale[d % FIELDS];
                }
            }
            x
        };
        let vecs: Vec<Vec<f64>> = modes.iter().map(|m| eq(&m.shape)).collect();
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let mut mb = vec![0.0; n];
        let mut m_dot = |a: &[f64], b: &[f64]| {
            mass_product(b, &mut mb);
            dot(a, &mb)
        };
        // the direct potential response z = [0; K_ΦΦ⁻¹ f_Φ] (the field change at fixed u)
        let z = potential_response(lin, solver)?;
        // the static correction as a Ritz vector: ψ = K⁻¹f − z (its potential is the condensed
        // one of its displacements), M-orthogonalised against the modes and normalised
        let mut solver_k = lin.new_solver(solver)?;
        solver_k.factor(&lin.k).map_err(|e| e.to_string())?;
        let mut psi = lin.force.clone();
        solver_k
            .solve_in_place(&mut psi)
            .map_err(|e| e.to_string())?;
        for (x, zi) in psi.iter_mut().zip(&z) {
            *x -= zi;
        }
        let mut basis = vecs.clone();
        for _ in 0..2 {
            for v in &vecs {
                let c = m_dot(v, &psi);
                for (x, vi) in psi.iter_mut().zip(v) {
                    *x -= c * vi;
                }
            }
        }
        let norm = m_dot(&psi, &psi).sqrt();
        let static_norm = {
            let mut w = lin.force.clone();
            solver_k.solve_in_place(&mut w).map_err(|e| e.to_string())?;
            for (x, zi) in w.iter_mut().zip(&z) {
                *x -= zi;
            }
            m_dot(&w, &w).sqrt()
        };
        if norm > 1e-10 * static_norm {
            psi.iter_mut().for_each(|x| *x /= norm);
            basis.push(psi);
        }
        // Galerkin projection: M_r = I, K_r, C_r, f_r (VᵀKV and VᵀCV summed over the processes'
        // parts in a distributed run)
        let nb = basis.len();
        let mut projected = vec![0.0; 2 * nb * nb];
        let mut kv = vec![0.0; n];
        let mut cv = vec![0.0; n];
        for j in 0..nb {
            lin.k.mul_vec(&basis[j], &mut kv);
            lin.c.mul_vec(&basis[j], &mut cv);
            for i in 0..nb {
                projected[i * nb + j] = dot(&basis[i], &kv);
                projected[nb * nb + i * nb + j] = dot(&basis[i], &cv);
            }
        }
        lin.sum_parts(&mut projected)?;
        let kr = DMatrix::from_row_slice(nb, nb, &projected[..nb * nb]);
        let cr = DMatrix::from_row_slice(nb, nb, &projected[nb * nb..]);
        let kr = (&kr + kr.transpose()) * 0.5;
        let fr: Vec<f64> = basis.iter().map(|v| dot(v, &lin.force)).collect();
        // outputs along each basis vector, and along the direct response (z and the 1 V itself)
        let to_dofs = |x: &[f64]| -> Vec<f64> {
            let mut out = vec![0.0; dofs.eq.len()];
            for (d, &e) in dofs.eq.iter().enumerate() {
                if e != CONSTRAINED {
                    out[d] = x[e] * dofs.scale[d % FIELDS];
                }
            }
            out
        };
        let c_basis: Vec<Vec<f64>> = basis
            .iter()
            .map(|v| (outputs.gradient)(&to_dofs(v)))
            .collect::<Result<_, _>>()?;
        let mut direct = to_dofs(&z);
        for &node in &lin.driven {
            direct[node * FIELDS + PHI] = 1.0;
        }
        let d_col = (outputs.gradient)(&direct)?;
        let p = outputs.names.len();
        let mut a = vec![vec![0.0; 2 * nb]; 2 * nb];
        for i in 0..nb {
            a[i][nb + i] = 1.0;
            for j in 0..nb {
                a[nb + i][j] = -kr[(i, j)];
                a[nb + i][nb + j] = -cr[(i, j)];
            }
        }
        let mut b = vec![vec![0.0]; 2 * nb];
        for i in 0..nb {
            b[nb + i][0] = fr[i];
        }
        let c = (0..p)
            .map(|k| {
                let mut row = vec![0.0; 2 * nb];
                for i in 0..nb {
                    row[i] = c_basis[i][k];
                }
                row
            })
            .collect();
        let d = (0..p).map(|k| vec![d_col[k]]).collect();
        Ok(ReducedModel {
            frequencies_hz: modes.iter().map(|m| m.frequency).collect(),
            outputs: outputs.names.clone(),
            output_offsets: outputs.offsets.clone(),
            electrode: electrode.to_string(),
            bias_v,
            a,
            b,
            c,
            d,
        })
    }

    fn matrices(&self) -> (DMatrix<f64>, DVector<f64>, DMatrix<f64>, DVector<f64>) {
        let ns = self.a.len();
        let p = self.c.len();
        (
            DMatrix::from_fn(ns, ns, |i, j| self.a[i][j]),
            DVector::from_fn(ns, |i, _| self.b[i][0]),
            DMatrix::from_fn(p, ns, |i, j| self.c[i][j]),
            DVector::from_fn(p, |i, _| self.d[i][0]),
        )
    }

    /// The outputs' complex response per volt at `omega` (rad/s): C (iω − A)⁻¹ B + D.
    pub fn response(&self, omega: f64) -> Vec<(f64, f64)> {
        let (a, b, c, d) = self.matrices();
        let ns = a.nrows();
        // (iω − A) z = B in real form [[−A, −ωI], [ωI, −A]] [z_r; z_i] = [B; 0]
        let mut big = DMatrix::<f64>::zeros(2 * ns, 2 * ns);
        for i in 0..ns {
            for j in 0..ns {
                big[(i, j)] = -a[(i, j)];
                big[(ns + i, ns + j)] = -a[(i, j)];
            }
            big[(i, ns + i)] = -omega;
            big[(ns + i, i)] = omega;
        }
        let mut rhs = DVector::<f64>::zeros(2 * ns);
        rhs.rows_mut(0, ns).copy_from(&b);
        let z = big
            .lu()
            .solve(&rhs)
            .unwrap_or_else(|| DVector::zeros(2 * ns));
        let (zr, zi) = (z.rows(0, ns), z.rows(ns, ns));
        let yr = &c * zr + &d;
        let yi = &c * zi;
        yr.iter().zip(yi.iter()).map(|(r, i)| (*r, *i)).collect()
    }

    /// The outputs (absolute values: offsets + change) at `times` for the voltage `v(t)` on the
    /// driven electrode, from rest at the bias, by the implicit midpoint rule (A-stable, second
    /// order; the voltage at the step's midpoint, as the finite element integrator takes it) with
    /// the steps between consecutive times.
    pub fn simulate(&self, v: &dyn Fn(f64) -> f64, times: &[f64]) -> Vec<Vec<f64>> {
        let (a, b, c, d) = self.matrices();
        let ns = a.nrows();
        let id = DMatrix::<f64>::identity(ns, ns);
        let mut z = DVector::<f64>::zeros(ns);
        let mut out = Vec::with_capacity(times.len());
        let mut t_prev = times.first().copied().unwrap_or(0.0);
        let mut lu: Option<(f64, nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>)> = None;
        for &t in times {
            let h = t - t_prev;
            if h > 0.0 {
                if lu.as_ref().is_none_or(|(hh, _)| (hh - h).abs() > 1e-12 * h) {
                    lu = Some((h, (&id - &a * (0.5 * h)).lu()));
                }
                let vm = v(t_prev + 0.5 * h) - self.bias_v;
                let rhs = (&id + &a * (0.5 * h)) * &z + &b * (h * vm);
                if let Some((_, f)) = &lu {
                    z = f.solve(&rhs).unwrap_or(z);
                }
            }
            let y = &c * &z + &d * (v(t) - self.bias_v);
            out.push(
                y.iter()
                    .zip(&self.output_offsets)
                    .map(|(a, b)| a + b)
                    .collect(),
            );
            t_prev = t;
        }
        out
    }
}

/// The potential at fixed displacements that the drive alone sets up: z = [0; K_ΦΦ⁻¹ f_Φ] in the
/// equation space (zero without free potential unknowns). With whole matrices K_ΦΦ is factored
/// on its own; with a process's parts, the matrix of K's pattern that holds K_ΦΦ and the identity
/// on the displacements (added once between the processes) is, so that the distributed solver
/// keeps the equations' layout.
fn potential_response(lin: &Linearisation, solver: &SolverSettings) -> Result<Vec<f64>, String> {
    let (k, dofs, force) = (&lin.k, &lin.dofs, &lin.force);
    let n = k.n;
    let fields = dofs.field_of_equation();
    let phi: Vec<usize> = (0..n).filter(|&e| fields[e] == PHI).collect();
    let mut z = vec![0.0; n];
    if phi.is_empty() {
        return Ok(z);
    }
    if lin.is_part() {
        let mut a = k.clone();
        for i in 0..n {
            for p in a.row_ptr[i]..a.row_ptr[i + 1] {
                let j = a.col_idx[p] as usize;
                a.values[p] = if fields[i] == PHI && fields[j] == PHI {
                    k.values[p]
                } else if i == j && lin.takes_terms_of(i) {
                    1.0
                } else {
                    0.0
                };
            }
        }
        let mut s = lin.new_solver(solver)?;
        s.factor(&a).map_err(|e| e.to_string())?;
        let mut rhs: Vec<f64> = (0..n)
            .map(|e| if fields[e] == PHI { force[e] } else { 0.0 })
            .collect();
        s.solve_in_place(&mut rhs).map_err(|e| e.to_string())?;
        return Ok(rhs);
    }
    let mut index = vec![usize::MAX; n];
    for (i, &e) in phi.iter().enumerate() {
        index[e] = i;
    }
    let mut row_ptr = vec![0];
    let (mut col_idx, mut values) = (Vec::new(), Vec::new());
    for &e in &phi {
        for p in k.row_ptr[e]..k.row_ptr[e + 1] {
            let j = index[k.col_idx[p] as usize];
            if j != usize::MAX {
                col_idx.push(crate::algebra::csr::col(j));
                values.push(k.values[p]);
            }
        }
        row_ptr.push(col_idx.len());
    }
    let block = crate::algebra::csr::CsrMatrix::new(phi.len(), row_ptr, col_idx, values);
    let mut s = solver.build();
    s.factor(&block).map_err(|e| e.to_string())?;
    let mut rhs: Vec<f64> = phi.iter().map(|&e| force[e]).collect();
    s.solve_in_place(&mut rhs).map_err(|e| e.to_string())?;
    for (&e, v) in phi.iter().zip(rhs) {
        z[e] = v;
    }
    Ok(z)
}
