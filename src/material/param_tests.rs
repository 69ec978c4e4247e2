//! The parameter vectors of the registry's materials and their exact parameter derivatives
//! against central finite differences (through [`Material::with_parameters`], so the names and
//! the rebuild are checked with them), and the derivatives of the Maxwell branches' update in
//! the committed internal variables.

use super::registry::{self, MaterialParams, MODELS};
use super::{Mat3, Material, PointHistory, Stress, Vec3};
use std::sync::Arc;

/// A general deformation: not symmetric, J ≈ 1.12.
fn general_f() -> Mat3 {
    Mat3::new(1.2, 0.1, -0.05, 0.02, 0.9, 0.1, 0.03, -0.04, 1.05)
}

/// A field of 0.3·√(μ₀/ε) in a general direction.
fn general_e0(m: &dyn Material) -> Vec3 {
    Vec3::new(0.2, -0.3, 1.0).normalize() * (m.shear_modulus() / m.permittivity()).sqrt() * 0.3
}

/// Every model with every parameter non-zero (c₁, c₂, C₂₀, C₃₀, D₂, D₃ too).
fn params(model: &str) -> MaterialParams {
    let base = MaterialParams {
        permittivity: Some(4.7),
        c1: Some(2e-12),
        c2: Some(3e-12),
        ..Default::default()
    };
    match model {
        "neo-hooke" => MaterialParams {
            mu: vec![1e5],
            lambda: Some(1e6),
            ..base
        },
        "neo-hooke-split" => MaterialParams {
            mu: vec![1e5],
            kappa: Some(1e6),
            ..base
        },
        "yeoh" => MaterialParams {
            c10: Some(5e4),
            c20: Some(-5e2),
            c30: Some(50.0),
            d1: Some(2e-6),
            d2: Some(1e-6),
            d3: Some(5e-7),
            ..base
        },
        "mooney-rivlin" => MaterialParams {
            c10: Some(4e4),
            c01: Some(1e4),
            d1: Some(2e-6),
            ..base
        },
        "gent" => MaterialParams {
            mu: vec![1e5],
            jm: Some(2.0),
            kappa: Some(1e6),
            ..base
        },
        "ogden" => MaterialParams {
            mu: vec![1.5e5, -2e3, 5e3],
            alpha: vec![1.3, -2.0, 5.0],
            kappa: Some(1e6),
            ..base
        },
        "arruda-boyce" | "arruda-boyce-series" => MaterialParams {
            mu: vec![1e5],
            lambda_m: Some(1.5),
            kappa: Some(1e6),
            ..base
        },
        _ => panic!("no parameters for {model}"),
    }
}

fn build(model: &str, p: &MaterialParams) -> Arc<dyn Material> {
    registry::build(model, p)
        .unwrap_or_else(|e| panic!("{model}: {e}"))
        .0
}

/// A Gent material with two Maxwell branches.
fn viscous() -> Arc<dyn Material> {
    let p = MaterialParams {
        branches: vec![(5e4, 0.3), (2e4, 4.0)],
        ..params("gent")
    };
    build("gent", &p)
}

/// The committed variables after one step from the virgin state to another deformation.
fn committed(m: &dyn Material) -> Vec<f64> {
    let mut a0 = vec![0.0; m.state_size()];
    m.initial_state(&mut a0);
    let mut a = vec![0.0; m.state_size()];
    let f1 = Mat3::new(1.1, 0.05, 0.0, 0.0, 0.95, 0.02, 0.01, 0.0, 1.03);
    let h = PointHistory {
        state: &a0,
        dt: 0.3,
    };
    m.update_state(&f1, &Vec3::zeros(), h, &mut a).unwrap();
    a
}

/// Fourth-order central difference of `g` at 0 with step `h`.
fn fd4<T>(h: f64, g: impl Fn(f64) -> T) -> T
where
    T: std::ops::Add<Output = T> + std::ops::Sub<Output = T> + std::ops::Mul<f64, Output = T>,
{
    (g(-2.0 * h) - g(2.0 * h) + (g(h) - g(-h)) * 8.0) * (1.0 / (12.0 * h))
}

