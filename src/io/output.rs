//! The output directory of a run: `history.csv`, `summary.json`, `fields.pvd` +
//! `fields/step_*.vtu` (on several MPI ranks `fields/step_*.pvtu` over one piece per rank,
//! `fields/step_*_pRRRR.vtu`; for an axisymmetric model also the revolved view, `fields_revolved.pvd` +
//! `fields/revolved_*.vtu`), `plots/`. Every file is written to a temporary name and renamed, so
//! an interrupted run leaves valid files. Only converged steps reach the writer.

use super::atomic::write_atomic;
use super::build::Plan;
use super::linear::{write_modes, write_response};
use super::pieces::Pieces;
use super::plot::{stacked_plot, PlotError, PlotSpec, Series};
use super::revolve::{Components, RevolvedMesh};
use super::vtu::{
    write_pvd, write_pvtu, write_vtu_as, CellType, DataArray, Encoding, Field, VtuError, VtuPiece,
};
use crate::element::CellFields;
use crate::job::observer::Observer;
use crate::job::run::{InstabilityRecord, LimitRecord, PathRecord, StepRecord};
use crate::job::state::FrequencyResponse;
use crate::job::state::RunSummary;
use crate::time::modal::Mode;
use rayon::prelude::*;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The fixed leading columns of `history.csv`.
pub const HISTORY_COLUMNS: &[&str] = &[
    "time",
    "stage",
    "step",
    "voltage",
    "newton_iterations",
    "kinetic",
    "stored",
    "electric",
    "gravity",
    "dissipated",
    "energy_error",
];

/// Seconds between the rewrites of `history.csv`, `electrodes.csv` and the running
/// `summary.json` during a run ...
const FLUSH_EVERY_S: f64 = 2.0;

/// ... or this many times what the last rewrite took, if that is longer: each rewrite writes
/// every row so far, so a long run (10⁵ steps) would otherwise spend a growing share of its
/// time rewriting; this keeps that share under 5 %.
const FLUSH_COST_FACTOR: f64 = 20.0;

/// Whether the running files are due for a rewrite, `since_last` s after the last one, which
/// took `last_cost` s.
fn flush_due(since_last: f64, last_cost: f64) -> bool {
    since_last > FLUSH_EVERY_S.max(FLUSH_COST_FACTOR * last_cost)
}

/// Writes a run's files into a directory.
pub struct OutputWriter {
    dir: PathBuf,
    records: Vec<StepRecord>,
    pvd: Vec<(f64, String)>,
    /// The entries of `fields_revolved.pvd` (axisymmetric models).
    pvd_revolved: Vec<(f64, String)>,
    /// The revolved mesh, built at the first field file of an axisymmetric model.
    revolved: Option<RevolvedMesh>,
    steps_seen: usize,
    last_flush: Instant,
    /// How long the last rewrite of the running files took (s).
    last_flush_cost: f64,
    /// When the writer was created (the provisional summary's wall time).
    started: Instant,
    last_state: Option<(StepRecord, Vec<f64>, Vec<CellFields>)>,
    last_written_step: Option<usize>,
    /// Cell means of the material points' internal variables for the next step (by name).
    point_states: Vec<(String, Vec<f64>)>,
    /// Problems that left an output out but are no write failure (a non-finite state, a plot
    /// without finite values), reported in the summary's warnings.
    pub errors: Vec<String>,
    /// The first file that could not be written (full disk, unwritable directory) and why.
    failure: Option<String>,
    /// Write failures after the first.
    more_failures: usize,
    /// The files of the small-signal stages so far: stage name and file stem.
    linear_files: Vec<(String, String)>,
    /// Per `frequency-response` stage: its name, the driven electrode and its bias (V).
    responses: Vec<(String, String, f64)>,
    /// The `--set` overrides of the run, for the summary.
    pub overrides: Vec<String>,
    /// The points and limit points of the continuation stages.
    path: Vec<PathRecord>,
    limits: Vec<LimitRecord>,
    /// In a run shared between MPI ranks: this rank's piece of the field files, which are then
    /// written as one `.vtu` piece per rank and a `.pvtu` index (by rank 0).
    pieces: Option<Pieces>,
    /// A rank other than 0 of a shared run: it writes its pieces of the field files only.
    piece_only: bool,
}

/// The arrays of one field file: nodal u and Φ, and per cell e, the three stress tensors (total,
/// mechanical, Maxwell) and J; for an axisymmetric model (u_r, u_z, 0) and components in
/// (R, Z, Θ), which its revolved view turns into 3-D ones.
struct Section<'a> {
    disp: &'a [f64],
    phi: &'a [f64],
    e: &'a [f64],
    tensors: [&'a [f64]; 3],
    j: &'a [f64],
}

impl<'a> Section<'a> {
    /// The field file of these arrays on `points` with the cells `connectivity` of `cell_type`:
    /// displacement and potential per node; electric field, the three stresses, J and the
    /// material's `states` (one scalar each) per cell.
    fn piece(
        &self,
        points: &'a [[f64; 3]],
        cell_type: CellType,
        connectivity: &'a [usize],
        states: &'a [(String, Vec<f64>)],
    ) -> VtuPiece<'a> {
        let [sigma, sigma_mech, maxwell] = self.tensors;
        let cell_data: Vec<Field> = [
            ("electric_field", 3, self.e),
            ("cauchy_stress", 9, sigma),
            ("mechanical_stress", 9, sigma_mech),
            ("maxwell_stress", 9, maxwell),
            ("J", 1, self.j),
        ]
        .into_iter()
        .chain(states.iter().map(|(n, v)| (n.as_str(), 1, v.as_slice())))
        .collect();
        VtuPiece::fields(
            points,
            cell_type,
            connectivity,
            &[("displacement", 3, self.disp), ("potential", 1, self.phi)],
            &cell_data,
        )
    }
}

/// Name and SI unit of the parameter of continuation stage `stage`.
fn path_parameter(plan: &Plan, stage: &str) -> (String, &'static str) {
    plan.stages
        .iter()
        .find(|s| s.name == stage)
        .and_then(|s| match &s.kind {
            crate::job::plan::StageKind::Continuation { parameter, .. } => {
                Some(parameter.column(plan))
            }
            _ => None,
        })
        .unwrap_or_else(|| ("parameter".into(), "-"))
}

/// Whether a file name is one deasim writes into `plots/`.
fn is_plot(name: &str) -> bool {
    name.ends_with(".png") || name.ends_with(".svg")
}

/// The number NNNNN of a field file `step_NNNNN.vtu` or `revolved_NNNNN.vtu`, or of a shared
/// run's index `step_NNNNN.pvtu` or piece `step_NNNNN_pRRRR.vtu`.
fn field_file_index(name: &str) -> Option<usize> {
    let digits = |d: &str| d.len() == 5 && d.bytes().all(|b| b.is_ascii_digit());
    fn piece(r: &str) -> Option<&str> {
        r.strip_suffix(".vtu")
            .and_then(|r| r.split_once("_p"))
            .filter(|(_, rank)| rank.len() == 4 && rank.bytes().all(|b| b.is_ascii_digit()))
            .map(|(d, _)| d)
    }
    let step = name.strip_prefix("step_").and_then(|r| {
        r.strip_suffix(".vtu")
            .or_else(|| r.strip_suffix(".pvtu"))
            .filter(|d| digits(d))
            .or_else(|| piece(r))
    });
    step.or_else(|| {
        name.strip_prefix("revolved_")
            .and_then(|r| r.strip_suffix(".vtu"))
    })
    .filter(|d| digits(d))
    .and_then(|d| d.parse().ok())
}

