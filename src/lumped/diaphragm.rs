//! The circular diaphragm actuator (docs/validation.md) as a one-degree-of-freedom Ritz model.
//!
//! Geometry in the pre-stretched state: pad radius a, electrode radius c, clamped rim radius b
//! (a < c ≤ b); reference thickness H, equibiaxial pre-stretch λp. The pad (r < a) is rigid and
//! carries the mass m; electrodes cover the annulus a..c on both faces. The pad deflection x
//! (positive downward, along gravity) is the only unknown; the membrane takes the shape
//!
//! ```text
//! w(r) = x ln(b/r)/L,  L = ln(b/a),  a ≤ r ≤ b       (w = x on the pad)
//! ```
//!
//! with no extra radial displacement, so λ_θ = λp and λ_r = λp √(1 + x² s²), s = −1/(r L).
//! This is the exact small-deflection shape of a pre-tensioned annular membrane (T r w' is
//! constant), so the model reproduces k = 2πT₀/L as x → 0; a cone w = x(b − r)/(b − a) would
//! overestimate it by (b + a)L/(2(b − a)) in energy (+19 % here) and, used as a force balance at
//! the pad edge (k = 2πaT₀/(b − a)), underestimate it by (b − a)/(aL) (2.4× here).
//!
//! Total potential (reference area dA = 2πr dr/λp², W the plane-stress energy of the material):
//!
//! ```text
//! Π(x, V) = ∫ H W(λ_r, λp) dA − ½ C(x) V² − (m + ρH S_g) g x,   S_g = ∫ (w/x) dA (pad included)
//! C(x)    = (ε/H) ∫_{a..c} λ_r λp / λ_z dA                  (current area / current thickness)
//! ```
//!
//! Radial integrals use Gauss–Legendre in u = ln r on the panels [a, c] and [c, b]: the weight
//! r² du = r dr · r concentrates the points toward r = a, where the slope is largest, and the
//! small-deflection integrands (∝ s² r dr ∝ du) become constants, integrated exactly.
//!
//! Viscosity (deasim's Kelvin–Voigt model, Rayleigh function R = (Jη/2) d:d per reference volume,
//! d = sym(Ḟ F⁻¹)): for F = Q diag(λ_r, λ_θ, λ_z) (Q the rotation of the meridian) d has the
//! eigenvalues λ̇_i/λ_i, with λ̇_θ = 0 and λ̇_z = (dλ_z/dλ_r) λ̇_r, so R = ½ c(x) ẋ² with
//!
//! ```text
//! c(x) = η H ∫ J (∂_x λ_r / λ_r)² [1 + (λ_r λ_z'/λ_z)²] dA,    J = λ_r λp λ_z
//! ```
//!
//! (≈ 2η H ∫ (∂_x λ_r/λ_r)² dA for a nearly incompressible material). Since ∂_x λ_r ∝ x, c vanishes
//! in the flat state: transverse motion about a flat membrane is a rotation to first order.

use std::f64::consts::PI;
use std::sync::Arc;

use super::equilibrium::{first_root, Root, Search};
use super::history::{History, Sample};
use super::integrator::{integrate, Oscillator};
use super::linearised::Linearised;
use super::plane_stress::{plane_stress, PlaneStress};
use super::quadrature::on_interval;
use super::{check, LumpedError};
use crate::material::Material;
use crate::waveform::Waveform;

/// Parameters of the diaphragm actuator (SI units; radii in the pre-stretched state).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiaphragmParams {
    /// Reference (unstretched) membrane thickness H (m).
    pub thickness: f64,
    /// Equibiaxial pre-stretch λp.
    pub prestretch: f64,
    /// Radius a of the rigid pad (m).
    pub pad_radius: f64,
    /// Radius c of the electrodes (m), a < c ≤ b.
    pub electrode_radius: f64,
    /// Radius b of the clamped rim (m).
    pub rim_radius: f64,
    /// Mass m carried by the pad (kg).
    pub mass: f64,
    /// Gravitational acceleration g ≥ 0 (m/s²), acting along +x.
    pub gravity: f64,
    /// Mass density ρ of the membrane (kg/m³).
    pub density: f64,
    /// Kelvin–Voigt viscosity η (Pa·s), as in deasim's viscous model.
    pub viscosity: f64,
    /// Dashpot on the pad (N·s/m): air and fixture losses of the mass, added to the membrane's
    /// viscous damping.
    pub pad_damping: f64,
    /// Gauss points per radial panel (two panels: a..c and c..b).
    pub quadrature_points: usize,
}

