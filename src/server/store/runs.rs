//! The writes of a job's run, each conditioned on the worker's lease: claim, iterations, checkpoints,
//! finish, and the recovery of runs a previous process left behind (the state machine of
//! [`crate::server::queue`]).
//!
//! A worker claims a job with one `UPDATE … WHERE status = 'queued' … RETURNING`, which sets `lease_owner`
//! to the worker; every later write of the run is conditioned on still holding that lease, so a job never
//! runs twice at once and a stale worker cannot overwrite it. Every state change appends its event row in
//! the same transaction.

use serde_json::{Value, json};
use sqlx::Row;

use super::{Store, append_event};
use crate::server::model::{Checkpoint, Claimed, Outcome, sha256_hex};

/// A [`Claimed`] job from a row with its columns.
fn claimed_of(row: &sqlx::sqlite::SqliteRow) -> Result<Claimed, sqlx::Error> {
    let checkpoint = match (
        row.try_get::<Option<Vec<u8>>, _>("checkpoint")?,
        row.try_get::<Option<i64>, _>("checkpoint_iteration")?,
    ) {
        (Some(data), Some(it)) => Some(Checkpoint {
            iteration: it.max(0) as u64,
            data,
        }),
        _ => None,
    };
    Ok(Claimed {
        id: row.try_get("id")?,
        tenant: row.try_get("tenant")?,
        kind: row.try_get("kind")?,
        spec: serde_json::from_str(&row.try_get::<String, _>("spec")?).unwrap_or(Value::Null),
        attempts: row.try_get("attempts")?,
        iterations: row.try_get::<i64, _>("iterations")?.max(0) as u64,
        cancel_requested: row.try_get::<i64, _>("cancel_requested")? != 0,
        checkpoint,
    })
}

impl Store {
    /// Claims the oldest queued job for `owner`, or `None` when the queue is empty. Appends its `started`
    /// event.
    pub async fn claim(&self, owner: &str) -> Result<Option<Claimed>, sqlx::Error> {
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
        let row = sqlx::query(
            "UPDATE jobs SET status = 'running', lease_owner = ?1, attempts = attempts + 1, \
                 started_at = COALESCE(started_at, strftime('%Y-%m-%dT%H:%M:%fZ', 'now')) \
             WHERE seq = (SELECT seq FROM jobs WHERE status = 'queued' ORDER BY seq LIMIT 1) AND status = 'queued' \
             RETURNING id, tenant, kind, spec, attempts, iterations, cancel_requested, checkpoint, checkpoint_iteration",
        )
        .bind(owner)
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

    /// The job `owner` holds as running (what [`Self::claim`] returned to that worker), read again by the
    /// job process that runs it; `None` when the lease is gone.
    pub async fn running_job(
        &self,
        job_id: &str,
        owner: &str,
    ) -> Result<Option<Claimed>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT id, tenant, kind, spec, attempts, iterations, cancel_requested, checkpoint, checkpoint_iteration \
             FROM jobs WHERE id = ?1 AND lease_owner = ?2 AND status = 'running'",
        )
        .bind(job_id)
        .bind(owner)
        .fetch_optional(&self.pool)
        .await?;
        row.as_ref().map(claimed_of).transpose()
    }

    /// Records an iteration if `owner` still holds the job; returns whether a cancel was requested, or
    /// `None` when the lease is gone.
    pub async fn record_iteration(
        &self,
        job_id: &str,
        owner: &str,
        iteration: u64,
        progress: Option<f64>,
        metrics: &Value,
    ) -> Result<Option<bool>, sqlx::Error> {
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
        let row = sqlx::query(
            "UPDATE jobs SET iterations = ?3, progress = COALESCE(?4, progress), last_metrics = ?5 \
             WHERE id = ?1 AND lease_owner = ?2 AND status = 'running' RETURNING cancel_requested",
        )
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

    /// Saves a checkpoint if `owner` still holds the job; `false` when the lease is gone.
    pub async fn save_checkpoint(
        &self,
        job_id: &str,
        owner: &str,
        iteration: u64,
        data: &[u8],
    ) -> Result<bool, sqlx::Error> {
        let done = sqlx::query(
            "UPDATE jobs SET checkpoint = ?3, checkpoint_iteration = ?4 \
             WHERE id = ?1 AND lease_owner = ?2 AND status = 'running'",
        )
        .bind(job_id)
        .bind(owner)
        .bind(data)
        .bind(iteration as i64)
        .execute(&self.pool)
        .await?;
        Ok(done.rows_affected() == 1)
    }

    /// Ends a run held by `owner` (storing a completed job's artifacts); returns `false` (and changes
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
            "UPDATE jobs SET status = ?3, lease_owner = NULL, summary = ?4, error_code = ?5, error_message = ?6, \
                 progress = CASE WHEN ?3 = 'completed' THEN 1.0 ELSE progress END, \
                 finished_at = CASE WHEN ?3 = 'queued' THEN NULL ELSE strftime('%Y-%m-%dT%H:%M:%fZ', 'now') END \
             WHERE id = ?1 AND lease_owner = ?2 AND status = 'running'",
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

    /// At start: jobs left `running` by a previous process (their run crashed with it) are re-queued, or
    /// cancelled if a cancel was asked for, or — once `max_attempts` runs have crashed — failed with code
    /// `crashed_repeatedly` (spec and events kept). Returns how many were recovered.
    pub async fn recover(&self, max_attempts: u32) -> Result<usize, sqlx::Error> {
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
        let rows = sqlx::query(
            "UPDATE jobs SET crashes = crashes + 1, \
                 status = CASE WHEN cancel_requested = 1 THEN 'cancelled' \
                     WHEN crashes + 1 >= ?1 THEN 'failed' ELSE 'queued' END, \
                 lease_owner = NULL, \
                 finished_at = CASE WHEN cancel_requested = 1 OR crashes + 1 >= ?1 \
                     THEN strftime('%Y-%m-%dT%H:%M:%fZ', 'now') ELSE NULL END, \
                 error_code = CASE WHEN cancel_requested = 1 THEN 'cancelled' \
                     WHEN crashes + 1 >= ?1 THEN 'crashed_repeatedly' ELSE NULL END, \
                 error_message = CASE WHEN cancel_requested = 1 THEN 'the job was cancelled' \
                     WHEN crashes + 1 >= ?1 THEN 'the server died during ' || (crashes + 1) || \
                         ' runs of this job (jobs.max_attempts = ' || ?1 || '); it is not run again' \
                     ELSE NULL END \
             WHERE status = 'running' RETURNING id, status, checkpoint_iteration, error_code, error_message",
        )
        .bind(i64::from(max_attempts))
        .fetch_all(&mut *tx)
        .await?;
        for row in &rows {
            let id: String = row.try_get("id")?;
            let status: String = row.try_get("status")?;
            let cp: Option<i64> = row.try_get("checkpoint_iteration")?;
            match status.as_str() {
                "cancelled" => append_event(&mut tx, &id, "cancelled", &json!({})).await?,
                "failed" => {
                    let code: Option<String> = row.try_get("error_code")?;
                    let message: Option<String> = row.try_get("error_message")?;
                    append_event(
                        &mut tx,
                        &id,
                        "failed",
                        &json!({ "error": { "code": code, "message": message } }),
                    )
                    .await?
                }
                _ => append_event(
                    &mut tx,
                    &id,
                    "queued",
                    &json!({ "reason": "recovered after a restart", "resume_from_iteration": cp }),
                )
                .await?,
            };
        }
        tx.commit().await?;
        Ok(rows.len())
    }
}
