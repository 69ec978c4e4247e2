//! The recorder of a run: evaluates the record of every accepted state (energies with the
//! discrete energy balance, probes, cell fields) and watches the dielectric strength.

use super::plan::Plan;
use super::probes::ProbeInput;
use super::state::RecorderState;
use super::state::{Energies, StepRecord};
use crate::element::CellFields;
use crate::problem::dofs::FIELDS;
use crate::problem::points::PointStates;
use crate::problem::statics::record_with;

/// Where a material's dielectric strength is first exceeded: the cell (in the whole mesh), its
/// true field (V/m) and its centre (m).
pub(super) type Breakdown = Option<(usize, f64, [f64; 3])>;

/// Accumulates the work of the prescribed values and evaluates records.
pub(super) struct Recorder<'p> {
    pub(super) plan: &'p Plan,
    pub(super) prev_reactions: Vec<f64>,
    pub(super) prev_state: Vec<f64>,
    pub(super) boundary_work: f64,
    pub(super) initial_potential: Option<f64>,
    /// Nodal forces of the tractions at full value (empty without tractions).
    pub(super) traction: Vec<f64>,
    /// Nodal forces of gravity and attached masses at full value (empty without).
    pub(super) weight: Vec<f64>,
    /// Load factor of the dead loads at the state being recorded.
    pub(super) external_factor: f64,
    /// The dead-load factor jumps to `external_factor` at the start of the step (dynamic stages)
    /// instead of ramping with it (static stages).
    pub(super) sudden_loads: bool,
    pub(super) prev_factor: f64,
    pub(super) prev_external: Vec<f64>,
    /// Work of changing the weight load factor at fixed positions, −∫ f·u dλ (J).
    pub(super) load_change_work: f64,
    /// The state deflections are measured from (the pre-stretched state; zero without).
    pub(super) reference: Vec<f64>,
    /// Materials whose dielectric strength has been exceeded (reported once each).
    pub(super) broken_down: Vec<bool>,
    /// Warnings raised while recording (breakdown).
    pub(super) warnings: Vec<String>,
    /// Per electrode: energy delivered by its circuit's source and lost in its resistance (J,
    /// whole device).
    pub(super) circuit_energy: Vec<(f64, f64)>,
    /// Whether the records are time steps of a dynamic stage, where circuits carry current
    /// (static stages hold them at their source's voltage).
    pub(super) circuit_current: bool,
    /// The fraction of each pressure at the state being recorded, and at the previous record.
    pub(super) pressure_now: Vec<f64>,
    /// The drive's free charges at the state being recorded (node, C of the meshed part): a
    /// charge −Q on a potential equation works like a force, −Q·ΔΦ.
    pub(super) charges_now: Vec<(usize, f64)>,
    pub(super) prev_pressure: Vec<f64>,
    /// Every record so far (kept for checkpoints only).
    pub(super) history: Vec<StepRecord>,
    pub(super) keep_history: bool,
    /// Committed internal variables of the material points at the state being recorded.
    pub(super) points: PointStates,
}

