//! Cell kernels: turn a material and a cell's geometry into the local residual, tangent, energy
//! and output fields of the cell.

pub mod axisymmetric;
pub mod deformation_vjp;
pub mod harmonic;
pub(crate) mod md_lanes;
pub(crate) mod md_point;
pub mod mean_dilatation;
pub mod standard;

pub use axisymmetric::AxisymmetricKernel;
pub use mean_dilatation::Formulation;
pub use standard::*;

use crate::fem::CellGeometry;
use crate::material::{Mat3, Material, Vec3};

/// What a cell kernel reads of one cell: its reference geometry (computed once per mesh), its
/// material with the committed point history, and its local values (u in m, Φ in V; four per
/// node, node-major).
#[derive(Clone, Copy)]
pub struct CellInput<'a> {
    pub geom: &'a CellGeometry,
    pub mat: &'a dyn Material,
    pub hist: CellHistory<'a>,
    pub local: &'a [f64],
}

/// A cell kernel: turns a material and a cell's geometry into the cell's residual, tangent,
/// energy and output fields, written into the caller's buffers (`r` with 4·n entries, `k`
/// row-major 4n × 4n). The assembler calls it and knows no physics; a new element formulation or
/// kinematics is a new kernel.
pub trait CellKernel: Send + Sync {
    /// Local residual ∂Π/∂x (and tangent when `k` is given); returns the cell energy (J).
    fn residual_tangent(
        &self,
        cell: &CellInput,
        r: &mut [f64],
        k: Option<&mut [f64]>,
    ) -> Result<f64, PointFailure>;
    /// The cell energy ∫Ψ dV (J).
    fn energy(&self, cell: &CellInput) -> Result<f64, PointFailure>;
    /// `(mechanical, electric)` parts of the stored energy at the committed state (J).
    fn energy_split(&self, cell: &CellInput) -> Result<(f64, f64), PointFailure>;
    /// Output fields of the cell.
    fn fields(&self, cell: &CellInput) -> Result<CellFields, PointFailure>;
    /// The Φ rows of the residual of [`CellKernel::residual_tangent`] into `r` (4·n entries),
    /// its displacement rows zero: a solve for the potential at held displacements needs no
    /// stress.
    fn potential_residual(&self, cell: &CellInput, r: &mut [f64]) -> Result<(), PointFailure> {
        self.residual_tangent(cell, r, None)?;
        for node in r[..cell.geom.n_nodes * crate::fem::FIELDS].chunks_exact_mut(crate::fem::FIELDS)
        {
            node[..crate::fem::PHI].fill(0.0);
        }
        Ok(())
    }
    /// The Φ rows of [`CellKernel::residual_tangent`]'s residual and tangent into `r` and `k`,
    /// their displacement rows zero: the electrostatic problem at held displacements, whose
    /// adjoint needs its coupling to the displacements but no stress and no stiffness.
    fn potential_residual_tangent(
        &self,
        cell: &CellInput,
        r: &mut [f64],
        k: &mut [f64],
    ) -> Result<(), PointFailure> {
        self.residual_tangent(cell, r, Some(&mut *k))?;
        zero_displacement_rows(cell.geom.n_nodes, r, k)
    }
    /// What the record of a state needs of the cell, in one call: the residual (into `r`, as
    /// [`CellKernel::residual_tangent`]), the energy split and the output fields. A kernel may
    /// share its kinematics and stresses among them; the values are those of the three calls up
    /// to round-off.
    fn record(
        &self,
        cell: &CellInput,
        r: &mut [f64],
    ) -> Result<((f64, f64), CellFields), PointFailure> {
        self.residual_tangent(cell, r, None)?;
        Ok((self.energy_split(cell)?, self.fields(cell)?))
    }
    /// The deformation gradient the material sees and E₀ at each quadrature point (where
    /// internal variables are updated), into `out[..n_qp]`.
    fn point_deformations(
        &self,
        cell: &CellInput,
        out: &mut [(Mat3, Vec3)],
    ) -> Result<(), PointFailure>;
    /// ∂(wᵀr)/∂P at each quadrature point, into `out[..n_qp]`: how the product of `w` (4 values
    /// per node) with the cell residual changes with the first Piola stress the material gives
    /// at that point (at the deformation of [`CellKernel::point_deformations`]). With it the
    /// derivative of the residual in anything a point's stress depends on (its internal
    /// variables) is one material product per point. The default holds for kernels whose F is
    /// linear in the displacements, r = Σ_q w_q P_q : δF_q: the weight w_q (F(w) − I).
    fn stress_weights(
        &self,
        cell: &CellInput,
        w: &[f64],
        out: &mut [Mat3],
    ) -> Result<(), PointFailure> {
        let mut fw = [(Mat3::identity(), Vec3::zeros()); crate::fem::MAX_QP];
        self.point_deformations(&CellInput { local: w, ..*cell }, &mut fw)?;
        for (q, o) in out[..cell.geom.n_qp].iter_mut().enumerate() {
            *o = (fw[q].0 - Mat3::identity()) * cell.geom.weights[q];
        }
        Ok(())
    }
    /// The residual of a dynamic step without its tangent, `f_r`·(r + r_vis), into `r`: the
    /// residual of [`CellKernel::residual_tangent`] plus, when `viscous` gives the Kelvin–Voigt
    /// kernel and the nodal velocities (4 per node), the viscous forces of
    /// [`KelvinVoigtKernel::forces`] at the same configuration. Returns the cell energy and the
    /// dissipation power (W, 0 without `viscous`). Most Newton iterations of a step need only
    /// this; a kernel may share its kinematics between the two parts. The values are those of
    /// the separate calls up to round-off.
    fn dynamic_residual(
        &self,
        cell: &CellInput,
        viscous: Option<(KelvinVoigtKernel, &[f64])>,
        f_r: f64,
        r: &mut [f64],
    ) -> Result<(f64, f64), PointFailure> {
        dynamic_residual_separate(self, cell, viscous, f_r, r)
    }
    /// [`CellKernel::residual_tangent`] whose tangent also holds the Kelvin–Voigt forces'
    /// configuration derivative plus `viscous.cv` times their velocity derivative (those of
    /// [`KelvinVoigtKernel::configuration_tangent`] and [`KelvinVoigtKernel::forces`]), formed
    /// with the kernel's own point blocks instead of two more passes over the cell's matrix;
    /// the residual is the elastic one. `None` where the kernel does not form them (the caller
    /// then adds the two matrices itself).
    fn residual_viscous_tangent(
        &self,
        _cell: &CellInput,
        _viscous: &ViscousTangent,
        _r: &mut [f64],
        _k: &mut [f64],
    ) -> Option<Result<f64, PointFailure>> {
        None
    }
}

