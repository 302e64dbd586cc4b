//! The PostgreSQL engine of the [`Store`](super::Store), for any number of API nodes and worker nodes
//! sharing one database: versioned migrations from `migrations/postgres/` (the same versions, tables and
//! columns as SQLite's), claims with `FOR UPDATE SKIP LOCKED`, and `NOTIFY` on every event and every
//! queued job, which other nodes `LISTEN` to ([`Notifications`]).
//!
//! Concurrency: transactions run at PostgreSQL's default `READ COMMITTED`. Every transaction that appends a
//! job's event first locks that job's row (the `UPDATE` of a state change, or `SELECT … FOR UPDATE`), so
//! the events of one job are appended one transaction at a time and their numbers (`MAX(seq) + 1`, read
//! after the lock) stay contiguous. A claim locks the oldest queued row that no other claim holds (`SKIP
//! LOCKED`), so concurrent workers never wait on each other nor claim the same job; the re-queuing of
//! expired leases skips rows another node is re-queuing. Submissions are stored one at a time (a
//! transaction-level advisory lock), as SQLite's writer lock stores them, so that the listing order (`seq`)
//! and `created_at` agree.
//!
//! Timestamps are UTC text like SQLite's (the migration's `skintight_now()`), and the lease arithmetic is
//! done by the database's clock alone, so the nodes' clocks need not agree.

use std::time::Duration;

use serde_json::{Value, json};
use sqlx::postgres::{PgConnectOptions, PgListener, PgPool, PgPoolOptions, PgRow};
use sqlx::{Postgres, Row, Transaction};

use super::{ArtifactMeta, Requeue, claimed_columns, secs};
use crate::server::model::{
    ArtifactInfo, Asset, AssetInfo, CancelResult, Claimed, EventRecord, Inserted, JobRow, NewJob,
    Outcome, sha256_hex,
};

/// The versioned migrations compiled into the binary.
pub static MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("./migrations/postgres");

/// The channel on which a committed event is announced (payload: the job id).
const EVENTS_CHANNEL: &str = "skintight_events";
/// The channel on which a queued job is announced (payload: the job id).
const JOBS_CHANNEL: &str = "skintight_jobs";

/// The advisory lock that orders submissions (an arbitrary constant of this service).
const SUBMISSION_LOCK: i64 = 0x736b_696e_7469;

/// A PostgreSQL database; cheap to clone (a connection pool).
#[derive(Clone, Debug)]
pub struct PgStore {
    pool: PgPool,
}

/// What another node announced.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Notice {
    /// An event of this job was committed.
    Event(String),
    /// This job was queued (new, or taken back from a worker).
    Queued(String),
}

/// A `LISTEN`ing connection of its own.
pub struct Notifications(PgListener);

impl Notifications {
    /// The next announcement. After an error the connection is re-established by the next call, and
    /// announcements in between are lost: callers also poll.
    pub async fn recv(&mut self) -> Result<Notice, sqlx::Error> {
        let n = self.0.recv().await?;
        Ok(if n.channel() == JOBS_CHANNEL {
            Notice::Queued(n.payload().to_string())
        } else {
            Notice::Event(n.payload().to_string())
        })
    }
}

/// Columns selected for a [`JobRow`].
macro_rules! job_columns {
    () => {
        "seq, id, tenant, kind, spec, status, cancel_requested, attempts, iterations, progress, last_metrics, \
         summary, error_code, error_message, created_at, started_at, finished_at, \
         CAST(ROUND(EXTRACT(EPOCH FROM (COALESCE(started_at, finished_at, skintight_now())::timestamptz - created_at::timestamptz)) * 1000) AS BIGINT) AS queued_ms, \
         CASE WHEN started_at IS NULL THEN NULL ELSE CAST(ROUND(EXTRACT(EPOCH FROM (COALESCE(finished_at, skintight_now())::timestamptz - started_at::timestamptz)) * 1000) AS BIGINT) END AS run_ms"
    };
}

/// The condition of every write of a run: the job is running under the lease `$2`, which has not expired.
macro_rules! held {
    () => {
        "id = $1 AND lease_owner = $2 AND status = 'running' AND lease_expires_at > skintight_now()"
    };
}

