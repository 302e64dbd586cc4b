//! Checking a design job's values: the scene part as a scene ([`crate::scene::Scene::validate`]), then
//! the objectives, the regularizers and the optimizer, one function per section. Every error names its
//! key (`objectives.pressure.max_pa`, `optimizer.mode_levels[1]`, …); the first key at fault is reported.

use skintight_geometry::anthropometry::LimbKind;
use skintight_geometry::math::Real;

use super::spec::{
    DesignJob, ObjectivesSpec, OptimizerMethod, OptimizerSpec, PrescriptionObjective,
    PressureObjective, RegularizersSpec, RemeshSpec, SeamTractionObjective, ShapeObjective,
    SlidingObjective, StretchObjective, TargetSpec,
};
use crate::scene::SceneError;

/// Largest weight of any term.
pub const MAX_WEIGHT: Real = 1e12;
/// Revolution target: `segments` and profile points.
pub const MAX_TARGET_SEGMENTS: usize = 1024;
pub const MAX_PROFILE_POINTS: usize = 256;
/// Lengths of a target (profile heights and radii, the shape radius), m.
pub const MAX_TARGET_LENGTH: Real = 10.0;
/// Poses of the sliding objective.
pub const MAX_POSES: usize = 16;
/// Friction coefficient (dimensionless).
pub const MAX_FRICTION: Real = 10.0;
/// Stretch window bounds (dimensionless).
pub const MAX_STRETCH: Real = 10.0;
/// Pressures, Pa (absolute value).
pub const MAX_PRESSURE_PA: Real = 1e6;
/// Design iterations, level iterations and mode counts.
pub const MAX_DESIGN_ITERATIONS: usize = 10_000;
/// Design time limit, s (one week).
pub const MAX_DESIGN_TIME_S: Real = 604_800.0;
/// L-BFGS memory; mode levels; remeshes.
pub const MAX_MEMORY: usize = 100;
pub const MAX_MODE_LEVELS: usize = 32;
pub const MAX_REMESHES: usize = 100;

fn non_negative(key: &str, v: Real) -> Result<(), SceneError> {
    if v.is_finite() && (0.0..=MAX_WEIGHT).contains(&v) {
        Ok(())
    } else {
        Err(SceneError::new(
            key,
            format!("must be a finite number in [0, {MAX_WEIGHT:e}], got {v}"),
        ))
    }
}

fn positive(key: &str, v: Real) -> Result<(), SceneError> {
    if v.is_finite() && v > 0.0 && v <= MAX_WEIGHT {
        Ok(())
    } else {
        Err(SceneError::new(
            key,
            format!("must be a finite number in (0, {MAX_WEIGHT:e}], got {v}"),
        ))
    }
}

fn at_most(key: &str, n: usize, max: usize) -> Result<(), SceneError> {
    if n > max {
        return Err(SceneError::new(
            key,
            format!("must be at most {max}, got {n}"),
        ));
    }
    Ok(())
}

impl DesignJob {
    /// Checks every value that cannot be right whatever the body, naming the first key at fault.
    pub fn validate(&self) -> Result<(), SceneError> {
        self.scene().validate()?;
        self.objectives.validate()?;
        if let Some(p) = &self.objectives.prescription {
            let limit = self.garment.fabric.limits.max_pressure_pa / skintight_physics::PA_PER_MMHG;
            p.prescription()
                .windows("objectives.prescription", limit, self.prescription_limb())?;
        }
        self.regularizers.validate()?;
        self.optimizer.validate()
    }
}

impl DesignJob {
    /// The kind of limb a prescription is on: an arm for an arm template, else a leg.
    pub fn prescription_limb(&self) -> LimbKind {
        match &self.garment.template {
            Some(t)
                if crate::scene::template::find_template(&t.name)
                    .is_ok_and(|t| t.limb == crate::scene::template::TemplateLimb::Arm) =>
            {
                LimbKind::Arm
            }
            _ => LimbKind::Leg,
        }
    }
}

impl ObjectivesSpec {
    /// Checks that there is an objective and each one's values; keys start with `objectives.`.
    pub fn validate(&self) -> Result<(), SceneError> {
        if self.shape.is_none()
            && self.stretch.is_none()
            && self.seam_traction.is_none()
            && self.pressure.is_none()
            && self.sliding.is_none()
            && self.prescription.is_none()
        {
            return Err(SceneError::new(
                "objectives",
                "give at least one objective: shape, stretch, seam_traction, pressure, sliding or \
                 prescription",
            ));
        }
        if let Some(s) = &self.shape {
            s.validate()?;
        }
        if let Some(s) = &self.stretch {
            s.validate()?;
        }
        if let Some(s) = &self.seam_traction {
            s.validate()?;
        }
        if let Some(s) = &self.sliding {
            s.validate()?;
        }
        if let Some(p) = &self.pressure {
            p.validate()?;
        }
        if let Some(p) = &self.prescription {
            p.validate()?;
        }
        Ok(())
    }
}

