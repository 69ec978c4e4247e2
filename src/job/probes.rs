//! Probes: named scalar outputs evaluated at every accepted step.

/// A nodal quantity.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum NodalQuantity {
    /// Displacement component 0, 1, 2 (m).
    Component(usize),
    /// Displacement magnitude (m).
    Magnitude,
    /// Electric potential (V).
    Potential,
}

impl NodalQuantity {
    fn value(self, state: &[f64], node: usize) -> f64 {
        let s = &state[node * 4..node * 4 + 4];
        match self {
            NodalQuantity::Component(c) => s[c],
            NodalQuantity::Magnitude => (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt(),
            NodalQuantity::Potential => s[3],
        }
    }

    /// `weight` · ∂(value at `node`)/∂state added into `out` (4 values per node); the magnitude
    /// of a zero displacement has none (its subgradient 0 is taken).
    fn add_gradient(self, state: &[f64], node: usize, weight: f64, out: &mut [f64]) {
        let i = node * 4;
        match self {
            NodalQuantity::Component(c) => out[i + c] += weight,
            NodalQuantity::Potential => out[i + 3] += weight,
            NodalQuantity::Magnitude => {
                let m = self.value(state, node);
                if m > 0.0 {
                    for c in 0..3 {
                        out[i + c] += weight * state[i + c] / m;
                    }
                }
            }
        }
    }
}

/// What a probe measures.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum ProbeKind {
    /// Weighted mean Σ wₐ qₐ / Σ wₐ of a nodal quantity over a set: the weights are the nodes'
    /// shares ∫Nₐ dA of the reference area of a face set (the surface mean of the interpolated
    /// quantity), or 1 each over a node set without faces.
    Mean(NodalQuantity, Vec<usize>, Vec<f64>),
    Max(NodalQuantity, Vec<usize>),
    Min(NodalQuantity, Vec<usize>),
    /// Value at one node.
    Point(NodalQuantity, usize),
    /// Charge (C) on the electrode with this index.
    Charge(usize),
    /// Charge / voltage (F) of the electrode with this index.
    Capacitance(usize),
    /// Sum of the reaction force component (N) over a node set.
    Reaction(usize, Vec<usize>),
    /// Mechanical strain energy (J).
    StoredEnergy,
    /// Electric field energy in the body (J).
    ElectricEnergy,
    /// Downward displacement of a set (the pad) from the reference state (the pre-stretched one):
    /// −mean(u_z − u_z,ref) (m, positive downward); with the axial slot (2 in 3-D, 1 in an
    /// axisymmetric model).
    Deflection(Vec<usize>, usize),
    /// Largest true (spatial) electric field magnitude at a quadrature point (V/m).
    MaxElectricField,
    /// Current (A) into the electrode with this index: the change of its charge over the last
    /// step divided by the step's time (backward difference; 0 at the first record).
    Current(usize),
    /// Electrical power (W) delivered to the electrode: its voltage times its current.
    Power(usize),
    /// Energy delivered by the source of the circuit-driven electrode with this index (J, whole
    /// device): ∫ V_s I dt over the dynamic stages.
    SourceEnergy(usize),
    /// Energy lost in that circuit's series resistance (J, whole device): ∫ R I² dt.
    ResistorLoss(usize),
    /// Area strain A/A_ref − 1 of a face set (an electrode) against the reference state (the
    /// pre-stretched one), from its faces' current and reference areas.
    AreaStrain(Vec<ProbeFace>),
    /// Volume (m³) enclosed by a face set, −⅓ ∮ x·n da with n the body's outward normal: the
    /// cavity a pressure inflates, or minus a solid's volume for its outer faces.
    Volume(Vec<crate::problem::pressure::SurfaceFace>),
    /// The pressure (Pa) of `model.pressures[i]` acting now: its ramped value, or under volume
    /// control the unknown that holds the volume.
    Pressure(usize),
}

/// A face of a surface probe: its cell (which decides the rank's part that holds it), its nodes
/// and their positions (m) in the mesh.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ProbeFace {
    pub cell: usize,
    pub nodes: Vec<usize>,
    pub positions: Vec<[f64; 3]>,
    /// A side (2 or 3 nodes, x = R, y = Z) of a meridian cell of an axisymmetric model: its area
    /// is that of the ring surface it sweeps, 2π∫R ds.
    #[serde(default)]
    pub ring: bool,
}