super::row_mappers!(PgRow);

/// Appends an event to a job's log inside `tx` (whose job row is locked) and announces it on commit;
/// returns its sequence number.
async fn append_event(
    tx: &mut Transaction<'static, Postgres>,
    job_id: &str,
    kind: &str,
    data: &Value,
) -> Result<i64, sqlx::Error> {
    let seq: i64 = sqlx::query_scalar(
        "INSERT INTO job_events (job_id, seq, kind, data) \
         SELECT $1, COALESCE(MAX(seq), 0) + 1, $2, $3 FROM job_events WHERE job_id = $1 RETURNING seq",
    )
    .bind(job_id)
    .bind(kind)
    .bind(data.to_string())
    .fetch_one(&mut **tx)
    .await?;
    notify(tx, EVENTS_CHANNEL, job_id).await?;
    Ok(seq)
}

/// `NOTIFY channel, payload`, delivered when `tx` commits (and not at all if it rolls back).
async fn notify(
    tx: &mut Transaction<'static, Postgres>,
    channel: &str,
    payload: &str,
) -> Result<(), sqlx::Error> {
    sqlx::query("SELECT pg_notify($1, $2)")
        .bind(channel)
        .bind(payload)
        .execute(&mut **tx)
        .await?;
    Ok(())
}

/// Each method below is the PostgreSQL side of the [`Store`](super::Store) method of the same name, which
/// documents it.
impl PgStore {
    /// Connects to the database at `url` and brings its schema up to date (migrations run under
    /// PostgreSQL's advisory lock, so nodes starting together apply them once).
    pub async fn open(url: &str, max_connections: u32) -> Result<PgStore, sqlx::Error> {
        let options: PgConnectOptions = url.parse()?;
        let pool = PgPoolOptions::new()
            .max_connections(max_connections.max(2))
            .min_connections(1)
            .acquire_timeout(Duration::from_secs(10))
            .connect_with(options.application_name("skintight"))
            .await?;
        MIGRATOR.run(&pool).await?;
        Ok(PgStore { pool })
    }

    pub(super) async fn ping(&self) -> Result<(), sqlx::Error> {
        sqlx::query("SELECT 1").execute(&self.pool).await?;
        Ok(())
    }

    pub(super) async fn close(&self) {
        self.pool.close().await;
    }

    /// A connection listening to the announcements of every node.
    pub async fn notifications(&self) -> Result<Notifications, sqlx::Error> {
        let mut listener = PgListener::connect_with(&self.pool).await?;
        listener.listen_all([EVENTS_CHANNEL, JOBS_CHANNEL]).await?;
        Ok(Notifications(listener))
    }

    // Assets.

    pub async fn insert_asset(
        &self,
        id: &str,
        tenant: &str,
        format: &str,
        data: &[u8],
    ) -> Result<(AssetInfo, bool), sqlx::Error> {
        let sha = sha256_hex(data);
        let inserted = sqlx::query(
            "INSERT INTO assets (id, tenant, sha256, bytes, format, data) VALUES ($1, $2, $3, $4, $5, $6) \
             ON CONFLICT (tenant, sha256) DO NOTHING",
        )
        .bind(id)
        .bind(tenant)
        .bind(&sha)
        .bind(data.len() as i64)
        .bind(format)
        .bind(data)
        .execute(&self.pool)
        .await?
        .rows_affected()
            == 1;
        let row = sqlx::query(
            "SELECT id, sha256, bytes, format, created_at FROM assets WHERE tenant = $1 AND sha256 = $2",
        )
        .bind(tenant)
        .bind(&sha)
        .fetch_one(&self.pool)
        .await?;
        Ok((asset_info(&row)?, inserted))
    }

