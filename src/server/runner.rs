//! Pluggable job kinds: the [`JobRunner`] trait, the [`JobRegistry`] of known kinds, and the
//! [`JobContext`] through which a running job reports iterations, observes cancellation and checkpoints.
//!
//! A runner runs on a blocking worker thread, never on the async runtime. It must call
//! [`JobContext::iteration`] once per iteration and return the error it gets (`?`), which is how
//! cancellation, the time limit and server shutdown reach it within one iteration.
//!
//! # A spec is parsed and validated once
//!
//! Each kind reads its spec into its own typed value, [`JobRunner::Spec`]. The JSON is turned into that
//! value exactly once on each side of the database:
//!
//! 1. At submission (`POST /v1/jobs`, [`super::jobs::submit`]) [`JobRegistry::accept`] calls the kind's
//!    [`JobRunner::parse`] and then [`JobRunner::validate`] on the typed spec. The resulting [`ParsedSpec`]
//!    names the assets to load ([`ParsedSpec::assets`]) and checks them ([`ParsedSpec::check_assets`], a
//!    mesh that cannot serve as a body is answered with 422). Nothing parses the spec again before it is
//!    stored; the stored text is the canonical JSON of the submitted spec (keys sorted), the same text the
//!    request hash is taken of.
//! 2. When a worker claims the job ([`super::worker`]), [`JobRegistry::load`] parses the stored JSON once
//!    with [`JobRunner::parse`], without validating it again: it was validated when it was stored. The
//!    same [`ParsedSpec`] names the assets to load and is what [`ParsedSpec::run`] hands to
//!    [`JobRunner::run`]. Asset checks are not repeated either: assets are content-addressed and cannot be
//!    changed or deleted, so the only thing that can differ is an asset gone missing, which the worker
//!    reports as invalid input.

use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Instant;

use serde_json::Value;
use tokio::runtime::Handle;

use super::model::{AssetRef, Assets, FieldError, JobCheckpoint, JobError, JobOutput, StopFlags};
use super::store::Store;
use crate::scene::Limits;

/// One job kind.
pub trait JobRunner: Send + Sync + 'static {
    /// The kind's spec, parsed from its JSON.
    type Spec: Send + Sync + 'static;

    /// The kind's name as used in `POST /v1/jobs {"kind": …}`.
    fn kind(&self) -> &'static str;

    /// Reads a spec's JSON into the typed spec: wrong types, unknown and missing fields. Called once at
    /// submission and once when a worker loads the stored job. Errors are answered with 422 naming
    /// `spec.<field>`.
    fn parse(&self, spec: &Value) -> Result<Self::Spec, FieldError>;

    /// Checks a parsed spec at submission (before anything is queued): the values that cannot be right.
    /// Bad specs are answered with 422 naming `spec.<field>`.
    fn validate(&self, _spec: &Self::Spec) -> Result<(), FieldError> {
        Ok(())
    }

    /// The assets the spec refers to; each must exist for the submitting tenant.
    fn assets(&self, _spec: &Self::Spec) -> Vec<AssetRef> {
        Vec::new()
    }

    /// Checks, at submission, the assets the spec refers to (each known to exist for the tenant): that a
    /// mesh can be read and serve its purpose, say. Runs on a blocking thread; an error answers 422 naming
    /// `spec.<field>`, so a job whose input cannot work is never queued.
    fn check_assets(&self, _spec: &Self::Spec, _assets: &Assets) -> Result<(), FieldError> {
        Ok(())
    }

    /// Admission costing, at submission after [`Self::check_assets`] (on the same blocking thread): the
    /// job's size estimated from the spec and its assets, checked against the server's `limits`
    /// (`jobs.max_unknowns`, …). An error answers 422 naming `spec.<field>`, the field to change.
    fn admit(
        &self,
        _spec: &Self::Spec,
        _assets: &Assets,
        _limits: &Limits,
    ) -> Result<(), FieldError> {
        Ok(())
    }

    /// Runs the job on a blocking thread. Deterministic kinds that checkpoint resume from
    /// [`JobContext::last_checkpoint`] after a restart.
    fn run(
        &self,
        spec: &Self::Spec,
        assets: &Assets,
        ctx: &mut JobContext,
    ) -> Result<JobOutput, JobError>;
}

