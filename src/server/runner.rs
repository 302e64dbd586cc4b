//! Pluggable job kinds: the [`JobRunner`] trait, the [`JobRegistry`] of known kinds, and the
//! [`JobContext`] through which a running job reports iterations, observes cancellation and checkpoints.
//!
//! A runner runs on a blocking worker thread, never on the async runtime. It must call
//! [`JobContext::iteration`] once per iteration and return the error it gets (`?`), which is how
//! cancellation, the time limit and server shutdown reach it within one iteration.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use serde_json::Value;
use sqlx::SqlitePool;
use tokio::runtime::Handle;

use super::queue;

/// A spec rejected at submission: `field` is a path inside the spec (`iterations`, `body.scale`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldError {
    pub field: String,
    pub message: String,
}

impl FieldError {
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        FieldError {
            field: field.into(),
            message: message.into(),
        }
    }
}

/// A reference from a spec to an uploaded asset: `field` is its path in the spec.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AssetRef {
    pub field: String,
    pub id: String,
}

/// An uploaded asset handed to a runner.
#[derive(Debug, Clone)]
pub struct Asset {
    pub id: String,
    /// `obj`, `stl`, `ply` or `off`.
    pub format: String,
    pub sha256: String,
    pub data: Vec<u8>,
}

/// The assets a job's spec refers to, by the spec field that names them.
#[derive(Debug, Clone, Default)]
pub struct Assets {
    pub by_field: BTreeMap<String, Asset>,
}

impl Assets {
    pub fn get(&self, field: &str) -> Option<&Asset> {
        self.by_field.get(field)
    }
}

/// A named output of a job.
#[derive(Debug, Clone)]
pub struct Artifact {
    /// File-like name, `[A-Za-z0-9._-]+`, unique within the job.
    pub name: String,
    pub content_type: String,
    pub data: Vec<u8>,
}

/// What a finished job produced.
#[derive(Debug, Clone, Default)]
pub struct JobOutput {
    pub artifacts: Vec<Artifact>,
    /// A small JSON summary shown with the job.
    pub summary: Value,
}

/// How a job run ended without output.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JobError {
    /// The client cancelled the job.
    #[error("the job was cancelled")]
    Cancelled,
    /// The job ran past the configured time limit.
    #[error("the job ran past its time limit of {limit_s} s")]
    TimedOut { limit_s: u64 },
    /// The server is shutting down (or lost the job's lease); the job is re-queued and resumes from its last
    /// checkpoint later.
    #[error("the job was interrupted and will be resumed")]
    Interrupted,
    /// The inputs turned out unusable while running (e.g. a mesh that does not parse).
    #[error("invalid input {field}: {message}")]
    Invalid { field: String, message: String },
    /// The computation failed.
    #[error("{0}")]
    Failed(String),
}

/// One job kind.
pub trait JobRunner: Send + Sync + 'static {
    /// The kind's name as used in `POST /v1/jobs {"kind": …}`.
    fn kind(&self) -> &'static str;

    /// Checks a spec at submission (before anything is queued). Bad specs are answered with 422 naming
    /// `spec.<field>`.
    fn validate(&self, spec: &Value) -> Result<(), FieldError>;

    /// The assets the (validated) spec refers to; each must exist for the submitting tenant.
    fn assets(&self, _spec: &Value) -> Vec<AssetRef> {
        Vec::new()
    }

    /// Checks, at submission, the assets the spec refers to (each known to exist for the tenant): that a
    /// mesh can be read and serve its purpose, say. Runs on a blocking thread; an error answers 422 naming
    /// `spec.<field>`, so a job whose input cannot work is never queued.
    fn check_assets(&self, _spec: &Value, _assets: &Assets) -> Result<(), FieldError> {
        Ok(())
    }

    /// Runs the job on a blocking thread. Deterministic kinds that checkpoint resume from
    /// [`JobContext::last_checkpoint`] after a restart.
    fn run(
        &self,
        spec: &Value,
        assets: &Assets,
        ctx: &mut JobContext,
    ) -> Result<JobOutput, JobError>;
}

/// The job kinds a server knows.
#[derive(Clone, Default)]
pub struct JobRegistry {
    runners: HashMap<&'static str, Arc<dyn JobRunner>>,
}

impl JobRegistry {
    pub fn new() -> Self {
        JobRegistry::default()
    }

    /// Adds a kind (replacing one of the same name).
    pub fn register(&mut self, runner: Arc<dyn JobRunner>) -> &mut Self {
        self.runners.insert(runner.kind(), runner);
        self
    }

    pub fn get(&self, kind: &str) -> Option<&Arc<dyn JobRunner>> {
        self.runners.get(kind)
    }

    /// Known kinds, sorted.
    pub fn kinds(&self) -> Vec<&'static str> {
        let mut k: Vec<_> = self.runners.keys().copied().collect();
        k.sort_unstable();
        k
    }
}

/// A saved intermediate state: the iteration it was taken after and the runner's bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Checkpoint {
    pub iteration: u64,
    pub data: Vec<u8>,
}

/// Why a running job should stop, shared between the worker, the cancel route and shutdown.
#[derive(Debug, Default)]
pub struct StopFlags {
    pub cancel: AtomicBool,
    pub shutdown: AtomicBool,
}