    pub async fn asset_info(
        &self,
        tenant: &str,
        id: &str,
    ) -> Result<Option<AssetInfo>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT id, sha256, bytes, format, created_at FROM assets WHERE id = $1 AND tenant = $2",
        )
        .bind(id)
        .bind(tenant)
        .fetch_optional(&self.pool)
        .await?;
        row.as_ref().map(asset_info).transpose()
    }

    pub async fn load_asset(&self, tenant: &str, id: &str) -> Result<Option<Asset>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT id, format, sha256, data FROM assets WHERE id = $1 AND tenant = $2",
        )
        .bind(id)
        .bind(tenant)
        .fetch_optional(&self.pool)
        .await?;
        row.map(|row| {
            Ok(Asset {
                id: row.try_get("id")?,
                format: row.try_get("format")?,
                sha256: row.try_get("sha256")?,
                data: row.try_get("data")?,
            })
        })
        .transpose()
    }

    // Jobs.

    pub async fn insert_job(&self, job: &NewJob) -> Result<Inserted, sqlx::Error> {
        let mut tx = self.pool.begin().await?;
        // Submissions are stored one at a time, as on SQLite, so that `seq` (the listing order) and
        // `created_at` (read after the lock) agree: newest first by one is newest first by the other.
        sqlx::query("SELECT pg_advisory_xact_lock($1)")
            .bind(SUBMISSION_LOCK)
            .execute(&mut *tx)
            .await?;
        // A unique violation would abort the transaction: conflicting rows are simply not inserted.
        let inserted = sqlx::query(
            "INSERT INTO jobs (id, tenant, kind, spec, idempotency_key, request_hash, status, created_at) \
             VALUES ($1, $2, $3, $4, $5, $6, 'queued', \
                 to_char(clock_timestamp() AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS.MS\"Z\"')) \
             ON CONFLICT DO NOTHING",
        )
        .bind(&job.id)
        .bind(&job.tenant)
        .bind(&job.kind)
        .bind(&job.spec)
        .bind(&job.idempotency_key)
        .bind(&job.request_hash)
        .execute(&mut *tx)
        .await?
        .rows_affected();
        if inserted == 0 {
            tx.rollback().await?;
            if job.idempotency_key.is_some() {
                return Ok(Inserted::KeyTaken);
            }
            return Err(sqlx::Error::Protocol(format!(
                "job id {} already exists",
                job.id
            )));
        }
        // The new row is this transaction's own: no one else can append to its log before the commit.
        append_event(&mut tx, &job.id, "queued", &json!({ "kind": job.kind })).await?;
        notify(&mut tx, JOBS_CHANNEL, &job.id).await?;
        tx.commit().await?;
        Ok(Inserted::Queued)
    }

    pub async fn job_by_idempotency_key(
        &self,
        tenant: &str,
        key: &str,
    ) -> Result<Option<(String, JobRow)>, sqlx::Error> {
        let row = sqlx::query(concat!(
            "SELECT request_hash, ",
            job_columns!(),
            " FROM jobs WHERE tenant = $1 AND idempotency_key = $2"
        ))
        .bind(tenant)
        .bind(key)
        .fetch_optional(&self.pool)
        .await?;
        row.map(|row| Ok((row.try_get("request_hash")?, job_row(&row)?)))
            .transpose()
    }

    pub async fn get_job(&self, tenant: &str, id: &str) -> Result<Option<JobRow>, sqlx::Error> {
        let row = sqlx::query(concat!(
            "SELECT ",
            job_columns!(),
            " FROM jobs WHERE id = $1 AND tenant = $2"
        ))
        .bind(id)
        .bind(tenant)
        .fetch_optional(&self.pool)
        .await?;
        row.as_ref().map(job_row).transpose()
    }

    pub async fn list_jobs(
        &self,
        tenant: &str,
        before: i64,
        status: Option<&str>,
        limit: i64,
    ) -> Result<Vec<JobRow>, sqlx::Error> {
        let rows = sqlx::query(concat!(
            "SELECT ",
            job_columns!(),
            " FROM jobs WHERE tenant = $1 AND seq < $2 AND ($3::text IS NULL OR status = $3) \
             ORDER BY seq DESC LIMIT $4"
        ))
        .bind(tenant)
        .bind(before)
        .bind(status)
        .bind(limit)
        .fetch_all(&self.pool)
        .await?;
        rows.iter().map(job_row).collect()
    }

    pub async fn job_status(&self, id: &str) -> Result<Option<String>, sqlx::Error> {
        sqlx::query_scalar("SELECT status FROM jobs WHERE id = $1")
            .bind(id)
            .fetch_optional(&self.pool)
            .await
    }

    pub async fn cancel_requested(&self, id: &str) -> Result<bool, sqlx::Error> {
        sqlx::query_scalar::<_, i64>("SELECT cancel_requested FROM jobs WHERE id = $1")
            .bind(id)
            .fetch_one(&self.pool)
            .await
            .map(|v| v != 0)
    }

    pub async fn cancel(&self, tenant: &str, id: &str) -> Result<CancelResult, sqlx::Error> {
        let mut tx = self.pool.begin().await?;
        let status: Option<String> =
            sqlx::query_scalar("SELECT status FROM jobs WHERE id = $1 AND tenant = $2 FOR UPDATE")
                .bind(id)
                .bind(tenant)
                .fetch_optional(&mut *tx)
                .await?;
        let result = match status.as_deref() {
            None => CancelResult::NotFound,
            Some("queued") => {
                sqlx::query(
                    "UPDATE jobs SET status = 'cancelled', cancel_requested = 1, error_code = 'cancelled', \
                         error_message = 'the job was cancelled', finished_at = skintight_now() \
                     WHERE id = $1",
                )
                .bind(id)
                .execute(&mut *tx)
                .await?;
                append_event(&mut tx, id, "cancelled", &json!({})).await?;
                CancelResult::Cancelled
            }
            Some("running") => {
                sqlx::query("UPDATE jobs SET cancel_requested = 1 WHERE id = $1")
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

    pub async fn status_counts(&self) -> Result<Vec<(String, i64)>, sqlx::Error> {
        let rows = sqlx::query("SELECT status, COUNT(*) AS n FROM jobs GROUP BY status")
            .fetch_all(&self.pool)
            .await?;
        rows.iter()
            .map(|r| Ok((r.try_get("status")?, r.try_get("n")?)))
            .collect()
    }

    // Events and artifacts.

    pub async fn events_after(
        &self,
        job_id: &str,
        after: i64,
        limit: i64,
    ) -> Result<Vec<EventRecord>, sqlx::Error> {
        let rows = sqlx::query(
            "SELECT seq, kind, data FROM job_events WHERE job_id = $1 AND seq > $2 ORDER BY seq LIMIT $3",
        )
        .bind(job_id)
        .bind(after)
        .bind(limit)
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|row| {
                Ok(EventRecord {
                    seq: row.try_get("seq")?,
                    kind: row.try_get("kind")?,
                    data: row.try_get("data")?,
                })
            })
            .collect()
    }

    pub async fn list_artifacts(&self, job_id: &str) -> Result<Vec<ArtifactInfo>, sqlx::Error> {
        let rows = sqlx::query(
            "SELECT name, content_type, bytes, sha256 FROM artifacts WHERE job_id = $1 ORDER BY name",
        )
        .bind(job_id)
        .fetch_all(&self.pool)
        .await?;
        rows.iter()
            .map(|r| {
                Ok(ArtifactInfo {
                    name: r.try_get("name")?,
                    content_type: r.try_get("content_type")?,
                    bytes: r.try_get("bytes")?,
                    sha256: r.try_get("sha256")?,
                })
            })
            .collect()
    }

    pub async fn artifact_meta(
        &self,
        job_id: &str,
        name: &str,
    ) -> Result<Option<ArtifactMeta>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT content_type, sha256, bytes FROM artifacts WHERE job_id = $1 AND name = $2",
        )
        .bind(job_id)
        .bind(name)
        .fetch_optional(&self.pool)
        .await?;
        row.map(|row| {
            Ok(ArtifactMeta {
                content_type: row.try_get("content_type")?,
                sha256: row.try_get("sha256")?,
                bytes: row.try_get("bytes")?,
            })
        })
        .transpose()
    }

    /// Up to `len` bytes of an artifact from byte `offset` (`substring` of a `bytea` counts bytes, from
    /// 1; PostgreSQL reads only the slices of the TOASTed value it needs when the column is stored
    /// uncompressed, and decompresses it otherwise).
    pub async fn artifact_chunk(
        &self,
        job_id: &str,
        name: &str,
        offset: i64,
        len: i64,
    ) -> Result<Vec<u8>, sqlx::Error> {
        let data: Option<Vec<u8>> = sqlx::query_scalar(
            "SELECT substring(data FROM ($3 + 1)::int FOR $4::int) FROM artifacts \
             WHERE job_id = $1 AND name = $2",
        )
        .bind(job_id)
        .bind(name)
        .bind(offset)
        .bind(len)
        .fetch_optional(&self.pool)
        .await?;
        Ok(data.unwrap_or_default())
    }

    // Runs.

    pub async fn claim(
        &self,
        lease: &str,
        lease_for: Duration,
    ) -> Result<Option<Claimed>, sqlx::Error> {
        let mut tx = self.pool.begin().await?;
        let row = sqlx::query(concat!(
            "WITH next AS (SELECT seq FROM jobs WHERE status = 'queued' ORDER BY seq LIMIT 1 \
                 FOR UPDATE SKIP LOCKED) \
             UPDATE jobs SET status = 'running', lease_owner = $1, attempts = attempts + 1, \
                 lease_expires_at = skintight_later($2), \
                 started_at = COALESCE(started_at, skintight_now()) \
             FROM next WHERE jobs.seq = next.seq \
             RETURNING ",
            claimed_columns!()
        ))
        .bind(lease)
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

    pub async fn renew_lease(
        &self,
        job_id: &str,
        lease: &str,
        lease_for: Duration,
    ) -> Result<Option<bool>, sqlx::Error> {
        let cancel: Option<i64> = sqlx::query_scalar(concat!(
            "UPDATE jobs SET lease_expires_at = skintight_later($3) WHERE ",
            held!(),
            " RETURNING cancel_requested"
        ))
        .bind(job_id)
        .bind(lease)
        .bind(secs(lease_for))
        .fetch_optional(&self.pool)
        .await?;
        Ok(cancel.map(|c| c != 0))
    }

    pub async fn running_job(
        &self,
        job_id: &str,
        lease: &str,
    ) -> Result<Option<Claimed>, sqlx::Error> {
        let row = sqlx::query(concat!(
            "SELECT ",
            claimed_columns!(),
            " FROM jobs WHERE ",
            held!()
        ))
        .bind(job_id)
        .bind(lease)
        .fetch_optional(&self.pool)
        .await?;
        row.as_ref().map(claimed_of).transpose()
    }

    pub async fn record_iteration(
        &self,
        job_id: &str,
        lease: &str,
        iteration: u64,
        progress: Option<f64>,
        metrics: &Value,
    ) -> Result<Option<bool>, sqlx::Error> {
        let mut tx = self.pool.begin().await?;
        let cancel: Option<i64> = sqlx::query_scalar(concat!(
            "UPDATE jobs SET iterations = $3, progress = COALESCE($4, progress), last_metrics = $5 WHERE ",
            held!(),
            " RETURNING cancel_requested"
        ))
        .bind(job_id)
        .bind(lease)
        .bind(iteration as i64)
        .bind(progress)
        .bind(metrics.to_string())
        .fetch_optional(&mut *tx)
        .await?;
        let Some(cancel) = cancel else {
            tx.rollback().await?;
            return Ok(None);
        };
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

    pub async fn save_checkpoint(
        &self,
        job_id: &str,
        lease: &str,
        iteration: u64,
        data: &[u8],
    ) -> Result<bool, sqlx::Error> {
        let done = sqlx::query(concat!(
            "UPDATE jobs SET checkpoint = $3, checkpoint_iteration = $4 WHERE ",
            held!()
        ))
        .bind(job_id)
        .bind(lease)
        .bind(data)
        .bind(iteration as i64)
        .execute(&self.pool)
        .await?;
        Ok(done.rows_affected() == 1)
    }

    pub async fn finish(
        &self,
        job_id: &str,
        lease: &str,
        outcome: Outcome,
    ) -> Result<bool, sqlx::Error> {
        let mut tx = self.pool.begin().await?;
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
        let done = sqlx::query(concat!(
            "UPDATE jobs SET status = $3, lease_owner = NULL, lease_expires_at = NULL, summary = $4, \
                 error_code = $5, error_message = $6, \
                 progress = CASE WHEN $3 = 'completed' THEN 1.0 ELSE progress END, \
                 finished_at = CASE WHEN $3 = 'queued' THEN NULL ELSE skintight_now() END \
             WHERE ",
            held!()
        ))
        .bind(job_id)
        .bind(lease)
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
                        "INSERT INTO artifacts (job_id, name, content_type, bytes, sha256, data) \
                         VALUES ($1, $2, $3, $4, $5, $6) \
                         ON CONFLICT (job_id, name) DO UPDATE SET content_type = EXCLUDED.content_type, \
                             bytes = EXCLUDED.bytes, sha256 = EXCLUDED.sha256, data = EXCLUDED.data",
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
                notify(&mut tx, JOBS_CHANNEL, job_id).await?;
            }
        }
        tx.commit().await?;
        Ok(true)
    }

    pub async fn requeue_runs(
        &self,
        max_attempts: u32,
        why: Requeue,
    ) -> Result<usize, sqlx::Error> {
        let mut tx = self.pool.begin().await?;
        let rows = sqlx::query(
            "UPDATE jobs SET crashes = crashes + 1, \
                 status = CASE WHEN cancel_requested = 1 THEN 'cancelled' \
                     WHEN crashes + 1 >= $1 THEN 'failed' ELSE 'queued' END, \
                 lease_owner = NULL, lease_expires_at = NULL, \
                 finished_at = CASE WHEN cancel_requested = 1 OR crashes + 1 >= $1 \
                     THEN skintight_now() ELSE NULL END, \
                 error_code = CASE WHEN cancel_requested = 1 THEN 'cancelled' \
                     WHEN crashes + 1 >= $1 THEN 'crashed_repeatedly' ELSE NULL END, \
                 error_message = CASE WHEN cancel_requested = 1 THEN 'the job was cancelled' \
                     WHEN crashes + 1 >= $1 THEN $3::text || (crashes + 1)::text || \
                         ' runs of this job (jobs.max_attempts = ' || $1::text || '); it is not run again' \
                     ELSE NULL END \
             WHERE seq IN (SELECT seq FROM jobs WHERE status = 'running' AND (NOT $2 \
                     OR lease_expires_at IS NULL OR lease_expires_at <= skintight_now()) \
                 FOR UPDATE SKIP LOCKED) \
             RETURNING id, status, checkpoint_iteration, error_code, error_message",
        )
        .bind(i64::from(max_attempts))
        .bind(why == Requeue::LeaseExpired)
        .bind(why.cause())
        .fetch_all(&mut *tx)
        .await?;
        for row in &rows {
            let id: String = row.try_get("id")?;
            let status: String = row.try_get("status")?;
            let cp: Option<i64> = row.try_get("checkpoint_iteration")?;
            let code: Option<String> = row.try_get("error_code")?;
            let message: Option<String> = row.try_get("error_message")?;
            let (kind, data) = super::requeue_event(&status, cp, code, message, why);
            append_event(&mut tx, &id, kind, &data).await?;
            if kind == "queued" {
                notify(&mut tx, JOBS_CHANNEL, &id).await?;
            }
        }
        tx.commit().await?;
        Ok(rows.len())
    }

    pub async fn hand_back(&self, prefix: &str) -> Result<usize, sqlx::Error> {
        let mut tx = self.pool.begin().await?;
        let rows = sqlx::query(
            "UPDATE jobs SET status = 'queued', lease_owner = NULL, lease_expires_at = NULL \
             WHERE status = 'running' AND starts_with(lease_owner, $1) \
             RETURNING id, checkpoint_iteration",
        )
        .bind(prefix)
        .fetch_all(&mut *tx)
        .await?;
        for row in &rows {
            let id: String = row.try_get("id")?;
            let cp: Option<i64> = row.try_get("checkpoint_iteration")?;
            append_event(&mut tx, &id, "queued", &super::handed_back_event(cp)).await?;
            notify(&mut tx, JOBS_CHANNEL, &id).await?;
        }
        tx.commit().await?;
        Ok(rows.len())
    }
}
