//! The homogeneous film: hex8 and tet4 against the closed form of `analytic::Film` (stretches and
//! electrode charge), the ramp's pull-in against the closed-form critical voltage, and the nearly
//! incompressible film against Zhao & Suo's incompressible pull-in.

use super::Case;
use crate::analytic::incompressible_neo_hooke_pull_in;
use crate::job::statics::solve_static;
use crate::material::{ElectroNeoHooke, EPSILON_0};
use crate::mesh::ElementKind;
use crate::problem::examples::{film, film_closed_form, FILM_EPS_R, FILM_MU, FILM_SIZE};
use crate::problem::model::Model;
use crate::problem::statics::nodal_reactions;
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::StepControl;
use std::sync::Arc;

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
pub fn pull_in_voltage(model: &Model, v_max: f64, steps: usize) -> Result<f64, String> {
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

/// Stretches and charge at three voltages, then the two pull-in rows.
pub fn cases() -> Result<Vec<Case>, String> {
    let mut out = Vec::new();
    let reference = film_closed_form();
    let h = FILM_SIZE[2];
    let closed_form = "closed form, docs/theory.md";
    for (kind, v) in [
        (ElementKind::Hex8, 10e3),
        (ElementKind::Hex8, 30e3),
        (ElementKind::Tet4, 20e3),
    ] {
        let model = film([3, 3, 2], kind, v).map_err(|e| e.to_string())?;
        let state = solve_film(&model, 10)?;
        let (l, t) = stretches(&model, &state);
        let s = reference.state(v / h).ok_or("closed form beyond pull-in")?;
        let at = format!("{} {:.0} kV", kind.name(), v / 1e3);
        out.push(Case::new(
            format!("{at}: in-plane stretch"),
            closed_form.into(),
            s.lambda,
            l,
            1e-9,
        ));
        out.push(Case::new(
            format!("{at}: thickness stretch"),
            closed_form.into(),
            s.t,
            t,
            1e-9,
        ));
        if v == 10e3 {
            // charge on the quarter film's top electrode: Q = D·A with D = ε λ²/t · V/H
            let r = nodal_reactions(&model, &state)?;
            let q: f64 = -model.mesh.node_sets["z1"]
                .iter()
                .map(|&n| r[n * 4 + 3])
                .sum::<f64>();
            let area = FILM_SIZE[0] * FILM_SIZE[1];
            let expected = FILM_EPS_R * EPSILON_0 * s.lambda * s.lambda / s.t * v / h * area;
            out.push(Case::new(
                format!("{at}: electrode charge (C)"),
                "Q = ελ²/t·V/H·A".into(),
                expected,
                q,
                1e-9,
            ));
        }
    }
    // pull-in of the film (closed form 33.695 kV): the last converged voltage lies within 0.5 % below
    let (ec, _) = reference.pull_in();
    let model = film([2, 2, 1], ElementKind::Hex8, 40e3).map_err(|e| e.to_string())?;
    out.push(Case::new(
        "hex8 ramp to 40 kV: pull-in voltage (V)".into(),
        "closed-form maximum of V(λ)".into(),
        ec * h,
        pull_in_voltage(&model, 40e3, 20)?,
        5e-3,
    ));
    // nearly incompressible film (Λ = 1e4 μ): pull-in approaches Zhao & Suo's Φ̂c = 0.687365
    let mut model = film([2, 2, 1], ElementKind::Hex8, 40e3).map_err(|e| e.to_string())?;
    model.materials = vec![Arc::new(ElectroNeoHooke::new(
        FILM_MU,
        1e4 * FILM_MU,
        FILM_EPS_R,
    ))];
    let scale = h * (FILM_MU / (FILM_EPS_R * EPSILON_0)).sqrt();
    let (_, phi_c) = incompressible_neo_hooke_pull_in();
    out.push(Case::new(
        "Λ = 1e4 μ: pull-in, V/(H√(μ/ε))".into(),
        "Zhao & Suo 2007, incompressible".into(),
        phi_c,
        pull_in_voltage(&model, 40e3, 20)? / scale,
        2e-3,
    ));
    Ok(out)
}
