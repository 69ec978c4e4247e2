//! The accepted steps of a dynamic stage as its adjoint asks for them, from the last to the
//! first: read from the tape ([`super::dynamic::Held`]), or recomputed from the stage's checkpoints
//! ([`Recompute`]) when the tape kept only those (a run beyond its memory budget).
//!
//! The checkpoints of the forward run split the stage into segments of `spacing` steps (the
//! last one shorter), reversed from the last to the first. A segment that fits the memory left
//! is run once from its checkpoint and taped whole; a longer one is reversed by the binomial
//! schedule of [`super::binomial`] with the snapshots and the window of taped steps the memory
//! allows. Each run restarts the integrator from a checkpoint with its resume point, which
//! refactors the held matrices where the forward run had factored them, so that the recomputed
//! steps are the forward run's, bit for bit; a recomputed level that differs from a checkpoint
//! of the forward run or from its last step is an error, not a silently wrong gradient.
//!
//! Two levels, not an online schedule (Stumm & Walther, SIAM J. Sci. Comput. 32 (2010) 836;
//! Wang, Moin & Iaccarino, SIAM J. Sci. Comput. 31 (2009) 2549): an adaptive stage's step count
//! is known only at its end, and evenly spaced checkpoints, thinned by halves as the stage
//! grows, need no prediction; inside a segment, whose length is then known, revolve's offline
//! schedule is optimal. When the segments fit the memory left, every step is recomputed once.

use super::binomial::{schedule, Action};
use super::dynamic::Steps;
use super::tape::{Checkpoint, Replay, Resume, TapedDynamics, TapedStage, TapedStep};
use crate::problem::points::PointStates;
use crate::time::integrator::TimeLevel;
use crate::time::stage::{run_dynamic_while, DynamicInputs};
use std::collections::{BTreeMap, VecDeque};

/// The steps of a stage kept as checkpoints, recomputed segment by segment.
pub struct Recompute<'t> {
    st: &'t TapedStage,
    replay: &'t Replay,
    dynamics: &'t TapedDynamics,
    /// The bytes the snapshots and the taped window may take, and those the tape holds.
    room: usize,
    base: usize,
    /// The current segment: its checkpoint's index and the actions left of its schedule.
    segment: Option<usize>,
    actions: VecDeque<Action>,
    snapshots: BTreeMap<usize, Checkpoint>,
    window: BTreeMap<usize, TapedStep>,
    held: usize,
    /// The most bytes held (the tape's included), the steps recomputed and the restarts of the
    /// integrator.
    pub peak: usize,
    pub recomputed: usize,
    pub restarts: usize,
}

impl<'t> Recompute<'t> {
    /// The recomputation of `st` (a checkpointed dynamic stage) within `budget` bytes, of which
    /// the tape holds `base`.
    pub fn new(st: &'t TapedStage, budget: usize, base: usize) -> Result<Self, String> {
        let (Some(replay), Some(dynamics)) = (st.replay.as_ref(), st.dynamics.as_ref()) else {
            return Err("a stage without checkpoints given to the recomputation".into());
        };
        Ok(Recompute {
            st,
            replay,
            dynamics,
            room: budget.saturating_sub(base),
            base,
            segment: None,
            actions: VecDeque::new(),
            snapshots: BTreeMap::new(),
            window: BTreeMap::new(),
            held: 0,
            peak: base,
            recomputed: 0,
            restarts: 0,
        })
    }

    /// Starts the segment that holds step `k`: its schedule from the memory left.
    fn begin_segment(&mut self, k: usize) -> Result<(), String> {
        let cks = &self.replay.checkpoints;
        let i = cks.partition_point(|c| c.step <= k).saturating_sub(1);
        if self.segment == Some(i) {
            return Err(format!(
                "the recomputation's schedule did not reach step {k} (a defect of the schedule)"
            ));
        }
        self.segment = Some(i);
        self.actions.clear();
        self.snapshots.clear();
        self.window.clear();
        self.held = 0;
        let start = cks[i].step;
        let end = cks.get(i + 1).map_or(self.replay.dts.len(), |c| c.step);
        let l = end - start;
        let step = self.st.last_step().bytes().max(1);
        let snapshot = cks
            .iter()
            .map(Checkpoint::bytes)
            .max()
            .unwrap_or(0)
            .max(step);
        let (snapshots, window) = if (l + 1) * step <= self.room {
            (0, l)
        } else {
            let w = (self.room / 2 / step).max(1);
            (self.room.saturating_sub((w + 1) * step) / snapshot, w)
        };
        self.actions = schedule(l, snapshots, window)
            .into_iter()
            .map(|a| match a {
                Action::Run {
                    from,
                    to,
                    store,
                    tape,
                } => Action::Run {
                    from: from + start,
                    to: to + start,
                    store: store.into_iter().map(|j| j + start).collect(),
                    tape: tape.start + start..tape.end + start,
                },
                Action::Reverse(r) => Action::Reverse(r.start + start..r.end + start),
                Action::Free(j) => Action::Free(j + start),
            })
            .collect();
        Ok(())
    }

