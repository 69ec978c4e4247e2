//! `deasim validate`: verification cases against closed-form solutions, printed as a table of
//! case, expected, computed, relative error and pass/fail.

use crate::analytic::{incompressible_neo_hooke_pull_in, Film};
use crate::job::statics::solve_static;
use crate::material::{ElectroNeoHooke, EPSILON_0};
use crate::mesh::ElementKind;
use crate::problem::examples::{film, FILM_EPS_R, FILM_LAMBDA, FILM_MU, FILM_SIZE};
use crate::problem::model::Model;
use crate::problem::statics::nodal_reactions;
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::StepControl;
use std::sync::Arc;

/// One verification result.
#[derive(Debug, Clone)]
pub struct Case {
    pub name: String,
    pub expected: f64,
    pub computed: f64,
    /// Largest accepted relative error.
    pub tolerance: f64,
}

impl Case {
    pub fn rel_error(&self) -> f64 {
        (self.computed - self.expected).abs() / self.expected.abs()
    }
    pub fn passed(&self) -> bool {
        self.rel_error() <= self.tolerance
    }
}

fn film_reference(lambda: f64) -> Film {
    Film {
        mu: FILM_MU,
        lambda,
        eps: FILM_EPS_R * EPSILON_0,
        c2: 0.0,
    }
}

/// Static solve of a film model to its target voltage; the final state.
fn solve_film(model: &Model, steps: usize) -> Result<Vec<f64>, String> {
    let out = solve_static(
        model,
        None,
        &StepControl {
            steps,
            ..Default::default()
        },
        &NewtonSettings::default(),
        |_, _| {},
    );
    out.result.map_err(|e| e.to_string())?;
    Ok(out.state)
}

/// Stretches (λ, t) read off the corner node (10, 10, 1) mm of a film state.
fn stretches(model: &Model, state: &[f64]) -> (f64, f64) {
    let n = model.mesh.nearest_node(FILM_SIZE);
    (
        1.0 + state[n * 4] / FILM_SIZE[0],
        1.0 + state[n * 4 + 2] / FILM_SIZE[2],
    )
}

/// Largest voltage with a converged stable state when ramping `model` (whose top electrode is at
/// `v_max`) in `steps` steps.
fn pull_in_voltage(model: &Model, v_max: f64, steps: usize) -> Result<f64, String> {
    let out = solve_static(
        model,
        None,
        &StepControl {
            steps,
            ..Default::default()
        },
        &NewtonSettings::default(),
        |_, _| {},
    );
    match out.result {
        Ok(_) => Err(format!("no instability up to {v_max} V")),
        Err(f) if f.limit_point => Ok(f.last_converged * v_max),
        Err(f) => Err(f.to_string()),
    }
}

/// Runs every case.
pub fn cases() -> Result<Vec<Case>, String> {
    let mut out = Vec::new();
    let reference = film_reference(FILM_LAMBDA);
    let h = FILM_SIZE[2];
    for (kind, v) in [
        (ElementKind::Hex8, 10e3),
        (ElementKind::Hex8, 30e3),
        (ElementKind::Tet4, 20e3),
    ] {
        let model = film([3, 3, 2], kind, v).map_err(|e| e.to_string())?;
        let state = solve_film(&model, 10)?;
        let (l, t) = stretches(&model, &state);
        let s = reference.state(v / h).ok_or("closed form beyond pull-in")?;
        out.push(Case {
            name: format!("film {} {:.0} kV: in-plane stretch", kind.name(), v / 1e3),
            expected: s.lambda,
            computed: l,
            tolerance: 1e-9,
        });
        out.push(Case {
            name: format!("film {} {:.0} kV: thickness stretch", kind.name(), v / 1e3),
            expected: s.t,
            computed: t,
            tolerance: 1e-9,
        });
        if v == 10e3 {
            // charge on the quarter film's top electrode: Q = D·A with D = ε λ²/t · V/H
            let model_ref = &model;
            let r = nodal_reactions(model_ref, &state)?;
            let top = model.mesh.node_sets["z1"].clone();
            let q: f64 = -top.iter().map(|&n| r[n * 4 + 3]).sum::<f64>();
            let area = FILM_SIZE[0] * FILM_SIZE[1];
            let expected = FILM_EPS_R * EPSILON_0 * s.lambda * s.lambda / s.t * v / h * area;
            out.push(Case {
                name: "film hex8 10 kV: electrode charge (C)".into(),
                expected,
                computed: q,
                tolerance: 1e-9,
            });
        }
    }
    // pull-in of the film (closed form 33.695 kV): the last converged voltage lies within 0.5 % below
    let (ec, _) = reference.pull_in();
    let model = film([2, 2, 1], ElementKind::Hex8, 40e3).map_err(|e| e.to_string())?;
    out.push(Case {
        name: "film pull-in voltage (V)".into(),
        expected: ec * h,
        computed: pull_in_voltage(&model, 40e3, 20)?,
        tolerance: 5e-3,
    });
    // nearly incompressible film (Λ = 1e4 μ): pull-in approaches Zhao & Suo's Φ̂c = 0.687365
    let lambda = 1e4 * FILM_MU;
    let mut model = film([2, 2, 1], ElementKind::Hex8, 40e3).map_err(|e| e.to_string())?;
    model.materials = vec![Arc::new(ElectroNeoHooke::new(FILM_MU, lambda, FILM_EPS_R))];
    let scale = h * (FILM_MU / (FILM_EPS_R * EPSILON_0)).sqrt();
    let (_, phi_c) = incompressible_neo_hooke_pull_in();
    out.push(Case {
        name: "incompressible limit pull-in, normalised voltage".into(),
        expected: phi_c,
        computed: pull_in_voltage(&model, 40e3, 20)? / scale,
        tolerance: 2e-3,
    });
    Ok(out)
}

/// Prints the table; exit status 0 when every case passes.
pub fn cmd_validate() -> i32 {
    match cases() {
        Ok(cases) => {
            println!(
                "{:<52} {:>14} {:>14} {:>10} {:>9}  result",
                "case", "expected", "computed", "rel_error", "tolerance"
            );
            let mut ok = true;
            for c in &cases {
                ok &= c.passed();
                println!(
                    "{:<52} {:>14.8e} {:>14.8e} {:>10.2e} {:>9.1e}  {}",
                    c.name,
                    c.expected,
                    c.computed,
                    c.rel_error(),
                    c.tolerance,
                    if c.passed() { "pass" } else { "FAIL" }
                );
            }
            println!(
                "{} passed, {} failed",
                cases.iter().filter(|c| c.passed()).count(),
                cases.iter().filter(|c| !c.passed()).count()
            );
            if ok {
                0
            } else {
                1
            }
        }
        Err(e) => {
            eprintln!("error: {e}");
            1
        }
    }
}
