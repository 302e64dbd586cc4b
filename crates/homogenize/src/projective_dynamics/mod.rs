//! Projective dynamics of the volumetric knit (the knitwear paper, Sec. 7.1, Eq. 25–28; Bouaziz et al.
//! 2014): a backward-Euler step `x = argmin a/(2Δt²) ‖x − y‖²_M + E(x) − f·x` of the mesh with the
//! material of Eq. 7, solved by alternating a **local step** (per element the targets `R(F_e)` and
//! `V(F_e)` that the energy measures its distance to) and a **global step** (one linear solve with a
//! matrix that depends only on the mesh, `γ` and `Δt`, factored once).
//!
//! - [`local_step`]: per element `F_e`, `R(F_e)`, `V(F_e)` and the target `P_e`, with `E(x)`, on
//!   several threads; [`local_step::element_weights`] the global step's `ω_e = 2V_e(γˢ_e + γᵛ_e)`.
//! - [`global_step`]: the linear solve of Eq. 27–28, `K x = b`, in three scalar systems that share one
//!   Cholesky factorization.
//! - [`jacobi_global_step`]: the same system by (Chebyshev-accelerated) Jacobi sweeps, warm-started.
//! - [`backward_euler`]: the time step ([`ProjectiveDynamics`]): inertia, gravity, clamped and moving
//!   nodes, mass-proportional Rayleigh damping, PD iterations to a relative residual of `∇Ψ`.
//!
//! - [`body_collision`]: the embedded yarns kept out of rigid spheres and cylinders, as PD constraints
//!   of constant weight (so `K` is still factored once).
//!
//! Domain decomposition (Sec. 7.2) is not here yet.

pub mod backward_euler;
pub mod body_collision;
pub mod global_step;
pub mod jacobi_global_step;
pub mod local_step;

pub use backward_euler::{
    GlobalSolver, PdStepReport, ProjectiveDynamics, ProjectiveDynamicsError,
    ProjectiveDynamicsParams,
};
pub use body_collision::{BodyCollider, BodyCollision, BodyCollisionError};
pub use global_step::{GlobalStep, GlobalStepError};
pub use jacobi_global_step::{JacobiError, JacobiGlobalStep, JacobiParams};
pub use local_step::{LocalStepError, element_weights, local_step};
