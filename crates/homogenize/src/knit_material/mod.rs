//! The material of the volumetric knit (the knitwear paper Eq. 7–8): per element
//!
//! ```text
//! E_e = γˢ_e V_e ‖F_e − R(F_e)‖²_F + γᵛ_e V_e ‖F_e − V(F_e)‖²_F      (J; γ in Pa, V_e in m³)
//! ```
//!
//! with `R` the closest rotation and `V` the closest volume-preserving matrix
//! ([`crate::closest_volume_preserving`]), one file per level:
//! - [`density`]: `ψ(F)` per unit rest volume, its stress and its 9 × 9 Hessian (exact, or the
//!   analytic PSD-filtered form), and how they were derived (envelope theorem, isotropic Hessian);
//! - [`element`]: one linear tetrahedron, `F = D_s D_m⁻¹`, derivatives with respect to its 12
//!   coordinates and to `γ`;
//! - [`assembly`]: the sum over a [`crate::volumetric_mesh::VolumetricMesh`] with `γ` per element
//!   (`#T × 2`): energy, gradient `3#V`, Hessian triplets, `∂g/∂γ` (`3#V × 2#T`);
//! - [`quasi_static`]: `min_x Σ_e E_e − f·x` with held coordinates as a Newton toolkit problem (the
//!   per-pose equilibrium of the elasticity fit, Eq. 14).

pub mod assembly;
pub mod density;
pub mod element;
pub mod quasi_static;
#[cfg(test)]
pub(crate) mod test_states;

pub use assembly::{KnitMaterial, KnitMaterialError, MaterialEvaluation};
pub use density::{CUT_LOCUS_FLOOR, DensityEvaluation, MaterialHessian, knit_density};
pub use element::{ElementEvaluation, RestTet, RestTetError, knit_element};
pub use quasi_static::{QuasiStaticError, QuasiStaticParams, QuasiStaticProblem};
