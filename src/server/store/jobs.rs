//! Jobs: submission, reads for the API, cancel, and the counts `/metrics` shows.

use serde_json::json;

use super::engine::{Engine, EngineStore};
use super::events::{EventsSql, announce_queued, append_event};
use super::rows;
use super::statement::Statement;
use crate::server::model::{CancelResult, Inserted, JobRow, NewJob};

/// The job statements, in the dialect's clock, date arithmetic and locks. Those that read a [`JobRow`]
/// (`job_columns!`) and the cancel of a queued job are the same text around the first two, stamped into
/// each engine by `job_statements!`.
pub trait JobsSql {
    /// Makes a submission wait for the one before it to commit, so that the listing order (`seq`) and
    /// `created_at` agree; `None` where the write lock of [`Engine::BEGIN_WRITE`] already does.
    const LOCK_SUBMISSIONS: Option<&'static str>;
    /// Inserts a queued job (id, tenant, kind, spec, idempotency key, request hash); a job that conflicts
    /// with a stored one (its id, or its tenant's idempotency key) is not inserted.
    const INSERT_JOB: &'static str;
    /// The request hash and the job of a tenant's idempotency key (tenant, key).
    const JOB_BY_KEY: &'static str;
    /// A tenant's job (id, tenant).
    const GET_JOB: &'static str;
    /// Up to `$4` jobs of a tenant (`$1`) with `seq < $2`, newest first, of the status `$3` unless it is
    /// `NULL`.
    const LIST_JOBS: &'static str;
    /// A tenant's job's status (id, tenant), locking the job for the cancel that follows.
    const STATUS_FOR_CANCEL: &'static str;
    /// Cancels a queued job at once (id).
    const CANCEL_QUEUED: &'static str;
}

/// The columns of a [`JobRow`] in a dialect whose clock is `$now!()` and in which `$millis!(from, to)` is
/// the milliseconds from the time `from` to the time `to`: with the waiting time (to the start, or to the
/// end of a job that never started, or to now) and the running time (to the end, or to now).
macro_rules! job_columns {
    ($now:ident, $millis:ident) => {
        concat!(
            "seq, id, tenant, kind, spec, status, cancel_requested, attempts, iterations, progress, \
             last_metrics, summary, error_code, error_message, created_at, started_at, finished_at, ",
            $millis!("created_at", concat!("COALESCE(started_at, finished_at, ", $now!(), ")")),
            " AS queued_ms, CASE WHEN started_at IS NULL THEN NULL ELSE ",
            $millis!("started_at", concat!("COALESCE(finished_at, ", $now!(), ")")),
            " END AS run_ms"
        )
    };
}
pub(super) use job_columns;

/// Stamps into an engine's [`JobsSql`] the statements both dialects write alike around their clock
/// `$now!()` and their `$millis!(from, to)` (see `job_columns!`).
macro_rules! job_statements {
    ($now:ident, $millis:ident) => {
        const JOB_BY_KEY: &'static str = concat!(
            "SELECT request_hash, ",
            $crate::server::store::jobs::job_columns!($now, $millis),
            " FROM jobs WHERE tenant = $1 AND idempotency_key = $2"
        );
        const GET_JOB: &'static str = concat!(
            "SELECT ",
            $crate::server::store::jobs::job_columns!($now, $millis),
            " FROM jobs WHERE id = $1 AND tenant = $2"
        );
        const LIST_JOBS: &'static str = concat!(
            "SELECT ",
            $crate::server::store::jobs::job_columns!($now, $millis),
            " FROM jobs WHERE tenant = $1 AND seq < $2 AND (CAST($3 AS TEXT) IS NULL OR status = $3) \
             ORDER BY seq DESC LIMIT $4"
        );
        const CANCEL_QUEUED: &'static str = concat!(
            "UPDATE jobs SET status = 'cancelled', cancel_requested = 1, error_code = 'cancelled', \
                 error_message = 'the job was cancelled', finished_at = ",
            $now!(),
            " WHERE id = $1"
        );
    };
}
pub(super) use job_statements;

/// A job's status, whoever its tenant (id).
const STATUS: &str = "SELECT status FROM jobs WHERE id = $1";
/// Whether a cancel was requested (id).
const CANCEL_REQUESTED: &str = "SELECT cancel_requested FROM jobs WHERE id = $1";
/// Asks a running job's worker to cancel it (id).
const REQUEST_CANCEL: &str = "UPDATE jobs SET cancel_requested = 1 WHERE id = $1";
/// Jobs per status.
const STATUS_COUNTS: &str = "SELECT status, COUNT(*) AS n FROM jobs GROUP BY status";

