//! Krylov methods for the Newton systems: flexible GMRES for any nonsingular matrix and
//! preconditioner, MINRES for a symmetric (indefinite) matrix with a symmetric positive definite
//! preconditioner.
//!
//! Both take the operator and the preconditioner as closures, so that they know nothing of where
//! the matrix comes from (an assembled tangent, a reused factorisation, a multigrid cycle).
//! References: Saad, *Iterative Methods for Sparse Linear Systems* (2nd ed., SIAM 2003), §6.5 and
//! §9.4 (GMRES, flexible GMRES); Paige & Saunders, SIAM J. Numer. Anal. 12 (1975) 617–629, in the
//! preconditioned form of Elman, Silvester & Wathen, *Finite Elements and Fast Iterative Solvers*
//! (2nd ed., OUP 2014), §4.2 (MINRES).

/// Outcome of a Krylov solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KrylovReport {
    /// Iterations (operator applications after the first residual).
    pub iterations: usize,
    /// The final residual norm relative to ‖b‖ (GMRES: ‖b − Ax‖₂; MINRES: its preconditioned
    /// norm ‖b − Ax‖_{M⁻¹}, which is what the method minimises).
    pub relative_residual: f64,
    /// Whether the tolerance was met.
    pub converged: bool,
}

/// Settings of a Krylov solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KrylovSettings {
    /// Converged when the residual norm ≤ `rtol` · ‖b‖ (in the method's norm).
    pub rtol: f64,
    /// Largest number of iterations in all.
    pub max_iterations: usize,
    /// GMRES restart length (basis vectors kept).
    pub restart: usize,
}

