//! Pattern design jobs: a scene plus `objectives`, `regularizers` and `optimizer` (docs/DESIGN_JOB.md), run
//! by the CLI (`skintight design`) and by the service (`design` job kind).
//!
//! The job is parsed and checked like a scene (every error names its key), the garment is built and
//! solved to equilibrium as in `simulate`, then the pattern boundary is optimized
//! ([`skintight_design::pattern_design`]) and the best design is written with the simulate outputs plus
//! `patterns.json` and `history.json`.

use std::ops::ControlFlow;

use serde::{Deserialize, Serialize};
use skintight_design::{
    BoundarySmoothness, Compactness, DesignIteration, DesignMesh, DesignProblem,
    EdgeLengthUniformity, GaussNewtonParams, GaussNewtonSolver, LbfgsParams, Optimizer,
    PatternDesignParams, PatternDesignResult, PatternMap, PatternQualityParams, PinnedTraction,
    Pressure, PressureStatistics, PressureTarget, SeamLength, SeamTraction, SeamTractionForm,
    ShapeImls, Sliding, StretchWindow, Term, TermInput, pattern_design, young_laplace_statistics,
};
use skintight_geometry::math::{Real, Vec2, Vec3};
use skintight_geometry::mesh::TriMesh;

use crate::scene::{
    BodySpec, GarmentSpec, PathResolver, Scene, SceneError, SolverSpec, parse_json,
};
use crate::simulate::{
    ArtifactFile, SimulateError, Simulation, SimulationResult, artifacts, equilibrium_params,
    prepare, run,
};

/// A design job: the scene (body, garment, solver) and what to optimize.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DesignJob {
    /// The deformable body (as in a scene).
    pub body: BodySpec,
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
    fn target(&self) -> Option<PressureTarget> {
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
    /// objective by less than this fraction (dimensionless, ≥ 0; 0 turns the rule off); default 1e-3.
    #[serde(default = "default_level_min_decrease")]
    pub level_min_decrease: Real,
    /// When to remesh the patterns (resample the boundary, remesh, re-embed, continue); default off
    /// (`max_remeshes` 0), see [`RemeshSpec`].
    #[serde(default)]
    pub remesh: RemeshSpec,
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
    1e-3
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
            remesh: RemeshSpec::default(),
        }
    }
}

fn non_negative(key: &str, v: Real) -> Result<(), SceneError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(SceneError::new(
            key,
            format!("must be a finite number ≥ 0, got {v}"),
        ))
    }
}

fn positive(key: &str, v: Real) -> Result<(), SceneError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(SceneError::new(
            key,
            format!("must be a finite number > 0, got {v}"),
        ))
    }
}