impl<E: Engine + JobsSql + EventsSql> EngineStore<E> {
    /// [`Store::insert_job`](super::Store::insert_job) on this engine.
    pub async fn insert_job(&self, job: &NewJob) -> Result<Inserted, sqlx::Error> {
        let mut tx = self.begin_write().await?;
        if let Some(lock) = E::LOCK_SUBMISSIONS {
            Statement::<E>::new(lock).execute(&mut tx).await?;
        }
        // A conflict is not inserted rather than an error, which would abort a PostgreSQL transaction.
        let inserted = Statement::<E>::new(E::INSERT_JOB)
            .bind(job.id.as_str())
            .bind(job.tenant.as_str())
            .bind(job.kind.as_str())
            .bind(job.spec.as_str())
            .bind(job.idempotency_key.as_deref())
            .bind(job.request_hash.as_str())
            .execute(&mut tx)
            .await?;
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
        append_event::<E>(&mut tx, &job.id, "queued", &json!({ "kind": job.kind })).await?;
        announce_queued::<E>(&mut tx, &job.id).await?;
        tx.commit().await?;
        Ok(Inserted::Queued)
    }

    /// [`Store::job_by_idempotency_key`](super::Store::job_by_idempotency_key) on this engine.
    pub async fn job_by_idempotency_key(
        &self,
        tenant: &str,
        key: &str,
    ) -> Result<Option<(String, JobRow)>, sqlx::Error> {
        let row = Statement::<E>::new(E::JOB_BY_KEY)
            .bind(tenant)
            .bind(key)
            .fetch_optional(&mut *self.conn().await?)
            .await?;
        row.map(|row| Ok((E::get(&row, "request_hash")?, rows::job::<E>(&row)?)))
            .transpose()
    }

    /// [`Store::get_job`](super::Store::get_job) on this engine.
    pub async fn get_job(&self, tenant: &str, id: &str) -> Result<Option<JobRow>, sqlx::Error> {
        let row = Statement::<E>::new(E::GET_JOB)
            .bind(id)
            .bind(tenant)
            .fetch_optional(&mut *self.conn().await?)
            .await?;
        row.as_ref().map(rows::job::<E>).transpose()
    }

    /// [`Store::list_jobs`](super::Store::list_jobs) on this engine.
    pub async fn list_jobs(
        &self,
        tenant: &str,
        before: i64,
        status: Option<&str>,
        limit: i64,
    ) -> Result<Vec<JobRow>, sqlx::Error> {
        let rows = Statement::<E>::new(E::LIST_JOBS)
            .bind(tenant)
            .bind(before)
            .bind(status)
            .bind(limit)
            .fetch_all(&mut *self.conn().await?)
            .await?;
        rows.iter().map(rows::job::<E>).collect()
    }

    /// [`Store::job_status`](super::Store::job_status) on this engine.
    pub async fn job_status(&self, id: &str) -> Result<Option<String>, sqlx::Error> {
        let row = Statement::<E>::new(STATUS)
            .bind(id)
            .fetch_optional(&mut *self.conn().await?)
            .await?;
        row.map(|row| E::get(&row, "status")).transpose()
    }

    /// [`Store::cancel_requested`](super::Store::cancel_requested) on this engine.
    pub async fn cancel_requested(&self, id: &str) -> Result<bool, sqlx::Error> {
        let row = Statement::<E>::new(CANCEL_REQUESTED)
            .bind(id)
            .fetch_one(&mut *self.conn().await?)
            .await?;
        Ok(E::get::<i64>(&row, "cancel_requested")? != 0)
    }

    /// [`Store::cancel`](super::Store::cancel) on this engine.
    pub async fn cancel(&self, tenant: &str, id: &str) -> Result<CancelResult, sqlx::Error> {
        let mut tx = self.begin_write().await?;
        let row = Statement::<E>::new(E::STATUS_FOR_CANCEL)
            .bind(id)
            .bind(tenant)
            .fetch_optional(&mut tx)
            .await?;
        let status: Option<String> = row.map(|row| E::get(&row, "status")).transpose()?;
        let result = match status.as_deref() {
            None => CancelResult::NotFound,
            Some("queued") => {
                Statement::<E>::new(E::CANCEL_QUEUED)
                    .bind(id)
                    .execute(&mut tx)
                    .await?;
                append_event::<E>(&mut tx, id, "cancelled", &json!({})).await?;
                CancelResult::Cancelled
            }
            Some("running") => {
                Statement::<E>::new(REQUEST_CANCEL)
                    .bind(id)
                    .execute(&mut tx)
                    .await?;
                CancelResult::Requested
            }
            Some(other) => CancelResult::AlreadyFinished(other.to_string()),
        };
        tx.commit().await?;
        Ok(result)
    }

    /// [`Store::status_counts`](super::Store::status_counts) on this engine.
    pub async fn status_counts(&self) -> Result<Vec<(String, i64)>, sqlx::Error> {
        let rows = Statement::<E>::new(STATUS_COUNTS)
            .fetch_all(&mut *self.conn().await?)
            .await?;
        rows.iter()
            .map(|r| Ok((E::get(r, "status")?, E::get(r, "n")?)))
            .collect()
    }
}
