//! `[electrodes.<name>]`: the electrode node sets and their voltage waveforms.

use super::{Ctx, Electrode};
use crate::io::scenario::{closest, InputError, Scenario, VoltageSpec, WaveformSpec};
use crate::job::plan::Stage;
use crate::mesh::Mesh;
use crate::problem::dofs::{Dirichlet, Field};
use crate::waveform::{FourierBase, Shape, Waveform};
use std::path::Path;

/// The waveforms by scenario name.
const WAVEFORMS: [&str; 8] = [
    "constant", "ramp", "step", "square", "triangle", "sine", "fourier", "table",
];

/// The electrodes in name order; no two may share a node. `base_dir` is where the CSV files of
/// `table` waveforms are.
pub(super) fn build_electrodes(
    ctx: &Ctx,
    s: &Scenario,
    mesh: &Mesh,
    base_dir: Option<&Path>,
) -> Result<Vec<Electrode>, InputError> {
    let mut electrodes = Vec::new();
    for (name, e) in &s.electrodes {
        let key = format!("electrodes.{name}");
        let nodes = ctx.set_nodes(mesh, &format!("{key}.set"), &e.set)?;
        let mut voltage = build_waveform(ctx, &format!("{key}.voltage"), &e.voltage, base_dir)?;
        let mut resistance = None;
        if let Some(c) = &e.circuit {
            if e.voltage != VoltageSpec::default() || e.charge.is_some() {
                return Err(ctx.err(
                    format!("{key}.circuit"),
                    "an electrode is held at a `voltage`, carries a `charge` or is driven through a \
                     `circuit`: one of the three",
                ));
            }
            voltage = build_waveform(ctx, &format!("{key}.circuit.source"), &c.source, base_dir)?;
            resistance = Some(ctx.positive(
                &format!("{key}.circuit.resistance"),
                Some(c.resistance),
                "series resistance in Ω",
            )?);
        }
        let charge = match &e.charge {
            None => None,
            Some(_) if e.voltage != VoltageSpec::default() => {
                return Err(ctx.err(
                    format!("{key}.charge"),
                    "an electrode is held at a `voltage` or carries a `charge`, not both",
                ))
            }
            Some(q) => Some(build_waveform_of(
                ctx,
                &format!("{key}.charge"),
                q,
                base_dir,
                ("charge", "C"),
            )?),
        };
        electrodes.push(Electrode {
            name: name.clone(),
            nodes,
            voltage,
            charge,
            charge_in_drive: false,
            resistance,
            controller: None,
        });
    }
    for (i, a) in electrodes.iter().enumerate() {
        for b in &electrodes[i + 1..] {
            if a.nodes.iter().any(|n| b.nodes.binary_search(n).is_ok()) {
                return Err(ctx.err(
                    format!("electrodes.{}.set", b.name),
                    format!(
                        "electrodes `{}` and `{}` share nodes: they would short-circuit",
                        a.name, b.name
                    ),
                ));
            }
        }
    }
    if !electrodes.is_empty()
        && electrodes
            .iter()
            .all(|e| e.charge.is_some() || e.resistance.is_some())
    {
        return Err(ctx.err(
            "electrodes",
            "charge-controlled and circuit-driven electrodes need a voltage-controlled one (e.g. \
             grounded, `voltage = 0`) as the reference of the potential",
        ));
    }
    Ok(electrodes)
}

/// Charge-controlled electrodes: each one's potential is one unknown (a tie of its nodes'
/// potentials) loaded by minus its charge (the potential equations' residual is ∂Π/∂Φ + Q), the
/// charge of the meshed part (the device's over the symmetry factor). A constant charge that no
/// stage controls is a dead load of the model; the others follow each stage's drive
/// (`charge_in_drive`).
pub(super) fn charge_electrodes(
    electrodes: &mut [Electrode],
    stages: &[Stage],
    model: &mut crate::problem::model::Model,
    symmetry: f64,
) {
    for e in electrodes.iter_mut() {
        if let Some(w) = &e.charge {
            model.ties.push(crate::problem::dofs::Tie {
                nodes: e.nodes.clone(),
                field: Field::Phi,
                held: false,
            });
            let controlled = stages
                .iter()
                .any(|s| s.controls.iter().any(|(name, _)| *name == e.name));
            match w.constant_value() {
                Some(q) if !controlled => model.point_charges.push((e.nodes[0], q / symmetry)),
                _ => e.charge_in_drive = true,
            }
        }
        if let Some(r) = e.resistance {
            // one potential unknown; static stages hold it at the source's voltage
            model.ties.push(crate::problem::dofs::Tie {
                nodes: e.nodes.clone(),
                field: Field::Phi,
                held: false,
            });
            // the meshed part draws 1/symmetry of the current through the same voltage drop
            model.circuits.push(crate::problem::circuit::Circuit {
                nodes: e.nodes.clone(),
                resistance: r * symmetry,
            });
        }
    }
}

