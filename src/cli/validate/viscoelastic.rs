//! Finite viscoelasticity: the VHB 4910 branch set of Wang, Decker, Henann & Chester (JMPS 2016;
//! Arruda–Boyce equilibrium, neo-Hookean Maxwell branches with the evolution law of Linder,
//! Tkachuk & Miehe 2011) on one hex8 cell in uniaxial stress, stretched to λ = 1.5, against the
//! material-point reference of `analytic::viscoelastic_uniaxial` (Runge–Kutta, no element) and
//! against the closed-form instantaneous and relaxed limits.

use super::Case;
use crate::analytic::viscoelastic_uniaxial;
use crate::job::statics::{solve_static_from, StageTime};
use crate::material::registry::{build, preset};
use crate::material::Material;
use crate::problem::examples::uniaxial_cell;
use crate::problem::points::PointStates;
use crate::solve::linear::SolverSettings;
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::StepControl;
use std::sync::Arc;

/// Stretch of the cell.
pub const STRETCH: f64 = 1.5;

/// The preset `vhb4910-wang2016` with κ = 10⁴ G₀ (nearly incompressible, as the reference).
#[derive(Debug, Clone)]
pub struct Wang2016 {
    /// Coefficient G₀ of the eight-chain form (Pa).
    pub mu: f64,
    /// Locking stretch λ_L.
    pub lambda_m: f64,
    /// Maxwell branches (g in Pa, τ in s).
    pub branches: Vec<(f64, f64)>,
    material: Arc<dyn Material>,
}

impl Wang2016 {
    pub fn new() -> Result<Self, String> {
        let (model, mut p) = preset("vhb4910-wang2016").ok_or("no preset vhb4910-wang2016")?;
        let lambda_m = p.lambda_m.ok_or("no λ_L")?;
        p.kappa = Some(1e4 * p.mu[0]);
        let (material, _) = build(model, &p).map_err(|e| e.to_string())?;
        Ok(Wang2016 {
            mu: p.mu[0],
            lambda_m,
            branches: p.branches.clone(),
            material,
        })
    }

    /// The viscoelastic material.
    pub fn material(&self) -> Arc<dyn Material> {
        self.material.clone()
    }

    /// ∂W/∂I₁ of the eight-chain energy, (G₀/6)(λ_L/λ̄) L⁻¹(λ̄/λ_L) with λ̄ = √(I₁/3) and Cohen's
    /// Padé L⁻¹(x) = x(3 − x²)/(1 − x²).
    pub fn w1(&self, i1: f64) -> f64 {
        let lb = (i1 / 3.0).sqrt();
        let x = lb / self.lambda_m;
        self.mu / 6.0 * self.lambda_m / lb * x * (3.0 - x * x) / (1.0 - x * x)
    }

    /// Nominal uniaxial stress of the equilibrium branch alone (the relaxed limit),
    /// 2W′(I₁)(λ − λ⁻²) with I₁ = λ² + 2/λ.
    pub fn p_eq(&self, l: f64) -> f64 {
        2.0 * self.w1(l * l + 2.0 / l) * (l - 1.0 / (l * l))
    }

    /// Nominal stress right after a step to λ (branches not yet relaxed, Aᵢ = I):
    /// P_eq + Σ gᵢ(λ − λ⁻²).
    pub fn p_instantaneous(&self, l: f64) -> f64 {
        self.p_eq(l) + self.branches.iter().map(|b| b.0).sum::<f64>() * (l - 1.0 / (l * l))
    }

    /// The material-point reference at the times `at` under `stretch(t)`.
    pub fn reference(
        &self,
        stretch: impl Fn(f64) -> f64,
        at: &[f64],
        steps_per_second: f64,
    ) -> Vec<f64> {
        viscoelastic_uniaxial(
            |i1| self.w1(i1),
            &self.branches,
            stretch,
            at,
            steps_per_second,
        )
    }
}

/// The stretch history of the ramp: λ from 1 to 1.5 in 0.1 s, then held.
pub fn ramp(t: f64) -> f64 {
    1.0 + (STRETCH - 1.0) * (t / 0.1).min(1.0)
}

/// Nominal stress (Pa) of the cell of `material` (`examples::uniaxial_cell`) at the end of each
/// stage `(duration in s, steps)`: the first stage moves the face to λ = 1.5, the others hold it.
pub fn cell_stress(
    material: Arc<dyn Material>,
    stages: &[(f64, usize)],
) -> Result<Vec<f64>, String> {
    let m = uniaxial_cell(material).map_err(|e| e.to_string())?;
    let x1 = m.set_nodes("x1").map_err(|e| e.to_string())?;
    let newton = NewtonSettings {
        rtol: 1e-12,
        ..Default::default()
    };
    let mut out = Vec::new();
    let mut state = vec![0.0; m.mesh.n_nodes() * 4];
    let mut points = PointStates::new(&m);
    for &(duration, steps) in stages {
        let mut last = Ok(0.0);
        let o = solve_static_from(
            &m,
            &SolverSettings::default(),
            state.clone(),
            StageTime {
                duration,
                points: points.clone(),
                drive: crate::problem::drive::Drive::ramped(&m),
            },
            None,
            &StepControl {
                steps,
                ..Default::default()
            },
            &newton,
            None,
            |prob, _| {
                // reaction on the moved face over the 1 mm² reference area
                last = prob
                    .nodal_reactions()
                    .map(|r| x1.iter().map(|&i| r[i * 4]).sum::<f64>() / 1e-6);
            },
        );
        o.result.map_err(|e| e.to_string())?;
        state = o.state;
        points = o.points;
        out.push(last?);
    }
    Ok(out)
}

/// Ramp rows (backward Euler at 80 + 800 steps against the Runge–Kutta reference: first order
/// in Δt, measured 6e-4 and 1.5e-4, plus the cell's compressibility ≈ 3e-4) and the two
/// limits of a step (1e-3).
pub fn cases() -> Result<Vec<Case>, String> {
    let w = Wang2016::new()?;
    let reference = w.reference(ramp, &[0.1, 10.0], 4e4);
    let fe = cell_stress(w.material(), &[(0.1, 80), (9.9, 800)])?;
    let mut out = Vec::new();
    for (k, t) in [0.1, 10.0].into_iter().enumerate() {
        out.push(Case::new(
            format!("ramp to λ = 1.5 in 0.1 s, hex8: P at {t} s (Pa)"),
            "material-point ODE, Runge–Kutta".into(),
            reference[k],
            fe[k],
            1e-3,
        ));
    }
    // a step in 1 µs (≪ τ = 0.6 s), then 1000 s (≫ τ = 61 s) of relaxation
    let step = cell_stress(w.material(), &[(1e-6, 5), (1000.0, 20)])?;
    out.push(Case::new(
        "step to λ = 1.5 in 1 µs: P (Pa)".into(),
        "instantaneous P_eq + Σg(λ − λ⁻²)".into(),
        w.p_instantaneous(STRETCH),
        step[0],
        1e-3,
    ));
    out.push(Case::new(
        "then held 1000 s: P (Pa)".into(),
        "relaxed: equilibrium branch".into(),
        w.p_eq(STRETCH),
        step[1],
        1e-3,
    ));
    Ok(out)
}
