//! The design job's types (docs/DESIGN_JOB.md): the scene part, the objectives, the regularizers and the
//! optimizer settings, with their defaults; and reading a job from JSON.

use serde::{Deserialize, Serialize};
use skintight_design::{Compactness, PatternQualityParams, PressureTarget};
use skintight_geometry::math::Real;

use crate::json_input::parse_json_input;
use crate::scene::{GarmentSpec, PatternsSpec, Scene, SceneBody, SceneError, SolverSpec};
use crate::simulate::prescription::{Prescription, ProfileSpec};
use skintight_geometry::anthropometry::Side;

/// A design job: the scene (body, garment, solver) and what to optimize.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DesignJob {
    /// The deformable body (as in a scene).
    pub body: SceneBody,
    /// The garment whose patterns are designed (as in a scene); its panels are the initial patterns.
    pub garment: GarmentSpec,
    /// Equilibrium solver settings of every simulation (as in a scene).
    #[serde(default)]
    pub solver: SolverSpec,
    /// The design objectives; at least one.
    pub objectives: ObjectivesSpec,
    /// Regularizers of the pattern shapes; all off when left out.
    #[serde(default)]
    pub regularizers: RegularizersSpec,
    /// Optimizer settings.
    #[serde(default)]
    pub optimizer: OptimizerSpec,
    /// The pattern files of the final design (as in a scene).
    #[serde(default)]
    pub patterns: PatternsSpec,
}

/// The objectives (thesis Sec. 6.2); each present one is added with its weight.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectivesSpec {
    /// Shape (Eq. 171–172): the worn cloth close to a target surface.
    pub shape: Option<ShapeObjective>,
    /// Stretch window (Eq. 173): principal stretches within `[min, max]`.
    pub stretch: Option<StretchObjective>,
    /// Seam traction (Eq. 181): low normal stress across the seams.
    pub seam_traction: Option<SeamTractionObjective>,
    /// Interface pressure (Eq. 174–180): the Young–Laplace pressure at a target value or in a range.
    pub pressure: Option<PressureObjective>,
    /// Sliding over body poses (Eq. 182–183): the cloth carried to each pose must be held by friction.
    pub sliding: Option<SlidingObjective>,
    /// A compression prescription (class and profile of a standard) on one leg: band pressures at the
    /// body's measuring points inside their windows.
    pub prescription: Option<PrescriptionObjective>,
}

/// The prescription objective (docs/DESIGN_JOB.md): the standard's class window at the ankle (`B`) and
/// its profile above it become pressure windows of bands across the leg at the body's landmarks (and
/// between them), and the band-averaged Young–Laplace pressure is pulled into each
/// ([`skintight_design::BandPressure`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PrescriptionObjective {
    /// `RAL-GZ 387`, `BS 6612` or `ASQUAL`.
    pub standard: String,
    /// The compression class, 1–4.
    pub class: u8,
    /// `"graduated"` (default: the standard's profile) or percent windows of the `B` pressure per point,
    /// e.g. `{"C": [50, 80]}`.
    #[serde(default)]
    pub profile: ProfileSpec,
    /// Weight (1/(m² Pa²)), ≥ 0.
    pub weight: Real,
    /// The leg; left out, the garment template's side.
    #[serde(default)]
    pub side: Option<Side>,
    /// Fraction of each window's width kept clear at both ends by the design, in `[0, 0.45]`; default
    /// 0.25 (class II's 23–32 mmHg is aimed at 25.25–29.75 mmHg), so that the verdict, which measures
    /// the pressure another way (normal force over area), still passes.
    #[serde(default = "default_prescription_margin")]
    pub margin: Real,
    /// Largest spacing of the bands along the leg (m): bands with linearly interpolated windows are added
    /// between landmarks further apart; default 0.03.
    #[serde(default = "default_band_spacing")]
    pub band_spacing_m: Real,
}

fn default_prescription_margin() -> Real {
    0.25
}

fn default_band_spacing() -> Real {
    0.03
}

impl PrescriptionObjective {
    /// The prescription the verdict checks.
    pub fn prescription(&self) -> Prescription {
        Prescription {
            standard: self.standard.clone(),
            class: self.class,
            profile: self.profile.clone(),
        }
    }
}

