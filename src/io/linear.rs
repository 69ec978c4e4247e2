//! Files of the small-signal analyses: the modes' table and shapes (`modes.csv`, `modes.pvd`,
//! `modes/mode_NN.vtu`) and the frequency response (`frequency_response.csv`, Bode plots).
//! Written by a run's `modes` and `frequency-response` stages and by the commands alike.

use crate::io::atomic::write_atomic;
use crate::io::plot::{stacked_plot, PlotSpec, Series};
use crate::io::vtu::{write_pvd, write_vtu, CellType, DataArray, VtuPiece};
use crate::job::linear::FrequencyResponse;
use crate::job::plan::Plan;
use crate::problem::dofs::{FIELDS, PHI};
use crate::time::modal::Mode;
use std::fmt::Write as _;
use std::path::Path;

/// `<stem>.csv` (mode, frequency, eigenvalue, residual), `<stem>.pvd` and `<stem>/mode_NN.vtu`
/// (the shapes scaled to a largest displacement of 1 on the deformed state `state`).
pub fn write_modes(
    plan: &Plan,
    dir: &Path,
    stem: &str,
    state: &[f64],
    found: &[Mode],
) -> Result<(), String> {
    let shapes_dir = dir.join(stem);
    std::fs::create_dir_all(&shapes_dir).map_err(|e| format!("{}: {e}", shapes_dir.display()))?;
    let mut csv = String::from("mode,frequency_hz,eigenvalue_rad2_per_s2,residual\n");
    for (i, m) in found.iter().enumerate() {
        let _ = writeln!(
            csv,
            "{},{},{},{:e}",
            i + 1,
            m.frequency,
            m.eigenvalue,
            m.residual
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
    let mut entries = Vec::new();
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
        let piece = VtuPiece {
            points: &mesh.nodes,
            cell_type,
            connectivity: &mesh.connectivity,
            point_data: vec![
                DataArray {
                    name: "displacement",
                    components: 3,
                    values: &disp,
                },
                DataArray {
                    name: "mode_shape",
                    components: 3,
                    values: &shape,
                },
                DataArray {
                    name: "mode_potential",
                    components: 1,
                    values: &phi,
                },
            ],
            cell_data: Vec::new(),
        };
        write_vtu(&shapes_dir.join(&name), &piece).map_err(|e| e.to_string())?;
        entries.push((m.frequency, format!("{stem}/{name}")));
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

/// `<stem>.csv` in `dir` and a Bode plot per probe, `bode_<probe>.<ext>` in `plots`.
pub fn write_response(
    r: &FrequencyResponse,
    dir: &Path,
    stem: &str,
    plots: Option<(&Path, &str)>,
) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let path = dir.join(format!("{stem}.csv"));
    write_atomic(&path, response_csv(r).as_bytes())
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let Some((plots, ext)) = plots else {
        return Ok(());
    };
    std::fs::create_dir_all(plots).map_err(|e| format!("{}: {e}", plots.display()))?;
    for (name, values) in &r.probes {
        let mag = Series {
            label: name.clone(),
            x: r.frequencies.iter().map(|f| f.log10()).collect(),
            y: values
                .iter()
                .map(|(re, im)| re.hypot(*im).max(f64::MIN_POSITIVE).log10())
                .collect(),
        };
        // the phase unwrapped (continuous across ±180°) for the plot
        let mut unwrapped: Vec<f64> = Vec::with_capacity(values.len());
        for (re, im) in values {
            let mut ph = im.atan2(*re).to_degrees();
            if let Some(&last) = unwrapped.last() {
                ph += 360.0 * ((last - ph) / 360.0).round();
            }
            unwrapped.push(ph);
        }
        let phase = Series {
            label: name.clone(),
            x: mag.x.clone(),
            y: unwrapped,
        };
        let suffix = stem.strip_prefix("frequency_response").unwrap_or(stem);
        let path = plots.join(format!("bode_{name}{suffix}.{ext}"));
        stacked_plot(
            &path,
            &[
                PlotSpec {
                    title: &format!("{name}: per volt on {} about {:.0} V", r.electrode, r.bias),
                    x_label: "log10(frequency / Hz)",
                    y_label: "log10(|response| per volt)",
                    series: std::slice::from_ref(&mag),
                },
                PlotSpec {
                    title: "",
                    x_label: "log10(frequency / Hz)",
                    y_label: "phase [deg]",
                    series: std::slice::from_ref(&phase),
                },
            ],
        )
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}
