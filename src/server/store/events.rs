//! A job's event log — appended with each state change, in the transaction that makes it, so the log is
//! exactly the job's history; read by SSE — and the announcements that let other nodes follow it.
//!
//! An event's number is `MAX(seq) + 1` among its job's events, read in the appending transaction. That
//! transaction has locked the job first (SQLite: the database's write lock, `BEGIN IMMEDIATE`; PostgreSQL:
//! the job's row, by the `UPDATE` of the state change or a `SELECT … FOR UPDATE`), so a job's events are
//! appended one transaction at a time and their numbers stay contiguous.

use serde_json::Value;

use super::engine::{Engine, EngineStore};
use super::statement::Statement;
use crate::server::model::EventRecord;

/// How an engine announces a committed change to the processes that do not make it.
pub trait EventsSql {
    /// Announces, when the transaction commits, that an event of the job `$1` was appended (PostgreSQL:
    /// `NOTIFY`); `None` where the engine announces nothing (SQLite: its writers are one server and its
    /// job processes, which tell the server themselves).
    const ANNOUNCE_EVENT: Option<&'static str>;
    /// Announces, likewise, that the job `$1` was queued (new, or taken back from a worker).
    const ANNOUNCE_QUEUED: Option<&'static str>;
}

/// Appends an event (job id, kind, data) numbered after the job's last one.
const APPEND: &str = "INSERT INTO job_events (job_id, seq, kind, data) \
     SELECT $1, COALESCE(MAX(seq), 0) + 1, $2, $3 FROM job_events WHERE job_id = $1 RETURNING seq";
/// Up to `$3` events of a job after the number `$2`, in order.
const AFTER: &str =
    "SELECT seq, kind, data FROM job_events WHERE job_id = $1 AND seq > $2 ORDER BY seq LIMIT $3";

/// The number of a job's last event (0 when it has none).
const LAST: &str = "SELECT COALESCE(MAX(seq), 0) AS seq FROM job_events WHERE job_id = $1";

/// Appends an event to a job's log inside a writing transaction whose job is locked, and announces it on
/// commit; returns its sequence number (the SSE id).
pub(super) async fn append_event<E: Engine + EventsSql>(
    tx: &mut E::Connection,
    job_id: &str,
    kind: &str,
    data: &Value,
) -> Result<i64, sqlx::Error> {
    let row = Statement::<E>::new(APPEND)
        .bind(job_id)
        .bind(kind)
        .bind(data.to_string())
        .fetch_one(tx)
        .await?;
    let seq = E::get(&row, "seq")?;
    announce::<E>(tx, E::ANNOUNCE_EVENT, job_id).await?;
    Ok(seq)
}

/// Announces on commit that the job `job_id` was queued, for the workers of every node.
pub(super) async fn announce_queued<E: Engine + EventsSql>(
    tx: &mut E::Connection,
    job_id: &str,
) -> Result<(), sqlx::Error> {
    announce::<E>(tx, E::ANNOUNCE_QUEUED, job_id).await
}

/// Runs an announcement of the job `job_id`, if the engine has it.
async fn announce<E: Engine + EventsSql>(
    tx: &mut E::Connection,
    sql: Option<&'static str>,
    job_id: &str,
) -> Result<(), sqlx::Error> {
    if let Some(sql) = sql {
        Statement::<E>::new(sql).bind(job_id).execute(tx).await?;
    }
    Ok(())
}

impl<E: Engine + EventsSql> EngineStore<E> {
    /// [`Store::events_after`](super::Store::events_after) on this engine.
    pub async fn events_after(
        &self,
        job_id: &str,
        after: i64,
        limit: i64,
    ) -> Result<Vec<EventRecord>, sqlx::Error> {
        let rows = Statement::<E>::new(AFTER)
            .bind(job_id)
            .bind(after)
            .bind(limit)
            .fetch_all(&mut *self.conn().await?)
            .await?;
        rows.iter()
            .map(|row| {
                Ok(EventRecord {
                    seq: E::get(row, "seq")?,
                    kind: E::get(row, "kind")?,
                    data: E::get(row, "data")?,
                })
            })
            .collect()
    }

    /// [`Store::last_event`](super::Store::last_event) on this engine.
    pub async fn last_event(&self, job_id: &str) -> Result<i64, sqlx::Error> {
        let row = Statement::<E>::new(LAST)
            .bind(job_id)
            .fetch_one(&mut *self.conn().await?)
            .await?;
        E::get(&row, "seq")
    }
}
