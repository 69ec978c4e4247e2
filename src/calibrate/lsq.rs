//! Bounded nonlinear least squares over residual blocks with their exact Jacobians, and the
//! Gauss–Newton statistics of the fitted parameters.
//!
//! This is the seam between what is fitted and how: anything that gives, for the fitted
//! parameters θ, blocks of weighted residuals (Pa) with their Jacobians ∂r/∂θ — the material
//! point's paths here, a finite element run with its adjoint or forward sensitivities later —
//! is fitted by [`fit`].
//!
//! # The method
//!
//! Levenberg–Marquardt (Levenberg 1944; Marquardt 1963) with Marquardt's diagonal scaling as in
//! Moré (1978), stepping in the scaled variables z (z = θ, or z = ln θ for a log-scaled
//! parameter) inside the box of the bounds: a variable at a bound whose gradient points out of
//! the box is held (the active set), the step of the others is projected onto the box, and the
//! step is accepted when the sum of squares falls (gain ratio against the linear model of the
//! projected step; damping updated as Nielsen 1999). A small solver of our own, because the
//! `levenberg-marquardt` crate has no bounds and the problems are small (a few to a few dozen
//! parameters, a few hundred residuals): the normal equations are solved densely.

use super::spec::{FitOptions, FitParameter};
use nalgebra::{DMatrix, DVector};

/// A block of weighted residuals (Pa) and their Jacobian in the fitted parameters θ (one row per
/// residual, one column per fitted parameter).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Block {
    /// The experiment (or objective) the block measures.
    pub name: String,
    pub residuals: Vec<f64>,
    /// Row-major, `residuals.len()` × n.
    pub jacobian: Vec<f64>,
}

/// Why a fit stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stop {
    /// The residuals are zero (to round-off).
    ZeroResidual,
    /// The projected gradient, relative to the residual's and the columns' norms, fell below
    /// `gtol`.
    Gradient,
    /// An accepted step lowered the sum of squares by less than `ftol` relatively; or no step
    /// lowers it (round-off of the residuals) and the undamped Gauss–Newton step predicts a
    /// reduction below `ftol`.
    Reduction,
    /// The step in the scaled variables fell below `xtol` relatively; or no step lowers the
    /// sum of squares (round-off of the residuals) and the undamped Gauss–Newton step is below
    /// it.
    Step,
    /// `max_iterations` reached.
    MaxIterations,
    /// No step lowers the sum of squares any more (the damping grew without bound).
    NoProgress,
}

impl Stop {
    /// Whether the stop is a convergence.
    pub fn converged(self) -> bool {
        !matches!(self, Stop::MaxIterations | Stop::NoProgress)
    }
    /// What it means, for a report.
    pub fn describe(self) -> &'static str {
        match self {
            Stop::ZeroResidual => "the residuals vanish",
            Stop::Gradient => "the projected gradient is below gtol",
            Stop::Reduction => "the relative reduction of the sum of squares is below ftol",
            Stop::Step => "the relative step is below xtol",
            Stop::MaxIterations => "the iteration limit was reached",
            Stop::NoProgress => "no step lowers the sum of squares any more",
        }
    }
}

/// The outcome of [`fit`].
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The fitted parameters θ.
    pub theta: Vec<f64>,
    /// The blocks at θ.
    pub blocks: Vec<Block>,
    /// Sum of squared residuals.
    pub ssr: f64,
    /// Iterations (of the best start).
    pub iterations: usize,
    pub stop: Stop,
    /// The start (0: the given values) that gave the result.
    pub start: usize,
}

/// The residual blocks and Jacobians at θ (`Err`: the model cannot be evaluated there, e.g. a
/// locking stretch passed; the fit then shortens its step).
pub type Evaluate<'a> = dyn FnMut(&[f64]) -> Result<Vec<Block>, String> + 'a;

struct Point {
    z: Vec<f64>,
    r: DVector<f64>,
    /// ∂r/∂z.
    j: DMatrix<f64>,
    blocks: Vec<Block>,
    cost: f64,
}

