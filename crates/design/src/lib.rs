//! Pattern design for skintight (thesis chapters 6–7): the 2D pattern shapes are changed until the worn
//! garment meets the designer's objectives. Each objective evaluation solves the garment on the body to
//! equilibrium (`skintight_physics`); gradients come from the adjoint method.
//!
//! **The problem.**
//! - [`design_mesh`]: the garment's cloth and pattern connectivity as the design terms see it.
//! - [`design_problem`]: the objective `T(X̄) = Σ T_i(x*(X̄), X̄)` as a function of the pattern, through the
//!   equilibrium, and its gradient by the adjoint method (Eq. 160–164); also the linearization (residuals,
//!   Jacobians, equilibrium Hessian) the Gauss-Newton directions are built from.
//! - [`term`]: the objective/regularizer abstraction ([`Term`]: value, per-element report, gradient with
//!   respect to the cloth and the pattern positions, sum-of-squares residuals for Gauss-Newton), and
//!   [`term::check_weight`], the one check of term weights.
//!
//! **Objectives**, [`Term`]s on the worn cloth:
//! - [`shape_imls`]: shape (Eq. 171–172), [`ShapeImls`]: squared IMLS distance of the cloth vertices to a
//!   target surface (m² × weight), with the procedural targets [`cylinder_target`] and [`sphere_target`].
//! - [`fabric_stretch_limit`]: the fabric's stretch limits along the wales and courses as a penalty
//!   constraint, [`FabricStretchLimit`] (m² × weight).
//! - [`stretch_window`]: stretch (Eq. 173), [`StretchWindow`]: area-weighted squared excursion of the
//!   principal stretches outside `[λmin, λmax]` (m² × weight).
//! - [`young_laplace_pressure`]: the Young–Laplace interface pressure `p = (d/Ā) S : W` of every cloth
//!   triangle (Eq. 174), from the mid-edge shape operator with its normal corrections
//!   ([`mid_edge_shape_operator`], Eq. 175–176, 180); [`pressure`]: the pressure objective (Eq. 177),
//!   [`Pressure`]: area-weighted squared deviation of that pressure from a target value or range
//!   (m² Pa² × weight), plus a lift-off penalty on negative pressure.
//! - [`band_pressure`]: the Young–Laplace pressure averaged over bands across a limb, each inside its own
//!   window, [`BandPressure`] (m² Pa² × weight) — what a compression prescription (class and profile)
//!   becomes.
//! - [`seam_traction`]: seam stress (Eq. 181), [`SeamTraction`]: the normal traction `n·S n` of the second
//!   Piola–Kirchhoff stress across every seam edge, squared (m² Pa² × weight) or plain as in the thesis
//!   (N × weight), chosen by [`SeamTractionForm`].
//! - [`sliding`]: sliding over several body poses with Coulomb friction (Eq. 182–183), [`Sliding`]: the
//!   squared excess of the tangential force over `μ` times the normal force at every cloth vertex carried
//!   to each pose (N² × weight).
//!
//! **Regularizers** (thesis §6.3), [`Term`]s on the pattern positions (and, for the last, the state):
//! - [`seam_length`]: equal lengths of corresponding seam edges (Eq. 184);
//! - [`boundary_smoothness`]: bending energy of the panel boundaries, pattern corners excluded (Eq. 185);
//! - [`edge_length_uniformity`]: equal lengths of consecutive boundary edges (text after Eq. 185);
//! - [`compactness`]: no thin patterns, from boundary chord/arc ratios (Eq. 186–187);
//! - [`pinned_traction`]: no tangential force on the cloth vertices pinned to the body (Eq. 188,
//!   J² × weight).
//!
//! **The design parametrization** (thesis ch. 6–7): [`mod@biharmonic_coordinates`] (interior vertices as
//! linear combinations of boundary vertices, reproducing linear functions), [`pattern_map`] (design
//! parameters = boundary positions → all pattern positions, with Jacobian and transpose) and
//! [`boundary_modes`] (a low-frequency boundary basis for a coarse-to-fine start).
//!
//! **The design loop.** [`mod@pattern_design`]: L-BFGS or adjoint Gauss-Newton ([`Optimizer`]) over the
//! pattern boundary, optionally coarse to fine over boundary modes, stopping for a remesh when the pattern
//! degrades, reporting every iteration and returning the best design; [`mod@design_checkpoint`] is where
//! it stands after an iteration. The optimizers themselves live in `skintight_optimize` (re-exported as
//! [`optimize`]), generic over a problem trait; [`mod@design_linearization`] puts the design problem's
//! linearization in their form.
//!
//! **Remeshing.** [`mod@pattern_quality`]: triangle shape quality `4√3·A / Σ edge²`, boundary edge ratio and
//! the remesh trigger ([`PatternQualityParams`]); [`mod@design_remesh`]: remesh the degraded patterns and
//! re-embed the worn garment so the optimization continues where it was.
//!
//! Units: SI throughout — positions in m, stresses and pressures in Pa, forces in N, energies in J.
//! Objective values carry the units their documentation states (a unit of length², Pa², N² or J² times
//! the weight's unit); the optimizers work on the normalized objective `T / T₀`
//! (see [`mod@pattern_design`]).

