//! Material registry: builds a validated [`Material`] from a model name and
//! a flat parameter set, lists the models and the literature presets, and
//! performs a Drucker stability check.
//!
//! | model             | parameters (SI)                                   | μ₀                | K₀          |
//! |-------------------|---------------------------------------------------|-------------------|-------------|
//! | `neo-hooke`       | `mu` (one value), `lambda`                        | μ                 | Λ + 2μ/3    |
//! | `neo-hooke-split` | `mu` (one value), `kappa`                         | μ                 | κ           |
//! | `yeoh`            | `c10`, `c20`=0, `c30`=0, `d1`, `d2`=0, `d3`=0     | 2C₁₀              | 2/D₁        |
//! | `mooney-rivlin`   | `c10`, `c01`, `d1`                                | 2(C₁₀ + C₀₁)      | 2/D₁        |
//! | `gent`            | `mu` (one value), `jm`, `kappa`                   | μ                 | κ           |
//! | `ogden`           | `mu` (list), `alpha` (list), `kappa`              | ½ Σ μₚαₚ          | κ           |
//! | `arruda-boyce`    | `mu` (one value), `lambda_m`, `kappa`             | μ(3λ_m² − 1)/(3λ_m² − 3) | κ    |
//! | `arruda-boyce-series` | `mu` (one value), `lambda_m`, `kappa`         | μ·(1 + 3/(5λ_m²) + …) | κ       |
//!
//! `arruda-boyce` is the eight-chain model with Cohen's Padé inverse Langevin function, `mu` the
//! coefficient G₀ of its form; `arruda-boyce-series` the five-term series in Ī₁, `mu` the series
//! coefficient (see [`super::arruda_boyce`]).
//!
//! Every model also takes the dielectric parameters `permittivity`
//! (relative, required, ≥ 1) and `c1`, `c2` (F/m, default 0); ε = εᵣε₀ and
//! the small-strain permittivity εᵣε₀ − 2c₁ − 2c₂ must be positive.
//! Moduli are in Pa, D in 1/Pa, `jm`, `lambda_m`, `alpha` dimensionless. A
//! parameter that the model does not use is an error (it is most likely a
//! typo or a parameter meant for another model).

use std::sync::Arc;

use super::arruda_boyce::{ArrudaBoyce, ArrudaBoyceSeries};
use super::electric::ElectricPart;
use super::electroelastic::Electroelastic;
use super::gent::Gent;
use super::homogeneous::{self, Mode};
use super::mooney_rivlin::MooneyRivlin;
use super::neo_hooke::ElectroNeoHooke;
use super::neo_hooke_split::NeoHookeSplit;
use super::ogden::Ogden;
use super::yeoh::Yeoh;
use super::{Material, EPSILON_0};

/// Flat parameter set of any model (SI units; see the module table).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MaterialParams {
    /// Shear modulus μ (one value) or the Ogden coefficients μₚ (Pa).
    pub mu: Vec<f64>,
    /// Lamé constant Λ of `neo-hooke` (Pa).
    pub lambda: Option<f64>,
    /// Bulk modulus κ of the split models (Pa).
    pub kappa: Option<f64>,
    /// Yeoh / Mooney–Rivlin C₁₀ (Pa).
    pub c10: Option<f64>,
    /// Yeoh C₂₀ (Pa).
    pub c20: Option<f64>,
    /// Yeoh C₃₀ (Pa).
    pub c30: Option<f64>,
    /// Mooney–Rivlin C₀₁ (Pa).
    pub c01: Option<f64>,
    /// Abaqus D₁ (1/Pa).
    pub d1: Option<f64>,
    /// Abaqus D₂ (1/Pa), Yeoh only.
    pub d2: Option<f64>,
    /// Abaqus D₃ (1/Pa), Yeoh only.
    pub d3: Option<f64>,
    /// Gent locking parameter J_m.
    pub jm: Option<f64>,
    /// Arruda–Boyce locking stretch λ_m.
    pub lambda_m: Option<f64>,
    /// Ogden exponents αₚ.
    pub alpha: Vec<f64>,
    /// Relative permittivity εᵣ.
    pub permittivity: Option<f64>,
    /// Electrostrictive coefficient c₁ (F/m).
    pub c1: Option<f64>,
    /// Electrostrictive coefficient c₂ (F/m).
    pub c2: Option<f64>,
    /// Neo-Hookean Maxwell branches (gᵢ in Pa, τᵢ in s) on the isochoric deformation, in
    /// parallel with the model ([`crate::material::maxwell::Viscoelastic`]).
    pub branches: Vec<(f64, f64)>,
}

impl MaterialParams {
    /// Sets the entry `key` of a parameter vector θ ([`crate::material::parameters`]): a scalar
    /// (`kappa`, `c10`, `permittivity`, …, and `mu` as the one shear modulus), a list entry
    /// (`mu.0`, `alpha.1`) or a branch's `branches.<i>.mu` / `branches.<i>.tau`; lists grow to
    /// the index.
    pub fn set(&mut self, key: &str, value: f64) -> Result<(), ParamError> {
        let index = |s: &str| {
            s.parse::<usize>()
                .map_err(|_| perr(key, format!("expected an index after the dot; got `{s}`")))
        };
        let at = |v: &mut Vec<f64>, i: usize| {
            if v.len() <= i {
                v.resize(i + 1, 0.0);
            }
            v[i] = value;
        };
        let parts: Vec<&str> = key.split('.').collect();
        match parts.as_slice() {
            ["mu"] => self.mu = vec![value],
            ["mu", i] => at(&mut self.mu, index(i)?),
            ["alpha", i] => at(&mut self.alpha, index(i)?),
            ["branches", i, which @ ("mu" | "tau")] => {
                let i = index(i)?;
                if self.branches.len() <= i {
                    self.branches.resize(i + 1, (0.0, 0.0));
                }
                if *which == "mu" {
                    self.branches[i].0 = value;
                } else {
                    self.branches[i].1 = value;
                }
            }
            [name] => {
                *self
                    .scalar_mut(name)
                    .ok_or_else(|| perr(key, "not a material parameter"))? = Some(value)
            }
            _ => return Err(perr(key, "not a material parameter")),
        }
        Ok(())
    }

