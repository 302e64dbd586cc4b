//! The writes of a job's run, each conditioned on the worker's lease (its id in `lease_owner`, unexpired):
//! claim, heartbeat, iterations, checkpoints, finish, and taking runs back from workers that died (the state
//! machine of [`crate::server::queue`], the leases of [`crate::server::store`]).
//!
//! A worker claims a job with one `UPDATE … WHERE status = 'queued' … RETURNING` inside `BEGIN IMMEDIATE`
//! (SQLite's one write lock), which sets the lease; every later write of the run is conditioned on still
//! holding that lease, so a job never runs twice at once and a stale worker cannot overwrite it. Every
//! state change appends its event row in the same transaction.

use std::time::Duration;

use serde_json::{Value, json};
use sqlx::Row;

use super::{SqliteStore, append_event, claimed_of};
use crate::server::model::{Claimed, Outcome, sha256_hex};
use crate::server::store::{Requeue, claimed_columns, secs};

/// The condition of every write of a run: the job is running under the lease `?2`, which has not expired.
macro_rules! held {
    () => {
        "id = ?1 AND lease_owner = ?2 AND status = 'running' \
         AND lease_expires_at > strftime('%Y-%m-%dT%H:%M:%fZ', 'now')"
    };
}

impl SqliteStore {
    /// Claims the oldest queued job under the lease `owner` for `lease_for`, or `None` when the queue is
    /// empty. Appends its `started` event.
    pub async fn claim(
        &self,
        owner: &str,
        lease_for: Duration,
    ) -> Result<Option<Claimed>, sqlx::Error> {
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
        let row = sqlx::query(concat!(
            "UPDATE jobs SET status = 'running', lease_owner = ?1, attempts = attempts + 1, \
                 lease_expires_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now', ?2 || ' seconds'), \
                 started_at = COALESCE(started_at, strftime('%Y-%m-%dT%H:%M:%fZ', 'now')) \
             WHERE seq = (SELECT seq FROM jobs WHERE status = 'queued' ORDER BY seq LIMIT 1) AND status = 'queued' \
             RETURNING ",
            claimed_columns!()
        ))
        .bind(owner)
        .bind(secs(lease_for))
        .fetch_optional(&mut *tx)
        .await?;
        let Some(row) = row else {
            tx.rollback().await?;
            return Ok(None);
        };
        let claimed = claimed_of(&row)?;
        append_event(
            &mut tx,
            &claimed.id,
            "started",
            &json!({
                "attempt": claimed.attempts,
                "resumed_from_iteration": claimed.checkpoint.as_ref().map(|c| c.iteration),
            }),
        )
        .await?;
        tx.commit().await?;
        Ok(Some(claimed))
    }

    /// Extends the lease `owner` on a running job by `lease_for` from now; whether a cancel was requested,
    /// or `None` when the lease is gone.
    pub async fn renew_lease(
        &self,
        job_id: &str,
        owner: &str,
        lease_for: Duration,
    ) -> Result<Option<bool>, sqlx::Error> {
        let cancel: Option<i64> = sqlx::query_scalar(concat!(
            "UPDATE jobs SET lease_expires_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now', ?3 || ' seconds') WHERE ",
            held!(),
            " RETURNING cancel_requested"
        ))
        .bind(job_id)
        .bind(owner)
        .bind(secs(lease_for))
        .fetch_optional(&self.pool)
        .await?;
        Ok(cancel.map(|c| c != 0))
    }

    /// The job held under the lease `owner`, read again by the job process that runs it; `None` when the
    /// lease is gone.
    pub async fn running_job(
        &self,
        job_id: &str,
        owner: &str,
    ) -> Result<Option<Claimed>, sqlx::Error> {
        let row = sqlx::query(concat!(
            "SELECT ",
            claimed_columns!(),
            " FROM jobs WHERE ",
            held!()
        ))
        .bind(job_id)
        .bind(owner)
        .fetch_optional(&self.pool)
        .await?;
        row.as_ref().map(claimed_of).transpose()
    }

