//! The writes of a job's run, each conditioned on the worker's lease (its id in `lease_owner`, unexpired):
//! claim, heartbeat, iterations, checkpoints, finish, and taking runs back from workers that died or stop
//! (the state machine of [`crate::server::queue`], the leases of [`crate::server::store`]).
//!
//! A claim is one `UPDATE` of the oldest queued job that sets the lease, inside a writing transaction;
//! every later write of the run is conditioned on still holding that lease (`held!`: `id = $1 AND
//! lease_owner = $2 AND status = 'running' AND lease_expires_at > now`), so a job never runs
//! twice at once and a stale worker cannot overwrite it. Every state change appends its event row in the
//! same transaction. All lease arithmetic uses the database's clock.

use std::time::Duration;

use serde_json::{Value, json};

use super::artifacts::ArtifactsSql;
use super::engine::{Engine, EngineStore};
use super::events::{EventsSql, announce_queued, append_event};
use super::rows;
use super::statement::Statement;
use crate::server::model::{Claimed, Outcome, sha256_hex};
use crate::server::store::Requeue;

/// The run statements, in the dialect's clock (`now`, `now + lease`) and row locks. All but the claim and
/// the hand-back are the same text around those, stamped into each engine by `run_statements!`; the claim
/// differs in how it picks and locks the oldest queued job, the hand-back in its text functions.
pub trait RunsSql {
    /// Claims the oldest queued job (lease id, lease seconds), returning its
    /// [`claimed_columns`](super::rows::claimed_columns); no row when the queue is empty.
    const CLAIM: &'static str;
    /// Extends a held lease (job id, lease id, lease seconds), returning `cancel_requested`.
    const RENEW_LEASE: &'static str;
    /// The job held under a lease (job id, lease id), its `claimed_columns`.
    const RUNNING_JOB: &'static str;
    /// Records an iteration of a held job (job id, lease id, iteration, progress or `NULL`, metrics),
    /// returning `cancel_requested`.
    const RECORD_ITERATION: &'static str;
    /// Stores a held job's checkpoint (job id, lease id, data, iteration).
    const SAVE_CHECKPOINT: &'static str;
    /// Ends a held run (job id, lease id, status, summary, error code, error message): `completed` sets
    /// the progress to 1, `queued` leaves the job unfinished.
    const FINISH: &'static str;
    /// Takes back the running jobs (max attempts, whether only expired leases, the start of the
    /// `crashed_repeatedly` message), counting a crash: cancelled if asked, failed after max attempts
    /// crashes, else queued; returns each one's id, status, checkpoint iteration, error code and message.
    const REQUEUE_RUNS: &'static str;
    /// Re-queues the running jobs whose lease id starts with `$1`, returning each one's id and checkpoint
    /// iteration.
    const HAND_BACK: &'static str;
}

/// The condition of every write of a run, in a dialect whose clock is `$now!()`: the job is running under
/// the lease `$2`, which has not expired.
macro_rules! held {
    ($now:ident) => {
        concat!(
            "id = $1 AND lease_owner = $2 AND status = 'running' AND lease_expires_at > ",
            $now!()
        )
    };
}
pub(super) use held;

