//! Time integration: the midpoint variational integrator without damping — its energy over many
//! periods (bounded O(Δt²) oscillation, no drift), linear and angular momentum of a free body
//! (conserved to round-off), and the axial frequency of a slender bar against the rod's closed
//! form.

use super::Case;
use crate::mesh::Mesh;
use crate::problem::dofs::{Dirichlet, Field, FIELDS};
use crate::problem::examples::{block, slender_bar};
use crate::problem::model::Model;
use crate::problem::statics::energies;
use crate::solve::newton::NewtonSettings;
use crate::time::integrator::Scheme;
use crate::time::integrator::TimeLevel;
use crate::time::mass::{MassKind, NodalMass};
use crate::time::stage::{run_dynamic, DynamicInputs, DynamicSettings, Method};
use crate::waveform::Waveform;

/// Mass density (kg/m³) of the dynamic examples.
pub const RHO: f64 = 1000.0;

/// The levels of a dynamic run with the energy kinetic + stored − electric and the dissipated
/// energy accumulated to each.
pub struct Run {
    pub levels: Vec<TimeLevel>,
    pub energy: Vec<f64>,
    pub dissipated: Vec<f64>,
}

/// `steps` steps of `dt` of `model` (density [`RHO`], consistent mass, Kelvin–Voigt viscosity
/// `eta`) with the nodes `bottom` at 0 V and `top` at `volts`, from rest or the velocity `v0`.
#[allow(clippy::too_many_arguments)]
pub fn simulate(
    model: &Model,
    top: &[usize],
    bottom: &[usize],
    volts: f64,
    eta: f64,
    scheme: Method,
    dt: f64,
    steps: usize,
    v0: Option<Vec<f64>>,
) -> Result<Run, String> {
    let mass = NodalMass::new(model, &[RHO], MassKind::Consistent);
    let inputs = DynamicInputs {
        mass: &mass,
        viscosity: vec![eta],
        drive: crate::problem::drive::Drive {
            voltages: vec![
                (bottom.to_vec(), Waveform::constant(0.0)),
                (top.to_vec(), Waveform::constant(volts)),
            ],
            ..crate::problem::drive::Drive::held(model)
        },
        points: Default::default(),
        part: None,
    };
    let n = model.mesh.n_nodes() * FIELDS;
    let start = TimeLevel {
        t: 0.0,
        q: vec![0.0; n],
        v: v0.unwrap_or(vec![0.0; n]),
        a: vec![0.0; n],
    };
    let settings = DynamicSettings {
        duration: dt * steps as f64,
        dt,
        scheme,
        min_fraction: 1.0 / 64.0,
        easy_iterations: 100,
        reuse_factorization: true,
        solver: Default::default(),
    };
    let mut run = Run {
        levels: Vec::new(),
        energy: Vec::new(),
        dissipated: Vec::new(),
    };
    let mut mv = vec![0.0; n];
    let mut dissipated = 0.0;
    let mut failure = None;
    let newton = NewtonSettings {
        rtol: 1e-12,
        check_stability: false,
        ..Default::default()
    };
    run_dynamic(model, &inputs, start, &settings, &newton, |level, info| {
        mass.mul(&level.v, &mut mv);
        let kinetic = 0.5 * level.v.iter().zip(&mv).map(|(a, b)| a * b).sum::<f64>();
        match energies(model, &level.q) {
            Ok((stored, electric)) => run.energy.push(kinetic + stored - electric),
            Err(e) => failure = Some(e),
        }
        dissipated += info.dissipated;
        run.dissipated.push(dissipated);
        run.levels.push(level.clone());
    })
    .map_err(|(_, f)| f.reason)?;
    match failure {
        Some(e) => Err(e),
        None => Ok(run),
    }
}

/// Largest deviation of a conserved quantity from its first value (the voltage is switched on at
/// t = 0, so the energy of the first level is the reference).
pub fn energy_band(e: &[f64]) -> f64 {
    e.iter().map(|v| (v - e[0]).abs()).fold(0.0, f64::max)
}

/// Least-squares trend of a series over its whole length (slope × number of samples).
pub fn trend(e: &[f64]) -> f64 {
    let n = e.len() as f64;
    let mean_i = (n - 1.0) / 2.0;
    let mean_e = e.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, v) in e.iter().enumerate() {
        sxy += (i as f64 - mean_i) * (v - mean_e);
        sxx += (i as f64 - mean_i).powi(2);
    }
    sxy / sxx * n
}

