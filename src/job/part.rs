//! A rank's part of a plan: the plan of the cells one MPI rank holds (its part of the mesh, the
//! model, the sets and the probes), with the rank's equations in the whole problem and the
//! exchange through which the ranks combine their parts. A run of such parts holds on each
//! rank only its part's vectors: no rank holds the whole state. Rank 0 alone builds the whole
//! plan, cuts every rank's part ([`messages`]) and sends it; each rank takes its own up
//! ([`receive`]).

use super::plan::{Plan, StageKind};
use super::probes::ProbeKind;
pub use super::rank::PlanPart;
use crate::algebra::exchange::{Exchange, LocalEquations};
use crate::mesh::distribute::{LocalMesh, Numbering};
pub use crate::problem::distributed::Division;
use crate::problem::distributed::{equation_owners, NodeBlocks};
use crate::problem::dofs::{constrained_flags, DofMap, FIELDS};
use crate::problem::model::Model;
use std::sync::Arc;

impl Plan {
    /// Sums `v` over the ranks of a plan divided between them (collective); nothing otherwise.
    pub fn sum_over_ranks(&self, v: &mut [f64]) -> Result<(), String> {
        match &self.part {
            Some(p) => p.stages.exchange.sum(v),
            None => Ok(()),
        }
    }

    /// The largest of each entry of `v` over the ranks of a divided plan (collective); nothing
    /// otherwise.
    pub fn max_over_ranks(&self, v: &mut [f64]) -> Result<(), String> {
        match &self.part {
            Some(p) => p.max(v),
            None => Ok(()),
        }
    }

    /// Each electrode's potential (V) in `state`, at its first node: on a rank's part, taken
    /// from the rank that owns that node (collective).
    pub fn electrode_voltages(&self, state: &[f64]) -> Result<Vec<f64>, String> {
        let Some(part) = &self.part else {
            return Ok(self
                .electrodes
                .iter()
                .map(|e| state[e.nodes[0] * FIELDS + 3])
                .collect());
        };
        let mut v: Vec<f64> = part
            .electrode_first
            .iter()
            .map(|n| n.map_or(0.0, |n| state[n * FIELDS + 3]))
            .collect();
        part.stages.exchange.sum(&mut v)?;
        Ok(v)
    }

    /// The whole mesh's node count (of every rank's part together).
    pub fn whole_nodes(&self) -> usize {
        self.part
            .as_ref()
            .map_or(self.model.mesh.n_nodes(), |p| p.whole_nodes)
    }

    /// The whole mesh's cell count.
    pub fn whole_cells(&self) -> usize {
        self.part
            .as_ref()
            .map_or(self.model.mesh.n_cells(), |p| p.whole_cells)
    }

    /// Why the plan cannot yet be divided into rank parts (see [`divide`]), or `None`.
    pub fn parts_unsupported(&self) -> Option<String> {
        if let Some(s) = self.stages.iter().find(|s| {
            !matches!(
                s.kind,
                StageKind::Static { .. }
                    | StageKind::QuasiStatic { .. }
                    | StageKind::Dynamic { .. }
                    | StageKind::Continuation { .. }
            )
        }) {
            return Some(format!(
                "stage `{}` is a small-signal analysis (only static, quasi-static, \
                 continuation and dynamic stages run on parts yet)",
                s.name
            ));
        }
        if self.model.is_axisymmetric() {
            return Some("an axisymmetric model is not divided into parts".into());
        }
        if self.electrodes.iter().any(|e| e.resistance.is_some()) {
            return Some("circuit-driven electrodes are not divided into parts yet".into());
        }
        if self.electrodes.iter().any(|e| e.charge_in_drive) {
            return Some(
                "an electrode whose charge follows a waveform or a control is not divided into \
                 parts yet"
                    .into(),
            );
        }
        None
    }
}