impl PrescriptionObjective {
    /// Keys start with `objectives.prescription.` (the standard, class and profile are checked against
    /// the table with the fabric's pressure limit, in [`DesignJob::validate`]).
    pub fn validate(&self) -> Result<(), SceneError> {
        non_negative("objectives.prescription.weight", self.weight)?;
        if !(self.margin.is_finite() && (0.0..=0.45).contains(&self.margin)) {
            return Err(SceneError::new(
                "objectives.prescription.margin",
                format!("must be a fraction in [0, 0.45], got {}", self.margin),
            ));
        }
        if !(self.band_spacing_m.is_finite() && (0.005..=0.5).contains(&self.band_spacing_m)) {
            return Err(SceneError::new(
                "objectives.prescription.band_spacing_m",
                format!("must be in [0.005, 0.5] m, got {}", self.band_spacing_m),
            ));
        }
        Ok(())
    }
}

impl ShapeObjective {
    /// Keys start with `objectives.shape.`.
    pub fn validate(&self) -> Result<(), SceneError> {
        non_negative("objectives.shape.weight", self.weight)?;
        if let Some(r) = self.radius {
            positive("objectives.shape.radius", r)?;
            if r > MAX_TARGET_LENGTH {
                return Err(SceneError::new(
                    "objectives.shape.radius",
                    format!("must be at most {MAX_TARGET_LENGTH} m, got {r}"),
                ));
            }
        }
        self.target.validate()
    }
}

impl TargetSpec {
    /// Keys start with `objectives.shape.target.`.
    pub fn validate(&self) -> Result<(), SceneError> {
        match self {
            TargetSpec::Mesh { path } if path.is_empty() => Err(SceneError::new(
                "objectives.shape.target.path",
                "the path is empty",
            )),
            TargetSpec::Mesh { .. } => Ok(()),
            TargetSpec::Revolution { profile, segments } => {
                if !(8..=MAX_TARGET_SEGMENTS).contains(segments) {
                    return Err(SceneError::new(
                        "objectives.shape.target.segments",
                        format!("must lie in [8, {MAX_TARGET_SEGMENTS}], got {segments}"),
                    ));
                }
                if profile.len() < 2 || profile.len() > MAX_PROFILE_POINTS {
                    return Err(SceneError::new(
                        "objectives.shape.target.profile",
                        format!(
                            "give 2 to {MAX_PROFILE_POINTS} [y, radius] points, got {}",
                            profile.len()
                        ),
                    ));
                }
                for (i, [y, r]) in profile.iter().enumerate() {
                    let key = format!("objectives.shape.target.profile[{i}]");
                    let m = MAX_TARGET_LENGTH;
                    if !(y.is_finite() && y.abs() <= m && r.is_finite() && *r > 0.0 && *r <= m) {
                        return Err(SceneError::new(
                            key,
                            format!("needs a height y in [-{m}, {m}] m and a radius in (0, {m}] m"),
                        ));
                    }
                    if i > 0 && !(*y > profile[i - 1][0]) {
                        return Err(SceneError::new(key, "heights must increase"));
                    }
                }
                Ok(())
            }
        }
    }
}

impl StretchObjective {
    /// Keys start with `objectives.stretch.`.
    pub fn validate(&self) -> Result<(), SceneError> {
        non_negative("objectives.stretch.weight", self.weight)?;
        non_negative("objectives.stretch.min", self.min)?;
        if !(self.max > self.min && self.max <= MAX_STRETCH) {
            return Err(SceneError::new(
                "objectives.stretch.max",
                format!(
                    "must exceed min ({}) and be at most {MAX_STRETCH}, got {}",
                    self.min, self.max
                ),
            ));
        }
        Ok(())
    }
}

impl SeamTractionObjective {
    /// Keys start with `objectives.seam_traction.`.
    pub fn validate(&self) -> Result<(), SceneError> {
        non_negative("objectives.seam_traction.weight", self.weight)
    }
}