/// Whether a file name is a field file `step_NNNNN.vtu`, `revolved_NNNNN.vtu`, or an index
/// or a piece of a shared run's field file.
fn is_field_file(name: &str) -> bool {
    field_file_index(name).is_some()
}

/// Removes a file; a missing one is fine.
fn remove_if_present(path: &Path) -> Result<(), String> {
    match std::fs::remove_file(path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(format!(
            "cannot remove {} of the earlier run: {e}",
            path.display()
        )),
    }
}

fn csv_number(v: f64) -> String {
    if v.is_finite() {
        format!("{v:e}")
    } else {
        "NaN".into()
    }
}

fn json_number(v: f64) -> Value {
    if v.is_finite() {
        json!(v)
    } else {
        Value::Null
    }
}

/// Writes this rank's piece `Pieces::file_name(index, rank)` of the field file whose whole-mesh
/// arrays are `whole`, with a cell array `rank`; with `index_file` (rank 0) also the index
/// `step_NNNNN.pvtu` over every rank's piece. Returns the name the PVD lists (the index).
fn write_rank_piece(
    dir: &Path,
    pieces: &Pieces,
    index: usize,
    whole: &VtuPiece,
    encoding: Encoding,
    index_file: bool,
) -> Result<String, VtuError> {
    let nodal: Vec<Vec<f64>> = whole
        .point_data
        .iter()
        .map(|a| pieces.node_values(a.values, a.components))
        .collect();
    let cells: Vec<Vec<f64>> = whole
        .cell_data
        .iter()
        .map(|a| pieces.cell_values(a.values, a.components))
        .collect();
    let rank = vec![pieces.rank as f64; pieces.n_cells()];
    let mut cell_data: Vec<DataArray> = whole
        .cell_data
        .iter()
        .zip(&cells)
        .map(|(a, v)| DataArray { values: v, ..*a })
        .collect();
    cell_data.push(DataArray {
        name: "rank",
        components: 1,
        values: &rank,
    });
    let piece = VtuPiece {
        points: pieces.points(),
        cell_type: whole.cell_type,
        connectivity: pieces.connectivity(),
        point_data: whole
            .point_data
            .iter()
            .zip(&nodal)
            .map(|(a, v)| DataArray { values: v, ..*a })
            .collect(),
        cell_data,
    };
    write_vtu_as(
        &dir.join(Pieces::file_name(index, pieces.rank)),
        &piece,
        encoding,
    )?;
    let name = format!("step_{index:05}.pvtu");
    if index_file {
        fn list<'a>(arrays: &[DataArray<'a>]) -> Vec<(&'a str, usize)> {
            arrays.iter().map(|a| (a.name, a.components)).collect()
        }
        let files: Vec<String> = (0..pieces.ranks)
            .map(|r| Pieces::file_name(index, r))
            .collect();
        write_pvtu(
            &dir.join(&name),
            &files,
            &list(&piece.point_data),
            &list(&piece.cell_data),
        )?;
    }
    Ok(name)
}

impl OutputWriter {
    /// Checks that `dir` may receive the results of scenario `name`: refused when it holds the
    /// results of a different scenario (its `summary.json` names another scenario) unless
    /// `overwrite`. Results of the same scenario are replaced: deasim's own files of the earlier
    /// run are deleted (`summary.json`, `history.csv`, `periods.csv`, `fields.pvd`,
    /// `fields_revolved.pvd`, `fields/step_NNNNN.vtu`, `fields/revolved_NNNNN.vtu`, `plots/*.png`
    /// and `plots/*.svg`), so that no stale step, plot or probe remains; other
    /// files in the directory are left alone.
    pub fn check_directory(dir: &Path, name: &str, overwrite: bool) -> Result<(), String> {
        let summary = dir.join("summary.json");
        if let Ok(text) = std::fs::read_to_string(&summary) {
            let other = serde_json::from_str::<Value>(&text)
                .ok()
                .and_then(|v| v.get("scenario").and_then(|s| s.as_str()).map(String::from));
            match other {
                Some(o) if o == name => {}
                Some(o) if !overwrite => {
                    return Err(format!(
                        "{} holds the results of scenario `{o}`; use --overwrite to replace them or --out to choose another directory",
                        dir.display()
                    ))
                }
                None if !overwrite => {
                    return Err(format!(
                        "{} holds a summary.json that deasim did not write; use --overwrite or another --out",
                        summary.display()
                    ))
                }
                _ => {}
            }
        }
        for (sub, ours) in [
            ("fields", is_field_file as fn(&str) -> bool),
            ("plots", is_plot),
        ] {
            if let Ok(entries) = std::fs::read_dir(dir.join(sub)) {
                for e in entries.flatten() {
                    let n = e.file_name().to_string_lossy().into_owned();
                    if ours(&n) && e.file_type().is_ok_and(|t| t.is_file()) {
                        remove_if_present(&e.path())?;
                    }
                }
            }
        }
        for f in [
            "fields.pvd",
            "fields_revolved.pvd",
            "history.csv",
            "electrodes.csv",
            "periods.csv",
            "summary.json",
            "modes.csv",
            "modes.pvd",
            "path.csv",
            "frequency_response.csv",
            "instability.csv",
            "instability.pvd",
            "modes_revolved.pvd",
            "instability_revolved.pvd",
        ] {
            remove_if_present(&dir.join(f))?;
        }
        for sub in ["modes", "instability"] {
            if let Ok(entries) = std::fs::read_dir(dir.join(sub)) {
                for e in entries.flatten() {
                    let n = e.file_name().to_string_lossy().into_owned();
                    if n.starts_with("mode_") && n.ends_with(".vtu") {
                        remove_if_present(&e.path())?;
                    }
                }
            }
        }
        Ok(())
    }

