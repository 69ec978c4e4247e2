//! Finite viscoelasticity: neo-Hookean Maxwell branches on the isochoric deformation in parallel
//! with any elastic material,
//!
//! ```text
//! Ψ = Ψ_eq(F, E₀) + Σᵢ (gᵢ/2)(tr(C̄ Aᵢ) − 3),   C̄ = J^(−2/3) C,   Ȧᵢ = (C̄⁻¹ − Aᵢ)/τᵢ,
//! ```
//!
//! with A the inverse viscous right Cauchy–Green tensor (the evolution law of Linder, Tkachuk &
//! Miehe, JMPS 59 (2011) 2134–2156). Backward Euler gives A_{n+1} = (A_n + k C̄⁻¹_{n+1})/(1 + k),
//! k = Δt/τ, and since tr(C̄ C̄⁻¹) = 3 the branch stress of the step is the derivative of the
//! incremental energy W_n(F) = g/(2(1 + k)) (tr(C̄ A_n) − 3): a hyperelastic-like energy with the
//! committed A_n as a structure tensor, whose tangent is symmetric and exact. Under a held
//! deformation A relaxes to C̄⁻¹ with the factor (1 + k)⁻ⁿ after n steps (e^(−t/τ) as Δt → 0),
//! which is the closed form the tests check. The dissipation of a step is
//! −∂Ψ/∂A : ΔA = (g k/2)(tr(C̄ A_{n+1}) − 3) per reference volume.
//!
//! Each branch keeps its Aᵢ (9 values, row-major) per quadrature point; branches add.

use super::{
    Mat3, Mat9, Material, MaterialError, Parameters, PointHistory, StateVjp, Stress, Tangent, Vec3,
};

/// An elastic material with one Maxwell branch (shear modulus `g` in Pa, relaxation time `tau`
/// in s).
#[derive(Debug, Clone)]
pub struct MaxwellBranch<M> {
    pub equilibrium: M,
    pub g: f64,
    pub tau: f64,
}

/// An elastic material (`dyn`) with any number of Maxwell branches `(g, τ)` (Pa, s).
#[derive(Debug, Clone)]
pub struct Viscoelastic {
    pub equilibrium: std::sync::Arc<dyn Material>,
    pub branches: Vec<(f64, f64)>,
}

impl Viscoelastic {
    fn branch(&self, i: usize) -> MaxwellBranch<&dyn Material> {
        MaxwellBranch {
            equilibrium: self.equilibrium.as_ref(),
            g: self.branches[i].0,
            tau: self.branches[i].1,
        }
    }

    fn state_of<'a>(h: &PointHistory<'a>, i: usize) -> PointHistory<'a> {
        PointHistory {
            state: if h.state.len() >= 9 * (i + 1) {
                &h.state[9 * i..9 * (i + 1)]
            } else {
                &[]
            },
            dt: h.dt,
        }
    }

    /// The branches' incremental energy, stress and (when asked) tangent, summed.
    fn branches_sum(
        &self,
        f: &Mat3,
        h: &PointHistory,
        want_tangent: bool,
    ) -> Result<(f64, Mat3, Mat9), MaterialError> {
        let (mut w, mut p, mut a) = (0.0, Mat3::zeros(), Mat9::zeros());
        // J^(−2/3) and F⁻ᵀ once for all branches (each branch would compute the same values)
        let kin = BranchKinematics::new(f)?;
        for i in 0..self.branches.len() {
            let b = self.branch(i);
            let hi = Self::state_of(h, i);
            let committed = MaxwellBranch::<&dyn Material>::committed(&hi);
            let (wi, pi, ai) = b.branch_at(f, &kin, &committed, b.k(&hi), want_tangent)?;
            w += wi;
            p += pi;
            if let Some(ai) = ai {
                a += ai;
            }
        }
        Ok((w, p, a))
    }

    /// Instantaneous shear modulus G_eq + Σ gᵢ (Pa) and the relaxed one G_eq.
    pub fn moduli(&self) -> (f64, f64) {
        let eq = self.equilibrium.shear_modulus();
        (eq + self.branches.iter().map(|b| b.0).sum::<f64>(), eq)
    }
}

impl Material for Viscoelastic {
    fn energy(&self, f: &Mat3, e0: &Vec3) -> Result<f64, MaterialError> {
        self.energy_at(f, e0, PointHistory::NONE)
    }

    fn stress(&self, f: &Mat3, e0: &Vec3) -> Result<Stress, MaterialError> {
        self.stress_at(f, e0, PointHistory::NONE)
    }

