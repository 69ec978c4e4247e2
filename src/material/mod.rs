//! Constitutive models for electro-active (dielectric elastomer) materials.
//!
//! Every model is described by an energy per unit reference volume Ψ(F, E0),
//! where F is the deformation gradient and E0 = −∇₀Φ the referential electric
//! field. The element kernels only see the [`Material`] trait, which provides
//!
//! * `P  = ∂Ψ/∂F` (first Piola–Kirchhoff stress),
//! * `D0 = −∂Ψ/∂E0` (referential electric displacement),
//! * `A  = ∂²Ψ/∂F∂F` as a 9×9 matrix, row/column index `i*3+J` for `F_iJ`,
//! * `B  = ∂²Ψ/∂F∂E0 = ∂P/∂E0` as a 9×3 matrix, entry `(i*3+J, K)`,
//! * `G  = ∂²Ψ/∂E0∂E0 = −∂D0/∂E0` (negative definite for a dielectric).
//!
//! Models that are naturally written in terms of C = FᵀF implement
//! [`isotropic::CMaterial`] and use the generic conversion functions in
//! [`isotropic`] to obtain the F-form quantities.
//!
//! The isotropic models are assembled from a purely mechanical energy W(C)
//! ([`hyperelastic::Hyperelastic`]: [`NeoHooke`], [`NeoHookeSplit`],
//! [`Yeoh`], [`MooneyRivlin`], [`Gent`], [`Ogden`], [`ArrudaBoyce`],
//! [`ArrudaBoyceSeries`]) and the
//! linear dielectric [`ElectricPart`] by the generic [`Electroelastic`].
//! [`registry`] builds validated models from names, parameters and
//! literature presets.

pub mod arruda_boyce;
pub mod electric;
pub mod electroelastic;
pub mod gent;
pub mod homogeneous;
pub mod hyperelastic;
pub mod isotropic;
pub mod lab;
pub mod maxwell;
pub mod mooney_rivlin;
pub mod neo_hooke;
pub mod neo_hooke_split;
pub mod ogden;
pub mod parameters;
pub mod point_history;
pub mod registry;
pub mod yeoh;

#[cfg(test)]
mod fd_tests;
#[cfg(test)]
mod model_tests;
#[cfg(test)]
mod param_tests;

use crate::algebra::lanes::{Lane, F4};
pub use arruda_boyce::{
    ArrudaBoyce, ArrudaBoyceSeries, ElectroArrudaBoyce, ElectroArrudaBoyceSeries,
};
pub use electric::ElectricPart;
pub use electroelastic::Electroelastic;
pub use gent::{ElectroGent, Gent};
pub use hyperelastic::Hyperelastic;
pub use mooney_rivlin::{ElectroMooneyRivlin, MooneyRivlin};
pub use neo_hooke::{ElectroNeoHooke, NeoHooke};
pub use neo_hooke_split::{ElectroNeoHookeSplit, NeoHookeSplit};
pub use ogden::{ElectroOgden, Ogden};
pub use parameters::{ParameterDerivative, Parameters, StateVjp};
pub use registry::{MaterialParams, ParamError};
pub use yeoh::{ElectroYeoh, Yeoh};

/// 3×3 matrix (deformation gradient, stresses, …).
pub type Mat3 = nalgebra::Matrix3<f64>;
/// 3-vector (electric field, displacement, …).
pub type Vec3 = nalgebra::Vector3<f64>;
/// 9×9 matrix: the mechanical tangent `∂P/∂F` in row-major flattening of F.
pub type Mat9 = nalgebra::SMatrix<f64, 9, 9>;
/// 9×3 matrix: the coupling tangent `∂P/∂E0`.
pub type Mat93 = nalgebra::SMatrix<f64, 9, 3>;

/// Vacuum permittivity ε₀ in F/m.
pub const EPSILON_0: f64 = 8.8541878128e-12;

