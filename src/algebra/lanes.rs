//! Lanes of f64: one value of [`LANES`] quadrature points (or cells) evaluated together.
//!
//! [`F4`] is four f64 with the arithmetic operators applied lane by lane. Code written for a
//! [`Lane`] (f64 or `F4`) runs the same operations in the same order on every lane, so a lane
//! of an `F4` result is bit for bit the f64 result of the same inputs: a kernel may evaluate
//! four points at once or one at a time and produce the same numbers on any machine and any
//! number of threads. The compiler turns the lane loops into SSE2 instructions, and into AVX
//! where a caller is compiled for it ([`with_wide_vectors`]); no fused multiply–add is formed,
//! so both give the same bits.
//!
//! nalgebra's matrices hold `F4` as a scalar (its `Scalar` needs only `Clone + PartialEq +
//! Debug`), so the 3 × 3 products of the material models run on lanes unchanged. No crate is
//! used for the lanes themselves: `wide` picks its instructions when the crate is compiled,
//! so the project's baseline build would never run AVX, and the operations needed here are
//! a dozen lines.

use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// Values per [`F4`].
pub const LANES: usize = 4;

/// Four f64 lanes.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[repr(C, align(32))]
pub struct F4(pub [f64; LANES]);

impl F4 {
    /// Every lane `x`.
    #[inline(always)]
    pub fn splat(x: f64) -> Self {
        F4([x; LANES])
    }

    /// Lane `l` from `f(l)`.
    #[inline(always)]
    pub fn from_fn(f: impl FnMut(usize) -> f64) -> Self {
        F4(std::array::from_fn(f))
    }

    /// `f` of every lane (a function with no lane form, such as `ln`).
    #[inline(always)]
    pub fn map(self, f: impl Fn(f64) -> f64) -> Self {
        let a = self.0;
        F4([f(a[0]), f(a[1]), f(a[2]), f(a[3])])
    }

    /// Whether `f` holds for every lane.
    #[inline(always)]
    pub fn all(self, f: impl Fn(f64) -> bool) -> bool {
        self.0.iter().all(|&x| f(x))
    }
}

macro_rules! lane_op {
    ($trait:ident, $method:ident, $assign:ident, $assign_method:ident, $op:tt) => {
        impl $trait for F4 {
            type Output = F4;
            #[inline(always)]
            fn $method(self, b: F4) -> F4 {
                let (a, b) = (self.0, b.0);
                F4([a[0] $op b[0], a[1] $op b[1], a[2] $op b[2], a[3] $op b[3]])
            }
        }
        impl $assign for F4 {
            #[inline(always)]
            fn $assign_method(&mut self, b: F4) {
                *self = *self $op b;
            }
        }
    };
}

lane_op!(Add, add, AddAssign, add_assign, +);
lane_op!(Sub, sub, SubAssign, sub_assign, -);
lane_op!(Mul, mul, MulAssign, mul_assign, *);
lane_op!(Div, div, DivAssign, div_assign, /);

impl Neg for F4 {
    type Output = F4;
    #[inline(always)]
    fn neg(self) -> F4 {
        self.map(|x| -x)
    }
}

impl num_traits::Zero for F4 {
    #[inline(always)]
    fn zero() -> Self {
        F4::splat(0.0)
    }
    fn is_zero(&self) -> bool {
        self.all(|x| x == 0.0)
    }
}

impl num_traits::One for F4 {
    #[inline(always)]
    fn one() -> Self {
        F4::splat(1.0)
    }
}

/// A value of one point (f64) or of [`LANES`] points ([`F4`]): what code written once for
/// both needs of it. Constants enter through [`Lane::splat`], which for f64 is the constant
/// itself, so the f64 instance is exactly the scalar code.
pub trait Lane:
    nalgebra::Scalar
    + Copy
    + num_traits::Zero
    + num_traits::One
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
{
    /// The constant `x` in every lane.
    fn splat(x: f64) -> Self;
    /// `f` of every lane.
    fn map(self, f: impl Fn(f64) -> f64) -> Self;
}

impl Lane for f64 {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> Self {
        f(self)
    }
}

impl Lane for F4 {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        F4::splat(x)
    }
    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> Self {
        F4::map(self, f)
    }
}

