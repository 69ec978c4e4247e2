//! Signals of time: electrode voltages and load factors.
//!
//! All waveforms are `offset + amplitude · shape(t)`; periodic shapes use `frequency` (Hz) and a
//! phase angle in degrees, as on a function generator. Unipolar shapes run between 0 and 1 (what
//! the experiment's DC–DC converter produces), bipolar ones between −1 and 1.

use std::f64::consts::PI;

/// A rise over x ∈ [0, 1]: x, or the raised cosine (1 − cos πx)/2.
fn rise(x: f64, cosine: bool) -> f64 {
    if cosine {
        0.5 * (1.0 - (PI * x).cos())
    } else {
        x
    }
}

/// The shape of a signal.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Shape {
    /// 1 at all times.
    Constant,
    /// Rise from 0 at t = 0 to 1 at t = `rise_time`, then 1: linear, or with `cosine` the
    /// raised cosine (1 − cos πx)/2 of x = t/`rise_time`, which starts and ends at rest.
    Ramp {
        rise_time: f64,
        #[serde(default)]
        cosine: bool,
    },
    /// 0 before `at`, then 1 (with a rise over `rise_time` when it is positive, as `Ramp`'s).
    Step {
        at: f64,
        rise_time: f64,
        #[serde(default)]
        cosine: bool,
    },
    /// Square wave: high for the fraction `duty` of each period.
    Square {
        frequency: f64,
        duty: f64,
        bipolar: bool,
    },
    /// Symmetric triangle wave, starting at its low value.
    Triangle { frequency: f64, bipolar: bool },
    /// Sine; unipolar is (1 − cos ωt)/2, starting at 0 like the other unipolar shapes.
    Sine { frequency: f64, bipolar: bool },
    /// Truncated Fourier series (first `terms` odd harmonics) of a unipolar or bipolar square
    /// or triangle wave: the band-limited signal of a real generator (docs/lumped.md).
    Fourier {
        base: FourierBase,
        frequency: f64,
        terms: usize,
        bipolar: bool,
    },
    /// Piecewise-linear interpolation of (time, value) points, held constant outside.
    Table { points: Vec<(f64, f64)> },
}

/// The signal a Fourier series approximates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum FourierBase {
    Square,
    Triangle,
    Sine,
}

/// A scalar of a waveform that a derivative may be taken in ([`Waveform::derivative`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaveformScalar {
    /// The amplitude (V, or C for a charge).
    Amplitude,
    /// The offset.
    Offset,
    /// The frequency (Hz) of a periodic shape.
    Frequency,
}

/// A signal offset + amplitude · shape(t + phase/(360 f)).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Waveform {
    pub shape: Shape,
    pub amplitude: f64,
    pub offset: f64,
    /// Phase angle (degrees) of periodic shapes.
    pub phase_deg: f64,
}

impl Waveform {
    /// The piecewise-linear table through `points` (time in s, value), held before the first
    /// and after the last.
    pub fn table(points: &[(f64, f64)]) -> Self {
        Waveform {
            shape: Shape::Table {
                points: points.to_vec(),
            },
            amplitude: 1.0,
            offset: 0.0,
            phase_deg: 0.0,
        }
    }

    /// A constant value.
    pub fn constant(value: f64) -> Self {
        Waveform {
            shape: Shape::Constant,
            amplitude: value,
            offset: 0.0,
            phase_deg: 0.0,
        }
    }

    /// The value of a constant waveform; `None` for the others.
    pub fn constant_value(&self) -> Option<f64> {
        matches!(self.shape, Shape::Constant).then(|| self.value(0.0))
    }

    /// The waveform times `factor` (its amplitude and offset scaled).
    pub fn scaled(&self, factor: f64) -> Waveform {
        Waveform {
            amplitude: self.amplitude * factor,
            offset: self.offset * factor,
            ..self.clone()
        }
    }

    /// Frequency (Hz) of a periodic shape; `None` for the others.
    pub fn frequency(&self) -> Option<f64> {
        match self.shape {
            Shape::Square { frequency, .. }
            | Shape::Triangle { frequency, .. }
            | Shape::Sine { frequency, .. }
            | Shape::Fourier { frequency, .. } => Some(frequency),
            _ => None,
        }
    }

