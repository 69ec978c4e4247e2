//! The lumped diaphragm model derived from a scenario: the same geometry, pre-stretch, material,
//! mass, gravity, damping and voltage signal as the finite element run of a `disc` scenario.

use super::{Diaphragm, DiaphragmParams};
use crate::io::build::{Plan, StageKind};
use crate::io::scenario::{InputError, Scenario};
use crate::waveform::{Shape, Waveform};

/// What `deasim lumped` simulates.
#[derive(Debug, Clone)]
pub struct LumpedSetup {
    pub model: Diaphragm,
    /// Voltage across the membrane (driven electrode minus grounded one), on stage time.
    pub waveform: Waveform,
    /// Simulated time of the first dynamic stage (s), and its start on the global clock (s).
    pub duration: f64,
    pub start: f64,
    /// Time step (s).
    pub dt: f64,
    /// Capacitance of the electroded pad disc ε π a² / h (F): the Ritz model covers the annulus.
    pub pad_capacitance: f64,
}

/// Samples per period of the linearised natural frequency, at least, in [`LumpedSetup::simulate`].
pub const STEPS_PER_PERIOD: f64 = 60.0;

impl LumpedSetup {
    /// The linearisation about the rest state at 0 V, and the simulation of the first dynamic
    /// stage's drive from there (stage time), with the stage's step or a shorter one that
    /// resolves the natural period by [`STEPS_PER_PERIOD`] samples; the step (s) is the third.
    pub fn simulate(&self) -> Result<(super::Linearised, super::History, f64), super::LumpedError> {
        let lin = self.model.linearise()?;
        let dt = self
            .dt
            .min(1.0 / (STEPS_PER_PERIOD * lin.natural_frequency().max(1e-12)));
        let history =
            self.model
                .simulate_from(&self.waveform, lin.equilibrium, 0.0, self.duration, dt)?;
        Ok((lin, history, dt))
    }
}

/// Builds the lumped model of a `disc` scenario. Errors name the key that does not fit.
pub fn from_scenario(s: &Scenario, plan: &Plan, file: &str) -> Result<LumpedSetup, InputError> {
    let err = |key: &str, msg: String| InputError::at_key(file, key, msg);
    let m = &s.mesh;
    if m.generator.as_deref() != Some("disc") {
        return Err(err(
            "mesh.generator",
            "the lumped model describes the circular actuator: expected `disc`".into(),
        ));
    }
    let need = |key: &str, v: Option<f64>| v.ok_or_else(|| err(key, "missing".into()));
    let lp = s.prestretch.as_ref().map(|p| p.stretch).unwrap_or(1.0);
    let (radius, thickness) = (
        need("mesh.radius", m.radius)?,
        need("mesh.thickness", m.thickness)?,
    );
    let (pad, electrode) = (
        need("mesh.pad_radius", m.pad_radius)?,
        need("mesh.electrode_radius", m.electrode_radius)?,
    );
    let loads = s.loads.as_ref();
    let rigid = loads.and_then(|l| l.rigid.first()).ok_or_else(|| {
        err(
            "loads.rigid",
            "the lumped model needs a rigid pad (`[[loads.rigid]]`)".into(),
        )
    })?;
    let g = loads.and_then(|l| l.gravity).unwrap_or([0.0; 3]);
    if g[0] != 0.0 || g[1] != 0.0 || g[2] > 0.0 {
        return Err(err(
            "loads.gravity",
            format!("the lumped model takes gravity along −z; got {g:?}"),
        ));
    }
    if plan.model.materials.len() != 1 {
        return Err(err(
            "materials",
            "the lumped model takes one membrane material".into(),
        ));
    }
    let params = DiaphragmParams {
        thickness,
        prestretch: lp,
        pad_radius: lp * pad,
        electrode_radius: lp * electrode,
        rim_radius: lp * radius,
        mass: rigid.mass,
        gravity: -g[2],
        density: plan.densities[0],
        viscosity: plan.viscosities[0],
        pad_damping: rigid.damping,
        quadrature_points: 16,
    };
    let model = Diaphragm::new(params, plan.model.materials[0].clone())
        .map_err(|e| err("mesh", format!("lumped model: {e}")))?;
    // one driven electrode against grounded ones
    let driven: Vec<&crate::io::build::Electrode> = plan
        .electrodes
        .iter()
        .filter(|e| !matches!(e.voltage.shape, Shape::Constant) || e.voltage.value(0.0) != 0.0)
        .collect();
    let waveform = match driven.as_slice() {
        [] => Waveform::constant(0.0),
        [one] => one.voltage.clone(),
        _ => {
            return Err(err(
                "electrodes",
                "the lumped model takes one driven electrode; the others must be grounded".into(),
            ))
        }
    };
    let mut start = 0.0;
    let mut stage = None;
    for st in &plan.stages {
        if let StageKind::Dynamic { dt, .. } = st.kind {
            stage = Some((st.duration, dt, st.electrodes_on));
            break;
        }
        start += st.duration;
    }
    let (duration, dt, on) = stage.ok_or_else(|| {
        err(
            "stages",
            "the lumped model simulates the first dynamic stage; there is none".into(),
        )
    })?;
    let h = model.flat_thickness();
    let a = model.params().pad_radius;
    Ok(LumpedSetup {
        pad_capacitance: model.permittivity() * std::f64::consts::PI * a * a / h,
        model,
        waveform: if on {
            waveform
        } else {
            Waveform::constant(0.0)
        },
        duration,
        start,
        dt,
    })
}
