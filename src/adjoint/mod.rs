//! Gradients of a run's objective J by the discrete adjoint of the steps the run accepted: the
//! forward run records its accepted load steps ([`tape::Tape`]); the backward sweep
//! ([`sweep::gradient`]) solves, from the last step to the first, the transposed step Jacobian
//! for the adjoint λₙ,
//!   (∂Rₙ/∂xₙ)ᵀ λₙ = ∂J/∂xₙ (+ what later steps take from xₙ),
//! and sums dJ/dp = ∂J/∂p − Σₙ λₙᵀ ∂Rₙ/∂p. The derivatives are those of the discretised
//! equations as solved, cut-backs included, so the gradient is exact for the computed solution
//! up to the round-off of the solves (Giles & Pierce, Flow Turbul. Combust. 65 (2000) 393;
//! Farrell et al., SIAM J. Sci. Comput. 35 (2013) C369).
//!
//! Under a memory budget the tape keeps a long dynamic stage as checkpoints
//! ([`tape::Tape::with_budget`]), whose steps [`replay`] recomputes for the sweep by the
//! schedule of [`binomial`]; the objective reads every step as the sweep meets it
//! ([`objective::Backward`]), so that the gradient is the same with and without recomputation.
//!
//! What is differentiated today: static, quasi-static and dynamic (midpoint, Newmark) stages of
//! elastic and viscoelastic materials (Maxwell branches, whose internal variables each step
//! commits and the sweep carries back) with Kelvin–Voigt viscosity, rigid pads and a
//! pre-stretch, instantaneous or timed ([`dynamic`] for the time steps), in the materials'
//! parameters and viscosities, the electrodes' waveforms' amplitudes, offsets and frequencies,
//! the follower pressures' values, the pads' masses, the pre-stretch, and the knots of
//! controlled voltages ([`sink::ControlGradient`]); the objective terms of
//! [`objective::Objective`]. Anything else is refused with a message that names it.

pub mod binomial;
pub mod charge;
pub mod dynamic;
pub mod lambda;
pub mod objective;
pub mod replay;
pub mod sink;
pub mod sweep;
pub mod tape;