/// A spec parsed by its kind, bound to that kind: what the rest of the server holds instead of JSON.
pub struct ParsedSpec(Box<dyn BoundSpec>);

impl ParsedSpec {
    /// The assets the spec refers to.
    pub fn assets(&self) -> Vec<AssetRef> {
        self.0.assets()
    }

    /// The kind's check of the loaded assets (see [`JobRunner::check_assets`]).
    pub fn check_assets(&self, assets: &Assets) -> Result<(), FieldError> {
        self.0.check_assets(assets)
    }

    /// The kind's admission costing (see [`JobRunner::admit`]).
    pub fn admit(&self, assets: &Assets, limits: &Limits) -> Result<(), FieldError> {
        self.0.admit(assets, limits)
    }

    /// Runs the job (see [`JobRunner::run`]).
    pub fn run(&self, assets: &Assets, ctx: &mut JobContext) -> Result<JobOutput, JobError> {
        self.0.run(assets, ctx)
    }
}

/// [`ParsedSpec`]'s object-safe face.
trait BoundSpec: Send + Sync {
    fn assets(&self) -> Vec<AssetRef>;
    fn check_assets(&self, assets: &Assets) -> Result<(), FieldError>;
    fn admit(&self, assets: &Assets, limits: &Limits) -> Result<(), FieldError>;
    fn run(&self, assets: &Assets, ctx: &mut JobContext) -> Result<JobOutput, JobError>;
}

struct Bound<R: JobRunner> {
    runner: Arc<R>,
    spec: R::Spec,
}

impl<R: JobRunner> BoundSpec for Bound<R> {
    fn assets(&self) -> Vec<AssetRef> {
        self.runner.assets(&self.spec)
    }
    fn check_assets(&self, assets: &Assets) -> Result<(), FieldError> {
        self.runner.check_assets(&self.spec, assets)
    }
    fn admit(&self, assets: &Assets, limits: &Limits) -> Result<(), FieldError> {
        self.runner.admit(&self.spec, assets, limits)
    }
    fn run(&self, assets: &Assets, ctx: &mut JobContext) -> Result<JobOutput, JobError> {
        self.runner.run(&self.spec, assets, ctx)
    }
}

/// A registered kind with its spec type hidden.
trait Kind: Send + Sync {
    fn parse(&self, spec: &Value, validate: bool) -> Result<ParsedSpec, FieldError>;
}

impl<R: JobRunner> Kind for Arc<R> {
    fn parse(&self, spec: &Value, validate: bool) -> Result<ParsedSpec, FieldError> {
        let runner: &R = self;
        let spec = runner.parse(spec)?;
        if validate {
            runner.validate(&spec)?;
        }
        Ok(ParsedSpec(Box::new(Bound {
            runner: self.clone(),
            spec,
        })))
    }
}

/// The job kinds a server knows.
#[derive(Clone, Default)]
pub struct JobRegistry {
    kinds: HashMap<&'static str, Arc<dyn Kind>>,
    /// The kinds the server's own executable knows (see [`registry_for`](super::lifecycle::registry_for)):
    /// those a job process (`jobs.isolation = "process"`) can run.
    builtin: std::collections::HashSet<&'static str>,
}

impl JobRegistry {
    pub fn new() -> Self {
        JobRegistry::default()
    }

    /// Adds a kind (replacing one of the same name).
    pub fn register<R: JobRunner>(&mut self, runner: Arc<R>) -> &mut Self {
        self.kinds.insert(runner.kind(), Arc::new(runner));
        self
    }

    /// Adds a kind of the server's own executable, which a job process can run too.
    pub fn register_builtin<R: JobRunner>(&mut self, runner: Arc<R>) -> &mut Self {
        self.builtin.insert(runner.kind());
        self.register(runner)
    }

    /// Whether `kind` is one of the server executable's own kinds (see [`Self::register_builtin`]).
    pub fn is_builtin(&self, kind: &str) -> bool {
        self.builtin.contains(kind)
    }

    /// Whether the server runs jobs of `kind`.
    pub fn contains(&self, kind: &str) -> bool {
        self.kinds.contains_key(kind)
    }