/// `got` within 1e-6 of `want` relative to |want|, or both zero up to round-off of `scale`.
fn assert_close(what: &str, got: f64, want: f64, scale: f64) {
    let err = (got - want).abs();
    assert!(
        err <= 1e-6 * want.abs() || (want == 0.0 && err <= 1e-12 * scale),
        "{what}: finite differences {got:e}, exact {want:e} (relative {:e})",
        err / want.abs()
    );
}

/// Ψ, P and D0 of `stress_at` through θ ± 2h, ± h against the exact derivatives, entry by entry.
fn check_parameter_derivatives(label: &str, m: &Arc<dyn Material>, h: PointHistory) {
    let f = general_f();
    let e0 = general_e0(m.as_ref());
    let p = m.parameters().expect("a registry material");
    let exact = m.parameter_derivatives_at(&f, &e0, h).unwrap();
    assert_eq!(exact.len(), p.values.len(), "{label}: {:?}", p.names);
    // each entry alone is that entry, bit for bit; one past the last is refused
    for (i, all) in exact.iter().enumerate() {
        let one = m.parameter_derivative_at(&f, &e0, h, i).unwrap();
        assert_eq!(&one, all, "{label}: entry {i} alone");
    }
    assert!(m.parameter_derivative_at(&f, &e0, h, exact.len()).is_err());
    // an entry said to leave D0 alone has ∂D0/∂θ = 0 exactly (the dielectric's do not)
    for (i, d) in exact.iter().enumerate() {
        if !m.parameter_enters_d0(i) {
            assert_eq!(d.d0, Vec3::zeros(), "{label}: {} enters D0", p.names[i]);
        }
    }
    let s0 = m.stress_at(&f, &e0, h).unwrap();
    for (i, name) in p.names.iter().enumerate() {
        let theta = p.values[i];
        assert!(theta != 0.0, "{label}: {name} = 0 is not checked");
        let at = |d: f64| {
            let mut t = p.values.clone();
            t[i] += d;
            let s = m
                .with_parameters(&t)
                .unwrap_or_else(|e| panic!("{label}: {e}"))
                .stress_at(&f, &e0, h)
                .unwrap();
            (s.energy, s.p, s.d0)
        };
        let step = 1e-3 * theta.abs();
        let g = |d: f64| {
            let (w, p, d0) = at(d);
            nalgebra::SVector::<f64, 13>::from_iterator(
                std::iter::once(w)
                    .chain(p.iter().copied())
                    .chain(d0.iter().copied()),
            )
        };
        let fd = fd4(step, g);
        let Stress { energy, p: dp, d0 } = &exact[i];
        let what = format!("{label}: ∂/∂{name}");
        let rel = |got: f64, want: f64| (got - want).abs() / want.abs().max(f64::MIN_POSITIVE);
        assert_close(&format!("{what} Ψ"), fd[0], *energy, s0.energy.abs());
        // P and D0 as tensors: the difference relative to the derivative's norm
        let fd_p = Mat3::from_iterator(fd.iter().skip(1).take(9).copied());
        let fd_d = Vec3::from_iterator(fd.iter().skip(10).copied());
        let (ep, ed) = ((fd_p - dp).norm(), (fd_d - d0).norm());
        assert!(
            ep <= 1e-6 * dp.norm() || (dp.norm() == 0.0 && ep <= 1e-12 * s0.p.norm()),
            "{what} P: {} vs {}",
            fd_p,
            dp
        );
        assert!(
            ed <= 1e-6 * d0.norm() || (d0.norm() == 0.0 && ed <= 1e-12 * s0.d0.norm()),
            "{what} D0: {fd_d} vs {d0} ({})",
            rel(ed, d0.norm())
        );
    }
}