impl ProbeFace {
    /// The face's area (m²) with the displacements of `state` (4 values per node).
    fn area(&self, state: &[f64]) -> f64 {
        let p: Vec<[f64; 3]> = self
            .nodes
            .iter()
            .zip(&self.positions)
            .map(|(&n, x)| std::array::from_fn(|i| x[i] + state[n * 4 + i]))
            .collect();
        if self.ring {
            crate::problem::faces::ring_node_areas(&p).iter().sum()
        } else {
            crate::problem::loads::face_point_areas(&p).iter().sum()
        }
    }
}

impl ProbeKind {
    /// Whether the value is a total over the device (multiplied by the symmetry factor).
    fn is_global(&self) -> bool {
        matches!(
            self,
            ProbeKind::Charge(_)
                | ProbeKind::Current(_)
                | ProbeKind::Power(_)
                | ProbeKind::Capacitance(_)
                | ProbeKind::Reaction(..)
                | ProbeKind::StoredEnergy
                | ProbeKind::ElectricEnergy
                | ProbeKind::Volume(_)
        )
    }
}

/// A probe: offset + scale · quantity.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Probe {
    pub kind: ProbeKind,
    pub scale: f64,
    pub offset: f64,
    /// Unit of the recorded value for plots and tables (`-` dimensionless, empty when unknown).
    pub unit: String,
    /// What the probe measures, in words (plot titles).
    pub description: String,
}

impl ProbeKind {
    /// SI unit of the quantity before `scale` and `offset`.
    pub fn unit(&self) -> &'static str {
        match self {
            ProbeKind::Mean(q, ..) | ProbeKind::Max(q, _) | ProbeKind::Min(q, _) => q.unit(),
            ProbeKind::Point(q, _) => q.unit(),
            ProbeKind::Charge(_) => "C",
            ProbeKind::Capacitance(_) => "F",
            ProbeKind::Reaction(..) => "N",
            ProbeKind::StoredEnergy | ProbeKind::ElectricEnergy => "J",
            ProbeKind::Deflection(..) => "m",
            ProbeKind::MaxElectricField => "V/m",
            ProbeKind::Current(_) => "A",
            ProbeKind::Power(_) => "W",
            ProbeKind::SourceEnergy(_) | ProbeKind::ResistorLoss(_) => "J",
            ProbeKind::AreaStrain(_) => "-",
            ProbeKind::Volume(_) => "m³",
            ProbeKind::Pressure(_) => "Pa",
        }
    }
}

impl NodalQuantity {
    /// SI unit of the quantity.
    pub fn unit(self) -> &'static str {
        match self {
            NodalQuantity::Potential => "V",
            _ => "m",
        }
    }
}

/// What probes read.
pub struct ProbeInput<'a> {
    /// Physical state, 4 values per node.
    pub state: &'a [f64],
    /// ∂Π/∂x per dof (N for u, C for Φ).
    pub reactions: &'a [f64],
    /// Node sets and present voltage (V) of the electrodes.
    pub electrodes: &'a [(&'a [usize], f64)],
    /// Mechanical and electric energies (J) of the meshed part.
    pub stored: f64,
    pub electric: f64,
    /// The state deflections are measured from (4 values per node).
    pub reference: &'a [f64],
    /// Largest true electric field (V/m).
    pub max_field: f64,
    /// Copies of the meshed part in the device (4 for a quarter model).
    pub symmetry: f64,
    /// The reactions of the previous record (empty at the first) and the time since it (s).
    pub previous: (&'a [f64], f64),
    /// Per electrode (plan order): energy delivered by its circuit's source and lost in its
    /// resistance so far (J, whole device; zero without a circuit).
    pub circuit_energy: &'a [(f64, f64)],
    /// Per pressure of the model: the pressure acting (Pa); empty where not known (0).
    pub pressures: &'a [f64],
    /// Per electrode (plan order): its charge (C, meshed part) now and at the previous record
    /// ([`electrode_charges`], summed over the processes that divide the model).
    pub charges: &'a [(f64, f64)],
}

/// A probe's share of its value on one process's part of the model, and how the shares of
/// the processes that divide a model combine (one process's share is its whole value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Share {
    /// Summed over the processes: [a, b] of a probe whose value follows from the two sums.
    Sum([f64; 2]),
    /// The largest over the processes.
    Max(f64),
    /// A probe of the inputs' whole-model values (energies, charges, the largest field): the
    /// same on every process.
    Whole,
}