impl SlidingObjective {
    /// Keys start with `objectives.sliding.` (the pose files are read, and checked against the body, when
    /// the design is prepared).
    pub fn validate(&self) -> Result<(), SceneError> {
        non_negative("objectives.sliding.weight", self.weight)?;
        non_negative(
            "objectives.sliding.friction_coefficient",
            self.friction_coefficient,
        )?;
        if self.friction_coefficient > MAX_FRICTION {
            return Err(SceneError::new(
                "objectives.sliding.friction_coefficient",
                format!(
                    "must be at most {MAX_FRICTION}, got {}",
                    self.friction_coefficient
                ),
            ));
        }
        if self.poses.is_empty() || self.poses.len() > MAX_POSES {
            return Err(SceneError::new(
                "objectives.sliding.poses",
                format!("needs 1 to {MAX_POSES} poses, got {}", self.poses.len()),
            ));
        }
        for (i, pose) in self.poses.iter().enumerate() {
            if pose.path.is_empty() {
                return Err(SceneError::new(
                    format!("objectives.sliding.poses[{i}].path"),
                    "the path is empty",
                ));
            }
        }
        Ok(())
    }
}

impl PressureObjective {
    /// Keys start with `objectives.pressure.`: a target or a range, not both, finite.
    pub fn validate(&self) -> Result<(), SceneError> {
        non_negative("objectives.pressure.weight", self.weight)?;
        non_negative("objectives.pressure.negative_weight", self.negative_weight)?;
        let finite = |key: &str, v: Option<Real>| match v {
            Some(v) if !(v.is_finite() && v.abs() <= MAX_PRESSURE_PA) => Err(SceneError::new(
                key,
                format!(
                    "must be a finite pressure in [-{MAX_PRESSURE_PA:e}, {MAX_PRESSURE_PA:e}] Pa, got {v}"
                ),
            )),
            _ => Ok(()),
        };
        finite("objectives.pressure.target_pa", self.target_pa)?;
        finite("objectives.pressure.min_pa", self.min_pa)?;
        finite("objectives.pressure.max_pa", self.max_pa)?;
        match (self.target_pa, self.min_pa, self.max_pa) {
            (Some(_), None, None) => Ok(()),
            (Some(_), _, _) => Err(SceneError::new(
                "objectives.pressure.target_pa",
                "give either target_pa or min_pa and max_pa, not both",
            )),
            (None, None, None) => Err(SceneError::new(
                "objectives.pressure",
                "give target_pa (Pa), or min_pa and max_pa (Pa)",
            )),
            (None, Some(_), None) => Err(SceneError::new(
                "objectives.pressure.max_pa",
                "missing: min_pa is given, give max_pa too",
            )),
            (None, None, Some(_)) => Err(SceneError::new(
                "objectives.pressure.min_pa",
                "missing: max_pa is given, give min_pa too",
            )),
            (None, Some(min), Some(max)) => {
                if max <= min {
                    return Err(SceneError::new(
                        "objectives.pressure.max_pa",
                        format!("must exceed min_pa ({min}), got {max}"),
                    ));
                }
                Ok(())
            }
        }
    }
}

impl RegularizersSpec {
    /// Keys start with `regularizers.`: every weight ≥ 0, the compactness threshold in (0, 1].
    pub fn validate(&self) -> Result<(), SceneError> {
        for (key, w) in [
            (
                "regularizers.seam_length.weight",
                self.seam_length.map(|w| w.weight),
            ),
            (
                "regularizers.smoothness.weight",
                self.smoothness.map(|w| w.weight),
            ),
            (
                "regularizers.edge_length.weight",
                self.edge_length.map(|w| w.weight),
            ),
            (
                "regularizers.compactness.weight",
                self.compactness.map(|w| w.weight),
            ),
            (
                "regularizers.pinned_traction.weight",
                self.pinned_traction.map(|w| w.weight),
            ),
        ] {
            if let Some(w) = w {
                non_negative(key, w)?;
            }
        }
        if let Some(c) = self.compactness
            && !(c.threshold > 0.0 && c.threshold <= 1.0)
        {
            return Err(SceneError::new(
                "regularizers.compactness.threshold",
                format!("must lie in (0, 1], got {}", c.threshold),
            ));
        }
        Ok(())
    }
}

