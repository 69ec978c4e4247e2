//! The material-point path of a stretch-controlled protocol and its exact forward sensitivities
//! in the material parameters θ, and the comparison of the path with measured points.
//!
//! Each step n prescribes λₙ; the lateral stretch tₙ solves P₃₃(λₙ, tₙ; θ, Aₙ) = 0 and the step
//! commits Aₙ₊₁ = U(Fₙ, Aₙ; θ). Differentiating both along the path (forward mode), with
//! S = dAₙ/dθ carried from step to step:
//!
//! * dtₙ/dθ = −(∂P₃₃/∂θ + ∂P₃₃/∂Aₙ·S) / (∂P₃₃/∂t) (implicit function theorem with the tangent),
//! * dP₁₁/dθ = ∂P₁₁/∂θ + ∂P₁₁/∂Aₙ·S + ∂P₁₁/∂t·dtₙ/dθ,
//! * dAₙ₊₁/dθ = ∂U/∂θ + ∂U/∂Aₙ·S + ∂U/∂F·dFₙ/dθ,
//!
//! where ∂P/∂θ is [`Material::parameter_derivatives_at`], ∂P/∂Aₙ [`Material::stress_state_vjp`]
//! for the unit stresses e₁₁ and e₃₃, and the dense ∂U/∂(θ, Aₙ, F) [`Material::update_state_vjp`]
//! for each unit vector over Aₙ₊₁ (the state of a Maxwell branch is nine numbers: a few dozen
//! products per step).
//!
//! The stretch and the times of every step do not depend on θ, so a measured point compared by
//! linear interpolation between two steps (in time or in stretch) has the interpolated
//! sensitivities as its Jacobian row.

use super::spec::{Data, Experiment, Protocol};
use crate::material::homogeneous::Mode;
use crate::material::point_history::{run, Control};
use crate::material::{Mat3, Material, PointHistory, Vec3};

/// A path: per point (index 0: the initial state at t = 0), the time, the stretch, the nominal
/// stress P₁₁ and dP₁₁/dθ (one entry per entry of the material's θ).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Path {
    pub time: Vec<f64>,
    pub stretch: Vec<f64>,
    pub stress: Vec<f64>,
    pub sensitivity: Vec<Vec<f64>>,
}

/// Diagonal slots of F that hold the lateral stretch t in a mode.
fn lateral_slots(mode: Mode) -> &'static [usize] {
    match mode {
        Mode::Uniaxial => &[1, 2],
        Mode::Equibiaxial | Mode::PureShear => &[2],
    }
}

/// Runs `protocol` on `mat` with `steps` steps per segment; with `sensitivities`, also
/// dP₁₁/dθ at every point (else those rows are empty).
pub fn path(
    mat: &dyn Material,
    mode: Mode,
    protocol: &Protocol,
    steps: usize,
    sensitivities: bool,
) -> Result<Path, String> {
    let (times, _) = protocol.times(steps);
    let l = |t: f64| protocol.stretch_at(t);
    let records = run(mat, mode, &Control::Stretch(&l), &times).map_err(|f| {
        format!(
            "stopped at t = {:.6} s after {} steps: {}",
            f.t,
            f.records.len(),
            f.reason
        )
    })?;
    let n_theta = mat.parameters().map_or(0, |p| p.values.len());
    let mut out = Path {
        time: vec![0.0],
        stretch: vec![protocol.stretch_at(0.0)],
        stress: vec![0.0],
        sensitivity: vec![vec![0.0; if sensitivities { n_theta } else { 0 }]],
    };
    for r in &records {
        out.time.push(r.t);
        out.stretch.push(r.stretch);
        out.stress.push(r.nominal);
    }
    if !sensitivities {
        return Ok(out);
    }
    let size = mat.state_size();
    let mut state = vec![0.0; size];
    mat.initial_state(&mut state);
    let mut new_state = state.clone();
    // S = dA/dθ, row-major s × p
    let mut s = vec![0.0; size * n_theta];
    let mut s_new = s.clone();
    let ts = lateral_slots(mode);
    let zero = Vec3::zeros();
    let e = |i: usize| {
        let mut m = Mat3::zeros();
        m[(i, i)] = 1.0;
        m
    };
    let fail = |t: f64, what: &str, e: crate::material::MaterialError| {
        format!("sensitivities at t = {t} s: {what}: {e}")
    };
    let mut t_prev = 0.0;
    for r in &records {
        let h = PointHistory {
            state: &state,
            dt: r.t - t_prev,
        };
        let f = mode.deformation(r.stretch, r.lateral);
        let tan = mat
            .tangent_at(&f, &zero, h)
            .map_err(|x| fail(r.t, "tangent", x))?;
        let dp33_dt: f64 = ts.iter().map(|&c| tan.a[(8, 4 * c)]).sum();
        let dp11_dt: f64 = ts.iter().map(|&c| tan.a[(0, 4 * c)]).sum();
        let dpar = mat
            .parameter_derivatives_at(&f, &zero, h)
            .map_err(|x| fail(r.t, "parameter derivatives", x))?;
        let (g11, g33) = if size > 0 {
            (
                mat.stress_state_vjp(&f, &zero, h, &e(0))
                    .map_err(|x| fail(r.t, "stress in the state", x))?,
                mat.stress_state_vjp(&f, &zero, h, &e(2))
                    .map_err(|x| fail(r.t, "stress in the state", x))?,
            )
        } else {
            (Vec::new(), Vec::new())
        };
        let mut dl = vec![0.0; n_theta];
        let mut dp11 = vec![0.0; n_theta];
        for k in 0..n_theta {
            let via_state =
                |g: &[f64]| -> f64 { (0..size).map(|j| g[j] * s[j * n_theta + k]).sum() };
            let p33 = dpar[k].p[(2, 2)] + via_state(&g33);
            dl[k] = -p33 / dp33_dt;
            dp11[k] = dpar[k].p[(0, 0)] + via_state(&g11) + dp11_dt * dl[k];
        }
        out.sensitivity.push(dp11);
        if size > 0 {
            let mut w = vec![0.0; size];
            for i in 0..size {
                w.iter_mut().for_each(|x| *x = 0.0);
                w[i] = 1.0;
                let v = mat
                    .update_state_vjp(&f, &zero, h, &w)
                    .map_err(|x| fail(r.t, "update in θ", x))?;
                let df: f64 = ts.iter().map(|&c| v.f[(c, c)]).sum();
                for k in 0..n_theta {
                    let via: f64 = (0..size).map(|j| v.state[j] * s[j * n_theta + k]).sum();
                    s_new[i * n_theta + k] = v.theta[k] + via + df * dl[k];
                }
            }
            mat.update_state(&f, &zero, h, &mut new_state)
                .map_err(|x| fail(r.t, "update", x))?;
            std::mem::swap(&mut state, &mut new_state);
            std::mem::swap(&mut s, &mut s_new);
        }
        t_prev = r.t;
    }
    Ok(out)
}