    /// The scalar parameter `name` (not `mu`, `alpha`, `branches`).
    fn scalar_mut(&mut self, name: &str) -> Option<&mut Option<f64>> {
        Some(match name {
            "lambda" => &mut self.lambda,
            "kappa" => &mut self.kappa,
            "c10" => &mut self.c10,
            "c20" => &mut self.c20,
            "c30" => &mut self.c30,
            "c01" => &mut self.c01,
            "d1" => &mut self.d1,
            "d2" => &mut self.d2,
            "d3" => &mut self.d3,
            "jm" => &mut self.jm,
            "lambda_m" => &mut self.lambda_m,
            "permittivity" => &mut self.permittivity,
            "c1" => &mut self.c1,
            "c2" => &mut self.c2,
            _ => return None,
        })
    }

    /// (name, values) of every parameter that is set.
    fn given(&self) -> Vec<(&'static str, Vec<f64>)> {
        let mut out = Vec::new();
        if !self.mu.is_empty() {
            out.push(("mu", self.mu.clone()));
        }
        if !self.alpha.is_empty() {
            out.push(("alpha", self.alpha.clone()));
        }
        let scalars = [
            ("lambda", self.lambda),
            ("kappa", self.kappa),
            ("c10", self.c10),
            ("c20", self.c20),
            ("c30", self.c30),
            ("c01", self.c01),
            ("d1", self.d1),
            ("d2", self.d2),
            ("d3", self.d3),
            ("jm", self.jm),
            ("lambda_m", self.lambda_m),
            ("permittivity", self.permittivity),
            ("c1", self.c1),
            ("c2", self.c2),
        ];
        for (k, v) in scalars {
            if let Some(x) = v {
                out.push((k, vec![x]));
            }
        }
        out
    }
}

/// One line per parameter that is set, with its unit: `mu = 25400 Pa`, the Maxwell branches as
/// `branch 1: g = 26060 Pa, tau = 0.6074 s`; and the small-strain moduli of the model built from
/// them (what a preset resolves to).
pub fn describe(model: &str, p: &MaterialParams) -> Vec<String> {
    let unit = |k: &str| match k {
        "mu" | "lambda" | "kappa" | "c10" | "c20" | "c30" | "c01" => " Pa",
        "d1" | "d2" | "d3" => " 1/Pa",
        "c1" | "c2" => " F/m",
        _ => "",
    };
    let mut out = vec![format!("model = {model}")];
    for (k, v) in p.given() {
        let values: Vec<String> = v
            .iter()
            .map(|&x| crate::units::Short(x).to_string())
            .collect();
        let value = if v.len() == 1 {
            values[0].clone()
        } else {
            format!("[{}]", values.join(", "))
        };
        out.push(format!("{k} = {value}{}", unit(k)));
    }
    for (i, (g, tau)) in p.branches.iter().enumerate() {
        out.push(format!(
            "branch {}: g = {} Pa, tau = {} s",
            i + 1,
            crate::units::Short(*g),
            crate::units::Short(*tau)
        ));
    }
    if let Ok((mat, _)) = build(model, p) {
        out.push(format!(
            "small-strain shear modulus {:.6e} Pa (instantaneous), bulk modulus {:.6e} Pa, relative \
             permittivity {:.6}",
            mat.shear_modulus(),
            mat.bulk_modulus(),
            mat.permittivity() / EPSILON_0
        ));
    }
    out
}

/// A rejected parameter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key}: {message}")]
pub struct ParamError {
    /// Parameter name as in [`MaterialParams`] (e.g. `"c10"`, `"mu"`), or
    /// `"model"` for an unknown model name.
    pub key: String,
    /// What was expected, with unit.
    pub message: String,
}

fn perr(key: &str, message: impl Into<String>) -> ParamError {
    ParamError {
        key: key.to_string(),
        message: message.into(),
    }
}

/// Model names accepted by [`build`].
pub const MODELS: &[&str] = &[
    "neo-hooke",
    "neo-hooke-split",
    "yeoh",
    "mooney-rivlin",
    "gent",
    "ogden",
    "arruda-boyce",
    "arruda-boyce-series",
];

/// Preset names accepted by [`preset`].
pub const PRESETS: &[&str] = &[
    "vhb4910-yeoh",
    "vhb4910-yeoh-calibrated",
    "vhb4910-gent",
    "vhb4910-gent-liu",
    "vhb4910-ab-wang",
    "vhb4910-wang2016",
    "vhb4910-hossain2012",
];

const ELECTRIC: [&str; 3] = ["permittivity", "c1", "c2"];

/// Mechanical parameter names of a model (the dielectric ones,
/// `permittivity`, `c1`, `c2`, are accepted by every model), or `None` for
/// an unknown model.
pub fn parameter_names(model: &str) -> Option<&'static [&'static str]> {
    Some(match model {
        "neo-hooke" => &["mu", "lambda"],
        "neo-hooke-split" => &["mu", "kappa"],
        "yeoh" => &["c10", "c20", "c30", "d1", "d2", "d3"],
        "mooney-rivlin" => &["c10", "c01", "d1"],
        "gent" => &["mu", "jm", "kappa"],
        "ogden" => &["mu", "alpha", "kappa"],
        "arruda-boyce" | "arruda-boyce-series" => &["mu", "lambda_m", "kappa"],
        _ => return None,
    })
}

/// Required, finite.
fn req(key: &str, v: Option<f64>, what: &str) -> Result<f64, ParamError> {
    let x = v.ok_or_else(|| perr(key, format!("missing: expected {what}")))?;
    if x.is_finite() {
        Ok(x)
    } else {
        Err(perr(
            key,
            format!(
                "must be a finite number ({what}); got {}",
                crate::units::Short(x)
            ),
        ))
    }
}

/// Required, finite and > 0.
fn req_pos(key: &str, v: Option<f64>, what: &str) -> Result<f64, ParamError> {
    let x = req(key, v, what)?;
    if x > 0.0 {
        Ok(x)
    } else {
        Err(perr(
            key,
            format!("must be positive ({what}); got {}", crate::units::Short(x)),
        ))
    }
}

/// Exactly one value of μ.
fn single_mu(p: &MaterialParams) -> Result<f64, ParamError> {
    match p.mu.as_slice() {
        [x] => req_pos("mu", Some(*x), "shear modulus μ in Pa"),
        [] => Err(perr("mu", "missing: expected the shear modulus μ in Pa")),
        v => Err(perr(
            "mu",
            format!(
                "expected exactly one value (shear modulus μ in Pa); got {}",
                v.len()
            ),
        )),
    }
}

