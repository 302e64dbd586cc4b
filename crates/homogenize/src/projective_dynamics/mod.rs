//! Projective dynamics of the volumetric knit (the knitwear paper, Sec. 7.1, Eq. 25–28; Bouaziz et al.
//! 2014): a backward-Euler step `x = argmin ½ ‖x − y‖²_M / Δt² + Σ_e E_e(x) − f·x` of the mesh with the
//! material of Eq. 7, solved by alternating a **local step** (per element the targets `R(F_e)` and
//! `V(F_e)` that the energy measures its distance to) and a **global step** (one linear solve with a
//! matrix that depends only on the mesh, `γ` and `Δt`, factored once).
//!
//! - [`global_step`]: the linear solve of Eq. 27–28, `K x = b`, in three scalar systems that share one
//!   factorization.

pub mod global_step;

pub use global_step::{GlobalStep, GlobalStepError};
