//! What a run gives back to a program: the summary, the history by named columns, statistics of
//! the probes and, on request, the nodal values and cell fields of steps.

use crate::element::CellFields;
use crate::job::observer::Observer;
use crate::job::plan::Plan;
use crate::job::state::{RunSummary, StepRecord};

/// Which steps' nodal values and cell fields a run keeps for its [`Results`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum FieldsKept {
    /// None (the history and summary only).
    #[default]
    None,
    /// The last accepted step's.
    Last,
    /// Every accepted step's.
    Every,
}

/// The nodal values and cell fields of one accepted step.
#[derive(Debug, Clone)]
pub struct StepFields {
    /// The index of the step in [`Results::records`].
    pub record: usize,
    /// u (m) and Φ (V) per node, 4 per node.
    pub nodal: Vec<f64>,
    /// The cell fields (electric field, stresses, volume ratio).
    pub cells: Vec<CellFields>,
}

/// The history of a run as columns: the numeric columns of `history.csv` under their names
/// (`time`, `voltage`, the energies, `probe:<name>`, `dt`, …) and the stage of every row.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct History {
    /// The stage of each row.
    pub stage: Vec<String>,
    /// (name, values): one value per row.
    pub columns: Vec<(String, Vec<f64>)>,
}

impl History {
    /// The history of `records` of `plan`.
    pub fn of(plan: &Plan, records: &[StepRecord]) -> History {
        let mut columns: Vec<(String, Vec<f64>)> = Vec::new();
        let mut push = |name: String, f: &dyn Fn(&StepRecord) -> f64| {
            columns.push((name, records.iter().map(f).collect()));
        };
        push("time".into(), &|r| r.time);
        push("step".into(), &|r| r.step as f64);
        push("voltage".into(), &|r| r.voltage);
        push("newton_iterations".into(), &|r| r.newton_iterations as f64);
        push("kinetic".into(), &|r| r.energies.kinetic);
        push("stored".into(), &|r| r.energies.stored);
        push("electric".into(), &|r| r.energies.electric);
        push("gravity".into(), &|r| r.energies.gravity);
        push("dissipated".into(), &|r| r.energies.dissipated);
        push("energy_error".into(), &|r| r.energies.energy_error);
        for (i, (name, _)) in plan.probes.iter().enumerate() {
            push(format!("probe:{name}"), &move |r| {
                r.probes.get(i).copied().unwrap_or(f64::NAN)
            });
        }
        push("dt".into(), &|r| r.dt);
        push("max_electric_field".into(), &|r| r.max_electric_field);
        History {
            stage: records.iter().map(|r| r.stage.clone()).collect(),
            columns,
        }
    }

    /// The values of column `name`.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.columns
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }

    /// The names of the columns, in order.
    pub fn names(&self) -> Vec<&str> {
        self.columns.iter().map(|(n, _)| n.as_str()).collect()
    }
}

/// Statistics of one probe over the accepted steps of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeStatistics {
    pub name: String,
    pub first: f64,
    pub last: f64,
    pub min: f64,
    pub max: f64,
}

/// The results of a run.
#[derive(Debug, Clone)]
pub struct Results {
    /// The run's outcome (converged, error, stages, wall time, warnings).
    pub summary: RunSummary,
    /// Every accepted step, in order.
    pub records: Vec<StepRecord>,
    /// The history as named columns.
    pub history: History,
    /// Per probe: its first, last, smallest and largest value.
    pub probes: Vec<ProbeStatistics>,
    /// The kept steps' nodal values and cell fields ([`FieldsKept`]).
    pub fields: Vec<StepFields>,
}

impl Results {
    /// The statistics of probe `name`.
    pub fn probe(&self, name: &str) -> Option<&ProbeStatistics> {
        self.probes.iter().find(|p| p.name == name)
    }
}

/// The observer that gathers a run's [`Results`].
pub(super) struct Collector {
    pub keep: FieldsKept,
    pub records: Vec<StepRecord>,
    pub fields: Vec<StepFields>,
    pub summary: Option<RunSummary>,
}

impl Collector {
    pub fn new(keep: FieldsKept) -> Self {
        Collector {
            keep,
            records: Vec::new(),
            fields: Vec::new(),
            summary: None,
        }
    }

    fn keep_fields(&mut self, nodal: &[f64], cells: &[CellFields]) {
        let kept = StepFields {
            record: self.records.len().saturating_sub(1),
            nodal: nodal.to_vec(),
            cells: cells.to_vec(),
        };
        match self.keep {
            FieldsKept::None => {}
            FieldsKept::Last => self.fields = vec![kept],
            FieldsKept::Every => self.fields.push(kept),
        }
    }

    /// The results, with the summary the run ended with.
    pub fn results(self, plan: &Plan, summary: RunSummary) -> Results {
        let history = History::of(plan, &self.records);
        let probes = plan
            .probes
            .iter()
            .enumerate()
            .map(|(i, (name, _))| {
                let values: Vec<f64> = self.records.iter().map(|r| r.probes[i]).collect();
                ProbeStatistics {
                    name: name.clone(),
                    first: values.first().copied().unwrap_or(f64::NAN),
                    last: values.last().copied().unwrap_or(f64::NAN),
                    min: values.iter().copied().fold(f64::INFINITY, f64::min),
                    max: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                }
            })
            .collect();
        Results {
            summary,
            records: self.records,
            history,
            probes,
            fields: self.fields,
        }
    }
}

impl Observer for Collector {
    fn step(&mut self, _plan: &Plan, record: &StepRecord, state: &[f64], fields: &[CellFields]) {
        self.records.push(record.clone());
        self.keep_fields(state, fields);
    }

    fn resumed(
        &mut self,
        _plan: &Plan,
        records: &[StepRecord],
        state: &[f64],
        fields: &[CellFields],
    ) {
        self.records = records.to_vec();
        self.keep_fields(state, fields);
    }

    fn finished(&mut self, _plan: &Plan, summary: &RunSummary) {
        self.summary = Some(summary.clone());
    }
}
