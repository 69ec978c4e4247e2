//! Homogeneous material-point tests with the same material code as a device run — uniaxial,
//! equibiaxial and pure-shear ramps at given stretch rates, load–unload cycles, relaxation and
//! creep — so that a material (its rate dependence, its relaxation) is seen before a device is
//! run. What `deasim material` computes.

use super::homogeneous::Mode;
use super::point_history::{run, Control, PointRecord};
use super::Material;

/// The kinds of test.
pub const TESTS: [&str; 6] = [
    "uniaxial",
    "equibiaxial",
    "pure-shear",
    "cyclic",
    "relaxation",
    "creep",
];

/// What to run: the test, its deformation and its numbers.
#[derive(Debug, Clone)]
pub struct TestSpec {
    /// One of [`TESTS`].
    pub test: String,
    /// The deformation of `cyclic`, `relaxation` and `creep`: `uniaxial`, `equibiaxial` or
    /// `pure-shear`.
    pub mode: String,
    /// Largest (ramps, cycles) or held (relaxation) stretch.
    pub stretch: f64,
    /// Stretch rates dλ/dt (1/s) of the ramps and cycles.
    pub rates: Vec<f64>,
    /// Held nominal stress of a creep test (Pa).
    pub stress: Option<f64>,
    /// Time (s) in which relaxation and creep tests reach their stretch or stress.
    pub ramp_time: f64,
    /// Hold time (s) of relaxation and creep tests.
    pub hold: f64,
    /// Load–unload cycles of the cyclic test.
    pub cycles: usize,
    /// Time steps per segment (ramp, hold, half cycle).
    pub steps: usize,
}

/// One curve of a test: its label (the rate) and its records.
#[derive(Debug, Clone)]
pub struct Curve {
    pub label: String,
    /// The stretch rate (1/s); 0 for relaxation and creep.
    pub rate: f64,
    pub records: Vec<PointRecord>,
}

impl TestSpec {
    /// The deformation of the test.
    pub fn mode(&self) -> Result<Mode, String> {
        let name = match self.test.as_str() {
            "uniaxial" | "equibiaxial" | "pure-shear" => self.test.as_str(),
            _ => self.mode.as_str(),
        };
        match name {
            "uniaxial" => Ok(Mode::Uniaxial),
            "equibiaxial" => Ok(Mode::Equibiaxial),
            "pure-shear" => Ok(Mode::PureShear),
            o => Err(format!(
                "mode: expected `uniaxial`, `equibiaxial` or `pure-shear`; got `{o}`"
            )),
        }
    }

    /// Validates the numbers of a test; an error starts with the parameter's name.
    pub fn check(&self) -> Result<(), String> {
        if !TESTS.contains(&self.test.as_str()) {
            return Err(format!(
                "test: expected one of {}; got `{}`",
                TESTS.join(", "),
                self.test
            ));
        }
        self.mode()?;
        let positive = |what: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{what}: must be a positive number; got {v}"))
            }
        };
        positive("stretch", self.stretch)?;
        if (self.stretch - 1.0).abs() < 1e-12 && self.test != "creep" {
            return Err("stretch: 1 is the undeformed state; give the stretch to reach".into());
        }
        for r in &self.rates {
            positive("rate", *r)?;
        }
        if self.rates.is_empty() {
            return Err("rate: at least one stretch rate (1/s) is needed".into());
        }
        positive("ramp-time", self.ramp_time)?;
        if self.hold < 0.0 || !self.hold.is_finite() {
            return Err(format!(
                "hold: must be a non-negative time in s; got {}",
                self.hold
            ));
        }
        if !(1..=1_000_000).contains(&self.steps) {
            return Err(format!(
                "steps: must be between 1 and 1000000; got {}",
                self.steps
            ));
        }
        if !(1..=1000).contains(&self.cycles) {
            return Err(format!(
                "cycles: must be between 1 and 1000; got {}",
                self.cycles
            ));
        }
        if self.test == "creep" {
            match self.stress {
                Some(s) if s.is_finite() && s != 0.0 => {}
                Some(s) => return Err(format!("stress: must be a non-zero stress in Pa; got {s}")),
                None => {
                    return Err("stress: a creep test needs the held nominal stress in Pa".into())
                }
            }
        }
        Ok(())
    }

    /// Runs the test's curves on `mat`.
    pub fn curves(&self, mat: &dyn Material) -> Result<Vec<Curve>, String> {
        let mode = self.mode()?;
        let (lmax, n) = (self.stretch, self.steps);
        let failed = |label: &str, f: crate::material::point_history::PointFailure| {
            format!(
                "{} test, {label}: stopped at t = {:.6} s after {} steps: {}",
                self.test,
                f.t,
                f.records.len(),
                f.reason
            )
        };
        match self.test.as_str() {
            "uniaxial" | "equibiaxial" | "pure-shear" | "cyclic" => {
                let cycles = if self.test == "cyclic" {
                    self.cycles
                } else {
                    0
                };
                self.rates
                    .iter()
                    .map(|&rate| {
                        let half = (lmax - 1.0).abs() / rate;
                        let sign = (lmax - 1.0).signum();
                        // a ramp to λmax, or triangles 1 → λmax → 1
                        let l = move |t: f64| {
                            if cycles == 0 {
                                1.0 + sign * rate * t
                            } else {
                                let p = (t / half) % 2.0;
                                let p = if p <= 1.0 { p } else { 2.0 - p };
                                1.0 + sign * rate * half * p
                            }
                        };
                        let mut times = Vec::new();
                        for k in 0..(2 * cycles).max(1) {
                            segment(&mut times, k as f64 * half, (k + 1) as f64 * half, n);
                        }
                        let label = format!("{rate} 1/s");
                        run(mat, mode, &Control::Stretch(&l), &times)
                            .map(|records| Curve {
                                label: label.clone(),
                                rate,
                                records,
                            })
                            .map_err(|f| failed(&label, f))
                    })
                    .collect()
            }
            "relaxation" | "creep" => {
                let ramp = self.ramp_time;
                let mut times = Vec::new();
                segment(&mut times, 0.0, ramp, n);
                if self.hold > 0.0 {
                    segment(&mut times, ramp, ramp + self.hold, n);
                }
                let label = format!("ramp {ramp} s");
                let result = if self.test == "relaxation" {
                    let l = |t: f64| 1.0 + (lmax - 1.0) * (t / ramp).min(1.0);
                    run(mat, mode, &Control::Stretch(&l), &times)
                } else {
                    let s0 = self.stress.unwrap_or(0.0);
                    let s = |t: f64| s0 * (t / ramp).min(1.0);
                    run(mat, mode, &Control::Stress(&s), &times)
                };
                result
                    .map(|records| {
                        vec![Curve {
                            label: label.clone(),
                            rate: 0.0,
                            records,
                        }]
                    })
                    .map_err(|f| failed(&label, f))
            }
            o => Err(format!("unknown test `{o}`")),
        }
    }
}

/// `steps` equal step ends over (a, b].
fn segment(times: &mut Vec<f64>, a: f64, b: f64, steps: usize) {
    times.extend((1..=steps).map(|i| a + (b - a) * i as f64 / steps as f64));
}
