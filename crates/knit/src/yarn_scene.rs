//! Yarn-level simulation scenes (`skintight knit simulate-yarn SCENE.json --out DIR`, job kind
//! `yarn_simulate`): a patch of `nx × ny` cells of a shared pattern ([`crate::tile`]) in one of five
//! scenarios, time-stepped with backward Euler ([`crate::implicit_euler`]) and written as a frame sequence
//! ([`crate::frame_sequence`]).
//!
//! The patch lies in the pattern's xy plane (courses along x, wales along y), skintight's +y is up and
//! gravity is `(0, −g, 0)`. A *grip band* is the vertices within `clamp_band_cells` cell periods of a side
//! of the patch's bounding box (x sides: `px`, y sides: `py`).
//!
//! - `hang`: the top band (largest y) is clamped; the patch hangs under gravity.
//! - `stretch_uniaxial`: the left band is clamped, the right band moves by `strain · W` along +x over
//!   `ramp_time_s` (`W` the patch width, m), then holds.
//! - `stretch_biaxial`: all four bands move to `c + (1 + strain)(X − c)` in x and y (`c` the box centre),
//!   i.e. an equibiaxial stretch of the border.
//! - `shear`: the bottom band is clamped, the top band moves by `strain · H` along +x (`H` the height; the
//!   shear `tan γ = strain`).
//! - `drape_sphere`: the patch is turned flat (its normal along +y), centred above a rigid sphere of radius
//!   `sphere_radius_m` (default 0.3 × the smaller side) whose top is one yarn radius below it, and falls on
//!   it under gravity, nothing held.
//!
//! **Start state.** The published rest geometry (`*Q`) is not an equilibrium of this crate's model (its
//! rest curvatures and twists are balanced by HYLC's own contact law; `tests/rest_state.rs`), so a patch
//! tiled from it would first spring into another shape. [`set_up`] therefore solves the periodic cell at
//! zero strain without gravity ([`crate::periodic_cell`], damped Newton) and tiles that equilibrium (its
//! positions, angles, reference frames and reference twists); then [`run`] relaxes the cut patch with its
//! held vertices, without gravity ([`crate::implicit_euler::ImplicitEuler::relax`]) — the border, which
//! lost the tension and moments the periodic neighbours carried, curls and settles — and frame 0 is that
//! relaxed state, at rest. The scenario's loads and grips act from there.
//!
//! **Edges** (`edges`, [`crate::edge_finish`]): `bonded` (the default) fuses every cut yarn end to the
//! nearest vertex of another yarn, as the laser- or ultrasound-cut edge of a synthetic knit or an
//! overlocked edge holds it; `cut` leaves the ends free, and with frictionless contact the border then
//! unravels, a motion with no nearby equilibrium (the 4 × 4 stockinette hang: relaxation 991 Newton
//! iterations and 12 a step with cut edges, 598 and 7 bonded).
//!
//! Units: SI (m, s, kg, Pa, rad).

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::PeriodicPattern;
use crate::checkpoint::{Checkpoint, CheckpointError, Phase};
use crate::edge_finish::EdgeFinish;
use crate::frame_sequence::{
    FORMAT, SequenceError, SequenceMeta, SequenceWriter, Units, VERSION, YarnRange,
};
use crate::implicit_euler::{
    ImplicitEuler, ImplicitEulerParams, ImplicitEulerState, Prescribed, StepError,
};
use crate::newton::{NewtonParams, minimize};
use crate::patch::{PatchLoads, PatchModel, transform_patch};
use crate::periodic_cell::{CellState, PeriodicCell};
use crate::sphere_contact::SphereObstacle;
use crate::tile::tile;
use crate::tubes::tubes;
use crate::yarn_params::YarnParams;

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
    /// [`crate::implicit_euler::ImplicitEuler::step`]): at most `2^k` substeps of `dt_s / 2^k` a step.
    #[serde(default = "default_max_step_halvings")]
    pub max_step_halvings: usize,
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
    crate::gravity::STANDARD_GRAVITY
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

/// Errors of a scene.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene cannot be read or has a bad value (the message names the field and the fix).
    #[error("{0}")]
    Input(String),
    /// Writing the outputs failed.
    #[error("{0}")]
    Output(String),
    /// A time step failed.
    #[error(transparent)]
    Step(#[from] StepError),
}

