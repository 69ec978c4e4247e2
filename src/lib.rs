//! deasim: a finite-strain electro-mechanical finite element simulator for dielectric elastomer
//! actuators. Unknowns are the displacement u and the electric potential Φ at every node; the
//! equations are the stationarity conditions of one energy Π(u, Φ) = ∫Ψ(F, E₀) dV − W_ext.
//!
//! Modules depend one way (`docs/architecture.md`; checked by `tests/architecture.rs`):
//! units, mesh, fem, material, waveform, analytic → element → problem → solve, time → job → io →
//! lumped → cli.

pub mod adjoint;
pub mod algebra;
pub mod analytic;
pub mod api;
pub mod calibrate;
pub mod cli;
pub mod control;
pub mod element;
pub mod fem;
pub mod io;
pub mod job;
pub mod lumped;
pub mod material;
pub mod mesh;
pub mod problem;
pub mod solve;
pub mod time;
pub mod units;
pub mod waveform;