/// Linear momentum Σ M v and angular momentum Σ x × M v of a level.
pub fn momenta(mesh: &Mesh, mass: &NodalMass, level: &TimeLevel) -> ([f64; 3], [f64; 3]) {
    let mut mv = vec![0.0; level.v.len()];
    mass.mul(&level.v, &mut mv);
    let (mut p, mut l) = ([0.0; 3], [0.0; 3]);
    for (a, x0) in mesh.nodes.iter().enumerate() {
        let x: Vec<f64> = (0..3).map(|i| x0[i] + level.q[a * FIELDS + i]).collect();
        let m = &mv[a * FIELDS..a * FIELDS + 3];
        for i in 0..3 {
            p[i] += m[i];
        }
        l[0] += x[1] * m[2] - x[2] * m[1];
        l[1] += x[2] * m[0] - x[0] * m[2];
        l[2] += x[0] * m[1] - x[1] * m[0];
    }
    (p, l)
}

/// Times at which `v` crosses zero downwards (linear interpolation between levels).
pub fn downward_crossings(v: &[(f64, f64)]) -> Vec<f64> {
    v.windows(2)
        .filter(|w| w[0].1 > 0.0 && w[1].1 <= 0.0)
        .map(|w| w[0].0 + (w[1].0 - w[0].0) * w[0].1 / (w[0].1 - w[1].1))
        .collect()
}

/// The supported block with its bottom grounded: the model and its electrode nodes.
pub fn grounded_block() -> Result<(Model, Vec<usize>, Vec<usize>), String> {
    let (mut model, bottom, top) = block(false).map_err(|e| e.to_string())?;
    model.dirichlet.push(Dirichlet {
        nodes: bottom.clone(),
        field: Field::Phi,
        value: 0.0,
    });
    Ok((model, bottom, top))
}

/// Energy rows: the block under a 20 kV step, 10⁴ steps of 2 µs.
fn energy_cases() -> Result<Vec<Case>, String> {
    let (model, bottom, top) = grounded_block()?;
    let dt = 2e-6;
    let run = |dt: f64, steps: usize| {
        simulate(
            &model,
            &top,
            &bottom,
            20e3,
            0.0,
            Method::Implicit(Scheme::Midpoint),
            dt,
            steps,
            None,
        )
    };
    let long = run(dt, 10_000)?;
    let e = &long.energy;
    let corner = model.mesh.nearest_node([2e-3, 2e-3, 1e-3]);
    let vz: Vec<(f64, f64)> = long
        .levels
        .iter()
        .map(|l| (l.t, l.v[corner * FIELDS + 2]))
        .collect();
    let periods = downward_crossings(&vz).len();
    let reference = "exact conservation";
    let mut out = vec![
        Case::new(
            format!("midpoint, 10⁴ steps ({periods} oscillations): energy (J)"),
            reference.into(),
            e[0],
            e[e.len() - 1],
            1e-5,
        )
        .with_deviation(energy_band(e)),
        Case::new(
            "midpoint, 10⁴ steps: least-squares drift (J)".into(),
            format!("{reference}, no drift"),
            e[0],
            e[0] + trend(e),
            1e-6,
        ),
    ];
    let full = run(dt, 1_000)?;
    let half = run(dt / 2.0, 2_000)?;
    out.push(Case::new(
        "midpoint: order of the energy error (Δt → Δt/2)".into(),
        "second order".into(),
        2.0,
        (energy_band(&full.energy) / energy_band(&half.energy)).log2(),
        0.1,
    ));
    Ok(out)
}

/// A free body's run: its model, mass, initial level and levels.
pub struct FreeBody {
    pub model: Model,
    pub mass: NodalMass,
    pub start: TimeLevel,
    pub run: Run,
}

