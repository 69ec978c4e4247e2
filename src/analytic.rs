//! Closed-form reference solutions used by tests and validation.
//!
//! The homogeneous film (docs/theory.md): F = diag(λ, λ, t), referential field E₀ = Φ/H through the
//! thickness, free lateral faces, the energy of docs/theory.md. Stationarity gives
//!   μ(λ − 1/λ) + Λ ln J/λ − (ε/2)E₀² λ/t = 0,
//!   μ(t − 1/t) + Λ ln J/t + 2c₂ t E₀² + (ε/2)E₀² λ²/t² = 0,   J = λ²t.
//! The incompressible equibiaxial film (Zhao & Suo, APL 91 (2007) 061921): neo-Hooke
//! Φ̂ = √(λ⁻² − λ⁻⁸), Gent with a nominal dead load P = s/μ:
//! Φ̂² = [Jm(λ − λ⁻⁵)/(Jm − 2λ² − λ⁻⁴ + 3) − P]/λ³, with Φ̂ = Φ/(H√(μ/ε)).

/// Parameters of the compressible film (SI).
#[derive(Debug, Clone, Copy)]
pub struct Film {
    pub mu: f64,
    pub lambda: f64,
    /// Permittivity ε (F/m) of the electric term.
    pub eps: f64,
    /// Coupling coefficient c₂ (N/V²).
    pub c2: f64,
}

/// A homogeneous state: in-plane stretch λ and thickness stretch t.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilmState {
    pub lambda: f64,
    pub t: f64,
}

impl Film {
    /// Residuals of the two stationarity conditions at (λ, t) for field `e0` (V/m).
    fn residuals(&self, e0: f64, s: FilmState) -> [f64; 2] {
        let (l, t) = (s.lambda, s.t);
        let lnj = (l * l * t).ln();
        let e2 = e0 * e0;
        [
            self.mu * (l - 1.0 / l) + self.lambda * lnj / l - 0.5 * self.eps * e2 * l / t,
            self.mu * (t - 1.0 / t)
                + self.lambda * lnj / t
                + 2.0 * self.c2 * t * e2
                + 0.5 * self.eps * e2 * l * l / (t * t),
        ]
    }

    /// In-plane stretch λ(t) on the solution curve (c₂ = 0): μ(t² + λ² − 2) + 2Λ ln(λ²t) = 0.
    fn lambda_of_t(&self, t: f64) -> f64 {
        let mut l = 1.0f64;
        for _ in 0..100 {
            let f = self.mu * (t * t + l * l - 2.0) + 2.0 * self.lambda * (l * l * t).ln();
            let df = 2.0 * self.mu * l + 4.0 * self.lambda / l;
            let dl = f / df;
            l -= dl;
            if dl.abs() < 1e-16 * l {
                break;
            }
        }
        l
    }

    /// Field E₀(t)² on the solution curve (c₂ = 0).
    fn field_sq_of_t(&self, t: f64) -> f64 {
        let l = self.lambda_of_t(t);
        self.mu * (l * l - t * t) * t / (self.eps * l * l)
    }

    /// The point of the solution curve (c₂ = 0) with thickness stretch `t`: the state and the
    /// nominal field E₀ ≥ 0 (V/m). Past the pull-in point (t below its) the curve goes on with a
    /// falling field: the states charge control reaches.
    pub fn on_curve(&self, t: f64) -> (FilmState, f64) {
        assert!(self.c2 == 0.0, "on_curve is derived for c2 = 0");
        (
            FilmState {
                lambda: self.lambda_of_t(t),
                t,
            },
            self.field_sq_of_t(t).max(0.0).sqrt(),
        )
    }

    /// The pull-in point: the largest field E₀ (V/m) with an equilibrium, and the state there
    /// (maximum of E₀(t) along the solution curve, c₂ = 0).
    pub fn pull_in(&self) -> (f64, FilmState) {
        assert!(self.c2 == 0.0, "pull_in is derived for c2 = 0");
        // golden-section search of the maximum of E₀(t)² on (0, 1)
        let (mut a, mut b) = (1e-3, 1.0);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let mut x1 = b - g * (b - a);
        let mut x2 = a + g * (b - a);
        let (mut f1, mut f2) = (self.field_sq_of_t(x1), self.field_sq_of_t(x2));
        while b - a > 1e-13 {
            if f1 < f2 {
                a = x1;
                x1 = x2;
                f1 = f2;
                x2 = a + g * (b - a);
                f2 = self.field_sq_of_t(x2);
            } else {
                b = x2;
                x2 = x1;
                f2 = f1;
                x1 = b - g * (b - a);
                f1 = self.field_sq_of_t(x1);
            }
        }
        let t = 0.5 * (a + b);
        (
            self.field_sq_of_t(t).sqrt(),
            FilmState {
                lambda: self.lambda_of_t(t),
                t,
            },
        )
    }

