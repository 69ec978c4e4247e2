//! Ready-made models used by tests, benchmarks and validation.

use crate::analytic::Film;
use crate::material::registry::build;
use crate::material::{ElectroNeoHooke, Material, MaterialParams, EPSILON_0};
use crate::mesh::{generate::box_mesh, ElementKind};
use crate::problem::dofs::{Dirichlet, Field, FIELDS};
use crate::problem::model::{Formulation, Model, ModelError};
use std::sync::Arc;

/// Parameters of the `film` example (docs/theory.md, homogeneous film): a 10 × 10 × 1 mm quarter of a film.
pub const FILM_SIZE: [f64; 3] = [10e-3, 10e-3, 1e-3];
/// Shear modulus μ (Pa) of the film.
pub const FILM_MU: f64 = 1e5;
/// Lamé constant Λ (Pa) of the film.
pub const FILM_LAMBDA: f64 = 1e7;
/// Relative permittivity of the film.
pub const FILM_EPS_R: f64 = 4.7;

/// The film: quarter-symmetric block (symmetry on x0 and y0), bottom face z0 held in z and
/// grounded, top face z1 at potential `voltage` (V), lateral faces free.
pub fn film(divisions: [usize; 3], kind: ElementKind, voltage: f64) -> Result<Model, ModelError> {
    film_on(box_mesh(FILM_SIZE, divisions, kind), voltage)
}

/// The film's material and conditions on `mesh` (a box mesh of the film, or a rank's part of
/// one), by its sets `x0`, `y0`, `z0`, `z1`.
pub fn film_on(mesh: crate::mesh::Mesh, voltage: f64) -> Result<Model, ModelError> {
    let material = Arc::new(ElectroNeoHooke::new(FILM_MU, FILM_LAMBDA, FILM_EPS_R));
    let mut model = Model::new(mesh, material)?;
    model.fix("x0", Field::Ux, 0.0)?;
    model.fix("y0", Field::Uy, 0.0)?;
    model.fix("z0", Field::Uz, 0.0)?;
    model.fix("z0", Field::Phi, 0.0)?;
    model.fix("z1", Field::Phi, voltage)?;
    Ok(model)
}

/// The film on `mesh` with its top face's displacement tied in z, as a rigid pad would hold it
/// (one unknown that spans every rank holding a node of the top face).
pub fn tied_film(mesh: crate::mesh::Mesh, voltage: f64) -> Result<Model, ModelError> {
    let mut model = film_on(mesh, voltage)?;
    let nodes = model.set_nodes("z1")?;
    model.ties.push(crate::problem::dofs::Tie {
        nodes,
        field: Field::Uz,
        held: false,
    });
    Ok(model)
}

/// The film's closed form (`analytic::Film`) with the film's parameters.
pub fn film_closed_form() -> Film {
    Film {
        mu: FILM_MU,
        lambda: FILM_LAMBDA,
        eps: FILM_EPS_R * EPSILON_0,
        c2: 0.0,
    }
}

/// Shear modulus μ (Pa) of Cook's membrane (deal.II code gallery, "Quasi-static finite-strain
/// compressible elasticity", Pelteret & McBride 2016).
pub const COOK_MU: f64 = 422.5e3;
/// Shear traction (Pa) on Cook's loaded edge: 1 N over its 16 mm × 1 mm reference area.
pub const COOK_TRACTION: f64 = 1.0 / (16e-3 * 1e-3);

/// The through-thickness condition of Cook's membrane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Thickness {
    /// u_z = 0 everywhere (plane strain).
    PlaneStrain,
    /// u_z free except on the clamped edge (what the gallery's program computes).
    Free,
}

