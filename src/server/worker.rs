//! The worker pool: N async loops, each claiming one job at a time from the queue and running it on a
//! blocking thread (`tokio::task::spawn_blocking`), never on the async runtime's threads.
//!
//! With `jobs.isolation = "process"` a job of a built-in kind runs in a child process instead
//! ([`super::isolation`]), which runs this module's [`execute`] itself ([`super::job_process`]).
//!
//! Each claim takes a lease of its own (see [`super::store`]), renewed by a heartbeat task while the job
//! runs; the job's writes are fenced by it.
//!
//! A claimed job's stored spec is parsed once here ([`JobRegistry::load`](super::runner::JobRegistry::load),
//! see [`super::runner`]); its assets are loaded from the store and the parsed spec runs with them.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use super::isolation;
use super::model::{AssetRef, Assets, Claimed, JobError, Outcome, StopFlags, valid_artifact_name};
use super::queue;
use super::runner::JobContext;
use super::state::AppState;

/// Runs worker `index` until shutdown.
pub async fn run_worker(state: AppState, index: usize) {
    let worker = format!("{}/{}", state.instance, index);
    let mut shutdown = state.shutdown.clone();
    loop {
        if *shutdown.borrow() {
            break;
        }
        // A lease id of its own for every claim: a run's writes are fenced by it, so nothing this worker
        // wrote under an earlier lease on the same job can pass for the current one.
        let lease = format!("{worker}/{}", uuid::Uuid::new_v4());
        let asked = Instant::now();
        match queue::claim(&state, &lease).await {
            Ok(Some(job)) => {
                state.metrics.observe_claim(asked.elapsed().as_secs_f64());
                // There may be more queued work: wake a sibling.
                state.job_available.notify_one();
                run_claimed(&state, &lease, job).await;
            }
            Ok(None) => {
                tokio::select! {
                    _ = state.job_available.notified() => {}
                    _ = tokio::time::sleep(Duration::from_millis(500)) => {}
                    _ = shutdown.changed() => {}
                }
            }
            Err(e) => {
                tracing::error!(worker = %worker, error = %e, "claiming a job failed");
                tokio::time::sleep(Duration::from_secs(1)).await;
            }
        }
    }
    tracing::debug!(worker = %worker, "worker stopped");
}

/// Renews the lease `lease` on the running `job_id` every third of `jobs.lease_s` until aborted. A
/// cancel requested on another node reaches the job here too; a lease found gone (it expired, and the job
/// was taken back) stops the job, whose writes would fail anyway.
async fn heartbeat(state: AppState, job_id: String, lease: String, flags: Arc<StopFlags>) {
    let lease_for = Duration::from_secs(state.config.jobs.lease_s);
    loop {
        tokio::time::sleep(lease_for / 3).await;
        match state.store.renew_lease(&job_id, &lease, lease_for).await {
            Ok(Some(cancel)) => {
                state.metrics.lease_renewed();
                if cancel {
                    flags.cancel.store(true, Ordering::SeqCst);
                }
            }
            Ok(None) => {
                state.metrics.lease_lost();
                tracing::warn!(job = %job_id, "the job's lease is gone (it expired); stopping the run");
                flags.shutdown.store(true, Ordering::SeqCst);
                return;
            }
            Err(e) => {
                tracing::error!(job = %job_id, error = %e, "renewing a lease failed; retrying");
            }
        }
    }
}

async fn run_claimed(state: &AppState, owner: &str, job: Claimed) {
    let started = Instant::now();
    let flags = Arc::new(StopFlags::default());
    state
        .running
        .lock()
        .expect("running map")
        .insert(job.id.clone(), flags.clone());
    state.bump_events();
    // A cancel that arrived between the claim and the registration above is in the database.
    let cancel_now =
        job.cancel_requested || state.store.cancel_requested(&job.id).await.unwrap_or(false);
    if cancel_now {
        flags.cancel.store(true, Ordering::SeqCst);
    }
    if *state.shutdown.borrow() {
        flags.shutdown.store(true, Ordering::SeqCst);
    }
    tracing::info!(job = %job.id, kind = %job.kind, attempt = job.attempts, "job started");
    let beat = tokio::spawn(heartbeat(
        state.clone(),
        job.id.clone(),
        owner.to_string(),
        flags.clone(),
    ));

    let label = if isolation::applies(state, &job.kind) {
        // In a job process, which stores the outcome itself unless it died.
        let died = isolation::run_in_child(state, owner, &job, flags.clone()).await;
        beat.abort();
        state.running.lock().expect("running map").remove(&job.id);
        match died {
            Some(outcome) => {
                let label = outcome.label();
                queue::finish(state, &job.id, owner, outcome).await;
                label
            }
            None => {
                state.bump_events();
                match state.store.job_status(&job.id).await {
                    Ok(Some(s)) if s == "queued" => "requeued",
                    Ok(Some(s)) if s == "completed" => "completed",
                    Ok(Some(s)) if s == "cancelled" => "cancelled",
                    _ => "failed",
                }
            }
        }
    } else {
        let outcome = execute(state, owner, &job, flags.clone()).await;
        beat.abort();
        let label = outcome.label();
        state.running.lock().expect("running map").remove(&job.id);
        queue::finish(state, &job.id, owner, outcome).await;
        label
    };
    let secs = started.elapsed().as_secs_f64();
    state.metrics.observe_job(&job.kind, label, secs);
    tracing::info!(job = %job.id, kind = %job.kind, outcome = label, seconds = secs, "job ended");
}