/// [`CellKernel::dynamic_residual`] by the separate calls: the elastic residual, scaled, plus the
/// scaled viscous forces.
pub fn dynamic_residual_separate<K: CellKernel + ?Sized>(
    kernel: &K,
    cell: &CellInput,
    viscous: Option<(KelvinVoigtKernel, &[f64])>,
    f_r: f64,
    r: &mut [f64],
) -> Result<(f64, f64), PointFailure> {
    let nl = cell.geom.n_nodes * crate::fem::FIELDS;
    let energy = kernel.residual_tangent(cell, r, None)?;
    r[..nl].iter_mut().for_each(|v| *v *= f_r);
    let mut power = 0.0;
    if let Some((kv, vel)) = viscous {
        let mut rv = [0.0; MAX_LOCAL];
        power = kv.forces(cell.geom, cell.local, &vel[..nl], &mut rv, None)?;
        for i in 0..nl {
            r[i] += f_r * rv[i];
        }
    }
    Ok((energy, power))
}

/// Zeroes the displacement rows of a cell's residual `r` and tangent `k` (`n` nodes): what
/// [`CellKernel::potential_residual_tangent`] leaves of a whole cell's.
fn zero_displacement_rows(n: usize, r: &mut [f64], k: &mut [f64]) -> Result<(), PointFailure> {
    let nl = n * crate::fem::FIELDS;
    for (i, (row, ri)) in k[..nl * nl]
        .chunks_exact_mut(nl)
        .zip(&mut r[..nl])
        .enumerate()
    {
        if i % crate::fem::FIELDS != crate::fem::PHI {
            row.fill(0.0);
            *ri = 0.0;
        }
    }
    Ok(())
}

