//! The checkpoint of a yarn simulation run (`DIR/checkpoint.json`), so that a run stopped part-way (by a
//! crash, a shutdown or its caller) continues where it was instead of from its start (`skintight knit
//! simulate-yarn SCENE --out DIR --resume`; the `yarn_simulate` job run again after a server restart). Why: a
//! large patch (the 16 × 16-cell stockinette hang of issue 19) needs longer than a worker may live
//! (docs/BENCHMARKS.md).
//!
//! [`YarnRunCheckpoint`] holds the scene it belongs to, the phase — the relaxation of the start state or
//! the time steps — with the Newton iterations and steps done, the result's counters so far and the
//! stepper's whole evolving state (`skintight_knit::implicit_euler::ImplicitEulerState`: time, step
//! halvings, the Levenberg–Marquardt shift, unknowns, velocities, rod frames and reference-twist hints). The
//! model, the boundary conditions and the bonds are rebuilt from the scene, which is deterministic. Numbers
//! are written in shortest round-trip form and read back exactly (serde_json's `float_roundtrip`), so a
//! resumed run starts from exactly the saved state; its frames then agree with an uninterrupted run's to
//! rounding, not bit for bit, because the resumed Newton solver analyzes its sparsity afresh (the
//! uninterrupted one may factor on a union of earlier patterns, which orders the sums differently). A
//! relaxation resumed part-way restarts its Newton loop at the saved state (the shift from 0), so it
//! follows a slightly different path to the same kind of equilibrium.
//!
//! The run (`run.rs`) writes one during the relaxation every
//! [`super::YarnRunParams::checkpoint_interval_s`] of wall-clock time and when stopped, and one after every
//! frame of the steps (with the frame files, so the sequence on disk and the checkpoint agree); it deletes
//! it when the run completes. A file is replaced atomically (written beside, then renamed), so a crash while
//! writing leaves the previous checkpoint. The format is in docs/OUTPUTS.md.
//!
//! Units: SI (s, m, rad); wall-clock times in s.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use skintight_knit::implicit_euler::ImplicitEulerState;

use super::error::YarnSceneError;
use super::output::YarnSimulationResult;
use super::spec::YarnScene;

/// The checkpoint's file name in a run's output folder.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";
/// The `format` value of a checkpoint.
pub const CHECKPOINT_FORMAT: &str = "skintight-yarn-checkpoint";
/// The `version` of this layout.
pub const CHECKPOINT_VERSION: u32 = 1;

/// Where a yarn run was.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum YarnRunPhase {
    /// Relaxing the start state (no frame written yet).
    Relaxing,
    /// Time stepping, after a written frame.
    Stepping,
}

/// A resumable snapshot of a yarn run (`DIR/checkpoint.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
// The name serde's messages about a malformed file give, as before the type moved here.
#[serde(rename = "Checkpoint")]
pub struct YarnRunCheckpoint {
    /// `"skintight-yarn-checkpoint"`.
    pub format: String,
    /// [`CHECKPOINT_VERSION`].
    pub version: u32,
    /// The scene of the run (a resume must give the same).
    pub scene: YarnScene,
    /// Relaxing or stepping.
    pub phase: YarnRunPhase,
    /// Newton iterations of the relaxation done.
    pub relax_newton_iterations: usize,
    /// Time steps done.
    pub steps: usize,
    /// The run's result so far (counters, extremes, frames written); `None` while relaxing.
    pub result: Option<YarnSimulationResult>,
    /// Centre of mass at frame 0 (m).
    pub centre_of_mass_start_m: [f64; 3],
    /// Wall-clock time of the run before this checkpoint, over every session (s).
    pub seconds: f64,
    /// Wall-clock time of the start state (periodic rest solve and relaxation) so far (s).
    pub relax_seconds: f64,
    /// The stepper's state.
    pub state: ImplicitEulerState,
}

impl YarnRunCheckpoint {
    /// The checkpoint file of the output folder `dir`.
    pub fn path(dir: &Path) -> PathBuf {
        dir.join(CHECKPOINT_FILE)
    }

    /// Deletes `dir/checkpoint.json` if there is one.
    pub fn remove(dir: &Path) -> Result<(), YarnSceneError> {
        let path = Self::path(dir);
        match std::fs::remove_file(&path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(YarnSceneError::Output(
                format!("cannot delete {}: {e}", path.display()),
            )),
            _ => Ok(()),
        }
    }

    /// Writes `dir/checkpoint.json` atomically (beside, then renamed over the old one).
    pub fn write(&self, dir: &Path) -> Result<(), YarnSceneError> {
        let path = Self::path(dir);
        let tmp = dir.join(format!("{CHECKPOINT_FILE}.tmp"));
        let text = serde_json::to_string(self).map_err(|e| {
            YarnSceneError::Output(format!(
                "cannot encode the checkpoint {}: {e}",
                path.display()
            ))
        })?;
        std::fs::create_dir_all(dir)
            .and_then(|()| std::fs::write(&tmp, text))
            .and_then(|()| std::fs::rename(&tmp, &path))
            .map_err(|e| YarnSceneError::Output(format!("cannot write {}: {e}", path.display())))
    }

    /// Reads `dir/checkpoint.json`: `None` when there is none; an error naming the file when it cannot be
    /// read or is not a checkpoint of this version.
    pub fn read(dir: &Path) -> Result<Option<Self>, YarnSceneError> {
        let path = Self::path(dir);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => {
                return Err(YarnSceneError::Input(format!(
                    "cannot read {}: {e}",
                    path.display()
                )));
            }
        };
        let bad = |problem: String| {
            YarnSceneError::Input(format!(
                "{} is not a checkpoint this version can resume ({problem}); delete it to start the \
                 run again",
                path.display()
            ))
        };
        let checkpoint: Self = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
        if checkpoint.format != CHECKPOINT_FORMAT || checkpoint.version != CHECKPOINT_VERSION {
            return Err(bad(format!(
                "format {} version {}, expected {CHECKPOINT_FORMAT} version {CHECKPOINT_VERSION}",
                checkpoint.format, checkpoint.version
            )));
        }
        if (checkpoint.phase == YarnRunPhase::Stepping) != checkpoint.result.is_some() {
            return Err(bad(
                "a stepping checkpoint needs the result so far, a relaxing one none".into(),
            ));
        }
        Ok(Some(checkpoint))
    }

    /// Checks that this checkpoint was written for `scene`: the error names the file and says what to do.
    pub fn check_scene(&self, scene: &YarnScene, dir: &Path) -> Result<(), YarnSceneError> {
        if self.scene != *scene {
            return Err(YarnSceneError::Input(format!(
                "{} was written for another scene; run without --resume (or delete it) to start again",
                Self::path(dir).display()
            )));
        }
        Ok(())
    }
}
