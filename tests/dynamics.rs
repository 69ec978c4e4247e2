//! Dynamics: the midpoint variational integrator (docs/theory.md) and the Newmark reference.
//!
//! References and tolerances are stated per test; all meshes are small so that 10⁴ steps run in
//! seconds in a release build.

use deasim::cli::validate::dynamics::{
    self, bar_frequency, energy_band, free_body, grounded_block, momenta, trend, Run, RHO,
};
use deasim::problem::dofs::FIELDS;
use deasim::problem::model::Model;
use deasim::time::integrator::Scheme;
use deasim::time::integrator::TimeLevel;
use deasim::time::stage::Method;
use deasim::waveform::{Shape, Waveform};

/// `validate::dynamics::simulate`, which must succeed.
#[allow(clippy::too_many_arguments)]
fn simulate(
    model: &Model,
    top: &[usize],
    bottom: &[usize],
    volts: f64,
    eta: f64,
    scheme: Method,
    dt: f64,
    steps: usize,
    v0: Option<Vec<f64>>,
) -> Run {
    dynamics::simulate(model, top, bottom, volts, eta, scheme, dt, steps, v0).unwrap()
}

/// Undamped, constant voltage: kinetic + stored − electric is conserved without drift over 10⁴
/// steps; its oscillation is O(Δt²) (the band shrinks ≈4× when Δt is halved).
#[test]
fn energy_is_conserved_without_drift() {
    let (model, bottom, top) = grounded_block().unwrap();
    let dt = 2e-6;
    let run = simulate(
        &model,
        &top,
        &bottom,
        20e3,
        0.0,
        Method::Implicit(Scheme::Midpoint),
        dt,
        10_000,
        None,
    );
    let e = &run.energy;
    let scale = e.iter().map(|v| v.abs()).fold(0.0, f64::max);
    let band = energy_band(e);
    let first = energy_band(&e[..1000]);
    let last: f64 = e[9000..]
        .iter()
        .map(|v| (v - e[0]).abs())
        .fold(0.0, f64::max);
    // least-squares trend of the energy over the 10⁴ steps
    let drift = trend(e);
    eprintln!(
        "energy {scale:.3e} J; oscillation band {band:.3e} J (first 1000 steps {first:.3e}, last 1000 {last:.3e}); trend over 10⁴ steps {drift:.3e} J"
    );
    assert!(band < 1e-5 * scale, "the oscillation is small");
    assert!(last < 2.0 * first, "bounded: no growth of the oscillation");
    assert!(
        drift.abs() < 0.5 * band,
        "no drift: trend {drift:e} against band {band:e}"
    );
    // order: same physical time with Δt/2
    let half = simulate(
        &model,
        &top,
        &bottom,
        20e3,
        0.0,
        Method::Implicit(Scheme::Midpoint),
        dt / 2.0,
        2_000,
        None,
    );
    let full = simulate(
        &model,
        &top,
        &bottom,
        20e3,
        0.0,
        Method::Implicit(Scheme::Midpoint),
        dt,
        1_000,
        None,
    );
    let ratio = energy_band(&full.energy) / energy_band(&half.energy);
    eprintln!("energy band ratio for Δt → Δt/2: {ratio:.2}");
    assert!((3.0..5.5).contains(&ratio), "O(Δt²): ratio {ratio}");
}

/// A free body (no support) given a translation and a rotation: linear and angular momentum
/// p = Σ M v, L = Σ x × M v stay constant to round-off (10⁻¹⁰ relative: the Newton tolerance).
#[test]
fn free_body_conserves_linear_and_angular_momentum() {
    let body = free_body().unwrap();
    let of = |level: &TimeLevel| momenta(&body.model.mesh, &body.mass, level);
    let (p0, l0) = of(&body.start);
    let pn = p0.iter().map(|v| v * v).sum::<f64>().sqrt();
    let ln = l0.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut worst: (f64, f64) = (0.0, 0.0);
    for level in &body.run.levels {
        let (p, l) = of(level);
        for i in 0..3 {
            worst.0 = worst.0.max((p[i] - p0[i]).abs() / pn);
            worst.1 = worst.1.max((l[i] - l0[i]).abs() / ln);
        }
    }
    // the body really deformed and rotated
    let last = body.run.levels.last().unwrap();
    assert!(last.q.iter().map(|v| v.abs()).fold(0.0, f64::max) > 1e-5);
    eprintln!(
        "momentum drift over 500 steps: linear {:.2e}, angular {:.2e}",
        worst.0, worst.1
    );
    assert!(worst.0 < 1e-10 && worst.1 < 1e-10, "{worst:?}");
}