impl DiaphragmParams {
    /// The experimental study's actuator (docs/validation.md): H = 1 mm, λp = 2, a = 7.5 mm, c = 15 mm,
    /// b = 35 mm, m = 46.22 g, g = 9.81 m/s², ρ = 960 kg/m³; no viscosity (set it explicitly).
    pub fn reference_study() -> Self {
        DiaphragmParams {
            thickness: 1e-3,
            prestretch: 2.0,
            pad_radius: 7.5e-3,
            electrode_radius: 15e-3,
            rim_radius: 35e-3,
            mass: 46.22e-3,
            gravity: 9.81,
            density: 960.0,
            viscosity: 0.0,
            pad_damping: 0.0,
            quadrature_points: 16,
        }
    }
}

/// A radial quadrature point in the annulus.
#[derive(Debug, Clone, Copy)]
struct Point {
    /// Radius r in the pre-stretched state (m).
    r: f64,
    /// s² = (w'/x)² = 1/(r L)² (1/m²).
    s2: f64,
    /// Reference-area weight dA (m²).
    da: f64,
    /// Inside the electrodes (r < c).
    electroded: bool,
}

/// Integrals over the annulus at one deflection.
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    /// ∫ H W dA (J).
    energy: f64,
    /// ∫ H P_rr ∂_x λ_r dA (N).
    force: f64,
    /// ∫ H (dP ∂_x λ_r² + P ∂²_x λ_r) dA (N/m), when requested.
    stiffness: f64,
    /// C (F), C' (F/m), C'' (F/m², when requested).
    cap: f64,
    dcap: f64,
    ddcap: f64,
    /// c(x) (N·s/m).
    damping: f64,
}

/// The diaphragm Ritz model for one material.
#[derive(Debug, Clone)]
pub struct Diaphragm {
    params: DiaphragmParams,
    material: Arc<dyn Material>,
    permittivity: f64,
    points: Vec<Point>,
    /// L = ln(b/a).
    log_ratio: f64,
    /// Flat pre-stretched state.
    flat: PlaneStress,
    /// J of the flat state (initial guess of λ_z).
    flat_volume_ratio: f64,
    /// m_eff (kg).
    effective_mass: f64,
    /// Weight (m + ρ H S_g) g (N).
    weight: f64,
}