/// Cook's membrane (Cook 1974; the gallery's finite-strain version): the tapered plate with
/// corners (0,0), (48,44), (48,60), (0,44) mm, 1 mm thick, clamped at x = 0, the shear traction
/// [`COOK_TRACTION`] in +y on x = 48 mm, split neo-Hooke with μ = [`COOK_MU`] and
/// κ = 2μ(1+ν)/(3(1−2ν)). `n` hex8 cells per edge, one through the thickness: a unit box mapped
/// bilinearly, x = 48ξ, y = (1 − ξ)·44η + ξ·(44 + 16η) mm. No field: Φ = 0 on every node.
pub fn cook(
    n: usize,
    nu: f64,
    formulation: Formulation,
    thickness: Thickness,
) -> Result<Model, ModelError> {
    let mut mesh = box_mesh([1.0, 1.0, 1e-3], [n, n, 1], ElementKind::Hex8);
    for x in &mut mesh.nodes {
        let (xi, eta) = (x[0], x[1]);
        x[0] = 48e-3 * xi;
        x[1] = (1.0 - xi) * 44e-3 * eta + xi * (44e-3 + 16e-3 * eta);
    }
    let kappa = 2.0 * COOK_MU * (1.0 + nu) / (3.0 * (1.0 - 2.0 * nu));
    let params = MaterialParams {
        mu: vec![COOK_MU],
        kappa: Some(kappa),
        permittivity: Some(1.0),
        ..Default::default()
    };
    let (mat, _warnings) =
        build("neo-hooke-split", &params).map_err(|e| ModelError::Invalid(e.to_string()))?;
    let mut model = Model::new(mesh, mat)?;
    model.formulation = formulation;
    let all: Vec<usize> = (0..model.mesh.n_nodes()).collect();
    let left = model.set_nodes("x0")?;
    for field in [Field::Ux, Field::Uy, Field::Uz] {
        model.dirichlet.push(Dirichlet {
            nodes: left.clone(),
            field,
            value: 0.0,
        });
    }
    if thickness == Thickness::PlaneStrain {
        model.dirichlet.push(Dirichlet {
            nodes: all.clone(),
            field: Field::Uz,
            value: 0.0,
        });
    }
    model.dirichlet.push(Dirichlet {
        nodes: all,
        field: Field::Phi,
        value: 0.0,
    });
    model.add_traction("x1", [0.0, COOK_TRACTION, 0.0])?;
    Ok(model)
}

/// Vertical displacement (mm) of Cook's top right corner (48, 60) mm: the mean of the two nodes
/// through the thickness.
pub fn cook_tip(model: &Model, state: &[f64]) -> f64 {
    let a = model.mesh.nearest_node([48e-3, 60e-3, 0.0]);
    let b = model.mesh.nearest_node([48e-3, 60e-3, 1e-3]);
    0.5 * (state[a * FIELDS + 1] + state[b * FIELDS + 1]) * 1e3
}

/// A small film block for dynamics: a 2 × 2 × 1 mm quarter on 2×2×1 hex8, μ = 1e5, Λ = 4e5 Pa,
/// εᵣ = 4.7, held on the symmetry planes x0, y0 and the bottom z0 (unless `free`), no electrode
/// conditions. Returns the model and the nodes of its faces z0 and z1.
pub fn block(free: bool) -> Result<(Model, Vec<usize>, Vec<usize>), ModelError> {
    let mesh = box_mesh([2e-3, 2e-3, 1e-3], [2, 2, 1], ElementKind::Hex8);
    let mut model = Model::new(mesh, Arc::new(ElectroNeoHooke::new(1e5, 4e5, 4.7)))?;
    if !free {
        model.fix("x0", Field::Ux, 0.0)?;
        model.fix("y0", Field::Uy, 0.0)?;
        model.fix("z0", Field::Uz, 0.0)?;
    }
    let bottom = model.set_nodes("z0")?;
    let top = model.set_nodes("z1")?;
    Ok((model, bottom, top))
}

/// A slender bar `l` × 20 mm × 20 mm on 40×1×1 hex8, neo-Hooke with shear modulus `mu` and Λ = 0
/// (ν = 0, E = 2μ exactly), clamped at x = 0, Φ = 0 everywhere: axial vibration of a
/// clamped–free rod.
pub fn slender_bar(l: f64, mu: f64) -> Result<Model, ModelError> {
    let mesh = box_mesh([l, 0.02, 0.02], [40, 1, 1], ElementKind::Hex8);
    let mut model = Model::new(mesh, Arc::new(ElectroNeoHooke::new(mu, 0.0, 1.0)))?;
    for f in [Field::Ux, Field::Uy, Field::Uz] {
        model.fix("x0", f, 0.0)?;
    }
    model.dirichlet.push(Dirichlet {
        nodes: (0..model.mesh.n_nodes()).collect(),
        field: Field::Phi,
        value: 0.0,
    });
    Ok(model)
}

