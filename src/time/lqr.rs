//! A sampled linear-quadratic state-feedback design on a reduced model
//! ([`crate::time::reduced::ReducedModel`]): the zero-order-hold discretisation of (A, B), the
//! LQR gain K, a steady-state Kalman observer gain L for the measured outputs and the reference
//! gains that make a set point the steady state. The state-feedback controller
//! ([`crate::job::state_feedback`]) runs the law it defines.
//!
//! With ṽ the voltage about the bias and y₁ the tracked output, g₁ its static gain (output per
//! volt at ω = 0), the controller minimises
//!
//! ```text
//! J = Σ_k  q (C₁ z_k / g₁)² + r ṽ_k²
//! ```
//!
//! over the sampled model z_{k+1} = A_d z_k + B_d ṽ_k: the output's change is counted in the volts
//! that would hold it statically, so q/r is a dimensionless ratio (q/r = 1: an output error worth
//! one volt costs as much as one volt of drive). With integral action (q_I > 0) the state grows by
//! the integrated tracking error ξ_{k+1} = ξ_k + T C₁ z_k (the feed-through D₁ left out) and J by
//! q_I (ξ_k / g₁)²: q_I/q is the square of the integrator's corner frequency (rad/s). The observer takes a white voltage disturbance of
//! variance w (V²) on the drive (process noise W = w B_d B_dᵀ) and, on each measured output i,
//! white noise of variance v g_i² (v in V²: noise equal to the response of a voltage of variance
//! v). Both gains come from the discrete algebraic Riccati equation ([`super::riccati`]); the
//! observer is the current estimator of Franklin, Powell & Workman, "Digital Control of Dynamic
//! Systems" (3rd ed., 1998), §8.2, and the reference gains (N_x, N_u) their §8.4.

use super::reduced::ReducedModel;
use super::riccati::{dare_residual, feedback_gain, solve_dare, spectral_radius};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// The weights of the design (see the module's cost).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Weights {
    /// Weight of the tracked output's change, counted in volts of static drive (> 0).
    pub q: f64,
    /// Weight of the drive's change about the bias, per V² (> 0).
    pub r: f64,
    /// Variance of the voltage disturbance the observer expects on the drive (V², > 0).
    pub w: f64,
    /// Variance of each measured output's noise, in V² of static drive (> 0).
    pub v: f64,
    /// Weight of the tracking error's time integral, counted in V·s of static drive, per s²
    /// (≥ 0; 0: no integral action).
    #[serde(default)]
    pub qi: f64,
}

/// What to design: the weights, the sample period, the tracked output and the measured ones
/// (names of the model's outputs; empty `measured`: the tracked one alone).
#[derive(Debug, Clone, PartialEq)]
pub struct LqrSettings {
    pub weights: Weights,
    pub sample_time: f64,
    pub tracked: String,
    pub measured: Vec<String>,
}

/// A state-feedback design on a reduced model: what `deasim reduce --lqr` writes (`lqr.json`) and
/// the state-feedback controller reads. Matrices are row-major; z is the reduced state about the
/// bias, ṽ the voltage about it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StateFeedbackDesign {
    /// The scenario the model was reduced from.
    pub scenario: String,
    /// The driven electrode and its bias (V).
    pub electrode: String,
    pub bias_v: f64,
    /// The sample period T (s).
    pub sample_time: f64,
    /// The natural frequencies of the model's modes (Hz).
    pub frequencies_hz: Vec<f64>,
    /// The rows of `c`, `d`, `output_offsets` and `static_gains`: the tracked output first, then
    /// the other measured outputs.
    pub outputs: Vec<String>,
    /// The output whose set point the controller follows (`outputs[0]`).
    pub tracked: String,
    /// The outputs the observer reads (probe names).
    pub measured: Vec<String>,
    /// The outputs' values at the biased state (their unit).
    pub output_offsets: Vec<f64>,
    /// The outputs' static change per volt about the bias (unit per V).
    pub static_gains: Vec<f64>,
    pub weights: Weights,
    /// z_{k+1} = A_d z_k + B_d ṽ_k (n × n, n × 1).
    pub ad: Vec<Vec<f64>>,
    pub bd: Vec<Vec<f64>>,
    /// y = C z + D ṽ for the rows of `outputs` (p × n, p × 1).
    pub c: Vec<Vec<f64>>,
    pub d: Vec<Vec<f64>>,
    /// The state-feedback gain (1 × n, V per state unit): ṽ = −K ẑ − k_I ξ + N̄ r̃.
    pub k: Vec<Vec<f64>>,
    /// The gain on the integrated tracking error ξ (V per output unit·s; 0 without integral
    /// action).
    #[serde(default)]
    pub k_i: f64,
    /// The observer gain (n × m for the m measured outputs): ẑ = z̄ + L (ỹ − C z̄).
    pub l: Vec<Vec<f64>>,
    /// The steady state and drive per unit of the tracked output's set point about its offset:
    /// z = N_x r̃, ṽ = N_u r̃; N̄ = N_u + K N_x (V per output unit).
    pub nx: Vec<f64>,
    pub nu: f64,
    pub n_bar: f64,
    /// Spectral radii of A_d (open loop), A_d − B_d K (the state feedback, with the integrator
    /// when there is one) and (I − L C) A_d (the observer's error).
    pub open_loop_radius: f64,
    pub closed_loop_radius: f64,
    pub observer_radius: f64,
    /// The Riccati residuals ‖X − (AᵀXA − … + Q)‖ / ‖X‖ of the control and filter equations.
    pub control_residual: f64,
    pub filter_residual: f64,
}

