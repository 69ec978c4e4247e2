//! Generic electro-elastic material: a mechanical energy W(C) plus the
//! linear dielectric part,
//!
//! ```text
//! Ω(C, E0) = W(C) + c₁ E0·E0 + c₂ E0·(C E0) − ε/2 J E0·(C⁻¹E0).
//! ```
//!
//! [`Material::energy_split`] returns `(W, −Ω_e)` with Ω_e the E0-dependent
//! terms, so that Ψ = mechanical − electric.

use super::electric::ElectricPart;
use super::hyperelastic::{HFirst, Hyperelastic};
use super::isotropic::{self, CDerivs, CFirst, CKinematics, CMaterial};
use super::parameters::{self, Parameters};
use super::{
    ElectricTangent, KnownDeformation, KnownLanes, Mat3, Material, MaterialError, PointHistory,
    PointRecord, Stress, StressLanes, Tangent, Vec3,
};
use crate::algebra::lanes::{with_wide_vectors, Wide, F4};
use nalgebra::Vector3;

/// Mechanical model `H` combined with a linear dielectric.
#[derive(Debug, Clone, PartialEq)]
pub struct Electroelastic<H> {
    /// Mechanical part W(C).
    pub mech: H,
    /// Dielectric part.
    pub elec: ElectricPart,
}

impl<H: Hyperelastic> Electroelastic<H> {
    /// Combine a mechanical model with a dielectric part.
    pub fn new(mech: H, elec: ElectricPart) -> Self {
        Self { mech, elec }
    }

    /// Mechanical model with an ideal dielectric of relative permittivity εᵣ.
    pub fn ideal(mech: H, eps_r: f64) -> Self {
        Self::new(mech, ElectricPart::ideal(eps_r))
    }
}

impl<H: Hyperelastic> Electroelastic<H> {
    /// W and the mechanical first Piola stress at a known deformation: the model's own F-form
    /// when it has one, else F S from C and C⁻¹.
    #[inline(always)]
    fn mech_piola(&self, k: &KnownDeformation) -> Result<(f64, Mat3), MaterialError> {
        match self.mech.first_piola(k) {
            Some(r) => r,
            None => {
                let m = self.mech.s(&CKinematics::from_known(k))?;
                Ok((m.w, k.f * m.s))
            }
        }
    }
}

/// The stresses of a lane of points, compiled for wide vectors.
struct LaneStress<'a, H> {
    material: &'a Electroelastic<H>,
    k: &'a KnownLanes,
    e0: &'a Vector3<F4>,
}

impl<H: Hyperelastic> Wide for LaneStress<'_, H> {
    type Output = Option<StressLanes>;
    #[inline(always)]
    fn run(self) -> Option<StressLanes> {
        let (w, p) = self.material.mech.first_piola_lanes(self.k)?;
        let (we, pe, d0) = self.material.elec.first_known(self.k, self.e0);
        Some(StressLanes {
            energy: w + we,
            p: p + pe,
            d0,
        })
    }
}

impl<H: Hyperelastic> CMaterial for Electroelastic<H> {
    #[inline]
    fn c_energy(&self, k: &CKinematics, e0: &Vec3) -> Result<f64, MaterialError> {
        Ok(self.mech.w(k)? + self.elec.energy(k, e0))
    }

    #[inline(always)]
    fn c_first(&self, k: &CKinematics, e0: &Vec3) -> Result<CFirst, MaterialError> {
        let m = self.mech.s(k)?;
        let (se, d0) = self.elec.first(k, e0);
        Ok(CFirst {
            energy: m.w + self.elec.energy(k, e0),
            s: m.s + se,
            d0,
        })
    }

    fn c_second(&self, k: &CKinematics, e0: &Vec3) -> Result<CDerivs, MaterialError> {
        let m = self.mech.ll(k)?;
        let (s_e, d0) = self.elec.first(k, e0);
        let mut ll = m.ll;
        let (se, dd) = self.elec.second_into(k, e0, &mut ll);
        Ok(CDerivs {
            energy: m.w + self.elec.energy(k, e0),
            s: m.s + s_e,
            d0,
            ll,
            se,
            dd,
        })
    }
}

impl<H: Hyperelastic> Material for Electroelastic<H> {
    fn energy(&self, f: &Mat3, e0: &Vec3) -> Result<f64, MaterialError> {
        isotropic::energy_from_c(self, f, e0)
    }

    fn stress(&self, f: &Mat3, e0: &Vec3) -> Result<Stress, MaterialError> {
        isotropic::stress_from_c(self, f, e0)
    }

