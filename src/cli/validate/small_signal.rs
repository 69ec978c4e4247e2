//! Small-signal: the natural frequencies of the pre-stretched membrane (`examples::membrane`)
//! about its static state against the membrane formula f_mn = ½ √(T/ρ_A) √(m²/L² + n²/W²), and
//! their electric softening against √(T(V)/T(0)).

use super::Case;
use crate::job::statics::solve_static;
use crate::problem::examples::{
    membrane, membrane_material, MEMBRANE_SIDE, MEMBRANE_STRETCH, MEMBRANE_THICKNESS,
};
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::StepControl;
use crate::time::mass::{MassKind, NodalMass};
use crate::time::modal::{modes, ModeSettings};

/// Mass density of the membrane (kg/m³).
pub const RHO: f64 = 1000.0;

/// The homogeneous state F = diag(λ, λ, t) of the membrane's compressible neo-Hooke under the
/// nominal field E₀ = V/H₀ with σ₃₃ = 0: the thickness stretch t and T/ρ_A (m²/s²), from
/// σ = (μ/J)(b − I) + (Λ ln J/J) I + ε(e⊗e − ½|e|²I), e₃ = E₀/t, T = σ₁₁ t H₀,
/// ρ_A = ρ₀H₀/λ².
pub fn homogeneous(volts: f64) -> (f64, f64) {
    let m = membrane_material();
    let l = MEMBRANE_STRETCH;
    let e0 = volts / MEMBRANE_THICKNESS;
    // J σ₃₃ = μ(t² − 1) + Λ ln(λ²t) + ½ε E₀² λ²/t = 0, by Newton from the incompressible guess
    let q = 0.5 * m.eps * e0 * e0 * l * l;
    let mut t = 1.0 / (l * l);
    for _ in 0..50 {
        let g = m.mu * (t * t - 1.0) + m.lambda * (l * l * t).ln() + q / t;
        let dg = 2.0 * m.mu * t + m.lambda / t - q / (t * t);
        let dt = -g / dg;
        t += dt;
        if dt.abs() < 1e-15 {
            break;
        }
    }
    let j = l * l * t;
    let e = e0 / t;
    let sigma = m.mu / j * (l * l - 1.0) + m.lambda * j.ln() / j - 0.5 * m.eps * e * e;
    (t, sigma * t * l * l / RHO)
}

/// The lowest flexural frequencies (Hz) of the membrane on n × n cells at `volts`, among the
/// `count` lowest modes: those whose kinetic energy is mostly (90 %) out of plane.
pub fn flexural(n: usize, volts: f64, count: usize) -> Result<Vec<f64>, String> {
    let m = membrane(n, volts).map_err(|e| e.to_string())?;
    // the homogeneous state is the equilibrium (one Newton solve from it)
    let t = homogeneous(volts).0;
    let mut guess = vec![0.0; m.mesh.n_nodes() * 4];
    for (node, x) in m.mesh.nodes.iter().enumerate() {
        guess[node * 4] = (MEMBRANE_STRETCH - 1.0) * x[0];
        guess[node * 4 + 1] = (MEMBRANE_STRETCH - 1.0) * x[1];
        guess[node * 4 + 2] = (t - 1.0) * x[2];
        guess[node * 4 + 3] = volts * x[2] / MEMBRANE_THICKNESS;
    }
    let out = solve_static(
        &m,
        Some(guess),
        &StepControl {
            steps: 1,
            ..Default::default()
        },
        &NewtonSettings::default(),
        |_, _| {},
    );
    out.result.map_err(|e| e.to_string())?;
    let mass = NodalMass::new(&m, &[RHO], MassKind::Consistent);
    let found = modes(
        &m,
        &out.state,
        &mass,
        &Default::default(),
        &ModeSettings {
            count,
            ..Default::default()
        },
    )?;
    let mut f = Vec::new();
    for mode in found {
        let (mut z, mut all) = (0.0, 0.0);
        for node in 0..m.mesh.n_nodes() {
            for i in 0..3 {
                let v = mode.shape[node * 4 + i].powi(2);
                all += v;
                if i == 2 {
                    z += v;
                }
            }
        }
        if z > 0.9 * all {
            if mode.residual > 1e-8 {
                return Err(format!("mode residual {:e}", mode.residual));
            }
            f.push(mode.frequency);
        }
    }
    Ok(f)
}

/// The (1, 1) mode on 16 × 16 cells against the membrane (hex8 cells that are thin and wide
/// over-stiffen bending: measured +0.70 %; 1 %), and its ratio at 2 kV to 0 V against the
/// tension ratio (1 %).
pub fn cases() -> Result<Vec<Case>, String> {
    let c2 = homogeneous(0.0).1;
    let l = MEMBRANE_STRETCH * MEMBRANE_SIDE;
    let f11 = 0.5 * c2.sqrt() * 2f64.sqrt() / l;
    let f0 = *flexural(16, 0.0, 4)?.first().ok_or("no flexural mode")?;
    let volts = 2000.0;
    let fv = *flexural(16, volts, 4)?.first().ok_or("no flexural mode")?;
    Ok(vec![
        Case::new(
            "membrane λ = 1.5, 16×16 hex8: f11 (Hz)".into(),
            "membrane ½√(T/ρ_A)·√2/L".into(),
            f11,
            f0,
            1e-2,
        ),
        Case::new(
            format!("membrane: f11({volts} V)/f11(0)"),
            "√(T(V)/T(0)), Maxwell stress".into(),
            (homogeneous(volts).1 / c2).sqrt(),
            fv / f0,
            1e-2,
        ),
    ])
}
