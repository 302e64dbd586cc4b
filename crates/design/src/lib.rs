//! Pattern design for skintight (thesis chapters 6–7): the 2D pattern shapes are changed until the worn
//! garment meets the designer's objectives.
//!
//! - [`design_mesh`]: the garment's cloth and pattern connectivity as the design terms see it.
//! - [`term`]: the objective/regularizer abstraction (value, per-element report, gradient with respect to
//!   the cloth positions and the pattern positions, and sum-of-squares residuals for Gauss-Newton).
//!
//! Units: SI throughout — positions in m, stresses in Pa, forces in N. Objective values carry the units
//! their documentation states.

pub use skintight_geometry::math;

pub mod design_mesh;
pub mod seam_traction;
pub mod shape_imls;
pub mod stretch_window;
pub mod term;
#[cfg(test)]
mod test_support;
mod triangle_strain;

pub use design_mesh::{DesignMesh, DesignPanel, DesignSeam};
pub use seam_traction::{SeamTraction, SeamTractionForm};
pub use shape_imls::{ShapeImls, cylinder_target, sphere_target};
pub use stretch_window::StretchWindow;
pub use term::{Fabric, Residuals, Term, TermError, TermEvaluation, TermGradient, TermInput};