    /// Creates the directory (and `fields/`, `plots/`). A sub-directory that cannot be created
    /// is a write failure ([`OutputWriter::write_failure`]); the run still writes the rest.
    pub fn new(dir: &Path) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        let mut w = OutputWriter {
            dir: dir.to_path_buf(),
            records: Vec::new(),
            pvd: Vec::new(),
            pvd_revolved: Vec::new(),
            revolved: None,
            steps_seen: 0,
            last_flush: Instant::now(),
            last_flush_cost: 0.0,
            started: Instant::now(),
            last_state: None,
            last_written_step: None,
            point_states: Vec::new(),
            errors: Vec::new(),
            failure: None,
            more_failures: 0,
            linear_files: Vec::new(),
            responses: Vec::new(),
            overrides: Vec::new(),
            path: Vec::new(),
            limits: Vec::new(),
            pieces: None,
            piece_only: false,
        };
        for sub in ["fields", "plots"] {
            let d = dir.join(sub);
            if let Err(e) = std::fs::create_dir_all(&d) {
                w.failed(format!("{}: cannot create the directory: {e}", d.display()));
            }
        }
        Ok(w)
    }

    /// Writes the field files in pieces, one per MPI rank (this rank's `pieces`); rank 0 also
    /// writes the `.pvtu` index of each and everything else, another rank (`piece_only`) only
    /// its pieces. The ranks must share the output directory.
    pub fn split_fields(&mut self, pieces: Pieces, piece_only: bool) {
        self.pieces = Some(pieces);
        self.piece_only = piece_only;
    }

    /// Records a file that could not be written.
    fn failed(&mut self, what: String) {
        if self.failure.is_none() {
            self.failure = Some(what);
        } else {
            self.more_failures += 1;
        }
    }

    /// When a file could not be written: the first such file and why, and how many more writes
    /// failed. The outputs then lack something, and the run must not end with success.
    pub fn write_failure(&self) -> Option<String> {
        self.failure.as_ref().map(|f| match self.more_failures {
            0 => format!("could not write {f}"),
            n => format!("could not write {f} (and {n} later writes failed as well)"),
        })
    }

    fn vtu_error(&mut self, e: VtuError) {
        match e {
            VtuError::Io { .. } => self.failed(e.to_string()),
            e => self.errors.push(e.to_string()),
        }
    }

    fn plot_error(&mut self, e: PlotError) {
        match e {
            PlotError::NoData { .. }
            | PlotError::Range { .. }
            | PlotError::LengthMismatch { .. } => self.errors.push(e.to_string()),
            e => self.failed(e.to_string()),
        }
    }

    /// The history as CSV text.
    pub fn history_csv(plan: &Plan, records: &[StepRecord]) -> String {
        let mut s = HISTORY_COLUMNS.join(",");
        for (name, _) in &plan.probes {
            s.push_str(&format!(",probe:{name}"));
        }
        s.push_str(",dt\n");
        for r in records {
            let e = &r.energies;
            let mut row = vec![
                csv_number(r.time),
                r.stage.clone(),
                r.step.to_string(),
                csv_number(r.voltage),
                r.newton_iterations.to_string(),
                csv_number(e.kinetic),
                csv_number(e.stored),
                csv_number(e.electric),
                csv_number(e.gravity),
                csv_number(e.dissipated),
                csv_number(e.energy_error),
            ];
            row.extend(r.probes.iter().map(|&v| csv_number(v)));
            row.push(csv_number(r.dt));
            s.push_str(&row.join(","));
            s.push('\n');
        }
        s
    }

    /// The electrodes' values per record as CSV text: time, stage, step, then for each electrode
    /// its voltage (V), charge (C), current (A) and power (W), and for a circuit-driven one the
    /// energy its source delivered and its resistance lost (J); whole device.
    pub fn electrodes_csv(plan: &Plan, records: &[StepRecord]) -> String {
        let mut s = String::from("time,stage,step");
        for e in &plan.electrodes {
            for q in ["voltage", "charge", "current", "power"] {
                s.push_str(&format!(",{q}:{}", e.name));
            }
            if e.resistance.is_some() {
                s.push_str(&format!(",source_energy:{0},resistor_loss:{0}", e.name));
            }
        }
        s.push('\n');
        for r in records {
            let mut row = vec![csv_number(r.time), r.stage.clone(), r.step.to_string()];
            for (i, e) in plan.electrodes.iter().enumerate() {
                let v = r.electrodes.get(i).copied().unwrap_or([f64::NAN; 6]);
                let n = if e.resistance.is_some() { 6 } else { 4 };
                row.extend(v[..n].iter().map(|&x| csv_number(x)));
            }
            s.push_str(&row.join(","));
            s.push('\n');
        }
        s
    }

    /// The continuation points as CSV text: stage, point, load factor, the parameter's name
    /// (with its unit) and value, arc length, negative pivots of the tangent and of a stable
    /// state, stability under control of the parameter, then the probes.
    pub fn path_csv(plan: &Plan, points: &[PathRecord]) -> String {
        let mut s = String::from(
            "stage,point,load_factor,parameter_name,parameter,arc_length,negative_pivots,\
             stable_negative_pivots,stable",
        );
        for (name, _) in &plan.probes {
            s.push_str(&format!(",probe:{name}"));
        }
        s.push('\n');
        for p in points {
            let (name, unit) = path_parameter(plan, &p.stage);
            let (neg, expected) = match p.negative_pivots {
                Some((n, e)) => (n.to_string(), e.to_string()),
                None => (String::new(), String::new()),
            };
            let mut row = vec![
                p.stage.clone(),
                p.point.to_string(),
                csv_number(p.load_factor),
                format!("{name} [{unit}]"),
                csv_number(p.parameter),
                csv_number(p.arc_length),
                neg,
                expected,
                p.stable.to_string(),
            ];
            row.extend(p.probes.iter().map(|&v| csv_number(v)));
            s.push_str(&row.join(","));
            s.push('\n');
        }
        s
    }

    fn write_history(&mut self, plan: &Plan) {
        let text = Self::history_csv(plan, &self.records);
        if let Err(e) = write_atomic(&self.dir.join("history.csv"), text.as_bytes()) {
            self.failed(format!("{}: {e}", self.dir.join("history.csv").display()));
        }
        if !plan.electrodes.is_empty() {
            let text = Self::electrodes_csv(plan, &self.records);
            let path = self.dir.join("electrodes.csv");
            if let Err(e) = write_atomic(&path, text.as_bytes()) {
                self.failed(format!("{}: {e}", path.display()));
            }
        }
        self.last_flush = Instant::now();
    }

    fn write_fields(
        &mut self,
        plan: &Plan,
        record: &StepRecord,
        state: &[f64],
        fields: &[CellFields],
    ) {
        let mesh = &plan.model.mesh;
        let n = mesh.n_nodes();
        let mut disp = Vec::with_capacity(3 * n);
        let mut phi = Vec::with_capacity(n);
        for node in 0..n {
            disp.extend_from_slice(&state[node * 4..node * 4 + 3]);
            phi.push(state[node * 4 + 3]);
        }
        let e: Vec<f64> = fields.iter().flat_map(|f| f.e).collect();
        let sigma: Vec<f64> = fields.iter().flat_map(|f| f.sigma).collect();
        let sigma_mech: Vec<f64> = fields.iter().flat_map(|f| f.sigma_mech).collect();
        let maxwell: Vec<f64> = sigma.iter().zip(&sigma_mech).map(|(t, m)| t - m).collect();
        let j: Vec<f64> = fields.iter().map(|f| f.j).collect();
        let name = format!("step_{:05}.vtu", self.pvd.len());
        let encoding = Encoding::from(plan.output.fields_format);
        let index = self.pvd.len();
        let section = Section {
            disp: &disp,
            phi: &phi,
            e: &e,
            tensors: [&sigma, &sigma_mech, &maxwell],
            j: &j,
        };
        let piece = section.piece(
            &mesh.nodes,
            CellType::from(mesh.kind),
            &mesh.connectivity,
            &self.point_states,
        );
        if self.revolved.is_none() {
            if let Some(revolve) = plan.output.revolve {
                self.revolved = RevolvedMesh::new(&plan.model.mesh, revolve);
            }
        }
        // the section and its revolved view are independent files: written side by side
        let fields_dir = self.dir.join("fields");
        let (written, revolved) = rayon::join(
            || match &self.pieces {
                Some(p) => {
                    write_rank_piece(&fields_dir, p, index, &piece, encoding, !self.piece_only)
                }
                None => write_vtu_as(&fields_dir.join(&name), &piece, encoding).map(|()| name),
            },
            || {
                if self.piece_only {
                    None
                } else {
                    self.write_revolved(plan, index, &section, encoding)
                }
            },
        );
        match written {
            Ok(file) => {
                self.pvd.push((record.time, format!("fields/{file}")));
                if !self.piece_only {
                    if let Err(e) = write_pvd(&self.dir.join("fields.pvd"), &self.pvd) {
                        self.vtu_error(e);
                    }
                }
                self.last_written_step = Some(self.steps_seen);
                match revolved {
                    Some(Ok(name)) => {
                        self.pvd_revolved
                            .push((record.time, format!("fields/{name}")));
                        if let Err(e) =
                            write_pvd(&self.dir.join("fields_revolved.pvd"), &self.pvd_revolved)
                        {
                            self.vtu_error(e);
                        }
                    }
                    Some(Err(e)) => self.vtu_error(e),
                    None => {}
                }
            }
            Err(e) => self.vtu_error(e),
        }
    }

    /// Writes the revolved view of field file `index` of an axisymmetric model,
    /// `fields/revolved_NNNNN.vtu`, and returns its name (`None` for a 3-D model or with
    /// `output.revolve = false`). It only reads the section's arrays.
    fn write_revolved(
        &self,
        plan: &Plan,
        index: usize,
        s: &Section,
        encoding: Encoding,
    ) -> Option<Result<String, VtuError>> {
        plan.output.revolve?;
        let mesh = self.revolved.as_ref()?;
        let disp = mesh.point_array(Components::Vector, s.disp);
        let phi = mesh.point_array(Components::Scalar, s.phi);
        let e = mesh.cell_array(Components::Vector, s.e);
        let [sigma, sigma_mech, maxwell] =
            s.tensors.map(|t| mesh.cell_array(Components::Tensor, t));
        let j = mesh.cell_array(Components::Scalar, s.j);
        let states = mesh.named_cell_scalars(&self.point_states);
        let revolved = Section {
            disp: &disp,
            phi: &phi,
            e: &e,
            tensors: [&sigma, &sigma_mech, &maxwell],
            j: &j,
        };
        let piece = revolved.piece(&mesh.points, mesh.cell_type, &mesh.connectivity, &states);
        let name = format!("revolved_{index:05}.vtu");
        Some(write_vtu_as(&self.dir.join("fields").join(&name), &piece, encoding).map(|()| name))
    }

    /// The summary as JSON.
    pub fn summary_json(&self, plan: &Plan, summary: &RunSummary) -> Value {
        let last = self.records.last();
        let mut probes = serde_json::Map::new();
        for (i, (name, _)) in plan.probes.iter().enumerate() {
            probes.insert(
                name.clone(),
                last.map(|r| json_number(r.probes[i]))
                    .unwrap_or(Value::Null),
            );
        }
        let e = last.map(|r| r.energies).unwrap_or_default();
        let max_field = self
            .records
            .iter()
            .map(|r| r.max_electric_field)
            .fold(0.0, f64::max);
        let mut warnings = summary.warnings.clone();
        warnings.extend(self.errors.iter().cloned());
        let failure = self.write_failure();
        warnings.extend(failure.clone());
        let mut v = json!({
            "scenario": plan.name,
            "dofs": summary.dofs,
            "nodes": plan.whole_nodes(),
            "elements": plan.whole_cells(),
            // a solve that converged but whose outputs lack a file did not finish its work
            "status": if summary.converged && failure.is_some() {
                "incomplete-outputs"
            } else if summary.converged {
                "finished"
            } else if summary.interrupted {
                "interrupted"
            } else {
                "failed"
            },
            "converged": summary.converged,
            "wall_s": summary.wall_s,
            "stages": summary.stages.iter().map(|s| json!({
                "name": s.name, "kind": s.kind, "steps": s.steps,
                "newton_iterations": s.newton_iterations, "wall_s": s.wall_s, "converged": s.converged,
                "linear": {
                    "factorizations": s.linear.factorizations, "solves": s.linear.solves,
                    "krylov_iterations": s.linear.krylov_iterations,
                    "krylov_decades": json_number(s.linear.krylov_decades),
                },
            })).collect::<Vec<_>>(),
            "probes": probes,
            "max_electric_field": json_number(max_field),
            "energy": {
                "kinetic": json_number(e.kinetic), "stored": json_number(e.stored),
                "electric": json_number(e.electric), "gravity": json_number(e.gravity),
                "dissipated": json_number(e.dissipated), "energy_error": json_number(e.energy_error),
            },
            "warnings": warnings,
            "outputs": {"complete": failure.is_none(), "reason": failure},
        });
        v["version"] = json!(env!("CARGO_PKG_VERSION"));
        v["date"] =
            json!(humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string());
        v["scenario_hash"] = json!(format!("{:016x}", plan.fingerprint()));
        v["model_hash"] = json!(format!("{:016x}", plan.model_hash()));
        v["overrides"] = json!(self.overrides);
        v["solver"] = json!(plan.solver.kind.name());
        v["probe_stats"] = self.probe_stats(plan);
        if let Some(last) = summary.stages.iter().rev().find(|s| s.kind == "modes") {
            v["modes"] = json!(last
                .modes_hz
                .iter()
                .map(|&f| json_number(f))
                .collect::<Vec<_>>());
            if last.modes_harmonic.iter().any(|&n| n > 0) {
                v["modes_harmonic"] = json!(last.modes_harmonic);
            }
            if let Some(note) = crate::job::linear::mode_symmetry_note(plan) {
                v["modes_note"] = json!(note);
            }
        }
        if !self.linear_files.is_empty() {
            v["linear_files"] = json!(self
                .linear_files
                .iter()
                .map(|(stage, stem)| json!({"stage": stage, "file": format!("{stem}.csv")}))
                .collect::<Vec<_>>());
        }
        if !self.responses.is_empty() {
            v["frequency_response"] = json!(self
                .responses
                .iter()
                .map(|(stage, e, bias)| json!({"stage": stage, "electrode": e, "bias_v": bias}))
                .collect::<Vec<_>>());
        }
        if !self.limits.is_empty() {
            v["limit_points"] = json!(self
                .limits
                .iter()
                .map(|l| {
                    let (name, unit) = path_parameter(plan, &l.stage);
                    let probes: serde_json::Map<String, Value> = plan
                        .probes
                        .iter()
                        .zip(&l.probes)
                        .map(|((n, _), &x)| (n.clone(), json_number(x)))
                        .collect();
                    json!({
                        "stage": l.stage,
                        "kind": if l.maximum { "maximum" } else { "minimum" },
                        "parameter": name,
                        "unit": unit,
                        "value": json_number(l.parameter),
                        "load_factor": json_number(l.load_factor),
                        "probes": probes,
                    })
                })
                .collect::<Vec<_>>());
        }
        if let Some(i) = summary.stages.iter().find_map(|s| s.instability.as_ref()) {
            let voltages: serde_json::Map<String, Value> = i
                .voltages
                .iter()
                .map(|(n, v)| (n.clone(), json_number(*v)))
                .collect();
            v["instability"] = json!({
                "stage": i.stage,
                "harmonic": i.harmonic,
                "load_factor": json_number(i.load_factor),
                "stable_load_factor": json_number(i.stable_load_factor),
                "time": json_number(i.time),
                "voltages": voltages,
                "unstable_harmonics": i.unstable,
                "axial_share": json_number(i.axial_share),
                "stopped": i.stopped,
                "mode": "instability.pvd",
            });
        }
        if let Some(err) = &summary.error {
            v["error"] = json!(err);
        }
        v
    }

    /// Per probe: `final`, `min` and `max` over every record (finite values), and with a
    /// periodic drive `mean` and `peak_to_peak` over its last full period.
    fn probe_stats(&self, plan: &Plan) -> Value {
        let last_period = crate::io::periods::periods(plan, &self.records).pop();
        let mut stats = serde_json::Map::new();
        for (i, (name, _)) in plan.probes.iter().enumerate() {
            let values = || {
                self.records
                    .iter()
                    .map(|r| r.probes[i])
                    .filter(|v| v.is_finite())
            };
            let mut o = json!({
                "final": self.records.last().map(|r| json_number(r.probes[i])).unwrap_or(Value::Null),
                "min": values().reduce(f64::min).map(json_number).unwrap_or(Value::Null),
                "max": values().reduce(f64::max).map(json_number).unwrap_or(Value::Null),
            });
            if let Some(p) = &last_period {
                let s = p.probes[i];
                o["mean"] = json_number(s.mean);
                o["peak_to_peak"] = json_number(s.max - s.min);
                o["period"] = json!({"stage": p.stage, "t_start": p.t_start, "t_end": p.t_end});
            }
            stats.insert(name.clone(), o);
        }
        Value::Object(stats)
    }

    fn write_plots(&mut self, plan: &Plan) {
        if !plan.output.plots || self.records.is_empty() {
            return;
        }
        let ext = &plan.output.plot_format;
        let dir = self.dir.join("plots");
        let jobs = run_plots(plan, &self.records, &self.path, &self.limits);
        // the plots are independent files: drawn on the pool's threads
        let errors: Vec<PlotError> = jobs
            .par_iter()
            .filter_map(|plot| {
                let path = dir.join(format!("{}.{ext}", plot.file));
                let specs: Vec<PlotSpec> = plot
                    .panels
                    .iter()
                    .map(|p| PlotSpec {
                        title: &p.title,
                        x_label: &p.x_label,
                        y_label: &p.y_label,
                        series: &p.series,
                    })
                    .collect();
                stacked_plot(&path, &specs).err()
            })
            .collect();
        for e in errors {
            self.plot_error(e);
        }
    }
}