    /// Records an iteration if the lease `owner` still holds the job; returns whether a cancel was
    /// requested, or `None` when the lease is gone.
    pub async fn record_iteration(
        &self,
        job_id: &str,
        owner: &str,
        iteration: u64,
        progress: Option<f64>,
        metrics: &Value,
    ) -> Result<Option<bool>, sqlx::Error> {
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
        let row = sqlx::query(concat!(
            "UPDATE jobs SET iterations = ?3, progress = COALESCE(?4, progress), last_metrics = ?5 WHERE ",
            held!(),
            " RETURNING cancel_requested"
        ))
        .bind(job_id)
        .bind(owner)
        .bind(iteration as i64)
        .bind(progress)
        .bind(metrics.to_string())
        .fetch_optional(&mut *tx)
        .await?;
        let Some(row) = row else {
            tx.rollback().await?;
            return Ok(None);
        };
        let cancel: i64 = row.try_get(0)?;
        append_event(
            &mut tx,
            job_id,
            "iteration",
            &json!({ "iteration": iteration, "progress": progress, "metrics": metrics }),
        )
        .await?;
        tx.commit().await?;
        Ok(Some(cancel != 0))
    }

    /// Saves a checkpoint if the lease `owner` still holds the job; `false` when the lease is gone.
    pub async fn save_checkpoint(
        &self,
        job_id: &str,
        owner: &str,
        iteration: u64,
        data: &[u8],
    ) -> Result<bool, sqlx::Error> {
        let done = sqlx::query(concat!(
            "UPDATE jobs SET checkpoint = ?3, checkpoint_iteration = ?4 WHERE ",
            held!()
        ))
        .bind(job_id)
        .bind(owner)
        .bind(data)
        .bind(iteration as i64)
        .execute(&self.pool)
        .await?;
        Ok(done.rows_affected() == 1)
    }