    /// The stable (pre-pull-in) state at field `e0` (V/m), or `None` beyond pull-in.
    pub fn state(&self, e0: f64) -> Option<FilmState> {
        if self.c2 == 0.0 {
            let (ec, sc) = self.pull_in();
            if e0.abs() > ec {
                return None;
            }
            // E₀(t) decreases monotonically from t_c to 1: bisection on t
            let target = e0 * e0;
            let (mut lo, mut hi) = (sc.t, 1.0);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if self.field_sq_of_t(mid) > target {
                    lo = mid;
                } else {
                    hi = mid;
                }
                if hi - lo < 1e-15 {
                    break;
                }
            }
            let t = 0.5 * (lo + hi);
            let mut s = FilmState {
                lambda: self.lambda_of_t(t),
                t,
            };
            self.polish(e0, &mut s);
            return Some(s);
        }
        // general case: Newton on both equations with continuation in the field
        let mut s = FilmState {
            lambda: 1.0,
            t: 1.0,
        };
        let n = 50;
        for k in 1..=n {
            let e = e0 * k as f64 / n as f64;
            if !self.polish(e, &mut s) {
                return None;
            }
        }
        Some(s)
    }

    /// Newton on the two equations from `s`; false when it does not converge.
    fn polish(&self, e0: f64, s: &mut FilmState) -> bool {
        for _ in 0..60 {
            let r = self.residuals(e0, *s);
            let h = 1e-7;
            let rl = self.residuals(
                e0,
                FilmState {
                    lambda: s.lambda + h,
                    t: s.t,
                },
            );
            let rt = self.residuals(
                e0,
                FilmState {
                    lambda: s.lambda,
                    t: s.t + h,
                },
            );
            let j = [
                [(rl[0] - r[0]) / h, (rt[0] - r[0]) / h],
                [(rl[1] - r[1]) / h, (rt[1] - r[1]) / h],
            ];
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if det == 0.0 || !det.is_finite() {
                return false;
            }
            let dl = (r[0] * j[1][1] - r[1] * j[0][1]) / det;
            let dt = (j[0][0] * r[1] - j[1][0] * r[0]) / det;
            s.lambda -= dl;
            s.t -= dt;
            if !(s.t > 0.0 && s.lambda > 0.0) {
                return false;
            }
            if dl.abs() < 1e-15 && dt.abs() < 1e-15 {
                return true;
            }
        }
        let r = self.residuals(e0, *s);
        r[0].abs().max(r[1].abs()) < 1e-9 * self.mu
    }
}

/// Normalised voltage Φ̂ of an incompressible equibiaxial neo-Hooke film at in-plane stretch λ.
pub fn incompressible_neo_hooke_voltage(lambda: f64) -> f64 {
    (lambda.powi(-2) - lambda.powi(-8)).max(0.0).sqrt()
}

/// Pull-in of the incompressible equibiaxial neo-Hooke film: λ_c = 2^(1/3), Φ̂_c = √(λ_c⁻² − λ_c⁻⁸).
pub fn incompressible_neo_hooke_pull_in() -> (f64, f64) {
    let l = 2f64.powf(1.0 / 3.0);
    (l, incompressible_neo_hooke_voltage(l))
}

/// Normalised voltage Φ̂ of an incompressible equibiaxial Gent film under nominal dead load `p`
/// (in units of μ); `None` where Φ̂² < 0 or beyond the locking stretch.
pub fn incompressible_gent_voltage(lambda: f64, jm: f64, p: f64) -> Option<f64> {
    let den = jm - 2.0 * lambda * lambda - lambda.powi(-4) + 3.0;
    if den <= 0.0 {
        return None;
    }
    let v2 = (jm * (lambda - lambda.powi(-5)) / den - p) / lambda.powi(3);
    (v2 >= 0.0).then(|| v2.sqrt())
}

/// The first local maximum of Φ̂(λ) of the Gent film (the pull-in point), as (λ, Φ̂).
pub fn incompressible_gent_pull_in(jm: f64, p: f64) -> Option<(f64, f64)> {
    let f = |l: f64| incompressible_gent_voltage(l, jm, p).unwrap_or(0.0);
    // march until Φ̂ decreases, then refine with golden section
    let dl = 1e-3;
    let mut l = 1.0;
    while f(l + dl) >= f(l) {
        l += dl;
        let den = jm - 2.0 * l * l - l.powi(-4) + 3.0;
        if den <= 0.0 {
            return None;
        }
    }
    let (mut a, mut b) = (l - dl, l + dl);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    while b - a > 1e-12 {
        let x1 = b - g * (b - a);
        let x2 = a + g * (b - a);
        if f(x1) < f(x2) {
            a = x1;
        } else {
            b = x2;
        }
    }
    let lc = 0.5 * (a + b);
    Some((lc, f(lc)))
}

