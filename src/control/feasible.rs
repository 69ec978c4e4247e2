//! The feasible set of a drive: bounds on every variable and largest changes between
//! neighbours along chains (a rate limit on a piecewise-linear table), with the Euclidean
//! projection onto it.
//!
//! The set is the intersection of three convex sets whose projections are closed forms: the box,
//! the pair constraints |xᵢ₊₁ − xᵢ| ≤ cᵢ of the even links of every chain, and those of the odd
//! links (each a set of disjoint pairs). Dykstra's alternating projection algorithm (Boyle &
//! Dykstra 1986) converges to the projection onto their intersection; a final sweep along each
//! chain then clamps every value into its bounds and its link to the previous value, so that the
//! returned point is feasible to the last bit even when the iteration stops early.

/// Bounds (`lower` ≤ x ≤ `upper`, ±∞ where absent) and rate chains.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Feasible {
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    /// Chains of variable indices with the largest |x_{k+1} − x_k| of each link (one fewer
    /// than indices).
    pub chains: Vec<(Vec<usize>, Vec<f64>)>,
}

/// Dykstra's iterations at most, and the change of a sweep below which they stop (relative to
/// the point's largest magnitude, 1 at least).
const MAX_SWEEPS: usize = 2000;
const SWEEP_TOLERANCE: f64 = 1e-14;

impl Feasible {
    /// A box without chains.
    pub fn boxed(lower: Vec<f64>, upper: Vec<f64>) -> Feasible {
        Feasible {
            lower,
            upper,
            chains: Vec::new(),
        }
    }

    /// The largest violation of a bound or a link at `x` (0 when feasible; a link clamped to
    /// its limit may exceed it by the round-off of x + c − x).
    pub fn violation(&self, x: &[f64]) -> f64 {
        let mut worst = 0.0f64;
        for (i, v) in x.iter().enumerate() {
            worst = worst.max(self.lower[i] - v).max(v - self.upper[i]);
        }
        for (idx, limits) in &self.chains {
            for (k, c) in limits.iter().enumerate() {
                worst = worst.max((x[idx[k + 1]] - x[idx[k]]).abs() - c);
            }
        }
        worst
    }

    /// The point of the set nearest to `x` (exactly, for a box alone).
    pub fn project(&self, x: &[f64]) -> Vec<f64> {
        let mut y: Vec<f64> = x.to_vec();
        self.clip(&mut y);
        if self.chains.is_empty() {
            return y;
        }
        if self.violation(&y) <= 0.0 {
            return y;
        }
        // Dykstra over A (box), B (even links), C (odd links), with one correction per set
        let n = x.len();
        let mut y = x.to_vec();
        let (mut pa, mut pb, mut pc) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let scale = x.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        for _ in 0..MAX_SWEEPS {
            let before = y.clone();
            for (set, p) in [(0, &mut pa), (1, &mut pb), (2, &mut pc)] {
                let mut z: Vec<f64> = y.iter().zip(p.iter()).map(|(a, b)| a + b).collect();
                let mut w = z.clone();
                match set {
                    0 => self.clip(&mut w),
                    1 => self.links(&mut w, 0),
                    _ => self.links(&mut w, 1),
                }
                for i in 0..n {
                    p[i] = z[i] - w[i];
                }
                std::mem::swap(&mut y, &mut w);
                z.clear();
            }
            let change = y
                .iter()
                .zip(&before)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            if change <= SWEEP_TOLERANCE * scale {
                break;
            }
        }
        self.repair(&mut y);
        y
    }

    /// Clamps every value into its bounds.
    fn clip(&self, x: &mut [f64]) {
        for (i, v) in x.iter_mut().enumerate() {
            *v = v.max(self.lower[i]).min(self.upper[i]);
        }
    }