/// On rank 0 of `ranks`: every rank's part of `plan` in turn, encoded (the bytes to send it),
/// the whole problem cut once; `fingerprint` (the whole plan's, of its checkpoints) goes to
/// every rank. A part that cannot be made is its error.
///
/// A rank's part: the plan's cells partitioned by METIS ([`Plan::partition`]), each node owned by
/// one rank whose cells meet it, the whole problem's unknowns numbered rank after rank; the
/// rank's plan over its cells and their nodes (owned first, then ghosts). The sets are
/// restricted so that each contribution counts once over the ranks: supports and electrodes keep
/// every node of the part; a probe's mean, point and deflection keep the owned nodes, its
/// reaction and extremes every node of the part (each rank's reactions are those of its own
/// cells). The plan's stages all solve for the same unknowns (static stages: the supports and
/// the electrodes, at their stages' values).
pub fn messages(
    plan: &Plan,
    ranks: usize,
    fingerprint: u64,
) -> Result<impl Iterator<Item = Result<Vec<u8>, String>> + '_, String> {
    let whole = Whole::of(plan, ranks)?;
    Ok((0..ranks).map(move |rank| whole.message(plan, rank, fingerprint)?.encode()))
}

/// The plan of this rank's part from its `message` ([`messages`]) with the plan's `materials`
/// (built from the scenario on every rank: they are code, not data), its exchanges made by
/// `exchange` (for the rank's equations, combining the ranks) once every rank agrees (`agree`,
/// collective) that its message is sound: a rank whose part cannot be made fails, and the
/// others with it, before any exchange is made.
pub fn receive(
    message: &[u8],
    materials: Vec<Arc<dyn crate::material::Material>>,
    rank: usize,
    ranks: usize,
    agree: impl Fn(bool) -> bool,
    exchange: impl Fn(&Arc<LocalEquations>) -> Result<Arc<dyn Exchange>, String>,
) -> Result<Plan, String> {
    let decoded = PartMessage::decode(message, materials, rank, ranks);
    if !agree(decoded.is_ok()) {
        return Err(decoded.err().unwrap_or_else(|| {
            "another rank could not make its part of the plan (its message is on that rank)".into()
        }));
    }
    let PartMessage {
        plan: mut plan_part,
        stages,
        prestretch,
        projection,
        explicit,
        electrode_first,
        cells,
        nodes,
        whole_nodes,
        whole_cells,
        fingerprint,
    } = decoded?;
    let division = |equations: LocalEquations, floor: f64| -> Result<Division, String> {
        let equations = Arc::new(equations);
        Ok(Division {
            exchange: exchange(&equations)?,
            equations,
            floor,
        })
    };
    let optional = |p: Option<(LocalEquations, f64)>| p.map(|(e, f)| division(e, f)).transpose();
    plan_part.part = Some(Arc::new(PlanPart {
        rank,
        ranks,
        cells,
        nodes,
        stages: division(stages.0, stages.1)?,
        prestretch: optional(prestretch)?,
        projection: optional(projection)?,
        explicit: optional(explicit)?,
        whole_nodes,
        whole_cells,
        electrode_first,
        fingerprint,
    }));
    Ok(plan_part)
}

/// What rank 0 sends a rank: the plan of its part (without its materials, which every rank
/// builds from the scenario, and without its [`PlanPart`]); its equations in the whole problem
/// and the whole problem's residual floor, of each problem the plan solves; the local first node
/// of each electrode owned here, the global number of each local cell and node, the whole mesh's
/// counts and the whole plan's fingerprint.
#[derive(serde::Serialize, serde::Deserialize)]
struct PartMessage {
    plan: Plan,
    stages: (LocalEquations, f64),
    prestretch: Option<(LocalEquations, f64)>,
    projection: Option<(LocalEquations, f64)>,
    explicit: Option<(LocalEquations, f64)>,
    electrode_first: Vec<Option<usize>>,
    cells: Vec<usize>,
    nodes: Vec<usize>,
    whole_nodes: usize,
    whole_cells: usize,
    fingerprint: u64,
}

impl PartMessage {
    /// The message as bytes (postcard).
    fn encode(&self) -> Result<Vec<u8>, String> {
        postcard::to_stdvec(self).map_err(|e| format!("cannot encode a rank's part: {e}"))
    }