/// The running job's window onto the server. Lives on the blocking worker thread.
pub struct JobContext {
    pub(crate) job_id: String,
    pub(crate) owner: String,
    pub(crate) pool: SqlitePool,
    pub(crate) handle: Handle,
    pub(crate) flags: Arc<StopFlags>,
    pub(crate) deadline: Instant,
    pub(crate) time_limit_s: u64,
    pub(crate) events: Arc<tokio::sync::watch::Sender<u64>>,
    /// Iterations done so far in this job (counting those before the checkpoint resumed from).
    pub(crate) iteration: u64,
    /// Highest iteration already announced as an event (from an earlier attempt).
    pub(crate) announced: u64,
    pub(crate) checkpoint: Option<Checkpoint>,
    /// Iterations done in this run.
    pub(crate) run_iterations: u64,
    pub(crate) progress: Option<f64>,
}

impl JobContext {
    /// Records one finished iteration with its metrics (an `iteration` event and the job's last metrics),
    /// then tells the runner whether to go on: `Err` when the job was cancelled, ran past its time limit or
    /// the server is shutting down. Iterations re-run after resuming from a checkpoint are not announced a
    /// second time, so a job's events never repeat an iteration number.
    pub fn iteration(&mut self, metrics: Value) -> Result<(), JobError> {
        self.iteration += 1;
        self.run_iterations += 1;
        if self.iteration > self.announced {
            let res = self.handle.block_on(queue::record_iteration(
                &self.pool,
                &self.job_id,
                &self.owner,
                self.iteration,
                self.progress,
                &metrics,
            ));
            match res {
                Ok(Some(cancel_requested)) => {
                    self.announced = self.iteration;
                    if cancel_requested {
                        self.flags.cancel.store(true, Ordering::SeqCst);
                    }
                    self.events.send_modify(|v| *v += 1);
                }
                // The job is no longer ours (its lease was taken away): stop without touching it.
                Ok(None) => return Err(JobError::Interrupted),
                Err(e) => {
                    tracing::error!(job = %self.job_id, error = %e, "recording an iteration failed");
                    return Err(JobError::Interrupted);
                }
            }
        }
        self.should_stop()
    }

    /// `Err` when the job should stop now (cancelled, out of time, shutting down).
    pub fn should_stop(&self) -> Result<(), JobError> {
        if self.flags.cancel.load(Ordering::SeqCst) {
            Err(JobError::Cancelled)
        } else if self.flags.shutdown.load(Ordering::SeqCst) {
            Err(JobError::Interrupted)
        } else if Instant::now() >= self.deadline {
            Err(JobError::TimedOut {
                limit_s: self.time_limit_s,
            })
        } else {
            Ok(())
        }
    }

    /// A poll for [`Self::should_stop`] that does not borrow the context (for solvers that check often,
    /// between the iterations they report).
    pub fn stop_poll(&self) -> impl Fn() -> bool + Send + Sync + 'static {
        let flags = self.flags.clone();
        let deadline = self.deadline;
        move || {
            flags.cancel.load(Ordering::SeqCst)
                || flags.shutdown.load(Ordering::SeqCst)
                || Instant::now() >= deadline
        }
    }

    /// Whether the client cancelled the job.
    pub fn is_cancelled(&self) -> bool {
        self.flags.cancel.load(Ordering::SeqCst)
    }

    /// The id of the job being run.
    pub fn job_id(&self) -> &str {
        &self.job_id
    }

    /// The number of iterations recorded so far.
    pub fn iterations(&self) -> u64 {
        self.iteration
    }

    /// Sets the fraction done, in [0, 1], reported with the next iteration.
    pub fn progress(&mut self, fraction: f64) {
        if fraction.is_finite() {
            self.progress = Some(fraction.clamp(0.0, 1.0));
        }
    }

    /// Durably saves the runner's state after the current iteration; a job interrupted later resumes from
    /// here (see [`JobContext::last_checkpoint`]).
    pub fn checkpoint(&mut self, data: Vec<u8>) -> Result<(), JobError> {
        let saved = self
            .handle
            .block_on(queue::save_checkpoint(
                &self.pool,
                &self.job_id,
                &self.owner,
                self.iteration,
                &data,
            ))
            .map_err(|e| {
                tracing::error!(job = %self.job_id, error = %e, "saving a checkpoint failed");
                JobError::Interrupted
            })?;
        if !saved {
            return Err(JobError::Interrupted);
        }
        self.checkpoint = Some(Checkpoint {
            iteration: self.iteration,
            data,
        });
        Ok(())
    }

    /// The latest checkpoint: at the start of a run, the one an earlier attempt saved. Calling it before
    /// the first iteration of a run means the runner resumes from it: the iteration count continues from
    /// the checkpoint's iteration (a runner that ignores checkpoints starts counting at 1 again, and its
    /// already-announced iterations are not announced twice).
    pub fn last_checkpoint(&mut self) -> Option<Checkpoint> {
        let cp = self.checkpoint.clone()?;
        if self.run_iterations == 0 {
            self.iteration = cp.iteration;
        }
        Some(cp)
    }
}