#[test]
fn parameter_vectors_name_the_scenario_keys() {
    let names = |model: &str| build(model, &params(model)).parameters().unwrap().names;
    let el = ["permittivity", "c1", "c2"];
    let with_el =
        |mech: &[&str]| -> Vec<String> { mech.iter().chain(&el).map(|s| s.to_string()).collect() };
    assert_eq!(names("neo-hooke"), with_el(&["mu", "lambda"]));
    assert_eq!(names("neo-hooke-split"), with_el(&["mu", "kappa"]));
    assert_eq!(
        names("yeoh"),
        with_el(&["c10", "c20", "c30", "d1", "d2", "d3"])
    );
    assert_eq!(names("mooney-rivlin"), with_el(&["c10", "c01", "d1"]));
    assert_eq!(names("gent"), with_el(&["mu", "jm", "kappa"]));
    assert_eq!(
        names("ogden"),
        with_el(&["mu.0", "mu.1", "mu.2", "alpha.0", "alpha.1", "alpha.2", "kappa"])
    );
    for m in ["arruda-boyce", "arruda-boyce-series"] {
        assert_eq!(names(m), with_el(&["mu", "lambda_m", "kappa"]));
    }
    // a Yeoh D₂ = D₃ = 0 switches the terms off: no entries
    let p = MaterialParams {
        d2: None,
        d3: Some(0.0),
        ..params("yeoh")
    };
    assert_eq!(
        build("yeoh", &p).parameters().unwrap().names,
        with_el(&["c10", "c20", "c30", "d1"])
    );
    let v = viscous().parameters().unwrap();
    assert_eq!(
        v.names[6..],
        [
            "branches.0.mu",
            "branches.0.tau",
            "branches.1.mu",
            "branches.1.tau"
        ]
    );
    assert_eq!(v.values[6..], [5e4, 0.3, 2e4, 4.0]);
    assert_eq!(v.model, "gent");
    // the relative permittivity, as the scenario gives it
    assert!((v.values[3] - 4.7).abs() < 1e-14);
}

#[test]
fn with_parameters_rebuilds_the_same_model_and_validates() {
    let f = general_f();
    for &model in MODELS {
        let m = build(model, &params(model));
        let p = m.parameters().unwrap();
        let again = m.with_parameters(&p.values).unwrap();
        assert_eq!(again.parameters().unwrap(), p, "{model}");
        let e0 = general_e0(m.as_ref());
        let (a, b) = (m.stress(&f, &e0).unwrap(), again.stress(&f, &e0).unwrap());
        assert!((a.p - b.p).norm() <= 1e-14 * a.p.norm(), "{model}");
        // the registry's checks, naming the entry
        let mut bad = p.values.clone();
        bad[p.index("permittivity").unwrap()] = 0.5;
        assert_eq!(m.with_parameters(&bad).unwrap_err().key, "permittivity");
        let e = m.with_parameters(&p.values[1..]).unwrap_err();
        assert!(e.message.contains("expected"), "{e}");
    }
    let v = viscous();
    let mut t = v.parameters().unwrap().values;
    t[9] = -1.0;
    assert_eq!(v.with_parameters(&t).unwrap_err().key, "branches.1.tau");
    let gent = build("gent", &params("gent"));
    let mut t = gent.parameters().unwrap().values;
    t[2] = 0.0;
    assert_eq!(gent.with_parameters(&t).unwrap_err().key, "kappa");
}

/// ∂Ψ/∂θ, ∂P/∂θ, ∂D0/∂θ of all eight models with the dielectric part, at a general F and
/// E0 ≠ 0.
#[test]
fn parameter_derivatives_of_every_model_match_finite_differences() {
    for &model in MODELS {
        let m = build(model, &params(model));
        check_parameter_derivatives(model, &m, PointHistory::NONE);
        // the mechanical entries are known to leave D0 alone, the dielectric's not
        let p = m.parameters().unwrap();
        let n = p.values.len();
        let electric = crate::material::parameters::ELECTRIC;
        assert!(
            (0..n).all(|i| m.parameter_enters_d0(i) == (i >= n - electric)),
            "{model}: {:?}",
            p.names
        );
    }
}