    /// The message of rank `rank` of `ranks` from its bytes, its plan given its `materials`;
    /// checked to be that rank's.
    fn decode(
        bytes: &[u8],
        materials: Vec<Arc<dyn crate::material::Material>>,
        rank: usize,
        ranks: usize,
    ) -> Result<Self, String> {
        let mut m: PartMessage = postcard::from_bytes(bytes)
            .map_err(|e| format!("rank {rank}: cannot decode its part of the plan: {e}"))?;
        if m.stages.0.rank != rank || m.stages.0.start.len() != ranks + 1 {
            return Err(format!(
                "rank {rank} of {ranks}: received the part of rank {} of {}",
                m.stages.0.rank,
                m.stages.0.start.len().saturating_sub(1)
            ));
        }
        if materials.len() != m.plan.material_names.len() {
            return Err(format!(
                "rank {rank}: {} materials for the plan's {}",
                materials.len(),
                m.plan.material_names.len()
            ));
        }
        m.plan.model.materials = materials;
        Ok(m)
    }
}

/// The problems a plan solves, each on its own unknowns: the stages', the pre-stretch's, the
/// dynamic stages' electrostatic projection (the potentials with every displacement held) and
/// the explicit scheme's velocity equation (the displacements with every potential held).
#[derive(Clone, Copy)]
enum Problem {
    Stages,
    Prestretch,
    Projection,
    Explicit,
}

impl Problem {
    /// The model of this problem on `plan` (the whole plan, or a rank's part of it), whose
    /// `model` holds the first stage's conditions; `None` when the plan does not solve it. Every
    /// stage holds the same supports and prescribed electrodes, so the first dynamic (explicit)
    /// stage's stand for all.
    fn model(self, plan: &Plan) -> Option<Model> {
        let first = plan.stages.first()?;
        let mut model = plan.model.clone();
        let dynamic = |explicit: bool| {
            plan.stages.iter().find(|s| match s.kind {
                StageKind::Dynamic { scheme, .. } => {
                    !explicit || scheme == crate::time::stage::Method::Trapezoidal
                }
                _ => false,
            })
        };
        match self {
            Problem::Stages => {
                plan.stage_conditions(&mut model, first);
                Some(model)
            }
            Problem::Prestretch => {
                plan.prestretch.as_ref()?;
                plan.stage_conditions(&mut model, first);
                Some(super::prestretch::prestretch_model(plan, &model))
            }
            Problem::Projection => {
                plan.stage_conditions(&mut model, dynamic(false)?);
                Some(crate::time::stage::projection_model(&model))
            }
            Problem::Explicit => {
                plan.stage_conditions(&mut model, dynamic(true)?);
                Some(crate::time::trapezoidal::velocity_model(&model))
            }
        }
    }
}

/// A problem's unknowns on the whole mesh, dealt out to the ranks by the rule of its own
/// unknowns (the projection's potentials lie elsewhere than the stages' unknowns), and its
/// residual floor.
struct WholeProblem {
    dofs: DofMap,
    /// The rank that owns each node of the whole mesh, by the rule of this problem's unknowns.
    owner: Vec<usize>,
    numbering: Numbering,
    blocks: NodeBlocks,
    floor: f64,
}

impl WholeProblem {
    fn of(whole: &Model, cells: &[usize], ranks: usize) -> Self {
        let dofs = dofs_of(whole);
        let owner = crate::problem::assembly::node_processes(&whole.mesh, &dofs, cells, ranks);
        let numbering = Numbering::contiguous(&equation_owners(&dofs, &owner), ranks);
        let floor = crate::problem::statics::residual_floor(whole, dofs.n_free);
        WholeProblem {
            blocks: NodeBlocks::new(&dofs, &numbering),
            dofs,
            owner,
            numbering,
            floor,
        }
    }