/// Without electrodes (a purely mechanical problem) the potential would be defined only up to a
/// constant (a singular tangent): it is held at 0 everywhere.
pub(super) fn ground_without_electrodes(
    electrodes: &[Electrode],
    mesh: &Mesh,
) -> Option<Dirichlet> {
    electrodes.is_empty().then(|| Dirichlet {
        nodes: (0..mesh.n_nodes()).collect(),
        field: Field::Phi,
        value: 0.0,
    })
}

/// The voltage of an electrode at `key`: a number (V) or a waveform table.
pub(super) fn build_waveform(
    ctx: &Ctx,
    key: &str,
    v: &VoltageSpec,
    base_dir: Option<&Path>,
) -> Result<Waveform, InputError> {
    build_waveform_of(ctx, key, v, base_dir, ("voltage", "V"))
}

/// [`build_waveform`] of a quantity (name, unit) other than a voltage: an electrode's charge.
fn build_waveform_of(
    ctx: &Ctx,
    key: &str,
    v: &VoltageSpec,
    base_dir: Option<&Path>,
    (quantity, unit): (&str, &str),
) -> Result<Waveform, InputError> {
    let w: &WaveformSpec = match v {
        VoltageSpec::Constant(x) => {
            let what = format!("{quantity} in {unit}");
            return Ok(Waveform::constant(ctx.finite(key, *x, &what)?));
        }
        VoltageSpec::Waveform(w) => w,
    };
    let k = |s: &str| format!("{key}.{s}");
    ctx.finite(
        &k("amplitude"),
        w.amplitude,
        &format!("amplitude in {unit}"),
    )?;
    ctx.finite(&k("offset"), w.offset, &format!("offset in {unit}"))?;
    ctx.finite(&k("phase"), w.phase, "phase in degrees")?;
    let bipolar = match w.polarity.as_deref() {
        None | Some("unipolar") => false,
        Some("bipolar") => true,
        Some(o) => {
            return Err(ctx.err(
                k("polarity"),
                format!("expected `unipolar` or `bipolar`; got `{o}`"),
            ))
        }
    };
    if w.waveform == "table" {
        return build_table(ctx, key, w, base_dir);
    }
    Ok(Waveform {
        shape: build_shape(ctx, key, w, bipolar)?,
        amplitude: w.amplitude,
        offset: w.offset,
        phase_deg: w.phase,
    })
}

