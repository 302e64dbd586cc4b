//! The SQLite engine of the [`Store`](super::Store): one file in WAL mode with versioned migrations from
//! `migrations/sqlite/`. Writers serialize on SQLite's one write lock (`BEGIN IMMEDIATE`), so a claim is
//! one `UPDATE … WHERE status = 'queued' … RETURNING` and nothing else can interleave. One `skintight
//! serve` process owns the file (its job processes write to it too, under its workers' leases).

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

/// The versioned migrations compiled into the binary.
pub static MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("./migrations/sqlite");

/// A SQLite database; cheap to clone (a connection pool).
#[derive(Clone, Debug)]
pub struct SqliteStore {
    pool: SqlitePool,
}

impl SqliteStore {
    /// Opens (creating if missing) the database at `path` and brings its schema up to date.
    pub async fn open(path: &Path, max_connections: u32) -> Result<SqliteStore, sqlx::Error> {
        let options = SqliteConnectOptions::from_str("sqlite://")?
            .filename(path)
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Normal)
            .foreign_keys(true)
            .busy_timeout(Duration::from_secs(10));
        let pool = SqlitePoolOptions::new()
            .max_connections(max_connections.max(1))
            .min_connections(1)
            .connect_with(options)
            .await?;
        MIGRATOR.run(&pool).await?;
        Ok(SqliteStore { pool })
    }

    pub(super) async fn ping(&self) -> Result<(), sqlx::Error> {
        sqlx::query("SELECT 1").execute(&self.pool).await?;
        Ok(())
    }

    pub(super) async fn close(&self) {
        self.pool.close().await;
    }
}

/// Columns selected for a [`JobRow`](crate::server::model::JobRow).
macro_rules! job_columns {
    () => {
        "seq, id, tenant, kind, spec, status, cancel_requested, attempts, iterations, progress, last_metrics, \
         summary, error_code, error_message, created_at, started_at, finished_at, \
         CAST(ROUND((julianday(COALESCE(started_at, finished_at, strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))) - julianday(created_at)) * 86400000) AS INTEGER) AS queued_ms, \
         CASE WHEN started_at IS NULL THEN NULL ELSE CAST(ROUND((julianday(COALESCE(finished_at, strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))) - julianday(started_at)) * 86400000) AS INTEGER) END AS run_ms"
    };
}
use job_columns;

super::row_mappers!(SqliteRow);

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
