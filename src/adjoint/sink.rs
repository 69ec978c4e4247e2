//! The gradient's accumulator: each step's adjoint hands it the products λᵀ∂R/∂p of the
//! parameters that step depends on, and the cotangents of the drive's values (a voltage at a
//! time), which it turns into the derivatives of the waveforms' parameters.

use crate::io::build::Parameter;
use crate::job::plan::Plan;
use crate::problem::dofs::FIELDS;
use crate::problem::drive::Drive;
use crate::problem::step::StepOperator;

/// dJ/dV at the knots of a control (`[[controls]]`).
#[derive(Debug, Clone, PartialEq)]
pub struct ControlGradient {
    /// The stage's index in the plan and the electrode's name.
    pub stage: usize,
    pub electrode: String,
    /// The knots: stage time (s) and voltage (V).
    pub knots: Vec<(f64, f64)>,
    /// dJ/dV at each knot.
    pub gradient: Vec<f64>,
    /// The electrode's nodes.
    nodes: Vec<usize>,
}

impl ControlGradient {
    /// dJ/dV += `a` at stage time `t`: the table's hat functions at t.
    fn add_at(&mut self, t: f64, a: f64) {
        let knots = &self.knots;
        let last = knots.len() - 1;
        if t <= knots[0].0 {
            self.gradient[0] += a;
        } else if t >= knots[last].0 {
            self.gradient[last] += a;
        } else {
            let i = knots.partition_point(|p| p.0 <= t);
            let x = (t - knots[i - 1].0) / (knots[i].0 - knots[i - 1].0);
            self.gradient[i - 1] += a * (1.0 - x);
            self.gradient[i] += a * x;
        }
    }
}

/// dJ/dp of the parameters named by their key paths, summed step by step.
pub struct Sink<'a> {
    plan: &'a Plan,
    /// The index of the stage whose steps are being swept.
    pub stage: usize,
    /// The controls, stage by stage.
    pub controls: Vec<ControlGradient>,
    parameters: &'a [(String, Parameter)],
    /// The materials whose parameters are asked for, by index in the plan.
    materials: Vec<usize>,
    /// dJ/dp, in the order of `parameters`.
    pub grad: Vec<f64>,
    /// For each material whose density is asked for, the nodal weight per unit density
    /// ∂f_w/∂ρ (N per kg/m³, 4 values per node; empty for the others).
    unit_weights: Vec<Vec<f64>>,
}

impl<'a> Sink<'a> {
    pub fn new(plan: &'a Plan, parameters: &'a [(String, Parameter)]) -> Self {
        let mut materials: Vec<usize> = parameters
            .iter()
            .filter_map(|(_, p)| match p {
                Parameter::Material(k) => Some(k.material_index),
                _ => None,
            })
            .collect();
        materials.sort_unstable();
        materials.dedup();
        let controls = plan
            .stages
            .iter()
            .enumerate()
            .flat_map(|(si, st)| {
                st.controls
                    .iter()
                    .map(move |(name, knots)| ControlGradient {
                        stage: si,
                        electrode: name.clone(),
                        knots: knots.clone(),
                        gradient: vec![0.0; knots.len()],
                        nodes: plan
                            .electrodes
                            .iter()
                            .find(|e| &e.name == name)
                            .map(|e| e.nodes.clone())
                            .unwrap_or_default(),
                    })
            })
            .collect();
        let mut unit_weights = vec![Vec::new(); plan.model.materials.len()];
        for (_, p) in parameters {
            if let Parameter::Density {
                material_index: m,
                value,
                ..
            } = p
            {
                // the body force ρg of the material, per unit density
                let mut w = plan.model.body_forces_of(|k| k == *m);
                w.iter_mut().for_each(|x| *x /= value);
                unit_weights[*m] = w;
            }
        }
        Sink {
            plan,
            stage: 0,
            controls,
            parameters,
            materials,
            grad: vec![0.0; parameters.len()],
            unit_weights,
        }
    }