    fn tangent(&self, f: &Mat3, e0: &Vec3) -> Result<Tangent, MaterialError> {
        self.tangent_at(f, e0, PointHistory::NONE)
    }

    fn locking(&self, f: &Mat3) -> Option<(f64, &'static str)> {
        self.equilibrium.locking(f)
    }

    /// The instantaneous modulus (equilibrium and branches).
    fn shear_modulus(&self) -> f64 {
        self.moduli().0
    }

    fn bulk_modulus(&self) -> f64 {
        self.equilibrium.bulk_modulus()
    }

    fn permittivity(&self) -> f64 {
        self.equilibrium.permittivity()
    }

    fn energy_split(&self, f: &Mat3, e0: &Vec3) -> Result<(f64, f64), MaterialError> {
        self.energy_split_at(f, e0, &[])
    }

    fn state_size(&self) -> usize {
        9 * self.branches.len()
    }

    fn relaxed(&self) -> Option<std::sync::Arc<dyn Material>> {
        Some(self.equilibrium.clone())
    }

    fn maxwell_branches(&self) -> Vec<(f64, f64)> {
        self.branches.clone()
    }

    fn initial_state(&self, state: &mut [f64]) {
        for c in state.chunks_mut(9) {
            c.copy_from_slice(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        }
    }

    fn state_names(&self) -> Vec<String> {
        let comps = ["xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz"];
        (1..=self.branches.len())
            .flat_map(|i| comps.iter().map(move |c| format!("A{i}_{c}")))
            .collect()
    }

    fn energy_at(&self, f: &Mat3, e0: &Vec3, h: PointHistory) -> Result<f64, MaterialError> {
        let (w, _, _) = self.branches_sum(f, &h, false)?;
        Ok(self.equilibrium.energy(f, e0)? + w)
    }

    fn stress_at(&self, f: &Mat3, e0: &Vec3, h: PointHistory) -> Result<Stress, MaterialError> {
        let mut s = self.equilibrium.stress(f, e0)?;
        let (w, p, _) = self.branches_sum(f, &h, false)?;
        s.energy += w;
        s.p += p;
        Ok(s)
    }

    fn tangent_at(&self, f: &Mat3, e0: &Vec3, h: PointHistory) -> Result<Tangent, MaterialError> {
        let mut t = self.equilibrium.tangent(f, e0)?;
        let (w, p, a) = self.branches_sum(f, &h, true)?;
        t.energy += w;
        t.p += p;
        t.a += a;
        Ok(t)
    }

    fn energy_split_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        state: &[f64],
    ) -> Result<(f64, f64), MaterialError> {
        let (mut mech, elec) = self.equilibrium.energy_split(f, e0)?;
        let h = PointHistory { state, dt: 0.0 };
        let kin = BranchKinematics::new(f)?;
        for i in 0..self.branches.len() {
            let b = self.branch(i);
            let hi = Self::state_of(&h, i);
            mech += b
                .branch_at(
                    f,
                    &kin,
                    &MaxwellBranch::<&dyn Material>::committed(&hi),
                    0.0,
                    false,
                )?
                .0;
        }
        Ok((mech, elec))
    }

    fn update_state(
        &self,
        f: &Mat3,
        _e0: &Vec3,
        h: PointHistory,
        new: &mut [f64],
    ) -> Result<f64, MaterialError> {
        let mut d = 0.0;
        for i in 0..self.branches.len() {
            d += self
                .branch(i)
                .update(f, &Self::state_of(&h, i), &mut new[9 * i..9 * (i + 1)])?;
        }
        Ok(d)
    }

    /// The equilibrium material's entries, then `branches.<i>.mu` and `branches.<i>.tau`.
    fn parameters(&self) -> Option<Parameters> {
        let mut p = self.equilibrium.parameters()?;
        for (i, &(g, tau)) in self.branches.iter().enumerate() {
            p.push(format!("branches.{i}.mu"), g);
            p.push(format!("branches.{i}.tau"), tau);
        }
        Some(p)
    }