/// The same for two Maxwell branches on a Gent material, in a step of Δt > 0 from a committed
/// state that is not the virgin one.
#[test]
fn parameter_derivatives_of_maxwell_branches_match_finite_differences() {
    let m = viscous();
    let a = committed(m.as_ref());
    check_parameter_derivatives("gent + 2 branches", &m, PointHistory { state: &a, dt: 0.2 });
    // and the instantaneous response (Δt = 0), where τ does not enter
    check_parameter_derivatives(
        "gent + 2 branches, dt = 0",
        &m,
        PointHistory { state: &a, dt: 0.0 },
    );
}

/// wᵀ ∂A_{n+1}/∂θ, ∂A_{n+1}/∂A_n, ∂A_{n+1}/∂F of the update, and wᵀ ∂P/∂A_n of the stress,
/// against central differences.
#[test]
fn state_derivatives_of_maxwell_branches_match_finite_differences() {
    let m = viscous();
    let f = general_f();
    let e0 = general_e0(m.as_ref());
    let a = committed(m.as_ref());
    let dt = 0.2;
    let n = m.state_size();
    let w: Vec<f64> = (0..n)
        .map(|i| ((i * 7 + 3) % 11) as f64 / 11.0 - 0.4)
        .collect();
    let update = |mat: &dyn Material, f: &Mat3, state: &[f64]| -> f64 {
        let mut new = vec![0.0; n];
        mat.update_state(f, &e0, PointHistory { state, dt }, &mut new)
            .unwrap();
        new.iter().zip(&w).map(|(x, y)| x * y).sum()
    };
    let vjp = m
        .update_state_vjp(&f, &e0, PointHistory { state: &a, dt }, &w)
        .unwrap();
    let p = m.parameters().unwrap();
    assert_eq!(vjp.theta.len(), p.values.len());
    for (i, name) in p.names.iter().enumerate() {
        let fd = fd4(1e-3 * p.values[i].abs(), |d| {
            let mut t = p.values.clone();
            t[i] += d;
            update(m.with_parameters(&t).unwrap().as_ref(), &f, &a)
        });
        assert_close(&format!("update ∂/∂{name}"), fd, vjp.theta[i], 1.0);
    }
    assert_eq!(vjp.state.len(), n);
    for s in 0..n {
        let fd = fd4(1e-4, |d| {
            let mut b = a.clone();
            b[s] += d;
            update(m.as_ref(), &f, &b)
        });
        assert_close(&format!("update ∂/∂A[{s}]"), fd, vjp.state[s], 1.0);
    }
    for r in 0..3 {
        for c in 0..3 {
            let fd = fd4(1e-4, |d| {
                let mut g = f;
                g[(r, c)] += d;
                update(m.as_ref(), &g, &a)
            });
            assert_close(&format!("update ∂/∂F[{r}{c}]"), fd, vjp.f[(r, c)], 1.0);
        }
    }
    assert_eq!(vjp.e0, Vec3::zeros());

    let wp = Mat3::new(0.3, -0.2, 0.5, 0.1, 0.7, -0.4, 0.2, 0.05, -0.6);
    let h = PointHistory { state: &a, dt };
    let sv = m.stress_state_vjp(&f, &e0, h, &wp).unwrap();
    assert_eq!(sv.len(), n);
    let p_scale = m.stress_at(&f, &e0, h).unwrap().p.norm();
    for s in 0..n {
        let fd = fd4(1e-4, |d| {
            let mut b = a.clone();
            b[s] += d;
            let st = m
                .stress_at(&f, &e0, PointHistory { state: &b, dt })
                .unwrap();
            st.p.dot(&wp)
        });
        assert_close(&format!("P ∂/∂A[{s}]"), fd, sv[s], p_scale);
    }

    // an elastic material has no internal variables: empty products
    let el = build("gent", &params("gent"));
    let v = el
        .update_state_vjp(&f, &e0, PointHistory::NONE, &[])
        .unwrap();
    assert!(v.state.is_empty() && v.theta.iter().all(|&x| x == 0.0));
    assert_eq!(v.theta.len(), 6);
    assert!(el
        .stress_state_vjp(&f, &e0, PointHistory::NONE, &wp)
        .unwrap()
        .is_empty());
}

