//! The discrete algebraic Riccati equation (DARE) of linear-quadratic control and steady-state
//! Kalman filtering,
//!
//! ```text
//! X = AᵀXA − AᵀXB (R + BᵀXB)⁻¹ BᵀXA + Q,   Q = Qᵀ ⪰ 0, R = Rᵀ ≻ 0,
//! ```
//!
//! solved for its stabilising solution by the structure-preserving doubling algorithm (SDA):
//! from A₀ = A, G₀ = B R⁻¹ Bᵀ, H₀ = Q,
//!
//! ```text
//! W_k = I + G_k H_k,
//! A_{k+1} = A_k W_k⁻¹ A_k,
//! G_{k+1} = G_k + A_k W_k⁻¹ G_k A_kᵀ,
//! H_{k+1} = H_k + A_kᵀ H_k W_k⁻¹ A_k,
//! ```
//!
//! H_k → X quadratically (the error falls like ρ(A − BK)^(2^k)) when the symplectic pencil has no
//! eigenvalue on the unit circle, which holds for a stabilisable and detectable pair (Chu, Fan,
//! Lin & Wang, "Structure-preserving algorithms for periodic discrete-time algebraic Riccati
//! equations", Int. J. Control 77 (2004) 767–788; Huang, Li & Lin, "Structure-Preserving
//! Doubling Algorithms for Nonlinear Matrix Equations", SIAM 2018, ch. 3). It needs only LU
//! solves of n × n matrices and no eigenvector reordering, which the project's linear algebra
//! (nalgebra, faer) has; neither offers a Riccati solver, and the ordered real Schur form that the
//! Schur method (Laub, IEEE TAC 24 (1979)) needs is not in nalgebra.

use nalgebra::DMatrix;

/// The iterations at most; convergence takes a few tens even for a closed loop barely inside
/// the unit circle (2^k samples of its slowest pole).
const MAX_ITERATIONS: usize = 100;