/// One plot of a run: its file name without the extension and its panels, top to bottom.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RunPlot {
    pub file: String,
    pub panels: Vec<RunPanel>,
}

/// One panel of a [`RunPlot`]: what [`PlotSpec`] borrows.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RunPanel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
}

impl RunPanel {
    fn new(title: String, x_label: &str, y_label: &str, series: Vec<Series>) -> Self {
        RunPanel {
            title,
            x_label: x_label.into(),
            y_label: y_label.into(),
            series,
        }
    }
}

/// The plots of a run's `plots/` directory: the voltage and every probe against the run's
/// abscissa ([`x_axis`]); every probe against the voltage, one curve per stage in which the
/// voltage varies continuously; per dynamic or quasi-static stage every probe above the voltage;
/// per continuation stage its parameter against every probe along the path, with the limit points.
pub(crate) fn run_plots(
    plan: &Plan,
    records: &[StepRecord],
    path: &[PathRecord],
    limits: &[LimitRecord],
) -> Vec<RunPlot> {
    use crate::job::plan::StageKind;
    let mut plots = Vec::new();
    if records.is_empty() {
        return plots;
    }
    let single = |file: String, title: String, x: &str, y: &str, series: Series| RunPlot {
        file,
        panels: vec![RunPanel::new(title, x, y, vec![series])],
    };
    let (t, x_label) = x_axis(plan, records, path);
    let v: Vec<f64> = records.iter().map(|r| r.voltage).collect();
    plots.push(single(
        "voltage".into(),
        "largest electrode voltage".into(),
        &x_label,
        "voltage [V]",
        Series {
            label: "voltage".into(),
            x: t.clone(),
            y: v.clone(),
        },
    ));
    // against the voltage: per stage in which it varies (a stage at zero or held voltage would
    // draw a vertical line), and moves continuously (a square wave's jumps would too); each curve
    // starts at the state its stage starts from
    let timed = |s: &crate::job::plan::Stage| {
        matches!(
            s.kind,
            StageKind::Dynamic { .. } | StageKind::QuasiStatic { .. }
        )
    };
    let jumps = |s: &crate::job::plan::Stage| {
        s.electrodes_on && timed(s) && !plan.electrodes.iter().all(|e| e.voltage.is_continuous())
    };
    let mut varying: Vec<(&str, Vec<usize>)> = Vec::new();
    for stage in &plan.stages {
        let rows: Vec<usize> = (0..records.len())
            .filter(|&i| records[i].stage == stage.name)
            .collect();
        let Some(&first) = rows.first() else {
            continue;
        };
        let mut span = rows.clone();
        if first > 0 {
            span.insert(0, first - 1);
        }
        let varies = span.iter().any(|&i| v[i] != v[span[0]]);
        if varies && !jumps(stage) {
            varying.push((&stage.name, span));
        }
    }
    for (i, (name, probe)) in plan.probes.iter().enumerate() {
        let y: Vec<f64> = records.iter().map(|r| r.probes[i]).collect();
        let y_label = probe_axis(name, probe);
        plots.push(single(
            name.clone(),
            format!("{name}: {}", probe.description),
            &x_label,
            &y_label,
            Series {
                label: name.clone(),
                x: t.clone(),
                y: y.clone(),
            },
        ));
        if !varying.is_empty() {
            let series = varying
                .iter()
                .map(|(stage, rows)| Series {
                    label: stage.to_string(),
                    x: rows.iter().map(|&k| v[k]).collect(),
                    y: rows.iter().map(|&k| y[k]).collect(),
                })
                .collect();
            let title = match varying.as_slice() {
                [(stage, _)] => format!("{name} against the voltage in stage {stage}"),
                _ => format!("{name} against the voltage, stage by stage"),
            };
            plots.push(RunPlot {
                file: format!("{name}_vs_voltage"),
                panels: vec![RunPanel::new(title, "voltage [V]", &y_label, series)],
            });
        }
    }
    // dynamic stages: every probe above the voltage, over the stage only
    for stage in plan.stages.iter().filter(|s| timed(s)) {
        let rows: Vec<&StepRecord> = records.iter().filter(|r| r.stage == stage.name).collect();
        if rows.len() < 2 {
            continue;
        }
        let t: Vec<f64> = rows.iter().map(|r| r.time).collect();
        let voltage = Series {
            label: "voltage".into(),
            x: t.clone(),
            y: rows.iter().map(|r| r.voltage).collect(),
        };
        for (i, (name, probe)) in plan.probes.iter().enumerate() {
            let series = Series {
                label: name.clone(),
                x: t.clone(),
                y: rows.iter().map(|r| r.probes[i]).collect(),
            };
            plots.push(RunPlot {
                file: format!("{}_{name}_and_voltage", stage.name),
                panels: vec![
                    RunPanel::new(
                        format!("{name} in stage {}", stage.name),
                        "time [s]",
                        &probe_axis(name, probe),
                        vec![series],
                    ),
                    RunPanel::new(
                        "largest electrode voltage".into(),
                        "time [s]",
                        "voltage [V]",
                        vec![voltage.clone()],
                    ),
                ],
            });
        }
    }
    // continuation stages: the parameter against every probe along the path (e.g. a balloon's
    // pressure against its stretch, through the maximum and the minimum)
    for stage in &plan.stages {
        if !matches!(stage.kind, StageKind::Continuation { .. }) {
            continue;
        }
        let points: Vec<&PathRecord> = path.iter().filter(|p| p.stage == stage.name).collect();
        if points.len() < 2 {
            continue;
        }
        let turns: Vec<&LimitRecord> = limits.iter().filter(|l| l.stage == stage.name).collect();
        let (parameter, unit) = path_parameter(plan, &stage.name);
        let y_label = format!("{parameter} [{unit}]");
        for (i, (name, probe)) in plan.probes.iter().enumerate() {
            let mut series = vec![Series {
                label: "path".into(),
                x: points.iter().map(|p| p.probes[i]).collect(),
                y: points.iter().map(|p| p.parameter).collect(),
            }];
            if !turns.is_empty() {
                // markers: single points between gaps
                let (mut x, mut y) = (Vec::new(), Vec::new());
                for l in &turns {
                    x.extend([f64::NAN, l.probes.get(i).copied().unwrap_or(f64::NAN)]);
                    y.extend([f64::NAN, l.parameter]);
                }
                series.push(Series {
                    label: "limit points".into(),
                    x,
                    y,
                });
            }
            plots.push(RunPlot {
                file: format!("{}_path_{name}", stage.name),
                panels: vec![RunPanel::new(
                    format!(
                        "{parameter} against {name} along the path of stage {}",
                        stage.name
                    ),
                    &probe_axis(name, probe),
                    &y_label,
                    series,
                )],
            });
        }
    }
    plots
}