    /// The equilibrium material's derivatives; a branch's incremental energy
    /// g/(2(1 + k))(tr(C̄ A_n) − 3), k = Δt/τ, is linear in g and has the derivative
    /// k/(τ(1 + k)) times itself in τ (and so has its stress).
    fn parameter_derivatives_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        h: PointHistory,
    ) -> Result<Vec<Stress>, MaterialError> {
        let mut out = self
            .equilibrium
            .parameter_derivatives_at(f, e0, PointHistory::NONE)?;
        let kin = BranchKinematics::new(f)?;
        for i in 0..self.branches.len() {
            let b = self.branch(i);
            let hi = Self::state_of(&h, i);
            let k = b.k(&hi);
            let committed = MaxwellBranch::<&dyn Material>::committed(&hi);
            let (w, p, _) = b.branch_at(f, &kin, &committed, k, false)?;
            for scale in [1.0 / b.g, k / (b.tau * (1.0 + k))] {
                out.push(Stress {
                    energy: w * scale,
                    p: p * scale,
                    d0: Vec3::zeros(),
                });
            }
        }
        Ok(out)
    }

    /// An equilibrium entry from the equilibrium material; a branch's from that branch alone.
    fn parameter_derivative_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        h: PointHistory,
        index: usize,
    ) -> Result<Stress, MaterialError> {
        let mut out = self
            .equilibrium
            .parameter_derivatives_at(f, e0, PointHistory::NONE)?;
        let n = out.len();
        if index < n {
            return Ok(out.swap_remove(index));
        }
        let (i, which) = ((index - n) / 2, (index - n) % 2);
        if i >= self.branches.len() {
            return Err(crate::material::no_parameter(
                index,
                n + 2 * self.branches.len(),
            ));
        }
        let kin = BranchKinematics::new(f)?;
        let b = self.branch(i);
        let hi = Self::state_of(&h, i);
        let k = b.k(&hi);
        let committed = MaxwellBranch::<&dyn Material>::committed(&hi);
        let (w, p, _) = b.branch_at(f, &kin, &committed, k, false)?;
        let scale = [1.0 / b.g, k / (b.tau * (1.0 + k))][which];
        Ok(Stress {
            energy: w * scale,
            p: p * scale,
            d0: Vec3::zeros(),
        })
    }

    fn stress_state_vjp(
        &self,
        f: &Mat3,
        _e0: &Vec3,
        h: PointHistory,
        w: &Mat3,
    ) -> Result<Vec<f64>, MaterialError> {
        let kin = BranchKinematics::new(f)?;
        let mut out = Vec::with_capacity(self.state_size());
        for i in 0..self.branches.len() {
            let b = self.branch(i);
            let g = b.stress_state_vjp(f, &kin, b.k(&Self::state_of(&h, i)), w);
            out.extend(g.transpose().iter());
        }
        Ok(out)
    }

    fn update_state_vjp(
        &self,
        f: &Mat3,
        _e0: &Vec3,
        h: PointHistory,
        w: &[f64],
    ) -> Result<StateVjp, MaterialError> {
        let n_eq = self.equilibrium.parameters().map_or(0, |p| p.values.len());
        let mut out = StateVjp {
            theta: vec![0.0; n_eq],
            state: Vec::with_capacity(self.state_size()),
            f: Mat3::zeros(),
            e0: Vec3::zeros(),
        };
        for i in 0..self.branches.len() {
            let (tau, state, f_bar) =
                self.branch(i)
                    .update_vjp(f, &Self::state_of(&h, i), &w[9 * i..9 * (i + 1)])?;
            out.theta.extend([0.0, tau]);
            out.state.extend(state.transpose().iter());
            out.f += f_bar;
        }
        Ok(out)
    }
}

/// What every branch's stress at F uses: J^(−2/3) and F⁻ᵀ.
struct BranchKinematics {
    alpha: f64,
    fit: Mat3,
}

impl BranchKinematics {
    fn new(f: &Mat3) -> Result<Self, MaterialError> {
        let j = f.determinant();
        if !(j > 0.0 && j.is_finite()) {
            return Err(MaterialError::NonPositiveJ(j));
        }
        Ok(Self {
            alpha: j.powf(-2.0 / 3.0),
            fit: f
                .try_inverse()
                .ok_or(MaterialError::NonPositiveJ(j))?
                .transpose(),
        })
    }
}

/// A from the 9 stored values (row-major).
fn tensor(s: &[f64]) -> Mat3 {
    Mat3::from_row_slice(s)
}