fn electric_part(p: &MaterialParams) -> Result<ElectricPart, ParamError> {
    let eps_r = req(
        "permittivity",
        p.permittivity,
        "the relative permittivity εᵣ ≥ 1 (dimensionless)",
    )?;
    if eps_r < 1.0 {
        return Err(perr(
            "permittivity",
            format!(
                "relative permittivity εᵣ must be ≥ 1 (dimensionless); got {}",
                crate::units::Short(eps_r)
            ),
        ));
    }
    let c1 = req(
        "c1",
        Some(p.c1.unwrap_or(0.0)),
        "coupling coefficient c₁ in F/m",
    )?;
    let c2 = req(
        "c2",
        Some(p.c2.unwrap_or(0.0)),
        "coupling coefficient c₂ in F/m",
    )?;
    let e = ElectricPart::ideal(eps_r).with_coupling(c1, c2);
    let eps0 = e.small_strain_permittivity();
    if eps0.is_nan() || eps0 <= 0.0 {
        return Err(perr(
            "c1",
            format!(
                "the small-strain permittivity εᵣε₀ − 2c₁ − 2c₂ must be positive; got {eps0:e} F/m (ε₀ = {EPSILON_0:e} F/m)"
            ),
        ));
    }
    Ok(e)
}

/// Bulk-to-shear ratio above which [`build`] warns.
pub const STIFF_RATIO_WARNING: f64 = 1e5;

/// Largest stretch of the Drucker check run by [`build`].
pub const DRUCKER_MAX_STRETCH: f64 = 3.0;

/// Build a validated material. Returns the material and warnings (Drucker
/// stability for Yeoh, Mooney–Rivlin and Ogden, non-convex volumetric
/// terms, very large K₀/μ₀); errors name the offending parameter.
pub fn build(
    model: &str,
    p: &MaterialParams,
) -> Result<(Arc<dyn Material>, Vec<String>), ParamError> {
    build_with(model, p, true)
}

/// The model `model` with the parameter vector θ = `values` named by `names` (as
/// [`Material::parameters`] gives them), validated as [`build`] validates, without its warnings
/// (and without the cost of the Drucker check): a material rebuilt in a calibration or an
/// optimisation. An error names the entry.
pub fn rebuild(
    model: &str,
    names: &[String],
    values: &[f64],
) -> Result<Arc<dyn Material>, ParamError> {
    if names.len() != values.len() {
        return Err(perr(
            "model",
            format!(
                "expected {} parameter values ({}); got {}",
                names.len(),
                names.join(", "),
                values.len()
            ),
        ));
    }
    let mut p = MaterialParams::default();
    for (name, &v) in names.iter().zip(values) {
        p.set(name, v)?;
    }
    build_with(model, &p, false).map(|(m, _)| m)
}

