//! SQLite's run statements. A claim needs no row locks: its transaction holds the write lock
//! (`BEGIN IMMEDIATE`), so the oldest queued job it reads is the one it updates. Lease times are UTC text,
//! compared as text.

use sqlx::Sqlite;

use super::{later, now, skip_locked};
use crate::server::store::rows::claimed_columns;
use crate::server::store::runs::{RunsSql, run_statements};

impl RunsSql for Sqlite {
    run_statements!(now, later, skip_locked);
    const CLAIM: &'static str = concat!(
        "UPDATE jobs SET status = 'running', lease_owner = $1, attempts = attempts + 1, \
             lease_expires_at = ",
        later!("$2"),
        ", started_at = COALESCE(started_at, ",
        now!(),
        ") WHERE seq = (SELECT seq FROM jobs WHERE status = 'queued' ORDER BY seq LIMIT 1) \
             AND status = 'queued' \
         RETURNING ",
        claimed_columns!()
    );
    const HAND_BACK: &'static str = "UPDATE jobs SET status = 'queued', lease_owner = NULL, \
             lease_expires_at = NULL \
         WHERE status = 'running' AND substr(lease_owner, 1, length($1)) = $1 \
         RETURNING id, checkpoint_iteration";
}
