//! The homogeneous film (docs/theory.md) under a ramped voltage.
//!
//! Reference: the closed-form compressible film state (`deasim::analytic::Film`), derived from the
//! energy of docs/theory.md; values checked against the closed form of `deasim::analytic`. Hex8 and tet4 (linear)
//! interpolations represent the homogeneous state exactly, so the computed stretches must match to
//! the Newton tolerance: |Δλ| < 1e-8. Pull-in: ramped to 40 kV, the solver must stop with the last
//! converged voltage within 0.5 % below the closed-form critical voltage 33.695 kV.

use deasim::job::statics::solve_static;
use deasim::mesh::ElementKind;
use deasim::problem::examples::{film, film_closed_form, FILM_SIZE};
use deasim::solve::newton::NewtonSettings;
use deasim::solve::stepping::StepControl;

/// Largest deviation of the computed stretches from the closed form over all load steps.
fn film_ramp_error(kind: ElementKind, threads: usize) -> (f64, usize) {
    let voltage = 30e3;
    let model = film([3, 3, 2], kind, voltage).unwrap();
    let reference = film_closed_form();
    let mut worst: f64 = 0.0;
    let mut steps = 0;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let outcome = pool.install(|| {
        solve_static(
            &model,
            None,
            &StepControl {
                steps: 15,
                ..Default::default()
            },
            &NewtonSettings::default(),
            |p, step| {
                let v = voltage * step.load;
                let s = reference.state(v / FILM_SIZE[2]).expect("below pull-in");
                for (n, x) in p.model.mesh.nodes.iter().enumerate() {
                    for i in 0..3 {
                        let stretch = if i == 2 { s.t } else { s.lambda };
                        let expect = (stretch - 1.0) * x[i];
                        let got = p.state[n * 4 + i];
                        // |Δλ| at this node = |Δu| / X
                        if x[i] > 0.0 {
                            worst = worst.max((got - expect).abs() / x[i]);
                        }
                    }
                    let phi = p.state[n * 4 + 3];
                    let expect_phi = v * x[2] / FILM_SIZE[2];
                    assert!(
                        (phi - expect_phi).abs() <= 1e-9 * voltage,
                        "potential at node {n}"
                    );
                }
                steps += 1;
            },
        )
    });
    outcome.result.expect("30 kV is below pull-in");
    (worst, steps)
}

#[test]
fn film_matches_closed_form_hex8_and_tet4_on_1_and_2_threads() {
    for kind in [ElementKind::Hex8, ElementKind::Tet4] {
        for threads in [1, 2] {
            let (err, steps) = film_ramp_error(kind, threads);
            eprintln!("{kind:?}, {threads} threads: {steps} steps, max |Δλ| = {err:.3e}");
            assert!(steps >= 15, "{kind:?}: {steps} accepted steps");
            assert!(
                err < 1e-8,
                "{kind:?}, {threads} threads: max |Δλ| = {err:e}"
            );
        }
    }
}

#[test]
fn ramp_to_40kv_stops_at_pull_in() {
    let model = film([2, 2, 1], ElementKind::Hex8, 40e3).unwrap();
    let (ec, _) = film_closed_form().pull_in();
    let v_crit = ec * FILM_SIZE[2];
    let outcome = solve_static(
        &model,
        None,
        &StepControl {
            steps: 20,
            ..Default::default()
        },
        &NewtonSettings::default(),
        |_, _| {},
    );
    let failure = outcome.result.expect_err("40 kV is beyond pull-in");
    assert!(failure.limit_point, "{failure:?}");
    let v_last = failure.last_converged * 40e3;
    eprintln!(
        "pull-in: last converged {v_last:.2} V, closed form {v_crit:.2} V; {}",
        failure.reason
    );
    assert!(
        v_last <= v_crit,
        "last converged {v_last} V above critical {v_crit} V"
    );
    assert!(
        v_last >= 0.995 * v_crit,
        "last converged {v_last} V, critical {v_crit} V"
    );
}