    /// Whether the signal has no jumps (a square wave or an instant step has).
    pub fn is_continuous(&self) -> bool {
        match self.shape {
            Shape::Square { .. } => false,
            Shape::Step { rise_time, .. } => rise_time > 0.0,
            _ => true,
        }
    }

    /// Value at time `t` (s).
    pub fn value(&self, t: f64) -> f64 {
        self.offset + self.amplitude * self.shape_value(t)
    }

    /// ∂value/∂`which` at time `t`: the shape's value, 1, or amplitude · ∂shape/∂f (0 for a
    /// shape without a frequency, and almost everywhere for a square wave, whose values jump).
    pub fn derivative(&self, t: f64, which: WaveformScalar) -> f64 {
        match which {
            WaveformScalar::Amplitude => self.shape_value(t),
            WaveformScalar::Offset => 1.0,
            WaveformScalar::Frequency => self.amplitude * self.shape_frequency_slope(t),
        }
    }

    /// ∂shape/∂f at time `t` of a periodic shape: its slope in the period's fraction
    /// x = t·f + phase/360 (mod 1) times ∂x/∂f = t; 0 for the others.
    fn shape_frequency_slope(&self, t: f64) -> f64 {
        let bip = |slope: f64, bipolar: bool| if bipolar { 2.0 * slope } else { slope };
        let slope = match &self.shape {
            Shape::Triangle { frequency, bipolar } => {
                let x = self.periodic_time(t, *frequency);
                bip(if x < 0.5 { 2.0 } else { -2.0 }, *bipolar)
            }
            Shape::Sine { frequency, bipolar } => {
                let w = 2.0 * PI * self.periodic_time(t, *frequency);
                if *bipolar {
                    2.0 * PI * w.cos()
                } else {
                    PI * w.sin()
                }
            }
            Shape::Fourier {
                base,
                frequency,
                terms,
                bipolar,
            } => {
                let w = 2.0 * PI * self.periodic_time(t, *frequency);
                bip(fourier_series(base, *terms, w).1, *bipolar)
            }
            _ => 0.0,
        };
        slope * t
    }

    fn periodic_time(&self, t: f64, frequency: f64) -> f64 {
        // fraction of the period in [0, 1)
        let x = t * frequency + self.phase_deg / 360.0;
        x - x.floor()
    }

    fn shape_value(&self, t: f64) -> f64 {
        let bip = |u: f64, bipolar: bool| if bipolar { 2.0 * u - 1.0 } else { u };
        match &self.shape {
            Shape::Constant => 1.0,
            Shape::Ramp { rise_time, cosine } => {
                if *rise_time <= 0.0 {
                    1.0
                } else {
                    rise((t / rise_time).clamp(0.0, 1.0), *cosine)
                }
            }
            Shape::Step {
                at,
                rise_time,
                cosine,
            } => {
                if t < *at {
                    0.0
                } else if *rise_time > 0.0 {
                    rise(((t - at) / rise_time).min(1.0), *cosine)
                } else {
                    1.0
                }
            }
            Shape::Square {
                frequency,
                duty,
                bipolar,
            } => {
                let x = self.periodic_time(t, *frequency);
                bip(if x < *duty { 1.0 } else { 0.0 }, *bipolar)
            }
            Shape::Triangle { frequency, bipolar } => {
                let x = self.periodic_time(t, *frequency);
                bip(if x < 0.5 { 2.0 * x } else { 2.0 - 2.0 * x }, *bipolar)
            }
            Shape::Sine { frequency, bipolar } => {
                let x = self.periodic_time(t, *frequency);
                if *bipolar {
                    (2.0 * PI * x).sin()
                } else {
                    0.5 * (1.0 - (2.0 * PI * x).cos())
                }
            }
            Shape::Fourier {
                base,
                frequency,
                terms,
                bipolar,
            } => {
                let w = 2.0 * PI * self.periodic_time(t, *frequency);
                // bipolar = 2·unipolar − 1
                bip(fourier_series(base, *terms, w).0, *bipolar)
            }
            Shape::Table { points } => table_value(points, t),
        }
    }
}

