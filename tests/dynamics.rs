//! Dynamics: the midpoint variational integrator (docs/theory.md) and the Newmark reference.
//!
//! References and tolerances are stated per test; all meshes are small so that 10⁴ steps run in
//! seconds in a release build.

use deasim::material::ElectroNeoHooke;
use deasim::mesh::{generate::box_mesh, ElementKind};
use deasim::problem::dofs::{Dirichlet, Field, FIELDS};
use deasim::problem::model::Model;
use deasim::solve::newton::NewtonSettings;
use deasim::time::integrator::TimeLevel;
use deasim::time::mass::{MassKind, NodalMass};
use deasim::time::stage::{run_dynamic, DynamicInputs, DynamicSettings, Method};
use deasim::waveform::{Shape, Waveform};
use std::sync::Arc;

const RHO: f64 = 1000.0;

/// A small film block (2 × 2 × 1 mm quarter, 2×2×1 hex8) with μ = 1e5, Λ = 4e5 Pa, εᵣ = 4.7,
/// supports on the symmetry planes and the bottom (unless `free`), electrodes z0 (0 V) and z1.
fn block(free: bool) -> (Model, Vec<usize>, Vec<usize>) {
    let mesh = box_mesh([2e-3, 2e-3, 1e-3], [2, 2, 1], ElementKind::Hex8);
    let mut model = Model::new(mesh, Arc::new(ElectroNeoHooke::new(1e5, 4e5, 4.7))).unwrap();
    if !free {
        model.fix("x0", Field::Ux, 0.0).unwrap();
        model.fix("y0", Field::Uy, 0.0).unwrap();
        model.fix("z0", Field::Uz, 0.0).unwrap();
    }
    let bottom = model.mesh.node_sets["z0"].clone();
    let top = model.mesh.node_sets["z1"].clone();
    (model, bottom, top)
}

struct Run {
    levels: Vec<TimeLevel>,
    energy: Vec<f64>,
    dissipated: Vec<f64>,
}

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
    let mass = NodalMass::new(model, &[RHO], MassKind::Consistent);
    let inputs = DynamicInputs {
        mass: &mass,
        viscosity: vec![eta],
        electrodes: vec![
            (bottom.to_vec(), Waveform::constant(0.0)),
            (top.to_vec(), Waveform::constant(volts)),
        ],
        points: Default::default(),
    };
    let n = model.mesh.n_nodes() * FIELDS;
    let start = TimeLevel {
        t: 0.0,
        q: vec![0.0; n],
        v: v0.unwrap_or(vec![0.0; n]),
        a: vec![0.0; n],
    };
    let settings = DynamicSettings {
        duration: dt * steps as f64,
        dt,
        scheme,
        min_fraction: 1.0 / 64.0,
        easy_iterations: 100,
        reuse_factorization: true,
        solver: Default::default(),
    };
    let mut run = Run {
        levels: Vec::new(),
        energy: Vec::new(),
        dissipated: Vec::new(),
    };
    let mut mv = vec![0.0; n];
    let mut dissipated = 0.0;
    let newton = NewtonSettings {
        rtol: 1e-12,
        check_stability: false,
        ..Default::default()
    };
    run_dynamic(model, &inputs, start, &settings, &newton, |level, info| {
        mass.mul(&level.v, &mut mv);
        let kinetic = 0.5 * level.v.iter().zip(&mv).map(|(a, b)| a * b).sum::<f64>();
        let (stored, electric) = deasim::problem::statics::energies(model, &level.q).unwrap();
        dissipated += info.dissipated;
        run.energy.push(kinetic + stored - electric);
        run.dissipated.push(dissipated);
        run.levels.push(level.clone());
    })
    .map_err(|(_, f)| f.reason)
    .unwrap();
    run
}