impl<'p> Recorder<'p> {
    /// Evaluates the record of an accepted state. `prescribed` flags the dofs whose values are
    /// prescribed (their reactions do work on the body); `kinetic` and `dissipated` come from the
    /// time integrator (0 in statics).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn record(
        &mut self,
        state: &[f64],
        prescribed: &[bool],
        time: f64,
        stage: &str,
        step: usize,
        iterations: usize,
        dt: f64,
        kinetic: f64,
        dissipated: f64,
    ) -> Result<(StepRecord, Vec<CellFields>), String> {
        let model = &self.plan.model;
        let cells = record_with(model, state, &self.points)?;
        let (reactions, (stored, electric), fields) =
            (cells.reactions, cells.energies, cells.fields);
        // work done on the body, by the trapezoidal rule: reactions at prescribed dofs
        // Σ ½(R₀ + R₁)·(x₁ − x₀) and external (traction) forces at free dofs
        let mut external: Vec<f64> = self
            .traction
            .iter()
            .map(|t| t * self.external_factor)
            .collect();
        if !self.charges_now.is_empty() {
            external.resize(state.len(), 0.0);
            for &(node, q) in &self.charges_now {
                external[node * FIELDS + 3] -= q;
            }
        }
        if !self.prev_state.is_empty() {
            for d in 0..state.len() {
                if !prescribed[d] && !external.is_empty() {
                    let prev = self.prev_external.get(d).copied().unwrap_or(0.0);
                    self.boundary_work +=
                        0.5 * (prev + external[d]) * (state[d] - self.prev_state[d]);
                }
                if prescribed[d] {
                    self.boundary_work += 0.5
                        * (self.prev_reactions[d] + reactions[d])
                        * (state[d] - self.prev_state[d]);
                }
            }
        }
        // gravity: potential −λ f·u of the weights; changing λ at fixed u does work −Δλ f·ū
        let weight_dot = |u: &[f64]| -> f64 { self.weight.iter().zip(u).map(|(f, x)| f * x).sum() };
        let gravity = -self.external_factor * weight_dot(state);
        if !self.prev_state.is_empty() && !self.weight.is_empty() {
            // a ramp changes λ along with u (trapezoidal mean); a dynamic stage switches the
            // loads on at once, at the positions it starts from
            let at = if self.sudden_loads {
                weight_dot(&self.prev_state)
            } else {
                0.5 * (weight_dot(state) + weight_dot(&self.prev_state))
            };
            self.load_change_work -= (self.external_factor - self.prev_factor) * at;
        }
        // follower pressures: their work ∫ p dV, by the trapezoidal rule in (p, V)
        if !self.prev_state.is_empty() {
            for (i, pr) in model.pressures.iter().enumerate() {
                let v0 = crate::problem::pressure::enclosed_volume(&pr.faces, &self.prev_state);
                let v1 = crate::problem::pressure::enclosed_volume(&pr.faces, state);
                let fraction = |f: &[f64]| f.get(i).copied().unwrap_or(0.0);
                let p1 = pr.value * fraction(&self.pressure_now);
                // a ramp changes p along with V; a sudden change acts at the start of the step
                let p0 = if self.sudden_loads {
                    p1
                } else {
                    pr.value * fraction(&self.prev_pressure)
                };
                self.boundary_work += 0.5 * (p0 + p1) * (v1 - v0);
            }
        }
        self.prev_pressure.clone_from(&self.pressure_now);
        self.prev_factor = self.external_factor;
        // circuits: the source delivers ½(V_n + V_{n+1})ΔQ to the electrode and R ΔQ²/Δt to the
        // resistance (I = ΔQ/Δt, the step's mean current)
        if self.circuit_current && !self.prev_state.is_empty() && dt > 0.0 {
            let symmetry = self.plan.symmetry_factor;
            for (i, e) in self.plan.electrodes.iter().enumerate() {
                let Some(r) = e.resistance else { continue };
                let charge = |reactions: &[f64]| {
                    -symmetry
                        * e.nodes
                            .iter()
                            .map(|&n| reactions[n * FIELDS + 3])
                            .sum::<f64>()
                };
                let dq = charge(&reactions) - charge(&self.prev_reactions);
                let v = 0.5
                    * (state[e.nodes[0] * FIELDS + 3] + self.prev_state[e.nodes[0] * FIELDS + 3]);
                let loss = r * dq * dq / dt;
                self.circuit_energy[i].0 += v * dq + loss;
                self.circuit_energy[i].1 += loss;
            }
        }
        // on a rank's part each term is its own cells' share: the sums make the whole model's
        let mut sums = [
            kinetic,
            stored,
            electric,
            gravity,
            dissipated,
            self.boundary_work,
            self.load_change_work,
        ];
        self.plan.sum_over_ranks(&mut sums)?;
        let [kinetic, stored, electric, gravity, dissipated, boundary_work, load_change_work] =
            sums;
        let total = kinetic + stored - electric + gravity + dissipated;
        // the first record of a balance is its origin: the work up to it does not count
        let origin = self.initial_potential.is_none();
        let initial = match self.initial_potential {
            Some(v) => v,
            None => {
                self.boundary_work = 0.0;
                self.load_change_work = 0.0;
                self.initial_potential = Some(total);
                total
            }
        };
        // the balance's origin: no work before it
        let (boundary_work, load_change_work) = if origin {
            (0.0, 0.0)
        } else {
            (boundary_work, load_change_work)
        };
        let energy_error = total - initial - boundary_work - load_change_work;
        let voltages = self.plan.electrode_voltages(state)?;
        let voltage = voltages
            .iter()
            .fold(0.0, |m: f64, &v| if v.abs() > m.abs() { v } else { m });
        let (max_electric_field, breakdowns) = self.field_extremes(&fields)?;
        self.check_breakdown(&breakdowns, time, stage);
        let (probes, electrodes) = self.probe_values(
            state,
            &reactions,
            (stored, electric),
            max_electric_field,
            (&self.prev_reactions, dt),
            &voltages,
        )?;
        self.prev_reactions = reactions;
        self.prev_external = external;
        self.prev_state = state.to_vec();
        let record = StepRecord {
            time,
            stage: stage.to_string(),
            step,
            voltage,
            newton_iterations: iterations,
            dt,
            energies: Energies {
                kinetic,
                stored,
                electric,
                gravity,
                dissipated,
                energy_error,
            }
            .scaled(self.plan.symmetry_factor),
            probes,
            max_electric_field,
            electrodes,
        };
        if self.keep_history {
            self.history.push(record.clone());
        }
        Ok((record, fields))
    }

    /// The probes and the electrodes' values (`probes::electrode_values`) at a state with its
    /// reactions, energies (mechanical, electric), largest field, the previous record's
    /// reactions with the time since it (for rates) and the electrodes' voltages. On a rank's
    /// part, the charges and the probes' shares are combined over the ranks (collective).
    fn probe_values(
        &self,
        state: &[f64],
        reactions: &[f64],
        (stored, electric): (f64, f64),
        max_field: f64,
        previous: (&[f64], f64),
        voltages: &[f64],
    ) -> Result<(Vec<f64>, Vec<[f64; 6]>), String> {
        use super::probes::Share;
        let plan = self.plan;
        let electrodes: Vec<(&[usize], f64)> = plan
            .electrodes
            .iter()
            .zip(voltages)
            .map(|(e, &v)| (e.nodes.as_slice(), v))
            .collect();
        let mut charges = super::probes::electrode_charges(&electrodes, reactions, previous.0);
        if plan.part.is_some() {
            let mut flat: Vec<f64> = charges.iter().flat_map(|&(a, b)| [a, b]).collect();
            plan.sum_over_ranks(&mut flat)?;
            charges = flat.chunks(2).map(|c| (c[0], c[1])).collect();
        }
        let pressures: Vec<f64> = plan
            .model
            .pressures
            .iter()
            .zip(&self.pressure_now)
            .map(|(p, f)| p.value * f)
            .collect();
        let input = ProbeInput {
            pressures: &pressures,
            state,
            reactions,
            electrodes: &electrodes,
            stored,
            electric,
            reference: &self.reference,
            max_field,
            symmetry: plan.symmetry_factor,
            previous,
            circuit_energy: &self.circuit_energy,
            charges: &charges,
        };
        let shares: Vec<Share> = plan.probes.iter().map(|(_, p)| p.share(&input)).collect();
        let mut sums: Vec<f64> = Vec::new();
        let mut maxima: Vec<f64> = Vec::new();
        for s in &shares {
            match s {
                Share::Sum(v) => sums.extend_from_slice(v),
                Share::Max(m) => maxima.push(*m),
                Share::Whole => {}
            }
        }
        plan.sum_over_ranks(&mut sums)?;
        plan.max_over_ranks(&mut maxima)?;
        let (mut sums, mut maxima) = (sums.chunks(2), maxima.into_iter());
        let probes = plan
            .probes
            .iter()
            .zip(&shares)
            .map(|((_, p), s)| {
                let combined = match s {
                    Share::Sum(_) => sums.next().map_or([0.0; 2], |c| [c[0], c[1]]),
                    Share::Max(_) => [maxima.next().unwrap_or(f64::NAN), 0.0],
                    Share::Whole => [0.0; 2],
                };
                p.value(&input, combined)
            })
            .collect();
        let electrodes = (0..plan.electrodes.len())
            .map(|e| crate::job::probes::electrode_values(&input, e))
            .collect();
        Ok((probes, electrodes))
    }

    /// The probes at a state that is not recorded (a located limit point): nothing is
    /// accumulated; rate probes (current, power) have no previous record and read 0.
    pub(super) fn probes_at(&self, state: &[f64]) -> Result<Vec<f64>, String> {
        let model = &self.plan.model;
        let cells = record_with(model, state, &self.points)?;
        let (reactions, energies, fields) = (cells.reactions, cells.energies, cells.fields);
        let mut energies = [energies.0, energies.1];
        self.plan.sum_over_ranks(&mut energies)?;
        let (max_field, _) = self.field_extremes(&fields)?;
        let voltages = self.plan.electrode_voltages(state)?;
        Ok(self
            .probe_values(
                state,
                &reactions,
                (energies[0], energies[1]),
                max_field,
                (&[], f64::NAN),
                &voltages,
            )?
            .0)
    }

    /// The bookkeeping for a checkpoint.
    pub(super) fn state(&self) -> RecorderState {
        RecorderState {
            prev_reactions: self.prev_reactions.clone(),
            prev_state: self.prev_state.clone(),
            boundary_work: self.boundary_work,
            initial_potential: self.initial_potential,
            external_factor: self.external_factor,
            prev_factor: self.prev_factor,
            prev_external: self.prev_external.clone(),
            load_change_work: self.load_change_work,
            reference: self.reference.clone(),
            broken_down: self.broken_down.clone(),
            warnings: self.warnings.clone(),
            circuit_energy: self.circuit_energy.clone(),
            prev_pressure: self.prev_pressure.clone(),
        }
    }

    /// Restores the bookkeeping of a checkpoint.
    pub(super) fn restore(&mut self, s: &RecorderState, history: &[StepRecord]) {
        self.prev_reactions = s.prev_reactions.clone();
        self.prev_state = s.prev_state.clone();
        self.boundary_work = s.boundary_work;
        self.initial_potential = s.initial_potential;
        self.external_factor = s.external_factor;
        self.prev_factor = s.prev_factor;
        self.prev_external = s.prev_external.clone();
        self.load_change_work = s.load_change_work;
        self.reference = s.reference.clone();
        self.broken_down = s.broken_down.clone();
        self.warnings = s.warnings.clone();
        self.prev_pressure = s.prev_pressure.clone();
        self.pressure_now = s.prev_pressure.clone();
        if s.circuit_energy.len() == self.circuit_energy.len() {
            self.circuit_energy = s.circuit_energy.clone();
        }
        self.history = history.to_vec();
    }
}

