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

/// The time now as the store writes it: UTC text with milliseconds, as SQLite's (the migration's
/// function).
macro_rules! now {
    () => {
        "skintight_now()"
    };
}
use now;

/// The parameter `$secs` seconds from now (the migration's function).
macro_rules! later {
    ($secs:literal) => {
        concat!("skintight_later(", $secs, ")")
    };
}
use later;

/// The milliseconds from the time `$from` to the time `$to`, both UTC text.
macro_rules! millis {
    ($from:expr, $to:expr) => {
        concat!(
            "CAST(ROUND(EXTRACT(EPOCH FROM (",
            $to,
            "::timestamptz - ",
            $from,
            "::timestamptz)) * 1000) AS BIGINT)"
        )
    };
}
use millis;

/// What a subquery that selects rows to update appends: lock them, skipping those that another
/// transaction holds (a claim, or another node's re-queuing).
macro_rules! skip_locked {
    () => {
        " FOR UPDATE SKIP LOCKED"
    };
}
use skip_locked;
