//! The point formulas of the mean-dilatation kernel that its point-by-point path
//! ([`super::mean_dilatation`]) and its lane path ([`super::md_lanes`]) share, written once for
//! one point and for a lane of points ([`Lane`]), so that both give the same bits.

use crate::algebra::lanes::Lane;
use nalgebra::Matrix3;

/// The cofactor matrix cof F = J F⁻ᵀ (∂J/∂F), of one point or a lane of points.
#[inline(always)]
pub(crate) fn cofactor<T: Lane>(f: &Matrix3<T>) -> Matrix3<T> {
    let m = |i: usize, j: usize| f[(i, j)];
    Matrix3::new(
        m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1),
        m(1, 2) * m(2, 0) - m(1, 0) * m(2, 2),
        m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0),
        m(0, 2) * m(2, 1) - m(0, 1) * m(2, 2),
        m(0, 0) * m(2, 2) - m(0, 2) * m(2, 0),
        m(0, 1) * m(2, 0) - m(0, 0) * m(2, 1),
        m(0, 1) * m(1, 2) - m(0, 2) * m(1, 1),
        m(0, 2) * m(1, 0) - m(0, 0) * m(1, 2),
        m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0),
    )
}

/// x^(1/3) for the ratios θ̄/J of a cell, which lie close to 1: near 1 one Halley step from the
/// Taylor polynomial (error (10/243)t⁴ for t = x − 1, cubed by the step: exact to a few ulps for
/// |t| ≤ 1/16), inlined and much cheaper than the correctly rounded library cube root, which
/// serves every other x.
#[inline(always)]
pub(crate) fn cbrt_near_one(x: f64) -> f64 {
    let t = x - 1.0;
    if t.abs() > 0.0625 {
        return x.cbrt();
    }
    let y = 1.0 + t * (1.0 / 3.0 + t * (-1.0 / 9.0 + t * (5.0 / 81.0)));
    let y3 = y * y * y;
    y * (y3 + 2.0 * x) / (2.0 * y3 + x)
}

/// The Kelvin–Voigt stress c d F⁻ᵀ and the power density c d:d of a point (or a lane of
/// points) with the rate Ḟ (`fd`), F⁻ᵀ and c = Jη, where d = sym(Ḟ F⁻¹).
#[inline(always)]
pub(crate) fn viscous_stress<T: Lane>(
    fd: &[[T; 3]; 3],
    finv_t: &Matrix3<T>,
    c: T,
) -> (Matrix3<T>, T) {
    // l = Ḟ F⁻¹: l_im = Σ_k Ḟ_ik (F⁻ᵀ)_mk
    let mut l = [[T::zero(); 3]; 3];
    for i in 0..3 {
        for m in 0..3 {
            l[i][m] =
                fd[i][0] * finv_t[(m, 0)] + fd[i][1] * finv_t[(m, 1)] + fd[i][2] * finv_t[(m, 2)];
        }
    }
    let d = Matrix3::from_fn(|i, m| T::splat(0.5) * (l[i][m] + l[m][i]));
    let dd = d.dot(&d);
    (d * finv_t * c, c * dd)
}