impl Probe {
    /// ∂(value)/∂state (4 values per node) at `state` on the whole model, for the probes that
    /// read the nodal values alone (means, extremes, points and deflections, whose reference
    /// state is held); `None` for the others (reactions, charges, energies, fields, areas,
    /// volumes). An extreme takes the derivative of its extreme node.
    pub fn state_gradient(&self, state: &[f64]) -> Option<Vec<f64>> {
        let mut g = vec![0.0; state.len()];
        let extreme = |q: &NodalQuantity, nodes: &[usize], sign: f64| {
            nodes
                .iter()
                .copied()
                .max_by(|&a, &b| (sign * q.value(state, a)).total_cmp(&(sign * q.value(state, b))))
        };
        match &self.kind {
            ProbeKind::Mean(q, nodes, weights) => {
                let total: f64 = weights.iter().sum();
                for (&n, w) in nodes.iter().zip(weights) {
                    q.add_gradient(state, n, w / total, &mut g);
                }
            }
            ProbeKind::Max(q, nodes) => {
                if let Some(n) = extreme(q, nodes, 1.0) {
                    q.add_gradient(state, n, 1.0, &mut g);
                }
            }
            ProbeKind::Min(q, nodes) => {
                if let Some(n) = extreme(q, nodes, -1.0) {
                    q.add_gradient(state, n, 1.0, &mut g);
                }
            }
            ProbeKind::Point(q, n) => q.add_gradient(state, *n, 1.0, &mut g),
            ProbeKind::Deflection(nodes, axial) => {
                let w = -1.0 / (nodes.len() as f64).max(1.0);
                for &n in nodes {
                    g[n * 4 + axial] += w;
                }
            }
            _ => return None,
        }
        g.iter_mut().for_each(|v| *v *= self.scale);
        Some(g)
    }

    /// Whether the probe's value depends on the reference state (a deflection, whose gradient
    /// in the reference is minus [`Probe::state_gradient`]).
    pub fn reads_reference(&self) -> bool {
        matches!(self.kind, ProbeKind::Deflection(..))
    }

    /// The probe's value.
    pub fn evaluate(&self, inp: &ProbeInput) -> f64 {
        let share = match self.share(inp) {
            Share::Sum(v) => v,
            Share::Max(m) => [m, 0.0],
            Share::Whole => [0.0, 0.0],
        };
        self.value(inp, share)
    }

    /// This process's share of the probe's value. A probe over nodes takes the nodes it is
    /// given: on a rank's part of a plan, the owned nodes of a mean or a deflection (each node
    /// counted once), every node of the part for a reaction (each rank's reactions are those of
    /// its own cells) or an extreme ([`crate::job::part`]).
    pub fn share(&self, inp: &ProbeInput) -> Share {
        match &self.kind {
            ProbeKind::Mean(q, nodes, weights) => Share::Sum([
                nodes
                    .iter()
                    .zip(weights)
                    .map(|(&n, w)| w * q.value(inp.state, n))
                    .sum::<f64>(),
                weights.iter().sum::<f64>(),
            ]),
            ProbeKind::Max(q, nodes) => Share::Max(
                nodes
                    .iter()
                    .map(|&n| q.value(inp.state, n))
                    .fold(f64::NEG_INFINITY, f64::max),
            ),
            // the largest of the negated values: the negated least
            ProbeKind::Min(q, nodes) => Share::Max(
                nodes
                    .iter()
                    .map(|&n| -q.value(inp.state, n))
                    .fold(f64::NEG_INFINITY, f64::max),
            ),
            // a node that is not this process's (usize::MAX) adds nothing
            ProbeKind::Point(q, n) => Share::Sum([
                if *n == usize::MAX {
                    0.0
                } else {
                    q.value(inp.state, *n)
                },
                0.0,
            ]),
            ProbeKind::Reaction(c, nodes) => {
                Share::Sum([nodes.iter().map(|&n| inp.reactions[n * 4 + c]).sum(), 0.0])
            }
            ProbeKind::Deflection(nodes, axial) => Share::Sum([
                nodes
                    .iter()
                    .map(|&n| inp.state[n * 4 + axial] - inp.reference[n * 4 + axial])
                    .sum::<f64>(),
                nodes.len() as f64,
            ]),
            ProbeKind::Volume(faces) => Share::Sum([
                crate::problem::pressure::enclosed_volume(faces, inp.state),
                0.0,
            ]),
            ProbeKind::AreaStrain(faces) => {
                let area = |state: &[f64]| faces.iter().map(|f| f.area(state)).sum::<f64>();
                Share::Sum([area(inp.state), area(inp.reference)])
            }
            _ => Share::Whole,
        }
    }

