//! deasim: a finite-strain electro-mechanical finite element simulator for dielectric elastomer
//! actuators. Unknowns are the displacement u and the electric potential Φ at every node; the
//! equations are the stationarity conditions of one energy Π(u, Φ) = ∫Ψ(F, E₀) dV − W_ext.
//!
//! See `docs/architecture.md` for the data flow and the module responsibilities.

pub mod analysis;
pub mod analytic;
pub mod app;
pub mod assembly;
pub mod bench;
pub mod dofs;
pub mod element;
pub mod element_fbar;
pub mod examples;
pub mod fem;
pub mod io;
pub mod loads;
pub mod lumped;
pub mod material;
pub mod mesh;
pub mod model;
pub mod solve;
pub mod sweep;
pub mod time;
pub mod validate;
pub mod waveform;
