//! Checkpoints of a yarn simulation run, so that a run stopped part-way (by a crash, a shutdown or its
//! caller) continues where it was instead of from its start (`skintight knit simulate-yarn SCENE --out DIR
//! --resume`; the `yarn_simulate` job run again after a server restart). Why: the 16 × 16-cell stockinette
//! hang of issue 19 needs hours on a 2-core machine (docs/BENCHMARKS.md), longer than a worker may live.
//!
//! `DIR/checkpoint.json` ([`Checkpoint`]) holds the scene it belongs to, the phase — the relaxation of the
//! start state or the time steps — with the Newton iterations and steps done, the result's counters so far
//! and the stepper's whole evolving state ([`ImplicitEulerState`]: time, step halvings, the
//! Levenberg–Marquardt shift, unknowns, velocities, rod frames and reference-twist hints). The model, the
//! boundary conditions and the bonds are rebuilt from the scene, which is deterministic. Numbers are
//! written in shortest round-trip form and read back exactly (serde_json's `float_roundtrip`), so a resumed
//! run starts from exactly the saved state; its frames then agree with an uninterrupted run's to rounding,
//! not bit for bit, because the resumed Newton solver analyzes its sparsity afresh (the uninterrupted one
//! may factor on a union of earlier patterns, which orders the sums differently). A relaxation resumed
//! part-way restarts its Newton loop at the saved state (the shift from 0), so it follows a slightly
//! different path to the same kind of equilibrium.
//!
//! [`crate::yarn_scene::run`] writes one during the relaxation every
//! [`crate::yarn_scene::RunParams::checkpoint_interval_s`] of wall-clock time and when stopped, and one
//! after every frame of the steps (with the frame files, so the sequence on disk and the checkpoint
//! agree); it deletes it when the run completes. A file is replaced atomically (written beside, then
//! renamed), so a crash while writing leaves the previous checkpoint.
//!
//! Units: SI (s, m, rad); wall-clock times in s.

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::implicit_euler::ImplicitEulerState;

/// The checkpoint's file name in a run's output folder.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";
/// The `format` value of a checkpoint.
pub const FORMAT: &str = "skintight-yarn-checkpoint";
/// The `version` of this layout.
pub const VERSION: u32 = 1;

/// Where a run was.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Relaxing the start state (no frame written yet).
    Relaxing,
    /// Time stepping, after a written frame.
    Stepping,
}

/// A resumable snapshot of a run (`DIR/checkpoint.json`) of the scene type `S` with the result type `R`
/// (for `skintight knit simulate-yarn`: [`crate::yarn_scene::RunCheckpoint`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint<S, R> {
    /// `"skintight-yarn-checkpoint"`.
    pub format: String,
    /// [`VERSION`].
    pub version: u32,
    /// The scene of the run (a resume must give the same).
    pub scene: S,
    /// Relaxing or stepping.
    pub phase: Phase,
    /// Newton iterations of the relaxation done.
    pub relax_newton_iterations: usize,
    /// Time steps done.
    pub steps: usize,
    /// The run's result so far (counters, extremes, frames written); `None` while relaxing.
    pub result: Option<R>,
    /// Centre of mass at frame 0 (m).
    pub centre_of_mass_start_m: [f64; 3],
    /// Wall-clock time of the run before this checkpoint, over every session (s).
    pub seconds: f64,
    /// Wall-clock time of the start state (periodic rest solve and relaxation) so far (s).
    pub relax_seconds: f64,
    /// The stepper's state.
    pub state: ImplicitEulerState,
}

/// Errors reading or writing a checkpoint; each message names the file and says what to do.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CheckpointError {
    /// The checkpoint cannot be read or resumed (a problem with its input).
    #[error("{0}")]
    Unusable(String),
    /// It cannot be written or deleted.
    #[error("{0}")]
    Write(String),
}

/// The checkpoint file of the output folder `dir`.
pub fn path(dir: &Path) -> PathBuf {
    dir.join(CHECKPOINT_FILE)
}

/// Deletes `dir/checkpoint.json` if there is one.
pub fn remove(dir: &Path) -> Result<(), CheckpointError> {
    let path = path(dir);
    match std::fs::remove_file(&path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(CheckpointError::Write(format!(
            "cannot delete {}: {e}",
            path.display()
        ))),
        _ => Ok(()),
    }
}

impl<S, R> Checkpoint<S, R>
where
    S: Serialize + DeserializeOwned + PartialEq,
    R: Serialize + DeserializeOwned,
{
    /// Writes `dir/checkpoint.json` atomically (beside, then renamed over the old one).
    pub fn write(&self, dir: &Path) -> Result<(), CheckpointError> {
        let path = path(dir);
        let tmp = dir.join(format!("{CHECKPOINT_FILE}.tmp"));
        let text = serde_json::to_string(self).map_err(|e| {
            CheckpointError::Write(format!(
                "cannot encode the checkpoint {}: {e}",
                path.display()
            ))
        })?;
        std::fs::create_dir_all(dir)
            .and_then(|()| std::fs::write(&tmp, text))
            .and_then(|()| std::fs::rename(&tmp, &path))
            .map_err(|e| CheckpointError::Write(format!("cannot write {}: {e}", path.display())))
    }

    /// Reads `dir/checkpoint.json`: `None` when there is none; an error naming the file when it cannot be
    /// read or is not a checkpoint of this version.
    pub fn read(dir: &Path) -> Result<Option<Self>, CheckpointError> {
        let path = path(dir);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => {
                return Err(CheckpointError::Unusable(format!(
                    "cannot read {}: {e}",
                    path.display()
                )));
            }
        };
        let bad = |problem: String| {
            CheckpointError::Unusable(format!(
                "{} is not a checkpoint this version can resume ({problem}); delete it to start the \
                 run again",
                path.display()
            ))
        };
        let checkpoint: Self = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
        if checkpoint.format != FORMAT || checkpoint.version != VERSION {
            return Err(bad(format!(
                "format {} version {}, expected {FORMAT} version {VERSION}",
                checkpoint.format, checkpoint.version
            )));
        }
        if (checkpoint.phase == Phase::Stepping) != checkpoint.result.is_some() {
            return Err(bad(
                "a stepping checkpoint needs the result so far, a relaxing one none".into(),
            ));
        }
        Ok(Some(checkpoint))
    }

    /// Checks that this checkpoint was written for `scene`: the error names the file and says what to do.
    pub fn check_scene(&self, scene: &S, dir: &Path) -> Result<(), CheckpointError> {
        if self.scene != *scene {
            return Err(CheckpointError::Unusable(format!(
                "{} was written for another scene; run without --resume (or delete it) to start again",
                path(dir).display()
            )));
        }
        Ok(())
    }
}