/// The unipolar (0..1) Fourier series of `base` with `terms` odd harmonics (docs/lumped.md) at
/// w = 2πx, x the period's fraction, and its derivative in x: each term's value and slope
/// written side by side.
fn fourier_series(base: &FourierBase, terms: usize, w: f64) -> (f64, f64) {
    let (mut u, mut du) = (0.5, 0.0);
    for k in 0..terms {
        let n = (2 * k + 1) as f64;
        let (v, dv) = match base {
            FourierBase::Square => (2.0 / (n * PI) * (n * w).sin(), 4.0 * (n * w).cos()),
            FourierBase::Triangle => (
                -4.0 / (n * n * PI * PI) * (n * w).cos(),
                8.0 / (n * PI) * (n * w).sin(),
            ),
            // the unipolar sine (1 − cos ωt)/2 is its own one-term series
            FourierBase::Sine if k == 0 => (-0.5 * w.cos(), PI * w.sin()),
            FourierBase::Sine => (0.0, 0.0),
        };
        u += v;
        du += dv;
    }
    (u, du)
}

/// The piecewise-linear table through `points` (increasing in t) at `t`, held beyond its ends.
pub(crate) fn table_value(points: &[(f64, f64)], t: f64) -> f64 {
    match points {
        [] => 0.0,
        [only] => only.1,
        _ => {
            if t <= points[0].0 {
                return points[0].1;
            }
            let last = points[points.len() - 1];
            if t >= last.0 {
                return last.1;
            }
            let i = points.partition_point(|p| p.0 <= t);
            let (a, b) = (points[i - 1], points[i]);
            a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
        }
    }
}

#[cfg(test)]
mod tests {
    /// ∂value/∂frequency against central differences of the value (h = 10⁻⁶ of f, where the
    /// truncation error is below 10⁻⁸ of the scale), for every periodic shape without jumps,
    /// unipolar and bipolar, at times away from a triangle's corners; 0 for a shape without a
    /// frequency.
    #[test]
    fn derivative_in_frequency() {
        let mut shapes = Vec::new();
        for bipolar in [false, true] {
            shapes.push(Shape::Sine {
                frequency: 3.0,
                bipolar,
            });
            shapes.push(Shape::Triangle {
                frequency: 3.0,
                bipolar,
            });
            for base in [
                FourierBase::Square,
                FourierBase::Triangle,
                FourierBase::Sine,
            ] {
                shapes.push(Shape::Fourier {
                    base,
                    frequency: 3.0,
                    terms: 4,
                    bipolar,
                });
            }
        }
        for shape in shapes {
            let w = Waveform {
                shape,
                amplitude: 2e3,
                offset: 50.0,
                phase_deg: 20.0,
            };
            let at = |f: f64| {
                let mut m = w.clone();
                match &mut m.shape {
                    Shape::Sine { frequency, .. }
                    | Shape::Triangle { frequency, .. }
                    | Shape::Fourier { frequency, .. } => *frequency = f,
                    _ => unreachable!(),
                }
                m
            };
            for t in [0.011, 0.07, 0.23, 0.41, 0.95] {
                let h = 3e-6;
                let fd = (at(3.0 + h).value(t) - at(3.0 - h).value(t)) / (2.0 * h);
                let d = w.derivative(t, WaveformScalar::Frequency);
                assert!(d != 0.0, "{:?} at {t}", w.shape);
                assert!(
                    (fd - d).abs() <= 1e-6 * d.abs().max(w.amplitude * t),
                    "{:?} at {t}: {d} against {fd}",
                    w.shape
                );
            }
        }
        let step = Waveform::constant(2e3);
        assert_eq!(step.derivative(0.3, WaveformScalar::Frequency), 0.0);
    }

    /// ∂value/∂amplitude and ∂value/∂offset against differences of the value, for a periodic
    /// and a stepped signal.
    #[test]
    fn derivatives_in_amplitude_and_offset() {
        let square = Waveform {
            shape: Shape::Square {
                frequency: 2.0,
                duty: 0.5,
                bipolar: true,
            },
            amplitude: 3e3,
            offset: 100.0,
            phase_deg: 30.0,
        };
        let step = Waveform {
            shape: Shape::Step {
                at: 0.1,
                rise_time: 0.2,
                cosine: false,
            },
            ..Waveform::constant(2e3)
        };
        for w in [square, step] {
            for t in [0.0, 0.13, 0.2, 0.45, 0.9] {
                let d = [WaveformScalar::Amplitude, WaveformScalar::Offset]
                    .map(|which| w.derivative(t, which));
                let moved = |da: f64, db: f64| Waveform {
                    amplitude: w.amplitude + da,
                    offset: w.offset + db,
                    ..w.clone()
                };
                let fa = (moved(1.0, 0.0).value(t) - moved(-1.0, 0.0).value(t)) / 2.0;
                let fb = (moved(0.0, 1.0).value(t) - moved(0.0, -1.0).value(t)) / 2.0;
                assert!(
                    (fa - d[0]).abs() < 1e-9 && (fb - d[1]).abs() < 1e-9,
                    "{t}: {d:?}"
                );
            }
        }
    }