/// Stamps into an engine's [`RunsSql`] the statements that both dialects write alike around their
/// fragments: `$now!()`, the time now; `$later!("$n")`, the parameter `$n` seconds from now; and
/// `$skip_locked!()`, what a subquery that selects rows to update appends to lock them and to skip those
/// another transaction holds.
macro_rules! run_statements {
    ($now:ident, $later:ident, $skip_locked:ident) => {
        const RENEW_LEASE: &'static str = concat!(
            "UPDATE jobs SET lease_expires_at = ",
            $later!("$3"),
            " WHERE ",
            $crate::server::store::runs::held!($now),
            " RETURNING cancel_requested"
        );
        const RUNNING_JOB: &'static str = concat!(
            "SELECT ",
            $crate::server::store::rows::claimed_columns!(),
            " FROM jobs WHERE ",
            $crate::server::store::runs::held!($now)
        );
        const RECORD_ITERATION: &'static str = concat!(
            "UPDATE jobs SET iterations = $3, progress = COALESCE($4, progress), last_metrics = $5 WHERE ",
            $crate::server::store::runs::held!($now),
            " RETURNING cancel_requested"
        );
        const SAVE_CHECKPOINT: &'static str = concat!(
            "UPDATE jobs SET checkpoint = $3, checkpoint_iteration = $4 WHERE ",
            $crate::server::store::runs::held!($now)
        );
        const FINISH: &'static str = concat!(
            "UPDATE jobs SET status = $3, lease_owner = NULL, lease_expires_at = NULL, summary = $4, \
                 error_code = $5, error_message = $6, \
                 progress = CASE WHEN $3 = 'completed' THEN 1.0 ELSE progress END, \
                 finished_at = CASE WHEN $3 = 'queued' THEN NULL ELSE ",
            $now!(),
            " END WHERE ",
            $crate::server::store::runs::held!($now)
        );
        const REQUEUE_RUNS: &'static str = concat!(
            "UPDATE jobs SET crashes = crashes + 1, \
                 status = CASE WHEN cancel_requested = 1 THEN 'cancelled' \
                     WHEN crashes + 1 >= $1 THEN 'failed' ELSE 'queued' END, \
                 lease_owner = NULL, lease_expires_at = NULL, \
                 finished_at = CASE WHEN cancel_requested = 1 OR crashes + 1 >= $1 THEN ",
            $now!(),
            " ELSE NULL END, \
                 error_code = CASE WHEN cancel_requested = 1 THEN 'cancelled' \
                     WHEN crashes + 1 >= $1 THEN 'crashed_repeatedly' ELSE NULL END, \
                 error_message = CASE WHEN cancel_requested = 1 THEN 'the job was cancelled' \
                     WHEN crashes + 1 >= $1 THEN CAST($3 AS TEXT) || CAST(crashes + 1 AS TEXT) || \
                         ' runs of this job (jobs.max_attempts = ' || CAST($1 AS TEXT) || \
                         '); it is not run again' \
                     ELSE NULL END \
             WHERE seq IN (SELECT seq FROM jobs WHERE status = 'running' \
                 AND (NOT $2 OR lease_expires_at IS NULL OR lease_expires_at <= ",
            $now!(),
            ")",
            $skip_locked!(),
            ") RETURNING id, status, checkpoint_iteration, error_code, error_message"
        );
    };
}
pub(super) use run_statements;

/// Seconds of a lease as the statements take them.
fn secs(d: Duration) -> f64 {
    d.as_secs_f64()
}

impl<E: Engine + RunsSql + ArtifactsSql + EventsSql> EngineStore<E> {
    /// [`Store::claim`](super::Store::claim) on this engine.
    pub async fn claim(
        &self,
        lease: &str,
        lease_for: Duration,
    ) -> Result<Option<Claimed>, sqlx::Error> {
        let mut tx = self.begin_write().await?;
        let row = Statement::<E>::new(E::CLAIM)
            .bind(lease)
            .bind(secs(lease_for))
            .fetch_optional(&mut tx)
            .await?;
        let Some(row) = row else {
            tx.rollback().await?;
            return Ok(None);
        };
        let claimed = rows::claimed::<E>(&row)?;
        let started = json!({
            "attempt": claimed.attempts,
            "resumed_from_iteration": claimed.checkpoint.as_ref().map(|c| c.iteration),
        });
        append_event::<E>(&mut tx, &claimed.id, "started", &started).await?;
        tx.commit().await?;
        Ok(Some(claimed))
    }

    /// [`Store::renew_lease`](super::Store::renew_lease) on this engine.
    pub async fn renew_lease(
        &self,
        job_id: &str,
        lease: &str,
        lease_for: Duration,
    ) -> Result<Option<bool>, sqlx::Error> {
        let row = Statement::<E>::new(E::RENEW_LEASE)
            .bind(job_id)
            .bind(lease)
            .bind(secs(lease_for))
            .fetch_optional(&mut *self.conn().await?)
            .await?;
        row.map(|row| Ok(E::get::<i64>(&row, "cancel_requested")? != 0))
            .transpose()
    }