impl DesignJob {
    /// Parses a design job and checks it with [`DesignJob::validate`]; errors name their key.
    pub fn from_json(text: &str) -> Result<DesignJob, SceneError> {
        let job: DesignJob = parse_json(text, "design job")?;
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
        }
    }

    /// Checks every value that cannot be right whatever the body, naming the first key at fault.
    pub fn validate(&self) -> Result<(), SceneError> {
        self.scene().validate()?;
        let o = &self.objectives;
        if o.shape.is_none()
            && o.stretch.is_none()
            && o.seam_traction.is_none()
            && o.pressure.is_none()
            && o.sliding.is_none()
        {
            return Err(SceneError::new(
                "objectives",
                "give at least one objective: shape, stretch, seam_traction, pressure or sliding",
            ));
        }
        if let Some(s) = &o.shape {
            non_negative("objectives.shape.weight", s.weight)?;
            if let Some(r) = s.radius {
                positive("objectives.shape.radius", r)?;
            }
            match &s.target {
                TargetSpec::Mesh { path } if path.is_empty() => {
                    return Err(SceneError::new(
                        "objectives.shape.target.path",
                        "the path is empty",
                    ));
                }
                TargetSpec::Mesh { .. } => {}
                TargetSpec::Revolution { profile, segments } => {
                    if *segments < 8 {
                        return Err(SceneError::new(
                            "objectives.shape.target.segments",
                            format!("must be at least 8, got {segments}"),
                        ));
                    }
                    if profile.len() < 2 {
                        return Err(SceneError::new(
                            "objectives.shape.target.profile",
                            "give at least two [y, radius] points",
                        ));
                    }
                    for (i, [y, r]) in profile.iter().enumerate() {
                        let key = format!("objectives.shape.target.profile[{i}]");
                        if !y.is_finite() || !(r.is_finite() && *r > 0.0) {
                            return Err(SceneError::new(
                                key,
                                "needs a finite height y (m) and a radius > 0 (m)",
                            ));
                        }
                        if i > 0 && !(*y > profile[i - 1][0]) {
                            return Err(SceneError::new(key, "heights must increase"));
                        }
                    }
                }
            }
        }
        if let Some(s) = &o.stretch {
            non_negative("objectives.stretch.weight", s.weight)?;
            non_negative("objectives.stretch.min", s.min)?;
            if !(s.max > s.min) {
                return Err(SceneError::new(
                    "objectives.stretch.max",
                    format!("must exceed min ({}), got {}", s.min, s.max),
                ));
            }
        }
        if let Some(s) = &o.seam_traction {
            non_negative("objectives.seam_traction.weight", s.weight)?;
        }
        if let Some(sl) = &self.objectives.sliding {
            non_negative("objectives.sliding.weight", sl.weight)?;
            non_negative(
                "objectives.sliding.friction_coefficient",
                sl.friction_coefficient,
            )?;
            if sl.poses.is_empty() {
                return Err(SceneError::new(
                    "objectives.sliding.poses",
                    "needs at least one pose",
                ));
            }
        }
        if let Some(p) = &o.pressure {
            non_negative("objectives.pressure.weight", p.weight)?;
            non_negative("objectives.pressure.negative_weight", p.negative_weight)?;
            let finite = |key: &str, v: Option<Real>| match v {
                Some(v) if !v.is_finite() => Err(SceneError::new(
                    key,
                    format!("must be a finite pressure (Pa), got {v}"),
                )),
                _ => Ok(()),
            };
            finite("objectives.pressure.target_pa", p.target_pa)?;
            finite("objectives.pressure.min_pa", p.min_pa)?;
            finite("objectives.pressure.max_pa", p.max_pa)?;
            match (p.target_pa, p.min_pa, p.max_pa) {
                (Some(_), None, None) => {}
                (Some(_), _, _) => {
                    return Err(SceneError::new(
                        "objectives.pressure.target_pa",
                        "give either target_pa or min_pa and max_pa, not both",
                    ));
                }
                (None, None, None) => {
                    return Err(SceneError::new(
                        "objectives.pressure",
                        "give target_pa (Pa), or min_pa and max_pa (Pa)",
                    ));
                }
                (None, Some(_), None) => {
                    return Err(SceneError::new(
                        "objectives.pressure.max_pa",
                        "missing: min_pa is given, give max_pa too",
                    ));
                }
                (None, None, Some(_)) => {
                    return Err(SceneError::new(
                        "objectives.pressure.min_pa",
                        "missing: max_pa is given, give min_pa too",
                    ));
                }
                (None, Some(min), Some(max)) => {
                    if max <= min {
                        return Err(SceneError::new(
                            "objectives.pressure.max_pa",
                            format!("must exceed min_pa ({min}), got {max}"),
                        ));
                    }
                }
            }
        }
        let r = &self.regularizers;
        for (key, w) in [
            (
                "regularizers.seam_length.weight",
                r.seam_length.map(|w| w.weight),
            ),
            (
                "regularizers.smoothness.weight",
                r.smoothness.map(|w| w.weight),
            ),
            (
                "regularizers.edge_length.weight",
                r.edge_length.map(|w| w.weight),
            ),
            (
                "regularizers.compactness.weight",
                r.compactness.map(|w| w.weight),
            ),
            (
                "regularizers.pinned_traction.weight",
                r.pinned_traction.map(|w| w.weight),
            ),
        ] {
            if let Some(w) = w {
                non_negative(key, w)?;
            }
        }
        if let Some(c) = r.compactness
            && !(c.threshold > 0.0 && c.threshold <= 1.0)
        {
            return Err(SceneError::new(
                "regularizers.compactness.threshold",
                format!("must lie in (0, 1], got {}", c.threshold),
            ));
        }
        let p = &self.optimizer;
        if p.max_iterations == 0 {
            return Err(SceneError::new(
                "optimizer.max_iterations",
                "must be at least 1",
            ));
        }
        positive("optimizer.time_limit_s", p.time_limit_s)?;
        positive("optimizer.gradient_tolerance", p.gradient_tolerance)?;
        if p.memory == 0 {
            return Err(SceneError::new("optimizer.memory", "must be at least 1"));
        }
        non_negative("optimizer.level_min_decrease", p.level_min_decrease)?;
        let r = &p.remesh;
        if !(r.min_quality.is_finite() && (0.0..1.0).contains(&r.min_quality)) {
            return Err(SceneError::new(
                "optimizer.remesh.min_quality",
                format!("must lie in [0, 1), got {}", r.min_quality),
            ));
        }
        if r.max_edge_ratio.is_nan() || r.max_edge_ratio <= 1.0 {
            return Err(SceneError::new(
                "optimizer.remesh.max_edge_ratio",
                format!("must exceed 1, got {}", r.max_edge_ratio),
            ));
        }
        if p.level_iterations == Some(0) {
            return Err(SceneError::new(
                "optimizer.level_iterations",
                "must be at least 1",
            ));
        }
        if p.gauss_newton_system.is_some() && p.method != OptimizerMethod::GaussNewton {
            return Err(SceneError::new(
                "optimizer.gauss_newton_system",
                "is a setting of method \"gauss_newton\" only",
            ));
        }
        if let Some(d) = p.damping {
            if p.method != OptimizerMethod::GaussNewton {
                return Err(SceneError::new(
                    "optimizer.damping",
                    "is a setting of method \"gauss_newton\" only",
                ));
            }
            positive("optimizer.damping", d)?;
        }
        if let Some(i) = (0..p.mode_levels.len())
            .find(|&i| p.mode_levels[i] == 0 || (i > 0 && p.mode_levels[i] <= p.mode_levels[i - 1]))
        {
            return Err(SceneError::new(
                format!("optimizer.mode_levels[{i}]"),
                "mode counts must be ≥ 1 and increase",
            ));
        }
        Ok(())
    }
}

