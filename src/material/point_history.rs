//! Homogeneous material-point histories in real time: one point of a [`Material`] under a
//! prescribed stretch, nominal stress or electric field, stepped with the material's own update
//! of its internal variables (the same code and the same time discretisation as the finite
//! element path). Used by `deasim material` to show a material before a device run, and by the
//! tests as the homogeneous reference of the finite element solution.
//!
//! The deformation is diagonal, F = diag(f₁, f₂, f₃), with the stretch λ and the lateral stretch t
//! placed by the [`Mode`]: uniaxial (λ, t, t), equibiaxial (λ, λ, t), pure shear (λ, 1, t). The free
//! directions carry no stress (P₃₃ = 0, and P₂₂ = P₃₃ = 0 in uniaxial tension by symmetry). Under
//! [`Control::Field`] the point is the homogeneous film between two electrodes: equibiaxial, free in
//! plane (P₁₁ = 0) and in thickness (P₃₃ = 0), with the nominal field E₀ = (0, 0, V/H).

use super::homogeneous::Mode;
use super::{Mat3, Material, MaterialError, PointHistory, Vec3};

/// What is prescribed along the loading direction, as a function of time (s).
pub enum Control<'a> {
    /// The stretch λ(t) (uniaxial, equibiaxial or pure shear; the lateral stretch is free).
    Stretch(&'a dyn Fn(f64) -> f64),
    /// The nominal stress P₁₁(t) (Pa): a creep test when held.
    Stress(&'a dyn Fn(f64) -> f64),
    /// The nominal field E₀(t) = V/H (V/m) through the thickness of a free film (equibiaxial).
    Field(&'a dyn Fn(f64) -> f64),
}

/// The point's state at the end of a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointRecord {
    /// Time (s).
    pub t: f64,
    /// Stretch λ and lateral stretch t.
    pub stretch: f64,
    pub lateral: f64,
    /// Nominal (first Piola–Kirchhoff) stress P₁₁ and true (Cauchy) stress σ₁₁ (Pa).
    pub nominal: f64,
    pub cauchy: f64,
    /// Nominal field E₀ (V/m) and nominal electric displacement D₀ (C/m²) through the thickness.
    pub field: f64,
    pub displacement: f64,
    /// Energy dissipated by the internal variables since the start (J/m³).
    pub dissipated: f64,
}

/// A history that stopped: the records up to the last converged step, the time that failed and
/// why (e.g. the limit point of a film under a rising field).
#[derive(Debug, Clone)]
pub struct PointFailure {
    pub records: Vec<PointRecord>,
    pub t: f64,
    pub reason: String,
}

/// Slots of F (diagonal index) that hold λ and t in a mode.
fn slots(mode: Mode) -> (&'static [usize], &'static [usize]) {
    match mode {
        Mode::Uniaxial => (&[0], &[1, 2]),
        Mode::Equibiaxial => (&[0, 1], &[2]),
        Mode::PureShear => (&[0], &[2]),
    }
}

fn deformation(mode: Mode, stretch: f64, lateral: f64) -> Mat3 {
    mode.deformation(stretch, lateral)
}

/// Runs the point from the virgin state through the step end times `times` (ascending, > 0),
/// recording every step. The first step starts at t = 0 from λ = 1 (or the control's value at 0).
pub fn run(
    mat: &dyn Material,
    mode: Mode,
    control: &Control,
    times: &[f64],
) -> Result<Vec<PointRecord>, PointFailure> {
    if matches!(control, Control::Field(_)) && mode != Mode::Equibiaxial {
        return Err(PointFailure {
            records: Vec::new(),
            t: 0.0,
            reason: "a field-controlled point is the free film: equibiaxial mode only".into(),
        });
    }
    let size = mat.state_size();
    let mut state = vec![0.0; size];
    mat.initial_state(&mut state);
    let mut new_state = state.clone();
    let mut records: Vec<PointRecord> = Vec::with_capacity(times.len());
    let (mut stretch, mut lateral) = (1.0, 1.0);
    if let Control::Stretch(l) = control {
        stretch = l(0.0);
        lateral = mode.incompressible_lateral(stretch);
    }
    let mut t_prev = 0.0;
    let mut dissipated = 0.0;
    let (ls, ts) = slots(mode);
    let scale = mat.shear_modulus().abs().max(1.0);
    let fail = |records: &[PointRecord], t: f64, reason: String| PointFailure {
        records: records.to_vec(),
        t,
        reason,
    };
    for &t in times {
        let dt = t - t_prev;
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(fail(
                &records,
                t,
                format!("step end times must increase; got {t} after {t_prev}"),
            ));
        }
        let h = PointHistory { state: &state, dt };
        let (target, e0) = match control {
            Control::Stretch(l) => {
                stretch = l(t);
                (0.0, 0.0)
            }
            Control::Stress(s) => (s(t), 0.0),
            Control::Field(e) => (0.0, e(t)),
        };
        let field = Vec3::new(0.0, 0.0, e0);
        let free_stretch = !matches!(control, Control::Stretch(_));
        // Newton on (λ, t) or t alone, residuals P₁₁ − target and P₃₃
        let residual =
            |stretch: f64, lateral: f64| -> Result<([f64; 2], Mat3, f64), MaterialError> {
                let f = deformation(mode, stretch, lateral);
                let s = mat.stress_at(&f, &field, h)?;
                Ok(([s.p[(0, 0)] - target, s.p[(2, 2)]], s.p, s.d0[2]))
            };
        let norm = |r: [f64; 2]| {
            if free_stretch {
                r[0].hypot(r[1])
            } else {
                r[1].abs()
            }
        };
        let mut converged = false;
        let (mut r, _, _) =
            residual(stretch, lateral).map_err(|e| fail(&records, t, e.to_string()))?;
        for _ in 0..100 {
            if norm(r) <= 1e-12 * scale {
                converged = true;
                break;
            }
            let tan = mat
                .tangent_at(&deformation(mode, stretch, lateral), &field, h)
                .map_err(|e| fail(&records, t, e.to_string()))?;
            let d = |row: usize, cols: &[usize]| -> f64 {
                cols.iter().map(|&c| tan.a[(row * 4, c * 4)]).sum()
            };
            // ∂(P₁₁, P₃₃)/∂(λ, t)
            let (a11, a12, a21, a22) = (d(0, ls), d(0, ts), d(2, ls), d(2, ts));
            let (dl, dtl) = if free_stretch {
                let det = a11 * a22 - a12 * a21;
                if det == 0.0 || !det.is_finite() {
                    return Err(fail(&records, t, "singular point tangent".into()));
                }
                (
                    -(a22 * r[0] - a12 * r[1]) / det,
                    -(-a21 * r[0] + a11 * r[1]) / det,
                )
            } else {
                if a22 == 0.0 || !a22.is_finite() {
                    return Err(fail(&records, t, "singular point tangent".into()));
                }
                (0.0, -r[1] / a22)
            };
            // backtracking: stretches stay positive and the residual falls
            let mut alpha = 1.0;
            let mut accepted = false;
            for _ in 0..40 {
                let (l1, t1) = (stretch + alpha * dl, lateral + alpha * dtl);
                if l1 > 0.0 && t1 > 0.0 {
                    if let Ok((r1, _, _)) = residual(l1, t1) {
                        if norm(r1) < norm(r) || norm(r1) <= 1e-12 * scale {
                            stretch = l1;
                            lateral = t1;
                            r = r1;
                            accepted = true;
                            break;
                        }
                    }
                }
                alpha *= 0.5;
            }
            if !accepted {
                break;
            }
            if (alpha * dl).abs() + (alpha * dtl).abs() <= 1e-15 * (stretch + lateral) {
                converged = norm(r) <= 1e-8 * scale;
                break;
            }
        }
        if !converged {
            return Err(fail(
                &records,
                t,
                format!(
                    "no homogeneous equilibrium at t = {t} s (residual {:.3e} Pa): a limit point \
                     of the loading",
                    norm(r)
                ),
            ));
        }
        let f = deformation(mode, stretch, lateral);
        let (_, p, d0) =
            residual(stretch, lateral).map_err(|e| fail(&records, t, e.to_string()))?;
        dissipated += mat
            .update_state(&f, &field, h, &mut new_state)
            .map_err(|e| fail(&records, t, e.to_string()))?;
        std::mem::swap(&mut state, &mut new_state);
        let j = f.determinant();
        records.push(PointRecord {
            t,
            stretch,
            lateral,
            nominal: p[(0, 0)],
            cauchy: p[(0, 0)] * stretch / j,
            field: e0,
            displacement: d0,
            dissipated,
        });
        t_prev = t;
    }
    Ok(records)
}