/// Error evaluating a material at a point (e.g. J <= 0).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MaterialError {
    /// The volume ratio J = det F is not positive (or not finite).
    #[error("non-positive volume ratio J = {0:e}")]
    NonPositiveJ(f64),
    /// Any other input outside the model's domain.
    #[error("{0}")]
    OutOfDomain(String),
}

/// First derivatives at a point.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Stress {
    /// Energy per reference volume Ψ (J/m³).
    pub energy: f64,
    /// First Piola–Kirchhoff stress P = ∂Ψ/∂F (Pa).
    pub p: Mat3,
    /// Referential electric displacement D0 = −∂Ψ/∂E0 (C/m²).
    pub d0: Vec3,
}

/// The derivatives of a point's energy that Gauss's law needs: D0 and the second derivatives in
/// E0 (what the potential's rows of a tangent are made of).
#[derive(Debug, Clone, PartialEq)]
pub struct ElectricTangent {
    /// Referential electric displacement D0 = −∂Ψ/∂E0 (C/m²).
    pub d0: Vec3,
    /// B = ∂P/∂E0 = −(∂D0/∂F)ᵀ, entry `(i*3+J, K)`.
    pub b: Mat93,
    /// G = ∂²Ψ/∂E0∂E0 = −∂D0/∂E0.
    pub g: Mat3,
}

/// First and second derivatives at a point.
#[derive(Debug, Clone, PartialEq)]
pub struct Tangent {
    /// Energy per reference volume Ψ (J/m³).
    pub energy: f64,
    /// First Piola–Kirchhoff stress P = ∂Ψ/∂F (Pa).
    pub p: Mat3,
    /// Referential electric displacement D0 = −∂Ψ/∂E0 (C/m²).
    pub d0: Vec3,
    /// A = ∂²Ψ/∂F∂F, entry `(i*3+J, k*3+L)` = ∂P_iJ/∂F_kL.
    pub a: Mat9,
    /// B = ∂P/∂E0, entry `(i*3+J, K)` = ∂P_iJ/∂E0_K.
    pub b: Mat93,
    /// G = ∂²Ψ/∂E0∂E0 = −∂D0/∂E0.
    pub g: Mat3,
}

/// A deformation gradient with its inverse transpose, determinant and J^(−2/3) already at hand
/// (an element kernel computes them for its own needs): the `*_known` methods of [`Material`]
/// then form no inverse and take no fractional power.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Known<T: Lane> {
    pub f: nalgebra::Matrix3<T>,
    /// F⁻ᵀ.
    pub f_inv_t: nalgebra::Matrix3<T>,
    /// J = det F > 0.
    pub j: T,
    /// J^(−2/3).
    pub jm23: T,
}

/// The [`Known`] deformation of one point.
pub type KnownDeformation = Known<f64>;

/// The [`Known`] deformations of a lane of points (four, one a lane).
pub type KnownLanes = Known<F4>;

/// The stresses of a lane of points ([`Material::stress_known_lanes`]): energies, first Piola
/// stresses and electric displacements, one point a lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StressLanes {
    pub energy: F4,
    pub p: nalgebra::Matrix3<F4>,
    pub d0: nalgebra::Vector3<F4>,
}

impl KnownDeformation {
    /// The quantities of F computed from F (`None` unless J > 0 and finite).
    pub fn new(f: &Mat3) -> Option<Self> {
        let j = f.determinant();
        if !(j > 0.0 && j.is_finite()) {
            return None;
        }
        let f_inv_t = f.try_inverse()?.transpose();
        let r = j.cbrt();
        Some(KnownDeformation {
            f: *f,
            f_inv_t,
            j,
            jm23: 1.0 / (r * r),
        })
    }
}

/// What the record of a state needs of a material point: the stress of the full state, the
/// energy split `(mechanical, electric)` of [`Material::energy_split_at`] and the first Piola
/// stress at zero field (the mechanical stress of the output fields).
#[derive(Debug, Clone, PartialEq)]
pub struct PointRecord {
    pub stress: Stress,
    pub split: (f64, f64),
    pub p_mech: Mat3,
}