/// [`build`], with the warnings' checks when `checks`.
fn build_with(
    model: &str,
    p: &MaterialParams,
    checks: bool,
) -> Result<(Arc<dyn Material>, Vec<String>), ParamError> {
    let names = parameter_names(model).ok_or_else(|| {
        perr(
            "model",
            format!(
                "unknown material model `{model}`; expected one of: {}",
                MODELS.join(", ")
            ),
        )
    })?;
    for (key, values) in p.given() {
        if !names.contains(&key) && !ELECTRIC.contains(&key) {
            return Err(perr(
                key,
                format!(
                    "not a parameter of model `{model}` (its parameters: {}, permittivity, c1, c2)",
                    names.join(", ")
                ),
            ));
        }
        if let Some(x) = values.iter().find(|x| !x.is_finite()) {
            return Err(perr(
                key,
                format!("must be finite; got {}", crate::units::Short(*x)),
            ));
        }
    }
    let elec = electric_part(p)?;
    let mut warnings = Vec::new();
    let mut drucker = false;
    let mat: Arc<dyn Material> = match model {
        "neo-hooke" => {
            let mu = single_mu(p)?;
            let lambda = req("lambda", p.lambda, "the Lamé constant Λ in Pa")?;
            let k0 = lambda + 2.0 * mu / 3.0;
            if k0 <= 0.0 {
                return Err(perr(
                    "lambda",
                    format!("the bulk modulus Λ + 2μ/3 must be positive (Pa); got {k0}"),
                ));
            }
            Arc::new(ElectroNeoHooke {
                mu,
                lambda,
                eps: elec.eps,
                c1: elec.c1,
                c2: elec.c2,
            })
        }
        "neo-hooke-split" => {
            let mu = single_mu(p)?;
            let kappa = req_pos("kappa", p.kappa, "bulk modulus κ in Pa")?;
            Arc::new(Electroelastic::new(NeoHookeSplit { mu, kappa }, elec))
        }
        "yeoh" => {
            let c10 = req_pos(
                "c10",
                p.c10,
                "C₁₀ in Pa (initial shear modulus μ₀ = 2C₁₀ > 0)",
            )?;
            let c20 = req("c20", Some(p.c20.unwrap_or(0.0)), "C₂₀ in Pa")?;
            let c30 = req("c30", Some(p.c30.unwrap_or(0.0)), "C₃₀ in Pa")?;
            let d1 = req_pos(
                "d1",
                p.d1,
                "D₁ in 1/Pa (initial bulk modulus K₀ = 2/D₁ > 0)",
            )?;
            let d2 = req("d2", Some(p.d2.unwrap_or(0.0)), "D₂ in 1/Pa (0 = term off)")?;
            let d3 = req("d3", Some(p.d3.unwrap_or(0.0)), "D₃ in 1/Pa (0 = term off)")?;
            let y = Yeoh::new(c10, c20, c30, d1, d2, d3);
            if checks && (d2 < 0.0 || d3 < 0.0) {
                warnings.push(volumetric_convexity_warning(&y));
            }
            drucker = checks;
            Arc::new(Electroelastic::new(y, elec))
        }
        "mooney-rivlin" => {
            let c10 = req("c10", p.c10, "C₁₀ in Pa")?;
            let c01 = req("c01", p.c01, "C₀₁ in Pa")?;
            if c10 + c01 <= 0.0 {
                return Err(perr(
                    "c10",
                    format!(
                        "the initial shear modulus 2(C₁₀ + C₀₁) must be positive (Pa); got {}",
                        2.0 * (c10 + c01)
                    ),
                ));
            }
            let d1 = req_pos(
                "d1",
                p.d1,
                "D₁ in 1/Pa (initial bulk modulus K₀ = 2/D₁ > 0)",
            )?;
            drucker = checks;
            Arc::new(Electroelastic::new(MooneyRivlin { c10, c01, d1 }, elec))
        }
        "gent" => {
            let mu = single_mu(p)?;
            let jm = req_pos("jm", p.jm, "locking parameter J_m > 0 (dimensionless)")?;
            let kappa = req_pos("kappa", p.kappa, "bulk modulus κ in Pa")?;
            Arc::new(Electroelastic::new(Gent { mu, jm, kappa }, elec))
        }
        "ogden" => {
            if p.mu.is_empty() {
                return Err(perr(
                    "mu",
                    "missing: expected the Ogden coefficients μₚ in Pa",
                ));
            }
            if p.alpha.len() != p.mu.len() {
                return Err(perr(
                    "alpha",
                    format!(
                        "expected one exponent αₚ (dimensionless) per coefficient μₚ: {} μ values, {} α values",
                        p.mu.len(),
                        p.alpha.len()
                    ),
                ));
            }
            if let Some(i) = p.alpha.iter().position(|&a| a == 0.0) {
                return Err(perr(
                    "alpha",
                    format!("exponent α{} must be non-zero (dimensionless)", i + 1),
                ));
            }
            let kappa = req_pos("kappa", p.kappa, "bulk modulus κ in Pa")?;
            let o = Ogden::new(p.mu.clone(), p.alpha.clone(), kappa);
            let mu0 = super::hyperelastic::Hyperelastic::shear_modulus(&o);
            if mu0.is_nan() || mu0 <= 0.0 {
                return Err(perr(
                    "mu",
                    format!("the initial shear modulus ½ Σ μₚαₚ must be positive (Pa); got {mu0}"),
                ));
            }
            drucker = checks;
            Arc::new(Electroelastic::new(o, elec))
        }
        "arruda-boyce" | "arruda-boyce-series" => {
            let mu = single_mu(p)?;
            let lambda_m = req(
                "lambda_m",
                p.lambda_m,
                "locking stretch λ_m > 1 (dimensionless)",
            )?;
            if lambda_m <= 1.0 {
                return Err(perr(
                    "lambda_m",
                    format!(
                        "locking stretch λ_m must be > 1 (dimensionless); got {}",
                        crate::units::Short(lambda_m)
                    ),
                ));
            }
            let kappa = req_pos("kappa", p.kappa, "bulk modulus κ in Pa")?;
            if model == "arruda-boyce" {
                Arc::new(Electroelastic::new(
                    ArrudaBoyce {
                        mu,
                        lambda_m,
                        kappa,
                    },
                    elec,
                ))
            } else {
                Arc::new(Electroelastic::new(
                    ArrudaBoyceSeries {
                        mu,
                        lambda_m,
                        kappa,
                    },
                    elec,
                ))
            }
        }
        _ => unreachable!("parameter_names covers every model"),
    };
    let (mu0, k0) = (mat.shear_modulus(), mat.bulk_modulus());
    debug_assert!(mu0 > 0.0 && k0 > 0.0);
    if checks && k0 / mu0 > STIFF_RATIO_WARNING {
        warnings.push(format!(
            "model `{model}`: K₀/μ₀ = {:.1e} (K₀ = {k0:e} Pa, μ₀ = {mu0:e} Pa) is very large: the tangent is ill-conditioned and displacement-only elements lock",
            k0 / mu0
        ));
    }
    if drucker {
        warnings.extend(
            drucker_check(mat.as_ref(), DRUCKER_MAX_STRETCH)
                .into_iter()
                .map(|w| format!("model `{model}`: {w}")),
        );
    }
    if p.branches.is_empty() {
        return Ok((mat, warnings));
    }
    for (i, &(g, tau)) in p.branches.iter().enumerate() {
        if !(g.is_finite() && g > 0.0) {
            return Err(perr(
                &format!("branches.{i}.mu"),
                format!(
                    "must be a positive shear modulus in Pa; got {}",
                    crate::units::Short(g)
                ),
            ));
        }
        if !(tau.is_finite() && tau > 0.0) {
            return Err(perr(
                &format!("branches.{i}.tau"),
                format!(
                    "must be a positive relaxation time in s; got {}",
                    crate::units::Short(tau)
                ),
            ));
        }
    }
    let visco: Arc<dyn Material> = Arc::new(crate::material::maxwell::Viscoelastic {
        equilibrium: mat,
        branches: p.branches.clone(),
    });
    Ok((visco, warnings))
}

/// Warning for a Yeoh model with a negative D₂ or D₃: where the
/// volumetric energy stops being convex (U″(J) ≤ 0).
fn volumetric_convexity_warning(y: &Yeoh) -> String {
    let inv_d = y.d.map(|d| if d == 0.0 { 0.0 } else { 1.0 / d });
    let mut first = None;
    'scan: for i in 1..=1000 {
        let x = i as f64 * 1e-3;
        for j in [1.0 - x, 1.0 + x] {
            if super::hyperelastic::vol_poly(&inv_d, j).ddu <= 0.0 {
                first = Some(x);
                break 'scan;
            }
        }
    }
    match first {
        Some(x) => format!(
            "model `yeoh`: a negative D₂/D₃ makes the volumetric energy non-convex for |J − 1| ≥ {x:.3}"
        ),
        None => "model `yeoh`: negative D₂/D₃; the volumetric energy stays convex for |J − 1| ≤ 1".to_string(),
    }
}