/// Runs a claimed job on a blocking thread of this process and returns how it ended (a worker thread's
/// run, and the whole of a job process's, [`super::job_process`]).
pub(super) async fn execute(
    state: &AppState,
    owner: &str,
    job: &Claimed,
    flags: Arc<StopFlags>,
) -> Outcome {
    let spec = match state.registry.load(&job.kind, &job.spec) {
        None => {
            return Outcome::Failed {
                code: "unknown_kind",
                message: format!("this server has no job kind {:?}", job.kind),
            };
        }
        // A stored spec that this server cannot read (stored by another version, say).
        Some(Err(e)) => {
            let e = JobError::Invalid {
                field: e.field,
                message: e.message,
            };
            return Outcome::Failed {
                code: "invalid_input",
                message: e.to_string(),
            };
        }
        Some(Ok(spec)) => spec,
    };
    let assets = match load_assets(state, job, spec.assets()).await {
        Ok(a) => a,
        Err(o) => return o,
    };
    let limit_s = state.config.jobs.time_limit_s;
    let mut ctx = JobContext {
        job_id: job.id.clone(),
        owner: owner.to_string(),
        store: state.store.clone(),
        handle: tokio::runtime::Handle::current(),
        flags: flags.clone(),
        deadline: Instant::now() + Duration::from_secs(limit_s),
        time_limit_s: limit_s,
        events: state.events.clone(),
        iteration: 0,
        run_iterations: 0,
        announced: job.iterations,
        checkpoint: job.checkpoint.clone(),
        progress: None,
    };
    let task = tokio::task::spawn_blocking(move || spec.run(&assets, &mut ctx));
    // A runner that stops calling `iteration` is abandoned a little after its time limit.
    let watchdog = Duration::from_secs(limit_s) + Duration::from_secs(5);
    let result = match tokio::time::timeout(watchdog, task).await {
        Ok(Ok(r)) => r,
        Ok(Err(join)) => {
            tracing::error!(job = %job.id, error = %join, "job runner panicked");
            return Outcome::Failed {
                code: "internal",
                message: "the job runner failed unexpectedly; the details are in the server log"
                    .into(),
            };
        }
        Err(_) => {
            flags.cancel.store(true, Ordering::SeqCst);
            Err(JobError::TimedOut { limit_s })
        }
    };
    match result {
        Ok(out) => {
            if let Some(bad) = out.artifacts.iter().find(|a| !valid_artifact_name(&a.name)) {
                tracing::error!(job = %job.id, name = %bad.name, "runner produced an invalid artifact name");
                return Outcome::Failed {
                    code: "internal",
                    message: "the job produced an invalid artifact name".into(),
                };
            }
            Outcome::Completed {
                artifacts: out.artifacts,
                summary: out.summary,
                warnings: out.warnings,
            }
        }
        Err(JobError::Cancelled) => Outcome::Cancelled,
        Err(JobError::Interrupted) => Outcome::Requeued {
            reason: "interrupted by a server shutdown",
        },
        Err(e @ JobError::TimedOut { .. }) => Outcome::Failed {
            code: "time_limit_exceeded",
            message: e.to_string(),
        },
        Err(e @ JobError::Invalid { .. }) => Outcome::Failed {
            code: "invalid_input",
            message: e.to_string(),
        },
        Err(JobError::Failed(message)) => Outcome::Failed {
            code: "job_failed",
            message,
        },
    }
}

async fn load_assets(
    state: &AppState,
    job: &Claimed,
    refs: Vec<AssetRef>,
) -> Result<Assets, Outcome> {
    let mut assets = Assets::default();
    for r in refs {
        let asset = state
            .store
            .load_asset(&job.tenant, &r.id)
            .await
            .map_err(|e| {
                tracing::error!(job = %job.id, error = %e, "loading an asset failed");
                Outcome::Failed {
                    code: "internal",
                    message: "loading the job's assets failed; the details are in the server log"
                        .into(),
                }
            })?
            .ok_or_else(|| Outcome::Failed {
                code: "invalid_input",
                message: format!("spec.{}: asset {:?} no longer exists", r.field, r.id),
            })?;
        assets.by_field.insert(r.field, asset);
    }
    Ok(assets)
}