impl From<CheckpointError> for SceneError {
    fn from(e: CheckpointError) -> Self {
        match e {
            CheckpointError::Unusable(m) => SceneError::Input(m),
            CheckpointError::Write(m) => SceneError::Output(m),
        }
    }
}

/// The checkpoint of a [`run`] (`out/checkpoint.json`, [`crate::checkpoint`]).
pub type RunCheckpoint = Checkpoint<YarnScene, YarnSimulationResult>;

impl From<SequenceError> for SceneError {
    fn from(e: SequenceError) -> Self {
        SceneError::Output(e.to_string())
    }
}

impl YarnScene {
    /// Parses scene JSON (`path` names the source in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, SceneError> {
        let scene: YarnScene = serde_json::from_str(text)
            .map_err(|e| SceneError::Input(format!("{}: {e}", path.display())))?;
        scene
            .validate()
            .map_err(|e| SceneError::Input(format!("{}: {e}", path.display())))?;
        Ok(scene)
    }

    /// Reads and validates a scene file.
    pub fn from_file(path: &Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SceneError::Input(format!("cannot read {}: {e}", path.display())))?;
        Self::parse(&text, path)
    }

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
        self.yarn.validate()?;
        Ok(())
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
        }
    }
}

/// Progress after a written frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FrameProgress {
    /// The frame just written (0 = the start).
    pub frame: usize,
    /// Frames the run will write.
    pub frame_count: usize,
    /// Simulated time (s).
    pub time_s: f64,
    /// Newton iterations so far.
    pub newton_iterations: usize,
    /// Smallest centreline distance over yarn diameter so far (while relaxing: of the start state, not
    /// measured again until frame 0 is written).
    pub min_distance_over_diameter: f64,
    /// Whether the start state is still being relaxed (then `frame` is 0 and not yet written; reported
    /// every few seconds of wall-clock time).
    pub relaxing: bool,
    /// Newton iterations of the relaxation so far.
    pub relax_newton_iterations: usize,
}

/// The outcome of a run (`result.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct YarnSimulationResult {
    /// The scenario's name.
    pub scenario: String,
    /// The `.pyp` read.
    pub pattern: String,
    /// Cells `[nx, ny]`.
    pub cells: [usize; 2],
    /// Yarns (with at least one edge).
    pub yarns: usize,
    /// Yarn vertices.
    pub vertices: usize,
    /// Unknowns (4 per vertex).
    pub dofs: usize,
    /// Held vertices (clamped or moving).
    pub prescribed_vertices: usize,
    /// The border's finish (`bonded` or `cut`).
    pub edges: EdgeFinish,
    /// Bonds of a fused edge (cut yarn ends tied to the fabric; 0 for `cut`).
    pub bonds: usize,
    /// Yarn radius (m).
    pub yarn_radius_m: f64,
    /// Total yarn mass (kg).
    pub mass_kg: f64,
    /// Frames written (including frame 0).
    pub frames: usize,
    /// Time steps taken.
    pub steps: usize,
    /// Time step (s).
    pub dt_s: f64,
    /// Simulated time reached (s).
    pub simulated_time_s: f64,
    /// Newton iterations of the relaxation of the start state.
    pub relax_newton_iterations: usize,
    /// Whether that relaxation reached the tolerance.
    pub relax_converged: bool,
    /// Wall-clock time of the start state: the periodic rest solve and the relaxation (s).
    pub relax_seconds: f64,
    /// Newton iterations over all steps.
    pub newton_iterations: usize,
    /// Most Newton iterations in one step.
    pub newton_iterations_max_step: usize,
    /// Cholesky factorizations over all steps.
    pub factorizations: usize,
    /// Steps with a substep whose Newton solve stopped before the tolerance at the finest substep allowed.
    pub unconverged_steps: usize,
    /// Substeps kept over all steps (equal to `steps` when no step was halved).
    pub substeps: usize,
    /// Substep attempts abandoned unconverged and halved.
    pub rejected_substeps: usize,
    /// Largest final residual of a step (dimensionless, force over `k_s`).
    pub max_residual: f64,
    /// Smallest centreline distance between non-excluded yarn segments over all steps (m; `null` in JSON
    /// when no pair came within the contact distance).
    #[serde(with = "infinite_as_null")]
    pub min_distance_m: f64,
    /// The same over the yarn diameter (≥ 0.5 means the yarn surfaces overlap by less than a radius; a
    /// yarn passing through another would reach 0).
    #[serde(with = "infinite_as_null")]
    pub min_distance_over_diameter: f64,
    /// Most segment pairs in contact in one step.
    pub max_contacts: usize,
    /// Most candidate pairs in one step.
    pub max_candidates: usize,
    /// Most vertices on the sphere in one step.
    pub max_sphere_contacts: usize,
    /// Kinetic energy at the end (J).
    pub kinetic_energy_j: f64,
    /// Displacement of the centre of mass from start to end (m).
    pub centre_of_mass_displacement_m: [f64; 3],
    /// Wall-clock time of the run (s).
    pub seconds: f64,
    /// Wall-clock time per step, without the start state (s).
    pub seconds_per_step: f64,
    /// Wall-clock time per Newton iteration of the steps, without the start state (s).
    pub seconds_per_newton_iteration: f64,
    /// Whether the run was stopped early by the caller.
    pub stopped: bool,
    /// Where the Newton solves of the steps spent their time (s), summed over the steps.
    #[serde(default)]
    pub newton_timings: crate::newton::NewtonTimings,
}

