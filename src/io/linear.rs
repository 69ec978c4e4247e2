//! Files of the small-signal analyses: the modes' table and shapes (`modes.csv`, `modes.pvd`,
//! `modes/mode_NN.vtu`) and the frequency response (`frequency_response.csv`, Bode plots).
//! Written by a run's `modes` and `frequency-response` stages and by the commands alike.

use crate::io::atomic::write_atomic;
use crate::io::plot::{stacked_plot_scaled, PlotSpec, Scale, Series};
use crate::io::revolve::{Components, RevolvedMesh};
use crate::io::vtu::{write_pvd, write_vtu_as, CellType, Encoding, VtuPiece};
use crate::job::plan::Plan;
use crate::job::state::FrequencyResponse;
use crate::problem::dofs::{FIELDS, PHI};
use crate::time::modal::Mode;
use std::fmt::Write as _;
use std::path::Path;

/// `<stem>.csv` (mode, frequency, eigenvalue, residual, circumferential harmonic), `<stem>.pvd` and `<stem>/mode_NN.vtu`
/// (the shapes scaled to a largest displacement of 1 on the deformed state `state`), encoded as
/// the field files (`output.vtu_format`).
pub fn write_modes(
    plan: &Plan,
    dir: &Path,
    stem: &str,
    state: &[f64],
    found: &[Mode],
) -> Result<(), String> {
    let shapes_dir = dir.join(stem);
    std::fs::create_dir_all(&shapes_dir).map_err(|e| format!("{}: {e}", shapes_dir.display()))?;
    let mut csv = String::from("mode,frequency_hz,eigenvalue_rad2_per_s2,residual,harmonic\n");
    for (i, m) in found.iter().enumerate() {
        let _ = writeln!(
            csv,
            "{},{},{},{:e},{}",
            i + 1,
            m.frequency,
            m.eigenvalue,
            m.residual,
            m.harmonic
        );
    }
    let path = dir.join(format!("{stem}.csv"));
    write_atomic(&path, csv.as_bytes()).map_err(|e| format!("{}: {e}", path.display()))?;
    let mesh = &plan.model.mesh;
    let n = mesh.n_nodes();
    let disp: Vec<f64> = (0..n)
        .flat_map(|a| state[a * FIELDS..a * FIELDS + 3].to_vec())
        .collect();
    let cell_type = CellType::from(mesh.kind);
    let encoding = Encoding::from(plan.output.fields_format);
    let revolved = plan.output.revolve.and_then(|r| RevolvedMesh::new(mesh, r));
    let revolved_disp = revolved
        .as_ref()
        .map(|r| r.point_array(Components::Vector, &disp));
    let mut entries = Vec::new();
    let mut revolved_entries = Vec::new();
    for (i, m) in found.iter().enumerate() {
        let largest = (0..n)
            .map(|a| {
                (0..3)
                    .map(|c| m.shape[a * FIELDS + c].powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        let shape: Vec<f64> = (0..n)
            .flat_map(|a| (0..3).map(move |c| (a, c)))
            .map(|(a, c)| m.shape[a * FIELDS + c] / largest)
            .collect();
        let phi: Vec<f64> = (0..n)
            .map(|a| m.shape[a * FIELDS + PHI] / largest)
            .collect();
        let name = format!("mode_{:02}.vtu", i + 1);
        let piece = VtuPiece::fields(
            &mesh.nodes,
            cell_type,
            &mesh.connectivity,
            &[
                ("displacement", 3, &disp),
                ("mode_shape", 3, &shape),
                ("mode_potential", 1, &phi),
            ],
            &[],
        );
        write_vtu_as(&shapes_dir.join(&name), &piece, encoding).map_err(|e| e.to_string())?;
        entries.push((m.frequency, format!("{stem}/{name}")));
        // the revolved view: the shape with its pattern cos nΘ (sin nΘ for u_θ) around the axis
        if let (Some(r), Some(rdisp)) = (&revolved, &revolved_disp) {
            let shape = r.harmonic_point_array(Components::Vector, &shape, m.harmonic);
            let phi = r.harmonic_point_array(Components::Scalar, &phi, m.harmonic);
            let name = format!("mode_{:02}_revolved.vtu", i + 1);
            let piece = VtuPiece::fields(
                &r.points,
                r.cell_type,
                &r.connectivity,
                &[
                    ("displacement", 3, rdisp),
                    ("mode_shape", 3, &shape),
                    ("mode_potential", 1, &phi),
                ],
                &[],
            );
            write_vtu_as(&shapes_dir.join(&name), &piece, encoding).map_err(|e| e.to_string())?;
            revolved_entries.push((m.frequency, format!("{stem}/{name}")));
        }
    }
    if !revolved_entries.is_empty() {
        write_pvd(&dir.join(format!("{stem}_revolved.pvd")), &revolved_entries)
            .map_err(|e| e.to_string())?;
    }
    write_pvd(&dir.join(format!("{stem}.pvd")), &entries).map_err(|e| e.to_string())
}

/// The response as CSV: `frequency_hz`, then per probe `<probe>:magnitude` (probe unit per
/// volt), `<probe>:phase_deg`, `<probe>:real`, `<probe>:imag`.
pub fn response_csv(r: &FrequencyResponse) -> String {
    let mut csv = String::from("frequency_hz");
    for (n, _) in &r.probes {
        let _ = write!(csv, ",{n}:magnitude,{n}:phase_deg,{n}:real,{n}:imag");
    }
    csv.push('\n');
    for (i, f) in r.frequencies.iter().enumerate() {
        let _ = write!(csv, "{f:e}");
        for (_, values) in &r.probes {
            let (re, im) = values[i];
            let _ = write!(
                csv,
                ",{:e},{:e},{re:e},{im:e}",
                re.hypot(im),
                im.atan2(re).to_degrees()
            );
        }
        csv.push('\n');
    }
    csv
}

/// The unit of a probe's response per volt: `m` → `m/V`, a voltage's → `-`, a field's → `1/m`,
/// a dimensionless probe's → `1/V`.
pub fn per_volt(unit: &str) -> String {
    match unit {
        "" | "-" => "1/V".into(),
        "V" => "-".into(),
        "V/m" => "1/m".into(),
        u => format!("{u}/V"),
    }
}

/// `<stem>.csv` in `dir` and a Bode plot per probe, `bode_<probe>.<ext>` in `plots`: the
/// magnitude per volt in the probe's unit per volt (`unit` gives a probe's unit by name) on a
/// logarithmic axis above the unwrapped phase, against the frequency on a logarithmic axis in Hz.
/// A probe without a finite response (a capacitance about 0 V) gets no plot: returns, for the
/// caller to report, why each such plot was left out.
pub fn write_response(
    r: &FrequencyResponse,
    dir: &Path,
    stem: &str,
    plots: Option<(&Path, &str)>,
    unit: &dyn Fn(&str) -> String,
) -> Result<Vec<String>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let path = dir.join(format!("{stem}.csv"));
    write_atomic(&path, response_csv(r).as_bytes())
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut skipped = Vec::new();
    let Some((plots, ext)) = plots else {
        return Ok(skipped);
    };
    std::fs::create_dir_all(plots).map_err(|e| format!("{}: {e}", plots.display()))?;
    for (name, values) in &r.probes {
        let suffix = stem.strip_prefix("frequency_response").unwrap_or(stem);
        let path = plots.join(format!("bode_{name}{suffix}.{ext}"));
        let magnitude: Vec<f64> = values.iter().map(|(re, im)| re.hypot(*im)).collect();
        if !magnitude.iter().any(|m| m.is_finite()) {
            skipped.push(format!(
                "{}: not drawn: the response of `{name}` has no finite value (e.g. a \
                 capacitance about 0 V); see {}",
                path.display(),
                dir.join(format!("{stem}.csv")).display()
            ));
            continue;
        }
        let magnitude_positive = magnitude.iter().any(|m| m.is_finite() && *m > 0.0);
        let mag = Series {
            label: name.clone(),
            x: r.frequencies.clone(),
            y: magnitude,
        };
        // the phase unwrapped (continuous across ±180°) for the plot
        let mut unwrapped: Vec<f64> = Vec::with_capacity(values.len());
        for (re, im) in values {
            let mut ph = im.atan2(*re).to_degrees();
            if let Some(&last) = unwrapped.iter().rev().find(|p| p.is_finite()) {
                ph += 360.0 * ((last - ph) / 360.0).round();
            }
            unwrapped.push(ph);
        }
        let phase = Series {
            label: name.clone(),
            x: mag.x.clone(),
            y: unwrapped,
        };
        let gain = format!("|{name}| per volt [{}]", per_volt(&unit(name)));
        stacked_plot_scaled(
            &path,
            &[
                PlotSpec {
                    title: &format!("{name}: per volt on {} about {:.0} V", r.electrode, r.bias),
                    x_label: "frequency [Hz]",
                    y_label: &gain,
                    series: std::slice::from_ref(&mag),
                },
                PlotSpec {
                    title: "",
                    x_label: "frequency [Hz]",
                    y_label: "phase [deg]",
                    series: std::slice::from_ref(&phase),
                },
            ],
            Scale::Log,
            // a response that is zero throughout (a deflection about 0 V) on a linear axis
            &[
                if magnitude_positive {
                    Scale::Log
                } else {
                    Scale::Linear
                },
                Scale::Linear,
            ],
        )
        .map_err(|e| e.to_string())?;
    }
    Ok(skipped)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::job::plan::ResponseMethod;

    /// The Bode plot is drawn in the probe's unit per volt with its metric prefix against a
    /// logarithmic frequency axis in Hz; a probe without a finite response (a capacitance about
    /// 0 V) is left out and reported, and the other plots are drawn.
    #[test]
    fn bode_plots_carry_units_and_skip_probes_without_a_response() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-bode-")
            .tempdir()
            .unwrap();
        let dir = tmp.path().join("out");
        let frequencies: Vec<f64> = (0..30).map(|i| 10f64.powf(i as f64 / 10.0)).collect();
        let n = frequencies.len();
        let r = FrequencyResponse {
            electrode: "top".into(),
            bias: 0.0,
            frequencies,
            probes: vec![
                ("center_deflection".into(), vec![(2e-6, -1e-7); n]),
                ("capacitance".into(), vec![(f64::NAN, f64::NAN); n]),
                ("zero".into(), vec![(0.0, 0.0); n]),
            ],
            method: ResponseMethod::Direct,
            solved_by: String::new(),
            warning: None,
        };
        let unit = |name: &str| if name == "capacitance" { "F" } else { "m" }.to_string();
        let skipped = write_response(&r, &dir, "frequency_response", Some((&dir, "svg")), &unit)
            .expect("the other plots are drawn");
        assert_eq!(skipped.len(), 1, "{skipped:?}");
        assert!(skipped[0].contains("bode_capacitance.svg"), "{skipped:?}");
        assert!(!dir.join("bode_capacitance.svg").exists());
        let svg = std::fs::read_to_string(dir.join("bode_center_deflection.svg")).unwrap();
        for text in [
            "frequency [Hz]",
            "|center_deflection| per volt [µm/V]",
            "\n100\n",
        ] {
            assert!(svg.contains(text), "the Bode plot lacks {text:?}");
        }
        assert!(!svg.contains("log10"));
        // a response that is zero throughout is drawn on a linear axis
        assert!(dir.join("bode_zero.svg").exists());
        assert_eq!(per_volt("V/m"), "1/m");
        assert_eq!(per_volt("-"), "1/V");
    }
}
