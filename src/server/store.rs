//! All SQL of the service, behind one [`Store`]: the SQLite database is one file in WAL mode, with
//! versioned migrations from `/migrations`. Route handlers, the queue, the worker and the running job's
//! context call `Store` methods; no other module writes a query.
//!
//! One submodule per table family: `assets` (uploads), `jobs` (submission, reads, cancel), `runs`
//! (the writes of a running job under its lease: claim, iterations, checkpoints, finish, recovery — the
//! state machine described in [`super::queue`]), `events` (the log SSE serves) and `artifacts`.
//!
//! Assets and artifacts are stored as BLOBs inside the database, so one file (plus its `-wal`/`-shm`
//! companions) is the whole durable state; back it up with `sqlite3 skintight.db ".backup copy.db"`.
//! One server process owns a database file at a time.

mod artifacts;
mod assets;
mod events;
mod jobs;
mod runs;

use std::path::Path;
use std::str::FromStr;
use std::time::Duration;

use serde_json::Value;
use sqlx::sqlite::{
    SqliteConnectOptions, SqliteJournalMode, SqlitePool, SqlitePoolOptions, SqliteRow,
    SqliteSynchronous,
};
use sqlx::{Row, Sqlite, Transaction};

use super::model::JobRow;

/// The versioned migrations compiled into the binary.
pub static MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("./migrations");

/// The current time as stored in the database.
pub const NOW: &str = "strftime('%Y-%m-%dT%H:%M:%fZ', 'now')";

/// The service's database; cheap to clone (a connection pool).
#[derive(Clone, Debug)]
pub struct Store {
    pool: SqlitePool,
}

impl Store {
    /// Opens (creating if missing) the database at `path` and brings its schema up to date.
    pub async fn open(path: &Path) -> Result<Store, sqlx::Error> {
        let options = SqliteConnectOptions::from_str("sqlite://")?
            .filename(path)
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Normal)
            .foreign_keys(true)
            .busy_timeout(Duration::from_secs(10));
        let pool = SqlitePoolOptions::new()
            .max_connections(8)
            .min_connections(1)
            .connect_with(options)
            .await?;
        MIGRATOR.run(&pool).await?;
        Ok(Store { pool })
    }

    /// A trivial query: whether the database answers (readiness).
    pub async fn ping(&self) -> Result<(), sqlx::Error> {
        sqlx::query("SELECT 1").execute(&self.pool).await?;
        Ok(())
    }

    /// Closes every connection (at shutdown).
    pub async fn close(&self) {
        self.pool.close().await;
    }
}

/// Columns selected for a [`JobRow`].
macro_rules! job_columns {
    () => {
        "seq, id, tenant, kind, spec, status, cancel_requested, attempts, iterations, progress, last_metrics, \
         summary, error_code, error_message, created_at, started_at, finished_at, \
         CAST(ROUND((julianday(COALESCE(started_at, finished_at, strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))) - julianday(created_at)) * 86400000) AS INTEGER) AS queued_ms, \
         CASE WHEN started_at IS NULL THEN NULL ELSE CAST(ROUND((julianday(COALESCE(finished_at, strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))) - julianday(started_at)) * 86400000) AS INTEGER) END AS run_ms"
    };
}
use job_columns;

fn json_col(row: &SqliteRow, col: &str) -> Result<Option<Value>, sqlx::Error> {
    let text: Option<String> = row.try_get(col)?;
    Ok(text.and_then(|t| serde_json::from_str(&t).ok()))
}

/// A [`JobRow`] from a row selected with `job_columns!()`.
fn job_row(row: &SqliteRow) -> Result<JobRow, sqlx::Error> {
    Ok(JobRow {
        seq: row.try_get("seq")?,
        id: row.try_get("id")?,
        tenant: row.try_get("tenant")?,
        kind: row.try_get("kind")?,
        spec: json_col(row, "spec")?.unwrap_or(Value::Null),
        status: row.try_get("status")?,
        cancel_requested: row.try_get::<i64, _>("cancel_requested")? != 0,
        attempts: row.try_get("attempts")?,
        iterations: row.try_get("iterations")?,
        progress: row.try_get("progress")?,
        last_metrics: json_col(row, "last_metrics")?,
        summary: json_col(row, "summary")?,
        error_code: row.try_get("error_code")?,
        error_message: row.try_get("error_message")?,
        created_at: row.try_get("created_at")?,
        started_at: row.try_get("started_at")?,
        finished_at: row.try_get("finished_at")?,
        queued_ms: row.try_get("queued_ms")?,
        run_ms: row.try_get("run_ms")?,
    })
}

/// Appends an event to a job's log inside `tx`; returns its sequence number (the SSE id). Every state
/// change appends its event in the same transaction, so the event log is exactly the job's history.
async fn append_event(
    tx: &mut Transaction<'static, Sqlite>,
    job_id: &str,
    kind: &str,
    data: &Value,
) -> Result<i64, sqlx::Error> {
    let row = sqlx::query(
        "INSERT INTO job_events (job_id, seq, kind, data) \
         SELECT ?1, COALESCE(MAX(seq), 0) + 1, ?2, ?3 FROM job_events WHERE job_id = ?1 RETURNING seq",
    )
    .bind(job_id)
    .bind(kind)
    .bind(data.to_string())
    .fetch_one(&mut **tx)
    .await?;
    row.try_get(0)
}