/// The model and boundary conditions of a scene.
pub fn set_up(
    scene: &YarnScene,
    pattern: &PeriodicPattern,
) -> Result<(PatchModel, Vec<Prescribed>), SceneError> {
    let [nx, ny] = scene.cells;
    let mut patch = tile(pattern, nx, ny).map_err(|e| SceneError::Input(e.to_string()))?;
    periodic_rest_start(&mut patch, pattern, scene)?;
    let r = pattern.radius;
    let gravity = [0.0, -scene.gravity_m_s2, 0.0];
    let mut sphere = None;
    if scene.scenario == Scenario::DrapeSphere {
        // Flat: (x, y, z) ↦ (x, z, −y), centred on the y axis.
        let rot = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]];
        let turned = transform_patch(&patch, rot, [0.0; 3]);
        let (lo, hi) = bounds(turned.yarns.iter().flat_map(|y| y.positions.iter()));
        let centre = [-(lo[0] + hi[0]) / 2.0, 0.0, -(lo[2] + hi[2]) / 2.0];
        patch = transform_patch(
            &turned,
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            centre,
        );
        let radius = scene
            .sphere_radius_m
            .unwrap_or(0.3 * (hi[0] - lo[0]).min(hi[2] - lo[2]));
        sphere = Some(SphereObstacle {
            center: [0.0, lo[1] - 2.0 * r - radius, 0.0],
            radius,
            stiffness: scene.sphere_stiffness_pa,
        });
    }
    let mut model = PatchModel::new(&patch, &scene.yarn, PatchLoads { gravity, sphere })
        .map_err(|e| SceneError::Input(e.to_string()))?;
    if scene.edges == EdgeFinish::Bonded {
        model.bond_cut_ends();
    }
    let x = model.initial_state();
    let points: Vec<[f64; 3]> = PatchModel::positions(&x);
    let (lo, hi) = bounds(points.iter());
    let (bx, by) = (
        scene.clamp_band_cells * pattern.period[0],
        scene.clamp_band_cells * pattern.period[1],
    );
    let ramp = scene.ramp_time_s.unwrap_or(scene.duration_s);
    let s = scene.strain;
    let (cx, cy) = ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
    let (w, h) = (hi[0] - lo[0], hi[1] - lo[1]);
    let mut prescribed = Vec::new();
    for (v, p) in points.iter().enumerate() {
        let left = p[0] < lo[0] + bx;
        let right = p[0] > hi[0] - bx;
        let bottom = p[1] < lo[1] + by;
        let top = p[1] > hi[1] - by;
        let end = match scene.scenario {
            Scenario::Hang => top.then_some(*p),
            Scenario::StretchUniaxial => {
                if left {
                    Some(*p)
                } else if right {
                    Some([p[0] + s * w, p[1], p[2]])
                } else {
                    None
                }
            }
            Scenario::StretchBiaxial => (left || right || top || bottom).then(|| {
                [
                    cx + (1.0 + s) * (p[0] - cx),
                    cy + (1.0 + s) * (p[1] - cy),
                    p[2],
                ]
            }),
            Scenario::Shear => {
                if bottom {
                    Some(*p)
                } else if top {
                    Some([p[0] + s * h, p[1], p[2]])
                } else {
                    None
                }
            }
            Scenario::DrapeSphere => None,
        };
        if let Some(end) = end {
            prescribed.push(Prescribed {
                vertex: v,
                start: *p,
                end,
                ramp_time: ramp,
            });
        }
    }
    Ok((model, prescribed))
}