impl<M> MaxwellBranch<M> {
    /// The branch's internal variables after an accepted step to F (into `new`) and the energy
    /// dissipated per reference volume.
    fn update(&self, f: &Mat3, h: &PointHistory, new: &mut [f64]) -> Result<f64, MaterialError> {
        let j = f.determinant();
        if !(j > 0.0 && j.is_finite()) {
            return Err(MaterialError::NonPositiveJ(j));
        }
        let cbar = f.transpose() * f * j.powf(-2.0 / 3.0);
        let cbar_inv = cbar.try_inverse().ok_or(MaterialError::NonPositiveJ(j))?;
        let k = self.k(h);
        let a = (Self::committed(h) + cbar_inv * k) / (1.0 + k);
        // row-major, as `tensor` reads it
        for r in 0..3 {
            for c in 0..3 {
                new[r * 3 + c] = a[(r, c)];
            }
        }
        Ok(0.5 * self.g * k * ((cbar * a).trace() - 3.0))
    }

    /// The branch's incremental energy density, stress and (when asked) tangent at F for a step
    /// of factor k from the committed A.
    fn branch(
        &self,
        f: &Mat3,
        a: &Mat3,
        k: f64,
        want_tangent: bool,
    ) -> Result<(f64, Mat3, Option<Mat9>), MaterialError> {
        self.branch_at(f, &BranchKinematics::new(f)?, a, k, want_tangent)
    }

    /// [`MaxwellBranch::branch`] with the kinematics of F computed beforehand.
    fn branch_at(
        &self,
        f: &Mat3,
        kin: &BranchKinematics,
        a: &Mat3,
        k: f64,
        want_tangent: bool,
    ) -> Result<(f64, Mat3, Option<Mat9>), MaterialError> {
        let (alpha, fit) = (kin.alpha, &kin.fit);
        let c = self.g / (2.0 * (1.0 + k));
        let fa = f * a;
        let ia = (f.transpose() * fa).trace();
        let w = c * (alpha * ia - 3.0);
        let p = (fa * 2.0 - fit * (2.0 / 3.0 * ia)) * (c * alpha);
        let t = want_tangent.then(|| {
            let mut t = Mat9::zeros();
            for i in 0..3 {
                for jj in 0..3 {
                    for kk in 0..3 {
                        for l in 0..3 {
                            let mut v = -4.0 / 3.0 * fit[(kk, l)] * fa[(i, jj)]
                                + 4.0 / 9.0 * ia * fit[(kk, l)] * fit[(i, jj)]
                                - 4.0 / 3.0 * fa[(kk, l)] * fit[(i, jj)]
                                + 2.0 / 3.0 * ia * fit[(i, l)] * fit[(kk, jj)];
                            if i == kk {
                                v += 2.0 * a[(l, jj)];
                            }
                            t[(i * 3 + jj, kk * 3 + l)] = c * alpha * v;
                        }
                    }
                }
            }
            t
        });
        Ok((w, p, t))
    }

    /// wᵀ ∂P/∂A of the branch stress P = cα(2FA − ⅔ tr(CA) F⁻ᵀ), c = g/(2(1 + k)),
    /// α = J^(−2/3): cα(2Fᵀw − ⅔ (w:F⁻ᵀ) C), entry (m, n) for A_mn.
    fn stress_state_vjp(&self, f: &Mat3, kin: &BranchKinematics, k: f64, w: &Mat3) -> Mat3 {
        let c = self.g / (2.0 * (1.0 + k));
        (f.tr_mul(w) * 2.0 - f.tr_mul(f) * (2.0 / 3.0 * w.dot(&kin.fit))) * (c * kin.alpha)
    }

    /// The vector–Jacobian products of the update A = (A_n + k C̄⁻¹)/(1 + k), k = Δt/τ, for `w`
    /// over A (row-major): in τ (∂A/∂τ = −(k/τ)(C̄⁻¹ − A_n)/(1 + k)²), in A_n (w/(1 + k)) and
    /// in F (k/(1 + k) w:∂C̄⁻¹/∂F with C̄⁻¹ = J^(2/3) C⁻¹:
    /// J^(2/3)(⅔ (w:C⁻¹) F⁻ᵀ − F⁻ᵀ(w + wᵀ)C⁻¹)).
    fn update_vjp(
        &self,
        f: &Mat3,
        h: &PointHistory,
        w: &[f64],
    ) -> Result<(f64, Mat3, Mat3), MaterialError> {
        let kin = BranchKinematics::new(f)?;
        let w = tensor(w);
        let j23 = 1.0 / kin.alpha;
        let c_inv = kin.fit.transpose() * kin.fit;
        let cbar_inv = c_inv * j23;
        let k = self.k(h);
        let d_tau =
            -(k / self.tau) / ((1.0 + k) * (1.0 + k)) * w.dot(&(cbar_inv - Self::committed(h)));
        let d_f = (kin.fit * (2.0 / 3.0 * w.dot(&c_inv)) - kin.fit * (w + w.transpose()) * c_inv)
            * (j23 * k / (1.0 + k));
        Ok((d_tau, w / (1.0 + k), d_f))
    }