/// A probe's axis title: `name [unit]`, or the name alone when its unit is unknown.
pub fn probe_axis(name: &str, probe: &crate::job::probes::Probe) -> String {
    if probe.unit.is_empty() {
        name.to_string()
    } else {
        format!("{name} [{}]", probe.unit)
    }
}

/// Per record, how far its stage has gone when that stage is a load ramp: the load factor of a
/// static stage, the arc length over its final value (0 → 1, monotone, also where the load
/// falls past a maximum) of a continuation stage; `None` in other stages.
fn ramp_fractions(plan: &Plan, records: &[StepRecord], path: &[PathRecord]) -> Vec<Option<f64>> {
    use crate::job::plan::StageKind;
    let mut out = vec![None; records.len()];
    let mut t0 = 0.0;
    for s in &plan.stages {
        let rows: Vec<usize> = (0..records.len())
            .filter(|&i| records[i].stage == s.name)
            .collect();
        match s.kind {
            StageKind::Static { .. } => {
                for &i in &rows {
                    if s.duration > 0.0 {
                        out[i] = Some((records[i].time - t0) / s.duration);
                    }
                }
            }
            StageKind::Continuation { .. } => {
                // the stage's last records are its path points, in order (a first stage's
                // initial and pre-stretch rows come before them, at its start)
                let points: Vec<&PathRecord> = path.iter().filter(|p| p.stage == s.name).collect();
                let total = points.last().map_or(0.0, |p| p.arc_length);
                let before = rows.len().saturating_sub(points.len());
                for (k, &i) in rows.iter().enumerate() {
                    out[i] = Some(if k < before {
                        0.0
                    } else if points.len() == rows.len() - before && total > 0.0 {
                        points[k - before].arc_length / total
                    } else {
                        // no path points (a resumed run): in the order of the records
                        (k + 1 - before) as f64 / (rows.len() - before) as f64
                    });
                }
            }
            _ => {}
        }
        t0 += s.duration;
    }
    out
}

