//! The lumped models (docs/lumped.md; `deasim::lumped`): the diaphragm Ritz model of the circular
//! actuator (docs/validation.md) and the dimensionless Gent membrane of DielectricElastomers.jl.
//! Figures are printed (`cargo test --release --test lumped -- --nocapture`) and collected in
//! docs/lumped.md.

use std::f64::consts::PI;
use std::sync::Arc;

use deasim::lumped::{Diaphragm, DiaphragmParams, GentMembrane, LumpedError};
use deasim::material::{registry, Material, MaterialParams};
use deasim::waveform::{FourierBase, Shape, Waveform};

fn preset(name: &str) -> Arc<dyn Material> {
    let (m, p) = registry::preset(name).unwrap();
    registry::build(m, &p).unwrap().0
}

/// Split neo-Hooke μ/2(Ī₁ − 3) + volumetric, εᵣ = 4.7.
fn neo_hooke(mu: f64, kappa: f64) -> Arc<dyn Material> {
    let p = MaterialParams {
        mu: vec![mu],
        kappa: Some(kappa),
        permittivity: Some(4.7),
        ..Default::default()
    };
    registry::build("neo-hooke-split", &p).unwrap().0
}

fn diaphragm(mat: Arc<dyn Material>, viscosity: f64) -> Diaphragm {
    let mut p = DiaphragmParams::reference_study();
    p.viscosity = viscosity;
    Diaphragm::new(p, mat).unwrap()
}

fn study() -> Diaphragm {
    diaphragm(preset("vhb4910-yeoh"), 0.0)
}

fn unipolar(shape: Shape, amplitude: f64) -> Waveform {
    Waveform {
        shape,
        amplitude,
        offset: 0.0,
        phase_deg: 0.0,
    }
}

/// As x → 0 the Ritz stiffness Π'' tends to the annular-membrane stiffness 2πT₀/ln(b/a)
/// (docs/theory.md, membrane statics), T₀ = σ₀h₀ the pre-tension. The log shape is that problem's exact solution and
/// its small-deflection integrand is constant in ln r, so only the O(x²) terms differ: at
/// x = 1e-7 m they are ~1e-11; tolerance 1e-4 as asked.
#[test]
fn small_deflection_stiffness_is_the_annular_membrane_formula() {
    for (name, mat) in [
        ("neo-Hooke μ = 100 kPa", neo_hooke(1e5, 1e8)),
        ("vhb4910-yeoh", preset("vhb4910-yeoh")),
    ] {
        let d = diaphragm(mat, 0.0);
        let k = d.stiffness(1e-7, 0.0).unwrap();
        let k0 = d.membrane_stiffness();
        let rel = (k / k0 - 1.0).abs();
        println!(
            "{name}: T0 = {:.6} N/m, h0 = {:.6e} m, 2πT0/ln(b/a) = {k0:.6} N/m, Π''(1e-7 m) = {k:.6} N/m, rel. diff {rel:.1e}",
            d.prestress_tension(),
            d.flat_thickness()
        );
        assert!(rel < 1e-4, "{name}: {k} vs {k0}");
    }
}

/// Every hand-written derivative against a central difference of the quantity it differentiates:
/// Π' vs Π, Π'' vs Π', C' vs C, C'' vs C', at small, moderate and large deflection and up to
/// 40 kV. Step 1e-4·x: truncation ~1e-8, round-off of Π (~1 J of pre-stretch energy) ~1e-9
/// relative to the force; tolerance 1e-6.
#[test]
fn hand_written_derivatives_match_finite_differences() {
    let d = study();
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    let mut worst = [0.0f64; 4];
    for x in [3e-4, 3e-3, 1.2e-2] {
        let h = 1e-4 * x;
        for v in [0.0, 5e3, 4e4] {
            let fd = |f: &dyn Fn(f64) -> f64| (f(x + h) - f(x - h)) / (2.0 * h);
            let errs = [
                rel(fd(&|y| d.potential(y, v).unwrap()), d.force(x, v).unwrap()),
                rel(fd(&|y| d.force(y, v).unwrap()), d.stiffness(x, v).unwrap()),
                rel(
                    fd(&|y| d.capacitance(y).unwrap()),
                    d.capacitance_slope(x).unwrap(),
                ),
                rel(
                    fd(&|y| d.capacitance_slope(y).unwrap()),
                    d.capacitance_curvature(x).unwrap(),
                ),
            ];
            for (w, e) in worst.iter_mut().zip(errs) {
                *w = w.max(e);
            }
            assert!(errs.iter().all(|e| *e < 1e-6), "x {x} V {v}: {errs:?}");
        }
    }
    println!(
        "largest relative FD differences: Π' {:.1e}, Π'' {:.1e}, C' {:.1e}, C'' {:.1e}",
        worst[0], worst[1], worst[2], worst[3]
    );
}