    /// The probe's value from the processes' combined shares (`combined`: the sums of a
    /// [`Share::Sum`], the largest of a [`Share::Max`] first) and the inputs.
    pub fn value(&self, inp: &ProbeInput, combined: [f64; 2]) -> f64 {
        let [a, b] = combined;
        let v = match &self.kind {
            ProbeKind::Mean(..) => a / b,
            ProbeKind::Max(..) => a,
            ProbeKind::Min(..) => -a,
            ProbeKind::Point(..) | ProbeKind::Reaction(..) => a,
            ProbeKind::Deflection(..) => -a / b.max(1.0),
            ProbeKind::Charge(e) => inp.charges[*e].0,
            ProbeKind::Capacitance(e) => {
                let v = inp.electrodes[*e].1;
                if v == 0.0 {
                    f64::NAN
                } else {
                    inp.charges[*e].0 / v
                }
            }
            ProbeKind::StoredEnergy => inp.stored,
            ProbeKind::ElectricEnergy => inp.electric,
            ProbeKind::MaxElectricField => inp.max_field,
            ProbeKind::Current(e) => current(inp, *e),
            ProbeKind::Power(e) => inp.electrodes[*e].1 * current(inp, *e),
            ProbeKind::SourceEnergy(e) => inp.circuit_energy.get(*e).map_or(0.0, |c| c.0),
            ProbeKind::ResistorLoss(e) => inp.circuit_energy.get(*e).map_or(0.0, |c| c.1),
            ProbeKind::Volume(_) => a,
            ProbeKind::Pressure(i) => inp.pressures.get(*i).copied().unwrap_or(0.0),
            // the current and the reference area
            ProbeKind::AreaStrain(_) => a / b - 1.0,
        };
        let v = if self.kind.is_global() {
            v * inp.symmetry
        } else {
            v
        };
        self.offset + self.scale * v
    }
}

/// Voltage (V), charge (C), current (A), power (W), and the energy its circuit's source delivered
/// and its resistance lost (J) of electrode `e` (plan index), whole device: the per-electrode
/// outputs of every record.
pub fn electrode_values(inp: &ProbeInput, e: usize) -> [f64; 6] {
    let s = inp.symmetry;
    let v = inp.electrodes[e].1;
    let i = current(inp, e) * s;
    let (source, loss) = inp.circuit_energy.get(e).copied().unwrap_or((0.0, 0.0));
    // + 0.0: no negative zero in the tables
    [
        v,
        inp.charges[e].0 * s + 0.0,
        i + 0.0,
        v * i + 0.0,
        source,
        loss,
    ]
}

/// Each electrode's charge Q = −Σ ∂Π/∂Φ_a over its nodes (the free charge the source supplies)
/// at the reactions `reactions`, and at the previous record's `previous` (0 without one): on a
/// rank's part, its own cells' share of both.
pub fn electrode_charges(
    electrodes: &[(&[usize], f64)],
    reactions: &[f64],
    previous: &[f64],
) -> Vec<(f64, f64)> {
    let charge = |nodes: &[usize], r: &[f64]| -> f64 {
        if r.is_empty() {
            return 0.0;
        }
        -nodes.iter().map(|&n| r[n * 4 + 3]).sum::<f64>()
    };
    electrodes
        .iter()
        .map(|(nodes, _)| (charge(nodes, reactions), charge(nodes, previous)))
        .collect()
}

/// Current into an electrode: (Q − Q_prev)/Δt over the last step, 0 without one.
fn current(inp: &ProbeInput, e: usize) -> f64 {
    let (prev, dt) = inp.previous;
    if prev.is_empty() || dt <= 0.0 {
        return 0.0;
    }
    let (now, before) = inp.charges[e];
    (now - before) / dt
}
