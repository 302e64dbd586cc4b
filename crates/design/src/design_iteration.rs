//! The progress report of one accepted design iteration ([`crate::pattern_design()`]): what the service
//! streams as an `iteration` event and writes to `history.json`, and what a checkpoint keeps of the
//! history ([`mod@crate::design_checkpoint`]). Units on every field.

use crate::math::Real;

/// Progress after one accepted design iteration (what the service streams).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DesignIteration {
    /// Accepted steps so far over all levels (0: the initial design).
    pub iteration: usize,
    /// Coarse-to-fine level (0-based; `mode_levels.len()` for the boundary positions).
    pub level: usize,
    /// The objective `T` (units of the terms).
    pub objective: Real,
    /// Each term's name and value.
    pub terms: Vec<(String, Real)>,
    /// `‖dT/dp‖₂` with respect to the boundary positions (units of T per m).
    pub gradient_norm: Real,
    /// The accepted step, in cloth edge lengths along the search direction (0 at the start).
    pub step_length: Real,
    /// Smallest and largest principal stretch of the cloth (dimensionless).
    pub min_stretch: Real,
    /// See `min_stretch`.
    pub max_stretch: Real,
    /// Area-weighted mean interface pressure over the cloth (Pa).
    pub mean_pressure_pa: Real,
    /// Largest element pressure (Pa).
    pub max_pressure_pa: Real,
    /// Young–Laplace interface pressure (Eq. 174, [`crate::young_laplace_pressure`]), area-weighted over
    /// the cloth triangles without a vertex on the free boundary: mean (Pa); NaN when undefined.
    pub young_laplace_mean_pa: Real,
    /// Its area-weighted standard deviation over its mean (dimensionless); NaN when undefined.
    pub young_laplace_spread: Real,
    /// Its smallest triangle value (Pa; negative: lift-off); NaN when undefined.
    pub young_laplace_min_pa: Real,
    /// Smallest pattern triangle shape quality `4√3·A / Σ edge²` (dimensionless, 1: equilateral, ≤ 0:
    /// degenerate or inverted; [`mod@crate::pattern_quality`]); NaN when not evaluated.
    pub min_pattern_quality: Real,
    /// Pattern remeshes so far.
    pub remeshes: usize,
    /// Objective evaluations (equilibrium solves) so far, failed ones included.
    pub evaluations: usize,
    /// Newton iterations of this design's equilibrium solve.
    pub newton_iterations: usize,
    /// Evaluations since the previous reported iteration (this iteration's line search, and its direction
    /// solve's re-evaluation if any).
    pub step_evaluations: usize,
    /// Newton iterations of every solve since the previous reported iteration.
    pub step_newton_iterations: usize,
    /// Numeric factorizations of every solve since the previous reported iteration.
    pub step_factorizations: usize,
    /// Newton iterations of every solve so far.
    pub newton_iterations_total: usize,
    /// Numeric factorizations of every solve so far.
    pub factorizations_total: usize,
    /// Seconds since the start.
    pub seconds: Real,
    /// With a stretch-window objective ([`crate::StretchWindow`]): the fraction of the pattern area whose
    /// triangles have both principal stretches inside the window (dimensionless, 0–1); `None` (JSON `null`)
    /// without one. Always serialized: checkpoints are postcard, which cannot skip a field.
    pub window_area_fraction: Option<Real>,
}
