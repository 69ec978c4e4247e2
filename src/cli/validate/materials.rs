//! Materials: every model of the registry at a homogeneous state against its stress written out
//! here from the literature form of its energy, and the dielectric part against D = εe and the
//! Maxwell stress.
//!
//! Two rows per model: (a) uniaxial stretch λ = 2 at J = 1, where σ₁₁ − σ₂₂ is the uniaxial
//! Cauchy stress of the incompressible material (the pressure cancels; the volumetric terms
//! vanish at J = 1); (b) a compressible equibiaxial state F = diag(λ, λ, t), J = 1.001, against
//! the principal Cauchy stresses of the energy W(Ī₁, Ī₂) + U(J) (or of the Ogden and
//! compressible neo-Hooke forms), the whole tensor compared.

use super::Case;
use crate::material::registry::{build, preset, MaterialParams, MODELS};
use crate::material::{cauchy_stress, spatial_field, Mat3, Material, Vec3, EPSILON_0};

/// Tolerance of a formula against the same formula: round-off only.
const TOL: f64 = 1e-10;
/// Stretch of the uniaxial rows.
const UNIAXIAL: f64 = 2.0;
/// In-plane stretch and volume ratio of the equibiaxial rows.
const BIAXIAL: (f64, f64) = (1.5, 1.001);

/// The parameters used for `model` and where they come from.
fn parameters(model: &str) -> Option<(MaterialParams, &'static str)> {
    let from_preset = |name: &str| preset(name).map(|(_, p)| p);
    let base = MaterialParams {
        permittivity: Some(4.7),
        ..Default::default()
    };
    Some(match model {
        "neo-hooke" => (
            MaterialParams {
                mu: vec![1e5],
                lambda: Some(1e7),
                ..base
            },
            "the film's μ, Λ",
        ),
        "neo-hooke-split" => (
            MaterialParams {
                mu: vec![422.5e3],
                kappa: Some(2.0 * 422.5e3 * 1.3 / (3.0 * 0.4)),
                ..base
            },
            "Cook's μ, ν = 0.3",
        ),
        "yeoh" => (from_preset("vhb4910-yeoh")?, "preset vhb4910-yeoh"),
        "mooney-rivlin" => (
            MaterialParams {
                c10: Some(4e4),
                c01: Some(1e4),
                d1: Some(2e-8),
                ..base
            },
            "C10 = 40, C01 = 10 kPa",
        ),
        "gent" => (from_preset("vhb4910-gent")?, "preset vhb4910-gent"),
        "ogden" => (
            MaterialParams {
                mu: vec![6.3e5, 1.2e3, -1e4],
                alpha: vec![1.3, 5.0, -2.0],
                kappa: Some(1e8),
                ..base
            },
            "Ogden 1972 (Treloar)",
        ),
        "arruda-boyce" => (from_preset("vhb4910-ab-wang")?, "preset vhb4910-ab-wang"),
        "arruda-boyce-series" => (
            from_preset("vhb4910-ab-wang")?,
            "the constants of vhb4910-ab-wang",
        ),
        _ => return None,
    })
}

/// Arruda–Boyce series coefficients (Arruda & Boyce 1993, five terms of the inverse Langevin
/// expansion).
pub const AB_SERIES: [f64; 5] = [
    1.0 / 2.0,
    1.0 / 20.0,
    11.0 / 1050.0,
    19.0 / 7000.0,
    519.0 / 673750.0,
];