    /// Known kinds, sorted.
    pub fn kinds(&self) -> Vec<&'static str> {
        let mut k: Vec<_> = self.kinds.keys().copied().collect();
        k.sort_unstable();
        k
    }

    /// At submission: parses and validates a spec of `kind`; `None` for an unknown kind.
    pub fn accept(&self, kind: &str, spec: &Value) -> Option<Result<ParsedSpec, FieldError>> {
        Some(self.kinds.get(kind)?.parse(spec, true))
    }

    /// At the worker: parses a stored spec of `kind`, validated when it was submitted; `None` for an
    /// unknown kind.
    pub fn load(&self, kind: &str, spec: &Value) -> Option<Result<ParsedSpec, FieldError>> {
        Some(self.kinds.get(kind)?.parse(spec, false))
    }
}

/// The running job's window onto the server. Lives on the blocking worker thread.
pub struct JobContext {
    pub(crate) job_id: String,
    pub(crate) owner: String,
    pub(crate) store: Store,
    pub(crate) handle: Handle,
    pub(crate) flags: Arc<StopFlags>,
    pub(crate) deadline: Instant,
    pub(crate) time_limit_s: u64,
    pub(crate) events: Arc<tokio::sync::watch::Sender<u64>>,
    /// Iterations done so far in this job (counting those before the checkpoint resumed from).
    pub(crate) iteration: u64,
    /// Highest iteration already announced as an event (from an earlier attempt).
    pub(crate) announced: u64,
    pub(crate) checkpoint: Option<JobCheckpoint>,
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
        self.record(metrics, None)
    }

    /// [`Self::iteration`] and [`Self::checkpoint`] at once, for a runner that numbers its iterations
    /// itself (as [`Self::iteration_number`]): the `iteration` event and the checkpoint after it are
    /// stored in one transaction, so that a run killed between them cannot have announced an iteration
    /// its checkpoint does not hold (it would re-run it quietly on resuming).
    pub fn iteration_checkpointed(
        &mut self,
        number: u64,
        metrics: Value,
        data: Vec<u8>,
    ) -> Result<(), JobError> {
        self.iteration = number.saturating_sub(1);
        self.record(metrics, Some(data))
    }

    fn record(&mut self, metrics: Value, checkpoint: Option<Vec<u8>>) -> Result<(), JobError> {
        self.iteration += 1;
        self.run_iterations += 1;
        if self.iteration > self.announced {
            let res = self.handle.block_on(self.store.record_iteration(
                &self.job_id,
                &self.owner,
                self.iteration,
                self.progress,
                &metrics,
                checkpoint.as_deref(),
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
            if let Some(data) = checkpoint {
                self.checkpoint = Some(JobCheckpoint {
                    iteration: self.iteration,
                    data,
                });
            }
        } else if let Some(data) = checkpoint {
            // An iteration announced by an earlier attempt: its checkpoint alone.
            self.checkpoint(data)?;
        }
        self.should_stop()
    }

    /// [`Self::iteration`] for a runner that numbers its iterations itself, from 1 on: the event carries
    /// `number`, so that it agrees with the number in the runner's own metrics and outputs.
    pub fn iteration_number(&mut self, number: u64, metrics: Value) -> Result<(), JobError> {
        self.iteration = number.saturating_sub(1);
        self.iteration(metrics)
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
            .block_on(
                self.store
                    .save_checkpoint(&self.job_id, &self.owner, self.iteration, &data),
            )
            .map_err(|e| {
                tracing::error!(job = %self.job_id, error = %e, "saving a checkpoint failed");
                JobError::Interrupted
            })?;
        if !saved {
            return Err(JobError::Interrupted);
        }
        self.checkpoint = Some(JobCheckpoint {
            iteration: self.iteration,
            data,
        });
        Ok(())
    }

    /// The latest checkpoint: at the start of a run, the one an earlier attempt saved. Calling it before
    /// the first iteration of a run means the runner resumes from it: the iteration count continues from
    /// the checkpoint's iteration (a runner that ignores checkpoints starts counting at 1 again, and its
    /// already-announced iterations are not announced twice).
    pub fn last_checkpoint(&mut self) -> Option<JobCheckpoint> {
        let cp = self.checkpoint.clone()?;
        if self.run_iterations == 0 {
            self.iteration = cp.iteration;
        }
        Some(cp)
    }
}