/// The abscissa of a run's plots and its title. When every recorded stage is a load ramp in
/// pseudo-time (static and continuation stages of elastic materials), each stage counts one unit:
/// static stages by their load factor, continuation stages by their path (arc length over its
/// final value), so that nothing runs backwards past a maximum of the load. Otherwise the time,
/// with a continuation stage's span spread along its path; the title says when static stages'
/// time is pseudo-time.
fn x_axis(plan: &Plan, records: &[StepRecord], path: &[PathRecord]) -> (Vec<f64>, String) {
    use crate::job::plan::StageKind;
    let ramp = |s: &crate::job::plan::Stage| {
        matches!(
            s.kind,
            StageKind::Static { .. } | StageKind::Continuation { .. }
        )
    };
    let pseudo = plan
        .model
        .materials
        .iter()
        .all(|m| m.state_size() == 0 && m.maxwell_branches().is_empty());
    let recorded: Vec<&crate::job::plan::Stage> = plan
        .stages
        .iter()
        .filter(|s| records.iter().any(|r| r.stage == s.name))
        .collect();
    let fractions = ramp_fractions(plan, records, path);
    // each stage's start: its index among the ramps, and its time
    let mut start = std::collections::HashMap::new();
    let (mut t0, mut k) = (0.0, 0.0);
    for s in &plan.stages {
        start.insert(s.name.as_str(), (t0, k));
        if ramp(s) {
            k += 1.0;
        }
        t0 += s.duration;
    }
    let continuation = |name: &str| {
        plan.stages
            .iter()
            .find(|s| s.name == name)
            .filter(|s| matches!(s.kind, StageKind::Continuation { .. }))
    };
    if pseudo && !recorded.is_empty() && recorded.iter().all(|s| ramp(s)) {
        let x = records
            .iter()
            .zip(&fractions)
            .map(|(r, f)| match (start.get(r.stage.as_str()), f) {
                (Some(&(_, k)), Some(f)) => k + f,
                _ => f64::NAN,
            })
            .collect();
        let paths = recorded
            .iter()
            .filter(|s| continuation(&s.name).is_some())
            .count();
        let label = match (recorded.len(), paths) {
            (1, 0) => "load factor [-]",
            (_, 0) => "load factor, stage by stage [-]",
            (1, _) => "pseudo-time: path, arc length over its final value [-]",
            _ => "pseudo-time: load factor, or path in continuation stages, stage by stage [-]",
        };
        return (x, label.to_string());
    }
    let x = records
        .iter()
        .zip(&fractions)
        .map(
            |(r, f)| match (continuation(&r.stage), start.get(r.stage.as_str()), f) {
                (Some(s), Some(&(t0, _)), Some(f)) => t0 + s.duration * f,
                _ => r.time,
            },
        )
        .collect();
    let label = if pseudo && recorded.iter().any(|s| ramp(s)) {
        "time, pseudo-time in static stages [s]"
    } else {
        "time [s]"
    };
    (x, label.to_string())
}

impl OutputWriter {
    /// The file stem of a small-signal stage's output: `base` for the first of its kind, then
    /// `base-<stage>`.
    fn linear_stem(&mut self, base: &str, stage: &str) -> String {
        let taken = self.linear_files.iter().any(|(_, s)| s == base);
        let stem = if taken {
            let safe: String = stage
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                        c
                    } else {
                        '_'
                    }
                })
                .collect();
            format!("{base}-{safe}")
        } else {
            base.to_string()
        };
        self.linear_files.push((stage.to_string(), stem.clone()));
        stem
    }
}

impl Observer for OutputWriter {
    fn modes(&mut self, plan: &Plan, stage: &str, state: &[f64], modes: &[Mode]) {
        if self.piece_only {
            return;
        }
        let stem = self.linear_stem("modes", stage);
        if let Err(e) = write_modes(plan, &self.dir, &stem, state, modes) {
            self.failed(e);
        }
    }