impl Default for KrylovSettings {
    fn default() -> Self {
        KrylovSettings {
            rtol: 1e-10,
            max_iterations: 200,
            restart: 50,
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

/// Entries per piece of the vectors in [`orthogonalise`]: the pieces' sums are added in order,
/// so the result is the same on any number of threads.
const PIECE: usize = 4096;

/// One classical Gram–Schmidt pass: c = Vᵀw and w −= V c for the orthonormal columns V stored
/// one after another in `basis`; returns c. Each piece of the vectors is done by one thread.
fn orthogonalise(basis: &[f64], w: &mut [f64]) -> Vec<f64> {
    use rayon::prelude::*;
    let n = w.len();
    let m = basis.len() / n.max(1);
    let piece = |p: usize| p * PIECE..((p + 1) * PIECE).min(n);
    let pieces = n.div_ceil(PIECE);
    let parallel = n >= 16 * PIECE && rayon::current_num_threads() > 1;
    let partial = |p: usize| -> Vec<f64> {
        let r = piece(p);
        (0..m)
            .map(|i| dot(&w[r.clone()], &basis[i * n + r.start..i * n + r.end]))
            .collect()
    };
    let partials: Vec<Vec<f64>> = if parallel {
        (0..pieces).into_par_iter().map(partial).collect()
    } else {
        (0..pieces).map(partial).collect()
    };
    let mut c = vec![0.0; m];
    for part in &partials {
        c.iter_mut().zip(part).for_each(|(ci, pi)| *ci += pi);
    }
    let update = |(p, wp): (usize, &mut [f64])| {
        let start = p * PIECE;
        for (i, ci) in c.iter().enumerate() {
            let v = &basis[i * n + start..i * n + start + wp.len()];
            wp.iter_mut().zip(v).for_each(|(wi, vi)| *wi -= ci * vi);
        }
    };
    if parallel {
        w.par_chunks_mut(PIECE).enumerate().for_each(update);
    } else {
        w.chunks_mut(PIECE).enumerate().for_each(update);
    }
    c
}

/// Right-preconditioned flexible GMRES(m) for A x = b, from the initial guess in `x`.
///
/// `apply(v, y)` sets y = A v; `precond(v, z)` sets z ≈ A⁻¹ v (it may change from call to call:
/// the flexible variant keeps the preconditioned vectors, so the update stays exact). The residual
/// of the iterate is minimised in the 2-norm; the true residual is recomputed at each restart.
pub fn fgmres(
    mut apply: impl FnMut(&[f64], &mut [f64]),
    mut precond: impl FnMut(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    settings: &KrylovSettings,
) -> KrylovReport {
    let n = b.len();
    let bnorm = norm(b);
    if bnorm == 0.0 {
        x.iter_mut().for_each(|v| *v = 0.0);
        return KrylovReport {
            iterations: 0,
            relative_residual: 0.0,
            converged: true,
        };
    }
    let m = settings.restart.max(1);
    let target = settings.rtol * bnorm;
    // the Krylov basis and the preconditioned vectors, each in one zeroed allocation: its pages
    // are mapped only as the iteration reaches them, and it goes back to the system as a whole
    // when the solve ends (m vectors of their own each would stay in the allocator's heap)
    let mut basis = vec![0.0; (m + 1) * n];
    let mut zs = vec![0.0; m * n];
    let mut h = vec![vec![0.0; m]; m + 1]; // h[i][j]: row i, column j
    let (mut cs, mut sn, mut g) = (vec![0.0; m], vec![0.0; m], vec![0.0; m + 1]);
    let mut w = vec![0.0; n];
    let mut iterations = 0;
    let mut residual;
    loop {
        // true residual r = b − A x, the first basis vector
        apply(x, &mut w);
        let r = &mut basis[..n];
        r.iter_mut()
            .zip(b.iter().zip(&w))
            .for_each(|(ri, (bi, wi))| *ri = bi - wi);
        residual = norm(r);
        if residual <= target || iterations >= settings.max_iterations || !residual.is_finite() {
            break;
        }
        r.iter_mut().for_each(|v| *v /= residual);
        g.iter_mut().for_each(|v| *v = 0.0);
        g[0] = residual;
        let mut k = 0;
        while k < m && iterations < settings.max_iterations {
            let z = &mut zs[k * n..(k + 1) * n];
            // as a fresh vector: a restart's earlier vector is not the preconditioner's guess
            z.iter_mut().for_each(|v| *v = 0.0);
            precond(&basis[k * n..(k + 1) * n], z);
            apply(z, &mut w);
            iterations += 1;
            // classical Gram–Schmidt, repeated once (CGS2: as orthogonal as the modified
            // process repeated, also when the preconditioner is nearly exact and the Hessenberg
            // entries span many decades, and one pass over the basis for all its products)
            for hcol in h.iter_mut() {
                hcol[k] = 0.0;
            }
            for _ in 0..2 {
                let c = orthogonalise(&basis[..(k + 1) * n], &mut w);
                for (i, ci) in c.into_iter().enumerate() {
                    h[i][k] += ci;
                }
            }
            let hn = norm(&w);
            h[k + 1][k] = hn;
            // apply the earlier rotations to the new column, then a new one to zero h[k+1][k]
            for i in 0..k {
                let t = cs[i] * h[i][k] + sn[i] * h[i + 1][k];
                h[i + 1][k] = -sn[i] * h[i][k] + cs[i] * h[i + 1][k];
                h[i][k] = t;
            }
            let d = (h[k][k] * h[k][k] + hn * hn).sqrt();
            if d == 0.0 {
                break;
            }
            cs[k] = h[k][k] / d;
            sn[k] = hn / d;
            h[k][k] = d;
            h[k + 1][k] = 0.0;
            g[k + 1] = -sn[k] * g[k];
            g[k] *= cs[k];
            k += 1;
            if g[k].abs() <= target || hn == 0.0 {
                break;
            }
            basis[k * n..(k + 1) * n]
                .iter_mut()
                .zip(&w)
                .for_each(|(v, wi)| *v = wi / hn);
        }
        // back substitution for the coefficients, then x += Z y
        let mut y = vec![0.0; k];
        for i in (0..k).rev() {
            let s: f64 = (i + 1..k).map(|j| h[i][j] * y[j]).sum();
            y[i] = (g[i] - s) / h[i][i];
        }
        for (z, yi) in zs.chunks_exact(n).zip(&y) {
            x.iter_mut().zip(z).for_each(|(xi, zi)| *xi += yi * zi);
        }
    }
    KrylovReport {
        iterations,
        relative_residual: residual / bnorm,
        converged: residual <= target,
    }
}

/// Preconditioned MINRES for a symmetric A, from the initial guess in `x`.
///
/// `apply(v, y)` sets y = A v; `precond(v, z)` sets z = M⁻¹ v for a fixed symmetric positive
/// definite M (a block-diagonal saddle-point preconditioner, for example). A may be indefinite.
/// Converged when the M⁻¹-norm of the residual falls below `rtol` times that of b − A x₀.
pub fn minres(
    mut apply: impl FnMut(&[f64], &mut [f64]),
    mut precond: impl FnMut(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    settings: &KrylovSettings,
) -> KrylovReport {
    let n = b.len();
    let mut v = vec![0.0; n];
    apply(x, &mut v);
    v.iter_mut().zip(b).for_each(|(vi, bi)| *vi = bi - *vi);
    let mut z = vec![0.0; n];
    precond(&v, &mut z);
    let mut gamma = dot(&z, &v);
    if gamma <= 0.0 || !gamma.is_finite() {
        // zero residual, or a preconditioner that is not positive definite
        return KrylovReport {
            iterations: 0,
            relative_residual: if gamma == 0.0 { 0.0 } else { f64::NAN },
            converged: gamma == 0.0,
        };
    }
    gamma = gamma.sqrt();
    let gamma1 = gamma;
    let mut eta = gamma;
    let (mut gamma_old, mut s_old, mut s, mut c_old, mut c) = (1.0, 0.0, 0.0, 1.0, 1.0);
    let mut v_old = vec![0.0; n];
    let (mut w_old, mut w) = (vec![0.0; n], vec![0.0; n]);
    let mut az = vec![0.0; n];
    let mut z_new = vec![0.0; n];
    let mut iterations = 0;
    while iterations < settings.max_iterations {
        iterations += 1;
        z.iter_mut().for_each(|zi| *zi /= gamma);
        apply(&z, &mut az);
        let delta = dot(&az, &z);
        // the next Lanczos vector, built in place of v_old
        for i in 0..n {
            v_old[i] = az[i] - (delta / gamma) * v[i] - (gamma / gamma_old) * v_old[i];
        }
        std::mem::swap(&mut v, &mut v_old); // v: new, v_old: previous
        precond(&v, &mut z_new);
        let gamma_new2 = dot(&z_new, &v);
        if gamma_new2 < 0.0 || !gamma_new2.is_finite() {
            break;
        }
        let gamma_new = gamma_new2.sqrt();
        let a0 = c * delta - c_old * s * gamma;
        let a1 = (a0 * a0 + gamma_new * gamma_new).sqrt();
        let a2 = s * delta + c_old * c * gamma;
        let a3 = s_old * gamma;
        if a1 == 0.0 {
            break;
        }
        let (c_new, s_new) = (a0 / a1, gamma_new / a1);
        // w_new = (z − a3 w_old − a2 w)/a1, built in place of w_old
        for i in 0..n {
            w_old[i] = (z[i] - a3 * w_old[i] - a2 * w[i]) / a1;
        }
        std::mem::swap(&mut w, &mut w_old); // w: new, w_old: previous
        x.iter_mut()
            .zip(&w)
            .for_each(|(xi, wi)| *xi += c_new * eta * wi);
        eta *= -s_new;
        std::mem::swap(&mut z, &mut z_new);
        gamma_old = gamma;
        gamma = gamma_new;
        c_old = c;
        c = c_new;
        s_old = s;
        s = s_new;
        if eta.abs() <= settings.rtol * gamma1 || gamma == 0.0 {
            break;
        }
    }
    let relative = eta.abs() / gamma1;
    KrylovReport {
        iterations,
        relative_residual: relative,
        converged: relative <= settings.rtol,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric indefinite tridiagonal-plus saddle test matrix, dense for simplicity.
    fn saddle(n: usize) -> Vec<Vec<f64>> {
        let mut a = vec![vec![0.0; n]; n];
        for i in 0..n {
            // alternate definite and negative definite diagonal parts, coupled
            a[i][i] = if i % 4 == 3 {
                -2.0 - 0.1 * i as f64
            } else {
                4.0 + 0.05 * i as f64
            };
            if i + 1 < n {
                a[i][i + 1] = -1.0;
                a[i + 1][i] = -1.0;
            }
            if i + 5 < n {
                a[i][i + 5] = 0.3;
                a[i + 5][i] = 0.3;
            }
        }
        a
    }

    fn matvec(a: &[Vec<f64>], x: &[f64], y: &mut [f64]) {
        for (yi, row) in y.iter_mut().zip(a) {
            *yi = dot(row, x);
        }
    }

    fn residual(a: &[Vec<f64>], x: &[f64], b: &[f64]) -> f64 {
        let mut y = vec![0.0; b.len()];
        matvec(a, x, &mut y);
        let r: Vec<f64> = b.iter().zip(&y).map(|(bi, yi)| bi - yi).collect();
        norm(&r) / norm(b)
    }

    fn rhs(n: usize) -> Vec<f64> {
        (0..n).map(|i| ((i * 7 + 3) % 11) as f64 - 5.0).collect()
    }

    #[test]
    fn fgmres_solves_an_indefinite_system_with_and_without_restarts() {
        let n = 60;
        let a = saddle(n);
        let b = rhs(n);
        for restart in [80, 10] {
            let mut x = vec![0.0; n];
            let s = KrylovSettings {
                rtol: 1e-12,
                max_iterations: 2000,
                restart,
            };
            let rep = fgmres(
                |v, y| matvec(&a, v, y),
                |v, z| z.copy_from_slice(v),
                &b,
                &mut x,
                &s,
            );
            assert!(rep.converged, "{rep:?}");
            let res = residual(&a, &x, &b);
            assert!(res < 1e-11, "restart {restart}: {res:e}");
            // without restarts GMRES finishes in at most n iterations
            if restart >= n {
                assert!(rep.iterations <= n, "{rep:?}");
            }
        }
    }

    #[test]
    fn fgmres_with_an_exact_preconditioner_converges_in_one_iteration() {
        let n = 30;
        let a = saddle(n);
        let b = rhs(n);
        // a Jacobi-scaled operator: A D⁻¹ is solved with the preconditioner D⁻¹ … here the
        // exact inverse from a dense solve with nalgebra
        let m = nalgebra::DMatrix::from_fn(n, n, |i, j| a[i][j]);
        let lu = m.lu();
        let mut x = vec![0.0; n];
        let rep = fgmres(
            |v, y| matvec(&a, v, y),
            |v, z| {
                let s = lu.solve(&nalgebra::DVector::from_column_slice(v)).unwrap();
                z.copy_from_slice(s.as_slice());
            },
            &b,
            &mut x,
            &KrylovSettings::default(),
        );
        assert!(rep.converged && rep.iterations == 1, "{rep:?}");
        assert!(residual(&a, &x, &b) < 1e-12);
    }

    #[test]
    fn minres_solves_a_symmetric_indefinite_system_with_a_positive_preconditioner() {
        let n = 80;
        let a = saddle(n);
        let b = rhs(n);
        // |diag| as the SPD preconditioner
        let d: Vec<f64> = (0..n).map(|i| a[i][i].abs()).collect();
        let mut x = vec![0.0; n];
        let rep = minres(
            |v, y| matvec(&a, v, y),
            |v, z| {
                z.iter_mut()
                    .zip(v)
                    .zip(&d)
                    .for_each(|((zi, vi), di)| *zi = vi / di)
            },
            &b,
            &mut x,
            &KrylovSettings {
                rtol: 1e-12,
                max_iterations: 500,
                restart: 0,
            },
        );
        assert!(rep.converged, "{rep:?}");
        let res = residual(&a, &x, &b);
        assert!(res < 1e-10, "{res:e}");
        // unpreconditioned takes more iterations on this scaled matrix than with |D|
        let mut x2 = vec![0.0; n];
        let plain = minres(
            |v, y| matvec(&a, v, y),
            |v, z| z.copy_from_slice(v),
            &b,
            &mut x2,
            &KrylovSettings {
                rtol: 1e-12,
                max_iterations: 500,
                restart: 0,
            },
        );
        assert!(plain.converged, "{plain:?}");
        assert!(residual(&a, &x2, &b) < 1e-10);
    }

    #[test]
    fn minres_refuses_an_indefinite_preconditioner_instead_of_returning_nonsense() {
        let n = 10;
        let a = saddle(n);
        let b = rhs(n);
        let mut x = vec![0.0; n];
        let rep = minres(
            |v, y| matvec(&a, v, y),
            |v, z| z.iter_mut().zip(v).for_each(|(zi, vi)| *zi = -vi),
            &b,
            &mut x,
            &KrylovSettings::default(),
        );
        assert!(!rep.converged);
    }

    #[test]
    fn a_zero_right_hand_side_gives_zero() {
        let a = saddle(5);
        let mut x = vec![1.0; 5];
        let rep = fgmres(
            |v, y| matvec(&a, v, y),
            |v, z| z.copy_from_slice(v),
            &[0.0; 5],
            &mut x,
            &KrylovSettings::default(),
        );
        assert!(rep.converged && x.iter().all(|v| *v == 0.0));
    }
}