    fn committed(h: &PointHistory) -> Mat3 {
        if h.state.len() == 9 {
            tensor(h.state)
        } else {
            Mat3::identity()
        }
    }

    fn k(&self, h: &PointHistory) -> f64 {
        h.dt / self.tau
    }
}

impl<M: Material> Material for MaxwellBranch<M> {
    fn energy(&self, f: &Mat3, e0: &Vec3) -> Result<f64, MaterialError> {
        self.energy_at(f, e0, PointHistory::NONE)
    }

    fn stress(&self, f: &Mat3, e0: &Vec3) -> Result<Stress, MaterialError> {
        self.stress_at(f, e0, PointHistory::NONE)
    }

    fn tangent(&self, f: &Mat3, e0: &Vec3) -> Result<Tangent, MaterialError> {
        self.tangent_at(f, e0, PointHistory::NONE)
    }

    fn locking(&self, f: &Mat3) -> Option<(f64, &'static str)> {
        self.equilibrium.locking(f)
    }

    /// The instantaneous modulus: equilibrium and branch.
    fn shear_modulus(&self) -> f64 {
        self.equilibrium.shear_modulus() + self.g
    }

    fn bulk_modulus(&self) -> f64 {
        self.equilibrium.bulk_modulus()
    }

    fn permittivity(&self) -> f64 {
        self.equilibrium.permittivity()
    }

    fn energy_split(&self, f: &Mat3, e0: &Vec3) -> Result<(f64, f64), MaterialError> {
        self.energy_split_at(f, e0, &[])
    }

    fn state_size(&self) -> usize {
        9
    }

    fn initial_state(&self, state: &mut [f64]) {
        state.copy_from_slice(Mat3::identity().transpose().as_slice());
    }

    fn state_names(&self) -> Vec<String> {
        ["xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz"]
            .iter()
            .map(|c| format!("A_{c}"))
            .collect()
    }

    fn energy_at(&self, f: &Mat3, e0: &Vec3, h: PointHistory) -> Result<f64, MaterialError> {
        let (w, _, _) = self.branch(f, &Self::committed(&h), self.k(&h), false)?;
        Ok(self.equilibrium.energy(f, e0)? + w)
    }

    fn stress_at(&self, f: &Mat3, e0: &Vec3, h: PointHistory) -> Result<Stress, MaterialError> {
        let (w, p, _) = self.branch(f, &Self::committed(&h), self.k(&h), false)?;
        let mut s = self.equilibrium.stress(f, e0)?;
        s.energy += w;
        s.p += p;
        Ok(s)
    }

    fn tangent_at(&self, f: &Mat3, e0: &Vec3, h: PointHistory) -> Result<Tangent, MaterialError> {
        let (w, p, a) = self.branch(f, &Self::committed(&h), self.k(&h), true)?;
        let mut t = self.equilibrium.tangent(f, e0)?;
        t.energy += w;
        t.p += p;
        t.a += a.expect("asked for");
        Ok(t)
    }

    fn energy_split_at(
        &self,
        f: &Mat3,
        e0: &Vec3,
        state: &[f64],
    ) -> Result<(f64, f64), MaterialError> {
        let (mech, elec) = self.equilibrium.energy_split(f, e0)?;
        let h = PointHistory { state, dt: 0.0 };
        let (w, _, _) = self.branch(f, &Self::committed(&h), 0.0, false)?;
        Ok((mech + w, elec))
    }

    fn update_state(
        &self,
        f: &Mat3,
        _e0: &Vec3,
        h: PointHistory,
        new: &mut [f64],
    ) -> Result<f64, MaterialError> {
        self.update(f, &h, new)
    }

    fn stress_state_vjp(
        &self,
        f: &Mat3,
        _e0: &Vec3,
        h: PointHistory,
        w: &Mat3,
    ) -> Result<Vec<f64>, MaterialError> {
        let g = MaxwellBranch::stress_state_vjp(self, f, &BranchKinematics::new(f)?, self.k(&h), w);
        Ok(g.transpose().iter().copied().collect())
    }

