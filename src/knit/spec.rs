//! The yarn scene file (`skintight knit simulate-yarn SCENE.json`, the `yarn_simulate` job's spec): its
//! types and defaults, reading it from JSON, where its pattern is and the time grid it implies. The checks
//! of every value are in `validate.rs`.
//!
//! A scene is a patch of `nx × ny` cells of a shared pattern (`skintight_knit::tile`) in one of five
//! [`Scenario`]s. The patch lies in the pattern's xy plane (courses along x, wales along y), skintight's +y
//! is up and gravity is `(0, −g, 0)`. A *grip band* is the vertices within `clamp_band_cells` cell periods
//! of a side of the patch's bounding box (x sides: `px`, y sides: `py`); how each scenario holds and moves
//! them is in `build.rs`.
//!
//! Units: SI (m, s, kg, Pa, rad).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use skintight_knit::edge_finish::EdgeFinish;
use skintight_knit::implicit_euler::ImplicitEulerParams;
use skintight_knit::newton::NewtonParams;
use skintight_knit::yarn_params::YarnParams;

use super::error::YarnSceneError;

/// What is simulated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scenario {
    /// Hanging under gravity from the clamped top band.
    Hang,
    /// Stretched along x between two grips.
    StretchUniaxial,
    /// Stretched equally in x and y by grips on all sides.
    StretchBiaxial,
    /// Sheared: the top grip moves along x over the clamped bottom grip.
    Shear,
    /// Falling flat onto a rigid sphere.
    DrapeSphere,
}

impl Scenario {
    /// The scenario's name in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Scenario::Hang => "hang",
            Scenario::StretchUniaxial => "stretch_uniaxial",
            Scenario::StretchBiaxial => "stretch_biaxial",
            Scenario::Shear => "shear",
            Scenario::DrapeSphere => "drape_sphere",
        }
    }
}

/// A yarn simulation scene (JSON; unknown keys are errors).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct YarnScene {
    /// The pattern: a folder holding `pattern.pyp` or a `.pyp` file, relative to the scene file; or the
    /// name of a shared pattern (`stock_9`, …) when a yarn data folder is configured.
    pub pattern: String,
    /// Cells `[nx, ny]`.
    pub cells: [usize; 2],
    /// The scenario.
    pub scenario: Scenario,
    /// Simulated time (s).
    pub duration_s: f64,
    /// Time step (s).
    #[serde(default = "default_dt")]
    pub dt_s: f64,
    /// Frames written per simulated second (Hz); frame 0 is the start. Must divide into whole time steps:
    /// the frame interval is rounded to a whole number of steps (at least 1).
    #[serde(default = "default_frame_rate")]
    pub frame_rate_hz: f64,
    /// Final strain of a stretch, or `tan γ` of the shear (dimensionless).
    #[serde(default = "default_strain")]
    pub strain: f64,
    /// Time over which grips move to their final positions (s); default: the whole duration.
    #[serde(default)]
    pub ramp_time_s: Option<f64>,
    /// Width of the grip bands, in cell periods.
    #[serde(default = "default_band")]
    pub clamp_band_cells: f64,
    /// Magnitude of gravity (m/s², along −y).
    #[serde(default = "default_gravity")]
    pub gravity_m_s2: f64,
    /// Mass-proportional damping rate (1/s).
    #[serde(default = "default_damping")]
    pub mass_damping_per_s: f64,
    /// Sphere radius for `drape_sphere` (m); default 0.3 × the patch's smaller side.
    #[serde(default)]
    pub sphere_radius_m: Option<f64>,
    /// Sphere penalty stiffness (Pa).
    #[serde(default = "default_sphere_stiffness")]
    pub sphere_stiffness_pa: f64,
    /// Yarn material and contact parameters.
    #[serde(default)]
    pub yarn: YarnParams,
    /// Newton settings of each time step.
    #[serde(default = "default_newton")]
    pub newton: NewtonParams,
    /// Most Newton iterations of the relaxation of the start state (0: start unrelaxed).
    #[serde(default = "default_relax_iterations")]
    pub relax_max_iterations: usize,
    /// The finish of the cut border ([`EdgeFinish`]): `bonded` (default; every cut yarn end fused to the
    /// nearest vertex of another yarn) or `cut` (free ends: the frictionless border unravels).
    #[serde(default)]
    pub edges: EdgeFinish,
    /// How many times a time step may be halved when its Newton solve does not converge (0 ..= 10;
    /// `skintight_knit::implicit_euler::ImplicitEuler::step`): at most `2^k` substeps of `dt_s / 2^k` a
    /// step.
    #[serde(default = "default_max_step_halvings")]
    pub max_step_halvings: usize,
    /// Yarn–yarn Coulomb friction coefficient μ (dimensionless, ≥ 0; default 0: frictionless, every step as
    /// without it). The contact pairs at each step's start become friction pairs with lagged normal forces
    /// (`skintight_knit::patch_friction`).
    #[serde(default)]
    pub friction_coefficient: f64,
    /// The slip ε (m, > 0) below which static friction is smoothed (`skintight_knit::yarn_friction`): a
    /// yarn held by friction creeps by at most about ε per time step. Default 10⁻⁶ m.
    #[serde(default = "default_friction_slip")]
    pub friction_slip: f64,
}