/// ‖M‖² of a 3 × 3 matrix (or 3-vector) in the order of nalgebra's `norm_squared` (column by
/// column, each a dot product), for any [`Lane`]: the same bits as `norm_squared` for f64.
#[inline(always)]
pub fn norm_squared<T: Lane, const R: usize, const C: usize>(m: &nalgebra::SMatrix<T, R, C>) -> T {
    let mut res = T::zero();
    for i in 0..C {
        let col = m.column(i);
        res += col.dot(&col);
    }
    res
}

/// A computation on lanes to be compiled for wide vectors ([`with_wide_vectors`]). Its
/// [`Wide::run`] is to be `#[inline(always)]`, with everything it calls on the lanes, so that
/// it is compiled inside the AVX2 function (a closure would stay a function of its own).
pub trait Wide {
    type Output;
    /// The computation.
    fn run(self) -> Self::Output;
}

/// Runs `w` compiled for AVX2 where the processor has it, else as compiled (SSE2 on the
/// baseline x86-64): the [`F4`] operations inlined into it then use 256-bit registers. The
/// results are the same bits either way (see the module documentation).
#[inline(always)]
pub fn with_wide_vectors<W: Wide>(w: W) -> W::Output {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2")]
        fn wide<W: Wide>(w: W) -> W::Output {
            w.run()
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2, the only feature `wide` is compiled for.
            return unsafe { wide(w) };
        }
    }
    w.run()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    #[test]
    fn lanes_are_the_scalar_operations() {
        let a = F4([1.5, -2.0, 3.25, 1e-300]);
        let b = F4([0.1, 7.0, -0.3, 1e10]);
        for l in 0..LANES {
            let (x, y) = (a.0[l], b.0[l]);
            assert_eq!((a + b).0[l], x + y);
            assert_eq!((a - b).0[l], x - y);
            assert_eq!((a * b).0[l], x * y);
            assert_eq!((a / b).0[l], x / y);
            assert_eq!((-a).0[l], -x);
            assert_eq!(a.map(f64::ln).0[l].to_bits(), x.ln().to_bits());
        }
    }

    /// nalgebra's generic products on lanes give each lane the f64 product's bits, and
    /// [`norm_squared`] those of nalgebra's own.
    #[test]
    fn matrices_of_lanes_are_matrices_of_scalars() {
        let m = |s: f64| Matrix3::from_fn(|i, j| (1.0 + s) / (1.0 + i as f64 + 3.1 * j as f64));
        let scalars: Vec<Matrix3<f64>> = (0..LANES).map(|l| m(0.37 * l as f64)).collect();
        let others: Vec<Matrix3<f64>> = (0..LANES).map(|l| m(1.1 + l as f64).transpose()).collect();
        let lanes = Matrix3::from_fn(|i, j| F4::from_fn(|l| scalars[l][(i, j)]));
        let lanes2 = Matrix3::from_fn(|i, j| F4::from_fn(|l| others[l][(i, j)]));
        let v = nalgebra::Vector3::new(F4::splat(0.3), F4::splat(-1.2), F4::splat(2.0));
        let product = lanes * lanes2;
        let mv = lanes.tr_mul(&(lanes2 * v));
        let n2 = norm_squared(&lanes);
        for l in 0..LANES {
            let s = scalars[l] * others[l];
            let sv = scalars[l].tr_mul(&(others[l] * nalgebra::Vector3::new(0.3, -1.2, 2.0)));
            for i in 0..3 {
                assert_eq!(mv[i].0[l].to_bits(), sv[i].to_bits());
                for j in 0..3 {
                    assert_eq!(product[(i, j)].0[l].to_bits(), s[(i, j)].to_bits());
                }
            }
            assert_eq!(n2.0[l].to_bits(), scalars[l].norm_squared().to_bits());
            assert_eq!(
                norm_squared(&scalars[l]).to_bits(),
                scalars[l].norm_squared().to_bits()
            );
        }
        struct Product(Matrix3<F4>, Matrix3<F4>);
        impl Wide for Product {
            type Output = Matrix3<F4>;
            #[inline(always)]
            fn run(self) -> Matrix3<F4> {
                self.0 * self.1
            }
        }
        assert_eq!(with_wide_vectors(Product(lanes, lanes2)), product);
    }
}