    /// Ends a run held under the lease `owner` (storing a completed job's artifacts); returns `false` (and changes
    /// nothing) when the lease is gone.
    pub async fn finish(
        &self,
        job_id: &str,
        owner: &str,
        outcome: Outcome,
    ) -> Result<bool, sqlx::Error> {
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
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
        let done = sqlx::query(
            "UPDATE jobs SET status = ?3, lease_owner = NULL, lease_expires_at = NULL, summary = ?4, error_code = ?5, error_message = ?6, \
                 progress = CASE WHEN ?3 = 'completed' THEN 1.0 ELSE progress END, \
                 finished_at = CASE WHEN ?3 = 'queued' THEN NULL ELSE strftime('%Y-%m-%dT%H:%M:%fZ', 'now') END \
             WHERE id = ?1 AND lease_owner = ?2 AND status = 'running' \
                 AND lease_expires_at > strftime('%Y-%m-%dT%H:%M:%fZ', 'now')",
        )
        .bind(job_id)
        .bind(owner)
        .bind(status)
        .bind(summary)
        .bind(code)
        .bind(message.clone())
        .execute(&mut *tx)
        .await?;
        if done.rows_affected() != 1 {
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
                    sqlx::query(
                        "INSERT OR REPLACE INTO artifacts (job_id, name, content_type, bytes, sha256, data) \
                         VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                    )
                    .bind(job_id)
                    .bind(&a.name)
                    .bind(&a.content_type)
                    .bind(a.data.len() as i64)
                    .bind(sha256_hex(&a.data))
                    .bind(&a.data)
                    .execute(&mut *tx)
                    .await?;
                    names.push(a.name.clone());
                }
                for w in &warnings {
                    append_event(&mut tx, job_id, "warning", w).await?;
                }
                append_event(
                    &mut tx,
                    job_id,
                    "completed",
                    &json!({ "summary": summary, "artifacts": names }),
                )
                .await?;
            }
            Outcome::Failed { code, message } => {
                append_event(
                    &mut tx,
                    job_id,
                    "failed",
                    &json!({ "error": { "code": code, "message": message } }),
                )
                .await?;
            }
            Outcome::Cancelled => {
                append_event(&mut tx, job_id, "cancelled", &json!({})).await?;
            }
            Outcome::Requeued { reason } => {
                append_event(&mut tx, job_id, "queued", &json!({ "reason": reason })).await?;
            }
        }
        tx.commit().await?;
        Ok(true)
    }

    /// Takes back runs from their workers (every running one, or those whose lease expired): re-queued,
    /// cancelled if asked, or failed with `crashed_repeatedly` after `max_attempts` crashed runs.
    pub async fn requeue_runs(
        &self,
        max_attempts: u32,
        why: Requeue,
    ) -> Result<usize, sqlx::Error> {
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
        let rows = sqlx::query(
            "UPDATE jobs SET crashes = crashes + 1, \
                 status = CASE WHEN cancel_requested = 1 THEN 'cancelled' \
                     WHEN crashes + 1 >= ?1 THEN 'failed' ELSE 'queued' END, \
                 lease_owner = NULL, lease_expires_at = NULL, \
                 finished_at = CASE WHEN cancel_requested = 1 OR crashes + 1 >= ?1 \
                     THEN strftime('%Y-%m-%dT%H:%M:%fZ', 'now') ELSE NULL END, \
                 error_code = CASE WHEN cancel_requested = 1 THEN 'cancelled' \
                     WHEN crashes + 1 >= ?1 THEN 'crashed_repeatedly' ELSE NULL END, \
                 error_message = CASE WHEN cancel_requested = 1 THEN 'the job was cancelled' \
                     WHEN crashes + 1 >= ?1 THEN ?3 || (crashes + 1) || \
                         ' runs of this job (jobs.max_attempts = ' || ?1 || '); it is not run again' \
                     ELSE NULL END \
             WHERE status = 'running' AND (?2 = 0 OR lease_expires_at IS NULL \
                 OR lease_expires_at <= strftime('%Y-%m-%dT%H:%M:%fZ', 'now')) \
             RETURNING id, status, checkpoint_iteration, error_code, error_message",
        )
        .bind(i64::from(max_attempts))
        .bind(i64::from(why == Requeue::LeaseExpired))
        .bind(why.cause())
        .fetch_all(&mut *tx)
        .await?;
        for row in &rows {
            let id: String = row.try_get("id")?;
            let status: String = row.try_get("status")?;
            let cp: Option<i64> = row.try_get("checkpoint_iteration")?;
            let code: Option<String> = row.try_get("error_code")?;
            let message: Option<String> = row.try_get("error_message")?;
            let (kind, data) = crate::server::store::requeue_event(&status, cp, code, message, why);
            append_event(&mut tx, &id, kind, &data).await?;
        }
        tx.commit().await?;
        Ok(rows.len())
    }

    /// Re-queues at once the runs held under leases starting with `prefix` (a worker node's graceful
    /// shutdown), without counting a crash.
    pub async fn hand_back(&self, prefix: &str) -> Result<usize, sqlx::Error> {
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
        let rows = sqlx::query(
            "UPDATE jobs SET status = 'queued', lease_owner = NULL, lease_expires_at = NULL \
             WHERE status = 'running' AND substr(lease_owner, 1, length(?1)) = ?1 \
             RETURNING id, checkpoint_iteration",
        )
        .bind(prefix)
        .fetch_all(&mut *tx)
        .await?;
        for row in &rows {
            let id: String = row.try_get("id")?;
            let cp: Option<i64> = row.try_get("checkpoint_iteration")?;
            append_event(
                &mut tx,
                &id,
                "queued",
                &crate::server::store::handed_back_event(cp),
            )
            .await?;
        }
        tx.commit().await?;
        Ok(rows.len())
    }
}