/// Second-order convergence: the top corner's displacement at T = 0.2 ms for Δt, Δt/2, Δt/4
/// against Δt/64; the error falls ≈4× per halving (midpoint and Newmark).
#[test]
fn trajectory_converges_at_second_order() {
    let (model, bottom, top) = grounded_block().unwrap();
    let corner = model.mesh.nearest_node([2e-3, 2e-3, 1e-3]);
    for scheme in [
        Method::Implicit(Scheme::Midpoint),
        Method::Implicit(Scheme::Newmark {
            beta: 0.25,
            gamma: 0.5,
        }),
        Method::Trapezoidal,
    ] {
        let t_end = 2e-4;
        let at = |dt: f64| {
            let steps = (t_end / dt).round() as usize;
            let run = simulate(&model, &top, &bottom, 20e3, 0.0, scheme, dt, steps, None);
            let q = &run.levels.last().unwrap().q;
            [q[corner * FIELDS], q[corner * FIELDS + 2]]
        };
        let reference = at(t_end / 1280.0);
        let errs: Vec<f64> = [20.0, 40.0, 80.0]
            .iter()
            .map(|n| {
                let u = at(t_end / n);
                ((u[0] - reference[0]).powi(2) + (u[1] - reference[1]).powi(2)).sqrt()
            })
            .collect();
        let r1 = errs[0] / errs[1];
        let r2 = errs[1] / errs[2];
        eprintln!("{scheme:?}: errors {errs:?}, ratios {r1:.2} {r2:.2}");
        assert!(
            (3.2..5.0).contains(&r1) && (3.2..5.0).contains(&r2),
            "{scheme:?}: {r1} {r2}"
        );
    }
}

/// First axial eigenfrequency of a slender clamped–free bar (1 m × 20 mm × 20 mm, Λ = 0 so that
/// ν = 0 and E = 2μ exactly): f₁ = √(E/ρ)/(4L). Excited in its first mode shape with a small
/// velocity; the period is measured from the zero crossings of the tip velocity over 5 periods.
/// Tolerance 1 %: spatial error (40 elements) ≈ 1e-4, temporal (100 steps per period) ≈ 3e-4.
#[test]
fn slender_bar_axial_frequency() {
    let (l, mu) = (1.0, 1e5);
    let f1 = (2.0 * mu / RHO).sqrt() / (4.0 * l);
    let computed = bar_frequency(l, mu, 1.0 / f1).unwrap();
    let rel = (computed - f1).abs() / f1;
    eprintln!("bar: f1 = {f1:.4} Hz analytic, {computed:.4} Hz computed, rel. error {rel:.2e}");
    assert!(rel < 0.01);
}

/// With viscosity the free vibration decays, the dissipated energy never decreases, and the energy
/// balance kinetic + stored − electric + dissipated closes to the integrator's accuracy: its
/// deviation falls ≈4× when Δt is halved.
#[test]
fn viscous_vibration_decays_and_balances_energy() {
    let (model, bottom, top) = grounded_block().unwrap();
    let eta = 5.0; // Pa·s
    let dt = 2e-6;
    let run = simulate(
        &model,
        &top,
        &bottom,
        20e3,
        eta,
        Method::Implicit(Scheme::Midpoint),
        dt,
        3000,
        None,
    );
    assert!(
        run.dissipated.windows(2).all(|w| w[1] >= w[0]),
        "dissipated never decreases"
    );
    assert!(*run.dissipated.last().unwrap() > 0.0);
    let corner = model.mesh.nearest_node([2e-3, 2e-3, 1e-3]);
    let amp = |lv: &[TimeLevel]| {
        lv.iter()
            .map(|l| l.v[corner * FIELDS + 2].abs())
            .fold(0.0, f64::max)
    };
    let early = amp(&run.levels[..300]);
    let late = amp(&run.levels[2700..]);
    eprintln!("velocity amplitude early {early:.3e}, late {late:.3e}");
    assert!(late < 0.2 * early, "free vibration decays");
    let balance = |r: &Run| {
        let e: Vec<f64> = r
            .energy
            .iter()
            .zip(&r.dissipated)
            .map(|(a, b)| a + b)
            .collect();
        energy_band(&e)
    };
    let coarse = simulate(
        &model,
        &top,
        &bottom,
        20e3,
        eta,
        Method::Implicit(Scheme::Midpoint),
        dt,
        500,
        None,
    );
    let fine = simulate(
        &model,
        &top,
        &bottom,
        20e3,
        eta,
        Method::Implicit(Scheme::Midpoint),
        dt / 2.0,
        1000,
        None,
    );
    let ratio = balance(&coarse) / balance(&fine);
    eprintln!(
        "energy balance error {:.3e} J (Δt), {:.3e} J (Δt/2), ratio {ratio:.2}",
        balance(&coarse),
        balance(&fine)
    );
    assert!((3.0..5.5).contains(&ratio), "{ratio}");
}

