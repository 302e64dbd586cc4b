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

/// The time now as the store writes it: UTC text with milliseconds, which orders as time does.
macro_rules! now {
    () => {
        "strftime('%Y-%m-%dT%H:%M:%fZ', 'now')"
    };
}
use now;

/// The parameter `$secs` seconds from now.
macro_rules! later {
    ($secs:literal) => {
        concat!(
            "strftime('%Y-%m-%dT%H:%M:%fZ', 'now', ",
            $secs,
            " || ' seconds')"
        )
    };
}
use later;

/// The milliseconds from the time `$from` to the time `$to`, both UTC text.
macro_rules! millis {
    ($from:expr, $to:expr) => {
        concat!(
            "CAST(ROUND((julianday(",
            $to,
            ") - julianday(",
            $from,
            ")) * 86400000) AS INTEGER)"
        )
    };
}
use millis;

/// What a subquery that selects rows to update appends: nothing, as the writing transaction holds the
/// database's one write lock.
macro_rules! skip_locked {
    () => {
        ""
    };
}
use skip_locked;