impl Diaphragm {
    /// Builds the model; every parameter is checked, and the flat pre-stretched membrane must
    /// be in tension.
    pub fn new(params: DiaphragmParams, material: Arc<dyn Material>) -> Result<Self, LumpedError> {
        let p = &params;
        check(
            "thickness",
            p.thickness,
            p.thickness > 0.0,
            "must be > 0 (m)",
        )?;
        check(
            "prestretch",
            p.prestretch,
            p.prestretch > 0.0,
            "must be > 0",
        )?;
        check(
            "pad_radius",
            p.pad_radius,
            p.pad_radius > 0.0,
            "must be > 0 (m)",
        )?;
        check(
            "rim_radius",
            p.rim_radius,
            p.rim_radius > p.pad_radius,
            "must exceed the pad radius (m)",
        )?;
        check(
            "electrode_radius",
            p.electrode_radius,
            p.electrode_radius > p.pad_radius && p.electrode_radius <= p.rim_radius,
            "must lie in (pad radius, rim radius] (m)",
        )?;
        check("mass", p.mass, p.mass >= 0.0, "must be ≥ 0 (kg)")?;
        check(
            "gravity",
            p.gravity,
            p.gravity >= 0.0,
            "must be ≥ 0 (m/s², along +x)",
        )?;
        check(
            "density",
            p.density,
            p.density >= 0.0,
            "must be ≥ 0 (kg/m³)",
        )?;
        check(
            "viscosity",
            p.viscosity,
            p.viscosity >= 0.0,
            "must be ≥ 0 (Pa·s)",
        )?;
        check(
            "pad_damping",
            p.pad_damping,
            p.pad_damping >= 0.0,
            "must be ≥ 0 (N·s/m)",
        )?;
        let nq = p.quadrature_points;
        check(
            "quadrature_points",
            nq as f64,
            (2..=400).contains(&nq),
            "must be in 2..=400",
        )?;
        let permittivity = material.permittivity();
        check(
            "permittivity",
            permittivity,
            permittivity >= 0.0,
            "the material's permittivity must be ≥ 0 (F/m)",
        )?;
        let (a, b, c, lp) = (p.pad_radius, p.rim_radius, p.electrode_radius, p.prestretch);
        let log_ratio = (b / a).ln();
        let mut points = Vec::with_capacity(2 * nq);
        let mut panels = vec![(a, c, true)];
        if c < b {
            panels.push((c, b, false));
        }
        for (lo, hi, electroded) in panels {
            for (u, wu) in on_interval(nq, lo.ln(), hi.ln()) {
                let r = u.exp();
                points.push(Point {
                    r,
                    s2: 1.0 / (r * log_ratio).powi(2),
                    da: 2.0 * PI * r * r * wu / (lp * lp),
                    electroded,
                });
            }
        }
        let flat = plane_stress(material.as_ref(), lp, lp, 1.0 / (lp * lp)).map_err(|source| {
            LumpedError::Material {
                stretch: lp,
                source,
            }
        })?;
        let tension = flat.p * p.thickness / lp;
        check(
            "prestretch",
            p.prestretch,
            tension > 0.0,
            &format!("the pre-stretched membrane must be in tension (T₀ = {tension:e} N/m)"),
        )?;
        // ∫ (w/x) dA and ∫ (w/x)² dA over the annulus, by the same rule; plus the pad disc
        let pad_area = PI * a * a / (lp * lp);
        let (mut sg, mut sm) = (pad_area, pad_area);
        for q in &points {
            let shape = (b / q.r).ln() / log_ratio;
            sg += shape * q.da;
            sm += shape * shape * q.da;
        }
        let effective_mass = p.mass + p.density * p.thickness * sm;
        check(
            "mass",
            effective_mass,
            effective_mass > 0.0,
            "the pad mass plus the membrane's effective mass must be > 0 (kg)",
        )?;
        let weight = (p.mass + p.density * p.thickness * sg) * p.gravity;
        Ok(Diaphragm {
            params,
            material,
            permittivity,
            points,
            log_ratio,
            flat_volume_ratio: lp * lp * flat.lz,
            flat,
            effective_mass,
            weight,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &DiaphragmParams {
        &self.params
    }

    /// The material.
    pub fn material(&self) -> &Arc<dyn Material> {
        &self.material
    }

    /// Thickness h₀ = λ_z H of the flat pre-stretched membrane (m).
    pub fn flat_thickness(&self) -> f64 {
        self.flat.lz * self.params.thickness
    }

    /// Pre-tension T₀ = σ₀ h₀ = P_rr H/λp of the flat membrane (N/m).
    pub fn prestress_tension(&self) -> f64 {
        self.flat.p * self.params.thickness / self.params.prestretch
    }

    /// Small-deflection membrane stiffness 2πT₀/ln(b/a) (N/m); docs/theory.md, membrane statics.
    pub fn membrane_stiffness(&self) -> f64 {
        2.0 * PI * self.prestress_tension() / self.log_ratio
    }

    /// Effective mass m_eff = m + ρH ∫ (w/x)² dA, pad disc included (kg).
    pub fn effective_mass(&self) -> f64 {
        self.effective_mass
    }

    /// Total weight (m + ρH ∫ (w/x) dA) g, the generalised gravity force (N).
    pub fn weight(&self) -> f64 {
        self.weight
    }

    /// The model's permittivity ε (F/m), from the material.
    pub fn permittivity(&self) -> f64 {
        self.permittivity
    }

    fn radial_stretch(&self, x: f64, s2: f64) -> (f64, f64, f64) {
        let lp = self.params.prestretch;
        let q = (1.0 + x * x * s2).sqrt();
        let lr = lp * q;
        // ∂λ_r/∂x and ∂²λ_r/∂x²
        (lr, lp * x * s2 / q, lp * s2 / (q * q * q))
    }

    fn state(&self, lr: f64, guess: f64) -> Result<PlaneStress, LumpedError> {
        plane_stress(self.material.as_ref(), lr, self.params.prestretch, guess).map_err(|source| {
            LumpedError::Material {
                stretch: lr,
                source,
            }
        })
    }

    /// g'(λ_r) with g = λ_r λp/λ_z: the derivative of the capacitance integrand.
    fn cap_slope(&self, lr: f64, s: &PlaneStress) -> f64 {
        let lp = self.params.prestretch;
        lp / s.lz * (1.0 - lr * s.dlz / s.lz)
    }

    fn sums(&self, x: f64, second: bool) -> Result<Sums, LumpedError> {
        check("deflection", x, true, "must be finite (m)")?;
        let (h, lp) = (self.params.thickness, self.params.prestretch);
        let eps_h = self.permittivity / h;
        let mut s = Sums::default();
        for q in &self.points {
            let (lr, dlr, ddlr) = self.radial_stretch(x, q.s2);
            let ps = self.state(lr, self.flat_volume_ratio / (lr * lp))?;
            s.energy += h * ps.w * q.da;
            s.force += h * ps.p * dlr * q.da;
            let rate = dlr / lr;
            let thick = lr * ps.dlz / ps.lz;
            s.damping += lr * lp * ps.lz * rate * rate * (1.0 + thick * thick) * q.da;
            if second {
                s.stiffness += h * (ps.dp * dlr * dlr + ps.p * ddlr) * q.da;
            }
            if q.electroded {
                let g1 = self.cap_slope(lr, &ps);
                s.cap += eps_h * lr * lp / ps.lz * q.da;
                s.dcap += eps_h * g1 * dlr * q.da;
                if second {
                    // g'' by a central difference of the analytic g' (needs third derivatives
                    // of W otherwise); relative error ~1e-8
                    let mut g2 = 0.0;
                    if dlr != 0.0 {
                        let d = 1e-4 * lr;
                        let sp = self.state(lr + d, ps.lz + ps.dlz * d)?;
                        let sm = self.state(lr - d, ps.lz - ps.dlz * d)?;
                        g2 =
                            (self.cap_slope(lr + d, &sp) - self.cap_slope(lr - d, &sm)) / (2.0 * d);
                    }
                    s.ddcap += eps_h * (g2 * dlr * dlr + g1 * ddlr) * q.da;
                }
            }
        }
        s.damping = s.damping * self.params.viscosity * h + self.params.pad_damping;
        Ok(s)
    }

    /// Total potential Π(x, V) (J).
    pub fn potential(&self, x: f64, voltage: f64) -> Result<f64, LumpedError> {
        let s = self.sums(x, false)?;
        Ok(s.energy - 0.5 * s.cap * voltage * voltage - self.weight * x)
    }

    /// Generalised force Π'(x, V) = ∂Π/∂x (N); zero at equilibrium.
    pub fn force(&self, x: f64, voltage: f64) -> Result<f64, LumpedError> {
        let s = self.sums(x, false)?;
        Ok(s.force - 0.5 * s.dcap * voltage * voltage - self.weight)
    }

    /// Tangent stiffness k = Π''(x, V) (N/m).
    pub fn stiffness(&self, x: f64, voltage: f64) -> Result<f64, LumpedError> {
        let s = self.sums(x, true)?;
        Ok(s.stiffness - 0.5 * s.ddcap * voltage * voltage)
    }

    /// Capacitance C(x) of the electroded annulus a..c (F). (An electrode also covering the pad
    /// adds the constant επa²/h₀.)
    pub fn capacitance(&self, x: f64) -> Result<f64, LumpedError> {
        Ok(self.sums(x, false)?.cap)
    }

    /// dC/dx (F/m).
    pub fn capacitance_slope(&self, x: f64) -> Result<f64, LumpedError> {
        Ok(self.sums(x, false)?.dcap)
    }

    /// d²C/dx² (F/m²).
    pub fn capacitance_curvature(&self, x: f64) -> Result<f64, LumpedError> {
        Ok(self.sums(x, true)?.ddcap)
    }

    /// Viscous coefficient c(x) (N·s/m) of the Kelvin–Voigt model for the assumed shape.
    pub fn damping(&self, x: f64) -> Result<f64, LumpedError> {
        Ok(self.sums(x, false)?.damping)
    }

    /// Smallest current thickness in the electroded annulus (at the pad edge r = a, m).
    pub fn min_thickness(&self, x: f64) -> Result<f64, LumpedError> {
        let a = self.params.pad_radius;
        let (lr, ..) = self.radial_stretch(x, 1.0 / (a * self.log_ratio).powi(2));
        let ps = self.state(lr, self.flat_volume_ratio / (lr * self.params.prestretch))?;
        Ok(ps.lz * self.params.thickness)
    }

    /// Largest true field V/h in the electroded annulus (V/m).
    pub fn max_field(&self, x: f64, voltage: f64) -> Result<f64, LumpedError> {
        Ok(voltage.abs() / self.min_thickness(x)?)
    }

    /// Static pad deflection (m) under gravity and voltage V: the first stable equilibrium reached
    /// from the flat state (safeguarded Newton on Π' = 0). Errors when none exists up to a
    /// deflection b − a (pull-in, loss of tension) or the material fails first.
    pub fn static_deflection(&self, voltage: f64) -> Result<f64, LumpedError> {
        check("voltage", voltage, true, "must be finite (V)")?;
        let span = self.params.rim_radius - self.params.pad_radius;
        let eval = |x: f64| Ok((self.force(x, voltage)?, self.stiffness(x, voltage)?));
        let search = Search {
            start: 0.0,
            limit: span,
            first_step: 1e-3 * span,
            tol: 1e-12,
        };
        let none = |reason: String| LumpedError::NoEquilibrium {
            load: voltage,
            reason,
        };
        match first_root(eval, search).map_err(|e| none(e.to_string()))? {
            Root::At(x) => {
                let k = self.stiffness(x, voltage)?;
                if k > 0.0 {
                    Ok(x)
                } else {
                    Err(none(format!(
                        "the equilibrium at x = {x:e} m is not stable (k = {k:e} N/m): \
                         the flat membrane has lost its tension"
                    )))
                }
            }
            Root::None { last, reason } => Err(none(format!(
                "{reason} (Π' < 0 up to x = {last:e} m; pull-in or loss of tension)"
            ))),
        }
    }

    /// Natural frequency (Hz) of small oscillations about the static equilibrium at voltage V.
    pub fn natural_frequency(&self, voltage: f64) -> Result<f64, LumpedError> {
        let x = self.static_deflection(voltage)?;
        let k = self.stiffness(x, voltage)?;
        Ok((k / self.effective_mass).sqrt() / (2.0 * PI))
    }

    /// The linearisation m_eff ẍ + c ẋ + k x = β V(t)² about the equilibrium at V = 0 with
    /// gravity (the experimental study's form), x measured from that equilibrium.
    pub fn linearise(&self) -> Result<Linearised, LumpedError> {
        let x0 = self.static_deflection(0.0)?;
        let s = self.sums(x0, true)?;
        Ok(Linearised {
            equilibrium: x0,
            mass: self.effective_mass,
            damping: s.damping,
            stiffness: s.stiffness,
            force_per_volt2: 0.5 * s.dcap,
            capacitance: s.cap,
            min_thickness: self.min_thickness(x0)?,
        })
    }

    /// Integrates m_eff ẍ + c(x) ẋ + Π'(x, V(t)) = 0 from rest at the static equilibrium under
    /// V(0) up to t_end with steps dt (midpoint rule, [`super::integrator`]).
    pub fn simulate(
        &self,
        waveform: &Waveform,
        t_end: f64,
        dt: f64,
    ) -> Result<History, LumpedError> {
        check("t_end", t_end, t_end >= 0.0, "must be ≥ 0 (s)")?;
        check("dt", dt, dt > 0.0, "must be > 0 (s)")?;
        let x0 = self.static_deflection(waveform.value(0.0))?;
        self.simulate_from(waveform, x0, 0.0, t_end, dt)
    }

    /// As [`Self::simulate`], from the deflection x₀ (m) and velocity v₀ (m/s) at t = 0.
    pub fn simulate_from(
        &self,
        waveform: &Waveform,
        x0: f64,
        v0: f64,
        t_end: f64,
        dt: f64,
    ) -> Result<History, LumpedError> {
        check("t_end", t_end, t_end >= 0.0, "must be ≥ 0 (s)")?;
        check("dt", dt, dt > 0.0, "must be > 0 (s)")?;
        check("x0", x0, true, "the initial deflection must be finite (m)")?;
        check("v0", v0, true, "the initial velocity must be finite (m/s)")?;
        let driven = Driven {
            model: self,
            waveform,
        };
        let mut history = History::default();
        integrate(&driven, 0.0, x0, v0, t_end, dt, |t, x, v| {
            let voltage = waveform.value(t);
            let s = self.sums(x, false)?;
            history.samples.push(Sample {
                time: t,
                deflection: x,
                velocity: v,
                voltage,
                capacitance: s.cap,
                charge: s.cap * voltage,
                max_field: self.max_field(x, voltage)?,
                energy: 0.5 * self.effective_mass * v * v + s.energy
                    - 0.5 * s.cap * voltage * voltage
                    - self.weight * x,
            });
            Ok(())
        })?;
        Ok(history)
    }
}

/// The diaphragm driven by a voltage signal.
struct Driven<'a> {
    model: &'a Diaphragm,
    waveform: &'a Waveform,
}

impl Oscillator for Driven<'_> {
    fn mass(&self) -> f64 {
        self.model.effective_mass
    }
    fn force(&self, x: f64, t: f64) -> Result<f64, LumpedError> {
        self.model.force(x, self.waveform.value(t))
    }
    fn stiffness(&self, x: f64, t: f64) -> Result<f64, LumpedError> {
        self.model.stiffness(x, self.waveform.value(t))
    }
    fn damping(&self, x: f64) -> Result<f64, LumpedError> {
        self.model.damping(x)
    }
}
