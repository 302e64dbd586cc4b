//! Jobs: submission, reads for the API, cancel, and the counts `/metrics` shows.

use serde_json::json;
use sqlx::Row;

use super::{SqliteStore, append_event, job_columns, job_row};
use crate::server::model::{CancelResult, Inserted, JobRow, NewJob};

impl SqliteStore {
    /// Stores a new job as `queued` and appends its `queued` event, in one transaction.
    pub async fn insert_job(&self, job: &NewJob) -> Result<Inserted, sqlx::Error> {
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
        let inserted = sqlx::query(
            "INSERT INTO jobs (id, tenant, kind, spec, idempotency_key, request_hash, status) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, 'queued')",
        )
        .bind(&job.id)
        .bind(&job.tenant)
        .bind(&job.kind)
        .bind(&job.spec)
        .bind(&job.idempotency_key)
        .bind(&job.request_hash)
        .execute(&mut *tx)
        .await;
        match inserted {
            Ok(_) => {}
            Err(sqlx::Error::Database(e))
                if e.is_unique_violation() && job.idempotency_key.is_some() =>
            {
                tx.rollback().await?;
                return Ok(Inserted::KeyTaken);
            }
            Err(e) => return Err(e),
        }
        append_event(&mut tx, &job.id, "queued", &json!({ "kind": job.kind })).await?;
        tx.commit().await?;
        Ok(Inserted::Queued)
    }

    /// The tenant's job submitted with idempotency key `key`, with the hash of the request that made it.
    pub async fn job_by_idempotency_key(
        &self,
        tenant: &str,
        key: &str,
    ) -> Result<Option<(String, JobRow)>, sqlx::Error> {
        let row = sqlx::query(concat!(
            "SELECT request_hash, ",
            job_columns!(),
            " FROM jobs WHERE tenant = ?1 AND idempotency_key = ?2"
        ))
        .bind(tenant)
        .bind(key)
        .fetch_optional(&self.pool)
        .await?;
        row.map(|row| Ok((row.try_get("request_hash")?, job_row(&row)?)))
            .transpose()
    }

    /// Loads one job of a tenant.
    pub async fn get_job(&self, tenant: &str, id: &str) -> Result<Option<JobRow>, sqlx::Error> {
        let row = sqlx::query(concat!(
            "SELECT ",
            job_columns!(),
            " FROM jobs WHERE id = ?1 AND tenant = ?2"
        ))
        .bind(id)
        .bind(tenant)
        .fetch_optional(&self.pool)
        .await?;
        row.as_ref().map(job_row).transpose()
    }

    /// Up to `limit` jobs of a tenant with `seq < before`, newest first, optionally of one status.
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
            " FROM jobs WHERE tenant = ?1 AND seq < ?2 AND (?3 IS NULL OR status = ?3) ORDER BY seq DESC LIMIT ?4"
        ))
        .bind(tenant)
        .bind(before)
        .bind(status)
        .bind(limit)
        .fetch_all(&self.pool)
        .await?;
        rows.iter().map(job_row).collect()
    }

    /// A job's status, whoever its tenant (`None` for an unknown id).
    pub async fn job_status(&self, id: &str) -> Result<Option<String>, sqlx::Error> {
        sqlx::query_scalar("SELECT status FROM jobs WHERE id = ?1")
            .bind(id)
            .fetch_optional(&self.pool)
            .await
    }

    /// Whether a cancel was requested for a job.
    pub async fn cancel_requested(&self, id: &str) -> Result<bool, sqlx::Error> {
        sqlx::query_scalar::<_, i64>("SELECT cancel_requested FROM jobs WHERE id = ?1")
            .bind(id)
            .fetch_one(&self.pool)
            .await
            .map(|v| v != 0)
    }

    /// Cancels a tenant's job: a queued one at once (with its `cancelled` event), a running one by setting
    /// `cancel_requested` (its worker ends it).
    pub async fn cancel(&self, tenant: &str, id: &str) -> Result<CancelResult, sqlx::Error> {
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
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
    pub async fn status_counts(&self) -> Result<Vec<(String, i64)>, sqlx::Error> {
        let rows = sqlx::query("SELECT status, COUNT(*) AS n FROM jobs GROUP BY status")
            .fetch_all(&self.pool)
            .await?;
        rows.iter()
            .map(|r| Ok((r.try_get("status")?, r.try_get("n")?)))
            .collect()
    }
}
