//! A material's parameters as a vector θ, and the exact derivatives of its response with respect
//! to them: what gradients of whole runs (adjoint), calibration and optimal control need.
//!
//! Every material built by the [`registry`](super::registry) names its parameters with the keys
//! a scenario gives them below `materials.<name>.` ([`Parameters::names`]): the model's own
//! (`mu`, `kappa`, `c10`, `jm`, `lambda_m`, …; `mu.0`, `alpha.0`, … for Ogden's lists), then the
//! dielectric `permittivity` (relative), `c1`, `c2`, then each Maxwell branch's
//! `branches.<i>.mu` and `branches.<i>.tau`. Units are the scenario's (SI; `permittivity`
//! dimensionless). A Yeoh D₂ or D₃ of 0 switches its term off and is no parameter: the energy
//! (J − 1)^(2i)/Dᵢ has no derivative in Dᵢ there.
//!
//! [`Material::with_parameters`](super::Material::with_parameters) rebuilds the same model from a
//! new θ through the registry's validation; [`Material::parameter_derivatives_at`] gives
//! ∂Ψ/∂θ, ∂P/∂θ and ∂D0/∂θ of [`Material::stress_at`](super::Material::stress_at), and a material
//! with internal variables the vector–Jacobian products of its update
//! ([`Material::update_state_vjp`]) and of its stress in the committed variables
//! ([`Material::stress_state_vjp`]).
//!
//! # Why by hand
//!
//! The derivatives are written out, not taken with dual numbers: most parameters enter the
//! energy linearly (μ, κ, Λ, Cᵢⱼ, 1/Dᵢ, ε, c₁, c₂, a branch's g), so the derivative in one of
//! them is the model evaluated with that coefficient 1 and the others 0 — the existing, tested
//! code, exact and as fast as one stress. The few that enter nonlinearly (Gent's J_m, the
//! Arruda–Boyce λ_m, Ogden's αₚ, a branch's τ) change only a scalar function of the invariants
//! (or of the principal stretches), whose derivative is short. Dual numbers would need every
//! model generic over its scalar type, or a dependency, for the same numbers.
//!
//! [`Material::parameter_derivatives_at`]: super::Material::parameter_derivatives_at
//! [`Material::update_state_vjp`]: super::Material::update_state_vjp
//! [`Material::stress_state_vjp`]: super::Material::stress_state_vjp

use super::electric::ElectricPart;
use super::isotropic::CKinematics;
use super::{Mat3, Material, MaterialError, PointHistory, Stress, Tangent, Vec3, EPSILON_0};

/// A material's parameter vector θ: the registry model it is an instance of, one name per entry
/// (the scenario key below `materials.<name>.`) and the values (SI units, as the scenario's).
#[derive(Debug, Clone, PartialEq)]
pub struct Parameters {
    /// The registry model (`gent`, `ogden`, …): [`super::registry::MODELS`].
    pub model: &'static str,
    pub names: Vec<String>,
    pub values: Vec<f64>,
}

impl Parameters {
    /// The index of the entry named `name`.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Appends the entry `name = value`.
    pub fn push(&mut self, name: impl Into<String>, value: f64) {
        self.names.push(name.into());
        self.values.push(value);
    }
}

/// The vector–Jacobian products of an update of the internal variables, A_{n+1} =
/// `update_state`(F, E0, A_n, Δt), for a vector w over A_{n+1}.
#[derive(Debug, Clone, PartialEq)]
pub struct StateVjp {
    /// wᵀ ∂A_{n+1}/∂θ, one entry per parameter.
    pub theta: Vec<f64>,
    /// wᵀ ∂A_{n+1}/∂A_n, one entry per committed internal variable.
    pub state: Vec<f64>,
    /// wᵀ ∂A_{n+1}/∂F (entry (i, J) for F_iJ).
    pub f: Mat3,
    /// wᵀ ∂A_{n+1}/∂E0.
    pub e0: Vec3,
}

/// The dielectric entries of θ: `permittivity` (relative εᵣ), `c1`, `c2` of `e`.
pub(crate) fn push_electric(p: &mut Parameters, e: &ElectricPart) {
    p.push("permittivity", e.eps / EPSILON_0);
    p.push("c1", e.c1);
    p.push("c2", e.c2);
}