    /// The model's first Piola form where it has one (no 𝕃 and no conversion of it), else the
    /// conversion of the C-form derivatives; a J ≤ 0 takes the conversion's error.
    fn tangent(&self, f: &Mat3, e0: &Vec3) -> Result<Tangent, MaterialError> {
        isotropic::check_field(e0)?;
        let mech =
            KnownDeformation::new(f).and_then(|k| Some((self.mech.first_piola_tangent(&k)?, k)));
        let Some((mech, k)) = mech else {
            return isotropic::tangent_from_c(self, f, e0);
        };
        let (w, p, mut a) = mech?;
        let (we, pe, et) = self.elec.tangent_known(&k, e0, &mut a);
        Ok(Tangent {
            energy: w + we,
            p: p + pe,
            d0: et.d0,
            a,
            b: et.b,
            g: et.g,
        })
    }

    fn shear_modulus(&self) -> f64 {
        self.mech.shear_modulus()
    }

    fn locking(&self, f: &Mat3) -> Option<(f64, &'static str)> {
        self.mech.locking(&isotropic::CKinematics::from_f(f).ok()?)
    }

    fn bulk_modulus(&self) -> f64 {
        self.mech.bulk_modulus()
    }

    fn permittivity(&self) -> f64 {
        self.elec.small_strain_permittivity()
    }

    fn electric_tangent_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        _h: PointHistory,
    ) -> Result<ElectricTangent, MaterialError> {
        // the mechanical part enters neither D0 nor the derivatives in E0; the checks and
        // errors of `tangent`
        isotropic::check_field(e0)?;
        let j = f.determinant();
        match f.try_inverse() {
            Some(f_inv) if j.is_finite() && j > 0.0 => {
                Ok(self
                    .elec
                    .electric_tangent_known(f, &f_inv.transpose(), j, e0))
            }
            _ => Err(MaterialError::NonPositiveJ(j)),
        }
    }

    fn electric_displacement_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        _h: PointHistory,
    ) -> Result<Vec3, MaterialError> {
        // the checks of `stress`; the mechanical part does not enter D0
        let k = isotropic::checked_kinematics(f, e0)?;
        Ok(self.elec.d0(&k, e0))
    }

    fn stress_known(
        &self,
        k: &KnownDeformation,
        e0: &Vec3,
        _h: PointHistory,
    ) -> Result<Stress, MaterialError> {
        isotropic::check_field(e0)?;
        let (w, p) = self.mech_piola(k)?;
        let (we, pe, d0) = self.elec.first_known(k, e0);
        Ok(Stress {
            energy: w + we,
            p: p + pe,
            d0,
        })
    }

    fn stress_known_lanes(
        &self,
        k: &KnownLanes,
        e0: &Vector3<F4>,
        _h: PointHistory,
    ) -> Option<StressLanes> {
        if !e0.iter().all(|x| x.all(f64::is_finite)) {
            return None;
        }
        with_wide_vectors(LaneStress {
            material: self,
            k,
            e0,
        })
    }

    fn electric_displacement_known(
        &self,
        k: &KnownDeformation,
        e0: &Vec3,
        _h: PointHistory,
    ) -> Result<Vec3, MaterialError> {
        isotropic::check_field(e0)?;
        Ok(self.elec.d0_known(k, e0))
    }

    /// One evaluation for the three parts: the zero-field stress is the mechanical one.
    fn record_known(
        &self,
        k: &KnownDeformation,
        e0: &Vec3,
        _h: PointHistory,
    ) -> Result<PointRecord, MaterialError> {
        isotropic::check_field(e0)?;
        let (w, p) = self.mech_piola(k)?;
        let (we, pe, d0) = self.elec.first_known(k, e0);
        Ok(PointRecord {
            stress: Stress {
                energy: w + we,
                p: p + pe,
                d0,
            },
            split: (w, -we),
            p_mech: p,
        })
    }

    /// The mechanical model's entries, then `permittivity`, `c1`, `c2`.
    fn parameters(&self) -> Option<Parameters> {
        let mut p = self.mech.parameters()?;
        parameters::push_electric(&mut p, &self.elec);
        Some(p)
    }

    fn parameter_derivatives_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        _h: PointHistory,
    ) -> Result<Vec<Stress>, MaterialError> {
        let k = isotropic::checked_kinematics(f, e0)?;
        let mut out: Vec<Stress> = self
            .mech
            .parameter_derivatives(&k)?
            .into_iter()
            .map(|d| mechanical(f, d))
            .collect();
        out.extend(parameters::electric(f, &k, e0));
        Ok(out)
    }

    /// The mechanical model's entries come first and leave D0 alone (it is the dielectric's).
    fn parameter_enters_d0(&self, index: usize) -> bool {
        self.mech
            .parameters()
            .is_none_or(|p| index >= p.values.len())
    }

    /// The mechanical entries from the model's derivatives, a dielectric one alone.
    fn parameter_derivative_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        _h: PointHistory,
        index: usize,
    ) -> Result<Stress, MaterialError> {
        let k = isotropic::checked_kinematics(f, e0)?;
        let mut mech = self.mech.parameter_derivatives(&k)?;
        let n = mech.len();
        if index < n {
            return Ok(mechanical(f, mech.swap_remove(index)));
        }
        if index - n < parameters::ELECTRIC {
            return Ok(parameters::electric_entry(f, &k, e0, index - n));
        }
        Err(crate::material::no_parameter(
            index,
            n + parameters::ELECTRIC,
        ))
    }

    fn energy_split(&self, f: &Mat3, e0: &Vec3) -> Result<(f64, f64), MaterialError> {
        // Validate exactly like the energy evaluation does.
        // the checks of `energy` (finite field, J > 0); its value would be the sum of the parts
        let k = isotropic::checked_kinematics(f, e0)?;
        Ok((self.mech.w(&k)?, -self.elec.energy(&k, e0)))
    }
}