/// The reference study (a = 7.5 mm, b = 35 mm, c = 15 mm, H = 1 mm, λp = 2, m = 46.22 g, Yeoh of
/// its Table 2, ρ = 960 kg/m³). The study measured 2 mm; nothing is tuned here. Checked: the
/// equilibrium is one (|Π'| tiny, k > 0), and since the slope there is small (x/(aL) ≈ 0.02) it
/// is the linear estimate W/k₀ to within 1 %.
#[test]
fn reference_study_static_deflection_and_linearisation() {
    let d = study();
    let x = d.static_deflection(0.0).unwrap();
    let lin = d.linearise().unwrap();
    println!(
        "reference study, vhb4910-yeoh: static deflection {:.4} mm (measured in the study: 2 mm)",
        x * 1e3
    );
    println!("{lin}");
    println!(
        "study's force S ε V²/d² per V²: {:.4e} N/V² vs β = {:.4e} N/V²",
        PI * (15e-3f64.powi(2) - 7.5e-3f64.powi(2)) * d.permittivity() / d.flat_thickness().powi(2),
        lin.force_per_volt2
    );
    assert!(d.force(x, 0.0).unwrap().abs() < 1e-9 * d.weight());
    assert!(lin.stiffness > 0.0);
    let linear = d.weight() / d.membrane_stiffness();
    assert!((x / linear - 1.0).abs() < 0.01, "{x} vs {linear}");
    assert_eq!(lin.equilibrium, x);
    assert!((d.natural_frequency(0.0).unwrap() / lin.natural_frequency() - 1.0).abs() < 1e-12);
    for name in ["vhb4910-gent", "vhb4910-gent-liu", "vhb4910-ab-wang"] {
        let l = diaphragm(preset(name), 0.0).linearise().unwrap();
        println!(
            "{name}: static deflection {:.4} mm, k = {:.3} N/m, f_n = {:.3} Hz",
            l.equilibrium * 1e3,
            l.stiffness,
            l.natural_frequency()
        );
    }
}

/// A voltage lowers the stiffness and raises the static deflection monotonically until the
/// equilibrium is lost. Neo-Hooke (μ = 25 kPa): its energy grows like λ_r² as does the electric
/// energy, so tension is lost at a finite voltage (Yeoh's C₃₀ term re-stiffens instead).
#[test]
fn voltage_softens_until_the_equilibrium_is_lost() {
    let d = diaphragm(neo_hooke(25e3, 25e7), 0.0);
    let (mut last_x, mut last_k) = (0.0, f64::INFINITY);
    let mut lost = None;
    for i in 0..=60 {
        let v = 500.0 * i as f64;
        match d.static_deflection(v) {
            Ok(x) => {
                let k = d.stiffness(x, v).unwrap();
                assert!(x > last_x && k < last_k, "V {v}: x {x} k {k}");
                (last_x, last_k) = (x, k);
            }
            Err(e) => {
                assert!(matches!(e, LumpedError::NoEquilibrium { .. }), "{e}");
                lost = Some((v, e));
                break;
            }
        }
    }
    let (v, e) = lost.expect("the equilibrium must be lost below 30 kV");
    println!(
        "neo-Hooke 25 kPa: last equilibrium {:.3} mm, k = {last_k:.2} N/m at {} V; {e}",
        last_x * 1e3,
        v - 500.0
    );
}