/// The standard displacement kernel (full integration).
#[derive(Debug, Clone, Copy)]
pub struct StandardKernel;

/// The mean-dilatation (Q1–P0) kernel for nearly incompressible materials.
#[derive(Debug, Clone, Copy)]
pub struct MeanDilatationKernel;

impl CellKernel for StandardKernel {
    fn residual_tangent(
        &self,
        c: &CellInput,
        r: &mut [f64],
        k: Option<&mut [f64]>,
    ) -> Result<f64, PointFailure> {
        cell_residual_tangent(c.geom, c.mat, c.hist, c.local, r, k)
    }
    fn residual_viscous_tangent(
        &self,
        c: &CellInput,
        viscous: &ViscousTangent,
        r: &mut [f64],
        k: &mut [f64],
    ) -> Option<Result<f64, PointFailure>> {
        Some(cell_residual_viscous_tangent(
            c.geom,
            c.mat,
            c.hist,
            c.local,
            Some(viscous),
            r,
            Some(k),
        ))
    }
    fn potential_residual_tangent(
        &self,
        c: &CellInput,
        r: &mut [f64],
        k: &mut [f64],
    ) -> Result<(), PointFailure> {
        cell_potential_tangent(c.geom, c.mat, c.hist, c.local, r, k)
    }
    fn energy(&self, c: &CellInput) -> Result<f64, PointFailure> {
        cell_energy(c.geom, c.mat, c.hist, c.local)
    }
    fn energy_split(&self, c: &CellInput) -> Result<(f64, f64), PointFailure> {
        cell_energy_split(c.geom, c.mat, c.hist, c.local)
    }
    fn fields(&self, c: &CellInput) -> Result<CellFields, PointFailure> {
        cell_fields(c.geom, c.mat, c.hist, c.local)
    }
    fn point_deformations(
        &self,
        c: &CellInput,
        out: &mut [(Mat3, Vec3)],
    ) -> Result<(), PointFailure> {
        standard::point_deformations(c.geom, c.local, out);
        Ok(())
    }
}

impl CellKernel for MeanDilatationKernel {
    fn residual_tangent(
        &self,
        c: &CellInput,
        r: &mut [f64],
        k: Option<&mut [f64]>,
    ) -> Result<f64, PointFailure> {
        mean_dilatation::cell_residual_tangent_md(c.geom, c.mat, c.hist, c.local, r, k)
    }
    fn residual_viscous_tangent(
        &self,
        c: &CellInput,
        viscous: &ViscousTangent,
        r: &mut [f64],
        k: &mut [f64],
    ) -> Option<Result<f64, PointFailure>> {
        (!c.geom.axisymmetric).then(|| {
            mean_dilatation::cell_residual_viscous_tangent_md(
                c.geom,
                c.mat,
                c.hist,
                c.local,
                Some(viscous),
                r,
                Some(k),
            )
        })
    }
    fn energy(&self, c: &CellInput) -> Result<f64, PointFailure> {
        mean_dilatation::cell_energy_md(c.geom, c.mat, c.hist, c.local)
    }
    fn energy_split(&self, c: &CellInput) -> Result<(f64, f64), PointFailure> {
        mean_dilatation::cell_energy_split_md(c.geom, c.mat, c.hist, c.local)
    }
    fn fields(&self, c: &CellInput) -> Result<CellFields, PointFailure> {
        mean_dilatation::cell_fields_md(c.geom, c.mat, c.hist, c.local)
    }
    fn potential_residual(&self, c: &CellInput, r: &mut [f64]) -> Result<(), PointFailure> {
        mean_dilatation::cell_potential_residual_md(c.geom, c.mat, c.hist, c.local, r)
    }
    fn potential_residual_tangent(
        &self,
        c: &CellInput,
        r: &mut [f64],
        k: &mut [f64],
    ) -> Result<(), PointFailure> {
        mean_dilatation::cell_potential_tangent_md(c.geom, c.mat, c.hist, c.local, r, k)
    }
    fn record(
        &self,
        c: &CellInput,
        r: &mut [f64],
    ) -> Result<((f64, f64), CellFields), PointFailure> {
        mean_dilatation::cell_record_md(c.geom, c.mat, c.hist, c.local, r)
    }
    fn point_deformations(
        &self,
        c: &CellInput,
        out: &mut [(Mat3, Vec3)],
    ) -> Result<(), PointFailure> {
        mean_dilatation::point_deformations_md(c.geom, c.local, out)
    }
    fn stress_weights(
        &self,
        c: &CellInput,
        w: &[f64],
        out: &mut [Mat3],
    ) -> Result<(), PointFailure> {
        mean_dilatation::stress_weights_md(c.geom, c.local, w, out)
    }
    fn dynamic_residual(
        &self,
        c: &CellInput,
        viscous: Option<(KelvinVoigtKernel, &[f64])>,
        f_r: f64,
        r: &mut [f64],
    ) -> Result<(f64, f64), PointFailure> {
        if c.geom.axisymmetric {
            return dynamic_residual_separate(self, c, viscous, f_r, r);
        }
        mean_dilatation::cell_dynamic_residual_md(c.geom, c.mat, c.hist, c.local, viscous, f_r, r)
    }
}