/// The derivative `(∂Ψ, ∂P, ∂D0)` of a mechanical parameter from ∂W/∂θ and ∂S/∂θ: P = F S and
/// D0 does not depend on it.
fn mechanical(f: &Mat3, d: HFirst) -> Stress {
    Stress {
        energy: d.w,
        p: f * d.s,
        d0: Vec3::zeros(),
    }
}

#[cfg(test)]
mod tests {
    use super::super::arruda_boyce::{ArrudaBoyce, ArrudaBoyceSeries};
    use super::super::fd_tests::Rng;
    use super::super::gent::Gent;
    use super::super::neo_hooke_split::NeoHookeSplit;
    use super::super::yeoh::Yeoh;
    use super::*;

    /// The first Piola form of the tangent against the conversion of 𝕃 it replaces, for every
    /// model that has one, with an ideal and an electrostrictive dielectric: the same A, B and
    /// G to round-off (a far tighter check than the finite differences of every model).
    #[test]
    fn first_piola_tangent_is_the_converted_one() {
        fn check<H: Hyperelastic + Clone>(name: &str, mech: H, rng: &mut Rng) {
            let elec = [
                ElectricPart::ideal(4.7),
                ElectricPart::ideal(3.0).with_coupling(2e-12, -5e-12),
            ];
            for elec in elec {
                let m = Electroelastic::new(mech.clone(), elec);
                for _ in 0..20 {
                    let f = rng.deformation();
                    let e0 = rng.field(&m);
                    let fast = m.tangent(&f, &e0).unwrap();
                    let conv = isotropic::tangent_from_c(&m, &f, &e0).unwrap();
                    let rel = |x: f64, y: f64| x / y.max(f64::MIN_POSITIVE);
                    let ea = rel((fast.a - conv.a).amax(), conv.a.amax());
                    let eb = rel((fast.b - conv.b).amax(), conv.b.amax());
                    let eg = rel((fast.g - conv.g).amax(), conv.g.amax());
                    assert!(
                        ea < 1e-12 && eb < 1e-12 && eg < 1e-12,
                        "{name}: A {ea:e}, B {eb:e}, G {eg:e}"
                    );
                }
            }
        }
        let mut rng = Rng::new(0x7a9e_0fa1_0001);
        check(
            "yeoh",
            Yeoh::new(1.5e5, -2e3, 80.0, 1e-8, 1e-9, 0.0),
            &mut rng,
        );
        check(
            "neo-hooke split",
            NeoHookeSplit {
                mu: 1e5,
                kappa: 4e6,
            },
            &mut rng,
        );
        check(
            "gent",
            Gent {
                mu: 1e5,
                jm: 90.0,
                kappa: 4e6,
            },
            &mut rng,
        );
        let ab = ArrudaBoyce {
            mu: 1e5,
            lambda_m: 5.0,
            kappa: 4e6,
        };
        check("arruda-boyce", ab, &mut rng);
        check(
            "arruda-boyce series",
            ArrudaBoyceSeries {
                mu: 1e5,
                lambda_m: 5.0,
                kappa: 4e6,
            },
            &mut rng,
        );
    }
}
