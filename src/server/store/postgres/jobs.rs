//! PostgreSQL's job statements. Submissions are stored one at a time under a transaction-level advisory
//! lock, as SQLite's writer lock stores them, and `created_at` is read after that lock
//! (`clock_timestamp()`, not the transaction's start), so that newest first by `seq` is newest first by
//! `created_at`. A cancel locks the job's row (`FOR UPDATE`) before it decides.

use sqlx::Postgres;

use super::{millis, now};
use crate::server::store::jobs::{JobsSql, job_statements};

impl JobsSql for Postgres {
    job_statements!(now, millis);
    /// The advisory lock's key is an arbitrary constant of this service, `0x736b_696e_7469`.
    const LOCK_SUBMISSIONS: Option<&'static str> =
        Some("SELECT pg_advisory_xact_lock(126905167541353)");
    const INSERT_JOB: &'static str = "INSERT INTO jobs \
         (id, tenant, kind, spec, idempotency_key, request_hash, status, created_at) \
         VALUES ($1, $2, $3, $4, $5, $6, 'queued', \
             to_char(clock_timestamp() AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS.MS\"Z\"')) \
         ON CONFLICT DO NOTHING";
    const STATUS_FOR_CANCEL: &'static str =
        "SELECT status FROM jobs WHERE id = $1 AND tenant = $2 FOR UPDATE";
}