/// Maxwell stress: in the flat state the voltage lowers the radial tension of the electroded ring
/// by εE²h₀ (E = V/h₀). With the log shape the ring a..c carries the fraction ln(c/a)/ln(b/a) of
/// the membrane's small-deflection stiffness, so
///   k(V) = 2π/ln(b/a) · [T₀ − εE²h₀ ln(c/a)/ln(b/a)]
/// (incompressible thickness change; compressibility changes the electric term by O(μ/K)).
/// Checked at x = 1e-7 m with εE²h₀ ≈ 0.3 T₀: neo-Hooke with K/μ = 1e6 to 1e-5 of the reduction,
/// the Yeoh preset (K/μ ≈ 2300) to 2e-3.
#[test]
fn maxwell_stress_lowers_the_small_deflection_stiffness() {
    for (name, mat, tol) in [
        ("neo-Hooke K/μ = 1e6", neo_hooke(1e5, 1e11), 1e-5),
        ("vhb4910-yeoh", preset("vhb4910-yeoh"), 2e-3),
    ] {
        let d = diaphragm(mat, 0.0);
        let p = d.params();
        let (l, lc) = (
            (p.rim_radius / p.pad_radius).ln(),
            (p.electrode_radius / p.pad_radius).ln(),
        );
        let h0 = d.flat_thickness();
        let t0 = d.prestress_tension();
        // voltage with εE²h₀ = 0.3 T₀
        let v = (0.3 * t0 * h0 / d.permittivity()).sqrt();
        let maxwell = d.permittivity() * v * v / h0;
        let predicted = 2.0 * PI / l * maxwell * lc / l;
        let k0 = d.stiffness(1e-7, 0.0).unwrap();
        let kv = d.stiffness(1e-7, v).unwrap();
        let ratio = (k0 - kv) / predicted;
        println!("{name}: V = {v:.0} V, k(0) = {k0:.4} N/m, k(V) = {kv:.4} N/m, reduction / Maxwell prediction = {ratio:.7}");
        assert!((ratio - 1.0).abs() < tol, "{name}: {ratio}");
    }
}

/// Undamped free oscillation of the nonlinear model (2 mm from equilibrium, 10 periods, Δt = T/40):
/// the midpoint rule keeps Π + ½m_eff v² bounded, no drift (the last period's error is not larger
/// than twice the first's) and small (1e-3 of the oscillation energy: O((ωΔt)²)); with viscosity
/// the energy falls.
#[test]
fn energy_is_conserved_without_viscosity_and_dissipated_with() {
    let calm = unipolar(Shape::Constant, 0.0);
    let d = study();
    let x0 = d.static_deflection(0.0).unwrap();
    let period = 1.0 / d.natural_frequency(0.0).unwrap();
    let dt = period / 40.0;
    let h = d
        .simulate_from(&calm, x0 + 2e-3, 0.0, 10.0 * period, dt)
        .unwrap();
    let e0 = h.samples[0].energy;
    let e_osc = e0 - d.potential(x0, 0.0).unwrap();
    let err = |lo: f64, hi: f64| {
        h.samples
            .iter()
            .filter(|s| s.time >= lo && s.time <= hi)
            .map(|s| (s.energy - e0).abs())
            .fold(0.0, f64::max)
            / e_osc
    };
    let (first, last, all) = (
        err(0.0, period),
        err(9.0 * period, 10.0 * period),
        err(0.0, 10.0 * period),
    );
    println!("undamped, Δt = T/40: oscillation energy {e_osc:.4e} J, max |ΔE|/E_osc: first period {first:.2e}, last {last:.2e}, all {all:.2e}");
    assert!(
        all < 1e-3 && last < 2.0 * first.max(1e-12),
        "{first} {last} {all}"
    );
    let damped = diaphragm(preset("vhb4910-yeoh"), 1e5);
    let hd = damped
        .simulate_from(&calm, x0 + 2e-3, 0.0, 10.0 * period, dt)
        .unwrap();
    let end = hd.samples.last().unwrap().energy - d.potential(x0, 0.0).unwrap();
    println!("η = 1e5 Pa·s: c(x0) = {:.3e} N s/m, c(x0 + 2 mm) = {:.3e} N s/m; oscillation energy after 10 periods {:.3e} of the initial", damped.damping(x0).unwrap(), damped.damping(x0 + 2e-3).unwrap(), end / e_osc);
    assert!(end < 0.5 * e_osc && end > 0.0);
}