    /// Projects onto the links k ≡ `parity` (mod 2) of every chain: a link that is too long is
    /// shortened symmetrically (its two ends move toward each other by half the excess).
    fn links(&self, x: &mut [f64], parity: usize) {
        for (idx, limits) in &self.chains {
            for k in (parity..limits.len()).step_by(2) {
                let (a, b) = (idx[k], idx[k + 1]);
                let d = x[b] - x[a];
                let excess = d.abs() - limits[k];
                if excess > 0.0 {
                    let m = 0.5 * excess * d.signum();
                    x[a] += m;
                    x[b] -= m;
                }
            }
        }
    }

    /// Makes `x` feasible by a sweep along each chain: each value clamped into its bounds and
    /// into reach of the value before it (never empty: the value before is in both).
    fn repair(&self, x: &mut [f64]) {
        self.clip(x);
        for (idx, limits) in &self.chains {
            for (k, c) in limits.iter().enumerate() {
                let (a, b) = (idx[k], idx[k + 1]);
                let lo = self.lower[b].max(x[a] - c);
                let hi = self.upper[b].min(x[a] + c);
                x[b] = x[b].max(lo).min(hi);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_is_a_clip() {
        let f = Feasible::boxed(vec![0.0, -1.0], vec![1.0, 1.0]);
        assert_eq!(f.project(&[2.0, -3.0]), vec![1.0, -1.0]);
        assert_eq!(f.project(&[0.5, 0.25]), vec![0.5, 0.25]);
    }

    #[test]
    fn a_rate_chain_projects_onto_the_nearest_feasible_point() {
        // one link: the projection of (0, 3) onto |b − a| ≤ 1 is (1, 2)
        let f = Feasible {
            lower: vec![-10.0; 2],
            upper: vec![10.0; 2],
            chains: vec![(vec![0, 1], vec![1.0])],
        };
        let p = f.project(&[0.0, 3.0]);
        assert!(
            (p[0] - 1.0).abs() < 1e-12 && (p[1] - 2.0).abs() < 1e-12,
            "{p:?}"
        );
        // a step from 0 to 4 over four links of 0.5 with a box [0, 4]: feasible after, and the
        // nearest such point, checked against every feasible point of a fine search along
        // the family of symmetric ramps it must lie in
        let f = Feasible {
            lower: vec![0.0; 5],
            upper: vec![4.0; 5],
            chains: vec![(vec![0, 1, 2, 3, 4], vec![0.5; 4])],
        };
        let x = [0.0, 0.0, 4.0, 4.0, 4.0];
        let p = f.project(&x);
        assert!(f.violation(&p) <= 1e-15, "{p:?}");
        // optimality: the projection satisfies (x − p)·(q − p) ≤ 0 for every feasible q
        let dist = |q: &[f64]| -> f64 { q.iter().zip(&x).map(|(a, b)| (a - b).powi(2)).sum() };
        for shift in 0..=40 {
            let c = 2.0 * shift as f64 / 40.0;
            let q: Vec<f64> = (0..5)
                .map(|k| (c + 0.5 * (k as f64 - 2.0)).clamp(0.0, 4.0))
                .collect();
            if f.violation(&q) <= 1e-12 {
                assert!(dist(&p) <= dist(&q) + 1e-9, "{p:?} farther than {q:?}");
                let inner: f64 = (0..5).map(|i| (x[i] - p[i]) * (q[i] - p[i])).sum();
                assert!(inner <= 1e-8, "{inner}");
            }
        }
    }

    #[test]
    fn repair_leaves_no_violation() {
        let f = Feasible {
            lower: vec![-1.0; 6],
            upper: vec![1.0; 6],
            chains: vec![(vec![0, 1, 2, 3, 4, 5], vec![0.1; 5])],
        };
        let mut x = vec![1.0, -1.0, 1.0, -1.0, 1.0, -1.0];
        f.repair(&mut x);
        assert!(f.violation(&x) <= 1e-15, "{x:?}");
        let p = f.project(&[1.0, -1.0, 1.0, -1.0, 1.0, -1.0]);
        assert!(f.violation(&p) <= 1e-15, "{p:?}");
    }
}