/// How a measured point reads the model's path: P(point) = (1 − w)·P[a] + w·P[b].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pick {
    pub a: usize,
    pub b: usize,
    pub w: f64,
}

/// The rule that compares a path with measured points, fixed for an experiment (the path's
/// times and stretches do not depend on θ):
///
/// * with a `time_s` column: linear interpolation of the path in time;
/// * without (ramps and cycles): the data are cut into monotone runs of the stretch (a run ends
///   where the stretch turns); run k is compared with the k-th monotone segment of the protocol
///   (loading, unloading, loading, …), interpolating linearly in stretch on that segment.
///
/// A point outside the protocol's time span or its segment's stretch range is an error naming
/// the file and line.
pub fn picks(exp: &Experiment, model: &Path) -> Result<Vec<Pick>, String> {
    let data: &Data = &exp.data;
    let file = exp.data_path.display();
    let (_, ends) = exp.protocol.times(exp.steps);
    let mut out = Vec::with_capacity(data.stress.len());
    if let Some(times) = &data.time {
        for (i, &t) in times.iter().enumerate() {
            out.push(bracket(&model.time, t).ok_or_else(|| {
                format!(
                    "{file}:{}: time {t} s lies outside the protocol (0 to {} s)",
                    data.lines[i],
                    model.time.last().copied().unwrap_or(0.0)
                )
            })?);
        }
        return Ok(out);
    }
    if matches!(exp.protocol, Protocol::Relaxation { .. }) {
        return Err(format!(
            "{file}: a relaxation test needs the column `time_s`"
        ));
    }
    // monotone runs of the data
    let mut segment = 0usize;
    let mut dir = 0.0f64;
    for i in 0..data.stretch.len() {
        if i > 0 {
            let d = (data.stretch[i] - data.stretch[i - 1]).signum();
            if data.stretch[i] != data.stretch[i - 1] {
                if dir != 0.0 && d != dir {
                    segment += 1;
                }
                dir = d;
            }
        }
        if segment >= ends.len() {
            return Err(format!(
                "{file}:{}: the stretch turns more often than the protocol ({} monotone \
                 segments); give `time_s` or more cycles",
                data.lines[i],
                ends.len()
            ));
        }
        let start = if segment == 0 { 0 } else { ends[segment - 1] };
        let x = &model.stretch[start..=ends[segment]];
        let l = data.stretch[i];
        let pick = bracket_any(x, l).ok_or_else(|| {
            format!(
                "{file}:{}: stretch {l} lies outside the protocol's segment {} ({} to {})",
                data.lines[i],
                segment + 1,
                x[0],
                x[x.len() - 1]
            )
        })?;
        out.push(Pick {
            a: pick.a + start,
            b: pick.b + start,
            w: pick.w,
        });
    }
    Ok(out)
}

