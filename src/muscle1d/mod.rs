//! The 1D Hill muscle: the law's uniaxial reduction as a time-stepped muscle
//! (MODEL_NOTES "The 1D Hill reduction" and "Co-simulation conventions"). No
//! FMI in it: `crate::fmus::hill1d` adapts it to the FMI layer.
//!
//! A prismatic muscle of rest length `L0` and cross-section `area` in
//! homogeneous uniaxial stress. Each step ([`Muscle1D::step`]):
//! 1. the activation level follows da/dt = S (u − a) exactly for the command
//!    held over the step (or linear over the step when an input derivative is
//!    set); with `activation_dynamics = false` the level is the command;
//! 2. the length moves linearly from where it is to the input `length` — or
//!    to `length + h · dlength/dt` when an input derivative is set — and the
//!    step ends there;
//! 3. the uniaxial state (lateral stretch from σ22 = 0, CE–SEE solve inside)
//!    is solved at the end of the step, in substeps when the error estimate
//!    of the CE–SEE update asks for them ([`piece_error`]): each substep is
//!    MODEL_NOTES' backward-Euler step over its own length (CE rate from the
//!    CE stretch change over it), so a step that needs no substep — the usual
//!    case with smooth inputs — is exactly that step over h; stiff transients
//!    (a stiff SEE, fast activation, length jumps) get as many as keep the
//!    estimated local error of the SEE stress below `substep_tolerance`·sigma0.
//!    Acceptance, growth and reduction of a piece are [`crate::step_control`]'s;
//!    this module places the pieces on a dyadic grid of the step.
//!
//! The state is committed only on success: a failed step ([`Discard`])
//! leaves the muscle unchanged. At initialization ([`Muscle1D::initialize`])
//! the muscle is in isometric equilibrium at its initial length and
//! `initial_activation`.
//!
//! The muscle is generic over the law's components ([`crate::law::Components`]):
//! an absent component's branch is a `false` constant and is not compiled.
//!
//! Files: [`muscle`] the parameters, inputs and committed state with
//! initialization and the step's entry point; [`step`] the step map and its
//! error control; [`predictor`] the solvers' starting points; [`outputs`]
//! the outputs and their partial derivatives; [`error`] what goes wrong and
//! its messages; [`musculotendon`] the muscle in series with a tendon at a
//! pennation angle, driven by its path length (its pieces' ends solved
//! through the step map's [`step::PieceEnd`] hook).

pub mod error;
pub mod muscle;
pub mod musculotendon;
pub mod outputs;
pub mod predictor;
pub mod step;

pub use error::{Discard, SetupError};
pub use muscle::{Muscle1D, DEFAULT_AREA, DEFAULT_L0};
pub use musculotendon::{Musculotendon1D, UnitOutput};
pub use outputs::{Input, Jacobian, Output, N_OUT};
pub use predictor::Predictor;
pub use step::{piece_error, StepStatistics};