/// A surface of revolution about y through the profile `[y, r]` (linear between points), open at both
/// ends, outward normals (counter-clockwise seen from outside). Rows are spaced about as far apart as the
/// `segments` vertices around, so the triangles are well shaped (the IMLS radius follows the edge length).
pub fn revolution_target(profile: &[[Real; 2]], segments: usize) -> TriMesh {
    // Heights: each profile interval split into pieces no longer than the spacing around.
    let mut rows: Vec<[Real; 2]> = vec![profile[0]];
    for w in profile.windows(2) {
        let ([y0, r0], [y1, r1]) = (w[0], w[1]);
        let around = 2.0 * std::f64::consts::PI * r0.max(r1) / segments as Real;
        let pieces = (((y1 - y0).hypot(r1 - r0) / around).ceil() as usize).max(1);
        for k in 1..=pieces {
            let t = k as Real / pieces as Real;
            rows.push([y0 + t * (y1 - y0), r0 + t * (r1 - r0)]);
        }
    }
    let mut positions = Vec::with_capacity(rows.len() * segments);
    for &[y, r] in &rows {
        for k in 0..segments {
            let a = 2.0 * std::f64::consts::PI * k as Real / segments as Real;
            positions.push(Vec3::new(r * a.cos(), y, -r * a.sin()));
        }
    }
    let mut faces = Vec::with_capacity(2 * (rows.len() - 1) * segments);
    for j in 0..rows.len() - 1 {
        for k in 0..segments {
            let (a, b) = (j * segments + k, j * segments + (k + 1) % segments);
            let (c, d) = (a + segments, b + segments);
            faces.push([a, b, d]);
            faces.push([a, d, c]);
        }
    }
    TriMesh {
        positions,
        faces,
        ..Default::default()
    }
}

/// A prepared design: the simulation of the initial garment at equilibrium and the design problem.
pub struct Design {
    /// The job.
    pub job: DesignJob,
    /// The simulation (initial garment, then the final design after [`run_design`]).
    pub sim: Simulation,
    /// The design problem.
    pub problem: DesignProblem,
    /// The boundary parametrization.
    pub map: PatternMap,
    /// With a stretch objective: the fraction of the cloth's pattern area whose principal stretches both
    /// lie in its window, for the initial garment.
    pub initial_window_fraction: Option<Real>,
    /// Young–Laplace pressure statistics of the initial garment (None when undefined).
    pub initial_pressure: Option<PressureStatistics>,
}

/// Young–Laplace pressure statistics (Eq. 174; area-weighted over the deformed cloth, the boundary ring
/// counted as the pressure objective counts it) of the garment in `sim` with pattern `pattern`.
pub fn pressure_statistics(
    job: &DesignJob,
    problem: &DesignProblem,
    sim: &Simulation,
    pattern: &[Vec2],
) -> Option<PressureStatistics> {
    let cloth = sim.system.cloth_positions(&sim.state).ok()?;
    let input = TermInput {
        mesh: problem.mesh(),
        cloth: &cloth,
        pattern,
        fabric: problem.fabric(),
    };
    let ring = job
        .objectives
        .pressure
        .as_ref()
        .is_some_and(|p| p.include_boundary_ring);
    young_laplace_statistics(&input, skintight_design::BoundaryEdges::Free, ring).ok()
}