/// Nominal uniaxial stress (Pa) of an incompressible material with neo-Hookean Maxwell branches
/// `(gᵢ, τᵢ)` (Pa, s) on an equilibrium energy W(I₁), under the stretch history `stretch(t)`,
/// at the times `at` (ascending). The branches follow Ȧᵢ = (C⁻¹ − Aᵢ)/τᵢ with
/// F = diag(λ, λ^(−1/2), λ^(−1/2)), Aᵢ = diag(a, b, b), and
/// P = 2W'(I₁)(λ − λ⁻²) + Σ gᵢ(λ aᵢ − bᵢ/λ²). Integrated by the classical Runge–Kutta method with
/// `steps_per_second` steps per second: the reference of the finite element path, independent of
/// it (no element, no incremental potential).
pub fn viscoelastic_uniaxial(
    w1: impl Fn(f64) -> f64,
    branches: &[(f64, f64)],
    stretch: impl Fn(f64) -> f64,
    at: &[f64],
    steps_per_second: f64,
) -> Vec<f64> {
    let n = branches.len();
    let rhs = |t: f64, a: &[f64]| -> Vec<f64> {
        let l = stretch(t);
        (0..n)
            .flat_map(|i| {
                let tau = branches[i].1;
                [(1.0 / (l * l) - a[2 * i]) / tau, (l - a[2 * i + 1]) / tau]
            })
            .collect()
    };
    let stress = |t: f64, a: &[f64]| -> f64 {
        let l = stretch(t);
        let i1 = l * l + 2.0 / l;
        let mut p = 2.0 * w1(i1) * (l - 1.0 / (l * l));
        for (i, &(g, _)) in branches.iter().enumerate() {
            p += g * (l * a[2 * i] - a[2 * i + 1] / (l * l));
        }
        p
    };
    let mut a = vec![1.0; 2 * n];
    let mut t = 0.0;
    let mut out = Vec::with_capacity(at.len());
    for &target in at {
        let steps = ((target - t) * steps_per_second).ceil().max(1.0) as usize;
        let h = (target - t) / steps as f64;
        for _ in 0..steps {
            let k1 = rhs(t, &a);
            let y2: Vec<f64> = a.iter().zip(&k1).map(|(y, k)| y + 0.5 * h * k).collect();
            let k2 = rhs(t + 0.5 * h, &y2);
            let y3: Vec<f64> = a.iter().zip(&k2).map(|(y, k)| y + 0.5 * h * k).collect();
            let k3 = rhs(t + 0.5 * h, &y3);
            let y4: Vec<f64> = a.iter().zip(&k3).map(|(y, k)| y + h * k).collect();
            let k4 = rhs(t + h, &y4);
            for j in 0..a.len() {
                a[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
            t += h;
        }
        t = target;
        out.push(stress(t, &a));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs()
    }

    /// Table of homogeneous film states (μ = 1, own computation): states to the 6 printed digits.
    #[test]
    fn film_table() {
        let cases = [
            (100.0, 1.0, 0.0, 0.2, 1.006946, 0.986316),
            (100.0, 1.0, 0.0, 0.4, 1.031685, 0.939765),
            (100.0, 1.0, 0.0, 0.6, 1.100194, 0.826595),
            (1000.0, 1.0, 0.0, 0.4, 1.031607, 0.939686),
            (10.0, 0.0, 0.05, 1.0, 1.014989, 0.967754),
            (10.0, 0.0, 0.10, 1.0, 1.028844, 0.939202),
        ];
        for (lambda, eps, c2, e0, l, t) in cases {
            let film = Film {
                mu: 1.0,
                lambda,
                eps,
                c2,
            };
            let s = film.state(e0).expect("below pull-in");
            assert!(
                (s.lambda - l).abs() < 1e-6,
                "{lambda} {e0}: λ {} vs {l}",
                s.lambda
            );
            assert!((s.t - t).abs() < 1e-6, "{lambda} {e0}: t {} vs {t}", s.t);
        }
    }

    /// The `film` example: pull-in at 33.695 kV (λ = 1.2597, t = 0.6302), 20 kV state.
    #[test]
    fn film_example_numbers() {
        let film = Film {
            mu: 1e5,
            lambda: 1e7,
            eps: 4.7 * crate::material::EPSILON_0,
            c2: 0.0,
        };
        let h = 1e-3;
        let (ec, sc) = film.pull_in();
        assert!(rel(ec * h, 33.695e3) < 2e-5, "{}", ec * h);
        assert!((sc.lambda - 1.2597).abs() < 1e-4 && (sc.t - 0.6302).abs() < 1e-4);
        let s = film.state(20e3 / h).unwrap();
        assert!((s.lambda - 1.033231).abs() < 1e-6 && (s.t - 0.936966).abs() < 1e-6);
        assert!(film.state(34e3 / h).is_none());
    }

    /// Zhao & Suo, APL 91 (2007) 061921: pull-in values.
    #[test]
    fn incompressible_pull_in_values() {
        let (l, v) = incompressible_neo_hooke_pull_in();
        assert!((l - 1.259921).abs() < 1e-6 && (v - 0.687365).abs() < 1e-6);
        for (jm, p, l_ref, v_ref) in [
            (100.0, 0.0, 1.26380, 0.68936),
            (120.0, 0.0, 1.26314, 0.68903),
            (100.0, 1.0, 1.78124, 0.37318),
        ] {
            let (l, v) = incompressible_gent_pull_in(jm, p).unwrap();
            assert!((l - l_ref).abs() < 1e-5, "{jm} {p}: {l}");
            assert!((v - v_ref).abs() < 1e-5, "{jm} {p}: {v}");
        }
    }
}
