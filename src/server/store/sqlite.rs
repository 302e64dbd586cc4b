//! The SQLite engine of the [`Store`](super::Store): one file in WAL mode with versioned migrations from
//! `migrations/sqlite/`, owned by one `skintight serve` process (its job processes write to it too, under
//! its workers' leases). Writers serialize on SQLite's one write lock, taken at the start of every writing
//! transaction (`BEGIN IMMEDIATE`), so a claim is one `UPDATE … WHERE status = 'queued' … RETURNING` and
//! nothing else can interleave. Timestamps are UTC text (`strftime('%Y-%m-%dT%H:%M:%fZ', 'now')`).
//!
//! This module opens the database; its submodules give the SQL in which SQLite's dialect differs from
//! PostgreSQL's, one file per concern of the store's control flow.

mod artifacts;
mod events;
mod jobs;
mod runs;

use std::path::Path;
use std::str::FromStr;
use std::time::Duration;

use sqlx::Sqlite;
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};

use super::engine::{Engine, EngineStore};

/// The versioned migrations compiled into the binary.
pub static MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("./migrations/sqlite");

/// A SQLite database; cheap to clone (a connection pool).
pub type SqliteStore = EngineStore<Sqlite>;

impl Engine for Sqlite {
    const BEGIN_WRITE: &'static str = "BEGIN IMMEDIATE";
}

impl EngineStore<Sqlite> {
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
        Ok(EngineStore { pool })
    }
}

/// Columns selected for a [`JobRow`](crate::server::model::JobRow), with its waiting and running times in
/// milliseconds.
macro_rules! job_columns {
    () => {
        "seq, id, tenant, kind, spec, status, cancel_requested, attempts, iterations, progress, last_metrics, \
         summary, error_code, error_message, created_at, started_at, finished_at, \
         CAST(ROUND((julianday(COALESCE(started_at, finished_at, strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))) - julianday(created_at)) * 86400000) AS INTEGER) AS queued_ms, \
         CASE WHEN started_at IS NULL THEN NULL ELSE CAST(ROUND((julianday(COALESCE(finished_at, strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))) - julianday(started_at)) * 86400000) AS INTEGER) END AS run_ms"
    };
}
use job_columns;

/// The condition of every write of a run: the job is running under the lease `$2`, which has not expired.
macro_rules! held {
    () => {
        "id = $1 AND lease_owner = $2 AND status = 'running' \
         AND lease_expires_at > strftime('%Y-%m-%dT%H:%M:%fZ', 'now')"
    };
}
use held;