/// Replaces the tiled published rest state of `patch` by the periodic cell's own equilibrium at zero strain
/// without gravity, tiled: positions, edge angles, reference directors and reference twists.
fn periodic_rest_start(
    patch: &mut crate::tile::Patch,
    pattern: &PeriodicPattern,
    scene: &YarnScene,
) -> Result<(), SceneError> {
    let mut cell = PeriodicCell::new(pattern, &scene.yarn, [0.0, 0.0, 0.0])
        .map_err(|e| SceneError::Input(e.to_string()))?;
    let mut x = cell.affine_state().to_vector();
    let newton = NewtonParams {
        tolerance: 1e-10,
        max_iterations: 400,
        max_factorizations: 2000,
        trace: false,
        ..NewtonParams::default()
    };
    let report = minimize(&mut cell, &mut x, &newton).map_err(|e| {
        SceneError::Output(format!(
            "the periodic rest state of the pattern failed: {e}"
        ))
    })?;
    if !report.converged {
        // Not converged: start from the published rest state instead (the relaxation absorbs it).
        return Ok(());
    }
    let state = CellState::from_vector(&x);
    cell.rebase_frames(&state, 0.0);
    let (frames, hints) = cell.frames();
    for y in &mut patch.yarns {
        for (i, &(v, c)) in y.source.iter().enumerate() {
            let o = pattern.shift_offset(c);
            let q = state.positions[v];
            y.positions[i] = [q[0] + o[0], q[1] + o[1], q[2] + o[2]];
            if i < y.twist.len() {
                y.twist[i] = state.twist[v];
                y.reference_director[i] = frames[v].director;
            }
            if y.reference_twist[i].is_some() {
                y.reference_twist[i] = Some(hints[v]);
            }
        }
    }
    Ok(())
}

fn bounds<'a>(points: impl Iterator<Item = &'a [f64; 3]>) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

/// Settings of [`run`] beyond the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunParams {
    /// Continue from `out/checkpoint.json` ([`crate::checkpoint`]) when there is one; it must have been
    /// written for the same scene. Without it (or when there is none) the run starts from the beginning
    /// and a checkpoint left in `out` is deleted.
    pub resume: bool,
    /// Wall-clock time between checkpoints during the relaxation of the start state (s); the time steps
    /// write one after every frame.
    pub checkpoint_interval_s: f64,
    /// Wall-clock time between progress reports during the relaxation (s).
    pub relax_progress_interval_s: f64,
}

impl Default for RunParams {
    fn default() -> Self {
        Self {
            resume: false,
            checkpoint_interval_s: 60.0,
            relax_progress_interval_s: 2.0,
        }
    }
}

