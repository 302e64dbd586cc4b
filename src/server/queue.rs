//! The durable job queue: the job state machine, and the transitions that also wake whoever waits on them
//! in this process (workers waiting for work, SSE streams waiting for events, a running job's stop flags).
//! The SQL of each transition is in [`super::store`]; this module adds the in-process signals.
//!
//! `queued → running → completed | failed | cancelled`, and `running → queued` when a run is interrupted
//! (shutdown; a crash found at the next start of a SQLite server, or a worker whose lease expired:
//! [`Store::requeue_runs`]; after `jobs.max_attempts` crashed runs the job fails with `crashed_repeatedly`
//! instead). A worker claims a job under a lease — a fresh lease id in `lease_owner` and an expiry it
//! renews while the job runs; every later write of the run is conditioned on still holding that unexpired
//! lease, so a job never runs twice at once and a stale worker cannot overwrite it (see [`super::store`]). Every state change appends its event row in the same transaction, so the
//! event log (what SSE serves) is exactly the job's history.

use std::sync::atomic::Ordering;

use super::model::Inserted;
use super::model::{CancelResult, Claimed, NewJob, Outcome};
use super::state::AppState;
use super::store::{Requeue, Store};

/// Stores a validated job as `queued` and wakes a worker and the SSE streams.
pub async fn submit(state: &AppState, job: &NewJob) -> Result<Inserted, sqlx::Error> {
    let inserted = state.store.insert_job(job).await?;
    if inserted == Inserted::Queued {
        state.bump_events();
        state.job_available.notify_one();
    }
    Ok(inserted)
}

/// Claims the oldest queued job under the new lease id `lease` for `jobs.lease_s`.
pub async fn claim(state: &AppState, lease: &str) -> Result<Option<Claimed>, sqlx::Error> {
    let lease_for = std::time::Duration::from_secs(state.config.jobs.lease_s);
    state.store.claim(lease, lease_for).await
}

/// Cancels a tenant's job: a queued one at once; a running one through its stop flag, so its runner stops
/// within one iteration.
pub async fn cancel(state: &AppState, tenant: &str, id: &str) -> Result<CancelResult, sqlx::Error> {
    let result = state.store.cancel(tenant, id).await?;
    match &result {
        CancelResult::Cancelled => state.bump_events(),
        CancelResult::Requested => {
            if let Some(flags) = state.running.lock().expect("running map").get(id) {
                flags.cancel.store(true, Ordering::SeqCst);
            }
        }
        CancelResult::NotFound | CancelResult::AlreadyFinished(_) => {}
    }
    Ok(result)
}

/// Ends the run of `job_id` held by `owner` and wakes the SSE streams. A run whose lease was lost changes
/// nothing (and is logged).
pub async fn finish(state: &AppState, job_id: &str, owner: &str, outcome: Outcome) {
    match state.store.finish(job_id, owner, outcome).await {
        Ok(true) => {}
        Ok(false) => {
            tracing::warn!(job = %job_id, "job lease lost before it finished; result dropped")
        }
        Err(e) => tracing::error!(job = %job_id, error = %e, "recording a job's end failed"),
    }
    state.bump_events();
}

/// At start, before any worker runs: re-queues (or cancels, if asked, or fails with `crashed_repeatedly`
/// after `max_attempts` crashed runs) the jobs a previous process left running; returns how many.
pub async fn recover(store: &Store, max_attempts: u32) -> Result<usize, sqlx::Error> {
    store.requeue_runs(max_attempts, Requeue::Restart).await
}