/// The fraction of the cloth's pattern area whose two principal stretches lie in `[min, max]`.
pub fn window_fraction(
    system: &skintight_physics::ClothOnBody,
    state: &skintight_physics::ClothOnBodyState,
    min: Real,
    max: Real,
) -> Option<Real> {
    let states = system.element_states(state).ok()?;
    let (mut inside, mut total) = (0.0, 0.0);
    for (s, e) in states.iter().zip(system.elements()) {
        let a = e.rest_area();
        total += a;
        if s.principal_stretches[1] >= min && s.principal_stretches[0] <= max {
            inside += a;
        }
    }
    (total > 0.0).then(|| inside / total)
}

/// Young–Laplace pressure (Pa) of every cloth triangle of the garment in `sim` with pattern `pattern`, in
/// the garment's triangle order (None when undefined).
pub fn pressure_per_triangle(
    problem: &DesignProblem,
    sim: &Simulation,
    pattern: &[Vec2],
) -> Option<Vec<Real>> {
    let cloth = sim.system.cloth_positions(&sim.state).ok()?;
    let input = TermInput {
        mesh: problem.mesh(),
        cloth: &cloth,
        pattern,
        fabric: problem.fabric(),
    };
    skintight_design::young_laplace_pressures(&input, skintight_design::BoundaryEdges::Free).ok()
}

/// Builds the garment, solves its initial equilibrium and sets up the objective. `resolver` finds the
/// body and target files.
pub fn prepare_design(
    job: &DesignJob,
    resolver: &dyn PathResolver,
) -> Result<Design, SimulateError> {
    job.validate()?;
    let scene = job.scene();
    let mut sim = prepare(&scene, resolver)?;
    let report = run(&mut sim, &mut |_| ControlFlow::Continue(()))?;
    if !report.converged {
        return Err(SimulateError::failed(format!(
            "the initial garment did not reach equilibrium ({:?} after {} iterations); fix the scene \
             before designing",
            report.stop_reason, report.newton_iterations
        )));
    }
    let (mesh, pattern) = DesignMesh::from_garment(&sim.garment);
    let pattern0 = pattern.clone();
    let map = PatternMap::new(&mesh, &pattern)
        .map_err(|e| SimulateError::failed(format!("pattern parametrization: {e}")))?;
    let terms = terms(job, resolver, &sim)?;
    let problem = DesignProblem::new(
        sim.system.clone(),
        sim.state.clone(),
        mesh,
        terms,
        equilibrium_params(&scene),
    )
    .map_err(|e| SimulateError::failed(e.to_string()))?;
    let initial_window_fraction = job
        .objectives
        .stretch
        .as_ref()
        .and_then(|w| window_fraction(&sim.system, &sim.state, w.min, w.max));
    let initial_pressure = pressure_statistics(job, &problem, &sim, &pattern0);
    Ok(Design {
        job: job.clone(),
        sim,
        problem,
        map,
        initial_window_fraction,
        initial_pressure,
    })
}

fn term_error(key: &str, e: impl std::fmt::Display) -> SimulateError {
    SimulateError::input(key, e.to_string())
}

/// The weighted terms of the job.
/// The control positions (`#Vs × 3`, m) of each pose of the sliding objective: each pose file must be the
/// body surface `surface` deformed — the same number of vertices and the same triangles.
fn pose_controls(
    sliding: &SlidingObjective,
    surface: &TriMesh,
    num_control: usize,
    resolver: &dyn PathResolver,
) -> Result<Vec<Vec<Vec3>>, SimulateError> {
    if surface.num_vertices() != num_control {
        return Err(SimulateError::input(
            "objectives.sliding.poses",
            format!(
                "the body's smooth surface has {num_control} control vertices for {} surface vertices; \
                 poses need a body whose surface is its own control mesh",
                surface.num_vertices()
            ),
        ));
    }
    let sorted = |f: &[usize; 3]| {
        let mut f = *f;
        f.sort_unstable();
        f
    };
    let mut body_faces: Vec<[usize; 3]> = surface.faces.iter().map(sorted).collect();
    body_faces.sort_unstable();
    let mut out = Vec::with_capacity(sliding.poses.len());
    for (i, pose) in sliding.poses.iter().enumerate() {
        let key = format!("objectives.sliding.poses[{i}].path");
        let file = resolver.resolve(&key, &pose.path)?;
        let mesh = skintight_geometry::mesh::io::read_mesh(&file)
            .map_err(|e| SimulateError::input(&key, format!("cannot read {}: {e}", pose.path)))?;
        if mesh.num_vertices() != surface.num_vertices() {
            return Err(SimulateError::input(
                &key,
                format!(
                    "{} has {} vertices, the body surface {}; a pose is the body deformed",
                    pose.path,
                    mesh.num_vertices(),
                    surface.num_vertices()
                ),
            ));
        }
        let mut faces: Vec<[usize; 3]> = mesh.faces.iter().map(sorted).collect();
        faces.sort_unstable();
        if faces != body_faces {
            return Err(SimulateError::input(
                &key,
                format!(
                    "{} does not have the body surface's triangles; a pose is the body deformed",
                    pose.path
                ),
            ));
        }
        if let Some(v) = mesh
            .positions
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(SimulateError::input(
                &key,
                format!("{}: vertex {v} is not finite", pose.path),
            ));
        }
        out.push(mesh.positions);
    }
    Ok(out)
}