impl Recorder<'_> {
    /// Starts the energy balance afresh: the next record is its initial value (energy_error 0).
    pub(super) fn restart_balance(&mut self) {
        self.initial_potential = None;
        self.boundary_work = 0.0;
        self.load_change_work = 0.0;
    }

    /// The largest true field of a state's cell fields (V/m) and, per material with a
    /// dielectric strength, the first cell where the field exceeds it, with that field and the
    /// cell's centre (m). When processes share the cells, or hold parts of the plan, each holds
    /// its own cells' fields: the result is then over every process's cells (the first in the
    /// whole mesh's numbering), the same on each.
    fn field_extremes(&self, fields: &[CellFields]) -> Result<(f64, Vec<Breakdown>), String> {
        let plan = self.plan;
        let mut max = 0.0f64;
        let mut first: Vec<Breakdown> = vec![None; plan.breakdown.len()];
        // a local cell's number in the whole mesh
        let global = |c: usize| plan.part.as_ref().map_or(c, |p| p.cells[c]);
        for (c, f) in fields.iter().enumerate() {
            max = max.max(f.e_max);
            let m = plan.model.cell_material[c];
            if first[m].is_none() && plan.breakdown[m].is_some_and(|s| f.e_max > s) {
                first[m] = Some((global(c), f.e_max, plan.model.mesh.cell_centroid(c)));
            }
        }
        let gather = |v: &[f64]| -> Option<Result<Vec<Vec<f64>>, String>> {
            if let Some(share) = plan.model.share.as_deref() {
                Some(share.gather(v))
            } else {
                plan.part.as_ref().map(|p| p.gather(v))
            }
        };
        // [largest field, per material: first cell + 1 (0: none), its field and centre]
        let mut local = vec![max];
        for f in &first {
            local.extend_from_slice(
                &f.map_or([0.0; 5], |(c, e, x)| [c as f64 + 1.0, e, x[0], x[1], x[2]]),
            );
        }
        let Some(all) = gather(&local) else {
            return Ok((max, first));
        };
        let all = all?;
        let max = all.iter().map(|v| v[0]).fold(0.0, f64::max);
        for (m, slot) in first.iter_mut().enumerate() {
            let at = 1 + 5 * m;
            *slot = all
                .iter()
                .filter(|v| v[at] > 0.0)
                .map(|v| {
                    (
                        v[at] as usize - 1,
                        v[at + 1],
                        [v[at + 2], v[at + 3], v[at + 4]],
                    )
                })
                .min_by_key(|&(c, _, _)| c);
        }
        Ok((max, first))
    }

    /// Warns (once per material) where the true field first exceeds a material's dielectric
    /// strength (`first`: per material, the first cell where it does and its field, from
    /// [`Recorder::field_extremes`]), and asks the driver to stop when the plan says so.
    pub(super) fn check_breakdown(&mut self, first: &[Breakdown], time: f64, stage: &str) {
        let plan = self.plan;
        // in cell order, as a pass over the cells meets them
        let mut exceeded: Vec<(usize, f64, [f64; 3], usize)> = first
            .iter()
            .enumerate()
            .filter_map(|(m, f)| f.map(|(c, e, x)| (c, e, x, m)))
            .collect();
        exceeded.sort_by_key(|&(c, _, _, _)| c);
        for (c, e_max, centre, m) in exceeded {
            let Some(strength) = plan.breakdown[m] else {
                continue;
            };
            if self.broken_down[m] {
                continue;
            }
            self.broken_down[m] = true;
            let message = format!(
                "dielectric breakdown: true field {:.4e} V/m exceeds the strength {:.4e} V/m of material `{}` at t = {:.6} s (stage `{stage}`), cell {c} at ({:.4e}, {:.4e}, {:.4e}) m",
                e_max,
                strength,
                plan.material_names[m],
                time,
                centre[0],
                centre[1],
                centre[2]
            );
            if plan.stop_at_breakdown {
                crate::solve::interrupt::stop_here(format!("stopped on {message}"));
            }
            self.warnings.push(message);
        }
    }
}