    fn frequency_response(&mut self, plan: &Plan, stage: &str, response: &FrequencyResponse) {
        if self.piece_only {
            return;
        }
        let stem = self.linear_stem("frequency_response", stage);
        self.responses
            .push((stage.to_string(), response.electrode.clone(), response.bias));
        let plots = self.dir.join("plots");
        let plots = plan
            .output
            .plots
            .then_some((plots.as_path(), plan.output.plot_format.as_str()));
        let unit = |name: &str| {
            plan.probes
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, p)| p.unit.clone())
                .unwrap_or_default()
        };
        match write_response(response, &self.dir, &stem, plots, &unit) {
            // a plot without finite values is a warning, as for the run's plots
            Ok(skipped) => self.errors.extend(skipped),
            Err(e) => self.failed(e),
        }
    }

    fn point_states(&mut self, _plan: &Plan, cell_means: &[(String, Vec<f64>)]) {
        self.point_states = cell_means.to_vec();
    }

    fn path_point(&mut self, _plan: &Plan, point: &PathRecord) {
        self.path.push(point.clone());
    }

    fn limit_point(&mut self, _plan: &Plan, limit: &LimitRecord) {
        self.limits.push(limit.clone());
    }

    fn instability(
        &mut self,
        plan: &Plan,
        _record: &InstabilityRecord,
        state: &[f64],
        mode: &Mode,
    ) {
        if self.piece_only {
            return;
        }
        if let Err(e) = write_modes(
            plan,
            &self.dir,
            "instability",
            state,
            std::slice::from_ref(mode),
        ) {
            self.failed(e);
        }
    }

    fn step(&mut self, plan: &Plan, record: &StepRecord, state: &[f64], fields: &[CellFields]) {
        let every = plan.output.fields_every;
        // a new stage begins: the state its predecessor ended in is in the field files too
        let stage_ended = self
            .records
            .last()
            .is_some_and(|prev| prev.stage != record.stage);
        if every > 0 && stage_ended && self.last_written_step != Some(self.steps_seen - 1) {
            if let Some((r, s, f)) = self.last_state.take() {
                self.write_fields(plan, &r, &s, &f);
                self.last_written_step = Some(self.steps_seen - 1);
            }
        }
        self.records.push(record.clone());
        if every > 0 && self.steps_seen.is_multiple_of(every) {
            self.write_fields(plan, record, state, fields);
        }
        self.steps_seen += 1;
        self.last_state = Some((record.clone(), state.to_vec(), fields.to_vec()));
        if !self.piece_only
            && (self.steps_seen == 1
                || flush_due(
                    self.last_flush.elapsed().as_secs_f64(),
                    self.last_flush_cost,
                ))
        {
            let started = Instant::now();
            self.write_history(plan);
            self.write_running_summary(plan);
            self.last_flush_cost = started.elapsed().as_secs_f64();
        }
    }

    /// Takes over the records of the run before the checkpoint: rebuilds the PVD index of the
    /// field files written for them, deletes deasim's own field files beyond it (written by the
    /// killed run after the checkpoint) and rewrites `history.csv`, `fields.pvd` and (revolved
    /// view) `fields_revolved.pvd` with the revolved files that exist, so that no row or entry is
    /// duplicated.
    fn resumed(
        &mut self,
        plan: &Plan,
        records: &[StepRecord],
        state: &[f64],
        fields: &[CellFields],
    ) {
        self.records = records.to_vec();
        self.steps_seen = records.len();
        self.pvd.clear();
        self.pvd_revolved.clear();
        self.last_written_step = None;
        if let Some(last) = records.last() {
            self.last_state = Some((last.clone(), state.to_vec(), fields.to_vec()));
        }
        let every = plan.output.fields_every;
        for (i, r) in records.iter().enumerate() {
            // as `step` wrote them: every `every`-th record and the last of each finished stage
            let stage_end = records.get(i + 1).is_some_and(|n| n.stage != r.stage);
            if every > 0 && (i.is_multiple_of(every) || stage_end) {
                let index = self.pvd.len();
                // a shared run's index, or the whole file (the part before the checkpoint may
                // have run on one rank)
                let pvtu = format!("fields/step_{index:05}.pvtu");
                let file = if self.dir.join(&pvtu).is_file() {
                    pvtu
                } else {
                    format!("fields/step_{index:05}.vtu")
                };
                self.pvd.push((r.time, file));
                // the revolved view of the files the earlier run wrote
                let revolved = format!("fields/revolved_{index:05}.vtu");
                if plan.output.revolve.is_some() && self.dir.join(&revolved).is_file() {
                    self.pvd_revolved.push((r.time, revolved));
                }
                self.last_written_step = Some(i);
            }
        }
        // another rank's writer leaves the directory to rank 0's
        if self.piece_only {
            return;
        }
        if let Ok(entries) = std::fs::read_dir(self.dir.join("fields")) {
            for e in entries.flatten() {
                let n = e.file_name().to_string_lossy().into_owned();
                // a killed run's half-written temporaries (`.<name>.tmp-<pid>-<n>`) go too
                let temporary = n.starts_with('.') && n.contains(".tmp-");
                if temporary || field_file_index(&n).is_some_and(|i| i >= self.pvd.len()) {
                    if let Err(err) = std::fs::remove_file(e.path()) {
                        self.errors.push(format!("{}: {err}", e.path().display()));
                    }
                }
            }
        }
        if let Err(e) = write_pvd(&self.dir.join("fields.pvd"), &self.pvd) {
            self.vtu_error(e);
        }
        if plan.output.revolve.is_some() {
            let path = self.dir.join("fields_revolved.pvd");
            if let Err(e) = write_pvd(&path, &self.pvd_revolved) {
                self.vtu_error(e);
            }
        }
        self.write_history(plan);
    }

    fn finished(&mut self, plan: &Plan, summary: &RunSummary) {
        if self.piece_only {
            self.write_last_fields(plan);
        } else {
            self.finished_summary(plan, summary);
        }
    }
}

impl OutputWriter {
    /// A `summary.json` with `status = "running"` and the records so far: a run that is killed
    /// (no chance to write its summary) still leaves one that says it did not finish.
    fn write_running_summary(&mut self, plan: &Plan) {
        let provisional = RunSummary {
            converged: false,
            error: Some("the run has not finished (it is running, or it was killed)".into()),
            stages: Vec::new(),
            wall_s: self.started.elapsed().as_secs_f64(),
            dofs: plan.whole_nodes() * crate::fem::FIELDS,
            warnings: Vec::new(),
            interrupted: false,
        };
        let mut json = self.summary_json(plan, &provisional);
        json["status"] = serde_json::json!("running");
        let text = serde_json::to_string_pretty(&json).unwrap_or_else(|_| "{}".into());
        if let Err(e) = write_atomic(&self.dir.join("summary.json"), text.as_bytes()) {
            self.failed(format!("{}: {e}", self.dir.join("summary.json").display()));
        }
    }

    /// The last converged state is always in the field files.
    fn write_last_fields(&mut self, plan: &Plan) {
        if self.last_written_step != Some(self.steps_seen.saturating_sub(1)) {
            if let Some((r, s, f)) = self.last_state.take() {
                self.write_fields(plan, &r, &s, &f);
            }
        }
    }

    fn finished_summary(&mut self, plan: &Plan, summary: &RunSummary) {
        self.write_last_fields(plan);
        self.write_history(plan);
        if !self.path.is_empty() {
            let path = self.dir.join("path.csv");
            let text = Self::path_csv(plan, &self.path);
            if let Err(e) = write_atomic(&path, text.as_bytes()) {
                self.failed(format!("{}: {e}", path.display()));
            }
        }
        if let Some(text) = crate::io::periods::periods_csv(plan, &self.records) {
            let path = self.dir.join("periods.csv");
            if let Err(e) = write_atomic(&path, text.as_bytes()) {
                self.failed(format!("{}: {e}", path.display()));
            }
        }
        self.write_plots(plan);
        let json = self.summary_json(plan, summary);
        let text = serde_json::to_string_pretty(&json).unwrap_or_else(|_| "{}".into());
        if let Err(e) = write_atomic(&self.dir.join("summary.json"), text.as_bytes()) {
            self.failed(format!("{}: {e}", self.dir.join("summary.json").display()));
        }
    }
}