    /// The checkpoint of level `j`: a snapshot of this segment's or the forward run's.
    fn checkpoint(&self, j: usize) -> Option<&Checkpoint> {
        self.snapshots.get(&j).or_else(|| {
            let cks = &self.replay.checkpoints;
            cks.binary_search_by_key(&j, |c| c.step)
                .ok()
                .map(|i| &cks[i])
        })
    }

    /// Runs the stage from level `from` to level `to`, storing the levels `store` and taping
    /// the steps `tape` (and the one before them).
    fn run(
        &mut self,
        from: usize,
        to: usize,
        store: &[usize],
        tape: std::ops::Range<usize>,
    ) -> Result<(), String> {
        let (st, replay, dynamics) = (self.st, self.replay, self.dynamics);
        let ck = self
            .checkpoint(from)
            .ok_or_else(|| format!("no checkpoint at step {from} to recompute from"))?;
        let level = TimeLevel {
            t: ck.t,
            q: ck.record.state.clone(),
            v: ck.record.v.clone(),
            a: ck.record.a.clone(),
        };
        let points = match ck.resume {
            None => replay.start_points.clone(),
            Some(_) => PointStates::from_data(&st.model, &ck.record.points),
        };
        let resume = ck.resume.as_ref().map(Resume::point);
        let inputs = DynamicInputs {
            mass: &dynamics.mass,
            viscosity: dynamics.viscosity.clone(),
            drive: st.drive.clone(),
            points,
            part: None,
        };
        let last = st.last_step();
        let n = replay.dts.len();
        let mut j = from;
        let mut departed: Option<usize> = None;
        let (window, snapshots) = (&mut self.window, &mut self.snapshots);
        let (held, peak, base) = (&mut self.held, &mut self.peak, self.base);
        let recomputed = &mut self.recomputed;
        self.restarts += 1;
        let outcome = run_dynamic_while(
            &st.model,
            &inputs,
            level,
            &replay.settings,
            &replay.newton,
            resume,
            |level, info| {
                j += 1;
                *recomputed += 1;
                let k = j - 1;
                let taped = tape.contains(&k) || (k + 1 == tape.start && tape.start > from);
                let stored = store.contains(&j);
                let forward = replay
                    .checkpoints
                    .binary_search_by_key(&j, |c| c.step)
                    .ok()
                    .map(|i| &replay.checkpoints[i].record);
                let check = forward.or((j == n).then_some(last));
                if taped || stored || check.is_some() {
                    let record = TapedStep::time_step(replay.clock, level, info);
                    if let Some(f) = check {
                        if f.state != record.state || f.v != record.v || f.points != record.points {
                            departed = Some(j);
                        }
                    }
                    if stored {
                        let c = Checkpoint::after(j, &record, level, info);
                        *held += c.bytes();
                        snapshots.insert(j, c);
                    }
                    if taped {
                        *held += record.bytes();
                        if let Some(old) = window.insert(k, record) {
                            *held -= old.bytes();
                        }
                    }
                    *peak = (*peak).max(base + *held);
                }
                j < to && departed.is_none()
            },
        );
        if let Err((_, f)) = outcome {
            return Err(format!(
                "recomputing the steps from step {from}: {} (at t = {:e} s)",
                f.reason, f.t
            ));
        }
        if let Some(j) = departed {
            return Err(format!(
                "the recomputed step {j} differs from the forward run's: the stage's replay is \
                 not bit for bit"
            ));
        }
        if j != to {
            return Err(format!(
                "the recomputation from step {from} ended at step {j}, not {to}"
            ));
        }
        Ok(())
    }

    /// Whether step `k` and the level it starts from are held.
    fn ready(&self, k: usize) -> bool {
        self.window.contains_key(&k)
            && (k == 0 || self.window.contains_key(&(k - 1)) || self.checkpoint(k).is_some())
    }
}

impl Steps for Recompute<'_> {
    fn step(&mut self, k: usize) -> Result<(Option<&TapedStep>, &TapedStep), String> {
        // the steps after k are swept
        let done = self.window.split_off(&(k + 1));
        self.held -= done.values().map(TapedStep::bytes).sum::<usize>();
        while !self.ready(k) {
            match self.actions.pop_front() {
                None => self.begin_segment(k)?,
                Some(Action::Run {
                    from,
                    to,
                    store,
                    tape,
                }) => self.run(from, to, &store, tape)?,
                Some(Action::Reverse(_)) => {}
                Some(Action::Free(j)) => {
                    if let Some(c) = self.snapshots.remove(&j) {
                        self.held -= c.bytes();
                    }
                }
            }
        }
        let step = &self.window[&k];
        let prev = match k {
            0 => None,
            _ => Some(match self.window.get(&(k - 1)) {
                Some(p) => p,
                None => &self.checkpoint(k).expect("ready").record,
            }),
        };
        Ok((prev, step))
    }
}
