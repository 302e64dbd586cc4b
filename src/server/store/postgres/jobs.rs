//! PostgreSQL's job statements. Submissions are stored one at a time under a transaction-level advisory
//! lock, as SQLite's writer lock stores them, and `created_at` is read after that lock
//! (`clock_timestamp()`, not the transaction's start), so that newest first by `seq` is newest first by
//! `created_at`. A cancel locks the job's row (`FOR UPDATE`) before it decides.

use sqlx::Postgres;

use super::job_columns;
use crate::server::store::jobs::JobsSql;

impl JobsSql for Postgres {
    /// The advisory lock's key is an arbitrary constant of this service, `0x736b_696e_7469`.
    const LOCK_SUBMISSIONS: Option<&'static str> = Some("SELECT pg_advisory_xact_lock(126905167541353)");
    const INSERT_JOB: &'static str = "INSERT INTO jobs \
         (id, tenant, kind, spec, idempotency_key, request_hash, status, created_at) \
         VALUES ($1, $2, $3, $4, $5, $6, 'queued', \
             to_char(clock_timestamp() AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS.MS\"Z\"')) \
         ON CONFLICT DO NOTHING";
    const JOB_BY_KEY: &'static str = concat!(
        "SELECT request_hash, ",
        job_columns!(),
        " FROM jobs WHERE tenant = $1 AND idempotency_key = $2"
    );
    const GET_JOB: &'static str = concat!(
        "SELECT ",
        job_columns!(),
        " FROM jobs WHERE id = $1 AND tenant = $2"
    );
    const LIST_JOBS: &'static str = concat!(
        "SELECT ",
        job_columns!(),
        " FROM jobs WHERE tenant = $1 AND seq < $2 AND ($3::text IS NULL OR status = $3) \
         ORDER BY seq DESC LIMIT $4"
    );
    const STATUS_FOR_CANCEL: &'static str =
        "SELECT status FROM jobs WHERE id = $1 AND tenant = $2 FOR UPDATE";
    const CANCEL_QUEUED: &'static str = "UPDATE jobs SET status = 'cancelled', cancel_requested = 1, \
             error_code = 'cancelled', error_message = 'the job was cancelled', \
             finished_at = skintight_now() \
         WHERE id = $1";
}
