//! The durable job queue in SQLite: the job state machine and its events.
//!
//! `queued → running → completed | failed | cancelled`, and `running → queued` when a run is interrupted
//! (shutdown, or a crash found at the next start). A worker claims a job with one
//! `UPDATE … WHERE status = 'queued' … RETURNING`, which sets `lease_owner` to the worker; every later write
//! of the run is conditioned on still holding that lease, so a job never runs twice at once and a stale
//! worker cannot overwrite it. Every state change appends its event row in the same transaction, so the
//! event log (what SSE serves) is exactly the job's history.

use serde_json::{Value, json};
use sqlx::{Row, Sqlite, SqlitePool, Transaction};

use super::runner::{Artifact, Checkpoint};

/// A job as stored.
#[derive(Debug, Clone)]
pub struct JobRow {
    pub seq: i64,
    pub id: String,
    pub tenant: String,
    pub kind: String,
    pub spec: Value,
    pub status: String,
    pub cancel_requested: bool,
    pub attempts: i64,
    pub iterations: i64,
    pub progress: Option<f64>,
    pub last_metrics: Option<Value>,
    pub summary: Option<Value>,
    pub error_code: Option<String>,
    pub error_message: Option<String>,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
    pub queued_ms: Option<i64>,
    pub run_ms: Option<i64>,
}

/// Columns selected for a [`JobRow`].
macro_rules! job_columns {
    () => {
        "seq, id, tenant, kind, spec, status, cancel_requested, attempts, iterations, progress, last_metrics, \
         summary, error_code, error_message, created_at, started_at, finished_at, \
         CAST(ROUND((julianday(COALESCE(started_at, strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))) - julianday(created_at)) * 86400000) AS INTEGER) AS queued_ms, \
         CASE WHEN started_at IS NULL THEN NULL ELSE CAST(ROUND((julianday(COALESCE(finished_at, strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))) - julianday(started_at)) * 86400000) AS INTEGER) END AS run_ms"
    };
}
pub(crate) use job_columns;

fn json_col(row: &sqlx::sqlite::SqliteRow, col: &str) -> Result<Option<Value>, sqlx::Error> {
    let text: Option<String> = row.try_get(col)?;
    Ok(text.and_then(|t| serde_json::from_str(&t).ok()))
}

impl JobRow {
    pub fn from_row(row: &sqlx::sqlite::SqliteRow) -> Result<JobRow, sqlx::Error> {
        Ok(JobRow {
            seq: row.try_get("seq")?,
            id: row.try_get("id")?,
            tenant: row.try_get("tenant")?,
            kind: row.try_get("kind")?,
            spec: json_col(row, "spec")?.unwrap_or(Value::Null),
            status: row.try_get("status")?,
            cancel_requested: row.try_get::<i64, _>("cancel_requested")? != 0,
            attempts: row.try_get("attempts")?,
            iterations: row.try_get("iterations")?,
            progress: row.try_get("progress")?,
            last_metrics: json_col(row, "last_metrics")?,
            summary: json_col(row, "summary")?,
            error_code: row.try_get("error_code")?,
            error_message: row.try_get("error_message")?,
            created_at: row.try_get("created_at")?,
            started_at: row.try_get("started_at")?,
            finished_at: row.try_get("finished_at")?,
            queued_ms: row.try_get("queued_ms")?,
            run_ms: row.try_get("run_ms")?,
        })
    }

    /// The job as the API shows it.
    pub fn to_json(&self) -> Value {
        json!({
            "id": self.id,
            "kind": self.kind,
            "status": self.status,
            "spec": self.spec,
            "cancel_requested": self.cancel_requested,
            "attempts": self.attempts,
            "progress": {
                "iterations": self.iterations,
                "fraction": self.progress,
            },
            "metrics": self.last_metrics,
            "summary": self.summary,
            "error": self.error_code.as_ref().map(|code| json!({
                "code": code,
                "message": self.error_message,
            })),
            "timings": {
                "created_at": self.created_at,
                "started_at": self.started_at,
                "finished_at": self.finished_at,
                "queued_ms": self.queued_ms,
                "run_ms": self.run_ms,
            },
        })
    }

