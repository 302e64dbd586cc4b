//! The checks of a yarn scene: every value in its range, each message naming the field and the range, so
//! that a scene file or a `yarn_simulate` spec is refused before anything is built (the service maps the
//! message's first word to the field of its error envelope).

use super::spec::YarnScene;

impl YarnScene {
    /// Checks every value; the message names the field and its range.
    pub fn validate(&self) -> Result<(), String> {
        let [nx, ny] = self.cells;
        if nx == 0 || ny == 0 || nx * ny > 4096 {
            return Err(format!(
                "cells {:?} must be two whole numbers ≥ 1 with nx × ny ≤ 4096",
                self.cells
            ));
        }
        let positive = [
            ("duration_s", self.duration_s),
            ("dt_s", self.dt_s),
            ("frame_rate_hz", self.frame_rate_hz),
            ("clamp_band_cells", self.clamp_band_cells),
            ("sphere_stiffness_pa", self.sphere_stiffness_pa),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} = {v} must be a number > 0"));
            }
        }
        let non_negative = [
            ("gravity_m_s2", self.gravity_m_s2),
            ("mass_damping_per_s", self.mass_damping_per_s),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} = {v} must be a number ≥ 0"));
            }
        }
        if !(self.strain.is_finite() && self.strain > -0.9 && self.strain <= 2.0) {
            return Err(format!("strain = {} must be in (−0.9, 2]", self.strain));
        }
        if let Some(r) = self.ramp_time_s
            && !(r.is_finite() && r >= 0.0)
        {
            return Err(format!("ramp_time_s = {r} must be ≥ 0"));
        }
        if let Some(r) = self.sphere_radius_m
            && !(r.is_finite() && r > 0.0)
        {
            return Err(format!("sphere_radius_m = {r} must be > 0"));
        }
        if self.duration_s / self.dt_s > 1.0e6 {
            return Err(format!(
                "duration_s / dt_s = {} time steps is too many (at most 10⁶)",
                self.duration_s / self.dt_s
            ));
        }
        if 2.0 * self.clamp_band_cells >= (nx.min(ny)) as f64 {
            return Err(format!(
                "clamp_band_cells = {} must be less than half the smaller cell count {}",
                self.clamp_band_cells,
                nx.min(ny)
            ));
        }
        if self.pattern.trim().is_empty() {
            return Err(
                "pattern is empty: give a pattern folder, a .pyp file or a shared pattern name"
                    .into(),
            );
        }
        if self.max_step_halvings > 10 {
            return Err(format!(
                "max_step_halvings = {} must be at most 10 (substeps of dt_s / 1024)",
                self.max_step_halvings
            ));
        }
        skintight_knit::patch_friction::PatchFriction::validate(
            self.friction_coefficient,
            self.friction_slip,
        )?;
        self.yarn.validate()?;
        Ok(())
    }
}