/// Second-order convergence of the midpoint rule: nonlinear free oscillation (5 mm amplitude,
/// slope ≈ 0.4 at the pad edge; Δt from T/80, T the small-amplitude period: coarser steps are not
/// yet asymptotic at this amplitude) and the damped linearised model under a sine drive; error at
/// the end time against Δt/32 (resp. /64); halving Δt must divide the error by 4 (accepted 3.5–4.5).
#[test]
fn the_integrator_converges_at_second_order() {
    let d = study();
    let x0 = d.static_deflection(0.0).unwrap();
    let period = 1.0 / d.natural_frequency(0.0).unwrap();
    let calm = unipolar(Shape::Constant, 0.0);
    let end = |dt: f64| {
        let h = d
            .simulate_from(&calm, x0 + 5e-3, 0.0, 2.0 * period, dt)
            .unwrap();
        h.samples.last().unwrap().deflection
    };
    let base = period / 80.0;
    let reference = end(base / 32.0);
    let errs: Vec<f64> = (0..3)
        .map(|i| (end(base / 2f64.powi(i)) - reference).abs())
        .collect();
    let ratios = [errs[0] / errs[1], errs[1] / errs[2]];
    println!("nonlinear free oscillation, Δt = T/80, T/160, T/320: errors {:.3e} {:.3e} {:.3e}, ratios {:.3} {:.3}", errs[0], errs[1], errs[2], ratios[0], ratios[1]);
    assert!(ratios.iter().all(|r| (3.5..4.5).contains(r)), "{ratios:?}");

    let mut lin = d.linearise().unwrap();
    lin.damping = 0.05 * 2.0 * (lin.stiffness * lin.mass).sqrt();
    let sine = unipolar(
        Shape::Sine {
            frequency: 20.0,
            bipolar: false,
        },
        3e3,
    );
    let end = |dt: f64| {
        lin.simulate(&sine, 0.1, dt)
            .unwrap()
            .samples
            .last()
            .unwrap()
            .deflection
    };
    let reference = end(1e-3 / 64.0);
    let errs: Vec<f64> = (0..3)
        .map(|i| (end(1e-3 / 2f64.powi(i)) - reference).abs())
        .collect();
    let ratios = [errs[0] / errs[1], errs[1] / errs[2]];
    println!("linearised, ζ = 0.05, 20 Hz sine, Δt = 1, 0.5, 0.25 ms: errors {:.3e} {:.3e} {:.3e}, ratios {:.3} {:.3}", errs[0], errs[1], errs[2], ratios[0], ratios[1]);
    assert!(ratios.iter().all(|r| (3.5..4.5).contains(r)), "{ratios:?}");
}