fn terms(
    job: &DesignJob,
    resolver: &dyn PathResolver,
    sim: &Simulation,
) -> Result<Vec<Box<dyn Term>>, SimulateError> {
    let mut out: Vec<Box<dyn Term>> = Vec::new();
    let o = &job.objectives;
    if let Some(s) = &o.sliding {
        let poses = pose_controls(
            s,
            &sim.body.surface,
            sim.system.surface().num_control_vertices(),
            resolver,
        )?;
        out.push(Box::new(
            Sliding::new(s.weight, s.friction_coefficient, poses)
                .map_err(|e| term_error("objectives.sliding", e))?,
        ));
    }
    if let Some(s) = &o.shape {
        let target = match &s.target {
            TargetSpec::Mesh { path } => {
                let key = "objectives.shape.target.path";
                let file = resolver.resolve(key, path)?;
                skintight_geometry::mesh::io::read_mesh(&file)
                    .map_err(|e| SimulateError::input(key, e.to_string()))?
            }
            TargetSpec::Revolution { profile, segments } => revolution_target(profile, *segments),
        };
        out.push(Box::new(
            ShapeImls::from_mesh(s.weight, &target, s.radius)
                .map_err(|e| term_error("objectives.shape", e))?,
        ));
    }
    if let Some(s) = &o.stretch {
        out.push(Box::new(
            StretchWindow::new(s.weight, s.min, s.max)
                .map_err(|e| term_error("objectives.stretch", e))?,
        ));
    }
    if let Some(s) = &o.seam_traction {
        let form = match s.form {
            SeamTractionFormSpec::Squared => SeamTractionForm::Squared,
            SeamTractionFormSpec::Linear => SeamTractionForm::Linear,
        };
        out.push(Box::new(
            SeamTraction::new(s.weight, form)
                .map_err(|e| term_error("objectives.seam_traction", e))?,
        ));
    }
    if let Some(p) = &o.pressure {
        let target = p.target().ok_or_else(|| {
            SimulateError::input(
                "objectives.pressure",
                "give target_pa (Pa), or min_pa and max_pa (Pa)",
            )
        })?;
        out.push(Box::new(
            Pressure::new(p.weight, target, p.negative_weight)
                .map_err(|e| term_error("objectives.pressure", e))?
                .with_boundary_ring(p.include_boundary_ring),
        ));
    }
    let r = &job.regularizers;
    if let Some(w) = r.seam_length {
        out.push(Box::new(
            SeamLength::new(w.weight).map_err(|e| term_error("regularizers.seam_length", e))?,
        ));
    }
    if let Some(w) = r.smoothness {
        out.push(Box::new(
            BoundarySmoothness::new(w.weight)
                .map_err(|e| term_error("regularizers.smoothness", e))?,
        ));
    }
    if let Some(w) = r.edge_length {
        out.push(Box::new(
            EdgeLengthUniformity::new(w.weight)
                .map_err(|e| term_error("regularizers.edge_length", e))?,
        ));
    }
    if let Some(c) = r.compactness {
        out.push(Box::new(
            Compactness::new(c.weight, c.threshold)
                .map_err(|e| term_error("regularizers.compactness", e))?,
        ));
    }
    if let Some(w) = r.pinned_traction {
        out.push(Box::new(
            PinnedTraction::new(w.weight)
                .map_err(|e| term_error("regularizers.pinned_traction", e))?,
        ));
    }
    Ok(out)
}