/// The interval of the increasing `xs` holding `x`.
fn bracket(xs: &[f64], x: f64) -> Option<Pick> {
    let tol = 1e-9 * xs.last().map_or(1.0, |v| v.abs().max(1.0));
    if xs.is_empty() || x < xs[0] - tol || x > xs[xs.len() - 1] + tol {
        return None;
    }
    let b = xs.partition_point(|&v| v < x).clamp(1, xs.len() - 1);
    let a = b - 1;
    let w = ((x - xs[a]) / (xs[b] - xs[a])).clamp(0.0, 1.0);
    Some(Pick { a, b, w })
}

/// The interval of the monotone (increasing or decreasing) `xs` holding `x`.
fn bracket_any(xs: &[f64], x: f64) -> Option<Pick> {
    if xs.len() < 2 {
        return None;
    }
    if xs[xs.len() - 1] >= xs[0] {
        bracket(xs, x)
    } else {
        let rev: Vec<f64> = xs.iter().rev().copied().collect();
        let p = bracket(&rev, x)?;
        let n = xs.len() - 1;
        Some(Pick {
            a: n - p.b,
            b: n - p.a,
            w: 1.0 - p.w,
        })
    }
}

impl Pick {
    /// The interpolated value of `v`.
    pub fn of(&self, v: &[f64]) -> f64 {
        (1.0 - self.w) * v[self.a] + self.w * v[self.b]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::registry::{build, MaterialParams};
    use std::sync::Arc;

    fn gent() -> Arc<dyn Material> {
        let p = MaterialParams {
            mu: vec![3e4],
            jm: Some(40.0),
            kappa: Some(3e7),
            permittivity: Some(4.7),
            ..Default::default()
        };
        build("gent", &p).unwrap().0
    }

    fn arruda_boyce_three_branches() -> Arc<dyn Material> {
        let p = MaterialParams {
            mu: vec![1.5e4],
            lambda_m: Some(6.0),
            kappa: Some(1.5e7),
            permittivity: Some(4.7),
            branches: vec![(2.6e4, 0.6), (2.6e4, 6.5), (1.1e4, 60.0)],
            ..Default::default()
        };
        build("arruda-boyce", &p).unwrap().0
    }

    /// dP₁₁/dθ along the path against central differences of whole paths, every entry of θ.
    fn check(mat: &dyn Material, mode: Mode, protocol: Protocol, steps: usize) {
        let exact = path(mat, mode, &protocol, steps, true).unwrap();
        let theta = mat.parameters().unwrap();
        for (k, name) in theta.names.iter().enumerate() {
            let h = 1e-4 * theta.values[k].abs().max(1e-12);
            let at = |x: f64| {
                let mut v = theta.values.clone();
                v[k] = x;
                let m = mat.with_parameters(&v).unwrap();
                path(m.as_ref(), mode, &protocol, steps, false)
                    .unwrap()
                    .stress
            };
            let (plus, minus) = (at(theta.values[k] + h), at(theta.values[k] - h));
            let col: Vec<f64> = exact.sensitivity.iter().map(|s| s[k]).collect();
            let size = col.iter().fold(0.0f64, |a, x| a.max(x.abs()));
            let mut worst = 0.0f64;
            for i in 0..col.len() {
                let fd = (plus[i] - minus[i]) / (2.0 * h);
                worst = worst.max((fd - col[i]).abs());
            }
            let scale = size.max(1e-30);
            assert!(
                worst <= 1e-6 * scale || (size == 0.0 && worst < 1e-9),
                "{name}: max |exact − fd| = {worst:e} against max |exact| = {size:e}"
            );
        }
    }

    #[test]
    fn gent_cyclic_and_relaxation_sensitivities_match_differences() {
        let m = gent();
        let cyc = Protocol::Cyclic {
            stretch: 3.0,
            rate: 0.5,
            cycles: 1,
        };
        check(m.as_ref(), Mode::Uniaxial, cyc, 40);
        let rel = Protocol::Relaxation {
            stretch: 2.0,
            ramp_time: 0.5,
            hold: 10.0,
        };
        check(m.as_ref(), Mode::PureShear, rel, 30);
    }

    #[test]
    fn arruda_boyce_with_three_branches_sensitivities_match_differences() {
        let m = arruda_boyce_three_branches();
        let cyc = Protocol::Cyclic {
            stretch: 2.5,
            rate: 0.05,
            cycles: 2,
        };
        check(m.as_ref(), Mode::Uniaxial, cyc, 40);
        let rel = Protocol::Relaxation {
            stretch: 2.0,
            ramp_time: 1.0,
            hold: 100.0,
        };
        check(m.as_ref(), Mode::Equibiaxial, rel, 40);
    }

    /// The comparison rule: monotone runs of untimed data read the matching half cycle.
    #[test]
    fn untimed_points_read_their_own_branch() {
        let xs = [1.0, 1.5, 2.0, 1.5, 1.0];
        let p = bracket_any(&xs[2..], 1.25).unwrap();
        assert_eq!((p.a, p.b), (1, 2));
        assert!((p.w - 0.5).abs() < 1e-15);
        assert!((p.of(&xs[2..]) - 1.25).abs() < 1e-15);
        assert!(bracket(&xs[..3], 2.5).is_none());
    }
}
