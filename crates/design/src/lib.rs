//! Pattern design for skintight (thesis chapters 6–7): the 2D pattern shapes are changed until the worn
//! garment meets the designer's objectives.
//!
//! - [`design_mesh`]: the garment's cloth and pattern connectivity as the design terms see it.
//! - [`design_problem`]: the objective as a function of the pattern, through the equilibrium, and its
//!   gradient by the adjoint method (Eq. 160–164).
//! - [`pattern_design`]: the design loop — L-BFGS over the pattern boundary, optionally coarse to fine
//!   over boundary modes, reporting every iteration and returning the best design.
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
//! - [`pressure`]: the pressure objective (Eq. 177), [`Pressure`]: area-weighted squared deviation of the
//!   Young–Laplace interface pressure ([`young_laplace_pressure`], Eq. 174) from a target value or range
//!   (m² Pa² × weight), plus a lift-off penalty on negative pressure; the pressure uses the mid-edge
//!   shape operator with its normal corrections ([`mid_edge_shape_operator`], Eq. 175–176, 180).
//! - Regularizers (thesis §6.3), [`Term`]s on the pattern positions only:
//!   - [`seam_length`]: equal lengths of corresponding seam edges (Eq. 184);
//!   - [`boundary_smoothness`]: bending energy of the panel boundaries, pattern corners excluded (Eq. 185);
//!   - [`edge_length_uniformity`]: equal lengths of consecutive boundary edges (text after Eq. 185);
//!   - [`compactness`]: no thin patterns, from boundary chord/arc ratios (Eq. 186–187).
//! - The design parametrization (thesis ch. 6–7): [`mod@biharmonic_coordinates`] (interior vertices as
//!   linear combinations of boundary vertices, reproducing linear functions), [`pattern_map`] (design
//!   parameters = boundary positions → all pattern positions, with Jacobian and transpose) and
//!   [`boundary_modes`] (a low-frequency boundary basis for a coarse-to-fine start).
//! - [`pattern_quality`]: triangle shape quality `4√3·A / Σ edge²`, boundary edge ratio and the remesh
//!   trigger ([`PatternQualityParams`]).
//! - [`mod@lbfgs`]: L-BFGS with a strong-Wolfe line search, tolerant of failing evaluations, always
//!   returning the best point seen.
//!
//! Units: SI throughout — positions in m, stresses in Pa, forces in N. Objective values carry the units
//! their documentation states.

pub use skintight_geometry::math;

pub mod design_mesh;
pub mod design_problem;
pub mod design_remesh;
mod dual;
pub mod mid_edge_shape_operator;
pub mod pattern_design;
pub mod pressure;
pub mod seam_traction;
pub mod shape_imls;
pub mod stretch_window;
pub mod term;
#[cfg(test)]
mod test_support;
mod triangle_strain;
pub mod young_laplace_pressure;

pub mod adjoint_gauss_newton;
pub mod biharmonic_coordinates;
pub mod boundary_modes;
pub mod boundary_smoothness;
pub mod compactness;
pub mod edge_length_uniformity;
pub mod gauss_newton;
pub mod lbfgs;
pub mod pattern_map;
pub mod pattern_quality;
pub mod pinned_traction;
pub mod reduced_gauss_newton;
pub mod seam_length;
pub mod sliding;

mod regularizer_input;
#[cfg(test)]
mod regularizer_test_support;

pub use design_mesh::{DesignMesh, DesignPanel, DesignSeam};
pub use design_problem::{DesignError, DesignEvaluation, DesignProblem, Linearization, TermReport};
pub use design_remesh::{RemeshedDesign, design_remesh, remesh_edge_length};
pub use mid_edge_shape_operator::{
    BoundaryEdges, MidEdgeError, MidEdgeShapeOperator, MidEdgeSolution,
};
pub use pattern_design::{
    DesignIteration, GaussNewtonSolver, Optimizer, PatternDesignParams, PatternDesignResult,
    pattern_design,
};
pub use pressure::{Pressure, PressureTarget};
pub use seam_traction::{SeamTraction, SeamTractionForm};
pub use shape_imls::{ShapeImls, cylinder_target, sphere_target};
pub use stretch_window::StretchWindow;
pub use term::{
    Fabric, Residuals, StateInput, Term, TermError, TermEvaluation, TermGradient, TermInput,
};
pub use young_laplace_pressure::{
    PressureStatistics, TrianglePressure, cauchy_stress, young_laplace_pressures,
    young_laplace_statistics,
};

pub use adjoint_gauss_newton::{
    AdjointGaussNewton, GaussNewtonDirection, GaussNewtonError, GaussNewtonSystem,
    design_map_matrix,
};
pub use biharmonic_coordinates::{BiharmonicCoordinates, BiharmonicError, biharmonic_coordinates};
pub use boundary_modes::{BoundaryModes, BoundaryModesError};
pub use boundary_smoothness::BoundarySmoothness;
pub use compactness::Compactness;
pub use edge_length_uniformity::EdgeLengthUniformity;
pub use gauss_newton::{
    GaussNewtonIteration, GaussNewtonOutcome, GaussNewtonParams, GaussNewtonRunError, gauss_newton,
};
pub use lbfgs::{LbfgsError, LbfgsIteration, LbfgsParams, LbfgsResult, StopReason, lbfgs};
pub use pattern_map::{PatternMap, PatternMapError};
pub use pattern_quality::{
    PatternQuality, PatternQualityParams, pattern_quality, triangle_quality,
};
pub use pinned_traction::PinnedTraction;
pub use reduced_gauss_newton::reduced_gauss_newton_direction;
pub use seam_length::SeamLength;
pub use sliding::Sliding;
