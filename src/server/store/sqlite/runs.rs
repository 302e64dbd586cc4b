//! SQLite's run statements. A claim needs no row locks: its transaction holds the write lock
//! (`BEGIN IMMEDIATE`), so the oldest queued job it reads is the one it updates. Lease times are UTC text,
//! compared as text; `now + lease` is `strftime(…, 'now', '<seconds> seconds')`.

use sqlx::Sqlite;

use super::held;
use crate::server::store::rows::claimed_columns;
use crate::server::store::runs::RunsSql;

impl RunsSql for Sqlite {
    const CLAIM: &'static str = concat!(
        "UPDATE jobs SET status = 'running', lease_owner = $1, attempts = attempts + 1, \
             lease_expires_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now', $2 || ' seconds'), \
             started_at = COALESCE(started_at, strftime('%Y-%m-%dT%H:%M:%fZ', 'now')) \
         WHERE seq = (SELECT seq FROM jobs WHERE status = 'queued' ORDER BY seq LIMIT 1) \
             AND status = 'queued' \
         RETURNING ",
        claimed_columns!()
    );
    const RENEW_LEASE: &'static str = concat!(
        "UPDATE jobs SET lease_expires_at = strftime('%Y-%m-%dT%H:%M:%fZ', 'now', $3 || ' seconds') \
         WHERE ",
        held!(),
        " RETURNING cancel_requested"
    );
    const RUNNING_JOB: &'static str =
        concat!("SELECT ", claimed_columns!(), " FROM jobs WHERE ", held!());
    const RECORD_ITERATION: &'static str = concat!(
        "UPDATE jobs SET iterations = $3, progress = COALESCE($4, progress), last_metrics = $5 WHERE ",
        held!(),
        " RETURNING cancel_requested"
    );
    const SAVE_CHECKPOINT: &'static str = concat!(
        "UPDATE jobs SET checkpoint = $3, checkpoint_iteration = $4 WHERE ",
        held!()
    );
    const FINISH: &'static str = concat!(
        "UPDATE jobs SET status = $3, lease_owner = NULL, lease_expires_at = NULL, summary = $4, \
             error_code = $5, error_message = $6, \
             progress = CASE WHEN $3 = 'completed' THEN 1.0 ELSE progress END, \
             finished_at = CASE WHEN $3 = 'queued' THEN NULL \
                 ELSE strftime('%Y-%m-%dT%H:%M:%fZ', 'now') END \
         WHERE ",
        held!()
    );
    const REQUEUE_RUNS: &'static str = "UPDATE jobs SET crashes = crashes + 1, \
             status = CASE WHEN cancel_requested = 1 THEN 'cancelled' \
                 WHEN crashes + 1 >= $1 THEN 'failed' ELSE 'queued' END, \
             lease_owner = NULL, lease_expires_at = NULL, \
             finished_at = CASE WHEN cancel_requested = 1 OR crashes + 1 >= $1 \
                 THEN strftime('%Y-%m-%dT%H:%M:%fZ', 'now') ELSE NULL END, \
             error_code = CASE WHEN cancel_requested = 1 THEN 'cancelled' \
                 WHEN crashes + 1 >= $1 THEN 'crashed_repeatedly' ELSE NULL END, \
             error_message = CASE WHEN cancel_requested = 1 THEN 'the job was cancelled' \
                 WHEN crashes + 1 >= $1 THEN $3 || (crashes + 1) || \
                     ' runs of this job (jobs.max_attempts = ' || $1 || '); it is not run again' \
                 ELSE NULL END \
         WHERE status = 'running' AND ($2 = 0 OR lease_expires_at IS NULL \
             OR lease_expires_at <= strftime('%Y-%m-%dT%H:%M:%fZ', 'now')) \
         RETURNING id, status, checkpoint_iteration, error_code, error_message";
    const HAND_BACK: &'static str = "UPDATE jobs SET status = 'queued', lease_owner = NULL, \
             lease_expires_at = NULL \
         WHERE status = 'running' AND substr(lease_owner, 1, length($1)) = $1 \
         RETURNING id, checkpoint_iteration";
}