/// One 1 mm hex8 cell of `material` in uniaxial stress along x, stretched to 1.5 (symmetry faces
/// x0, y0, z0 held, x1 moved by 0.5 mm, lateral faces free, Φ = 0 on z0 and z1).
pub fn uniaxial_cell(material: Arc<dyn Material>) -> Result<Model, ModelError> {
    let l = 1e-3;
    let mesh = box_mesh([l, l, l], [1, 1, 1], ElementKind::Hex8);
    let mut m = Model::new(mesh, material)?;
    m.fix("x0", Field::Ux, 0.0)?;
    m.fix("x1", Field::Ux, 0.5 * l)?;
    m.fix("y0", Field::Uy, 0.0)?;
    m.fix("z0", Field::Uz, 0.0)?;
    m.fix("z0", Field::Phi, 0.0)?;
    m.fix("z1", Field::Phi, 0.0)?;
    Ok(m)
}

/// Side of the square membrane of [`membrane`] (m).
pub const MEMBRANE_SIDE: f64 = 10e-3;
/// Thickness of the membrane (m).
pub const MEMBRANE_THICKNESS: f64 = 0.1e-3;
/// Equibiaxial pre-stretch of the membrane.
pub const MEMBRANE_STRETCH: f64 = 1.5;

/// The pre-stretched membrane: a 10 × 10 × 0.1 mm film of neo-Hooke (μ = 1e5, Λ = 1e7 Pa,
/// εᵣ = 4.7) on n × n × 1 hex8, its side faces held in plane at the stretch
/// [`MEMBRANE_STRETCH`] and out of plane along their bottom edge (the film thins freely), the
/// bottom face grounded and the top face at `volts`.
pub fn membrane(n: usize, volts: f64) -> Result<Model, ModelError> {
    let mesh = box_mesh(
        [MEMBRANE_SIDE, MEMBRANE_SIDE, MEMBRANE_THICKNESS],
        [n, n, 1],
        ElementKind::Hex8,
    );
    let mut m = Model::new(mesh, Arc::new(membrane_material()))?;
    let mut sides: Vec<usize> = Vec::new();
    for s in ["x0", "x1", "y0", "y1"] {
        sides.extend(m.set_nodes(s)?);
    }
    sides.sort_unstable();
    sides.dedup();
    for &node in &sides {
        let x = m.mesh.nodes[node];
        let stretched = [
            (Field::Ux, (MEMBRANE_STRETCH - 1.0) * x[0]),
            (Field::Uy, (MEMBRANE_STRETCH - 1.0) * x[1]),
        ];
        for (field, value) in stretched {
            m.dirichlet.push(Dirichlet {
                nodes: vec![node],
                field,
                value,
            });
        }
        if x[2] == 0.0 {
            m.dirichlet.push(Dirichlet {
                nodes: vec![node],
                field: Field::Uz,
                value: 0.0,
            });
        }
    }
    m.fix("z0", Field::Phi, 0.0)?;
    m.fix("z1", Field::Phi, volts)?;
    Ok(m)
}

/// The membrane's material.
pub fn membrane_material() -> ElectroNeoHooke {
    ElectroNeoHooke::new(1e5, 1e7, 4.7)
}

/// A state of `model` for tests of the cell passes: a uniform stretch of `stretch` in every
/// direction plus a smooth displacement wave of amplitude `wave` (m), and a potential wave of
/// amplitude `potential` (V), different at every node and field.
#[cfg(test)]
pub(crate) fn wavy_state(model: &Model, stretch: f64, wave: f64, potential: f64) -> Vec<f64> {
    use crate::problem::dofs::PHI;
    (0..model.mesh.n_nodes() * FIELDS)
        .map(|d| {
            let x = model.mesh.nodes[d / FIELDS];
            let w = (300.0 * x[0] + 500.0 * x[1] + 700.0 * x[2] + d as f64).sin();
            if d % FIELDS == PHI {
                potential * w
            } else {
                stretch * x[d % FIELDS] + wave * w
            }
        })
        .collect()
}