    /// The equations of rank `local` whose part of the problem is `part`, as the problem on
    /// `part` numbers them, in the whole problem's numbering.
    fn equations(&self, local: &LocalMesh, part: &Model) -> Result<(LocalEquations, f64), String> {
        let equations = LocalEquations::in_blocks(
            &self.blocks,
            &self.dofs,
            &self.numbering,
            local,
            &dofs_of(part),
        )?;
        Ok((equations, self.floor))
    }
}

/// What every rank's part is cut from, made once: the plan's model with the first stage's
/// conditions (for the ties it holds), the partition of its cells, and each problem the plan
/// solves on the whole mesh (the stages' problem gives each node its owner, and so each rank
/// its nodes).
struct Whole {
    ranks: usize,
    model: Model,
    cells: Vec<usize>,
    stages: WholeProblem,
    prestretch: Option<WholeProblem>,
    projection: Option<WholeProblem>,
    explicit: Option<WholeProblem>,
}

impl Whole {
    fn of(plan: &Plan, ranks: usize) -> Result<Self, String> {
        if let Some(why) = plan.parts_unsupported() {
            return Err(why);
        }
        let Some(model) = Problem::Stages.model(plan) else {
            return Err("the plan has no stage".into());
        };
        let cells = plan.partition(ranks);
        let problem = |p: Problem| p.model(plan).map(|m| WholeProblem::of(&m, &cells, ranks));
        Ok(Whole {
            ranks,
            stages: WholeProblem::of(&model, &cells, ranks),
            prestretch: problem(Problem::Prestretch),
            projection: problem(Problem::Projection),
            explicit: problem(Problem::Explicit),
            model,
            cells,
        })
    }

    /// The message of rank `rank`: its plan and its equations of each problem.
    fn message(&self, plan: &Plan, rank: usize, fingerprint: u64) -> Result<PartMessage, String> {
        let mesh = &self.model.mesh;
        let local = LocalMesh::of_rank(mesh, &self.cells, &self.stages.owner, rank, self.ranks)
            .map_err(|e| e.to_string())?;
        let part = plan_of(plan, &self.model, &local)?;
        let equations =
            |p: Problem, whole: &WholeProblem| -> Result<(LocalEquations, f64), String> {
                let model = p
                    .model(&part)
                    .ok_or("a rank's part does not solve a problem of the whole plan")?;
                whole.equations(&local, &model)
            };
        let optional = |p: Problem, whole: &Option<WholeProblem>| {
            whole.as_ref().map(|w| equations(p, w)).transpose()
        };
        let stages = equations(Problem::Stages, &self.stages)?;
        let prestretch = optional(Problem::Prestretch, &self.prestretch)?;
        let projection = optional(Problem::Projection, &self.projection)?;
        let explicit = optional(Problem::Explicit, &self.explicit)?;
        let at = global_to_local(&local, mesh.n_nodes());
        let electrode_first = plan
            .electrodes
            .iter()
            .map(|e| {
                let n = at[e.nodes[0]];
                (n < local.owned).then_some(n)
            })
            .collect();
        Ok(PartMessage {
            plan: part,
            stages,
            prestretch,
            projection,
            explicit,
            electrode_first,
            cells: local.cells,
            nodes: local.nodes,
            whole_nodes: mesh.n_nodes(),
            whole_cells: mesh.n_cells(),
            fingerprint,
        })
    }
}

/// The numbering of `model`'s unknowns (its supports and ties), as its problems number them.
fn dofs_of(model: &Model) -> DofMap {
    let n = model.mesh.n_nodes();
    DofMap::with_ties(
        n,
        &constrained_flags(n, &model.dirichlet),
        model.potential_scale(),
        &model.ties,
    )
}

/// Each whole-mesh node's local number on `local` (`usize::MAX`: not on the part).
fn global_to_local(local: &LocalMesh, n_nodes: usize) -> Vec<usize> {
    let mut at = vec![usize::MAX; n_nodes];
    for (l, &n) in local.nodes.iter().enumerate() {
        at[n] = l;
    }
    at
}