/// Drucker stability check on homogeneous paths.
///
/// For the uniaxial, equibiaxial and pure-shear paths (lateral stresses
/// zero, solved on the compressible model, see [`homogeneous`]) and
/// stretches λ ∈ [1/max_stretch, max_stretch] (121 log-spaced samples), it
/// checks Drucker's condition dτ:dε > 0 (τ Kirchhoff stress, ε logarithmic
/// strain, as in Abaqus), which on these paths reduces to
/// d(λP₁₁)/dλ > 0. Returns one warning per mode and contiguous stretch
/// range where the condition fails (or the path cannot be evaluated);
/// empty if stable.
pub fn drucker_check(mat: &dyn Material, max_stretch: f64) -> Vec<String> {
    let mut out = Vec::new();
    if !(max_stretch.is_finite() && max_stretch > 1.0) {
        return out;
    }
    const N: usize = 121;
    let lmax = max_stretch.ln();
    let stretches: Vec<f64> = (0..N)
        .map(|i| (-lmax + 2.0 * lmax * i as f64 / (N - 1) as f64).exp())
        .collect();
    for mode in Mode::ALL {
        // Contiguous ranges of unstable samples and of samples where the
        // path cannot be evaluated (e.g. Gent locking), with the first error.
        let mut unstable: Option<(f64, f64)> = None;
        let mut failed: Option<(f64, f64, String)> = None;
        let flush_unstable = |r: &mut Option<(f64, f64)>, out: &mut Vec<String>| {
            if let Some((a, b)) = r.take() {
                out.push(format!(
                    "Drucker stability lost in {} loading for stretch {a:.3}–{b:.3} (dτ/d(ln λ) ≤ 0)",
                    mode.name()
                ));
            }
        };
        let flush_failed = |r: &mut Option<(f64, f64, String)>, out: &mut Vec<String>| {
            if let Some((a, b, e)) = r.take() {
                out.push(format!(
                    "Drucker check: the {} path could not be evaluated for stretch {a:.3}–{b:.3} ({e})",
                    mode.name()
                ));
            }
        };
        for &l in &stretches {
            match homogeneous::solve(mat, mode, l) {
                Ok(st) => {
                    flush_failed(&mut failed, &mut out);
                    if st.drucker > 0.0 {
                        flush_unstable(&mut unstable, &mut out);
                    } else {
                        unstable = Some(unstable.map_or((l, l), |(a, _)| (a, l)));
                    }
                }
                Err(e) => {
                    flush_unstable(&mut unstable, &mut out);
                    failed = Some(match failed {
                        Some((a, _, first)) => (a, l, first),
                        None => (l, l, e.to_string()),
                    });
                }
            }
        }
        flush_unstable(&mut unstable, &mut out);
        flush_failed(&mut failed, &mut out);
    }
    out
}