impl Energies {
    /// All energies times `factor` (the symmetry factor of a partial model).
    fn scaled(self, factor: f64) -> Self {
        Energies {
            kinetic: self.kinetic * factor,
            stored: self.stored * factor,
            electric: self.electric * factor,
            gravity: self.gravity * factor,
            dissipated: self.dissipated * factor,
            energy_error: self.energy_error * factor,
        }
    }
}

impl<'p> Recorder<'p> {
    /// A recorder at the start of a run; `keep_history` keeps every record (for checkpoints).
    pub(super) fn new(plan: &'p Plan, keep_history: bool) -> Self {
        let n_nodes = plan.model.mesh.n_nodes();
        Recorder {
            plan,
            prev_reactions: Vec::new(),
            prev_state: Vec::new(),
            boundary_work: 0.0,
            initial_potential: None,
            traction: if plan.model.tractions.is_empty() && plan.model.point_charges.is_empty() {
                Vec::new()
            } else {
                let mut f = crate::problem::loads::traction_forces(
                    &plan.model.mesh,
                    &plan.model.tractions,
                    1.0,
                );
                // a charge −Q on a potential equation works like a force: −Q·ΔΦ
                for &(node, q) in &plan.model.point_charges {
                    f[node * FIELDS + 3] -= q;
                }
                f
            },
            weight: if plan.model.point_forces.is_empty()
                && plan.model.body_force.iter().all(|b| *b == [0.0; 3])
            {
                Vec::new()
            } else {
                plan.model.weight_forces()
            },
            external_factor: 0.0,
            sudden_loads: false,
            prev_factor: 0.0,
            prev_external: Vec::new(),
            load_change_work: 0.0,
            reference: vec![0.0; n_nodes * FIELDS],
            circuit_energy: vec![(0.0, 0.0); plan.electrodes.len()],
            pressure_now: Vec::new(),
            charges_now: Vec::new(),
            prev_pressure: Vec::new(),
            circuit_current: false,
            broken_down: vec![false; plan.model.materials.len()],
            warnings: Vec::new(),
            history: Vec::new(),
            keep_history,
            points: PointStates::default(),
        }
    }
}
