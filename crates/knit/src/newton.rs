//! The yarn solves' Newton method — the periodic cell's rest and strained states
//! ([`crate::periodic_cell`]), the time steps and the relaxation of a patch
//! ([`crate::implicit_euler`]) — is the Newton toolkit's minimizer ([`skintight_physics::newton`]):
//! Levenberg–Marquardt shift on the scaled diagonal, Armijo backtracking cut to the yarns' step limit,
//! the pattern cache across iterations and time steps. This crate keeps its problems (the
//! [`NewtonProblem`] implementations) and this choice of policy; the names are re-exported here so that
//! the yarn code and its callers name one place.
//!
//! Why this policy for yarns, not the garment's trust-ratio damping: contact and compressed rods make
//! the Hessian indefinite away from equilibrium and the steps are cut to a quarter radius per vertex (a
//! step cannot jump a yarn through another), so the shift must factor any matrix and the step's model
//! quality says little; see [`skintight_physics::newton::LevenbergMarquardt`]. Measurements:
//! docs/BENCHMARKS.md ("Moved from module docs (issue 42, newton)").

pub use skintight_physics::newton::{
    MinimizeFigures, NewtonError, NewtonParams, NewtonProblem, NewtonReport, NewtonTimings,
    NewtonWorkspace, StopReason, minimize, minimize_with,
};