/// The unsupported block given a translation (0.1, 0.05, −0.02) m/s and a rotation
/// (30, −20, 50) rad/s, 500 steps of 1 µs under 20 kV.
pub fn free_body() -> Result<FreeBody, String> {
    let (mut model, bottom, top) = block(true).map_err(|e| e.to_string())?;
    let mut v0 = vec![0.0; model.mesh.n_nodes() * FIELDS];
    let omega = [30.0, -20.0, 50.0]; // rad/s
    for (a, x) in model.mesh.nodes.iter().enumerate() {
        let w = [
            omega[1] * x[2] - omega[2] * x[1],
            omega[2] * x[0] - omega[0] * x[2],
            omega[0] * x[1] - omega[1] * x[0],
        ];
        for i in 0..3 {
            v0[a * FIELDS + i] = [0.1, 0.05, -0.02][i] + w[i];
        }
    }
    model.dirichlet.push(Dirichlet {
        nodes: bottom.clone(),
        field: Field::Phi,
        value: 0.0,
    });
    let mass = NodalMass::new(&model, &[RHO], MassKind::Consistent);
    let run = simulate(
        &model,
        &top,
        &bottom,
        20e3,
        0.0,
        Method::Implicit(Scheme::Midpoint),
        1e-6,
        500,
        Some(v0.clone()),
    )?;
    let start = TimeLevel {
        t: 0.0,
        q: vec![0.0; v0.len()],
        v: v0,
        a: vec![],
    };
    Ok(FreeBody {
        model,
        mass,
        start,
        run,
    })
}

/// Momentum rows of [`free_body`]: error the largest deviation of a component over the run.
fn momentum_cases() -> Result<Vec<Case>, String> {
    let body = free_body()?;
    let of = |level: &TimeLevel| momenta(&body.model.mesh, &body.mass, level);
    let (p0, l0) = of(&body.start);
    let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let (mut dp, mut dl) = (0.0f64, 0.0f64);
    for level in &body.run.levels {
        let (p, l) = of(level);
        for i in 0..3 {
            dp = dp.max((p[i] - p0[i]).abs());
            dl = dl.max((l[i] - l0[i]).abs());
        }
    }
    let (p1, l1) = of(body.run.levels.last().ok_or("no step")?);
    let reference = "exact conservation (symmetry)";
    Ok(vec![
        Case::new(
            "free body, 500 steps: |linear momentum| (kg·m/s)".into(),
            reference.into(),
            norm(p0),
            norm(p1),
            1e-10,
        )
        .with_deviation(dp),
        Case::new(
            "free body, 500 steps: |angular momentum| (kg·m²/s)".into(),
            reference.into(),
            norm(l0),
            norm(l1),
            1e-10,
        )
        .with_deviation(dl),
    ])
}

/// First axial frequency (Hz) of the clamped–free bar of length `l` and shear modulus `mu`,
/// excited in its first mode shape with a small velocity and integrated with 100 steps per
/// period: the mean period between the downward zero crossings of the tip velocity over 5
/// periods.
pub fn bar_frequency(l: f64, mu: f64, period: f64) -> Result<f64, String> {
    let model = slender_bar(l, mu).map_err(|e| e.to_string())?;
    let mut v0 = vec![0.0; model.mesh.n_nodes() * FIELDS];
    for (a, x) in model.mesh.nodes.iter().enumerate() {
        v0[a * FIELDS] = 1e-4 * (std::f64::consts::PI * x[0] / (2.0 * l)).sin();
    }
    let run = simulate(
        &model,
        &[],
        &[],
        0.0,
        0.0,
        Method::Implicit(Scheme::Midpoint),
        period / 100.0,
        500,
        Some(v0),
    )?;
    let tip = model.mesh.nearest_node([l, 0.0, 0.0]);
    let v: Vec<(f64, f64)> = run
        .levels
        .iter()
        .map(|lv| (lv.t, lv.v[tip * FIELDS]))
        .collect();
    let c = downward_crossings(&v);
    if c.len() < 4 {
        return Err(format!("bar: only {} zero crossings", c.len()));
    }
    Ok((c.len() - 1) as f64 / (c[c.len() - 1] - c[0]))
}

/// Energy, momentum and frequency rows.
pub fn cases() -> Result<Vec<Case>, String> {
    let mut out = energy_cases()?;
    out.extend(momentum_cases()?);
    // Λ = 0: ν = 0 and E = 2μ exactly; the rod's f₁ = √(E/ρ)/(4L). Spatial error (40 cells)
    // ≈ 1e-4, temporal (100 steps per period) ≈ 3e-4.
    let (l, mu) = (1.0, 1e5);
    let f1 = (2.0 * mu / RHO).sqrt() / (4.0 * l);
    out.push(Case::new(
        "slender bar, 40 hex8: first axial frequency (Hz)".into(),
        "clamped–free rod √(E/ρ)/(4L)".into(),
        f1,
        bar_frequency(l, mu, 1.0 / f1)?,
        1e-2,
    ));
    Ok(out)
}
