//! The elasticity fit (the knitwear paper, Sec. 6): the per-element material parameters `γ` (`2#T`,
//! Pa) for which the mesh's quasi-static equilibria reproduce the fitted poses of a yarn-level sequence.
//!
//! **Loss (Eq. 9–10).** Over the poses `i`, `T(γ) = Σᵢ εᵢ(xᵢ(γ))` with `εᵢ` the shape-fit error
//! ([`crate::shape_fit::ShapeFit::error`], m³) of the mesh positions `xᵢ` against pose `i`'s target, and
//! `xᵢ(γ)` the equilibrium `gᵢ(x, γ) = ∇E(x; γ) − fᵢ = 0` on the pose's free coordinates (Eq. 14: `fᵢ` the
//! external plus inertia forces, N; the pose's clamped coordinates held at their prescribed values). The
//! equilibrium is solved with the Newton toolkit ([`crate::knit_material::QuasiStaticProblem`]), warm
//! started from the last equilibrium found.
//!
//! **Adjoint gradient (Eq. 15–17).** With `Hᵢ = ∂gᵢ/∂x` (the exact material Hessian, N/m, on the free
//! coordinates) and `Kᵢ = ∂gᵢ/∂γ` ([`crate::knit_material::KnitMaterial::gradient_per_gamma`], m²), the
//! implicit derivative is `dxᵢ/dγ = −Hᵢ⁻¹ Kᵢ`, so `dT/dγ = −Σᵢ Kᵢᵀ λᵢ` with the adjoint `Hᵢ λᵢ = ∂εᵢ/∂x`
//! (one solve per pose with the factor of `Hᵢ`; the clamped rows of `λ` and `K` are zero). The variables
//! `c` give `γ = A c` through a constant map `A`: `γ` itself scaled to order one, or harmonic coefficients
//! with `A = diag(H, H)` (Eq. 23–24, [`crate::harmonic_basis`]); `dT/dc = Aᵀ dT/dγ`.
//!
//! **Gauss-Newton (Eq. 18–21).** The loss is a sum of squares (the residual form
//! [`crate::shape_fit::ShapeFit::error_residuals`]), so the problem is an
//! [`skintight_optimize::AdjointProblem`]: state `q` = all poses' positions, parameters `p = γ`,
//! `U = Σᵢ (E(xᵢ; γ) − fᵢ · xᵢ)`, whose block-diagonal Hessian and mixed derivative `K` the linearization
//! returns. The direction and the line search are the shared optimizer's
//! ([`skintight_optimize::AdjointGaussNewton`], [`skintight_optimize::gauss_newton`]); a trial with a
//! negative `γ` is not a material ([`crate::knit_material::KnitMaterial::set_gamma`] refuses it) and the
//! line search shortens the step.
//!
//! Files: [`adjoint_loss`] (the problem above).

pub mod adjoint_loss;

pub use adjoint_loss::{ElasticityFit, ElasticityFitError, ElasticityFitParams, FitPose};