/// The sliding objective: `weight · Σ_poses Σ_vertices max(0, f_t − μ N)²` (docs/DESIGN_JOB.md).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlidingObjective {
    /// Weight (1/N²), ≥ 0.
    pub weight: Real,
    /// Coulomb friction coefficient between fabric and skin (dimensionless, ≥ 0); default 0.5.
    #[serde(default = "default_friction")]
    pub friction_coefficient: Real,
    /// The poses: surface meshes with the body's vertices and faces (same count, same triangles),
    /// deformed (OBJ/PLY/STL paths or asset ids, m). At least one.
    pub poses: Vec<PoseSpec>,
}

fn default_friction() -> Real {
    0.5
}

/// One body pose.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseSpec {
    /// The posed body surface.
    pub path: String,
}

/// The pressure objective: `weight · Σ Ā (p − target)²` (or the excursion outside `[min_pa, max_pa]`)
/// plus `negative_weight · Σ Ā min(p, 0)²`, over the cloth triangles (docs/DESIGN_JOB.md).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PressureObjective {
    /// Weight (1/(m² Pa²)), ≥ 0.
    pub weight: Real,
    /// Target pressure (Pa); give it, or `min_pa` and `max_pa`.
    #[serde(default)]
    pub target_pa: Option<Real>,
    /// Lower end of the wanted range (Pa), with `max_pa`.
    #[serde(default)]
    pub min_pa: Option<Real>,
    /// Upper end of the wanted range (Pa), > `min_pa`.
    #[serde(default)]
    pub max_pa: Option<Real>,
    /// Weight of the lift-off penalty on negative pressure (1/(m² Pa²)), ≥ 0; default 0.
    #[serde(default)]
    pub negative_weight: Real,
    /// Count the triangles with a vertex on the cloth's free boundary (where the shape operator is
    /// unreliable); default false.
    #[serde(default)]
    pub include_boundary_ring: bool,
}

impl PressureObjective {
    /// The target, once validated.
    pub(super) fn target(&self) -> Option<PressureTarget> {
        match (self.target_pa, self.min_pa, self.max_pa) {
            (Some(t), None, None) => Some(PressureTarget::Value(t)),
            (None, Some(min), Some(max)) => Some(PressureTarget::Range { min, max }),
            _ => None,
        }
    }
}

/// The shape objective.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeObjective {
    /// Weight (1/m², so that the term is dimensionless for weight 1/area), ≥ 0.
    pub weight: Real,
    /// The target surface.
    pub target: TargetSpec,
    /// IMLS support radius `h` (m); left out: 3 × the target's mean edge length.
    #[serde(default)]
    pub radius: Option<Real>,
}

/// A target surface.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum TargetSpec {
    /// A triangle mesh file (OBJ, PLY, STL, glTF binary), m, outward normals; path relative to the job file
    /// (or an asset id in the service).
    Mesh {
        /// The file.
        path: String,
    },
    /// A surface of revolution about the y axis (the axis of the procedural cylinder body): the radius
    /// (m) at each height y (m), linearly interpolated between the given `[y, r]` points (increasing y).
    Revolution {
        /// `[y, radius]` pairs (m), at least two, y increasing, radii > 0.
        profile: Vec<[Real; 2]>,
        /// Vertices around (≥ 8); default 48.
        #[serde(default = "default_segments")]
        segments: usize,
    },
}

fn default_segments() -> usize {
    48
}

/// The stretch-window objective.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StretchObjective {
    /// Weight (1/m²), ≥ 0.
    pub weight: Real,
    /// Smallest wanted principal stretch (dimensionless, ≥ 0).
    pub min: Real,
    /// Largest wanted principal stretch (dimensionless, > min).
    pub max: Real,
}

/// The seam-traction objective.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeamTractionObjective {
    /// Weight, ≥ 0 (units: 1/(m² Pa²) for the squared form, 1/N for the plain one).
    pub weight: Real,
    /// `"squared"` (default: penalizes peaks) or `"linear"` (thesis Eq. 181 as printed).
    #[serde(default)]
    pub form: SeamTractionFormSpec,
}

/// How seam traction is measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SeamTractionFormSpec {
    /// `Σ l0 d τ²`.
    #[default]
    Squared,
    /// `Σ l0 d τ`.
    Linear,
}