/// Runs `scene` (its pattern read from `pattern_path`) and writes into `out`: the frame sequence
/// (`sequence.json`, `vertex_sources.npy`, `frames/*.npy`), `yarns.obj` and `yarns.glb` of the last frame,
/// and `result.json`. `progress` is called every few seconds while the start state relaxes
/// (`relaxing: true`) and after every written frame; returning `Break` stops the run there (the outputs are
/// then those of the frames so far, with `stopped: true`; during the relaxation frame 0 is the state
/// reached).
///
/// **Checkpoints** ([`crate::checkpoint`]): `out/checkpoint.json` is written during the relaxation every
/// `params.checkpoint_interval_s` and when stopped, and after every frame; with `params.resume` a run
/// continues from it, writing the same frames as an uninterrupted run. It is deleted when the run
/// completes. `seconds` and `relax_seconds` of the result add up the wall-clock time of every session.
pub fn run(
    scene: &YarnScene,
    pattern_path: &Path,
    out: &Path,
    params: &RunParams,
    mut progress: impl FnMut(&FrameProgress) -> ControlFlow<()>,
) -> Result<YarnSimulationResult, SceneError> {
    let start = Instant::now();
    for (name, v) in [
        ("checkpoint interval", params.checkpoint_interval_s),
        ("progress interval", params.relax_progress_interval_s),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(SceneError::Input(format!("{name} {v} s must be ≥ 0")));
        }
    }
    let pattern =
        PeriodicPattern::read(pattern_path).map_err(|e| SceneError::Input(e.to_string()))?;
    let (model, prescribed) = set_up(scene, &pattern)?;
    let sim_params = scene.time_stepping();
    let prescribed_vertices = prescribed.len();
    let mut sim = ImplicitEuler::new(model, sim_params, prescribed)?;
    let saved = if params.resume {
        RunCheckpoint::read(out)?
    } else {
        crate::checkpoint::remove(out)?;
        None
    };
    if let Some(c) = &saved {
        c.check_scene(scene, out)?;
    }
    let seconds_before = saved.as_ref().map_or(0.0, |c| c.seconds);
    let elapsed = || seconds_before + start.elapsed().as_secs_f64();
    let diameter = 2.0 * sim.model().radius();
    let (steps, per_frame) = scene.steps();
    let frame_count = 1 + steps.div_ceil(per_frame);
    let bad_state = |e: StepError| {
        SceneError::Input(format!(
            "{}: {e}; run without --resume to start again",
            crate::checkpoint::path(out).display()
        ))
    };

    // The start state: relaxed (resumed when the checkpoint is of the relaxation), unless the checkpoint
    // is of the steps.
    let mut relax_iterations = 0;
    let mut relax_seconds_before = 0.0;
    let mut stepping = None;
    match saved {
        Some(c) if c.phase == Phase::Relaxing => {
            relax_iterations = c.relax_newton_iterations;
            relax_seconds_before = c.relax_seconds;
            sim.restore_state(c.state).map_err(bad_state)?;
        }
        Some(c) => stepping = Some(c),
        None => {}
    }
    let mut relax_converged = false;
    let mut stopped = false;
    let mut relax_seconds = relax_seconds_before;
    if stepping.is_none() {
        let remaining = scene.relax_max_iterations.saturating_sub(relax_iterations);
        if remaining > 0 {
            let relax_start = Instant::now();
            let interval = params.checkpoint_interval_s;
            let mut last_checkpoint = Instant::now();
            let mut last_report = Instant::now();
            let mut failure = None;
            let zero = vec![0.0; sim.state().len()];
            let done_before = relax_iterations;
            let mut done = done_before;
            let min_distance = sim.model().min_distance(sim.state());
            let report = sim.relax_observed(
                &NewtonParams {
                    max_iterations: remaining,
                    max_factorizations: 5 * remaining,
                    ..scene.newton
                },
                &mut |model: &PatchModel, x: &[f64]| {
                    done += 1;
                    let mut flow = ControlFlow::Continue(());
                    if last_report.elapsed().as_secs_f64() >= params.relax_progress_interval_s {
                        last_report = Instant::now();
                        flow = progress(&FrameProgress {
                            frame: 0,
                            frame_count,
                            time_s: 0.0,
                            newton_iterations: 0,
                            min_distance_over_diameter: min_distance / diameter,
                            relaxing: true,
                            relax_newton_iterations: done,
                        });
                    }
                    if flow.is_break() || last_checkpoint.elapsed().as_secs_f64() >= interval {
                        last_checkpoint = Instant::now();
                        let checkpoint = RunCheckpoint {
                            format: crate::checkpoint::FORMAT.into(),
                            version: crate::checkpoint::VERSION,
                            scene: scene.clone(),
                            phase: Phase::Relaxing,
                            relax_newton_iterations: done,
                            steps: 0,
                            result: None,
                            centre_of_mass_start_m: [0.0; 3],
                            seconds: elapsed(),
                            relax_seconds: relax_seconds_before
                                + relax_start.elapsed().as_secs_f64(),
                            state: ImplicitEulerState {
                                time: 0.0,
                                halvings: 0,
                                shift: 0.0,
                                x: x.to_vec(),
                                v: zero.clone(),
                                frames: model.frames_snapshot(),
                            },
                        };
                        if let Err(e) = checkpoint.write(out) {
                            failure = Some(e);
                            return ControlFlow::Break(());
                        }
                    }
                    flow
                },
            )?;
            if let Some(e) = failure {
                return Err(e.into());
            }
            stopped = report.stop == crate::newton::StopReason::Cancelled;
            relax_iterations = done_before + report.iterations;
            relax_converged = report.converged;
        }
        // This session's set-up (the periodic rest solve) counts with the relaxation.
        relax_seconds = relax_seconds_before + start.elapsed().as_secs_f64();
    }

    let model = sim.model().clone();
    let mut result;
    let mut writer;
    let com0;
    let mut step;
    if let Some(c) = stepping {
        result = c
            .result
            .expect("a stepping checkpoint holds the result (checked when read)");
        step = c.steps;
        com0 = c.centre_of_mass_start_m;
        sim.restore_state(c.state).map_err(bad_state)?;
        writer = SequenceWriter::resume(out, result.frames)?;
    } else {
        let sources: Vec<(usize, [i32; 2])> = model
            .patch()
            .yarns
            .iter()
            .flat_map(|y| y.source.iter().copied())
            .collect();
        let meta = SequenceMeta {
            format: FORMAT.into(),
            version: VERSION,
            pattern: pattern_path.display().to_string(),
            cells: scene.cells,
            scenario: scene.scenario.name().into(),
            units: Units::default(),
            yarn_radius_m: model.radius(),
            linear_density_kg_per_m: model.linear_density(),
            dt_s: scene.dt_s,
            frame_interval_s: scene.dt_s * per_frame as f64,
            vertex_count: model.vertex_count(),
            frame_count: 0,
            yarns: model
                .yarn_ranges()
                .iter()
                .zip(&model.patch().yarns)
                .map(|(r, y)| YarnRange {
                    first_vertex: r.start,
                    vertex_count: r.len(),
                    closed: y.closed,
                })
                .collect(),
            frames: vec![],
        };
        writer = SequenceWriter::create(out, meta, &sources)?;
        writer.push(0.0, sim.state())?;
        step = 0;
        com0 = centre_of_mass(&model, sim.state());
        let min_distance_m = model.min_distance(sim.state());
        result = YarnSimulationResult {
            scenario: scene.scenario.name().into(),
            pattern: pattern_path.display().to_string(),
            cells: scene.cells,
            yarns: model.patch().yarns.len(),
            vertices: model.vertex_count(),
            dofs: model.dof_count(),
            prescribed_vertices,
            edges: scene.edges,
            bonds: model.bonds().count(),
            yarn_radius_m: model.radius(),
            mass_kg: model.masses().iter().sum(),
            frames: 1,
            steps: 0,
            dt_s: scene.dt_s,
            simulated_time_s: 0.0,
            relax_newton_iterations: relax_iterations,
            relax_converged,
            relax_seconds,
            newton_iterations: 0,
            newton_iterations_max_step: 0,
            factorizations: 0,
            unconverged_steps: 0,
            substeps: 0,
            rejected_substeps: 0,
            max_residual: 0.0,
            min_distance_m,
            min_distance_over_diameter: min_distance_m / diameter,
            max_contacts: 0,
            max_candidates: 0,
            max_sphere_contacts: 0,
            kinetic_energy_j: 0.0,
            centre_of_mass_displacement_m: [0.0; 3],
            seconds: 0.0,
            seconds_per_step: 0.0,
            seconds_per_newton_iteration: 0.0,
            stopped: false,
            newton_timings: Default::default(),
        };
    }
    let checkpoint = |result: &YarnSimulationResult, step: usize, sim: &ImplicitEuler| {
        RunCheckpoint {
            format: crate::checkpoint::FORMAT.into(),
            version: crate::checkpoint::VERSION,
            scene: scene.clone(),
            phase: Phase::Stepping,
            relax_newton_iterations: result.relax_newton_iterations,
            steps: step,
            result: Some(result.clone()),
            centre_of_mass_start_m: com0,
            seconds: elapsed(),
            relax_seconds: result.relax_seconds,
            state: sim.save_state(),
        }
        .write(out)
    };
    let report = |result: &YarnSimulationResult| FrameProgress {
        frame: result.frames - 1,
        frame_count,
        time_s: result.simulated_time_s,
        newton_iterations: result.newton_iterations,
        min_distance_over_diameter: result.min_distance_m / diameter,
        relaxing: false,
        relax_newton_iterations: result.relax_newton_iterations,
    };
    if !stopped {
        // Frame 0 written, the steps start from here (a resumed run: its checkpoint's frame); report it.
        if step == 0 {
            checkpoint(&result, step, &sim)?;
        }
        stopped = progress(&report(&result)).is_break();
    }
    while !stopped && step < steps {
        let r = sim.step()?;
        step += 1;
        result.steps = step;
        result.simulated_time_s = r.time;
        result.newton_iterations += r.newton.iterations;
        result.newton_iterations_max_step =
            result.newton_iterations_max_step.max(r.newton.iterations);
        result.factorizations += r.newton.factorizations;
        result.newton_timings.add(&r.newton.timings);
        result.unconverged_steps += usize::from(!r.newton.converged);
        result.substeps += r.substeps;
        result.rejected_substeps += r.rejected_substeps;
        result.max_residual = result.max_residual.max(r.newton.residual);
        result.min_distance_m = result.min_distance_m.min(r.min_distance);
        result.max_contacts = result.max_contacts.max(r.contacts);
        result.max_candidates = result.max_candidates.max(r.candidates);
        result.max_sphere_contacts = result.max_sphere_contacts.max(r.sphere_contacts);
        if step % per_frame == 0 {
            writer.push(r.time, sim.state())?;
            result.frames += 1;
            result.min_distance_over_diameter = result.min_distance_m / diameter;
            if step < steps {
                checkpoint(&result, step, &sim)?;
            }
            stopped = progress(&report(&result)).is_break();
        }
    }
    if !stopped && step % per_frame != 0 {
        writer.push(sim.time(), sim.state())?;
        result.frames += 1;
        result.min_distance_over_diameter = result.min_distance_m / diameter;
        let _ = progress(&report(&result));
    }
    result.stopped = stopped;
    result.min_distance_over_diameter = result.min_distance_m / diameter;
    result.kinetic_energy_j = sim.kinetic_energy();
    let com1 = centre_of_mass(&model, sim.state());
    result.centre_of_mass_displacement_m = std::array::from_fn(|k| com1[k] - com0[k]);
    write_shapes(&model, sim.state(), out)?;
    result.seconds = elapsed();
    let stepping = result.seconds - result.relax_seconds;
    result.seconds_per_step = stepping / result.steps.max(1) as f64;
    result.seconds_per_newton_iteration = stepping / result.newton_iterations.max(1) as f64;
    let path = out.join("result.json");
    let text =
        serde_json::to_string_pretty(&result).map_err(|e| SceneError::Output(e.to_string()))?;
    std::fs::write(&path, text)
        .map_err(|e| SceneError::Output(format!("cannot write {}: {e}", path.display())))?;
    if !stopped {
        crate::checkpoint::remove(out)?;
    }
    Ok(result)
}