    pub fn is_finished(&self) -> bool {
        is_terminal(&self.status)
    }
}

/// Whether a status (or event kind) ends a job.
pub fn is_terminal(status: &str) -> bool {
    matches!(status, "completed" | "failed" | "cancelled")
}

/// Appends an event to a job's log inside `tx`; returns its sequence number (the SSE id).
pub async fn append_event(
    tx: &mut Transaction<'static, Sqlite>,
    job_id: &str,
    kind: &str,
    data: &Value,
) -> Result<i64, sqlx::Error> {
    let row = sqlx::query(
        "INSERT INTO job_events (job_id, seq, kind, data) \
         SELECT ?1, COALESCE(MAX(seq), 0) + 1, ?2, ?3 FROM job_events WHERE job_id = ?1 RETURNING seq",
    )
    .bind(job_id)
    .bind(kind)
    .bind(data.to_string())
    .fetch_one(&mut **tx)
    .await?;
    row.try_get(0)
}

/// Loads one job of a tenant.
pub async fn get_job(
    pool: &SqlitePool,
    tenant: &str,
    id: &str,
) -> Result<Option<JobRow>, sqlx::Error> {
    let row = sqlx::query(concat!(
        "SELECT ",
        job_columns!(),
        " FROM jobs WHERE id = ?1 AND tenant = ?2"
    ))
    .bind(id)
    .bind(tenant)
    .fetch_optional(pool)
    .await?;
    row.as_ref().map(JobRow::from_row).transpose()
}

/// A job the worker claimed.
#[derive(Debug, Clone)]
pub struct Claimed {
    pub id: String,
    pub tenant: String,
    pub kind: String,
    pub spec: Value,
    pub attempts: i64,
    pub iterations: u64,
    pub cancel_requested: bool,
    pub checkpoint: Option<Checkpoint>,
}

/// Claims the oldest queued job for `owner`, or `None` when the queue is empty. Appends its `started` event.
pub async fn claim(pool: &SqlitePool, owner: &str) -> Result<Option<Claimed>, sqlx::Error> {
    let mut tx = pool.begin_with("BEGIN IMMEDIATE").await?;
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
    let claimed = Claimed {
        id: row.try_get("id")?,
        tenant: row.try_get("tenant")?,
        kind: row.try_get("kind")?,
        spec: serde_json::from_str(&row.try_get::<String, _>("spec")?).unwrap_or(Value::Null),
        attempts: row.try_get("attempts")?,
        iterations: row.try_get::<i64, _>("iterations")?.max(0) as u64,
        cancel_requested: row.try_get::<i64, _>("cancel_requested")? != 0,
        checkpoint,
    };
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

/// Records an iteration if `owner` still holds the job; returns whether a cancel was requested, or `None`
/// when the lease is gone.
pub async fn record_iteration(
    pool: &SqlitePool,
    job_id: &str,
    owner: &str,
    iteration: u64,
    progress: Option<f64>,
    metrics: &Value,
) -> Result<Option<bool>, sqlx::Error> {
    let mut tx = pool.begin_with("BEGIN IMMEDIATE").await?;
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
    pool: &SqlitePool,
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
    .execute(pool)
    .await?;
    Ok(done.rows_affected() == 1)
}

/// How a run ended, as the queue records it.
#[derive(Debug)]
pub enum Outcome {
    Completed {
        artifacts: Vec<Artifact>,
        summary: Value,
    },
    Failed {
        code: &'static str,
        message: String,
    },
    Cancelled,
    /// Back to the queue (shutdown); resumes from the last checkpoint.
    Requeued {
        reason: &'static str,
    },
}

impl Outcome {
    pub fn label(&self) -> &'static str {
        match self {
            Outcome::Completed { .. } => "completed",
            Outcome::Failed { .. } => "failed",
            Outcome::Cancelled => "cancelled",
            Outcome::Requeued { .. } => "requeued",
        }
    }
}