/// (∂W/∂Ī₁, ∂W/∂Ī₂) of the invariant models at Ī₁, or `None` for the others.
fn invariant_derivatives(model: &str, p: &MaterialParams, i1: f64) -> Option<(f64, f64)> {
    let g = |v: Option<f64>| v.unwrap_or(0.0);
    Some(match model {
        "neo-hooke-split" => (0.5 * p.mu[0], 0.0),
        "mooney-rivlin" => (g(p.c10), g(p.c01)),
        "yeoh" => {
            let x = i1 - 3.0;
            (g(p.c10) + 2.0 * g(p.c20) * x + 3.0 * g(p.c30) * x * x, 0.0)
        }
        "gent" => {
            let jm = g(p.jm);
            (0.5 * p.mu[0] * jm / (jm - i1 + 3.0), 0.0)
        }
        // eight-chain: (μ/6)(λ_L/λ̄) L⁻¹(λ̄/λ_L), λ̄ = √(Ī₁/3), Cohen's Padé L⁻¹(x) = x(3 − x²)/(1 − x²)
        "arruda-boyce" => {
            let lm = g(p.lambda_m);
            let lb = (i1 / 3.0).sqrt();
            let x = lb / lm;
            let inv_langevin = x * (3.0 - x * x) / (1.0 - x * x);
            (p.mu[0] / 6.0 * lm / lb * inv_langevin, 0.0)
        }
        "arruda-boyce-series" => {
            let lm2 = g(p.lambda_m).powi(2);
            let w1 = AB_SERIES
                .iter()
                .enumerate()
                .map(|(k, c)| (k + 1) as f64 * c * i1.powi(k as i32) / lm2.powi(k as i32))
                .sum::<f64>();
            (p.mu[0] * w1, 0.0)
        }
        _ => return None,
    })
}

/// U′(J): κ/2 (J − 1/J) for U = κ/4 (J² − 1 − 2 ln J); Σ 2i (J − 1)^(2i−1)/Dᵢ for the Abaqus
/// polynomial U = Σ (J − 1)^(2i)/Dᵢ.
fn volumetric_derivative(model: &str, p: &MaterialParams, j: f64) -> f64 {
    match model {
        "yeoh" | "mooney-rivlin" => [p.d1, p.d2, p.d3]
            .iter()
            .enumerate()
            .filter_map(|(i, d)| d.filter(|d| *d != 0.0).map(|d| (i, d)))
            .map(|(i, d)| 2.0 * (i + 1) as f64 * (j - 1.0).powi(2 * i as i32 + 1) / d)
            .sum(),
        _ => 0.5 * p.kappa.unwrap_or(0.0) * (j - 1.0 / j),
    }
}

/// Uniaxial Cauchy stress of the incompressible material at stretch λ (I₁ = λ² + 2/λ), in the
/// form its source gives.
fn uniaxial_incompressible(model: &str, p: &MaterialParams, l: f64) -> Option<f64> {
    let g = |v: Option<f64>| v.unwrap_or(0.0);
    let i1 = l * l + 2.0 / l;
    let d = l * l - 1.0 / l;
    Some(match model {
        // Treloar: μ(λ² − 1/λ)
        "neo-hooke" | "neo-hooke-split" => p.mu[0] * d,
        // Rivlin & Saunders: 2(C₁₀ + C₀₁/λ)(λ² − 1/λ)
        "mooney-rivlin" => 2.0 * (g(p.c10) + g(p.c01) / l) * d,
        // Yeoh: 2(λ² − 1/λ)(C₁₀ + 2C₂₀(I₁ − 3) + 3C₃₀(I₁ − 3)²)
        "yeoh" => {
            let x = i1 - 3.0;
            2.0 * d * (g(p.c10) + 2.0 * g(p.c20) * x + 3.0 * g(p.c30) * x * x)
        }
        // Gent: μJm(λ² − 1/λ)/(Jm − I₁ + 3)
        "gent" => p.mu[0] * g(p.jm) * d / (g(p.jm) - i1 + 3.0),
        // Arruda–Boyce eight-chain: (μ/3)(λ² − 1/λ)(λ_L/λ̄) L⁻¹(λ̄/λ_L)
        "arruda-boyce" => {
            let (lm, lb) = (g(p.lambda_m), (i1 / 3.0).sqrt());
            let x = lb / lm;
            p.mu[0] / 3.0 * d * lm / lb * x * (3.0 - x * x) / (1.0 - x * x)
        }
        // Arruda–Boyce series: 2(λ² − 1/λ) μ Σ i Cᵢ I₁^(i−1)/λ_m^(2i−2)
        "arruda-boyce-series" => 2.0 * d * invariant_derivatives(model, p, i1)?.0,
        // Ogden: Σ μₚ(λ^αₚ − λ^(−αₚ/2))
        "ogden" => {
            p.mu.iter()
                .zip(&p.alpha)
                .map(|(m, a)| m * (l.powf(*a) - l.powf(-0.5 * a)))
                .sum()
        }
        _ => return None,
    })
}