/// A weight alone.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WeightSpec {
    /// Weight, ≥ 0.
    pub weight: Real,
}

/// The compactness regularizer.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompactnessSpec {
    /// Weight, ≥ 0.
    pub weight: Real,
    /// Chord-to-arc ratio below which a boundary pair is penalized, in (0, 1]; default 0.1.
    #[serde(default = "default_compactness_threshold")]
    pub threshold: Real,
}

fn default_compactness_threshold() -> Real {
    Compactness::DEFAULT_THRESHOLD
}

/// The regularizers (thesis Sec. 6.3).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegularizersSpec {
    /// Equal lengths of the two sides of every seam edge (Eq. 184), weight in 1/m².
    pub seam_length: Option<WeightSpec>,
    /// Smooth boundaries (Eq. 185), weight in m.
    pub smoothness: Option<WeightSpec>,
    /// Equal consecutive boundary edge lengths, weight in 1/m².
    pub edge_length: Option<WeightSpec>,
    /// No thin patterns (Eq. 186–187).
    pub compactness: Option<CompactnessSpec>,
    /// Traction-free pinned boundaries (Eq. 188): no tangential force `dU/ds` at the pinned cloth
    /// vertices, weight in 1/J².
    pub pinned_traction: Option<WeightSpec>,
}

/// The optimizer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OptimizerSpec {
    /// `"lbfgs"` (default) or `"gauss_newton"`.
    #[serde(default)]
    pub method: OptimizerMethod,
    /// Gauss-Newton only: the initial Levenberg-Marquardt damping factor `μ` (> 0, per cloth edge length;
    /// `κ = μ ‖dT̃/dp̃‖`, so a pure gradient step would move the boundary by `1/μ` edge lengths); default 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<Real>,
    /// Gauss-Newton only: how each direction is solved for — `"auto"` (default), `"kkt"` (the sparse KKT
    /// system of the paper's Eq. 21) or `"reduced"` (the sensitivity by one multi-column solve with the
    /// equilibrium factor, then a dense `#c × #c` system). Both give the same direction; `"auto"` picks
    /// `"reduced"` while its dense `#q × #c` sensitivity has at most 5·10⁷ entries.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gauss_newton_system: Option<GaussNewtonSystemSpec>,
    /// Most design iterations (≥ 1); default 100.
    #[serde(default = "default_design_iterations")]
    pub max_iterations: usize,
    /// Wall-clock limit of the design (s, > 0); default 3600.
    #[serde(default = "default_design_time")]
    pub time_limit_s: Real,
    /// Stop when `‖dT̃/dp̃‖ <` this (the normalized gradient, see docs/DESIGN_JOB.md); default 1e-3.
    #[serde(default = "default_gradient_tolerance")]
    pub gradient_tolerance: Real,
    /// L-BFGS memory (≥ 1); default 8.
    #[serde(default = "default_memory")]
    pub memory: usize,
    /// Coarse-to-fine boundary mode counts per panel (increasing), before the boundary positions
    /// themselves; default none.
    #[serde(default)]
    pub mode_levels: Vec<usize>,
    /// Most iterations of each mode level (≥ 1), so that the finer levels get their turn; default none
    /// (a level runs until it stops by itself).
    #[serde(default)]
    pub level_iterations: Option<usize>,
    /// A mode level hands over to the next after two iterations in a row that each lowered the
    /// objective by less than this fraction (dimensionless, ≥ 0; 0 turns the rule off); default 3e-3.
    #[serde(default = "default_level_min_decrease")]
    pub level_min_decrease: Real,
    /// `"gauss_newton"` only: the first trial step of an iteration moves the design parameters (max-norm)
    /// at most this many times as far as the last accepted step did (dimensionless, ≥ 1; 0 turns the
    /// bound off); default 2.
    #[serde(default = "default_step_growth")]
    pub step_growth: Real,
    /// When to remesh the patterns (resample the boundary, remesh, re-embed, continue); default off
    /// (`max_remeshes` 0), see [`RemeshSpec`].
    #[serde(default)]
    pub remesh: RemeshSpec,
    /// Predictor–corrector evaluations: each equilibrium solve starts from the first-order prediction of
    /// the new equilibrium, with the damping the last solve ended with
    /// ([`skintight_design::equilibrium_predictor`]); default true.
    #[serde(default = "default_true")]
    pub predictor: bool,
    /// Chord steps in the predictor's corrector: Newton iterations that reuse the factorization they find
    /// while it contracts the residual tenfold ([`skintight_design::DesignProblem::set_chord_steps`]);
    /// default false (they cost more Newton iterations than they save factorization time, measured in
    /// docs/BENCHMARKS.md).
    #[serde(default)]
    pub chord_steps: bool,
    /// Inexact equilibria: each evaluation solved to a tolerance that follows the optimizer's gradient,
    /// from `solver.tolerance` (at the gradient tolerance and below) up to `inexact_loosest`
    /// ([`skintight_design::inexact_tolerance`]); the final design is evaluated at `solver.tolerance`.
    /// Default true.
    #[serde(default = "default_true")]
    pub inexact_solves: bool,
    /// The loosest relative residual of inexact solves (in (0, 1)); default 1e-3.
    #[serde(default = "default_inexact_loosest")]
    pub inexact_loosest: Real,
    /// The largest first-order error of an inexactly solved objective, relative to it (> 0): an
    /// evaluation whose adjoint estimate `|λᵀ g|` exceeds it is solved again, tighter
    /// ([`skintight_design::inexact_tolerance`]); default 1e-3.
    #[serde(default = "default_inexact_objective_error")]
    pub inexact_objective_error: Real,
    /// The fabric's stretch limits (`garment.fabric.limits.max_stretch`) as a constraint of the design: a
    /// penalty on the stretch along the wales and courses above the limits lowered by `margin`
    /// ([`skintight_design::fabric_stretch_limit`]); on by default, `weight` 0 turns it off.
    #[serde(default)]
    pub fabric_limits: FabricLimitsConstraint,
    /// Seams held during the design: every evaluated pattern has every pair of sewn edges equally long
    /// (the optimizer's boundary parameters projected onto that set, [`mod@skintight_design::seam_projection`]),
    /// so the truing of the final patterns moves nothing. Default true; false leaves the boundary free and
    /// only `regularizers.seam_length` keeps the seams near sewable.
    #[serde(default = "default_true")]
    pub hold_seams: bool,
}