/// Serde for a distance that is infinite when nothing was near: `null` in JSON.
mod infinite_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else {
            s.serialize_none()
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
    }
}

fn centre_of_mass(model: &PatchModel, x: &[f64]) -> [f64; 3] {
    let m: f64 = model.masses().iter().sum();
    std::array::from_fn(|k| {
        model
            .masses()
            .iter()
            .zip(x.chunks(4))
            .map(|(mi, c)| mi * c[k])
            .sum::<f64>()
            / m
    })
}

/// Writes `yarns.obj` (polylines) and `yarns.glb` (tubes) of the state `x` into `out`.
pub fn write_shapes(model: &PatchModel, x: &[f64], out: &Path) -> Result<(), SceneError> {
    let points = PatchModel::positions(x);
    let mut patch = model.patch().clone();
    for (y, range) in patch.yarns.iter_mut().zip(model.yarn_ranges()) {
        y.positions = points[range].to_vec();
    }
    let obj = out.join("yarns.obj");
    patch
        .write_obj(&obj)
        .map_err(|e| SceneError::Output(format!("cannot write {}: {e}", obj.display())))?;
    let lines: Vec<(&[[f64; 3]], bool)> = patch
        .yarns
        .iter()
        .map(|y| (y.positions.as_slice(), y.closed))
        .collect();
    let glb = out.join("yarns.glb");
    let bytes = tubes(&lines, patch.radius, 8)
        .to_glb("yarns")
        .map_err(|e| SceneError::Output(format!("cannot encode {}: {e}", glb.display())))?;
    std::fs::write(&glb, bytes)
        .map_err(|e| SceneError::Output(format!("cannot write {}: {e}", glb.display())))
}

#[cfg(test)]
mod tests;