/// `n` equal step end times over (0, end].
pub fn uniform_times(end: f64, n: usize) -> Vec<f64> {
    (1..=n).map(|i| end * i as f64 / n as f64).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::maxwell::Viscoelastic;
    use crate::material::neo_hooke::ElectroNeoHooke;
    use std::sync::Arc;

    fn visco(g: f64, tau: f64) -> Viscoelastic {
        Viscoelastic {
            equilibrium: Arc::new(ElectroNeoHooke::new(1e4, 1e7, 4.7)),
            branches: vec![(g, tau)],
        }
    }

    /// An elastic point follows the homogeneous solver of `homogeneous` at every stretch.
    #[test]
    fn elastic_uniaxial_matches_the_static_path() {
        let m = ElectroNeoHooke::new(1e4, 1e7, 4.7);
        let l = |t: f64| 1.0 + t;
        let rec = run(
            &m,
            Mode::Uniaxial,
            &Control::Stretch(&l),
            &uniform_times(1.0, 10),
        )
        .unwrap();
        for r in &rec {
            let s = crate::material::homogeneous::solve(&m, Mode::Uniaxial, r.stretch).unwrap();
            assert!(
                (r.nominal - s.p11).abs() < 1e-9 * 1e4,
                "{} {}",
                r.nominal,
                s.p11
            );
            assert!((r.lateral - s.lateral).abs() < 1e-12);
        }
    }

    /// A stress held on a Maxwell point: the stretch creeps from the instantaneous to the relaxed
    /// value of the prescribed stress, which the stretch-controlled point confirms.
    #[test]
    fn held_stress_creeps_to_the_relaxed_stretch() {
        let m = visco(4e4, 0.5);
        let s = |_t: f64| 5e3;
        let rec = run(
            &m,
            Mode::Uniaxial,
            &Control::Stress(&s),
            &uniform_times(20.0, 400),
        )
        .unwrap();
        let first = rec[0].stretch;
        let last = rec.last().unwrap().stretch;
        assert!(last > first + 0.05, "{first} {last}");
        assert!(rec.windows(2).all(|w| w[1].stretch >= w[0].stretch - 1e-12));
        // relaxed: the equilibrium material alone at that stress
        let eq = ElectroNeoHooke::new(1e4, 1e7, 4.7);
        let l = |_t: f64| last;
        let r = run(&eq, Mode::Uniaxial, &Control::Stretch(&l), &[1.0]).unwrap();
        assert!((r[0].nominal - 5e3).abs() < 1e-3 * 5e3, "{}", r[0].nominal);
        assert!(rec.last().unwrap().dissipated > 0.0);
    }

    /// The elastic film under a rising field reaches the closed-form pull-in field and fails just
    /// beyond it.
    #[test]
    fn film_fails_at_the_closed_form_pull_in() {
        let m = ElectroNeoHooke::new(1e5, 1e7, 4.7);
        let film = crate::analytic::Film {
            mu: 1e5,
            lambda: 1e7,
            eps: 4.7 * crate::material::EPSILON_0,
            c2: 0.0,
        };
        let (ec, _) = film.pull_in();
        let e = |t: f64| t * 1e6;
        let times = uniform_times(2.0 * ec / 1e6, 4000);
        let f = run(&m, Mode::Equibiaxial, &Control::Field(&e), &times).unwrap_err();
        let last = f.records.last().unwrap();
        assert!(
            last.field <= ec && f.t * 1e6 > ec,
            "{} {} {ec}",
            last.field,
            f.t
        );
        assert!((last.field - ec).abs() < 2e-3 * ec);
        // on the way the closed-form states (near the peak dt/dE is unbounded: looser there)
        for r in &f.records {
            let closed = film.state(r.field).unwrap();
            let tol = if r.field < 0.9 * ec { 1e-10 } else { 1e-6 };
            assert!(
                (r.lateral - closed.t).abs() < tol,
                "{} {}",
                r.lateral,
                closed.t
            );
        }
    }
}