/// How the design keeps the garment within its fabric's stretch limits (docs/DESIGN_JOB.md).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FabricLimitsConstraint {
    /// Weight of the penalty (1/m², multiplies m² of pattern times squared excess stretch), ≥ 0; default
    /// 1e4 — a 10 % excess over 10 cm² then weighs 0.1, more than the objectives of the examples.
    #[serde(default = "default_limit_weight")]
    pub weight: Real,
    /// The penalty acts above `limit · (1 − margin)` (but never below stretch 1), so that what an exterior
    /// penalty leaves over its bound stays within the limit; dimensionless, in [0, 0.5); default 0.02.
    #[serde(default = "default_limit_margin")]
    pub margin: Real,
}

fn default_limit_weight() -> Real {
    1e4
}
fn default_limit_margin() -> Real {
    0.02
}

impl Default for FabricLimitsConstraint {
    fn default() -> Self {
        Self {
            weight: default_limit_weight(),
            margin: default_limit_margin(),
        }
    }
}

/// When the design remeshes its patterns (docs/DESIGN_JOB.md): after an accepted iteration whose pattern
/// has a triangle of shape quality `4√3·A / Σ edge²` below `min_quality`, or a boundary edge longer or
/// shorter than the cloth edge length by more than `max_edge_ratio` (bounds relative to the mesh the run
/// started from where that mesh is near them: 10 % worse quality, 1.5 × its edge ratio) — at most `max_remeshes` times.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RemeshSpec {
    /// Smallest triangle shape quality kept (dimensionless, in [0, 1); 1 is equilateral); default 0.2.
    #[serde(default = "default_remesh_quality")]
    pub min_quality: Real,
    /// Largest boundary edge length ratio to the cloth edge length kept (> 1); default 3.
    #[serde(default = "default_remesh_edge_ratio")]
    pub max_edge_ratio: Real,
    /// Most remeshes per design; default 0: no remeshing (docs/DESIGN_JOB.md says why).
    #[serde(default = "default_max_remeshes")]
    pub max_remeshes: usize,
}