/// Unipolar 0..3 kV at 2 Hz as truncated Fourier series (15 odd harmonics; crate::waveform): the
/// extra deflection averaged over whole periods orders square > sine > triangle, as their mean V²
/// (≈ V²/2, 3V²/8, V²/3); the square wave also gives the largest peak. Both the nonlinear model and
/// its linearisation; 2 periods after the static start, η = 1e5 Pa·s, Δt = 0.5 ms (T_n/65).
#[test]
fn fourier_waveforms_order_the_mean_deflection() {
    let d = diaphragm(preset("vhb4910-yeoh"), 1e5);
    let lin = d.linearise().unwrap();
    let x0 = lin.equilibrium;
    let (period, t_end, dt) = (0.5, 1.0, 5e-4);
    let mut rows = Vec::new();
    for base in [
        FourierBase::Square,
        FourierBase::Sine,
        FourierBase::Triangle,
    ] {
        let w = unipolar(
            Shape::Fourier {
                base,
                frequency: 2.0,
                terms: 15,
                bipolar: false,
            },
            3e3,
        );
        let h = d.simulate(&w, t_end, dt).unwrap();
        let hl = lin.simulate(&w, t_end, dt).unwrap();
        let mean = h.mean_deflection(0.0, 2.0 * period) - x0;
        let peak = h.max_deflection(0.0, t_end) - x0;
        let mean_l = hl.mean_deflection(0.0, 2.0 * period) - x0;
        let mean_v2 =
            h.samples.iter().map(|s| s.voltage * s.voltage).sum::<f64>() / h.samples.len() as f64;
        println!(
            "{base:?}: mean V² = {:.4} (3 kV)², mean extra deflection {:.4e} m (linearised {:.4e} m), largest extra {:.4e} m",
            mean_v2 / 9e6,
            mean,
            mean_l,
            peak
        );
        rows.push((mean, peak, mean_l));
    }
    assert!(rows[0].0 > rows[1].0 && rows[1].0 > rows[2].0, "{rows:?}");
    assert!(rows[0].2 > rows[1].2 && rows[1].2 > rows[2].2, "{rows:?}");
    assert!(rows[0].1 > rows[1].1 && rows[0].1 > rows[2].1, "{rows:?}");
}

/// Near the loaded state the linearisation is the model: under the exact 3 kV unipolar square
/// wave at 2 Hz (one period) the two histories differ by less than 1 % of the extra deflection.
#[test]
fn the_linearisation_follows_the_nonlinear_model_at_3kv() {
    let d = study();
    let lin = d.linearise().unwrap();
    let w = unipolar(
        Shape::Square {
            frequency: 2.0,
            duty: 0.5,
            bipolar: false,
        },
        3e3,
    );
    let (h, hl) = (
        d.simulate(&w, 0.5, 5e-4).unwrap(),
        lin.simulate(&w, 0.5, 5e-4).unwrap(),
    );
    let extra = h.max_deflection(0.0, 0.5) - lin.equilibrium;
    let diff = h
        .samples
        .iter()
        .zip(&hl.samples)
        .map(|(a, b)| (a.deflection - b.deflection).abs())
        .fold(0.0, f64::max);
    let cap = h.samples[100].capacitance;
    println!(
        "3 kV square: largest extra deflection {extra:.4e} m, nonlinear − linear ≤ {diff:.2e} m; C = {cap:.5e} F, largest field {:.4e} V/m",
        h.samples.iter().map(|s| s.max_field).fold(0.0, f64::max)
    );
    assert!(diff < 0.01 * extra, "{diff} vs {extra}");
}

fn jl_membrane() -> GentMembrane {
    GentMembrane {
        jm: 100.0,
        pressure: 0.5,
        v_dc: 0.1,
        v_ac: 0.0,
        omega: 0.0,
        damping: 0.0,
    }
}

