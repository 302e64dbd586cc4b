//! Checking a design job's values: the scene part as a scene ([`crate::scene::Scene::validate`]), then
//! the objectives, the regularizers and the optimizer, one function per section. Every error names its
//! key (`objectives.pressure.max_pa`, `optimizer.mode_levels[1]`, …); the first key at fault is reported.

use skintight_geometry::math::Real;

use super::spec::{
    DesignJob, ObjectivesSpec, OptimizerMethod, OptimizerSpec, PressureObjective, RegularizersSpec,
    RemeshSpec, SeamTractionObjective, ShapeObjective, SlidingObjective, StretchObjective,
    TargetSpec,
};
use crate::scene::SceneError;

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
    /// Checks every value that cannot be right whatever the body, naming the first key at fault.
    pub fn validate(&self) -> Result<(), SceneError> {
        self.scene().validate()?;
        self.objectives.validate()?;
        self.regularizers.validate()?;
        self.optimizer.validate()
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
        {
            return Err(SceneError::new(
                "objectives",
                "give at least one objective: shape, stretch, seam_traction, pressure or sliding",
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
        Ok(())
    }
}

impl ShapeObjective {
    /// Keys start with `objectives.shape.`.
    pub fn validate(&self) -> Result<(), SceneError> {
        non_negative("objectives.shape.weight", self.weight)?;
        if let Some(r) = self.radius {
            positive("objectives.shape.radius", r)?;
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
        if !(self.max > self.min) {
            return Err(SceneError::new(
                "objectives.stretch.max",
                format!("must exceed min ({}), got {}", self.min, self.max),
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
        if self.poses.is_empty() {
            return Err(SceneError::new(
                "objectives.sliding.poses",
                "needs at least one pose",
            ));
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
            Some(v) if !v.is_finite() => Err(SceneError::new(
                key,
                format!("must be a finite pressure (Pa), got {v}"),
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
        positive("optimizer.time_limit_s", self.time_limit_s)?;
        positive("optimizer.gradient_tolerance", self.gradient_tolerance)?;
        if self.memory == 0 {
            return Err(SceneError::new("optimizer.memory", "must be at least 1"));
        }
        non_negative("optimizer.level_min_decrease", self.level_min_decrease)?;
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
        if self.max_edge_ratio.is_nan() || self.max_edge_ratio <= 1.0 {
            return Err(SceneError::new(
                "optimizer.remesh.max_edge_ratio",
                format!("must exceed 1, got {}", self.max_edge_ratio),
            ));
        }
        Ok(())
    }
}
