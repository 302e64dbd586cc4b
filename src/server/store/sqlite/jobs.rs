//! SQLite's job statements. A submission takes the write lock (`BEGIN IMMEDIATE`), which orders
//! submissions by itself; `created_at` is the column's default, the time of the insert.

use sqlx::Sqlite;

use super::{millis, now};
use crate::server::store::jobs::{JobsSql, job_statements};

impl JobsSql for Sqlite {
    job_statements!(now, millis);
    const LOCK_SUBMISSIONS: Option<&'static str> = None;
    const INSERT_JOB: &'static str = "INSERT INTO jobs \
         (id, tenant, kind, spec, idempotency_key, request_hash, status) \
         VALUES ($1, $2, $3, $4, $5, $6, 'queued') ON CONFLICT DO NOTHING";
    const STATUS_FOR_CANCEL: &'static str = "SELECT status FROM jobs WHERE id = $1 AND tenant = $2";
}