/// Adds `key` = `value` to the `summary.json` of the run in `dir` (a value computed from the
/// whole run after it ended: the objective of its `[[objective]]` terms).
pub fn add_to_summary(dir: &Path, key: &str, value: serde_json::Value) -> Result<(), String> {
    let path = dir.join("summary.json");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut doc: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let Some(map) = doc.as_object_mut() else {
        return Err(format!("{}: not a JSON object", path.display()));
    };
    map.insert(key.to_string(), value);
    let text = serde_json::to_string_pretty(&doc).unwrap_or_default() + "\n";
    crate::io::atomic::write_atomic(&path, text.as_bytes())
        .map_err(|e| format!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The running files are rewritten every 2 s while a rewrite is cheap, and at most every 20
    /// times its cost once it is not (a history of many steps): under 5 % of the run.
    #[test]
    fn the_running_files_are_rewritten_at_a_bounded_share_of_the_run() {
        assert!(!flush_due(1.9, 0.0));
        assert!(flush_due(2.1, 0.0));
        assert!(flush_due(2.1, 0.1));
        // a rewrite of 0.5 s waits 10 s
        assert!(!flush_due(9.9, 0.5));
        assert!(flush_due(10.1, 0.5));
    }

    /// The plan of a scenario of `scenarios/` with `--set` overrides.
    fn scenario_plan(file: &str, overrides: &[&str]) -> Plan {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenarios")
            .join(file);
        let text = std::fs::read_to_string(&path).expect("scenario");
        let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
        let s = crate::io::scenario::parse(&text, file, &overrides).expect("parse");
        crate::io::build::build(&s, file, path.parent()).expect("build")
    }

    /// A record of stage `stage` at `time` with `voltage` and the probe values `probes`.
    fn record(stage: &str, step: usize, time: f64, voltage: f64, probes: Vec<f64>) -> StepRecord {
        StepRecord {
            time,
            stage: stage.into(),
            step,
            voltage,
            newton_iterations: 0,
            dt: 0.0,
            energies: Default::default(),
            probes,
            max_electric_field: 0.0,
            electrodes: Vec::new(),
        }
    }

    fn find<'a>(plots: &'a [RunPlot], file: &str) -> &'a RunPlot {
        plots
            .iter()
            .find(|p| p.file == file)
            .unwrap_or_else(|| panic!("no plot {file}"))
    }

    /// A probe against the voltage gets one curve per stage in which the voltage varies: the
    /// diaphragm's load stage (voltage 0, the sag grows) draws no vertical line in front of the
    /// actuation loop, and the curve starts at the state the stage starts from.
    #[test]
    fn probes_against_the_voltage_are_drawn_per_stage_where_it_varies() {
        let plan = scenario_plan(
            "diaphragm.toml",
            &["electrodes.top.voltage={waveform=\"sine\",amplitude=3000.0,frequency=2.0}"],
        );
        let n = plan.probes.len();
        let mut records = vec![record("load", 0, 0.0, 0.0, vec![0.0; n])];
        for k in 1..=4 {
            records.push(record(
                "load",
                k,
                0.25 * k as f64,
                0.0,
                vec![1e-4 * k as f64; n],
            ));
        }
        for k in 1..=8 {
            let t = 1.0 + 0.0625 * k as f64;
            let v = 3000.0 * (2.0 * std::f64::consts::PI * 2.0 * (t - 1.0)).sin().powi(2);
            records.push(record("actuate", k, t, v, vec![4e-4 + 1e-8 * v; n]));
        }
        let plots = run_plots(&plan, &records, &[], &[]);
        let vs = find(&plots, "center_deflection_vs_voltage");
        let series = &vs.panels[0].series;
        assert_eq!(series.len(), 1, "{series:?}");
        assert_eq!(series[0].label, "actuate");
        // the stage's start (the load stage's last state) and its 8 steps
        assert_eq!(series[0].x.len(), 9);
        assert_eq!((series[0].x[0], series[0].y[0]), (0.0, 4e-4));
        assert_eq!(
            vs.panels[0].title,
            "center_deflection against the voltage in stage actuate"
        );
        // the time axis says that the static stage's time is pseudo-time
        let c = find(&plots, "center_deflection");
        assert_eq!(
            c.panels[0].x_label,
            "time, pseudo-time in static stages [s]"
        );
        // a run whose voltage never varies has no such plot
        let mut held = records.clone();
        held.iter_mut().for_each(|r| r.voltage = 0.0);
        let plots = run_plots(&plan, &held, &[], &[]);
        assert!(!plots.iter().any(|p| p.file.ends_with("_vs_voltage")));
    }

    /// A continuation stage is drawn against its path (arc length), so that nothing runs back
    /// where the load falls past its maximum; the axis says it is pseudo-time; the stage's
    /// parameter is drawn against every probe along the path, with its limit points.
    #[test]
    fn continuation_stages_plot_their_path() {
        let plan = scenario_plan("balloon.toml", &[]);
        let n = plan.probes.len();
        let stretch = plan
            .probes
            .iter()
            .position(|(p, _)| p == "stretch")
            .unwrap();
        let mut records = vec![record("charge", 0, 0.0, 0.0, vec![1.0; n])];
        for k in 1..=4 {
            records.push(record(
                "charge",
                k,
                0.25 * k as f64,
                1250.0 * k as f64,
                vec![1.0; n],
            ));
        }
        // the load rises, falls past a maximum and rises again; the arc length grows
        let loads = [0.2, 0.5, 0.4, 0.3, 0.6];
        let mut path = Vec::new();
        for (k, &s) in loads.iter().enumerate() {
            let mut probes = vec![1.0; n];
            probes[stretch] = 1.0 + 0.5 * (k + 1) as f64;
            records.push(record("inflate", k + 1, 1.0 + s, 5e3, probes.clone()));
            path.push(PathRecord {
                stage: "inflate".into(),
                point: k + 1,
                load_factor: s,
                parameter: 1e4 * s,
                arc_length: 0.1 * (k + 1) as f64,
                negative_pivots: None,
                stable: true,
                probes,
            });
        }
        let limits = [LimitRecord {
            stage: "inflate".into(),
            maximum: true,
            load_factor: 0.5,
            parameter: 5e3,
            probes: vec![2.0; n],
        }];
        let plots = run_plots(&plan, &records, &path, &limits);
        let s = &find(&plots, "stretch").panels[0];
        assert!(s.x_label.starts_with("pseudo-time"), "{}", s.x_label);
        let x = &s.series[0].x;
        assert!(x.windows(2).all(|w| w[1] >= w[0]), "{x:?}");
        assert_eq!(x[4], 1.0);
        assert!(
            (x[9] - 2.0).abs() < 1e-12 && (x[5] - 1.2).abs() < 1e-12,
            "{x:?}"
        );
        // the balloon's result: pressure against stretch through the maximum
        let p = &find(&plots, "inflate_path_stretch").panels[0];
        assert_eq!(p.x_label, "stretch [-]");
        assert_eq!(p.y_label, "pressure_0 [Pa]");
        assert_eq!(p.series[0].y, vec![2e3, 5e3, 4e3, 3e3, 6e3]);
        assert_eq!(p.series[0].x, vec![1.5, 2.0, 2.5, 3.0, 3.5]);
        assert_eq!(p.series[1].label, "limit points");
        assert_eq!(p.series[1].y[1], 5e3);
        // only the charge stage varies the voltage
        let vs = &find(&plots, "stretch_vs_voltage").panels[0];
        assert_eq!(vs.series.len(), 1);
        assert_eq!(vs.series[0].label, "charge");
    }

    /// The field files a run may leave, serial and shared: each with its index; nothing else.
    #[test]
    fn field_file_names() {
        for (name, index) in [
            ("step_00012.vtu", Some(12)),
            ("revolved_00003.vtu", Some(3)),
            ("step_00012.pvtu", Some(12)),
            ("step_00012_p0001.vtu", Some(12)),
            ("step_00012_p01.vtu", None),
            ("step_0012.vtu", None),
            ("revolved_00003.pvtu", None),
            ("step_00012_p0001.pvtu", None),
            ("notes.vtu", None),
        ] {
            assert_eq!(field_file_index(name), index, "{name}");
        }
    }
}