/// The stabilising solution X of the DARE for (A, B, Q, R); an error when the iteration does not
/// converge (an unstabilisable pair, or a mode on the unit circle that Q does not see).
pub fn solve_dare(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<DMatrix<f64>, String> {
    let n = a.nrows();
    if a.ncols() != n
        || b.nrows() != n
        || q.shape() != (n, n)
        || r.shape() != (b.ncols(), b.ncols())
    {
        return Err(format!(
            "Riccati equation: inconsistent shapes A {:?}, B {:?}, Q {:?}, R {:?}",
            a.shape(),
            b.shape(),
            q.shape(),
            r.shape()
        ));
    }
    let r_inv_bt = r
        .clone()
        .cholesky()
        .ok_or("Riccati equation: the input weight R is not positive definite")?
        .solve(&b.transpose());
    let id = DMatrix::<f64>::identity(n, n);
    let mut ak = a.clone();
    let mut g = sym(&(b * r_inv_bt));
    let mut h = sym(q);
    for _ in 0..MAX_ITERATIONS {
        let lu = (&id + &g * &h).lu();
        let w_a = lu
            .solve(&ak)
            .ok_or("Riccati equation: I + G H became singular in the doubling iteration")?;
        let w_g = lu
            .solve(&g)
            .ok_or("Riccati equation: I + G H became singular in the doubling iteration")?;
        let h_next = sym(&(&h + ak.transpose() * &h * &w_a));
        let g_next = sym(&(&g + &ak * &w_g * ak.transpose()));
        let a_next = &ak * &w_a;
        let change = (&h_next - &h).norm();
        let size = h_next.norm();
        if !size.is_finite() || !a_next.norm().is_finite() {
            return Err(
                "Riccati equation: the doubling iteration diverged (no stabilising \
                        solution: an unstabilisable pair or a mode on the unit circle)"
                    .into(),
            );
        }
        h = h_next;
        g = g_next;
        ak = a_next;
        if change <= 1e-15 * size || size == 0.0 {
            return Ok(h);
        }
    }
    Err(format!(
        "Riccati equation: no convergence in {MAX_ITERATIONS} doubling steps (a closed-loop \
         pole on the unit circle?)"
    ))
}

/// The residual AᵀXA − AᵀXB (R + BᵀXB)⁻¹ BᵀXA + Q − X of a candidate X.
pub fn dare_residual(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    x: &DMatrix<f64>,
) -> DMatrix<f64> {
    let s = r + b.transpose() * x * b;
    let bxa = b.transpose() * x * a;
    let k = s
        .lu()
        .solve(&bxa)
        .unwrap_or_else(|| DMatrix::from_element(bxa.nrows(), bxa.ncols(), f64::NAN));
    a.transpose() * x * a - bxa.transpose() * k + q - x
}

/// The gain K = (R + BᵀXB)⁻¹ BᵀXA of the optimal state feedback u = −K z for the DARE's X.
pub fn feedback_gain(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    r: &DMatrix<f64>,
    x: &DMatrix<f64>,
) -> Result<DMatrix<f64>, String> {
    (r + b.transpose() * x * b)
        .lu()
        .solve(&(b.transpose() * x * a))
        .ok_or_else(|| "the feedback gain: R + BᵀXB is singular".to_string())
}

/// The largest modulus of the eigenvalues of a square matrix (its spectral radius).
pub fn spectral_radius(m: &DMatrix<f64>) -> f64 {
    m.complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
}

fn sym(m: &DMatrix<f64>) -> DMatrix<f64> {
    (m + m.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scalar DARE x = a²x − a²b²x²/(r + b²x) + q has the closed form
    /// b²x² − (a²r − r + qb²)x − qr = 0 (positive root); an unstable a is stabilised.
    #[test]
    fn the_scalar_equation_has_its_closed_form() {
        for (a, b, q, r) in [
            (0.9, 1.0, 1.0, 1.0),
            (1.5, 0.3, 2.0, 0.1),
            (-2.0, 1.0, 0.5, 3.0),
        ] {
            let m = |v: f64| DMatrix::from_element(1, 1, v);
            let x = solve_dare(&m(a), &m(b), &m(q), &m(r)).unwrap()[(0, 0)];
            let p = a * a * r - r + q * b * b;
            let exact = (p + (p * p + 4.0 * b * b * q * r).sqrt()) / (2.0 * b * b);
            assert!((x - exact).abs() <= 1e-13 * exact, "{x} {exact}");
            let k = feedback_gain(&m(a), &m(b), &m(r), &m(x)).unwrap()[(0, 0)];
            assert!((a - b * k).abs() < 1.0, "closed loop {}", a - b * k);
        }
    }

    /// A lightly damped oscillator sampled with a zero-order hold, with a rank-one state weight
    /// (one output) and an unstable mode beside it: the residual is round-off, the closed loop
    /// stable, and X is symmetric positive semi-definite.
    #[test]
    fn a_multivariable_solution_satisfies_its_equation() {
        let (w, zeta, t) = (2.0 * std::f64::consts::PI * 30.0, 0.02, 1e-3);
        let ac = DMatrix::from_row_slice(
            3,
            3,
            &[0.0, 1.0, 0.0, -w * w, -2.0 * zeta * w, 0.0, 0.0, 0.0, 5.0],
        );
        let bc = DMatrix::from_row_slice(3, 1, &[0.0, 1.0, 1.0]);
        let mut aug = DMatrix::zeros(4, 4);
        aug.view_mut((0, 0), (3, 3)).copy_from(&(&ac * t));
        aug.view_mut((0, 3), (3, 1)).copy_from(&(&bc * t));
        let e = aug.exp();
        let a = e.view((0, 0), (3, 3)).into_owned();
        let b = e.view((0, 3), (3, 1)).into_owned();
        let c = DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 1.0]);
        let q = c.transpose() * &c * 1e4;
        let r = DMatrix::from_element(1, 1, 1e-2);
        let x = solve_dare(&a, &b, &q, &r).unwrap();
        let res = dare_residual(&a, &b, &q, &r, &x);
        assert!(
            res.norm() <= 1e-11 * x.norm(),
            "{:e} {:e}",
            res.norm(),
            x.norm()
        );
        assert!((&x - x.transpose()).norm() <= 1e-14 * x.norm());
        assert!(x.symmetric_eigenvalues().min() > -1e-10 * x.norm());
        let k = feedback_gain(&a, &b, &r, &x).unwrap();
        let rho = spectral_radius(&(&a - &b * &k));
        assert!(rho < 1.0, "{rho}");
        assert!(spectral_radius(&a) > 1.0);
    }

    /// An unstabilisable pair (an unstable mode the input does not reach) has no stabilising
    /// solution: refused, not looped on.
    #[test]
    fn an_unstabilisable_pair_is_refused() {
        let a = DMatrix::from_row_slice(2, 2, &[1.2, 0.0, 0.0, 0.5]);
        let b = DMatrix::from_row_slice(2, 1, &[0.0, 1.0]);
        let q = DMatrix::identity(2, 2);
        let r = DMatrix::identity(1, 1);
        assert!(solve_dare(&a, &b, &q, &r).is_err());
    }
}