fn default_remesh_quality() -> Real {
    PatternQualityParams::default().min_quality
}
fn default_remesh_edge_ratio() -> Real {
    PatternQualityParams::default().max_edge_ratio
}
fn default_max_remeshes() -> usize {
    0
}

impl Default for RemeshSpec {
    fn default() -> Self {
        Self {
            min_quality: default_remesh_quality(),
            max_edge_ratio: default_remesh_edge_ratio(),
            max_remeshes: default_max_remeshes(),
        }
    }
}

impl RemeshSpec {
    /// The trigger settings.
    pub fn params(&self) -> PatternQualityParams {
        PatternQualityParams {
            min_quality: self.min_quality,
            max_edge_ratio: self.max_edge_ratio,
            max_remeshes: self.max_remeshes,
        }
    }
}

/// How Gauss-Newton directions are solved for (see [`OptimizerSpec::gauss_newton_system`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GaussNewtonSystemSpec {
    /// Reduced while the dense sensitivity is small enough, else KKT.
    #[default]
    Auto,
    /// The sparse KKT system.
    Kkt,
    /// The reduced (sensitivity) form.
    Reduced,
}

/// Optimization method.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OptimizerMethod {
    /// L-BFGS with a strong-Wolfe line search.
    #[default]
    Lbfgs,
    /// Adjoint Gauss-Newton (sparse KKT system) with Levenberg-Marquardt damping and a halving line
    /// search.
    GaussNewton,
}

impl OptimizerMethod {
    /// The name in the job and in `result.json`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Lbfgs => "lbfgs",
            Self::GaussNewton => "gauss_newton",
        }
    }
}

fn default_design_iterations() -> usize {
    100
}
fn default_design_time() -> Real {
    3600.0
}
fn default_gradient_tolerance() -> Real {
    1e-3
}
fn default_memory() -> usize {
    8
}
fn default_level_min_decrease() -> Real {
    skintight_design::PatternDesignParams::default().level_min_relative_decrease
}
fn default_step_growth() -> Real {
    skintight_design::GaussNewtonParams::default().max_step_growth
}

fn default_true() -> bool {
    true
}

fn default_inexact_loosest() -> Real {
    skintight_design::InexactTolerance::default().loosest
}

fn default_inexact_objective_error() -> Real {
    skintight_design::InexactTolerance::default().objective_error
}

impl Default for OptimizerSpec {
    fn default() -> Self {
        Self {
            method: OptimizerMethod::Lbfgs,
            damping: None,
            gauss_newton_system: None,
            max_iterations: default_design_iterations(),
            time_limit_s: default_design_time(),
            gradient_tolerance: default_gradient_tolerance(),
            memory: default_memory(),
            mode_levels: Vec::new(),
            level_iterations: None,
            level_min_decrease: default_level_min_decrease(),
            step_growth: default_step_growth(),
            remesh: RemeshSpec::default(),
            predictor: true,
            chord_steps: false,
            inexact_solves: true,
            inexact_loosest: default_inexact_loosest(),
            inexact_objective_error: default_inexact_objective_error(),
            fabric_limits: FabricLimitsConstraint::default(),
            hold_seams: true,
        }
    }
}

impl DesignJob {
    /// Parses a design job and checks it with [`DesignJob::validate`]; errors name their key.
    pub fn from_json(text: &str) -> Result<DesignJob, SceneError> {
        let job: DesignJob = parse_json_input(text.as_bytes())
            .map_err(|e| SceneError::from_json_input(e, "design job"))?;
        job.validate()?;
        Ok(job)
    }

    /// Reads and parses a design job file.
    pub fn from_file(path: &std::path::Path) -> Result<DesignJob, SceneError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SceneError::new("", format!("cannot read {}: {e}", path.display())))?;
        DesignJob::from_json(&text)
            .map_err(|e| SceneError::new(e.key, format!("{}: {}", path.display(), e.message)))
    }

    /// The scene part.
    pub fn scene(&self) -> Scene {
        Scene {
            body: self.body.clone(),
            garment: self.garment.clone(),
            solver: self.solver,
            patterns: self.patterns.clone(),
        }
    }
}
