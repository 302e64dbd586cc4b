//! The PostgreSQL engine of the [`Store`](super::Store), for any number of API nodes and worker nodes
//! sharing one database: versioned migrations from `migrations/postgres/` (the same versions, tables and
//! columns as SQLite's), claims with `FOR UPDATE SKIP LOCKED`, and `NOTIFY` on every event and every
//! queued job, which other nodes `LISTEN` to ([`Notifications`]).
//!
//! Concurrency: transactions run at PostgreSQL's default `READ COMMITTED`. Every transaction that appends a
//! job's event first locks that job's row (the `UPDATE` of a state change, or `SELECT … FOR UPDATE`), so
//! the events of one job are appended one transaction at a time and their numbers (`MAX(seq) + 1`, read
//! after the lock) stay contiguous. A claim locks the oldest queued row that no other claim holds (`SKIP
//! LOCKED`), so concurrent workers never wait on each other nor claim the same job; the re-queuing of
//! expired leases skips rows another node is re-queuing. Submissions are stored one at a time (a
//! transaction-level advisory lock), as SQLite's writer lock stores them, so that the listing order (`seq`)
//! and `created_at` agree.
//!
//! Timestamps are UTC text like SQLite's (the migration's `skintight_now()`), and the lease arithmetic is
//! done by the database's clock alone, so the nodes' clocks need not agree.
//!
//! This module connects and listens; its submodules give the SQL in which PostgreSQL's dialect differs from
//! SQLite's, one file per concern of the store's control flow.

mod artifacts;
mod events;
mod jobs;
mod runs;

use std::time::Duration;

use sqlx::Postgres;
use sqlx::postgres::{PgConnectOptions, PgListener, PgPoolOptions};

use super::engine::{Engine, EngineStore};

/// The versioned migrations compiled into the binary.
pub static MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("./migrations/postgres");

/// The channel on which a committed event is announced (payload: the job id).
macro_rules! events_channel {
    () => {
        "skintight_events"
    };
}
use events_channel;

/// The channel on which a queued job is announced (payload: the job id).
macro_rules! jobs_channel {
    () => {
        "skintight_jobs"
    };
}
use jobs_channel;

/// A PostgreSQL database; cheap to clone (a connection pool).
pub type PgStore = EngineStore<Postgres>;

impl Engine for Postgres {
    const BEGIN_WRITE: &'static str = "BEGIN";
}

/// What another node announced.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Notice {
    /// An event of this job was committed.
    Event(String),
    /// This job was queued (new, or taken back from a worker).
    Queued(String),
}

/// A `LISTEN`ing connection of its own.
pub struct Notifications(PgListener);

impl Notifications {
    /// The next announcement. After an error the connection is re-established by the next call, and
    /// announcements in between are lost: callers also poll.
    pub async fn recv(&mut self) -> Result<Notice, sqlx::Error> {
        let n = self.0.recv().await?;
        Ok(if n.channel() == jobs_channel!() {
            Notice::Queued(n.payload().to_string())
        } else {
            Notice::Event(n.payload().to_string())
        })
    }
}

impl EngineStore<Postgres> {
    /// Connects to the database at `url` and brings its schema up to date (migrations run under
    /// PostgreSQL's advisory lock, so nodes starting together apply them once).
    pub async fn open(url: &str, max_connections: u32) -> Result<PgStore, sqlx::Error> {
        let options: PgConnectOptions = url.parse()?;
        let pool = PgPoolOptions::new()
            .max_connections(max_connections.max(2))
            .min_connections(1)
            .acquire_timeout(Duration::from_secs(10))
            .connect_with(options.application_name("skintight"))
            .await?;
        MIGRATOR.run(&pool).await?;
        Ok(EngineStore { pool })
    }

    /// A connection listening to the announcements of every node.
    pub async fn notifications(&self) -> Result<Notifications, sqlx::Error> {
        let mut listener = PgListener::connect_with(&self.pool).await?;
        listener
            .listen_all([events_channel!(), jobs_channel!()])
            .await?;
        Ok(Notifications(listener))
    }
}

/// Columns selected for a [`JobRow`](crate::server::model::JobRow), with its waiting and running times in
/// milliseconds.
macro_rules! job_columns {
    () => {
        "seq, id, tenant, kind, spec, status, cancel_requested, attempts, iterations, progress, last_metrics, \
         summary, error_code, error_message, created_at, started_at, finished_at, \
         CAST(ROUND(EXTRACT(EPOCH FROM (COALESCE(started_at, finished_at, skintight_now())::timestamptz - created_at::timestamptz)) * 1000) AS BIGINT) AS queued_ms, \
         CASE WHEN started_at IS NULL THEN NULL ELSE CAST(ROUND(EXTRACT(EPOCH FROM (COALESCE(finished_at, skintight_now())::timestamptz - started_at::timestamptz)) * 1000) AS BIGINT) END AS run_ms"
    };
}
use job_columns;

/// The condition of every write of a run: the job is running under the lease `$2`, which has not expired.
macro_rules! held {
    () => {
        "id = $1 AND lease_owner = $2 AND status = 'running' AND lease_expires_at > skintight_now()"
    };
}
use held;