fn point(eval: &mut Evaluate, params: &[FitParameter], z: &[f64]) -> Result<Point, String> {
    let n = params.len();
    let theta: Vec<f64> = params.iter().zip(z).map(|(p, &z)| p.to_theta(z)).collect();
    let blocks = eval(&theta)?;
    let m: usize = blocks.iter().map(|b| b.residuals.len()).sum();
    let mut r = DVector::zeros(m);
    let mut j = DMatrix::zeros(m, n);
    let mut row = 0;
    for b in &blocks {
        if b.jacobian.len() != b.residuals.len() * n {
            return Err(format!(
                "block `{}`: a Jacobian of {} entries for {} residuals and {n} parameters",
                b.name,
                b.jacobian.len(),
                b.residuals.len()
            ));
        }
        for (i, &x) in b.residuals.iter().enumerate() {
            r[row] = x;
            for k in 0..n {
                j[(row, k)] = b.jacobian[i * n + k] * params[k].dtheta_dz(theta[k]);
            }
            row += 1;
        }
    }
    if r.iter().chain(j.iter()).any(|x| !x.is_finite()) {
        return Err("non-finite residual or Jacobian".into());
    }
    let cost = 0.5 * r.norm_squared();
    Ok(Point {
        z: z.to_vec(),
        r,
        j,
        blocks,
        cost,
    })
}

/// Fits the parameters `params` (starting values, bounds, scales) to the residuals of `eval`;
/// with `options.starts` > 1 the further starts are spread over the box (a fixed low-discrepancy
/// sequence in z) and the best result is kept.
pub fn fit(
    eval: &mut Evaluate,
    params: &[FitParameter],
    options: &FitOptions,
) -> Result<Fitted, String> {
    let lo: Vec<f64> = params.iter().map(|p| p.to_z(p.lower)).collect();
    let hi: Vec<f64> = params.iter().map(|p| p.to_z(p.upper)).collect();
    let mut best: Option<Fitted> = None;
    let mut first_error = None;
    for s in 0..options.starts {
        let z0: Vec<f64> = if s == 0 {
            params.iter().map(|p| p.to_z(p.initial)).collect()
        } else {
            (0..params.len())
                .map(|k| lo[k] + (hi[k] - lo[k]) * van_der_corput(s, PRIMES[k % PRIMES.len()]))
                .collect()
        };
        match one_start(eval, params, &lo, &hi, z0, options) {
            Ok(mut f) => {
                f.start = s;
                if best.as_ref().is_none_or(|b| f.ssr < b.ssr) {
                    best = Some(f);
                }
            }
            Err(e) => {
                if first_error.is_none() {
                    first_error = Some(format!("start {}: {e}", s + 1));
                }
            }
        }
    }
    best.ok_or_else(|| first_error.unwrap_or_else(|| "no start".into()))
}

const PRIMES: [usize; 12] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37];

/// The radical inverse of `i` in base `b` (in (0, 1) for i ≥ 1).
fn van_der_corput(mut i: usize, b: usize) -> f64 {
    let (mut x, mut f) = (0.0, 1.0 / b as f64);
    while i > 0 {
        x += (i % b) as f64 * f;
        i /= b;
        f /= b as f64;
    }
    x
}