/// ∂(Ψ, P, D0)/∂(εᵣ, c₁, c₂): the dielectric energy is linear in ε = εᵣε₀, c₁ and c₂, so each
/// derivative is the dielectric part with that coefficient alone (ε₀ for εᵣ).
pub(crate) fn electric(f: &Mat3, k: &CKinematics, e0: &Vec3) -> [Stress; ELECTRIC] {
    std::array::from_fn(|i| electric_entry(f, k, e0, i))
}

/// Parameters of the dielectric part: εᵣ, c₁, c₂.
pub(crate) const ELECTRIC: usize = 3;

/// The entry `i` (< [`ELECTRIC`]) of [`electric`] alone.
pub(crate) fn electric_entry(f: &Mat3, k: &CKinematics, e0: &Vec3, i: usize) -> Stress {
    let mut unit = [0.0; ELECTRIC];
    unit[i] = 1.0;
    let part = ElectricPart {
        eps: unit[0] * EPSILON_0,
        c1: unit[1],
        c2: unit[2],
    };
    let (s, d0) = part.first(k, e0);
    Stress {
        energy: part.energy(k, e0),
        p: f * s,
        d0,
    }
}

/// The derivative of a material's response with respect to one of its parameters θₖ, seen as a
/// material: its energy, stress and electric displacement at (F, E0) and a point history are
/// ∂Ψ/∂θₖ, ∂P/∂θₖ and ∂D0/∂θₖ of the base material's [`Material::stress_at`]. An element kernel's
/// residual is linear in the stress and the electric displacement at fixed kinematics, so the
/// residual a kernel computes with this material is ∂r/∂θₖ of its residual with the base: the
/// parameter vector–Jacobian product of the cell kernels, exact, with no kernel code of its own.
/// It has no tangent. Each evaluation asks the base for its one entry
/// ([`Material::parameter_derivative_at`]).
#[derive(Debug, Clone)]
pub struct ParameterDerivative {
    pub base: std::sync::Arc<dyn Material>,
    /// The entry k of the base's [`Material::parameters`].
    pub index: usize,
}

impl Material for ParameterDerivative {
    fn energy(&self, f: &Mat3, e0: &Vec3) -> Result<f64, MaterialError> {
        self.stress(f, e0).map(|s| s.energy)
    }
    fn stress(&self, f: &Mat3, e0: &Vec3) -> Result<Stress, MaterialError> {
        self.stress_at(f, e0, PointHistory::NONE)
    }
    fn tangent(&self, _f: &Mat3, _e0: &Vec3) -> Result<Tangent, MaterialError> {
        Err(MaterialError::OutOfDomain(
            "a parameter derivative has no tangent".into(),
        ))
    }
    fn shear_modulus(&self) -> f64 {
        self.base.shear_modulus()
    }
    fn bulk_modulus(&self) -> f64 {
        self.base.bulk_modulus()
    }
    fn permittivity(&self) -> f64 {
        self.base.permittivity()
    }
    fn energy_split(&self, f: &Mat3, e0: &Vec3) -> Result<(f64, f64), MaterialError> {
        self.stress(f, e0).map(|s| (s.energy, 0.0))
    }
    fn state_size(&self) -> usize {
        self.base.state_size()
    }
    fn energy_at(&self, f: &Mat3, e0: &Vec3, h: PointHistory) -> Result<f64, MaterialError> {
        self.stress_at(f, e0, h).map(|s| s.energy)
    }
    fn stress_at(&self, f: &Mat3, e0: &Vec3, h: PointHistory) -> Result<Stress, MaterialError> {
        self.base.parameter_derivative_at(f, e0, h, self.index)
    }
    fn tangent_at(
        &self,
        _f: &Mat3,
        _e0: &Vec3,
        _h: PointHistory,
    ) -> Result<Tangent, MaterialError> {
        Err(MaterialError::OutOfDomain(
            "a parameter derivative has no tangent".into(),
        ))
    }
}