/// The shape of every waveform but `table`.
fn build_shape(ctx: &Ctx, key: &str, w: &WaveformSpec, bipolar: bool) -> Result<Shape, InputError> {
    let k = |s: &str| format!("{key}.{s}");
    let freq = || ctx.positive(&k("frequency"), w.frequency, "frequency in Hz");
    let rise_time = || {
        w.rise_time
            .map(|r| ctx.positive(&k("rise_time"), Some(r), "rise time in s"))
            .transpose()
            .map(|r| r.unwrap_or(0.0))
    };
    let cosine = match w.rise.as_deref() {
        None | Some("linear") => false,
        Some("cosine") if matches!(w.waveform.as_str(), "ramp" | "step") => true,
        Some("cosine") => {
            return Err(ctx.err(
                k("rise"),
                format!("`rise` shapes a `ramp` or `step`, not a `{}`", w.waveform),
            ))
        }
        Some(other) => {
            return Err(ctx.err(
                k("rise"),
                format!("expected \"linear\" or \"cosine\"; got \"{other}\""),
            ))
        }
    };
    Ok(match w.waveform.as_str() {
        "constant" => Shape::Constant,
        "ramp" => Shape::Ramp {
            rise_time: rise_time()?,
            cosine,
        },
        "step" => Shape::Step {
            at: ctx.finite(&k("at"), w.at.unwrap_or(0.0), "time in s")?,
            rise_time: rise_time()?,
            cosine,
        },
        "square" => {
            let duty = w.duty.unwrap_or(0.5);
            if !(duty > 0.0 && duty < 1.0) {
                return Err(ctx.err(
                    k("duty"),
                    format!(
                        "must lie strictly between 0 and 1; got {}",
                        crate::units::Short(duty)
                    ),
                ));
            }
            Shape::Square {
                frequency: freq()?,
                duty,
                bipolar,
            }
        }
        "triangle" => Shape::Triangle {
            frequency: freq()?,
            bipolar,
        },
        "sine" => Shape::Sine {
            frequency: freq()?,
            bipolar,
        },
        "fourier" => build_fourier(ctx, key, w, bipolar)?,
        other => {
            let hint = closest(other, WAVEFORMS)
                .map(|c| format!("; did you mean `{c}`?"))
                .unwrap_or_default();
            return Err(ctx.err(
                k("waveform"),
                format!(
                    "unknown waveform `{other}` (known: {}){hint}",
                    WAVEFORMS.join(", ")
                ),
            ));
        }
    })
}

/// `waveform = "fourier"`: `terms` terms of the series of `base`.
fn build_fourier(
    ctx: &Ctx,
    key: &str,
    w: &WaveformSpec,
    bipolar: bool,
) -> Result<Shape, InputError> {
    let k = |s: &str| format!("{key}.{s}");
    let base = match w.base.as_deref() {
        Some("square") => FourierBase::Square,
        Some("triangle") => FourierBase::Triangle,
        Some("sine") => FourierBase::Sine,
        Some(o) => {
            return Err(ctx.err(
                k("base"),
                format!("expected `square`, `triangle` or `sine`; got `{o}`"),
            ))
        }
        None => {
            return Err(ctx.err(
                k("base"),
                "missing: a `fourier` waveform needs `base` = `square`, `triangle` or `sine`",
            ))
        }
    };
    let terms = w.terms.unwrap_or(5);
    if !(1..=10_000).contains(&terms) {
        return Err(ctx.err(
            k("terms"),
            format!("must be between 1 and 10000; got {terms}"),
        ));
    }
    Ok(Shape::Fourier {
        base,
        frequency: ctx.positive(&k("frequency"), w.frequency, "frequency in Hz")?,
        terms: terms as usize,
        bipolar,
    })
}

/// `waveform = "table"`: `time,value` rows of a CSV file (relative to `base_dir`), in volts.
fn build_table(
    ctx: &Ctx,
    key: &str,
    w: &WaveformSpec,
    base_dir: Option<&Path>,
) -> Result<Waveform, InputError> {
    let k = |s: &str| format!("{key}.{s}");
    let file = w
        .file
        .as_deref()
        .ok_or_else(|| ctx.err(k("file"), "missing: a CSV file of `time,value` rows"))?;
    let path = base_dir
        .map(|d| d.join(file))
        .unwrap_or_else(|| file.into());
    let text = std::fs::read_to_string(&path)
        .map_err(|e| ctx.err(k("file"), format!("cannot read `{}`: {e}", path.display())))?;
    let points = table_points(&text)
        .map_err(|line| {
            format!(
                "{}:{line}: expected `time,value` with two finite numbers",
                path.display()
            )
        })
        .map_err(|msg| ctx.err(k("file"), msg))?;
    if points.is_empty() || points.windows(2).any(|p| p[1].0 <= p[0].0) {
        return Err(ctx.err(
            k("file"),
            format!(
                "{}: expected at least one row and strictly increasing times",
                path.display()
            ),
        ));
    }
    // the table holds volts: amplitude scales it (1 by default when not given)
    Ok(Waveform {
        shape: Shape::Table { points },
        amplitude: if w.amplitude == 0.0 { 1.0 } else { w.amplitude },
        offset: w.offset,
        phase_deg: 0.0,
    })
}