    /// [`Store::running_job`](super::Store::running_job) on this engine.
    pub async fn running_job(
        &self,
        job_id: &str,
        lease: &str,
    ) -> Result<Option<Claimed>, sqlx::Error> {
        let row = Statement::<E>::new(E::RUNNING_JOB)
            .bind(job_id)
            .bind(lease)
            .fetch_optional(&mut *self.conn().await?)
            .await?;
        row.as_ref().map(rows::claimed::<E>).transpose()
    }

    /// [`Store::record_iteration`](super::Store::record_iteration) on this engine.
    pub async fn record_iteration(
        &self,
        job_id: &str,
        lease: &str,
        iteration: u64,
        progress: Option<f64>,
        metrics: &Value,
        checkpoint: Option<&[u8]>,
    ) -> Result<Option<bool>, sqlx::Error> {
        let mut tx = self.begin_write().await?;
        let row = Statement::<E>::new(E::RECORD_ITERATION)
            .bind(job_id)
            .bind(lease)
            .bind(iteration as i64)
            .bind(progress)
            .bind(metrics.to_string())
            .fetch_optional(&mut tx)
            .await?;
        let Some(row) = row else {
            tx.rollback().await?;
            return Ok(None);
        };
        let cancel: i64 = E::get(&row, "cancel_requested")?;
        let event = json!({ "iteration": iteration, "progress": progress, "metrics": metrics });
        append_event::<E>(&mut tx, job_id, "iteration", &event).await?;
        // The iteration's checkpoint in the same transaction as its event: a run killed at any moment
        // has stored both or neither, so it resumes from the last iteration it announced.
        if let Some(data) = checkpoint {
            Statement::<E>::new(E::SAVE_CHECKPOINT)
                .bind(job_id)
                .bind(lease)
                .bind(data)
                .bind(iteration as i64)
                .execute(&mut tx)
                .await?;
        }
        tx.commit().await?;
        Ok(Some(cancel != 0))
    }

    /// [`Store::save_checkpoint`](super::Store::save_checkpoint) on this engine.
    pub async fn save_checkpoint(
        &self,
        job_id: &str,
        lease: &str,
        iteration: u64,
        data: &[u8],
    ) -> Result<bool, sqlx::Error> {
        let done = Statement::<E>::new(E::SAVE_CHECKPOINT)
            .bind(job_id)
            .bind(lease)
            .bind(data)
            .bind(iteration as i64)
            .execute(&mut *self.conn().await?)
            .await?;
        Ok(done == 1)
    }