/// Ends a run held by `owner`; returns `false` (and changes nothing) when the lease is gone.
pub async fn finish(
    pool: &SqlitePool,
    job_id: &str,
    owner: &str,
    outcome: Outcome,
) -> Result<bool, sqlx::Error> {
    let mut tx = pool.begin_with("BEGIN IMMEDIATE").await?;
    let (status, summary, code, message) = match &outcome {
        Outcome::Completed { summary, .. } => ("completed", Some(summary.to_string()), None, None),
        Outcome::Failed { code, message } => ("failed", None, Some(*code), Some(message.clone())),
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
        Outcome::Completed { artifacts, summary } => {
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
                .bind(super::assets::sha256_hex(&a.data))
                .bind(&a.data)
                .execute(&mut *tx)
                .await?;
                names.push(a.name.clone());
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

/// At start: jobs left `running` by a previous process are re-queued (or cancelled, if a cancel was asked
/// for). Returns how many were recovered.
pub async fn recover(pool: &SqlitePool) -> Result<usize, sqlx::Error> {
    let mut tx = pool.begin_with("BEGIN IMMEDIATE").await?;
    let rows = sqlx::query(
        "UPDATE jobs SET status = CASE WHEN cancel_requested = 1 THEN 'cancelled' ELSE 'queued' END, \
             lease_owner = NULL, \
             finished_at = CASE WHEN cancel_requested = 1 THEN strftime('%Y-%m-%dT%H:%M:%fZ', 'now') ELSE NULL END, \
             error_code = CASE WHEN cancel_requested = 1 THEN 'cancelled' ELSE NULL END, \
             error_message = CASE WHEN cancel_requested = 1 THEN 'the job was cancelled' ELSE NULL END \
         WHERE status = 'running' RETURNING id, status, checkpoint_iteration",
    )
    .fetch_all(&mut *tx)
    .await?;
    for row in &rows {
        let id: String = row.try_get("id")?;
        let status: String = row.try_get("status")?;
        let cp: Option<i64> = row.try_get("checkpoint_iteration")?;
        if status == "cancelled" {
            append_event(&mut tx, &id, "cancelled", &json!({})).await?;
        } else {
            append_event(
                &mut tx,
                &id,
                "queued",
                &json!({ "reason": "recovered after a restart", "resume_from_iteration": cp }),
            )
            .await?;
        }
    }
    tx.commit().await?;
    Ok(rows.len())
}

/// Result of a cancel request.
pub enum CancelResult {
    NotFound,
    /// Cancelled while queued (final now).
    Cancelled,
    /// Running: the flag is set and the runner stops within one iteration.
    Requested,
    AlreadyFinished(String),
}

/// Cancels a tenant's job.
pub async fn cancel(
    pool: &SqlitePool,
    tenant: &str,
    id: &str,
) -> Result<CancelResult, sqlx::Error> {
    let mut tx = pool.begin_with("BEGIN IMMEDIATE").await?;
    let status: Option<String> =
        sqlx::query_scalar("SELECT status FROM jobs WHERE id = ?1 AND tenant = ?2")
            .bind(id)
            .bind(tenant)
            .fetch_optional(&mut *tx)
            .await?;
    let result = match status.as_deref() {
        None => CancelResult::NotFound,
        Some("queued") => {
            sqlx::query(
                "UPDATE jobs SET status = 'cancelled', cancel_requested = 1, error_code = 'cancelled', \
                     error_message = 'the job was cancelled', finished_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now') \
                 WHERE id = ?1",
            )
            .bind(id)
            .execute(&mut *tx)
            .await?;
            append_event(&mut tx, id, "cancelled", &json!({})).await?;
            CancelResult::Cancelled
        }
        Some("running") => {
            sqlx::query("UPDATE jobs SET cancel_requested = 1 WHERE id = ?1")
                .bind(id)
                .execute(&mut *tx)
                .await?;
            CancelResult::Requested
        }
        Some(other) => CancelResult::AlreadyFinished(other.to_string()),
    };
    tx.commit().await?;
    Ok(result)
}

/// Jobs per status (for /metrics).
pub async fn status_counts(pool: &SqlitePool) -> Result<Vec<(String, i64)>, sqlx::Error> {
    let rows = sqlx::query("SELECT status, COUNT(*) AS n FROM jobs GROUP BY status")
        .fetch_all(pool)
        .await?;
    rows.iter()
        .map(|r| Ok((r.try_get("status")?, r.try_get("n")?)))
        .collect()
}