fn one_start(
    eval: &mut Evaluate,
    params: &[FitParameter],
    lo: &[f64],
    hi: &[f64],
    z0: Vec<f64>,
    o: &FitOptions,
) -> Result<Fitted, String> {
    let n = params.len();
    let mut p = point(eval, params, &z0)?;
    let mut mu: f64 = 1e-3;
    let mut nu: f64 = 2.0;
    let mut iterations = 0;
    let stop = loop {
        if p.cost <= f64::MIN_POSITIVE || p.r.norm() == 0.0 {
            break Stop::ZeroResidual;
        }
        let g = p.j.tr_mul(&p.r);
        let jtj = p.j.tr_mul(&p.j);
        // active set: at a bound with the descent direction −g leaving the box
        let tol = |k: usize| 1e-12 * (hi[k] - lo[k]);
        let free: Vec<usize> = (0..n)
            .filter(|&k| {
                !((p.z[k] <= lo[k] + tol(k) && g[k] > 0.0)
                    || (p.z[k] >= hi[k] - tol(k) && g[k] < 0.0))
            })
            .collect();
        let rnorm = p.r.norm();
        let gmax = free
            .iter()
            .map(|&k| {
                let c = jtj[(k, k)].sqrt();
                if c > 0.0 {
                    g[k].abs() / (c * rnorm)
                } else {
                    0.0
                }
            })
            .fold(0.0, f64::max);
        if free.is_empty() || gmax <= o.gtol {
            break Stop::Gradient;
        }
        if iterations >= o.max_iterations {
            break Stop::MaxIterations;
        }
        iterations += 1;
        let diag_max = free.iter().map(|&k| jtj[(k, k)]).fold(0.0, f64::max);
        if mu < 0.0 {
            mu = 1e-3;
        }
        let mut accepted = None;
        while mu.is_finite() && mu < 1e32 {
            let nf = free.len();
            let mut a = DMatrix::zeros(nf, nf);
            let mut b = DVector::zeros(nf);
            for (x, &i) in free.iter().enumerate() {
                b[x] = -g[i];
                for (y, &k) in free.iter().enumerate() {
                    a[(x, y)] = jtj[(i, k)];
                }
                a[(x, x)] += mu * jtj[(i, i)].max(1e-12 * diag_max).max(f64::MIN_POSITIVE);
            }
            let Some(d) = a.cholesky().map(|c| c.solve(&b)) else {
                mu *= nu;
                nu *= 2.0;
                continue;
            };
            let mut z = p.z.clone();
            for (x, &i) in free.iter().enumerate() {
                z[i] = (z[i] + d[x]).clamp(lo[i], hi[i]);
            }
            let dz = DVector::from_iterator(n, (0..n).map(|k| z[k] - p.z[k]));
            let predicted = p.cost - 0.5 * (&p.r + &p.j * &dz).norm_squared();
            let trial = point(eval, params, &z);
            let Ok(t) = trial else {
                mu *= nu;
                nu *= 2.0;
                continue;
            };
            let actual = p.cost - t.cost;
            let rho = if predicted > 0.0 {
                actual / predicted
            } else {
                -1.0
            };
            if actual > 0.0 && rho > 1e-4 {
                mu *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                nu = 2.0;
                accepted = Some((t, dz, actual));
                break;
            }
            mu *= nu;
            nu *= 2.0;
        }
        // the step's size against the point's, each variable scaled by its column norm
        let scaled = |v: &[f64]| -> f64 {
            (0..n)
                .map(|k| (jtj[(k, k)].sqrt() * v[k]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let Some((t, dz, actual)) = accepted else {
            // At the optimum of residuals computed to round-off (a model run converged to its
            // Newton tolerance), no step lowers the cost: a converged fit when the undamped
            // Gauss–Newton step is itself below xtol, or when the reduction it predicts is
            // below ftol (MINPACK's test on the predicted reduction; at a flat optimum the
            // step may be large and still lower nothing that the residuals resolve).
            let Some(d) = gauss_newton_step(&jtj, &g, &free, n) else {
                break Stop::NoProgress;
            };
            let dz = DVector::from_column_slice(&d);
            let predicted = p.cost - 0.5 * (&p.r + &p.j * &dz).norm_squared();
            break if scaled(&d) <= o.xtol * (scaled(&p.z) + o.xtol) {
                Stop::Step
            } else if predicted <= o.ftol * p.cost {
                Stop::Reduction
            } else {
                Stop::NoProgress
            };
        };
        let step = scaled(dz.as_slice());
        let size = scaled(&t.z);
        let old_cost = p.cost;
        p = t;
        if actual <= o.ftol * old_cost {
            break Stop::Reduction;
        }
        if step <= o.xtol * (size + o.xtol) {
            break Stop::Step;
        }
    };
    let theta = params
        .iter()
        .zip(&p.z)
        .map(|(q, &z)| q.to_theta(z))
        .collect();
    Ok(Fitted {
        theta,
        ssr: 2.0 * p.cost,
        blocks: p.blocks,
        iterations,
        stop,
        start: 0,
    })
}

/// The undamped Gauss–Newton step −(JᵀJ)⁻¹g on the `free` variables (0 on the others); `None`
/// where JᵀJ is singular there.
fn gauss_newton_step(
    jtj: &DMatrix<f64>,
    g: &DVector<f64>,
    free: &[usize],
    n: usize,
) -> Option<Vec<f64>> {
    let a = DMatrix::from_fn(free.len(), free.len(), |x, y| jtj[(free[x], free[y])]);
    let b = DVector::from_fn(free.len(), |x, _| -g[free[x]]);
    let d = a.cholesky()?.solve(&b);
    let mut out = vec![0.0; n];
    for (x, &i) in free.iter().enumerate() {
        out[i] = d[x];
    }
    Some(out)
}

/// Gauss–Newton statistics of a least-squares fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Statistics {
    /// s² = SSR/(m − n) (Pa²).
    pub variance: f64,
    /// Degrees of freedom m − n.
    pub dof: usize,
    /// Standard errors of θ (parameter units).
    pub std_error: Vec<f64>,
    /// 95 % confidence intervals of θ: symmetric θ ± q·SE for a linear parameter,
    /// θ·exp(±q·SE(ln θ)) for a log-scaled one.
    pub ci95: Vec<[f64; 2]>,
    /// The quantile q used (Student's t with m − n degrees of freedom).
    pub quantile: f64,
    /// Correlation matrix of θ.
    pub correlation: Vec<Vec<f64>>,
    /// Numerical rank of J and n.
    pub rank: usize,
    /// Warnings naming parameters: an interval reaching a bound, |correlation| > 0.99, J rank
    /// deficient.
    pub warnings: Vec<String>,
}

/// The two-sided 95 % quantile of Student's t with `dof` degrees of freedom: a table to 30,
/// the Cornish–Fisher expansion about the normal 1.959964 beyond (error < 1e-4).
pub fn t_quantile_975(dof: usize) -> f64 {
    const TABLE: [f64; 30] = [
        12.7062, 4.3027, 3.1824, 2.7764, 2.5706, 2.4469, 2.3646, 2.3060, 2.2622, 2.2281, 2.2010,
        2.1788, 2.1604, 2.1448, 2.1314, 2.1199, 2.1098, 2.1009, 2.0930, 2.0860, 2.0796, 2.0739,
        2.0687, 2.0639, 2.0595, 2.0555, 2.0518, 2.0484, 2.0452, 2.0423,
    ];
    if dof == 0 {
        return f64::INFINITY;
    }
    if dof <= 30 {
        return TABLE[dof - 1];
    }
    let z: f64 = 1.959963985;
    let v = dof as f64;
    z + (z.powi(3) + z) / (4.0 * v)
        + (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / (96.0 * v * v)
}

/// The statistics of `fitted`: the Jacobian in z of its blocks, the covariance s²(JᵀJ)⁻¹ (a
/// pseudo-inverse when J is rank deficient, with a warning), standard errors, intervals and
/// correlations, mapped to θ.
pub fn statistics(fitted: &Fitted, params: &[FitParameter]) -> Statistics {
    let n = params.len();
    let m: usize = fitted.blocks.iter().map(|b| b.residuals.len()).sum();
    let mut j = DMatrix::zeros(m, n);
    let mut row = 0;
    for b in &fitted.blocks {
        for i in 0..b.residuals.len() {
            for k in 0..n {
                j[(row, k)] = b.jacobian[i * n + k] * params[k].dtheta_dz(fitted.theta[k]);
            }
            row += 1;
        }
    }
    let dof = m.saturating_sub(n);
    let variance = if dof > 0 {
        fitted.ssr / dof as f64
    } else {
        f64::NAN
    };
    // column-scale for the rank test (units differ)
    let scale: Vec<f64> = (0..n)
        .map(|k| {
            let c = j.column(k).norm();
            if c > 0.0 {
                c
            } else {
                1.0
            }
        })
        .collect();
    let mut js = j.clone();
    for k in 0..n {
        js.column_mut(k).scale_mut(1.0 / scale[k]);
    }
    let svd = js.svd(false, true);
    let smax = svd.singular_values.max();
    let cut = 1e-10 * smax.max(f64::MIN_POSITIVE);
    let vt = svd.v_t.expect("V requested");
    let mut cov = DMatrix::zeros(n, n);
    let mut rank = 0;
    let mut null = Vec::new();
    for (i, &s) in svd.singular_values.iter().enumerate() {
        let v = vt.row(i).transpose();
        if s > cut {
            rank += 1;
            cov += &v * v.transpose() / (s * s);
        } else {
            null.push(v);
        }
    }
    for a in 0..n {
        for b in 0..n {
            cov[(a, b)] *= variance / (scale[a] * scale[b]);
        }
    }
    let quantile = t_quantile_975(dof);
    let mut warnings = Vec::new();
    let sd_z: Vec<f64> = (0..n).map(|k| cov[(k, k)].max(0.0).sqrt()).collect();
    let mut std_error = Vec::new();
    let mut ci95 = Vec::new();
    for (k, p) in params.iter().enumerate() {
        let th = fitted.theta[k];
        std_error.push(sd_z[k] * p.dtheta_dz(th).abs());
        let ci = match p.scale {
            super::spec::Scale::Linear => [th - quantile * sd_z[k], th + quantile * sd_z[k]],
            super::spec::Scale::Log => [
                th * (-quantile * sd_z[k]).exp(),
                th * (quantile * sd_z[k]).exp(),
            ],
        };
        if ci[0] <= p.lower || ci[1] >= p.upper {
            warnings.push(format!(
                "`{}`: the 95 % interval [{:.6e}, {:.6e}] reaches its bounds [{:.6e}, {:.6e}]: \
                 the data do not pin it inside the box",
                p.path, ci[0], ci[1], p.lower, p.upper
            ));
        }
        ci95.push(ci);
    }
    let mut correlation = vec![vec![0.0; n]; n];
    for a in 0..n {
        for b in 0..n {
            let d = sd_z[a] * sd_z[b];
            correlation[a][b] = if a == b {
                1.0
            } else if d > 0.0 {
                cov[(a, b)] / d
            } else {
                0.0
            };
        }
    }
    for a in 0..n {
        for b in a + 1..n {
            if correlation[a][b].abs() > 0.99 {
                warnings.push(format!(
                    "`{}` and `{}` are correlated ({:+.4}): the data determine a combination of \
                     the two better than each",
                    params[a].path, params[b].path, correlation[a][b]
                ));
            }
        }
    }
    if rank < n {
        for v in &null {
            let names: Vec<&str> = (0..n)
                .filter(|&k| v[k].abs() > 0.1)
                .map(|k| params[k].path.as_str())
                .collect();
            warnings.push(format!(
                "the Jacobian is rank deficient (rank {rank} of {n}): the data do not determine \
                 {} (their covariance is a pseudo-inverse's)",
                names
                    .iter()
                    .map(|s| format!("`{s}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    Statistics {
        variance,
        dof,
        std_error,
        ci95,
        quantile,
        correlation,
        rank,
        warnings,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::spec::Scale;

    /// Residuals (θ − 2)·xᵢ + c·yᵢ whose first term is computed to a resolution of 10⁻⁹
    /// (as a model run converged to its tolerance resolves its probes), with c·y a misfit of
    /// 10⁻¹³ that no θ removes: from θ = 1 the fit's last accepted step lands near θ = 2, and
    /// no step lowers the cost from there. It has converged (its Gauss–Newton step, about
    /// 10⁻¹⁴, is below xtol), not stalled.
    #[test]
    fn a_fit_to_round_off_stops_converged() {
        let q = 1e-9;
        let xs: Vec<f64> = (0..20).map(|i| 1.0 + 0.05 * i as f64).collect();
        let ys: Vec<f64> = (0..20)
            .map(|i| if i % 2 == 0 { 1.3 } else { -0.9 })
            .collect();
        let mut eval = |theta: &[f64]| -> Result<Vec<Block>, String> {
            let resolved = q * ((theta[0] - 2.0) / q).round();
            Ok(vec![Block {
                name: "line".into(),
                residuals: xs
                    .iter()
                    .zip(&ys)
                    .map(|(x, y)| resolved * x + 1e-13 * y)
                    .collect(),
                jacobian: xs.clone(),
            }])
        };
        let params = [FitParameter {
            path: "slope".into(),
            index: 0,
            initial: 1.0,
            lower: 0.0,
            upper: 10.0,
            scale: Scale::Linear,
        }];
        let options = FitOptions {
            ftol: 0.0,
            gtol: 0.0,
            ..FitOptions::default()
        };
        let f = fit(&mut eval, &params, &options).unwrap();
        assert_eq!(f.stop, Stop::Step, "{}", f.stop.describe());
        assert!(f.stop.converged());
        assert!((f.theta[0] - 2.0).abs() < q, "{}", f.theta[0]);
        // with no step tolerance, the same stall: converged where the Gauss–Newton step's
        // predicted reduction (2.6 % of the cost: the misfit is nearly orthogonal to x) is
        // below ftol, a stall where it is not
        for (ftol, stop) in [(0.05, Stop::Reduction), (0.01, Stop::NoProgress)] {
            let options = FitOptions {
                ftol,
                gtol: 0.0,
                xtol: 0.0,
                ..FitOptions::default()
            };
            let f = fit(&mut eval, &params, &options).unwrap();
            assert_eq!(f.stop, stop, "ftol {ftol}: {}", f.stop.describe());
            assert!((f.theta[0] - 2.0).abs() < q, "{}", f.theta[0]);
        }
    }
}