    use super::*;

    fn wave(shape: Shape) -> Waveform {
        Waveform {
            shape,
            amplitude: 3000.0,
            offset: 0.0,
            phase_deg: 0.0,
        }
    }

    #[test]
    fn shapes_take_their_defining_values() {
        let sq = wave(Shape::Square {
            frequency: 2.0,
            duty: 0.5,
            bipolar: false,
        });
        assert_eq!(sq.value(0.1), 3000.0);
        assert_eq!(sq.value(0.3), 0.0);
        assert_eq!(sq.value(0.6), 3000.0);
        let sqb = wave(Shape::Square {
            frequency: 2.0,
            duty: 0.5,
            bipolar: true,
        });
        assert_eq!(sqb.value(0.3), -3000.0);
        let tri = wave(Shape::Triangle {
            frequency: 1.0,
            bipolar: false,
        });
        assert!((tri.value(0.25) - 1500.0).abs() < 1e-9);
        assert!((tri.value(0.5) - 3000.0).abs() < 1e-9);
        assert!((tri.value(0.75) - 1500.0).abs() < 1e-9);
        let sine = wave(Shape::Sine {
            frequency: 1.0,
            bipolar: false,
        });
        assert!(sine.value(0.0).abs() < 1e-9);
        assert!((sine.value(0.5) - 3000.0).abs() < 1e-9);
        let ramp = wave(Shape::Ramp {
            rise_time: 2.0,
            cosine: false,
        });
        assert_eq!(ramp.value(1.0), 1500.0);
        assert_eq!(ramp.value(5.0), 3000.0);
        let step = wave(Shape::Step {
            at: 1.0,
            rise_time: 0.0,
            cosine: false,
        });
        assert_eq!(step.value(0.999), 0.0);
        assert_eq!(step.value(1.0), 3000.0);
        let table = wave(Shape::Table {
            points: vec![(0.0, 0.0), (1.0, 1.0), (3.0, 0.0)],
        });
        assert_eq!(table.value(2.0), 1500.0);
        assert_eq!(table.value(-1.0), 0.0);
        assert_eq!(table.value(9.0), 0.0);
        let mut shifted = wave(Shape::Square {
            frequency: 1.0,
            duty: 0.5,
            bipolar: false,
        });
        shifted.phase_deg = 180.0;
        assert_eq!(shifted.value(0.1), 0.0);
    }

    /// The truncated Fourier series converges to the exact unipolar wave (away from the jumps for
    /// the square wave): mean error falls as more terms are kept.
    #[test]
    fn fourier_series_converge_to_the_exact_waves() {
        for (base, exact) in [
            (
                FourierBase::Square,
                Shape::Square {
                    frequency: 1.0,
                    duty: 0.5,
                    bipolar: false,
                },
            ),
            (
                FourierBase::Triangle,
                Shape::Triangle {
                    frequency: 1.0,
                    bipolar: false,
                },
            ),
        ] {
            let ex = wave(exact);
            let err = |terms: usize| {
                let f = wave(Shape::Fourier {
                    base,
                    frequency: 1.0,
                    terms,
                    bipolar: false,
                });
                (0..1000)
                    .map(|i| (i as f64 + 0.5) / 1000.0)
                    .filter(|t| (t - 0.5).abs() > 0.05 && *t > 0.05 && *t < 0.95)
                    .map(|t| (f.value(t) - ex.value(t)).abs())
                    .fold(0.0, f64::max)
            };
            let (e3, e30) = (err(3), err(30));
            assert!(e30 < e3 / 3.0, "{base:?}: {e3} {e30}");
            assert!(e30 < 0.02 * 3000.0, "{base:?}: {e30}");
        }
    }
}
