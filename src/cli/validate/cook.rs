//! Cook's membrane (Cook 1974, in the finite-strain form of the deal.II code gallery, Pelteret &
//! McBride 2016): the tip deflection at ν = 0.3 with the standard hex8 against the gallery's Q1
//! table and with the mean-dilatation hex8 against its converged Q2 value, and at ν = 0.4999 in
//! plane strain with the mean-dilatation hex8 against a fine-mesh reference.

use super::Case;
use crate::job::statics::solve_static;
use crate::problem::examples::{cook, cook_tip, Thickness};
use crate::problem::model::Formulation;
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::StepControl;

/// Converged tip deflection of the gallery (Q2 elements, ν = 0.3, free thickness), mm.
pub const GALLERY_Q2: f64 = 14.33;
/// The gallery's Q1 table at ν = 0.3 (free thickness): (cells per edge, tip deflection in mm).
pub const GALLERY_Q1: [(usize, f64); 6] = [
    (1, 5.15),
    (2, 8.72),
    (4, 12.02),
    (8, 13.61),
    (16, 14.13),
    (32, 14.28),
];
/// Tip deflection (mm) in plane strain at ν = 0.4999 of the mean-dilatation hex8 with n = 64,
/// computed once with this code (35 s; `cargo test --release --test cooks_membrane -- --ignored`
/// recomputes it): a finer mesh of the same element, not an independent method.
pub const MD_4999_N64: f64 = 11.465;

/// Tip deflection (mm) of Cook's membrane after ramping the traction in 5 steps (the ramp cuts
/// back by itself when a step is too large). The free-thickness state is the gallery's symmetric
/// branch, laterally unstable in 3-D, so its stability is not checked.
pub fn tip(
    n: usize,
    nu: f64,
    formulation: Formulation,
    thickness: Thickness,
) -> Result<f64, String> {
    let model = cook(n, nu, formulation, thickness).map_err(|e| e.to_string())?;
    let newton = NewtonSettings {
        check_stability: thickness == Thickness::PlaneStrain,
        ..Default::default()
    };
    let out = solve_static(
        &model,
        None,
        &StepControl {
            steps: 5,
            ..Default::default()
        },
        &newton,
        |_, _| {},
    );
    out.result
        .map_err(|e| format!("Cook n = {n}, ν = {nu}, {formulation:?}, {thickness:?}: {e}"))?;
    Ok(cook_tip(&model, &out.state))
}

/// Four rows: n = 16 and 32 against the Q1 table (its rounding to 0.01 mm: 1e-3), the
/// mean-dilatation n = 32 against Q2, and the nearly incompressible mean-dilatation n = 32
/// against n = 64 (1 %).
pub fn cases() -> Result<Vec<Case>, String> {
    let mut out = Vec::new();
    for (n, expected) in GALLERY_Q1.into_iter().filter(|(n, _)| *n >= 16) {
        out.push(Case::new(
            format!("ν = 0.3, hex8, n = {n}: tip deflection (mm)"),
            format!("gallery Q1 table, n = {n}"),
            expected,
            tip(n, 0.3, Formulation::Standard, Thickness::Free)?,
            1e-3,
        ));
    }
    out.push(Case::new(
        "ν = 0.3, mean-dilatation, n = 32 (mm)".into(),
        "gallery Q2, converged".into(),
        GALLERY_Q2,
        tip(32, 0.3, Formulation::MeanDilatation, Thickness::Free)?,
        2e-3,
    ));
    out.push(Case::new(
        "ν = 0.4999, plane strain, mean-dil., n = 32 (mm)".into(),
        "same element, n = 64 (fine mesh)".into(),
        MD_4999_N64,
        tip(
            32,
            0.4999,
            Formulation::MeanDilatation,
            Thickness::PlaneStrain,
        )?,
        1e-2,
    ));
    Ok(out)
}