fn default_friction_slip() -> f64 {
    ImplicitEulerParams::default().friction_slip
}

fn default_max_step_halvings() -> usize {
    ImplicitEulerParams::default().max_halvings
}
fn default_dt() -> f64 {
    ImplicitEulerParams::default().dt
}
fn default_frame_rate() -> f64 {
    60.0
}
fn default_strain() -> f64 {
    0.2
}
fn default_band() -> f64 {
    0.25
}
fn default_gravity() -> f64 {
    skintight_knit::gravity::STANDARD_GRAVITY
}
fn default_damping() -> f64 {
    ImplicitEulerParams::default().mass_damping
}
fn default_sphere_stiffness() -> f64 {
    1.0e8
}
fn default_relax_iterations() -> usize {
    300
}
fn default_newton() -> NewtonParams {
    ImplicitEulerParams::default().newton
}

impl YarnScene {
    /// Parses scene JSON (`path` names the source in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, YarnSceneError> {
        let scene: YarnScene = serde_json::from_str(text)
            .map_err(|e| YarnSceneError::Input(format!("{}: {e}", path.display())))?;
        scene
            .validate()
            .map_err(|e| YarnSceneError::Input(format!("{}: {e}", path.display())))?;
        Ok(scene)
    }

    /// Reads and validates a scene file.
    pub fn from_file(path: &Path) -> Result<Self, YarnSceneError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| YarnSceneError::Input(format!("cannot read {}: {e}", path.display())))?;
        Self::parse(&text, path)
    }

    /// Whether `pattern` is a plain name (letters, digits, `_`, `-`): a shared pattern's folder name.
    pub fn pattern_is_name(&self) -> bool {
        !self.pattern.is_empty()
            && self
                .pattern
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    }

    /// The `.pyp` file: `pattern` relative to `base` (a folder means its `pattern.pyp`); a plain name that is
    /// not found there is looked up in `yarns_dir`.
    pub fn pattern_path(&self, base: &Path, yarns_dir: Option<&Path>) -> PathBuf {
        let local = base.join(&self.pattern);
        let chosen = if !local.exists()
            && self.pattern_is_name()
            && let Some(dir) = yarns_dir
        {
            dir.join(&self.pattern)
        } else {
            local
        };
        if chosen.is_dir() {
            chosen.join("pattern.pyp")
        } else {
            chosen
        }
    }

    /// Number of time steps and steps per frame.
    pub fn steps(&self) -> (usize, usize) {
        let steps = (self.duration_s / self.dt_s).round().max(1.0) as usize;
        let per_frame = (1.0 / (self.frame_rate_hz * self.dt_s)).round().max(1.0) as usize;
        (steps, per_frame)
    }

    /// The settings of the scene's backward Euler stepper.
    pub fn time_stepping(&self) -> ImplicitEulerParams {
        ImplicitEulerParams {
            dt: self.dt_s,
            mass_damping: self.mass_damping_per_s,
            newton: self.newton,
            max_halvings: self.max_step_halvings,
            friction_coefficient: self.friction_coefficient,
            friction_slip: self.friction_slip,
        }
    }
}