/// The design parameters of the job's optimizer settings.
pub fn design_params(job: &DesignJob) -> PatternDesignParams {
    let o = &job.optimizer;
    PatternDesignParams {
        method: match o.method {
            OptimizerMethod::Lbfgs => Optimizer::Lbfgs,
            OptimizerMethod::GaussNewton => Optimizer::GaussNewton,
        },
        gauss_newton_solver: match o.gauss_newton_system.unwrap_or_default() {
            GaussNewtonSystemSpec::Auto => GaussNewtonSolver::Auto,
            GaussNewtonSystemSpec::Kkt => GaussNewtonSolver::Kkt,
            GaussNewtonSystemSpec::Reduced => GaussNewtonSolver::Reduced,
        },
        gauss_newton: GaussNewtonParams {
            initial_damping: o
                .damping
                .unwrap_or(GaussNewtonParams::default().initial_damping),
            gradient_tolerance: o.gradient_tolerance,
            max_iterations: o.max_iterations,
            time_limit_seconds: Some(o.time_limit_s),
            ..GaussNewtonParams::default()
        },
        lbfgs: LbfgsParams {
            memory: o.memory,
            gradient_tolerance: o.gradient_tolerance,
            max_iterations: o.max_iterations,
            time_limit_seconds: Some(o.time_limit_s),
            ..LbfgsParams::default()
        },
        mode_levels: o.mode_levels.clone(),
        level_max_iterations: o.level_iterations,
        level_min_relative_decrease: o.level_min_decrease,
        remesh: (o.remesh.max_remeshes > 0).then(|| o.remesh.params()),
    }
}

/// Runs the optimization; `on_iteration` sees every design iteration and may stop the run (the best
/// design so far is kept), `should_stop` is polled at every Newton iteration of every solve. Afterwards
/// `design.sim` holds the final design at equilibrium.
///
/// Remeshing (`optimizer.remesh`): when a run stops because its pattern degraded, the patterns are
/// remeshed so that the worn triangles keep about the cloth edge length ([`skintight_design::remesh_edge_length`]), the worn garment is
/// re-embedded ([`skintight_design::design_remesh`]) and the optimization continues from there — at the
/// coarse-to-fine level it had reached, within what is left of the iteration and time limits — until
/// `max_remeshes`. A remesh that fails (a boundary crossing itself, say) ends the remeshing; the design
/// goes on without it. The history numbers iterations across remeshes and counts them in `remeshes`.
pub fn run_design(
    design: &mut Design,
    on_iteration: &mut dyn FnMut(&DesignIteration) -> ControlFlow<()>,
    should_stop: &dyn Fn() -> bool,
) -> Result<PatternDesignResult, SimulateError> {
    let start = std::time::Instant::now();
    let base = design_params(&design.job);
    let edge_length = design.job.garment.edge_length;
    let max_remeshes = design.job.optimizer.remesh.max_remeshes;
    let (max_iterations, time_limit) = match base.method {
        Optimizer::Lbfgs => (base.lbfgs.max_iterations, base.lbfgs.time_limit_seconds),
        Optimizer::GaussNewton => (
            base.gauss_newton.max_iterations,
            base.gauss_newton.time_limit_seconds,
        ),
    };
    let mut total: Option<PatternDesignResult> = None;
    let mut level = 0;
    let mut remeshes = 0;
    let mut remesh_seconds = 0.0;
    let mut remesh_on = base.remesh.is_some();
    // The design before the last remesh, to go back to if the remeshed garment cannot be solved.
    let mut before_remesh: Option<Backup> = None;
    loop {
        let done = total.as_ref().map_or(0, |t| t.iterations);
        let mut params = base.clone();
        let left = max_iterations.saturating_sub(done).max(1);
        let time_left = time_limit.map(|t| (t - start.elapsed().as_secs_f64()).max(1e-3));
        params.lbfgs.max_iterations = left;
        params.lbfgs.time_limit_seconds = time_left;
        params.gauss_newton.max_iterations = left;
        params.gauss_newton.time_limit_seconds = time_left;
        params.mode_levels = base.mode_levels[level.min(base.mode_levels.len())..].to_vec();
        if !remesh_on || remeshes >= max_remeshes {
            params.remesh = None;
        }
        let offset_seconds = start.elapsed().as_secs_f64();
        let continuing = total.is_some();
        let shift = |it: &DesignIteration| {
            let mut it = it.clone();
            it.iteration += done;
            it.level += level;
            it.remeshes = remeshes;
            it.seconds += offset_seconds;
            it
        };
        let mut forward = |it: &DesignIteration| {
            // After a remesh the new start is the previous run's last iteration, already reported.
            if continuing && it.iteration == 0 {
                return ControlFlow::Continue(());
            }
            on_iteration(&shift(it))
        };
        let result = match pattern_design(
            &mut design.problem,
            &design.map,
            edge_length,
            &params,
            &mut forward,
            should_stop,
        ) {
            Ok(r) => r,
            Err(e) => match before_remesh.take() {
                // The remeshed garment failed: the best design is the one before the remesh.
                Some(b) if total.is_some() => {
                    b.restore(design)?;
                    remeshes -= 1;
                    break;
                }
                _ => return Err(SimulateError::failed(format!("design failed: {e}"))),
            },
        };
        let remesh_requested = result.remesh_requested;
        let reached = level + result.level;
        let pattern = result.pattern.clone();
        total = Some(match total.take() {
            None => PatternDesignResult {
                history: result.history.iter().map(&shift).collect(),
                ..result
            },
            Some(t) => {
                let mut history = t.history;
                history.extend(
                    result
                        .history
                        .iter()
                        .filter(|it| it.iteration > 0)
                        .map(&shift),
                );
                PatternDesignResult {
                    initial_objective: t.initial_objective,
                    iterations: t.iterations + result.iterations,
                    history,
                    ..result
                }
            }
        });
        if !remesh_requested || should_stop() {
            break;
        }
        before_remesh = Some(Backup::of(design));
        let remesh_start = std::time::Instant::now();
        let target = skintight_design::remesh_edge_length(&design.problem, edge_length);
        let remeshed = skintight_design::design_remesh(
            &mut design.problem,
            &design.sim.garment,
            &pattern,
            target,
        );
        remesh_seconds += remesh_start.elapsed().as_secs_f64();
        match remeshed {
            Ok(r) => {
                design.sim.garment = r.garment;
                design.sim.pinned = r.pinned;
                design.map = r.map;
                design.sim.initial_state = design.problem.state().clone();
                remeshes += 1;
                level = reached;
            }
            Err(_) => {
                // The design goes on with the mesh it has (the problem was left as it was).
                before_remesh = None;
                remesh_on = false;
                level = reached;
            }
        }
        let used = total.as_ref().map_or(0, |t| t.iterations);
        if used >= max_iterations || time_limit.is_some_and(|t| start.elapsed().as_secs_f64() >= t)
        {
            break;
        }
    }
    let mut result = total.expect("at least one run");
    result.remeshes = remeshes;
    result.remesh_seconds = remesh_seconds;
    result.seconds = start.elapsed().as_secs_f64();
    // The final design into the simulation: rest shapes, equilibrium, pattern panels.
    design.sim.system = design.problem.system().clone();
    design.sim.state = design.problem.state().clone();
    let mesh = design.problem.mesh();
    for (p, panel) in design.sim.garment.panels.iter_mut().enumerate() {
        let first = mesh.panels[p].first_vertex;
        for (k, v) in panel.pattern.iter_mut().enumerate() {
            *v = result.pattern[first + k];
        }
    }
    Ok(result)
}