    /// [`Store::finish`](super::Store::finish) on this engine.
    pub async fn finish(
        &self,
        job_id: &str,
        lease: &str,
        outcome: Outcome,
    ) -> Result<bool, sqlx::Error> {
        let mut tx = self.begin_write().await?;
        let (status, summary, code, message) = match &outcome {
            Outcome::Completed { summary, .. } => {
                ("completed", Some(summary.to_string()), None, None)
            }
            Outcome::Failed { code, message } => {
                ("failed", None, Some(*code), Some(message.clone()))
            }
            Outcome::Cancelled => (
                "cancelled",
                None,
                Some("cancelled"),
                Some("the job was cancelled".to_string()),
            ),
            Outcome::Requeued { .. } => ("queued", None, None, None),
        };
        let done = Statement::<E>::new(E::FINISH)
            .bind(job_id)
            .bind(lease)
            .bind(status)
            .bind(summary)
            .bind(code)
            .bind(message)
            .execute(&mut tx)
            .await?;
        if done != 1 {
            tx.rollback().await?;
            return Ok(false);
        }
        match outcome {
            Outcome::Completed {
                artifacts,
                summary,
                warnings,
            } => {
                let mut names = Vec::with_capacity(artifacts.len());
                for a in &artifacts {
                    Statement::<E>::new(E::SAVE_ARTIFACT)
                        .bind(job_id)
                        .bind(a.name.as_str())
                        .bind(a.content_type.as_str())
                        .bind(a.data.len() as i64)
                        .bind(sha256_hex(&a.data))
                        .bind(a.data.as_slice())
                        .execute(&mut tx)
                        .await?;
                    names.push(a.name.clone());
                }
                for w in &warnings {
                    append_event::<E>(&mut tx, job_id, "warning", w).await?;
                }
                let completed = json!({ "summary": summary, "artifacts": names });
                append_event::<E>(&mut tx, job_id, "completed", &completed).await?;
            }
            Outcome::Failed { code, message } => {
                let failed = json!({ "error": { "code": code, "message": message } });
                append_event::<E>(&mut tx, job_id, "failed", &failed).await?;
            }
            Outcome::Cancelled => {
                append_event::<E>(&mut tx, job_id, "cancelled", &json!({})).await?;
            }
            Outcome::Requeued { reason } => {
                append_event::<E>(&mut tx, job_id, "queued", &json!({ "reason": reason })).await?;
                announce_queued::<E>(&mut tx, job_id).await?;
            }
        }
        tx.commit().await?;
        Ok(true)
    }

    /// [`Store::requeue_runs`](super::Store::requeue_runs) on this engine.
    pub async fn requeue_runs(
        &self,
        max_attempts: u32,
        why: Requeue,
    ) -> Result<usize, sqlx::Error> {
        let mut tx = self.begin_write().await?;
        let rows = Statement::<E>::new(E::REQUEUE_RUNS)
            .bind(i64::from(max_attempts))
            .bind(why == Requeue::LeaseExpired)
            .bind(why.cause())
            .fetch_all(&mut tx)
            .await?;
        for row in &rows {
            let id: String = E::get(row, "id")?;
            let (kind, data) = requeue_event(
                &E::get::<String>(row, "status")?,
                E::get(row, "checkpoint_iteration")?,
                E::get(row, "error_code")?,
                E::get(row, "error_message")?,
                why,
            );
            append_event::<E>(&mut tx, &id, kind, &data).await?;
            if kind == "queued" {
                announce_queued::<E>(&mut tx, &id).await?;
            }
        }
        tx.commit().await?;
        Ok(rows.len())
    }

    /// [`Store::hand_back`](super::Store::hand_back) on this engine.
    pub async fn hand_back(&self, prefix: &str) -> Result<usize, sqlx::Error> {
        let mut tx = self.begin_write().await?;
        let rows = Statement::<E>::new(E::HAND_BACK)
            .bind(prefix)
            .fetch_all(&mut tx)
            .await?;
        for row in &rows {
            let id: String = E::get(row, "id")?;
            let event = handed_back_event(E::get(row, "checkpoint_iteration")?);
            append_event::<E>(&mut tx, &id, "queued", &event).await?;
            announce_queued::<E>(&mut tx, &id).await?;
        }
        tx.commit().await?;
        Ok(rows.len())
    }
}

/// The event of a run taken back from its worker ([`EngineStore::requeue_runs`]), by the job's new
/// status.
fn requeue_event(
    status: &str,
    checkpoint_iteration: Option<i64>,
    code: Option<String>,
    message: Option<String>,
    why: Requeue,
) -> (&'static str, Value) {
    match status {
        "cancelled" => ("cancelled", json!({})),
        "failed" => (
            "failed",
            json!({ "error": { "code": code, "message": message } }),
        ),
        _ => (
            "queued",
            json!({ "reason": why.reason(), "resume_from_iteration": checkpoint_iteration }),
        ),
    }
}

/// The event of a run handed back at its worker's shutdown ([`EngineStore::hand_back`]).
fn handed_back_event(checkpoint_iteration: Option<i64>) -> Value {
    json!({
        "reason": "handed back by a worker shutting down",
        "resume_from_iteration": checkpoint_iteration,
    })
}