/// Every waveform against its formula at many times.
#[test]
fn waveforms_match_their_formulas() {
    use std::f64::consts::PI;
    let (a, f, off) = (3000.0, 2.0, 100.0);
    let w = |shape| Waveform {
        shape,
        amplitude: a,
        offset: off,
        phase_deg: 0.0,
    };
    for i in 0..400 {
        let t = i as f64 * 0.00371;
        let x = (t * f).fract();
        let sq = w(Shape::Square {
            frequency: f,
            duty: 0.3,
            bipolar: false,
        })
        .value(t);
        assert_eq!(sq, off + a * if x < 0.3 { 1.0 } else { 0.0 });
        let tri = w(Shape::Triangle {
            frequency: f,
            bipolar: true,
        })
        .value(t);
        let tri_ref = off + a * (2.0 * (if x < 0.5 { 2.0 * x } else { 2.0 - 2.0 * x }) - 1.0);
        assert!((tri - tri_ref).abs() < 1e-9);
        let s = w(Shape::Sine {
            frequency: f,
            bipolar: true,
        })
        .value(t);
        assert!((s - (off + a * (2.0 * PI * f * t).sin())).abs() < 1e-9);
        let su = w(Shape::Sine {
            frequency: f,
            bipolar: false,
        })
        .value(t);
        assert!((su - (off + a * 0.5 * (1.0 - (2.0 * PI * f * t).cos()))).abs() < 1e-9);
        let fs = w(Shape::Fourier {
            base: deasim::waveform::FourierBase::Square,
            frequency: f,
            terms: 3,
            bipolar: false,
        })
        .value(t);
        let ws = 2.0 * PI * f * t;
        let fs_ref = off
            + a * (0.5 + 2.0 / PI * (ws.sin() + (3.0 * ws).sin() / 3.0 + (5.0 * ws).sin() / 5.0));
        assert!((fs - fs_ref).abs() < 1e-9);
        let ft = w(Shape::Fourier {
            base: deasim::waveform::FourierBase::Triangle,
            frequency: f,
            terms: 2,
            bipolar: false,
        })
        .value(t);
        let ft_ref = off + a * (0.5 - 4.0 / (PI * PI) * (ws.cos() + (3.0 * ws).cos() / 9.0));
        assert!((ft - ft_ref).abs() < 1e-9);
        let ramp = w(Shape::Ramp {
            rise_time: 0.5,
            cosine: false,
        })
        .value(t);
        assert!((ramp - (off + a * (t / 0.5).min(1.0))).abs() < 1e-9);
        let x = (t / 0.5).min(1.0);
        let smooth = w(Shape::Ramp {
            rise_time: 0.5,
            cosine: true,
        })
        .value(t);
        assert!((smooth - (off + a * 0.5 * (1.0 - (PI * x).cos()))).abs() < 1e-9);
    }
}

/// The trapezoidal discrete Lagrangian (explicit Störmer–Verlet on the reduced Lagrangian): momenta
/// of a free body conserved to round-off, energy oscillation bounded and O(Δt²), viscous balance
/// closes at O(Δt²). Δt is kept below its stability limit (≈2e-5 s for this mesh).
#[test]
fn trapezoidal_integrator_conserves_momenta_and_energy() {
    let (model, bottom, top) = grounded_block().unwrap();
    let band = |dt: f64, steps: usize, eta: f64| {
        let r = simulate(
            &model,
            &top,
            &bottom,
            20e3,
            eta,
            Method::Trapezoidal,
            dt,
            steps,
            None,
        );
        let e: Vec<f64> = r
            .energy
            .iter()
            .zip(&r.dissipated)
            .map(|(a, b)| a + b)
            .collect();
        (energy_band(&e), e[0], r)
    };
    let (b1, e0, run) = band(2e-6, 2000, 0.0);
    let (b2, _, _) = band(1e-6, 4000, 0.0);
    eprintln!(
        "trapezoidal: energy band {b1:.3e} J of {e0:.3e} J, ratio for Δt/2 {:.2}",
        b1 / b2
    );
    assert!(b1 < 1e-4 * e0.abs());
    assert!((3.0..5.5).contains(&(b1 / b2)), "{}", b1 / b2);
    assert!(
        run.levels.last().unwrap().q.iter().any(|v| v.abs() > 1e-6),
        "the film moved"
    );
    let (v1, _, _) = band(2e-6, 1000, 5.0);
    let (v2, _, _) = band(1e-6, 2000, 5.0);
    eprintln!(
        "trapezoidal viscous balance {v1:.3e} → {v2:.3e} J, ratio {:.2}",
        v1 / v2
    );
    assert!((3.0..5.5).contains(&(v1 / v2)));
}