/// The Kelvin–Voigt viscous kernel: a rate-dependent force on top of an elastic kernel.
#[derive(Debug, Clone, Copy)]
pub struct KelvinVoigtKernel {
    /// Viscosity η (Pa·s).
    pub eta: f64,
}

impl KelvinVoigtKernel {
    /// Adds the viscous forces at configuration `local` and nodal velocities `vel` to `r` (and
    /// their velocity derivative to `kv`); returns the dissipation power (W). See
    /// [`cell_viscous`].
    pub fn forces(
        &self,
        geom: &CellGeometry,
        local: &[f64],
        vel: &[f64],
        r: &mut [f64],
        kv: Option<&mut [f64]>,
    ) -> Result<f64, PointFailure> {
        if geom.axisymmetric {
            return axisymmetric::cell_viscous_meridian(geom, self.eta, local, vel, r, kv);
        }
        cell_viscous(geom, self.eta, local, vel, r, kv)
    }

    /// Adds the derivative of the forces of [`KelvinVoigtKernel::forces`] with respect to the
    /// configuration `local`, at fixed nodal velocities `vel`, to `kq` (4n × 4n, row-major). The
    /// mean-dilatation kernel's viscous forces see the compatible F, so this is its derivative
    /// too. See [`cell_viscous_configuration`].
    pub fn configuration_tangent(
        &self,
        geom: &CellGeometry,
        local: &[f64],
        vel: &[f64],
        kq: &mut [f64],
    ) -> Result<(), PointFailure> {
        if geom.axisymmetric {
            return axisymmetric::cell_viscous_meridian_configuration(
                geom, self.eta, local, vel, kq,
            );
        }
        cell_viscous_configuration(geom, self.eta, local, vel, kq)
    }
}

use crate::material::PointHistory;

/// The committed internal variables of a cell's quadrature points (`size` values per point,
/// point-major) and the time step of the state being evaluated. Empty for elastic materials.
#[derive(Debug, Clone, Copy)]
pub struct CellHistory<'a> {
    pub state: &'a [f64],
    pub size: usize,
    pub dt: f64,
}

impl<'a> CellHistory<'a> {
    /// No internal variables.
    pub const NONE: CellHistory<'static> = CellHistory {
        state: &[],
        size: 0,
        dt: 0.0,
    };

    /// The history of quadrature point `q`.
    pub fn at(&self, q: usize) -> PointHistory<'a> {
        PointHistory {
            state: if self.size == 0 {
                &[]
            } else {
                &self.state[q * self.size..(q + 1) * self.size]
            },
            dt: self.dt,
        }
    }
}