/// Largest deviation of the conserved quantity from its value after the first step (the voltage
/// is switched on at t = 0, so the energy of the first level is the reference).
fn energy_band(e: &[f64]) -> f64 {
    e.iter().map(|v| (v - e[0]).abs()).fold(0.0, f64::max)
}

/// Undamped, constant voltage: kinetic + stored − electric is conserved without drift over 10⁴
/// steps; its oscillation is O(Δt²) (the band shrinks ≈4× when Δt is halved).
#[test]
fn energy_is_conserved_without_drift() {
    let (mut model, bottom, top) = block(false);
    model.dirichlet.push(Dirichlet {
        nodes: bottom.clone(),
        field: Field::Phi,
        value: 0.0,
    });
    let dt = 2e-6;
    let run = simulate(
        &model,
        &top,
        &bottom,
        20e3,
        0.0,
        Method::Midpoint,
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
    let n = e.len() as f64;
    let mean_i = (n - 1.0) / 2.0;
    let mean_e = e.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, v) in e.iter().enumerate() {
        sxy += (i as f64 - mean_i) * (v - mean_e);
        sxx += (i as f64 - mean_i).powi(2);
    }
    let drift = sxy / sxx * n;
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
        Method::Midpoint,
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
        Method::Midpoint,
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
    let (model, bottom, top) = block(true);
    let n_nodes = model.mesh.n_nodes();
    let mut v0 = vec![0.0; n_nodes * FIELDS];
    let omega = [30.0, -20.0, 50.0]; // rad/s
    for (a, x) in model.mesh.nodes.iter().enumerate() {
        let w = [
            omega[1] * x[2] - omega[2] * x[1],
            omega[2] * x[0] - omega[0] * x[2],
            omega[0] * x[1] - omega[1] * x[0],
        ];
        for i in 0..3 {
            v0[a * FIELDS + i] = [0.1, 0.05, -0.02][i] + w[i];
        }
    }
    let mut model = model;
    model.dirichlet.push(Dirichlet {
        nodes: bottom.clone(),
        field: Field::Phi,
        value: 0.0,
    });
    let mass = NodalMass::new(&model, &[RHO], MassKind::Consistent);
    let run = simulate(
        &model,
        &top,
        &bottom,
        20e3,
        0.0,
        Method::Midpoint,
        1e-6,
        500,
        Some(v0.clone()),
    );
    let momenta = |level: &TimeLevel| {
        let mut mv = vec![0.0; level.v.len()];
        mass.mul(&level.v, &mut mv);
        let (mut p, mut l) = ([0.0; 3], [0.0; 3]);
        for (a, x0) in model.mesh.nodes.iter().enumerate() {
            let x: Vec<f64> = (0..3).map(|i| x0[i] + level.q[a * FIELDS + i]).collect();
            let m = &mv[a * FIELDS..a * FIELDS + 3];
            for i in 0..3 {
                p[i] += m[i];
            }
            l[0] += x[1] * m[2] - x[2] * m[1];
            l[1] += x[2] * m[0] - x[0] * m[2];
            l[2] += x[0] * m[1] - x[1] * m[0];
        }
        (p, l)
    };
    let start = TimeLevel {
        t: 0.0,
        q: vec![0.0; v0.len()],
        v: v0,
        a: vec![],
    };
    let (p0, l0) = momenta(&start);
    let pn = p0.iter().map(|v| v * v).sum::<f64>().sqrt();
    let ln = l0.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut worst: (f64, f64) = (0.0, 0.0);
    for level in &run.levels {
        let (p, l) = momenta(level);
        for i in 0..3 {
            worst.0 = worst.0.max((p[i] - p0[i]).abs() / pn);
            worst.1 = worst.1.max((l[i] - l0[i]).abs() / ln);
        }
    }
    // the body really deformed and rotated
    let last = run.levels.last().unwrap();
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
    let (mut model, bottom, top) = block(false);
    model.dirichlet.push(Dirichlet {
        nodes: bottom.clone(),
        field: Field::Phi,
        value: 0.0,
    });
    let corner = model.mesh.nearest_node([2e-3, 2e-3, 1e-3]);
    for scheme in [
        Method::Midpoint,
        Method::Newmark {
            beta: 0.25,
            gamma: 0.5,
        },
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
    let mesh = box_mesh([l, 0.02, 0.02], [40, 1, 1], ElementKind::Hex8);
    let mut model = Model::new(mesh, Arc::new(ElectroNeoHooke::new(mu, 0.0, 1.0))).unwrap();
    for f in [Field::Ux, Field::Uy, Field::Uz, Field::Phi] {
        model.fix("x0", f, 0.0).unwrap();
    }
    let all: Vec<usize> = (0..model.mesh.n_nodes()).collect();
    model.dirichlet.push(Dirichlet {
        nodes: all.clone(),
        field: Field::Phi,
        value: 0.0,
    });
    let f1 = (2.0 * mu / RHO).sqrt() / (4.0 * l);
    let period = 1.0 / f1;
    let dt = period / 100.0;
    let mut v0 = vec![0.0; model.mesh.n_nodes() * FIELDS];
    for (a, x) in model.mesh.nodes.iter().enumerate() {
        v0[a * FIELDS] = 1e-4 * (std::f64::consts::PI * x[0] / (2.0 * l)).sin();
    }
    let run = simulate(
        &model,
        &[],
        &[],
        0.0,
        0.0,
        Method::Midpoint,
        dt,
        500,
        Some(v0),
    );
    let tip = model.mesh.nearest_node([l, 0.0, 0.0]);
    let v: Vec<(f64, f64)> = run
        .levels
        .iter()
        .map(|lv| (lv.t, lv.v[tip * FIELDS]))
        .collect();
    let mut crossings = Vec::new();
    for w in v.windows(2) {
        if w[0].1 > 0.0 && w[1].1 <= 0.0 {
            let t = w[0].0 + (w[1].0 - w[0].0) * w[0].1 / (w[0].1 - w[1].1);
            crossings.push(t);
        }
    }
    assert!(crossings.len() >= 4, "{crossings:?}");
    let measured = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    let rel = (1.0 / measured - f1).abs() / f1;
    eprintln!(
        "bar: f1 = {f1:.4} Hz analytic, {:.4} Hz computed, rel. error {rel:.2e}",
        1.0 / measured
    );
    assert!(rel < 0.01);
}

/// With viscosity the free vibration decays, the dissipated energy never decreases, and the energy
/// balance kinetic + stored − electric + dissipated closes to the integrator's accuracy: its
/// deviation falls ≈4× when Δt is halved.
#[test]
fn viscous_vibration_decays_and_balances_energy() {
    let (mut model, bottom, top) = block(false);
    model.dirichlet.push(Dirichlet {
        nodes: bottom.clone(),
        field: Field::Phi,
        value: 0.0,
    });
    let eta = 5.0; // Pa·s
    let dt = 2e-6;
    let run = simulate(
        &model,
        &top,
        &bottom,
        20e3,
        eta,
        Method::Midpoint,
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
        Method::Midpoint,
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
        Method::Midpoint,
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
        let ramp = w(Shape::Ramp { rise_time: 0.5 }).value(t);
        assert!((ramp - (off + a * (t / 0.5).min(1.0))).abs() < 1e-9);
    }
}

/// The trapezoidal discrete Lagrangian (explicit Störmer–Verlet on the reduced Lagrangian): momenta
/// of a free body conserved to round-off, energy oscillation bounded and O(Δt²), viscous balance
/// closes at O(Δt²). Δt is kept below its stability limit (≈2e-5 s for this mesh).
#[test]
fn trapezoidal_integrator_conserves_momenta_and_energy() {
    let (mut model, bottom, top) = block(false);
    model.dirichlet.push(Dirichlet {
        nodes: bottom.clone(),
        field: Field::Phi,
        value: 0.0,
    });
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