impl OptimizerSpec {
    /// Keys start with `optimizer.`: limits and tolerances, the remesh trigger, the Gauss-Newton-only
    /// settings given only with that method, increasing mode levels.
    pub fn validate(&self) -> Result<(), SceneError> {
        if self.max_iterations == 0 {
            return Err(SceneError::new(
                "optimizer.max_iterations",
                "must be at least 1",
            ));
        }
        non_negative("optimizer.fabric_limits.weight", self.fabric_limits.weight)?;
        let m = self.fabric_limits.margin;
        if !(m.is_finite() && (0.0..0.5).contains(&m)) {
            return Err(SceneError::new(
                "optimizer.fabric_limits.margin",
                format!(
                    "must lie in [0, 0.5) (0.02: the penalty acts from 98 % of the limit), got {m}"
                ),
            ));
        }
        at_most(
            "optimizer.max_iterations",
            self.max_iterations,
            MAX_DESIGN_ITERATIONS,
        )?;
        positive("optimizer.time_limit_s", self.time_limit_s)?;
        if self.time_limit_s > MAX_DESIGN_TIME_S {
            return Err(SceneError::new(
                "optimizer.time_limit_s",
                format!(
                    "must be at most {MAX_DESIGN_TIME_S} s (a week), got {}",
                    self.time_limit_s
                ),
            ));
        }
        positive("optimizer.gradient_tolerance", self.gradient_tolerance)?;
        if self.memory == 0 {
            return Err(SceneError::new("optimizer.memory", "must be at least 1"));
        }
        at_most("optimizer.memory", self.memory, MAX_MEMORY)?;
        non_negative("optimizer.level_min_decrease", self.level_min_decrease)?;
        if !(self.step_growth == 0.0 || self.step_growth >= 1.0 && self.step_growth.is_finite()) {
            return Err(SceneError::new(
                "optimizer.step_growth",
                format!(
                    "must be at least 1 (0 turns the bound off), got {}",
                    self.step_growth
                ),
            ));
        }
        if let Err(e) = (skintight_design::InexactTolerance {
            loosest: self.inexact_loosest,
            objective_error: self.inexact_objective_error,
        })
        .validate()
        {
            let (key, field) = if e.starts_with("loosest") {
                ("optimizer.inexact_loosest", "loosest ")
            } else {
                ("optimizer.inexact_objective_error", "objective_error ")
            };
            return Err(SceneError::new(key, e.trim_start_matches(field)));
        }
        if let Some(n) = self.level_iterations {
            at_most("optimizer.level_iterations", n, MAX_DESIGN_ITERATIONS)?;
        }
        at_most(
            "optimizer.mode_levels",
            self.mode_levels.len(),
            MAX_MODE_LEVELS,
        )?;
        if let Some(i) = self
            .mode_levels
            .iter()
            .position(|&m| m > MAX_DESIGN_ITERATIONS)
        {
            at_most(
                &format!("optimizer.mode_levels[{i}]"),
                self.mode_levels[i],
                MAX_DESIGN_ITERATIONS,
            )?;
        }
        self.remesh.validate()?;
        if self.level_iterations == Some(0) {
            return Err(SceneError::new(
                "optimizer.level_iterations",
                "must be at least 1",
            ));
        }
        if self.gauss_newton_system.is_some() && self.method != OptimizerMethod::GaussNewton {
            return Err(SceneError::new(
                "optimizer.gauss_newton_system",
                "is a setting of method \"gauss_newton\" only",
            ));
        }
        if let Some(d) = self.damping {
            if self.method != OptimizerMethod::GaussNewton {
                return Err(SceneError::new(
                    "optimizer.damping",
                    "is a setting of method \"gauss_newton\" only",
                ));
            }
            positive("optimizer.damping", d)?;
        }
        let levels = &self.mode_levels;
        if let Some(i) =
            (0..levels.len()).find(|&i| levels[i] == 0 || (i > 0 && levels[i] <= levels[i - 1]))
        {
            return Err(SceneError::new(
                format!("optimizer.mode_levels[{i}]"),
                "mode counts must be ≥ 1 and increase",
            ));
        }
        Ok(())
    }
}

impl RemeshSpec {
    /// Keys start with `optimizer.remesh.`.
    pub fn validate(&self) -> Result<(), SceneError> {
        if !(self.min_quality.is_finite() && (0.0..1.0).contains(&self.min_quality)) {
            return Err(SceneError::new(
                "optimizer.remesh.min_quality",
                format!("must lie in [0, 1), got {}", self.min_quality),
            ));
        }
        if !(self.max_edge_ratio.is_finite()
            && self.max_edge_ratio > 1.0
            && self.max_edge_ratio <= MAX_WEIGHT)
        {
            return Err(SceneError::new(
                "optimizer.remesh.max_edge_ratio",
                format!(
                    "must lie in (1, {MAX_WEIGHT:e}], got {}",
                    self.max_edge_ratio
                ),
            ));
        }
        at_most(
            "optimizer.remesh.max_remeshes",
            self.max_remeshes,
            MAX_REMESHES,
        )?;
        Ok(())
    }
}