    /// The parameters asked for.
    pub fn parameters(&self) -> &'a [(String, Parameter)] {
        self.parameters
    }

    /// dJ/dθ −= λᵀ ∂R/∂θ of a step's residual in the materials' parameters.
    pub fn step_materials(
        &mut self,
        op: &mut dyn StepOperator,
        lambda: &[f64],
    ) -> Result<(), String> {
        for m in self.materials.clone() {
            let entries = self.entries(m);
            let vjp = op.parameter_vjp(lambda, m, Some(&entries))?;
            self.materials_product(m, &vjp, -1.0);
        }
        Ok(())
    }

    /// dJ/dθ += `factor` · `vjp` for the parameters of material `m` (`vjp` in the order of
    /// the material's parameter vector).
    pub fn materials_product(&mut self, m: usize, vjp: &[f64], factor: f64) {
        for (i, (_, p)) in self.parameters.iter().enumerate() {
            if let Parameter::Material(key) = p {
                if key.material_index == m {
                    self.grad[i] += factor * vjp[key.entry];
                }
            }
        }
    }

    /// The entries of material `m`'s parameter vector that are asked for.
    pub fn entries(&self, m: usize) -> Vec<usize> {
        self.parameters
            .iter()
            .filter_map(|(_, p)| match p {
                Parameter::Material(k) if k.material_index == m => Some(k.entry),
                _ => None,
            })
            .collect()
    }

    /// The materials whose parameters are asked for.
    pub fn materials(&self) -> &[usize] {
        &self.materials
    }

    /// dJ/dp += `a` · ∂V/∂p for the waveform `k` of `drive` at stage time `t`, `a` the
    /// cotangent of that voltage, to the parameters that name its electrode.
    pub fn voltage(&mut self, drive: &Drive, k: usize, t: f64, a: f64) {
        let (nodes, waveform) = &drive.voltages[k];
        let stage = self.stage;
        if let Some(c) = self
            .controls
            .iter_mut()
            .find(|c| c.stage == stage && c.nodes == *nodes)
        {
            c.add_at(t, a);
            return;
        }
        for (i, (_, p)) in self.parameters.iter().enumerate() {
            if let Parameter::Voltage {
                electrode, scalar, ..
            } = p
            {
                let on_it = self
                    .plan
                    .electrodes
                    .iter()
                    .any(|e| &e.name == electrode && e.nodes == *nodes);
                if on_it {
                    self.grad[i] += a * waveform.derivative(t, *scalar);
                }
            }
        }
    }

    /// dJ/dp += ∂Q/∂p · `a` for the driven charge `k` of `drive` at stage time `t` and load
    /// factor `s`, `a` the cotangent of that charge on the meshed part: to the control of its
    /// electrode in this stage, or to the parameter of its constant charge (C, whole device).
    pub fn charge(&mut self, drive: &Drive, k: usize, t: f64, s: f64, a: f64) {
        let c = &drive.charges[k];
        let Some(e) = self.plan.electrodes.iter().find(|e| e.nodes[0] == c.node) else {
            return;
        };
        // Q_mesh = ramp(s) · Q(t) / symmetry
        let a = a * c.ramp.at(s) / self.plan.symmetry_factor;
        let t = c.time(t);
        let stage = self.stage;
        if let Some(control) = self
            .controls
            .iter_mut()
            .find(|g| g.stage == stage && g.electrode == e.name)
        {
            control.add_at(t, a);
            return;
        }
        for (i, (_, p)) in self.parameters.iter().enumerate() {
            if let Parameter::Charge {
                electrode, scalar, ..
            } = p
            {
                if *electrode == e.name {
                    self.grad[i] += a * c.charge.derivative(t, *scalar);
                }
            }
        }
    }

    /// The name of the electrode of the model's circuit `i` (circuits are the circuit-driven
    /// electrodes in the plan's order).
    fn circuit_electrode(&self, i: usize) -> Option<&'a str> {
        self.plan
            .electrodes
            .iter()
            .filter(|e| e.resistance.is_some())
            .nth(i)
            .map(|e| e.name.as_str())
    }

    /// dJ/dp += `a` · ∂V_s/∂p for the source of the model's circuit `i` in `drive` at stage time
    /// `t`, `a` the cotangent of that source voltage: to the control of its electrode in this
    /// stage, or to the parameters of its source's waveform.
    pub fn source(&mut self, drive: &Drive, i: usize, t: f64, a: f64) {
        let Some(name) = self.circuit_electrode(i) else {
            return;
        };
        let stage = self.stage;
        if let Some(c) = self
            .controls
            .iter_mut()
            .find(|c| c.stage == stage && c.electrode == name)
        {
            c.add_at(t, a);
            return;
        }
        for (k, (_, p)) in self.parameters.iter().enumerate() {
            if let Parameter::Voltage {
                electrode, scalar, ..
            } = p
            {
                if electrode == name {
                    self.grad[k] += a * drive.circuits[i].derivative(t, *scalar);
                }
            }
        }
    }

    /// dJ/dR += `product` · (the symmetry factor) for the series resistance R of the model's
    /// circuit `i`: `product` is the derivative in the resistance the mesh sees, R times the
    /// symmetry factor.
    pub fn resistance(&mut self, i: usize, product: f64) {
        let Some(name) = self.circuit_electrode(i) else {
            return;
        };
        let factor = self.plan.symmetry_factor;
        for (k, (_, p)) in self.parameters.iter().enumerate() {
            if matches!(p, Parameter::Resistance { electrode, .. } if electrode == name) {
                self.grad[k] += factor * product;
            }
        }
    }

    /// dJ/dm += `product` / (the symmetry factor) for the mass m of rigid pad `index`:
    /// `product` is the derivative in the mass the mesh carries, m over the symmetry factor.
    pub fn rigid_mass(&mut self, index: usize, product: f64) {
        let factor = 1.0 / self.plan.symmetry_factor;
        for (i, (_, p)) in self.parameters.iter().enumerate() {
            if matches!(p, Parameter::RigidMass { index: j, .. } if *j == index) {
                self.grad[i] += factor * product;
            }
        }
    }

    /// dJ/dp −= λᵀ∂R/∂p through the dead loads −`factor`·f_w in R: for the masses m of the
    /// rigid pads (f_w = m·g at each pad's first node), the densities ρ of the materials (f_w
    /// the consistent nodal forces of ρg over the material's cells) and the charges of
    /// charge-controlled electrodes (f_w = −Q on the electrode's potential); `w` is λ over
    /// every dof (unscaled).
    pub fn weights(&mut self, w: &[f64], factor: f64) {
        for i in 0..self.parameters.len() {
            match self.parameters[i].1 {
                Parameter::RigidMass { index, .. } => {
                    let r = &self.plan.rigid[index];
                    let node = r.nodes[0];
                    let p: f64 = (0..3).map(|k| w[node * FIELDS + k] * r.gravity[k]).sum();
                    self.grad[i] += factor * p / self.plan.symmetry_factor;
                }
                Parameter::Density { material_index, .. } => {
                    let unit = &self.unit_weights[material_index];
                    let p: f64 = unit.iter().zip(w).map(|(a, b)| a * b).sum();
                    self.grad[i] += factor * p;
                }
                Parameter::Charge { ref electrode, .. } => {
                    // the free charge Q/(symmetry) on the electrode's potential unknown (its
                    // first node), a dead load −Q on the Φ equation (a charge the drive gives
                    // is in [`Sink::charge`])
                    let dead = |e: &&crate::job::plan::Electrode| {
                        &e.name == electrode && !e.charge_in_drive
                    };
                    if let Some(e) = self.plan.electrodes.iter().find(dead) {
                        let d = e.nodes[0] * FIELDS + crate::problem::dofs::PHI;
                        self.grad[i] -= factor * w[d] / self.plan.symmetry_factor;
                    }
                }
                _ => {}
            }
        }
    }

    /// dJ/dρ += `product` for the density of material `m`.
    pub fn density(&mut self, m: usize, product: f64) {
        for (i, (_, p)) in self.parameters.iter().enumerate() {
            if matches!(p, Parameter::Density { material_index, .. } if *material_index == m) {
                self.grad[i] += product;
            }
        }
    }

    /// The materials whose density is asked for.
    pub fn densities(&self) -> Vec<usize> {
        let mut m: Vec<usize> = self
            .parameters
            .iter()
            .filter_map(|(_, p)| match p {
                Parameter::Density { material_index, .. } => Some(*material_index),
                _ => None,
            })
            .collect();
        m.sort_unstable();
        m.dedup();
        m
    }

    /// The node that carries the mass of rigid pad `index`.
    pub fn rigid_node(&self, index: usize) -> Option<usize> {
        self.plan.rigid.get(index).map(|r| r.nodes[0])
    }

    /// dJ/dη += `product` for the Kelvin–Voigt viscosity of material `m`.
    pub fn viscosity(&mut self, m: usize, product: f64) {
        for (i, (_, p)) in self.parameters.iter().enumerate() {
            if matches!(p, Parameter::Viscosity { material_index, .. } if *material_index == m) {
                self.grad[i] += product;
            }
        }
    }
}

/// For each dof of a nodal vector (4 per node), the index of the drive's waveform that
/// prescribes it, or `usize::MAX`.
pub fn waveform_dofs(drive: &Drive, n_dofs: usize) -> Vec<usize> {
    let mut out = vec![usize::MAX; n_dofs];
    for (k, (nodes, _)) in drive.voltages.iter().enumerate() {
        for &n in nodes {
            out[n * FIELDS + crate::problem::dofs::PHI] = k;
        }
    }
    out
}