/// Principal Cauchy stresses at F = diag(λ₁, λ₂, λ₃) of the compressible model:
/// σᵢ = (2/J)[W₁(λ̄ᵢ² − Ī₁/3) + W₂(Ī₁λ̄ᵢ² − λ̄ᵢ⁴ − 2Ī₂/3)] + U′(J) for W(Ī₁, Ī₂) + U(J),
/// σᵢ = (1/J) Σₚ μₚ(λ̄ᵢ^αₚ − ⅓ Σⱼ λ̄ⱼ^αₚ) + U′(J) for Ogden, σᵢ = (μ/J)(λᵢ² − 1) + Λ ln J/J for
/// the compressible neo-Hooke, with λ̄ᵢ = J^(−1/3)λᵢ.
fn principal_cauchy(model: &str, p: &MaterialParams, l: [f64; 3]) -> Option<[f64; 3]> {
    let j = l[0] * l[1] * l[2];
    let lb = l.map(|x| x * j.powf(-1.0 / 3.0));
    let b2 = lb.map(|x| x * x);
    let i1 = b2.iter().sum::<f64>();
    let i2 = b2[0] * b2[1] + b2[1] * b2[2] + b2[2] * b2[0];
    let du = volumetric_derivative(model, p, j);
    Some(match model {
        "neo-hooke" => {
            let (mu, lambda) = (p.mu[0], p.lambda?);
            l.map(|x| mu / j * (x * x - 1.0) + lambda * j.ln() / j)
        }
        "ogden" => {
            let mut s = [du; 3];
            for (m, a) in p.mu.iter().zip(&p.alpha) {
                let pw = lb.map(|x| x.powf(*a));
                let mean = pw.iter().sum::<f64>() / 3.0;
                for i in 0..3 {
                    s[i] += m * (pw[i] - mean) / j;
                }
            }
            s
        }
        _ => {
            let (w1, w2) = invariant_derivatives(model, p, i1)?;
            b2.map(|b| {
                2.0 / j * (w1 * (b - i1 / 3.0) + w2 * (i1 * b - b * b - 2.0 * i2 / 3.0)) + du
            })
        }
    })
}

/// Cauchy stress of `mat` at (F, E₀).
fn cauchy(mat: &dyn Material, f: &Mat3, e0: &Vec3) -> Result<Mat3, String> {
    let s = mat.stress(f, e0).map_err(|e| e.to_string())?;
    Ok(cauchy_stress(&s.p, f))
}

/// The two rows of one model.
fn model_cases(model: &str) -> Result<Vec<Case>, String> {
    let (p, source) = parameters(model).ok_or(format!("no parameters for model `{model}`"))?;
    let no_form = || format!("no closed form for model `{model}`");
    let (mat, _) = build(model, &p).map_err(|e| e.to_string())?;
    let l = UNIAXIAL;
    let f = Mat3::from_diagonal(&Vec3::new(l, 1.0 / l.sqrt(), 1.0 / l.sqrt()));
    let s = cauchy(mat.as_ref(), &f, &Vec3::zeros())?;
    let uniaxial = Case::new(
        format!("{model}: uniaxial λ = {l}, J = 1, σ11 − σ22 (Pa)"),
        format!("incompressible form ({source})"),
        uniaxial_incompressible(model, &p, l).ok_or_else(no_form)?,
        s[(0, 0)] - s[(1, 1)],
        TOL,
    );
    let (l, j) = BIAXIAL;
    let stretches = [l, l, j / (l * l)];
    let f = Mat3::from_diagonal(&Vec3::from(stretches));
    let s = cauchy(mat.as_ref(), &f, &Vec3::zeros())?;
    let expected = Mat3::from_diagonal(&Vec3::from(
        principal_cauchy(model, &p, stretches).ok_or_else(no_form)?,
    ));
    let biaxial = Case::new(
        format!("{model}: equibiaxial λ = {l}, J = {j}, |σ| (Pa)"),
        "principal stresses of W(λ₁,λ₂,λ₃)".to_string(),
        expected.norm(),
        s.norm(),
        TOL,
    )
    .with_deviation((s - expected).norm());
    Ok(vec![uniaxial, biaxial])
}