/// The sampled design for `model` (from scenario `scenario`) with `settings`.
pub fn design(
    model: &ReducedModel,
    scenario: &str,
    settings: &LqrSettings,
) -> Result<StateFeedbackDesign, String> {
    let Weights { q, r, w, v, qi } = settings.weights;
    for (name, x) in [("q", q), ("r", r), ("w", w), ("v", v)] {
        if !(x.is_finite() && x > 0.0) {
            return Err(format!(
                "weight {name}: expected a positive number; got {x}"
            ));
        }
    }
    if !(qi.is_finite() && qi >= 0.0) {
        return Err(format!("integral weight: expected a number ≥ 0; got {qi}"));
    }
    let t = settings.sample_time;
    if !(t.is_finite() && t > 0.0) {
        return Err(format!(
            "sample time: expected a positive number of s; got {t}"
        ));
    }
    let n = model.a.len();
    let a = DMatrix::from_fn(n, n, |i, j| model.a[i][j]);
    let b = DMatrix::from_fn(n, 1, |i, _| model.b[i][0]);
    let row = |name: &str| -> Result<usize, String> {
        let k = model
            .outputs
            .iter()
            .position(|o| o == name)
            .ok_or_else(|| {
                format!(
                    "output `{name}` is not one of the model's ({})",
                    model.outputs.join(", ")
                )
            })?;
        let finite = model.c[k].iter().all(|x| x.is_finite())
            && model.d[k][0].is_finite()
            && model.output_offsets[k].is_finite();
        if !finite {
            return Err(format!(
                "output `{name}` has no linearisation at the bias (not a number): choose another"
            ));
        }
        Ok(k)
    };
    let tracked = row(&settings.tracked)?;
    let mut rows = vec![tracked];
    for m in &settings.measured {
        let k = row(m)?;
        if !rows.contains(&k) {
            rows.push(k);
        }
    }
    let measured: Vec<usize> = if settings.measured.is_empty() {
        vec![tracked]
    } else {
        settings
            .measured
            .iter()
            .map(|m| row(m))
            .collect::<Result<_, _>>()?
    };
    let p = rows.len();
    let c = DMatrix::from_fn(p, n, |i, j| model.c[rows[i]][j]);
    let d = DVector::from_fn(p, |i, _| model.d[rows[i]][0]);
    // static gains g = D − C A⁻¹ B
    let a_inv_b = a
        .clone()
        .lu()
        .solve(&b)
        .ok_or("the model's A is singular (a rigid mode): no static gain")?;
    let gains: Vec<f64> = (0..p)
        .map(|i| d[i] - (c.row(i) * &a_inv_b)[(0, 0)])
        .collect();
    for (i, g) in gains.iter().enumerate() {
        if !(g.is_finite() && g.abs() > 0.0) {
            return Err(format!(
                "output `{}` has no static response to the drive: it cannot be {}",
                model.outputs[rows[i]],
                if i == 0 { "tracked" } else { "measured" }
            ));
        }
    }
    // zero-order hold: exp([[A, B], [0, 0]] T) = [[A_d, B_d], [0, I]]
    let mut aug = DMatrix::<f64>::zeros(n + 1, n + 1);
    aug.view_mut((0, 0), (n, n)).copy_from(&(&a * t));
    aug.view_mut((0, n), (n, 1)).copy_from(&(&b * t));
    let e = aug.exp();
    let ad = e.view((0, 0), (n, n)).into_owned();
    let bd = e.view((0, n), (n, 1)).into_owned();
    if !(ad.iter().chain(bd.iter()).all(|x| x.is_finite())) {
        return Err("the sampled model is not finite (the matrix exponential overflowed)".into());
    }
    // the controller: Q = q/g₁² C₁ᵀC₁, R = r; with integral action on [z; ξ],
    // ξ_{k+1} = ξ_k + T C₁ z_k, Q adds q_I/g₁² on ξ
    let c1 = c.rows(0, 1).into_owned();
    let integral = qi > 0.0;
    if integral && !measured.contains(&tracked) {
        return Err(format!(
            "integral action integrates the measured error of `{}`: measure it too",
            model.outputs[tracked]
        ));
    }
    let na = n + usize::from(integral);
    let mut aa = DMatrix::<f64>::zeros(na, na);
    aa.view_mut((0, 0), (n, n)).copy_from(&ad);
    let mut ba = DMatrix::<f64>::zeros(na, 1);
    ba.view_mut((0, 0), (n, 1)).copy_from(&bd);
    let mut qm = DMatrix::<f64>::zeros(na, na);
    qm.view_mut((0, 0), (n, n))
        .copy_from(&(c1.transpose() * &c1 * (q / (gains[0] * gains[0]))));
    if integral {
        aa.view_mut((n, 0), (1, n)).copy_from(&(&c1 * t));
        aa[(n, n)] = 1.0;
        qm[(n, n)] = qi / (gains[0] * gains[0]);
    }
    let rm = DMatrix::from_element(1, 1, r);
    let x = solve_dare(&aa, &ba, &qm, &rm).map_err(|e| format!("the control {e}"))?;
    let control_residual = relative(&dare_residual(&aa, &ba, &qm, &rm, &x), &x);
    let k_aug = feedback_gain(&aa, &ba, &rm, &x)?;
    let k = k_aug.columns(0, n).into_owned();
    let k_i = if integral { k_aug[(0, n)] } else { 0.0 };
    // the observer: the dual equation with W = w B_d B_dᵀ, V = v diag(g_i²)
    let m = measured.len();
    let cm = DMatrix::from_fn(m, n, |i, j| model.c[measured[i]][j]);
    let measured_gain = |i: usize| gains[rows.iter().position(|&r| r == measured[i]).unwrap()];
    let wm = &bd * bd.transpose() * w;
    let vm = DMatrix::from_fn(m, m, |i, j| {
        if i == j {
            v * measured_gain(i).powi(2)
        } else {
            0.0
        }
    });
    let adt = ad.transpose();
    let cmt = cm.transpose();
    let pcov = solve_dare(&adt, &cmt, &wm, &vm).map_err(|e| format!("the observer's {e}"))?;
    let filter_residual = relative(&dare_residual(&adt, &cmt, &wm, &vm, &pcov), &pcov);
    // the current estimator's gain L = P Cᵀ (C P Cᵀ + V)⁻¹
    let l = (&cm * &pcov * &cmt + &vm)
        .lu()
        .solve(&(&cm * &pcov))
        .ok_or("the observer gain: C P Cᵀ + V is singular")?
        .transpose();
    // reference gains: [[A_d − I, B_d], [C₁, D₁]] [N_x; N_u] = [0; 1]
    let mut big = DMatrix::<f64>::zeros(n + 1, n + 1);
    big.view_mut((0, 0), (n, n))
        .copy_from(&(&ad - DMatrix::identity(n, n)));
    big.view_mut((0, n), (n, 1)).copy_from(&bd);
    big.view_mut((n, 0), (1, n)).copy_from(&c1);
    big[(n, n)] = d[0];
    let mut rhs = DVector::<f64>::zeros(n + 1);
    rhs[n] = 1.0;
    let sol = big
        .lu()
        .solve(&rhs)
        .ok_or("the reference gains: the tracked output has no steady state per set point")?;
    let nx: Vec<f64> = sol.rows(0, n).iter().copied().collect();
    let nu = sol[n];
    let n_bar = nu + (&k * sol.rows(0, n))[(0, 0)];
    let observer = (DMatrix::identity(n, n) - &l * &cm) * &ad;
    let rows_of = |m: &DMatrix<f64>| -> Vec<Vec<f64>> {
        (0..m.nrows())
            .map(|i| m.row(i).iter().copied().collect())
            .collect()
    };
    Ok(StateFeedbackDesign {
        scenario: scenario.to_string(),
        electrode: model.electrode.clone(),
        bias_v: model.bias_v,
        sample_time: t,
        frequencies_hz: model.frequencies_hz.clone(),
        outputs: rows.iter().map(|&i| model.outputs[i].clone()).collect(),
        tracked: model.outputs[tracked].clone(),
        measured: measured.iter().map(|&i| model.outputs[i].clone()).collect(),
        output_offsets: rows.iter().map(|&i| model.output_offsets[i]).collect(),
        static_gains: gains,
        weights: settings.weights,
        open_loop_radius: spectral_radius(&ad),
        closed_loop_radius: spectral_radius(&(&aa - &ba * &k_aug)),
        observer_radius: spectral_radius(&observer),
        ad: rows_of(&ad),
        bd: rows_of(&bd),
        c: rows_of(&c),
        d: rows_of(&DMatrix::from_column_slice(p, 1, d.as_slice())),
        k: rows_of(&k),
        k_i,
        l: rows_of(&l),
        nx,
        nu,
        n_bar,
        control_residual,
        filter_residual,
    })
}

/// ‖res‖ / ‖x‖ (Frobenius), 0 for a zero x with a zero residual.
fn relative(res: &DMatrix<f64>, x: &DMatrix<f64>) -> f64 {
    let (a, b) = (res.norm(), x.norm());
    if b > 0.0 {
        a / b
    } else {
        a
    }
}