/// What a remesh replaces, to undo it.
struct Backup {
    garment: skintight_garment::garment::Garment,
    pinned: Vec<bool>,
    initial_state: skintight_physics::ClothOnBodyState,
    map: PatternMap,
    system: skintight_physics::ClothOnBody,
    state: skintight_physics::ClothOnBodyState,
    mesh: DesignMesh,
}

impl Backup {
    fn of(design: &Design) -> Self {
        Self {
            garment: design.sim.garment.clone(),
            pinned: design.sim.pinned.clone(),
            initial_state: design.sim.initial_state.clone(),
            map: design.map.clone(),
            system: design.problem.system().clone(),
            state: design.problem.state().clone(),
            mesh: design.problem.mesh().clone(),
        }
    }

    fn restore(self, design: &mut Design) -> Result<(), SimulateError> {
        design.sim.garment = self.garment;
        design.sim.pinned = self.pinned;
        design.sim.initial_state = self.initial_state;
        design.map = self.map;
        design
            .problem
            .replace_cloth(self.system, self.state, self.mesh)
            .map_err(|e| SimulateError::failed(e.to_string()))
    }
}

/// The one-line summary of a finished design (CLI standard output, the job's summary).
pub fn design_summary(result: &PatternDesignResult) -> serde_json::Value {
    serde_json::json!({
        "initial_objective": result.initial_objective,
        "final_objective": result.final_objective,
        "iterations": result.iterations,
        "evaluations": result.evaluations,
        "remeshes": result.remeshes,
        "stop_reason": format!("{:?}", result.stop_reason),
        "seconds": result.seconds,
    })
}

/// One panel of `patterns.json`.
#[derive(Clone, Debug, Serialize)]
pub struct PatternJson {
    /// Panel name.
    pub name: String,
    /// Outer boundary polyline, counter-clockwise, in mm.
    pub boundary_mm: Vec<[Real; 2]>,
}