    /// θ is empty: a single branch on any material is not built by the registry.
    fn update_state_vjp(
        &self,
        f: &Mat3,
        _e0: &Vec3,
        h: PointHistory,
        w: &[f64],
    ) -> Result<StateVjp, MaterialError> {
        let (_, state, f_bar) = self.update_vjp(f, &h, w)?;
        Ok(StateVjp {
            theta: Vec::new(),
            state: state.transpose().iter().copied().collect(),
            f: f_bar,
            e0: Vec3::zeros(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::ElectroNeoHooke;

    fn material() -> MaxwellBranch<ElectroNeoHooke> {
        MaxwellBranch {
            equilibrium: ElectroNeoHooke::new(1e5, 1e7, 4.7),
            g: 3e5,
            tau: 0.5,
        }
    }

    /// P = ∂W/∂F and ∂P/∂F of the step's incremental energy against central differences, from
    /// a committed state that is not the identity: one branch, and two branches on a `dyn`
    /// equilibrium material.
    #[test]
    fn step_stress_and_tangent_match_finite_differences() {
        check_derivatives(&material());
        check_derivatives(&Viscoelastic {
            equilibrium: std::sync::Arc::new(ElectroNeoHooke::new(1e5, 1e7, 4.7)),
            branches: vec![(3e5, 0.5), (1e5, 20.0)],
        });
    }

    fn check_derivatives(m: &dyn Material) {
        let f = Mat3::new(1.2, 0.1, -0.05, 0.02, 0.9, 0.1, 0.03, -0.04, 1.05);
        let e0 = Vec3::new(1e5, -2e5, 3e6);
        let mut a0 = vec![0.0; m.state_size()];
        m.initial_state(&mut a0);
        let mut a = vec![0.0; m.state_size()];
        m.update_state(
            &Mat3::new(1.1, 0.05, 0.0, 0.0, 0.95, 0.02, 0.01, 0.0, 0.97),
            &e0,
            PointHistory {
                state: &a0,
                dt: 0.3,
            },
            &mut a,
        )
        .unwrap();
        let h = PointHistory { state: &a, dt: 0.2 };
        let t = m.tangent_at(&f, &e0, h).unwrap();
        let s = m.stress_at(&f, &e0, h).unwrap();
        assert_eq!(s.p, t.p);
        let eps = 1e-6;
        for r in 0..9 {
            let (i, jj) = (r / 3, r % 3);
            let (mut fp, mut fm) = (f, f);
            fp[(i, jj)] += eps;
            fm[(i, jj)] -= eps;
            let dw = (m.energy_at(&fp, &e0, h).unwrap() - m.energy_at(&fm, &e0, h).unwrap())
                / (2.0 * eps);
            assert!((dw - t.p[(i, jj)]).abs() < 1e-6 * t.p.norm(), "P {r}");
            let dp = (m.stress_at(&fp, &e0, h).unwrap().p - m.stress_at(&fm, &e0, h).unwrap().p)
                / (2.0 * eps);
            for c in 0..9 {
                let (k, l) = (c / 3, c % 3);
                assert!(
                    (dp[(k, l)] - t.a[(c, r)]).abs() < 1e-6 * t.a.norm(),
                    "A ({c}, {r}): {} vs {}",
                    dp[(k, l)],
                    t.a[(c, r)]
                );
            }
        }
    }

    /// Held after a step, A relaxes to C̄⁻¹ by the factor (1 + k)⁻ⁿ, and the branch stress with
    /// it; the dissipation is positive.
    #[test]
    fn held_deformation_relaxes_geometrically() {
        let m = material();
        let f = Mat3::from_diagonal(&Vec3::new(1.3, 1.0, 1.0));
        let j: f64 = 1.3;
        let cbar_inv = (f.transpose() * f * j.powf(-2.0 / 3.0))
            .try_inverse()
            .unwrap();
        let mut a = [0.0; 9];
        m.initial_state(&mut a);
        let dt = 0.05;
        let k = dt / m.tau;
        for n in 1..=20 {
            let mut next = [0.0; 9];
            let d = m
                .update_state(
                    &f,
                    &Vec3::zeros(),
                    PointHistory { state: &a, dt },
                    &mut next,
                )
                .unwrap();
            assert!(d > 0.0);
            a = next;
            let expect = cbar_inv + (Mat3::identity() - cbar_inv) * (1.0 + k).powi(-n);
            assert!((tensor(&a) - expect).norm() < 1e-14, "step {n}");
        }
    }
}
