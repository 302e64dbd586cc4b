//! Pattern design for skintight (thesis chapters 6–7): the 2D pattern shapes are changed until the worn
//! garment meets the designer's objectives.
//!
//! - [`design_mesh`]: the garment's cloth and pattern connectivity as the design terms see it.
//! - [`design_problem`]: the objective as a function of the pattern, through the equilibrium, and its
//!   gradient by the adjoint method (Eq. 160–164).
//! - [`term`]: the objective/regularizer abstraction (value, per-element report, gradient with respect to
//!   the cloth positions and the pattern positions, and sum-of-squares residuals for Gauss-Newton).
//! - [`shape_imls`]: the shape objective (Eq. 171–172), [`ShapeImls`]: squared IMLS distance of the cloth
//!   vertices to a target surface (m² × weight), with the procedural targets [`cylinder_target`] and
//!   [`sphere_target`].
//! - [`stretch_window`]: the stretch objective (Eq. 173), [`StretchWindow`]: area-weighted squared
//!   excursion of the principal stretches outside `[λmin, λmax]` (m² × weight).
//! - [`seam_traction`]: the seam stress objective (Eq. 181), [`SeamTraction`]: the normal traction
//!   `n·S n` of the second Piola–Kirchhoff stress across every seam edge, squared (m² Pa² × weight) or
//!   plain as in the thesis (N × weight), chosen by [`SeamTractionForm`].
//!
//! Units: SI throughout — positions in m, stresses in Pa, forces in N. Objective values carry the units
//! their documentation states.

pub use skintight_geometry::math;

pub mod design_mesh;
pub mod design_problem;
pub mod seam_traction;
pub mod shape_imls;
pub mod stretch_window;
pub mod term;
#[cfg(test)]
mod test_support;
mod triangle_strain;

pub use design_mesh::{DesignMesh, DesignPanel, DesignSeam};
pub use design_problem::{DesignError, DesignEvaluation, DesignProblem, TermReport};
pub use seam_traction::{SeamTraction, SeamTractionForm};
pub use shape_imls::{ShapeImls, cylinder_target, sphere_target};
pub use stretch_window::StretchWindow;
pub use term::{Fabric, Residuals, Term, TermError, TermEvaluation, TermGradient, TermInput};
