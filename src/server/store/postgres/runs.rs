//! PostgreSQL's run statements. A claim locks the oldest queued row that no other claim holds (`FOR UPDATE
//! SKIP LOCKED`), and the re-queuing of expired leases skips the rows another node is re-queuing; text is
//! concatenated with explicit casts.

use sqlx::Postgres;

use super::{later, now, skip_locked};
use crate::server::store::rows::claimed_columns;
use crate::server::store::runs::{RunsSql, run_statements};

impl RunsSql for Postgres {
    run_statements!(now, later, skip_locked);
    const CLAIM: &'static str = concat!(
        "WITH next AS (SELECT seq FROM jobs WHERE status = 'queued' ORDER BY seq LIMIT 1",
        skip_locked!(),
        ") UPDATE jobs SET status = 'running', lease_owner = $1, attempts = attempts + 1, \
             lease_expires_at = ",
        later!("$2"),
        ", started_at = COALESCE(started_at, ",
        now!(),
        ") FROM next WHERE jobs.seq = next.seq \
         RETURNING ",
        claimed_columns!()
    );
    const HAND_BACK: &'static str = "UPDATE jobs SET status = 'queued', lease_owner = NULL, \
             lease_expires_at = NULL \
         WHERE status = 'running' AND starts_with(lease_owner, $1) \
         RETURNING id, checkpoint_iteration";
}