pub use skintight_geometry::math;
/// The optimizers the design loop runs (L-BFGS, adjoint Gauss-Newton), generic over the problem.
pub use skintight_optimize as optimize;
/// The optimizers' settings, stop reasons and checkpoint states, as the design loop's settings name them.
pub use skintight_optimize::{
    GaussNewtonParams, GaussNewtonSolver, LbfgsParams, OptimizerState, OptimizerStop,
};

// The problem.
pub mod design_mesh;
pub mod design_problem;
pub mod equilibrium_predictor;
pub mod term;

// Objectives.
pub mod band_pressure;
pub mod fabric_stretch_limit;
pub mod mid_edge_shape_operator;
pub mod pressure;
pub mod seam_traction;
pub mod shape_imls;
pub mod sliding;
pub mod stretch_window;
pub mod young_laplace_pressure;

// Regularizers.
pub mod boundary_smoothness;
pub mod compactness;
pub mod edge_length_uniformity;
pub mod pinned_traction;
pub mod seam_length;

// The design parametrization.
pub mod biharmonic_coordinates;
pub mod boundary_modes;
pub mod pattern_map;

// The design loop.
pub mod design_checkpoint;
pub mod design_iteration;
pub mod design_linearization;
pub mod inexact_tolerance;
pub mod pattern_design;

// Remeshing.
pub mod design_remesh;
pub mod pattern_quality;

// Internals and test fixtures.
mod dual;
mod regularizer_input;
#[cfg(test)]
mod test_support;
mod triangle_strain;

pub use band_pressure::{BandPressure, PressureBand, band_weight};
pub use design_checkpoint::DesignCheckpoint;
pub use design_linearization::DesignLinearization;
pub use design_mesh::{DesignMesh, DesignPanel, DesignSeam};
pub use design_problem::{
    DesignError, DesignEvaluation, DesignProblem, EquilibriumTotals, EvaluationStart, FINAL_ROUNDS,
    TermReport,
};
pub use design_remesh::{RemeshedDesign, design_remesh, remesh_edge_length};
pub use fabric_stretch_limit::FabricStretchLimit;
pub use mid_edge_shape_operator::{
    BoundaryEdges, MidEdgeError, MidEdgeShapeOperator, MidEdgeSolution,
};
pub use pattern_design::{
    DesignIteration, Optimizer, PatternDesignParams, PatternDesignResult, pattern_design,
    pattern_design_from,
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

pub use biharmonic_coordinates::{BiharmonicCoordinates, BiharmonicError, biharmonic_coordinates};
pub use boundary_modes::{BoundaryModes, BoundaryModesError};
pub use boundary_smoothness::BoundarySmoothness;
pub use compactness::Compactness;
pub use edge_length_uniformity::EdgeLengthUniformity;
pub use inexact_tolerance::InexactTolerance;
pub use pattern_map::{PatternMap, PatternMapError};
pub use pattern_quality::{
    PatternQuality, PatternQualityParams, pattern_quality, triangle_quality,
};
pub use pinned_traction::PinnedTraction;
pub use seam_length::SeamLength;
pub use sliding::Sliding;