/// DielectricElastomers.jl's example (Sheng et al. 2014): Jm = 100, P = 0.5, V_dc = 0.1, V_ac = 0 gives
/// λ = 1.149229 and small-oscillation frequency 1.6727, which is the *angular* frequency √k
/// (dimensionless rad per unit time; √k/2π = 0.2662 would be the cyclic one). A free oscillation
/// (amplitude 1e-4, undamped, Δt = T/400: midpoint phase error (ωΔt)²/24 ≈ 1e-5) has the period
/// 2π/√k to 1e-4 and conserves ½λ̇² + Π to 1e-5 of its oscillation energy (the midpoint rule is
/// exact for a quadratic energy; the error is O((ωΔt)²) = 2.5e-4 times the small anharmonic part).
#[test]
fn gent_membrane_matches_dielectric_elastomers_jl() {
    let m = jl_membrane();
    let l = m.static_stretch().unwrap();
    let w = m.angular_frequency().unwrap();
    println!(
        "Gent membrane: λ = {l:.7}, √k = {w:.6} (period {:.5})",
        2.0 * PI / w
    );
    assert!((l - 1.149229).abs() < 5e-7, "{l}");
    assert!((w - 1.6727).abs() < 5e-5, "{w}");
    let period = 2.0 * PI / w;
    let h = m
        .simulate(l + 1e-4, 0.0, 20.0 * period, period / 400.0)
        .unwrap();
    // upward crossings of the equilibrium, linearly interpolated
    let crossings: Vec<f64> = h
        .windows(2)
        .filter(|p| p[0].stretch < l && p[1].stretch >= l)
        .map(|p| {
            p[0].time + (l - p[0].stretch) / (p[1].stretch - p[0].stretch) * (p[1].time - p[0].time)
        })
        .collect();
    let measured = (crossings.last().unwrap() - crossings[0]) / (crossings.len() - 1) as f64;
    let e0 = h[0].energy;
    let e_osc = e0 - m.potential(l, 0.0).unwrap();
    let drift = h.iter().map(|s| (s.energy - e0).abs()).fold(0.0, f64::max) / e_osc;
    println!("free oscillation: period {measured:.6} vs 2π/√k = {period:.6} ({} periods), max |ΔE|/E_osc = {drift:.1e}", crossings.len() - 1);
    assert!(
        (measured / period - 1.0).abs() < 1e-4,
        "{measured} vs {period}"
    );
    assert!(drift < 1e-5, "{drift}");
    // a driven, damped run stays finite and bounded below the locking stretch
    let driven = GentMembrane {
        v_ac: 0.2,
        omega: 1.0,
        damping: 0.1,
        ..m
    };
    let hd = driven.simulate(l, 0.0, 100.0, 0.01).unwrap();
    let max = hd.iter().map(|s| s.stretch).fold(0.0, f64::max);
    println!("driven (V_ac = 0.2, Ω = 1, c = 0.1): largest λ over 100 time units {max:.5}");
    assert!(max > l && max < 2.0);
}

/// Bad parameters are errors with the parameter's name, never panics.
#[test]
fn bad_parameters_are_errors() {
    let mat = preset("vhb4910-yeoh");
    let base = DiaphragmParams::reference_study();
    let cases: Vec<(&str, DiaphragmParams)> = vec![
        (
            "rim_radius",
            DiaphragmParams {
                rim_radius: base.pad_radius,
                ..base
            },
        ),
        (
            "electrode_radius",
            DiaphragmParams {
                electrode_radius: 40e-3,
                ..base
            },
        ),
        (
            "electrode_radius",
            DiaphragmParams {
                electrode_radius: 5e-3,
                ..base
            },
        ),
        (
            "thickness",
            DiaphragmParams {
                thickness: 0.0,
                ..base
            },
        ),
        (
            "pad_radius",
            DiaphragmParams {
                pad_radius: -1.0,
                ..base
            },
        ),
        (
            "prestretch",
            DiaphragmParams {
                prestretch: f64::NAN,
                ..base
            },
        ),
        (
            "prestretch",
            DiaphragmParams {
                prestretch: 0.8,
                ..base
            },
        ),
        ("mass", DiaphragmParams { mass: -1.0, ..base }),
        (
            "viscosity",
            DiaphragmParams {
                viscosity: -1.0,
                ..base
            },
        ),
        (
            "gravity",
            DiaphragmParams {
                gravity: f64::INFINITY,
                ..base
            },
        ),
        (
            "quadrature_points",
            DiaphragmParams {
                quadrature_points: 1,
                ..base
            },
        ),
    ];
    for (name, p) in cases {
        match Diaphragm::new(p, mat.clone()) {
            Err(LumpedError::InvalidParameter { name: n, .. }) => assert_eq!(n, name),
            other => panic!("{name}: {other:?}"),
        }
    }
    let d = study();
    let w = unipolar(Shape::Constant, 0.0);
    let err = d.simulate(&w, 1.0, 0.0).unwrap_err();
    println!("{err}");
    assert!(matches!(
        err,
        LumpedError::InvalidParameter { name: "dt", .. }
    ));
    assert!(d.static_deflection(f64::NAN).is_err());
    assert!(GentMembrane {
        jm: 0.0,
        ..jl_membrane()
    }
    .static_stretch()
    .is_err());
    assert!(GentMembrane {
        pressure: -1.0,
        ..jl_membrane()
    }
    .static_stretch()
    .is_err());
}