/// The time of one stress evaluation, with and without the parameter derivatives (printed, not
/// asserted): `cargo test --release --lib stress_with_parameter_derivatives_timing -- --ignored
/// --nocapture`.
#[test]
#[ignore]
fn stress_with_parameter_derivatives_timing() {
    let f = general_f();
    for (label, m) in [
        ("gent", build("gent", &params("gent"))),
        ("ogden (3 terms)", build("ogden", &params("ogden"))),
        ("gent + 2 branches", viscous()),
    ] {
        let e0 = general_e0(m.as_ref());
        let a = committed(m.as_ref());
        let h = PointHistory {
            state: if m.state_size() > 0 { &a } else { &[] },
            dt: 0.2,
        };
        let n = 200_000;
        let mut sink = 0.0;
        let t = std::time::Instant::now();
        for i in 0..n {
            let g = f * (1.0 + 1e-9 * i as f64);
            sink += m.stress_at(&g, &e0, h).unwrap().energy;
        }
        let plain = t.elapsed().as_secs_f64() / n as f64;
        let t = std::time::Instant::now();
        for i in 0..n {
            let g = f * (1.0 + 1e-9 * i as f64);
            sink += m.stress_at(&g, &e0, h).unwrap().energy;
            sink += m.parameter_derivatives_at(&g, &e0, h).unwrap()[0].energy;
        }
        let both = t.elapsed().as_secs_f64() / n as f64;
        println!(
            "{label}: stress_at {:.0} ns, stress_at + parameter_derivatives_at {:.0} ns \
             ({} parameters; {sink:e})",
            plain * 1e9,
            both * 1e9,
            m.parameters().unwrap().values.len()
        );
    }
}

/// A single [`MaxwellBranch`](super::maxwell::MaxwellBranch) on a material gives the products of
/// the registry's one-branch material.
#[test]
fn single_branch_state_products_equal_the_registry_materials() {
    let p = MaterialParams {
        mu: vec![1e5],
        lambda: Some(1e6),
        permittivity: Some(4.7),
        branches: vec![(3e5, 0.5)],
        ..Default::default()
    };
    let registry = build("neo-hooke", &p);
    let single = super::maxwell::MaxwellBranch {
        equilibrium: super::ElectroNeoHooke::new(1e5, 1e6, 4.7),
        g: 3e5,
        tau: 0.5,
    };
    let f = general_f();
    let e0 = general_e0(registry.as_ref());
    let a = committed(registry.as_ref());
    let h = PointHistory { state: &a, dt: 0.2 };
    let w: Vec<f64> = (0..9).map(|i| i as f64 / 9.0 - 0.3).collect();
    let (x, y) = (
        registry.update_state_vjp(&f, &e0, h, &w).unwrap(),
        single.update_state_vjp(&f, &e0, h, &w).unwrap(),
    );
    assert_eq!((x.state, x.f), (y.state, y.f));
    assert!(y.theta.is_empty() && single.parameters().is_none());
    let wp = Mat3::new(0.3, -0.2, 0.5, 0.1, 0.7, -0.4, 0.2, 0.05, -0.6);
    assert_eq!(
        registry.stress_state_vjp(&f, &e0, h, &wp).unwrap(),
        single.stress_state_vjp(&f, &e0, h, &wp).unwrap()
    );
}
