//! Ready-made models used by tests, benchmarks and validation.

use crate::material::ElectroNeoHooke;
use crate::mesh::{generate::box_mesh, ElementKind};
use crate::problem::dofs::Field;
use crate::problem::model::{Model, ModelError};
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
    let mesh = box_mesh(FILM_SIZE, divisions, kind);
    let material = Arc::new(ElectroNeoHooke::new(FILM_MU, FILM_LAMBDA, FILM_EPS_R));
    let mut model = Model::new(mesh, material)?;
    model.fix("x0", Field::Ux, 0.0)?;
    model.fix("y0", Field::Uy, 0.0)?;
    model.fix("z0", Field::Uz, 0.0)?;
    model.fix("z0", Field::Phi, 0.0)?;
    model.fix("z1", Field::Phi, voltage)?;
    Ok(model)
}
