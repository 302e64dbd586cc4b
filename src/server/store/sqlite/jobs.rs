//! SQLite's job statements. A submission takes the write lock (`BEGIN IMMEDIATE`), which orders
//! submissions by itself; `created_at` is the column's default, the time of the insert.

use sqlx::Sqlite;

use super::job_columns;
use crate::server::store::jobs::JobsSql;

impl JobsSql for Sqlite {
    const LOCK_SUBMISSIONS: Option<&'static str> = None;
    const INSERT_JOB: &'static str = "INSERT INTO jobs \
         (id, tenant, kind, spec, idempotency_key, request_hash, status) \
         VALUES ($1, $2, $3, $4, $5, $6, 'queued') ON CONFLICT DO NOTHING";
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
        " FROM jobs WHERE tenant = $1 AND seq < $2 AND ($3 IS NULL OR status = $3) \
         ORDER BY seq DESC LIMIT $4"
    );
    const STATUS_FOR_CANCEL: &'static str = "SELECT status FROM jobs WHERE id = $1 AND tenant = $2";
    const CANCEL_QUEUED: &'static str = "UPDATE jobs SET status = 'cancelled', cancel_requested = 1, \
             error_code = 'cancelled', error_message = 'the job was cancelled', \
             finished_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now') \
         WHERE id = $1";
}