/// A general deformation and referential field for the dielectric rows.
fn general_state() -> (Mat3, Vec3) {
    let f = Mat3::new(1.2, 0.1, 0.05, -0.08, 0.9, 0.12, 0.03, -0.06, 1.1);
    (f, Vec3::new(1e6, -2e6, 3e7))
}

/// The dielectric rows: ideal D = εe and Maxwell stress ε(e⊗e − ½|e|²I); electrostrictive (Vu,
/// Steinmann & Possart 2007) d = εe − (2/J)(c₁b + c₂b²)e, from D₀ = −∂Ψ/∂E₀ pushed forward,
/// d = F D₀/J.
fn dielectric_cases() -> Result<Vec<Case>, String> {
    let eps_r = 4.7;
    let eps = eps_r * EPSILON_0;
    let (f, e0) = general_state();
    let j = f.determinant();
    let e = spatial_field(&f, &e0).ok_or("singular F")?;
    let params = |c1: f64, c2: f64| MaterialParams {
        mu: vec![1e5],
        lambda: Some(1e7),
        permittivity: Some(eps_r),
        c1: Some(c1),
        c2: Some(c2),
        ..Default::default()
    };
    let (ideal, _) = build("neo-hooke", &params(0.0, 0.0)).map_err(|e| e.to_string())?;
    let d = f * ideal.stress(&f, &e0).map_err(|e| e.to_string())?.d0 / j;
    let expected = e * eps;
    let mut out = vec![Case::new(
        "ideal dielectric: spatial D at a general F (C/m²)".into(),
        "D = εe, e = F⁻ᵀE₀".into(),
        expected.norm(),
        d.norm(),
        TOL,
    )
    .with_deviation((d - expected).norm())];
    let maxwell = cauchy(ideal.as_ref(), &f, &e0)? - cauchy(ideal.as_ref(), &f, &Vec3::zeros())?;
    let expected = (e * e.transpose() - Mat3::identity() * (0.5 * e.norm_squared())) * eps;
    out.push(
        Case::new(
            "ideal dielectric: σ(F, E₀) − σ(F, 0) (Pa)".into(),
            "Maxwell stress ε(e⊗e − ½|e|²I)".into(),
            expected.norm(),
            maxwell.norm(),
            TOL,
        )
        .with_deviation((maxwell - expected).norm()),
    );
    let (c1, c2) = (0.1 * eps, 0.15 * eps);
    let (vu, _) = build("neo-hooke", &params(c1, c2)).map_err(|e| e.to_string())?;
    let d = f * vu.stress(&f, &e0).map_err(|e| e.to_string())?.d0 / j;
    let b = f * f.transpose();
    let expected = e * eps - (b * c1 + b * b * c2) * e * (2.0 / j);
    out.push(
        Case::new(
            "electrostrictive c1, c2: spatial D (C/m²)".into(),
            "εe − (2/J)(c₁b + c₂b²)e (Vu et al.)".into(),
            expected.norm(),
            d.norm(),
            TOL,
        )
        .with_deviation((d - expected).norm()),
    );
    Ok(out)
}

/// Every model of the registry, then the dielectric.
pub fn cases() -> Result<Vec<Case>, String> {
    let mut out = Vec::new();
    for model in MODELS {
        out.extend(model_cases(model)?);
    }
    out.extend(dielectric_cases()?);
    Ok(out)
}