/// The plan of `local`'s part (without its [`PlanPart`]): `whole` is the plan's model with the
/// first stage's conditions (for the ties it holds).
fn plan_of(
    plan: &Plan,
    whole: &crate::problem::model::Model,
    local: &LocalMesh,
) -> Result<Plan, String> {
    let at = global_to_local(local, whole.mesh.n_nodes());
    let all = |list: &[usize]| -> Vec<usize> {
        list.iter()
            .filter(|&&n| at[n] != usize::MAX)
            .map(|&n| at[n])
            .collect()
    };
    let owned = |n: usize| at[n] < local.owned;
    let mut cell_at = vec![usize::MAX; whole.mesh.n_cells()];
    for (l, &c) in local.cells.iter().enumerate() {
        cell_at[c] = l;
    }
    let mut part = plan.clone();
    part.model = whole.part(local).map_err(|e| e.to_string())?;
    part.supports = plan
        .supports
        .iter()
        .map(|d| crate::problem::dofs::Dirichlet {
            nodes: all(&d.nodes),
            ..d.clone()
        })
        .collect();
    for e in &mut part.electrodes {
        e.nodes = all(&e.nodes);
    }
    for r in &mut part.rigid {
        // the attached mass acts once: on the rank that owns the region's first node, which
        // stays its first node here
        if !r.nodes.first().is_some_and(|&n| owned(n)) {
            r.mass = 0.0;
        }
        r.nodes = all(&r.nodes);
    }
    for (_, probe) in &mut part.probes {
        probe.kind = match &probe.kind {
            ProbeKind::Mean(q, nodes, weights) => {
                let (n, w): (Vec<usize>, Vec<f64>) = nodes
                    .iter()
                    .zip(weights)
                    .filter(|(&n, _)| owned(n))
                    .map(|(&n, &w)| (at[n], w))
                    .unzip();
                ProbeKind::Mean(*q, n, w)
            }
            ProbeKind::Max(q, nodes) => ProbeKind::Max(*q, all(nodes)),
            ProbeKind::Min(q, nodes) => ProbeKind::Min(*q, all(nodes)),
            ProbeKind::Point(q, n) => {
                ProbeKind::Point(*q, if owned(*n) { at[*n] } else { usize::MAX })
            }
            ProbeKind::Reaction(c, nodes) => ProbeKind::Reaction(*c, all(nodes)),
            ProbeKind::Deflection(nodes, axial) => ProbeKind::Deflection(
                nodes
                    .iter()
                    .filter(|&&n| owned(n))
                    .map(|&n| at[n])
                    .collect(),
                *axial,
            ),
            // a face on the rank of its cell: each face's share counts once
            ProbeKind::AreaStrain(faces) => ProbeKind::AreaStrain(
                faces
                    .iter()
                    .filter(|f| cell_at[f.cell] != usize::MAX)
                    .map(|f| super::probes::ProbeFace {
                        cell: cell_at[f.cell],
                        nodes: f.nodes.iter().map(|&n| at[n]).collect(),
                        positions: f.positions.clone(),
                        ring: f.ring,
                    })
                    .collect(),
            ),
            ProbeKind::Volume(faces) => ProbeKind::Volume(crate::problem::pressure::faces_on_part(
                faces, &cell_at, &at,
            )),
            other => other.clone(),
        };
    }
    Ok(part)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algebra::exchange::SumExchange;
    use crate::job::observer::Observer;
    use crate::job::recorder::Recorder;
    use crate::job::run::StepRecord;
    use crate::job::state::RunSummary;
    use crate::problem::assembly::on_threads;

    /// The `film` example on 4 × 4 × 2 cells with its weight, a follower pressure on its top and
    /// a probe of every kind a part divides: means over face sets of quantities that vary over
    /// them, a point, extremes, the supports' reaction (the weight), a deflection, charges, the
    /// energies, the largest field, and the sums over faces (area strain, enclosed volume) with
    /// the pressure's value.
    const OVERRIDES: &[&str] = &[
        "mesh.divisions=[4,4,2]",
        "stages.0.steps=4",
        "materials.elastomer.density=1000.0",
        "loads.gravity=[0.0,0.0,-9.81]",
        "probes.spread.kind=\"mean\"",
        "probes.spread.quantity=\"ux\"",
        "probes.spread.set=\"z1\"",
        "probes.side.kind=\"mean\"",
        "probes.side.quantity=\"ux\"",
        "probes.side.set=\"x1\"",
        "probes.highest.kind=\"max\"",
        "probes.highest.quantity=\"uz\"",
        "probes.highest.set=\"z1\"",
        "probes.lowest.kind=\"min\"",
        "probes.lowest.quantity=\"ux\"",
        "probes.lowest.set=\"x1\"",
        "probes.support.kind=\"reaction\"",
        "probes.support.quantity=\"z\"",
        "probes.support.set=\"z0\"",
        "probes.deflection.kind=\"center_deflection\"",
        "probes.deflection.set=\"x1\"",
        "probes.stored.kind=\"energy\"",
        "probes.stored.quantity=\"stored\"",
        "probes.electric.kind=\"energy\"",
        "probes.electric.quantity=\"electric\"",
        "probes.field.kind=\"max_electric_field\"",
        "probes.area.kind=\"area_strain\"",
        "probes.area.set=\"z1\"",
        "probes.volume.kind=\"volume\"",
        "probes.volume.set=\"z1\"",
        "probes.pressure.kind=\"pressure\"",
        "probes.pressure.set=\"z1\"",
        "loads.pressure=[{set=\"z1\",value=2e3}]",
    ];

    /// The last recorded state of a run.
    #[derive(Default)]
    struct Last(Vec<f64>, Option<StepRecord>);

    impl Observer for Last {
        fn step(
            &mut self,
            _: &Plan,
            r: &StepRecord,
            state: &[f64],
            _: &[crate::element::CellFields],
        ) {
            self.0 = state.to_vec();
            self.1 = Some(r.clone());
        }
        fn finished(&mut self, _: &Plan, _: &RunSummary) {}
    }

    fn film() -> Plan {
        film_with(true)
    }

    /// The film's plan; `geometry`: whether it holds its cells' geometry (rank 0 cuts a plan
    /// built without).
    fn film_with(geometry: bool) -> Plan {
        let text = crate::io::examples::example("film").unwrap();
        let overrides: Vec<String> = OVERRIDES.iter().map(|o| o.to_string()).collect();
        let scenario = crate::io::scenario::parse(text, "film.toml", &overrides).unwrap();
        let plan = crate::io::build::build_with(&scenario, "film.toml", None, geometry).unwrap();
        assert_eq!(
            plan.probes.len(),
            16,
            "the example's 4 probes and the 12 added"
        );
        plan
    }

    /// Rank `rank`'s part of `plan` on a thread of [`on_threads`], its exchanges summing over
    /// the threads by `sum` (one sum for every exchange the division makes): the message rank 0
    /// would send it, received with the materials built from the scenario `source` (example
    /// name, overrides) as the other ranks build them.
    fn divide_on_thread(
        plan: &Plan,
        source: (&str, &[&str]),
        rank: usize,
        ranks: usize,
        sum: crate::algebra::exchange::SumOverProcesses,
    ) -> Plan {
        let sum = Arc::new(sum);
        let message = messages(plan, ranks, plan.fingerprint())
            .unwrap()
            .nth(rank)
            .unwrap()
            .unwrap();
        let text = crate::io::examples::example(source.0).unwrap();
        let overrides: Vec<String> = source.1.iter().map(|o| o.to_string()).collect();
        let scenario = crate::io::scenario::parse(text, source.0, &overrides).unwrap();
        let materials = crate::io::build::materials(&scenario, source.0).unwrap();
        receive(
            &message,
            materials,
            rank,
            ranks,
            |ok| ok,
            |eq| {
                let sum = Arc::clone(&sum);
                let exchange =
                    SumExchange::new(Arc::clone(eq), Box::new(move |v: &mut [f64]| sum(v)));
                Ok(Arc::new(exchange) as Arc<dyn Exchange>)
            },
        )
        .unwrap()
    }

    /// The record of `plan` at `state` (its first record: the energy balance's origin).
    fn record(plan: &Plan, state: &[f64]) -> StepRecord {
        let mut model = plan.model.clone();
        let prescribed = plan.stage_conditions(&mut model, &plan.stages[0]);
        let mut rec = Recorder::new(plan, false);
        rec.external_factor = 1.0;
        // the pressures at the end of their ramp
        rec.pressure_now = vec![1.0; plan.model.pressures.len()];
        rec.record(state, &prescribed, 1.0, "charge", 4, 0, 0.25, 0.0, 0.0)
            .unwrap()
            .0
    }

    /// The ranks' records of their parts at the serial run's last state are the serial record:
    /// each probe, the energies, the voltage and the electrodes' values, on 2 and 3 ranks.
    #[test]
    fn the_records_of_the_parts_are_the_whole_record() {
        let plan = film();
        let mut last = Last::default();
        let summary = crate::job::run::run(&plan, &mut last);
        assert!(summary.converged, "{:?}", summary.error);
        let whole = record(&plan, &last.0);
        assert!(
            whole.probes.iter().all(|p| p.is_finite()),
            "{:?}",
            whole.probes
        );
        let probe =
            |name: &str| whole.probes[plan.probes.iter().position(|p| p.0 == name).unwrap()];
        // the top spreads and the pressure acts at its full value
        assert!(probe("area") > 1e-3, "{}", probe("area"));
        assert!(probe("volume").abs() > 0.0);
        assert_eq!(probe("pressure"), 2e3);
        for ranks in [2, 3] {
            // cut, as rank 0 does, from the plan built without its cells' geometry
            let lean = film_with(false);
            assert_eq!(lean.fingerprint(), plan.fingerprint());
            let records = on_threads(ranks, |rank, sum| {
                let part = divide_on_thread(&lean, ("film", OVERRIDES), rank, ranks, sum);
                let p = part.part.as_ref().unwrap();
                assert!(part.model.mesh.n_nodes() < plan.model.mesh.n_nodes());
                assert_eq!(p.fingerprint, plan.fingerprint());
                assert_eq!((p.whole_nodes, p.whole_cells), (75, 32));
                let state: Vec<f64> = p
                    .nodes
                    .iter()
                    .flat_map(|&n| last.0[n * FIELDS..(n + 1) * FIELDS].to_vec())
                    .collect();
                record(&part, &state)
            });
            for (rank, r) in records.iter().enumerate() {
                let close = |a: f64, b: f64, what: &str| {
                    assert!(
                        (a - b).abs() <= 1e-12 * a.abs().max(b.abs()),
                        "{ranks} ranks, rank {rank}: {what} {a:e} against {b:e}"
                    )
                };
                for (i, (a, b)) in r.probes.iter().zip(&whole.probes).enumerate() {
                    close(*a, *b, &plan.probes[i].0);
                }
                close(r.voltage, whole.voltage, "voltage");
                close(r.energies.stored, whole.energies.stored, "stored energy");
                close(
                    r.energies.electric,
                    whole.energies.electric,
                    "electric energy",
                );
                close(r.energies.gravity, whole.energies.gravity, "gravity");
                close(
                    r.max_electric_field,
                    whole.max_electric_field,
                    "largest field",
                );
                for (a, b) in r.electrodes.iter().zip(&whole.electrodes) {
                    for (x, y) in a.iter().zip(b) {
                        close(*x, *y, "electrode value");
                    }
                }
            }
        }
    }

    /// A rank receiving another rank's part, or a message that is not a part, refuses it and
    /// says why; so does every other rank through the agreement, before any exchange is made.
    #[test]
    fn a_rank_refuses_a_message_that_is_not_its_part() {
        let plan = film();
        let sent: Vec<Vec<u8>> = messages(&plan, 2, 7).unwrap().map(Result::unwrap).collect();
        assert!(sent.iter().all(|m| !m.is_empty()));
        let materials = plan.model.materials.clone();
        let no_exchange = |_: &Arc<LocalEquations>| -> Result<Arc<dyn Exchange>, String> {
            unreachable!("no exchange after a refusal")
        };
        let e = receive(&sent[1], materials.clone(), 0, 2, |ok| ok, no_exchange).unwrap_err();
        assert!(e.contains("received the part of rank 1 of 2"), "{e}");
        let e = receive(&sent[0], materials.clone(), 0, 3, |ok| ok, no_exchange).unwrap_err();
        assert!(e.contains("received the part of rank 0 of 2"), "{e}");
        let e = receive(&sent[0][..9], materials.clone(), 0, 2, |ok| ok, no_exchange).unwrap_err();
        assert!(e.contains("cannot decode its part"), "{e}");
        let e = receive(&sent[0], Vec::new(), 0, 2, |ok| ok, no_exchange).unwrap_err();
        assert!(e.contains("0 materials for the plan's 1"), "{e}");
        // a rank whose own message is sound stops when another's was not
        let e = receive(&sent[0], materials, 0, 2, |_| false, no_exchange).unwrap_err();
        assert!(e.contains("another rank could not make its part"), "{e}");
    }

    /// A plan the parts cannot hold yet is refused with the reason, before any exchange.
    #[test]
    fn a_plan_with_a_modes_stage_is_not_divided() {
        let mut plan = film();
        plan.stages[0].kind = StageKind::Modes {
            count: 3,
            shift_hz: 0.0,
            harmonics: vec![0],
        };
        let e = messages(&plan, 2, 0).err().expect("refused");
        assert!(
            e.contains("stage `charge` is a small-signal analysis"),
            "{e}"
        );
    }

    /// The parts of the 3-D diaphragm (a static and a dynamic stage, a rigid pad with its
    /// mass): the projection's potentials and the stages' unknowns are each owned once over
    /// the ranks, in as many equations as the whole problem's, and the pad's mass is carried
    /// by one rank.
    #[test]
    fn a_dynamic_plan_divides_its_projection_and_its_attached_mass_once() {
        let text = crate::io::examples::example("diaphragm-3d").unwrap();
        let scenario = crate::io::scenario::parse(text, "diaphragm-3d.toml", &[]).unwrap();
        let plan = crate::io::build::build(&scenario, "diaphragm-3d.toml", None).unwrap();
        let dynamic = plan
            .stages
            .iter()
            .find(|s| matches!(s.kind, StageKind::Dynamic { .. }))
            .expect("the example has a dynamic stage");
        // the whole problem's unknowns: the stages' and the projection's
        let mut whole = plan.model.clone();
        plan.stage_conditions(&mut whole, dynamic);
        let stage_free = dofs_of(&whole).n_free;
        let projection_free = dofs_of(&crate::time::stage::projection_model(&whole)).n_free;
        assert!(0 < projection_free && projection_free < stage_free);
        let mass: f64 = plan.rigid.iter().map(|r| r.mass).sum();
        assert!(mass > 0.0, "the example's pad carries a mass");
        let ranks = 2;
        let parts = on_threads(ranks, |rank, sum| {
            let part = divide_on_thread(&plan, ("diaphragm-3d", &[]), rank, ranks, sum);
            let p = part.part.as_ref().unwrap();
            let projection = p.projection.as_ref().expect("a division of the projection");
            (
                p.stages.equations.n_owned(),
                projection.equations.n_owned(),
                projection.equations.n_global(),
                part.rigid.iter().map(|r| r.mass).sum::<f64>(),
            )
        });
        let total =
            |f: fn(&(usize, usize, usize, f64)) -> usize| parts.iter().map(f).sum::<usize>();
        assert_eq!(total(|p| p.0), stage_free);
        assert_eq!(total(|p| p.1), projection_free);
        assert!(parts.iter().all(|p| p.2 == projection_free));
        let carried: Vec<f64> = parts.iter().map(|p| p.3).collect();
        assert_eq!(
            carried.iter().filter(|&&m| m > 0.0).count(),
            1,
            "{carried:?}"
        );
        assert_eq!(carried.iter().sum::<f64>(), mass);
    }
}