/// What a material with internal variables sees of a point's history: the committed internal
/// variables (empty for an elastic material) and the time step to the state being evaluated.
#[derive(Debug, Clone, Copy)]
pub struct PointHistory<'a> {
    pub state: &'a [f64],
    /// Time step (s) from the committed state; 0 gives the instantaneous response.
    pub dt: f64,
}

impl PointHistory<'_> {
    /// No history: an elastic material's point.
    pub const NONE: PointHistory<'static> = PointHistory {
        state: &[],
        dt: 0.0,
    };
}

/// An electro-elastic material described by an energy Ψ(F, E0) per unit
/// reference volume.
///
/// A material may carry internal variables per quadrature point ([`Material::state_size`] > 0).
/// Within a step it is evaluated from the committed variables and the time step (the `*_at`
/// methods: the energy, stress and tangent of the step's incremental potential); when the step is
/// accepted, [`Material::update_state`] gives the new variables, which the run commits. Elastic
/// materials keep the defaults and pay nothing.
pub trait Material: Send + Sync + std::fmt::Debug {
    /// Energy per reference volume Ψ(F, E0).
    fn energy(&self, f: &Mat3, e0: &Vec3) -> Result<f64, MaterialError>;
    /// Energy and first derivatives.
    fn stress(&self, f: &Mat3, e0: &Vec3) -> Result<Stress, MaterialError>;
    /// Energy, first and second derivatives.
    fn tangent(&self, f: &Mat3, e0: &Vec3) -> Result<Tangent, MaterialError>;
    /// Small-strain shear modulus (Pa), used to scale the potential unknowns.
    fn shear_modulus(&self) -> f64;
    /// Small-strain bulk modulus (Pa).
    fn bulk_modulus(&self) -> f64;
    /// Small-strain permittivity (F/m), ε − 2c₁ − 2c₂ for the Vu form.
    fn permittivity(&self) -> f64;
    /// Split of the energy for bookkeeping: `(mechanical, electric)` where
    /// `mechanical` is the purely hyperelastic part (no E0 dependence) and
    /// `electric = −(all E0-dependent terms)`, so that Ψ = mechanical − electric.
    fn energy_split(&self, f: &Mat3, e0: &Vec3) -> Result<(f64, f64), MaterialError>;

