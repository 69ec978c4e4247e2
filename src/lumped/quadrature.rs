//! Gauss–Legendre quadrature on an interval (radial integrals of the lumped models).

/// Nodes and weights of the n-point Gauss–Legendre rule on [−1, 1] (exact for degree 2n − 1),
/// computed by Newton's method on the Legendre polynomial.
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    for i in 0..n.div_ceil(2) {
        // Tricomi's initial guess of the i-th largest root
        let mut z = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (z * p1 - p0) / (z * z - 1.0);
            let dz = p1 / dp;
            z -= dz;
            if dz.abs() < 1e-16 {
                break;
            }
        }
        let wi = 2.0 / ((1.0 - z * z) * dp * dp);
        x[i] = -z;
        x[n - 1 - i] = z;
        w[i] = wi;
        w[n - 1 - i] = wi;
    }
    (x, w)
}

/// Points and weights of the n-point rule mapped to [lo, hi].
pub fn on_interval(n: usize, lo: f64, hi: f64) -> Vec<(f64, f64)> {
    let (x, w) = gauss_legendre(n);
    let (mid, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    x.iter()
        .zip(&w)
        .map(|(xi, wi)| (mid + half * xi, half * wi))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The n-point rule integrates x^k exactly for k ≤ 2n − 1 and (small n) not x^{2n}.
    #[test]
    fn lumped_gauss_legendre_is_exact_to_degree_2n_minus_1() {
        for n in [1, 2, 3, 8, 24, 40] {
            let (x, w) = gauss_legendre(n);
            for k in 0..=2 * n {
                let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(k as i32)).sum();
                let exact = if k % 2 == 1 {
                    0.0
                } else {
                    2.0 / (k + 1) as f64
                };
                if k < 2 * n {
                    assert!((q - exact).abs() < 1e-13, "n {n} k {k}: {q} vs {exact}");
                } else if n <= 3 {
                    // the rule's error for x^{2n} is then large enough to see
                    assert!((q - exact).abs() > 1e-3, "n {n} k {k}: {q} vs {exact}");
                }
            }
        }
    }
}
