//! Checkpoints of a design job: after every design iteration, what [`super::run_design_from`] needs to go
//! on exactly where it was — the optimization run's own checkpoint
//! ([`skintight_design::DesignCheckpoint`]: optimizer memory, level, best design, the last equilibrium
//! solve to replay), what the runs before the last remesh gathered, and the remeshes to replay.
//!
//! Stored as bytes: an 8-byte magic with the format version, then the [`RunCheckpoint`] in postcard (serde,
//! every `f64` bit for bit). A checkpoint of another version, or bytes that are not one, read as `None`:
//! the job starts afresh.

use skintight_design::{DesignCheckpoint, DesignIteration};
use skintight_physics::ClothOnBodyState;

/// The first bytes of a design checkpoint (format version 1).
const MAGIC: &[u8; 8] = b"STDES\x001\x00";

/// What the optimization runs before the last remesh gathered.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Gathered {
    /// The objective of the initial design (units of the terms).
    pub initial_objective: f64,
    /// Their accepted iterations.
    pub iterations: usize,
    /// Their history, numbered across runs.
    pub history: Vec<DesignIteration>,
}

/// A remesh to replay: the run that asked for it ended with the best boundary parameters (m) and their
/// equilibrium as found; its final evaluation started from that state.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RemeshRecord {
    /// The best boundary parameters of the run (m), in the map before the remesh.
    pub parameters: Vec<f64>,
    /// Their equilibrium as the run found it.
    pub best_state: ClothOnBodyState,
}

/// A design job's checkpoint (see the module documentation).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunCheckpoint {
    /// The optimization run in progress.
    pub design: DesignCheckpoint,
    /// What the runs before the last remesh gathered (`None` before the first remesh).
    pub gathered: Option<Gathered>,
    /// The coarse-to-fine level the run in progress started at.
    pub level: usize,
    /// Remeshes so far, the seconds they took, and whether remeshing is still on.
    pub remeshes: usize,
    /// See `remeshes`.
    pub remesh_seconds: f64,
    /// See `remeshes`.
    pub remesh_on: bool,
    /// The remeshes, in order.
    pub remesh_log: Vec<RemeshRecord>,
    /// Seconds from the design's start to the run in progress's start.
    pub offset_seconds: f64,
    /// Seconds since the design started.
    pub seconds: f64,
}

impl RunCheckpoint {
    /// The design iteration it was taken at (numbered across remeshes).
    pub fn iteration(&self) -> usize {
        let run = &self.design;
        let before = self.gathered.as_ref().map_or(0, |g| g.iterations);
        before + run.iterations_before + run.optimizer.iteration()
    }

    /// The bytes to store.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        // Serializing plain data into a Vec cannot fail.
        out.extend(postcard::to_stdvec(self).unwrap_or_default());
        out
    }

    /// Reads [`RunCheckpoint::encode`]'s bytes; `None` when they are not a checkpoint of this version.
    pub fn decode(data: &[u8]) -> Option<Self> {
        let body = data.strip_prefix(MAGIC.as_slice())?;
        postcard::from_bytes(body).ok()
    }
}
