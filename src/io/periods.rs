//! `periods.csv`: statistics of every probe over each full period of a periodic drive, so that a
//! slow drift (creep of the mean position) is told apart from the stroke (peak-to-peak) without
//! post-processing. Written for the dynamic and quasi-static stages whose electrodes follow a
//! periodic waveform (the first such electrode sets the period).

use crate::job::plan::{Plan, StageKind};
use crate::job::state::StepRecord;
use std::fmt::Write as _;

/// The statistics of one probe over one period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeriodStats {
    /// Time-weighted mean (trapezoidal rule over the recorded steps).
    pub mean: f64,
    pub min: f64,
    pub max: f64,
}

/// One full period of a stage.
#[derive(Debug, Clone, PartialEq)]
pub struct Period {
    pub stage: String,
    /// 1 for the first period of the stage.
    pub index: usize,
    pub t_start: f64,
    pub t_end: f64,
    /// Per probe, in plan order.
    pub probes: Vec<PeriodStats>,
}

/// The full periods of every periodically driven stage in `records`.
pub fn periods(plan: &Plan, records: &[StepRecord]) -> Vec<Period> {
    let mut out = Vec::new();
    for stage in &plan.stages {
        if matches!(stage.kind, StageKind::Static { .. })
            || stage.kind.is_linearised()
            || !stage.electrodes_on
        {
            continue;
        }
        let Some(f) = plan
            .electrodes
            .iter()
            .find_map(|e| e.voltage.frequency())
            .filter(|f| *f > 0.0)
        else {
            continue;
        };
        let rows: Vec<&StepRecord> = records
            .iter()
            .filter(|r| r.stage == stage.name && r.step > 0)
            .collect();
        let Some(first) = rows.first() else {
            continue;
        };
        // the stage starts where its first step started
        let t0 = first.time - first.dt;
        let period = 1.0 / f;
        let last = rows.last().map_or(t0, |r| r.time);
        let eps = 1e-9 * period;
        let mut k = 0;
        while t0 + (k + 1) as f64 * period <= last + eps {
            let (a, b) = (t0 + k as f64 * period, t0 + (k + 1) as f64 * period);
            // the samples of [a, b], with the stage's start state before the first step
            let mut samples: Vec<(f64, &[f64])> = Vec::new();
            let before = records
                .iter()
                .rfind(|r| r.time <= a + eps)
                .filter(|r| r.time >= a - eps);
            if let Some(r) = before {
                samples.push((r.time, &r.probes));
            }
            samples.extend(
                rows.iter()
                    .filter(|r| r.time > a + eps && r.time <= b + eps)
                    .map(|r| (r.time, r.probes.as_slice())),
            );
            k += 1;
            if samples.len() < 2 {
                continue;
            }
            let n_probes = samples[0].1.len();
            let probes = (0..n_probes)
                .map(|p| {
                    let mut s = PeriodStats {
                        mean: 0.0,
                        min: f64::INFINITY,
                        max: f64::NEG_INFINITY,
                    };
                    let mut span = 0.0;
                    for w in samples.windows(2) {
                        let (ta, va) = (w[0].0, w[0].1[p]);
                        let (tb, vb) = (w[1].0, w[1].1[p]);
                        if va.is_finite() && vb.is_finite() {
                            s.mean += 0.5 * (va + vb) * (tb - ta);
                            span += tb - ta;
                        }
                    }
                    for (_, v) in &samples {
                        if v[p].is_finite() {
                            s.min = s.min.min(v[p]);
                            s.max = s.max.max(v[p]);
                        }
                    }
                    s.mean = if span > 0.0 { s.mean / span } else { f64::NAN };
                    if s.min > s.max {
                        (s.min, s.max) = (f64::NAN, f64::NAN);
                    }
                    s
                })
                .collect();
            out.push(Period {
                stage: stage.name.clone(),
                index: k,
                t_start: a,
                t_end: b,
                probes,
            });
        }
    }
    out
}

/// The CSV text: `stage,period,t_start,t_end`, then `<probe>:mean,<probe>:min,<probe>:max,
/// <probe>:peak_to_peak` for every probe; `None` when no stage has a full period.
pub fn periods_csv(plan: &Plan, records: &[StepRecord]) -> Option<String> {
    let periods = periods(plan, records);
    if periods.is_empty() {
        return None;
    }
    let mut s = String::from("stage,period,t_start,t_end");
    for (name, _) in &plan.probes {
        let _ = write!(s, ",{name}:mean,{name}:min,{name}:max,{name}:peak_to_peak");
    }
    s.push('\n');
    for p in &periods {
        let _ = write!(s, "{},{},{:e},{:e}", p.stage, p.index, p.t_start, p.t_end);
        for st in &p.probes {
            let _ = write!(
                s,
                ",{:e},{:e},{:e},{:e}",
                st.mean,
                st.min,
                st.max,
                st.max - st.min
            );
        }
        s.push('\n');
    }
    Some(s)
}