    /// How far the material is towards its locking limit at `f` (1 = locked, e.g. a Gent
    /// network with Ī₁ − 3 = J_m) and the key of the parameter that sets the limit; `None` for a
    /// material without one. Tells a failure at the material's limit from a loss of stability.
    fn locking(&self, _f: &Mat3) -> Option<(f64, &'static str)> {
        None
    }
    /// Internal variables per quadrature point (0: elastic).
    fn state_size(&self) -> usize {
        0
    }
    /// The elastic material a point with internal variables relaxes to in the long-time limit
    /// (`None`: elastic, or no such limit is known). The small-signal analyses linearise about
    /// the relaxed state.
    fn relaxed(&self) -> Option<std::sync::Arc<dyn Material>> {
        None
    }
    /// The Maxwell branches `(shear modulus in Pa, relaxation time in s)` that
    /// [`Material::relaxed`] drops: about the relaxed state their instantaneous tangents scale
    /// with the moduli, which the frequency response uses (complex modulus).
    fn maxwell_branches(&self) -> Vec<(f64, f64)> {
        Vec::new()
    }
    /// The internal variables of the virgin material.
    fn initial_state(&self, _state: &mut [f64]) {}
    /// Names of the internal variables (for field output).
    fn state_names(&self) -> Vec<String> {
        Vec::new()
    }
    /// Incremental energy of a step from the committed state `h`.
    fn energy_at(&self, f: &Mat3, e0: &Vec3, _h: PointHistory) -> Result<f64, MaterialError> {
        self.energy(f, e0)
    }
    /// Its first derivatives.
    fn stress_at(&self, f: &Mat3, e0: &Vec3, _h: PointHistory) -> Result<Stress, MaterialError> {
        self.stress(f, e0)
    }
    /// The referential electric displacement D0 of [`Material::stress_at`] alone: a solve for
    /// the potential at held displacements needs no stress.
    fn electric_displacement_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        h: PointHistory,
    ) -> Result<Vec3, MaterialError> {
        self.stress_at(f, e0, h).map(|s| s.d0)
    }
    /// [`Material::stress_at`] at a deformation whose inverse and J^(−2/3) the caller knows;
    /// equal to it up to round-off. Models override it to skip their own kinematics.
    fn stress_known(
        &self,
        k: &KnownDeformation,
        e0: &Vec3,
        h: PointHistory,
    ) -> Result<Stress, MaterialError> {
        self.stress_at(&k.f, e0, h)
    }
    /// [`Material::stress_known`] of a lane of points at once, each lane the same
    /// bits as `stress_known` of its point; `None` where the model has no lane form or a lane
    /// is out of its domain (the caller then evaluates the points one by one, and meets the
    /// error there). `h` is the first point's history: a model with internal variables has
    /// no lane form, and callers ask it only of points that have none.
    fn stress_known_lanes(
        &self,
        _k: &KnownLanes,
        _e0: &nalgebra::Vector3<F4>,
        _h: PointHistory,
    ) -> Option<StressLanes> {
        None
    }
    /// [`Material::electric_displacement_at`] at a known deformation (see
    /// [`Material::stress_known`]).
    fn electric_displacement_known(
        &self,
        k: &KnownDeformation,
        e0: &Vec3,
        h: PointHistory,
    ) -> Result<Vec3, MaterialError> {
        self.electric_displacement_at(&k.f, e0, h)
    }
    /// The [`PointRecord`] of a point at a known deformation: by default the stress at the
    /// state, the energy split and the stress at zero field, three evaluations that a model may
    /// share.
    fn record_known(
        &self,
        k: &KnownDeformation,
        e0: &Vec3,
        h: PointHistory,
    ) -> Result<PointRecord, MaterialError> {
        Ok(PointRecord {
            stress: self.stress_known(k, e0, h)?,
            split: self.energy_split_at(&k.f, e0, h.state)?,
            p_mech: self.stress_known(k, &Vec3::zeros(), h)?.p,
        })
    }
    /// Its first and second derivatives (the consistent tangent of the update).
    fn tangent_at(&self, f: &Mat3, e0: &Vec3, _h: PointHistory) -> Result<Tangent, MaterialError> {
        self.tangent(f, e0)
    }
    /// The part of [`Material::tangent_at`] that Gauss's law needs (D0, B, G): a model whose
    /// electric part is separate gives it without the mechanical second derivatives.
    fn electric_tangent_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        h: PointHistory,
    ) -> Result<ElectricTangent, MaterialError> {
        let t = self.tangent_at(f, e0, h)?;
        Ok(ElectricTangent {
            d0: t.d0,
            b: t.b,
            g: t.g,
        })
    }
    /// `(stored mechanical, electric)` energy densities at a committed state (the branches' stored
    /// energy included), as [`Material::energy_split`].
    fn energy_split_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        _state: &[f64],
    ) -> Result<(f64, f64), MaterialError> {
        self.energy_split(f, e0)
    }
    /// The internal variables at the end of an accepted step (written to `new`) and the energy
    /// dissipated per reference volume over the step (J/m³).
    fn update_state(
        &self,
        _f: &Mat3,
        _e0: &Vec3,
        _h: PointHistory,
        _new: &mut [f64],
    ) -> Result<f64, MaterialError> {
        Ok(0.0)
    }

    /// The parameter vector θ: the registry model, one name per entry (the scenario's key below
    /// `materials.<name>.`) and the values ([`parameters`]); `None` for a material the registry
    /// does not build.
    fn parameters(&self) -> Option<Parameters> {
        None
    }
    /// The same model with the parameter vector `theta` (in the order of
    /// [`Material::parameters`]), validated as the registry validates a scenario's material
    /// (without its warnings); an error names the entry.
    fn with_parameters(&self, theta: &[f64]) -> Result<std::sync::Arc<dyn Material>, ParamError> {
        let p = self.parameters().ok_or_else(|| ParamError {
            key: "model".into(),
            message: "this material has no parameter vector (it is not built by the registry)"
                .into(),
        })?;
        registry::rebuild(p.model, &p.names, theta)
    }
    /// ∂Ψ/∂θᵢ, ∂P/∂θᵢ and ∂D0/∂θᵢ of [`Material::stress_at`] at (F, E0) and the history `h`, one
    /// [`Stress`] per entry of [`Material::parameters`] (none for a material without them).
    fn parameter_derivatives_at(
        &self,
        _f: &Mat3,
        _e0: &Vec3,
        _h: PointHistory,
    ) -> Result<Vec<Stress>, MaterialError> {
        Ok(Vec::new())
    }
    /// The entry `index` of [`Material::parameter_derivatives_at`] alone: a pass over the cells
    /// for one parameter asks for this, and a material may skip the other entries' work (a
    /// Maxwell branch's, the dielectric's).
    fn parameter_derivative_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        h: PointHistory,
        index: usize,
    ) -> Result<Stress, MaterialError> {
        let all = self.parameter_derivatives_at(f, e0, h)?;
        let n = all.len();
        all.into_iter()
            .nth(index)
            .ok_or_else(|| no_parameter(index, n))
    }
    /// Whether ∂D0/∂θ_index can be nonzero: false only where the model knows that the
    /// parameter enters the stress alone (a solve for the potential at held displacements then
    /// has no derivative in it, and its adjoint skips that pass over the cells).
    fn parameter_enters_d0(&self, _index: usize) -> bool {
        true
    }
    /// wᵀ ∂P/∂A_n: the derivative of the first Piola stress of [`Material::stress_at`] in the
    /// committed internal variables, for `w` over P (zero-length for an elastic material).
    fn stress_state_vjp(
        &self,
        _f: &Mat3,
        _e0: &Vec3,
        _h: PointHistory,
        _w: &Mat3,
    ) -> Result<Vec<f64>, MaterialError> {
        no_state_derivatives(self.state_size())?;
        Ok(Vec::new())
    }
    /// The vector–Jacobian products of [`Material::update_state`] for `w` over the new internal
    /// variables: in θ, in the committed variables, in F and in E0 (all zero for an elastic
    /// material).
    fn update_state_vjp(
        &self,
        _f: &Mat3,
        _e0: &Vec3,
        _h: PointHistory,
        _w: &[f64],
    ) -> Result<StateVjp, MaterialError> {
        no_state_derivatives(self.state_size())?;
        Ok(StateVjp {
            theta: vec![0.0; self.parameters().map_or(0, |p| p.values.len())],
            state: Vec::new(),
            f: Mat3::zeros(),
            e0: Vec3::zeros(),
        })
    }
}

/// The error of a parameter `index` asked of a material with `n` parameters.
pub(crate) fn no_parameter(index: usize, n: usize) -> MaterialError {
    MaterialError::OutOfDomain(format!(
        "parameter {index} of a material with {n} parameters"
    ))
}

/// The defaults of the derivatives in the internal variables hold for an elastic material only.
fn no_state_derivatives(state_size: usize) -> Result<(), MaterialError> {
    if state_size == 0 {
        Ok(())
    } else {
        Err(MaterialError::OutOfDomain(
            "this material gives no derivatives in its internal variables".into(),
        ))
    }
}

/// Cauchy stress σ = P Fᵀ / J from the first Piola stress.
///
/// No check on J is made here; callers obtain `p` from a successful material
/// evaluation, which already guarantees J > 0.
pub fn cauchy_stress(p: &Mat3, f: &Mat3) -> Mat3 {
    let j = f.determinant();
    p * f.transpose() / j
}

/// Spatial electric field e = F⁻ᵀ E0, or `None` if F is singular.
pub fn spatial_field(f: &Mat3, e0: &Vec3) -> Option<Vec3> {
    f.try_inverse().map(|fi| fi.transpose() * e0)
}
