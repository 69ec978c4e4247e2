//! The discrete boundary value problem: dofs and constraints, the body (mesh, materials,
//! formulation, loads), assembly of residual and tangent, and the static problem.

pub mod assembly;
pub mod circuit;
pub mod distributed;
pub mod dofs;
pub mod drive;
pub mod examples;
pub mod faces;
pub mod field_penalty;
pub mod kept_tangents;
pub mod loads;
pub mod model;
pub mod points;
pub mod pressure;
pub mod statics;
pub mod step;