/// Parameters of a literature preset: `(model, params)`. The caller may
/// override any field before calling [`build`].
///
/// * `vhb4910-yeoh` — Yeoh fit of VHB 4910 from an experimental study of a
///   circular dielectric elastomer actuator loaded by a mass (its Table 2,
///   values as printed): C₁₀ = 0.2019 MPa, C₂₀ = 4.43e-5 MPa,
///   C₃₀ = 1.295e-4 MPa, D₁ = 2.1839e-3, D₂ = 8.68e-5, D₃ = −1.794e-5 MPa⁻¹,
///   εᵣ = 4.7. Note D₃ < 0 (the volumetric energy is non-convex far from
///   J = 1; `build` warns) and that C₁₀ is about ten times stiffer than
///   other VHB 4910 fits.
/// * `vhb4910-yeoh-calibrated` — the same with C₁₀ alone recalibrated to
///   17.85 kPa so that the study's actuator (λp = 2, 46.22 g) sags by the
///   measured 2 mm (lumped model 2.000 mm, finite elements 1.996 mm; see
///   docs/validation.md). Table 2's C₁₀ gives 0.27 mm.
/// * `vhb4910-gent` — Gent fit from the same experimental study (MATLAB
///   parameter estimate): μ = 25.4 kPa, J_m = 120, εᵣ = 4.7. The source
///   gives no bulk modulus; κ = 1000·μ is chosen here.
/// * `vhb4910-gent-liu` — Liu, Foo, Zhang, Acta Mechanica Solida Sinica 30
///   (2017): μ = 43 kPa, J_m = 115, ε = 4.12e-11 F/m (εᵣ = ε/ε₀ ≈ 4.653),
///   K = 4.3e10 Pa as given in the project's summary of that paper. That
///   makes K/μ = 1e6 (`build` warns); override `kappa` if that is a typo.
/// * `vhb4910-ab-wang` — the eight-chain (`arruda-boyce`, Padé inverse
///   Langevin) equilibrium model of Wang, Decker, Henann & Chester, J. Mech.
///   Phys. Solids 95 (2016): G₀ = 15.36 kPa as the coefficient of the
///   eight-chain form (as they use it), λ_L = 5.99, εᵣ = 4.8; the initial shear
///   modulus is G₀(3λ_L² − 1)/(3λ_L² − 3) ≈ 15.65 kPa. κ = 1000·G₀ is chosen
///   here.
/// * `vhb4910-wang2016` — the same equilibrium branch with the three
///   neo-Hookean Maxwell branches of Wang, Decker, Henann & Chester,
///   J. Mech. Phys. Solids (2016): g = 26.06, 26.53, 10.83 kPa, τ = 0.6074, 6.56, 61.25 s.
/// * `vhb4910-hossain2012` — Hossain, Vu & Steinmann, Comput. Mater. Sci. 59
///   (2012): equilibrium μ = 13.7 kPa (the eight-chain model at small
///   stretch, taken as neo-Hooke here), branches 56.4, 31.5, 19.8 kPa with
///   τ = 0.82, 10.7, 500 s; εᵣ = 4.7 and κ = 1000·μ are chosen here.
///
/// Mass densities of the sources are not part of the material energy and
/// are not included.
pub fn preset(name: &str) -> Option<(&'static str, MaterialParams)> {
    let p = match name {
        "vhb4910-yeoh" => (
            "yeoh",
            MaterialParams {
                c10: Some(0.2019e6),
                c20: Some(4.43e1),
                c30: Some(1.295e2),
                d1: Some(2.1839e-9),
                d2: Some(8.68e-11),
                d3: Some(-1.794e-11),
                permittivity: Some(4.7),
                ..Default::default()
            },
        ),
        "vhb4910-yeoh-calibrated" => {
            let (model, mut p) = preset("vhb4910-yeoh")?;
            p.c10 = Some(17.85e3);
            (model, p)
        }
        "vhb4910-gent" => (
            "gent",
            MaterialParams {
                mu: vec![25.4e3],
                jm: Some(120.0),
                kappa: Some(1000.0 * 25.4e3),
                permittivity: Some(4.7),
                ..Default::default()
            },
        ),
        "vhb4910-gent-liu" => (
            "gent",
            MaterialParams {
                mu: vec![43e3],
                jm: Some(115.0),
                kappa: Some(4.3e10),
                permittivity: Some(4.12e-11 / EPSILON_0),
                ..Default::default()
            },
        ),
        "vhb4910-ab-wang" => {
            let g0 = 15.36e3;
            let lambda_m = 5.99;
            (
                "arruda-boyce",
                MaterialParams {
                    mu: vec![g0],
                    lambda_m: Some(lambda_m),
                    kappa: Some(1000.0 * g0),
                    permittivity: Some(4.8),
                    ..Default::default()
                },
            )
        }
        "vhb4910-wang2016" => {
            let (model, mut p) = preset("vhb4910-ab-wang")?;
            p.branches = vec![(26.06e3, 0.6074), (26.53e3, 6.56), (10.83e3, 61.25)];
            (model, p)
        }
        "vhb4910-hossain2012" => (
            "neo-hooke-split",
            MaterialParams {
                mu: vec![13.7e3],
                kappa: Some(1000.0 * 13.7e3),
                permittivity: Some(4.7),
                branches: vec![(56.4e3, 0.82), (31.5e3, 10.7), (19.8e3, 500.0)],
                ..Default::default()
            },
        ),
        _ => return None,
    };
    Some(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::{Mat3, MaterialError, Vec3};

    /// A valid parameter set for every model.
    fn valid(model: &str) -> MaterialParams {
        let base = MaterialParams {
            permittivity: Some(4.7),
            ..Default::default()
        };
        match model {
            "neo-hooke" => MaterialParams {
                mu: vec![1e5],
                lambda: Some(1e7),
                ..base
            },
            "neo-hooke-split" => MaterialParams {
                mu: vec![1e5],
                kappa: Some(1e7),
                ..base
            },
            "yeoh" => MaterialParams {
                c10: Some(5e4),
                c20: Some(-5e2),
                c30: Some(50.0),
                d1: Some(2e-9),
                ..base
            },
            "mooney-rivlin" => MaterialParams {
                c10: Some(4e4),
                c01: Some(1e4),
                d1: Some(2e-9),
                ..base
            },
            "gent" => MaterialParams {
                mu: vec![1e5],
                jm: Some(50.0),
                kappa: Some(1e7),
                ..base
            },
            "ogden" => MaterialParams {
                mu: vec![6.3e5, 1.2e3, -1e4],
                alpha: vec![1.3, 5.0, -2.0],
                kappa: Some(1e8),
                ..base
            },
            "arruda-boyce" | "arruda-boyce-series" => MaterialParams {
                mu: vec![1e5],
                lambda_m: Some(4.0),
                kappa: Some(1e7),
                ..base
            },
            _ => panic!("no valid set for {model}"),
        }
    }

    fn key_of(model: &str, p: &MaterialParams) -> String {
        match build(model, p) {
            Ok(_) => panic!("{model}: expected a parameter error for {p:?}"),
            Err(e) => {
                assert!(!e.message.is_empty());
                e.key
            }
        }
    }

    #[test]
    fn every_model_builds_and_lists_its_parameters() {
        for &m in MODELS {
            let (mat, warnings) = build(m, &valid(m)).unwrap_or_else(|e| panic!("{m}: {e}"));
            assert!(warnings.is_empty(), "{m}: {warnings:?}");
            assert!(mat.shear_modulus() > 0.0 && mat.bulk_modulus() > 0.0);
            assert!((mat.permittivity() - 4.7 * EPSILON_0).abs() < 1e-24);
            assert!(parameter_names(m).is_some());
            // Evaluates at a general point.
            let f = Mat3::new(1.1, 0.1, 0.0, 0.0, 0.95, 0.05, 0.02, 0.0, 1.0);
            mat.tangent(&f, &Vec3::new(0.0, 0.0, 1e7)).unwrap();
        }
        assert!(parameter_names("rubber").is_none());
    }

    #[test]
    fn neo_hooke_is_the_existing_model() {
        let p = MaterialParams {
            c1: Some(1e-12),
            c2: Some(2e-12),
            ..valid("neo-hooke")
        };
        let (mat, _) = build("neo-hooke", &p).unwrap();
        let reference = ElectroNeoHooke::new(1e5, 1e7, 4.7).with_coupling(1e-12, 2e-12);
        let f = Mat3::new(1.1, 0.1, 0.0, 0.0, 0.95, 0.05, 0.02, 0.0, 1.0);
        let e0 = Vec3::new(1e6, -2e6, 3e7);
        assert_eq!(
            mat.tangent(&f, &e0).unwrap(),
            reference.tangent(&f, &e0).unwrap()
        );
        assert_eq!(mat.permittivity(), reference.permittivity());
    }

    #[test]
    fn presets_build() {
        assert_eq!(PRESETS.len(), 7);
        for &name in PRESETS {
            let (model, p) = preset(name).unwrap_or_else(|| panic!("{name}"));
            assert!(MODELS.contains(&model), "{name}: {model}");
            let (mat, warnings) = build(model, &p).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(
                !warnings.iter().any(|w| w.contains("Drucker")),
                "{name}: {warnings:?}"
            );
            assert!(mat.shear_modulus() > 0.0);
            let t = mat.tangent(&Mat3::identity(), &Vec3::zeros()).unwrap();
            assert!(t.p.amax() < 1e-6 * mat.shear_modulus());
        }
        assert!(preset("vhb").is_none());

        let mu0 = |n: &str| {
            let (m, p) = preset(n).unwrap();
            build(m, &p).unwrap().0.shear_modulus()
        };
        assert!((mu0("vhb4910-yeoh") - 2.0 * 0.2019e6).abs() < 1e-6);
        assert_eq!(mu0("vhb4910-gent"), 25.4e3);
        assert_eq!(mu0("vhb4910-gent-liu"), 43e3);
        // Arruda–Boyce (eight-chain, Padé): G₀ = 15.36 kPa is the coefficient of the form, the
        // initial shear modulus G₀(3λ_L² − 1)/(3λ_L² − 3) = 15.6536 kPa at λ_L = 5.99
        let (m, p) = preset("vhb4910-ab-wang").unwrap();
        assert_eq!((m, p.mu.as_slice()), ("arruda-boyce", &[15.36e3][..]));
        assert_eq!(p.lambda_m, Some(5.99));
        assert_eq!(p.permittivity, Some(4.8));
        let g_eq: f64 = 15.36e3 * (3.0 * 35.8801 - 1.0) / (3.0 * 35.8801 - 3.0);
        assert!((g_eq - 15.6536e3).abs() < 0.1, "{g_eq}");
        assert!((mu0("vhb4910-ab-wang") - g_eq).abs() < 1e-9 * g_eq);
        // viscoelastic presets: the instantaneous modulus G_eq + Σ gᵢ, internal variables
        assert!((mu0("vhb4910-wang2016") - (g_eq + 63.42e3)).abs() < 1e-6);
        assert!((mu0("vhb4910-hossain2012") - (13.7e3 + 107.7e3)).abs() < 1e-6);
        let (m, p) = preset("vhb4910-wang2016").unwrap();
        assert_eq!(build(m, &p).unwrap().0.state_size(), 27);
        let mut bad = p.clone();
        bad.branches[1].1 = -1.0;
        let e = build(m, &bad).err().unwrap();
        assert_eq!(e.key, "branches.1.tau");

        let (m, p) = preset("vhb4910-gent-liu").unwrap();
        let (mat, warnings) = build(m, &p).unwrap();
        assert!((mat.permittivity() - 4.12e-11).abs() < 1e-24);
        assert!((mat.bulk_modulus() - 4.3e10).abs() < 1.0);
        assert!(warnings.iter().any(|w| w.contains("K₀/μ₀")), "{warnings:?}");

        // Yeoh preset: the negative D₃ is reported, bulk modulus 2/D₁.
        let (m, p) = preset("vhb4910-yeoh").unwrap();
        let (mat, warnings) = build(m, &p).unwrap();
        assert!((mat.bulk_modulus() - 2.0 / 2.1839e-9).abs() < 1e-3);
        assert!(
            warnings.iter().any(|w| w.contains("non-convex")),
            "{warnings:?}"
        );

        // Overriding a preset parameter.
        let (m, mut p) = preset("vhb4910-gent").unwrap();
        p.kappa = Some(1e8);
        assert_eq!(build(m, &p).unwrap().0.bulk_modulus(), 1e8);
    }

    #[test]
    fn bad_parameters_name_the_key() {
        let with = |model: &str, f: &dyn Fn(&mut MaterialParams)| {
            let mut p = valid(model);
            f(&mut p);
            key_of(model, &p)
        };
        assert_eq!(key_of("rubber", &valid("gent")), "model");
        // Missing.
        assert_eq!(with("yeoh", &|p| p.c10 = None), "c10");
        assert_eq!(with("yeoh", &|p| p.d1 = None), "d1");
        assert_eq!(with("gent", &|p| p.mu.clear()), "mu");
        assert_eq!(with("gent", &|p| p.kappa = None), "kappa");
        assert_eq!(with("neo-hooke", &|p| p.lambda = None), "lambda");
        assert_eq!(with("mooney-rivlin", &|p| p.c01 = None), "c01");
        assert_eq!(with("arruda-boyce", &|p| p.lambda_m = None), "lambda_m");
        assert_eq!(
            with("arruda-boyce-series", &|p| p.lambda_m = None),
            "lambda_m"
        );
        assert_eq!(with("ogden", &|p| p.alpha.clear()), "alpha");
        assert_eq!(
            with("neo-hooke-split", &|p| p.permittivity = None),
            "permittivity"
        );
        // Non-finite.
        assert_eq!(
            with("neo-hooke-split", &|p| p.kappa = Some(f64::NAN)),
            "kappa"
        );
        assert_eq!(with("ogden", &|p| p.mu[1] = f64::INFINITY), "mu");
        assert_eq!(with("yeoh", &|p| p.c30 = Some(f64::NAN)), "c30");
        assert_eq!(with("gent", &|p| p.c2 = Some(f64::NAN)), "c2");
        // Non-positive moduli.
        assert_eq!(with("neo-hooke-split", &|p| p.mu = vec![-1.0]), "mu");
        assert_eq!(with("neo-hooke", &|p| p.lambda = Some(-1e5)), "lambda");
        assert_eq!(with("yeoh", &|p| p.c10 = Some(0.0)), "c10");
        assert_eq!(with("yeoh", &|p| p.d1 = Some(0.0)), "d1");
        assert_eq!(with("mooney-rivlin", &|p| p.c01 = Some(-5e4)), "c10");
        assert_eq!(with("mooney-rivlin", &|p| p.d1 = Some(-1e-7)), "d1");
        assert_eq!(with("gent", &|p| p.kappa = Some(0.0)), "kappa");
        assert_eq!(with("ogden", &|p| p.mu = vec![-6.3e5, 1.2e3, -1e4]), "mu");
        // Model-specific.
        assert_eq!(with("gent", &|p| p.jm = Some(0.0)), "jm");
        assert_eq!(
            with("arruda-boyce", &|p| p.lambda_m = Some(1.0)),
            "lambda_m"
        );
        assert_eq!(
            with("arruda-boyce-series", &|p| p.lambda_m = Some(0.5)),
            "lambda_m"
        );
        assert_eq!(with("ogden", &|p| p.alpha.push(2.0)), "alpha");
        assert_eq!(with("ogden", &|p| p.alpha[0] = 0.0), "alpha");
        assert_eq!(with("gent", &|p| p.mu.push(1e5)), "mu");
        // Dielectric.
        assert_eq!(
            with("gent", &|p| p.permittivity = Some(0.5)),
            "permittivity"
        );
        assert_eq!(with("gent", &|p| p.c1 = Some(3.0 * EPSILON_0)), "c1");
        // A parameter of another model.
        assert_eq!(with("gent", &|p| p.c10 = Some(1e5)), "c10");
        assert_eq!(with("neo-hooke-split", &|p| p.lambda = Some(1e7)), "lambda");
        assert_eq!(with("mooney-rivlin", &|p| p.d2 = Some(1e-9)), "d2");
        // Display includes the key and the unit.
        let e = build(
            "gent",
            &MaterialParams {
                jm: Some(-1.0),
                ..valid("gent")
            },
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("jm: "), "{e}");
        let e = build(
            "gent",
            &MaterialParams {
                kappa: None,
                ..valid("gent")
            },
        )
        .unwrap_err();
        assert!(e.message.contains("Pa"), "{e}");
    }

    #[test]
    fn drucker_check_flags_unstable_yeoh_only() {
        // K₀/μ₀ = 5e4: close to the incompressible limit, so that the onset
        // can be compared with the incompressible closed form.
        let yeoh = |c20: f64, c30: f64| MaterialParams {
            c10: Some(1e5),
            c20: Some(c20),
            c30: Some(c30),
            d1: Some(2e-10),
            permittivity: Some(4.7),
            ..Default::default()
        };
        // Stable: W₁ = 1e5 − 2e3 x + 300 x² > 0 and the check range includes
        // equibiaxial compression to 1/3 (Ī₁ − 3 ≈ 78).
        let (_, w) = build("yeoh", &yeoh(-1e3, 1e2)).unwrap();
        assert!(w.is_empty(), "{w:?}");
        // Unstable: W₁ = C₁₀ + 2C₂₀(Ī₁ − 3) vanishes at Ī₁ − 3 = 2.5.
        let (mat, w) = build("yeoh", &yeoh(-2e4, 0.0)).unwrap();
        for mode in ["uniaxial", "equibiaxial", "pure shear"] {
            assert!(
                w.iter().any(|s| s.contains("Drucker") && s.contains(mode)),
                "{mode}: {w:?}"
            );
        }
        // Uniaxial tension: the incompressible Drucker rate
        // λ dτ/dλ = 2(2λ² + 1/λ)W₁ + 4(λ² − 1/λ)² W₁₁ (W₁ = 1e5 − 4e4 x,
        // W₁₁ = −4e4, x = λ² + 2/λ − 3) first vanishes at λ ≈ 1.664; the
        // warning for the tension range must start at the first sample
        // beyond that.
        let direct = drucker_check(mat.as_ref(), 3.0);
        let start_of = |s: &str| -> f64 {
            s.split("stretch ")
                .nth(1)
                .and_then(|s| s.split('–').next())
                .and_then(|s| s.parse().ok())
                .unwrap_or_else(|| panic!("cannot parse {s}"))
        };
        let uni = direct
            .iter()
            .find(|s| s.contains("uniaxial") && start_of(s) > 1.0)
            .unwrap_or_else(|| panic!("{direct:?}"));
        let rate = |l: f64| {
            let x = l * l + 2.0 / l - 3.0;
            let (w1, w11) = (1e5 - 4e4 * x, -4e4);
            2.0 * (2.0 * l * l + 1.0 / l) * w1 + 4.0 * (l * l - 1.0 / l).powi(2) * w11
        };
        // Bisection for the onset in tension.
        let (mut a, mut b) = (1.0, 3.0);
        for _ in 0..60 {
            let c = 0.5 * (a + b);
            if rate(c) > 0.0 {
                a = c
            } else {
                b = c
            }
        }
        assert!((a - 1.6637).abs() < 1e-3, "{a}");
        let start = start_of(uni);
        // The check samples 121 log-spaced stretches (ratio 1.0185 apart).
        // Allow 1e-3 for the residual compressibility.
        assert!(
            start >= a * (1.0 - 1e-3) && start < a * 1.02,
            "onset {a}, reported {uni}"
        );

        // Ogden with a dominant negative-α softening term is flagged too.
        let og = MaterialParams {
            mu: vec![2e5, -5e2],
            alpha: vec![1.0, 4.0],
            kappa: Some(1e8),
            permittivity: Some(4.7),
            ..Default::default()
        };
        let (_, w) = build("ogden", &og).unwrap();
        assert!(w.iter().any(|s| s.contains("Drucker")), "{w:?}");
        // Split neo-Hooke is stable everywhere.
        let nh = build("neo-hooke-split", &valid("neo-hooke-split"))
            .unwrap()
            .0;
        assert!(drucker_check(nh.as_ref(), 3.0).is_empty());
        // Gent (J_m = 50) locks in equibiaxial compression before 1/3
        // (Ī₁ − 3 ≈ 78 there): reported as not evaluable, nothing else.
        let gent = build("gent", &valid("gent")).unwrap().0;
        let w = drucker_check(gent.as_ref(), 3.0);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("equibiaxial") && w[0].contains("locked"),
            "{w:?}"
        );
    }

    #[test]
    fn gent_locking_is_out_of_domain() {
        let p = MaterialParams {
            jm: Some(5.0),
            ..valid("gent")
        };
        let (mat, _) = build("gent", &p).unwrap();
        // Incompressible uniaxial λ = 3: Ī₁ − 3 = 9 + 2/3 − 3 ≈ 6.67 > J_m.
        let s = 1.0 / 3f64.sqrt();
        let f = Mat3::from_diagonal(&Vec3::new(3.0, s, s));
        let e0 = Vec3::zeros();
        assert!(matches!(
            mat.energy(&f, &e0),
            Err(MaterialError::OutOfDomain(_))
        ));
        assert!(matches!(
            mat.stress(&f, &e0),
            Err(MaterialError::OutOfDomain(_))
        ));
        assert!(matches!(
            mat.tangent(&f, &e0),
            Err(MaterialError::OutOfDomain(_))
        ));
        assert!(matches!(
            mat.energy_split(&f, &e0),
            Err(MaterialError::OutOfDomain(_))
        ));
        // Just inside the limit it evaluates (λ = 2.5: Ī₁ − 3 = 4.05).
        let s = 1.0 / 2.5f64.sqrt();
        let f = Mat3::from_diagonal(&Vec3::new(2.5, s, s));
        let t = mat.tangent(&f, &e0).unwrap();
        assert!(t.a.iter().all(|x| x.is_finite()));
    }

    /// The eight-chain model locks at λ̄ = λ_L (Ī₁ = 3λ_L²): an error naming λ_L, not a NaN;
    /// the series has no such limit.
    #[test]
    fn arruda_boyce_locking_is_out_of_domain() {
        let (mat, _) = build("arruda-boyce", &valid("arruda-boyce")).unwrap();
        let (series, _) = build("arruda-boyce-series", &valid("arruda-boyce-series")).unwrap();
        let e0 = Vec3::zeros();
        // λ_m = 4: incompressible uniaxial λ̄ = λ_L at λ² + 2/λ = 48, λ ≈ 6.914
        let at = |l: f64| {
            let s = 1.0 / l.sqrt();
            Mat3::from_diagonal(&Vec3::new(l, s, s))
        };
        for l in [6.92, 7.5, 20.0] {
            let f = at(l);
            let e = mat.tangent(&f, &e0).unwrap_err();
            assert!(matches!(e, MaterialError::OutOfDomain(_)), "{e:?}");
            assert!(e.to_string().contains("lambda_m"), "{e}");
            assert!(matches!(
                mat.stress(&f, &e0),
                Err(MaterialError::OutOfDomain(_))
            ));
            assert!(matches!(
                mat.energy(&f, &e0),
                Err(MaterialError::OutOfDomain(_))
            ));
            let k = crate::material::KnownDeformation::new(&f).unwrap();
            assert!(mat
                .stress_known(&k, &e0, crate::material::PointHistory::NONE)
                .is_err());
            assert!(series.tangent(&f, &e0).is_ok());
        }
        let t = mat.tangent(&at(6.9), &e0).unwrap();
        assert!(t.a.iter().chain(t.p.iter()).all(|x| x.is_finite()));
    }
}