/// The (time, value) rows of a CSV text, skipping blank lines, `#` comments and a header on the
/// first line; `Err` holds the 1-based number of a malformed line.
fn table_points(text: &str) -> Result<Vec<(f64, f64)>, usize> {
    let mut points = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut parts = line.split(',').map(|p| p.trim().parse::<f64>());
        match (parts.next(), parts.next(), parts.next()) {
            (Some(Ok(t)), Some(Ok(v)), None) if t.is_finite() && v.is_finite() => {
                points.push((t, v))
            }
            _ if i == 0 => {} // header
            _ => return Err(i + 1),
        }
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::super::testing::{assert_names, assert_rejected, plan, scenario, CTX};
    use super::*;

    /// The electrodes of a scenario whose `top` electrode has `voltage`.
    fn top(voltage: &str) -> String {
        format!(
            "[electrodes.top]\nset = \"z1\"\nvoltage = {voltage}\n\
             [electrodes.bottom]\nset = \"z0\"\nvoltage = 0.0"
        )
    }

    /// The electrodes built with a base directory.
    fn electrodes(voltage: &str, base_dir: &Path) -> Result<Vec<Electrode>, InputError> {
        let p = plan(&[]);
        let s = scenario(&[("electrodes", &top(voltage))]);
        build_electrodes(&CTX, &s, &p.model.mesh, Some(base_dir))
    }

    /// A fresh directory for the CSV files of one test, removed when it is dropped.
    fn dir(test: &str) -> tempfile::TempDir {
        tempfile::Builder::new()
            .prefix(&format!("deasim-build-{test}-"))
            .tempdir()
            .unwrap()
    }

    #[test]
    fn electrodes_with_their_nodes_and_constant_voltages() {
        let p = plan(&[]);
        // name order: bottom, top
        let names: Vec<&str> = p.electrodes.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["bottom", "top"]);
        assert_eq!(p.electrodes[1].nodes.len(), 9);
        assert_eq!(p.electrodes[1].voltage.value(0.3), 1000.0);
        assert_eq!(p.electrodes[0].voltage.value(0.3), 0.0);
    }

    #[test]
    fn periodic_waveforms_take_their_values() {
        let p = plan(&[(
            "electrodes",
            &top("{ waveform = \"square\", amplitude = 100.0, frequency = 2.0, duty = 0.25 }"),
        )]);
        let v = &p.electrodes[1].voltage;
        assert_eq!(v.frequency(), Some(2.0));
        assert_eq!((v.value(0.1), v.value(0.2)), (100.0, 0.0));
        let p = plan(&[(
            "electrodes",
            &top("{ waveform = \"sine\", amplitude = 10.0, frequency = 1.0, \
                  polarity = \"bipolar\", offset = 5.0 }"),
        )]);
        assert!((p.electrodes[1].voltage.value(0.25) - 15.0).abs() < 1e-12);
        let p = plan(&[(
            "electrodes",
            &top(
                "{ waveform = \"fourier\", base = \"triangle\", amplitude = 10.0, \
                  frequency = 1.0, terms = 3 }",
            ),
        )]);
        assert!(matches!(
            p.electrodes[1].voltage.shape,
            Shape::Fourier {
                base: FourierBase::Triangle,
                terms: 3,
                bipolar: false,
                ..
            }
        ));
    }

    #[test]
    fn ramps_steps_and_tables() {
        let p = plan(&[(
            "electrodes",
            &top("{ waveform = \"step\", amplitude = 50.0, at = 0.5, rise_time = 0.1 }"),
        )]);
        let v = &p.electrodes[1].voltage;
        assert_eq!((v.value(0.4), v.value(0.7)), (0.0, 50.0));
        assert!((v.value(0.55) - 25.0).abs() < 1e-9, "{}", v.value(0.55));
        let p = plan(&[(
            "electrodes",
            &top("{ waveform = \"ramp\", amplitude = 40.0, rise_time = 2.0 }"),
        )]);
        assert_eq!(p.electrodes[1].voltage.value(0.5), 10.0);
        let tmp = dir("table");
        let d = tmp.path().to_path_buf();
        std::fs::write(
            d.join("v.csv"),
            "time,value\n# volts\n0, 0\n1, 100\n\n2, 50\n",
        )
        .unwrap();
        let e = electrodes("{ waveform = \"table\", file = \"v.csv\" }", &d).unwrap();
        assert_eq!(e[1].voltage.amplitude, 1.0);
        assert_eq!(
            (e[1].voltage.value(0.5), e[1].voltage.value(1.5)),
            (50.0, 75.0)
        );
        let e = electrodes(
            "{ waveform = \"table\", file = \"v.csv\", amplitude = 2.0 }",
            &d,
        );
        assert_eq!(e.unwrap()[1].voltage.value(1.0), 200.0);
    }

    #[test]
    fn unknown_sets_and_shared_nodes_are_rejected() {
        assert_rejected(
            &[(
                "electrodes",
                "[electrodes.top]\nset = \"top\"\nvoltage = 1.0",
            )],
            "electrodes.top.set",
            "unknown set `top` (the mesh has: all,",
        );
        assert_rejected(
            &[(
                "electrodes",
                "[electrodes.a]\nset = \"z1\"\nvoltage = 1.0\n\
                 [electrodes.b]\nset = \"x1\"\nvoltage = 0.0",
            )],
            "electrodes.b.set",
            "electrodes `a` and `b` share nodes: they would short-circuit",
        );
        assert_rejected(
            &[("electrodes", &top("nan"))],
            "electrodes.top.voltage",
            "must be a finite number (voltage in V); got NaN",
        );
    }

    #[test]
    fn bad_waveforms_are_rejected() {
        let cases = [
            (
                "{ waveform = \"sinus\", amplitude = 1.0 }",
                "waveform",
                "unknown waveform `sinus` (known: constant, ramp,",
            ),
            (
                "{ waveform = \"square\", amplitude = 1.0 }",
                "frequency",
                "missing: expected frequency in Hz (a positive number)",
            ),
            (
                "{ waveform = \"square\", amplitude = 1.0, frequency = 1.0, duty = 1.0 }",
                "duty",
                "must lie strictly between 0 and 1; got 1",
            ),
            (
                "{ waveform = \"sine\", amplitude = 1.0, frequency = 1.0, polarity = \"both\" }",
                "polarity",
                "expected `unipolar` or `bipolar`; got `both`",
            ),
            (
                "{ waveform = \"fourier\", amplitude = 1.0, frequency = 1.0 }",
                "base",
                "missing: a `fourier` waveform needs `base` = `square`, `triangle` or `sine`",
            ),
            (
                "{ waveform = \"fourier\", base = \"saw\", amplitude = 1.0, frequency = 1.0 }",
                "base",
                "expected `square`, `triangle` or `sine`; got `saw`",
            ),
            (
                "{ waveform = \"fourier\", base = \"sine\", amplitude = 1.0, terms = 0 }",
                "terms",
                "must be between 1 and 10000; got 0",
            ),
            (
                "{ waveform = \"ramp\", amplitude = 1.0, rise_time = -1.0 }",
                "rise_time",
                "must be a positive finite number (rise time in s); got -1",
            ),
            (
                "{ waveform = \"ramp\", amplitude = inf }",
                "amplitude",
                "must be a finite number (amplitude in V); got inf",
            ),
        ];
        for (voltage, key, expected) in cases {
            let key = format!("electrodes.top.voltage.{key}");
            assert_rejected(&[("electrodes", &top(voltage))], &key, expected);
        }
    }

    #[test]
    fn bad_tables_are_rejected() {
        let tmp = dir("bad-tables");
        let d = tmp.path().to_path_buf();
        std::fs::write(d.join("bad.csv"), "time,value\n0, 0\n1, x\n").unwrap();
        std::fs::write(d.join("back.csv"), "0, 0\n1, 1\n1, 2\n").unwrap();
        let key = "electrodes.top.voltage.file";
        let e = electrodes("{ waveform = \"table\" }", &d).unwrap_err();
        assert_names(&e, key, "missing: a CSV file of `time,value` rows");
        let e = electrodes("{ waveform = \"table\", file = \"none.csv\" }", &d).unwrap_err();
        assert_names(&e, key, "cannot read `");
        let e = electrodes("{ waveform = \"table\", file = \"bad.csv\" }", &d).unwrap_err();
        assert_names(
            &e,
            key,
            "bad.csv:3: expected `time,value` with two finite numbers",
        );
        let e = electrodes("{ waveform = \"table\", file = \"back.csv\" }", &d).unwrap_err();
        assert_names(
            &e,
            key,
            "back.csv: expected at least one row and strictly increasing",
        );
    }
}