/// One seam of `patterns.json`: boundary indices sewn together, index by index.
#[derive(Clone, Debug, Serialize)]
pub struct SeamJson {
    /// The two panels (indices into `panels`).
    pub panels: [usize; 2],
    /// Indices into each panel's `boundary_mm`, same length, sewn pairwise.
    pub boundary_indices: [Vec<usize>; 2],
    /// Whether the seam closes on itself.
    pub closed: bool,
}

/// `patterns.json`: per panel the 2D boundary in mm, and the seam correspondences.
pub fn patterns_json(design: &Design, pattern: &[Vec2]) -> serde_json::Value {
    let mesh = design.problem.mesh();
    let panels: Vec<PatternJson> = mesh
        .panels
        .iter()
        .map(|p| PatternJson {
            name: p.name.clone(),
            boundary_mm: p
                .boundary
                .iter()
                .map(|&v| [pattern[v].x * 1e3, pattern[v].y * 1e3])
                .collect(),
        })
        .collect();
    let position_in = |panel: usize, v: usize| -> usize {
        mesh.panels[panel]
            .boundary
            .iter()
            .position(|&b| b == v)
            .unwrap_or(usize::MAX)
    };
    let seams: Vec<SeamJson> = mesh
        .seams
        .iter()
        .map(|s| SeamJson {
            panels: s.panels,
            boundary_indices: [0, 1].map(|k| {
                s.vertices[k]
                    .iter()
                    .map(|&v| position_in(s.panels[k], v))
                    .collect()
            }),
            closed: s.closed,
        })
        .collect();
    serde_json::json!({ "units": "mm", "panels": panels, "seams": seams })
}

/// The outputs of a finished design: the simulate artifacts of the final design (its `result.json` with
/// the design figures added) plus `patterns.json` and `history.json`.
pub fn design_artifacts(
    design: &Design,
    result: &PatternDesignResult,
) -> Result<Vec<ArtifactFile>, SimulateError> {
    let sim_result = SimulationResult::new(&design.sim, &result.evaluation.equilibrium)?;
    let mut files = artifacts(&design.sim, &sim_result)?;
    let mut json =
        serde_json::to_value(&sim_result).map_err(|e| SimulateError::failed(e.to_string()))?;
    if let Some(obj) = json.as_object_mut() {
        obj.insert("initial_objective".into(), result.initial_objective.into());
        obj.insert("final_objective".into(), result.final_objective.into());
        obj.insert("iterations".into(), result.iterations.into());
        obj.insert("evaluations".into(), result.evaluations.into());
        obj.insert("remeshes".into(), result.remeshes.into());
        obj.insert("remesh_seconds".into(), result.remesh_seconds.into());
        obj.insert(
            "optimizer".into(),
            design.job.optimizer.method.name().into(),
        );
        obj.insert(
            "design_stop_reason".into(),
            format!("{:?}", result.stop_reason).into(),
        );
        obj.insert("design_seconds".into(), result.seconds.into());
        if let Some(w) = &design.job.objectives.stretch {
            obj.insert(
                "window_area_fraction".into(),
                serde_json::json!({
                    "min": w.min,
                    "max": w.max,
                    "initial": design.initial_window_fraction,
                    "final": window_fraction(&design.sim.system, &design.sim.state, w.min, w.max),
                }),
            );
        }
        obj.insert(
            "young_laplace_pressure".into(),
            serde_json::json!({
                "initial": design.initial_pressure,
                "final": pressure_statistics(&design.job, &design.problem, &design.sim, &result.pattern),
                "per_triangle_pa": pressure_per_triangle(&design.problem, &design.sim, &result.pattern),
            }),
        );
        obj.insert(
            "terms".into(),
            serde_json::to_value(
                result
                    .evaluation
                    .terms
                    .iter()
                    .map(|t| serde_json::json!({"name": t.name, "value": t.value, "per_element": t.per_element}))
                    .collect::<Vec<_>>(),
            )
            .unwrap_or_default(),
        );
    }
    for f in &mut files {
        if f.name == "result.json" {
            f.data = serde_json::to_vec_pretty(&json)
                .map_err(|e| SimulateError::failed(e.to_string()))?;
        }
    }
    files.push(ArtifactFile {
        name: "patterns.json",
        content_type: "application/json",
        data: serde_json::to_vec_pretty(&patterns_json(design, &result.pattern))
            .map_err(|e| SimulateError::failed(e.to_string()))?,
    });
    files.push(ArtifactFile {
        name: "history.json",
        content_type: "application/json",
        data: serde_json::to_vec_pretty(&result.history)
            .map_err(|e| SimulateError::failed(e.to_string()))?,
    });
    Ok(files)
}
