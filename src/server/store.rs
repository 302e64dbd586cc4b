//! All SQL of the service, behind one [`Store`] with two engines: SQLite (the embedded default, one file in
//! WAL mode owned by one `skintight serve` process) and PostgreSQL (`database.url = "postgres://…"`, shared
//! by any number of API nodes and worker nodes). Route handlers, the queue, the workers and the running
//! job's context call `Store` methods; no other module writes a query.
//!
//! # One control flow, two dialects
//!
//! Each operation — its transaction, the order of its statements, the decisions between them, the lease
//! fencing, the events it appends, the errors it returns — is written once, generic over the engine, in a
//! file per table family: `assets.rs` (uploads), `jobs.rs` (submission, reads, cancel), `runs.rs` (the
//! writes of a running job under its lease: claim, heartbeat, iterations, checkpoints, finish, the
//! re-queuing of runs whose lease expired — the state machine described in [`super::queue`]), `events.rs`
//! (the log SSE serves, and the announcements to other nodes) and `artifacts.rs`. They are methods of
//! [`EngineStore<E>`], a connection pool of the engine `E`.
//!
//! An engine ([`Engine`], in `engine.rs`) is a sqlx database type, [`sqlx::Sqlite`] or
//! [`sqlx::Postgres`], and supplies only what differs between the two dialects:
//! - SQL fragments, as macros in [`sqlite`] and [`postgres`]: the time now (`strftime(…)` vs
//!   `skintight_now()`), a time some seconds ahead, the milliseconds between two times, and what a
//!   subquery appends to lock the rows it selects (nothing vs `FOR UPDATE SKIP LOCKED`);
//! - per family, a trait of its statements in the dialect (`JobsSql`, `RunsSql`, `ArtifactsSql`,
//!   `EventsSql`, declared beside the family's operations), implemented in `sqlite/<family>.rs` and
//!   `postgres/<family>.rs`. A statement that is the same text around the fragments is written once, as
//!   a template macro beside the trait (`job_statements!`, `run_statements!`) that each engine stamps
//!   with its fragments; the engines write out only the statements that really differ: the claim, the
//!   hand-back (`substr` vs `starts_with`), `INSERT OR REPLACE` vs an upsert, `substr` vs `substring`, the
//!   submission's `created_at` and the cancel's `FOR UPDATE`, the submission lock, the announcements
//!   (`NOTIFY` on PostgreSQL, none on SQLite);
//! - the statement that opens a writing transaction (`BEGIN IMMEDIATE` vs `BEGIN`), and the opening of
//!   its pool with its migrations.
//!
//! A statement both dialects accept as it is stands once, as a constant beside the operation that runs it.
//! Parameters are numbered `$1`, `$2`, … everywhere: PostgreSQL's form, which sqlx's SQLite driver reads as
//! SQLite's `?NNN`.
//!
//! The generic code runs statements through `statement.rs` ([`Driver`](statement::Driver)): sqlx states
//! what a driver binds and decodes as per-type bounds that Rust would make every generic function repeat,
//! so the driver's capabilities are methods instead, implemented once for both sqlx types where sqlx's own
//! bounds hold. Values keep their native types in each engine. sqlx's `Any` driver would have let one
//! query text run on both, but only over the intersection of the dialects and of the types, converted at
//! run time: no `FOR UPDATE SKIP LOCKED`, no `LISTEN/NOTIFY`, no `BEGIN IMMEDIATE`.
//!
//! [`Store`] chooses the engine at run time: `enum { Sqlite(SqliteStore), Postgres(PgStore) }`, whose
//! methods call the same method of [`EngineStore`] on either — there are exactly two engines, both known
//! here, and the enum keeps `Store` `Clone` and `Sized` and its methods plain `async fn`s.
//!
//! Both engines keep the same tables and columns (versioned migrations in `migrations/sqlite/` and
//! `migrations/postgres/`, the same versions and names; `tests/store_engines.rs` fails if they diverge) and
//! the same semantics: `tests/store_engines.rs` runs one conformance test against both.
//!
//! # Leases
//!
//! A worker claims the oldest queued job under a lease: a fresh lease id (stored as `lease_owner`) and an
//! expiry (`lease_expires_at`, `jobs.lease_s` ahead). The worker renews the lease while the job runs
//! ([`Store::renew_lease`]); every write of a running job (iteration, checkpoint, finish) is conditioned on
//! the job still being held under that lease id *and* the lease not having expired, so a worker that lost
//! its lease — it stalled, or another node re-queued the job — can write nothing (fencing by lease id). A
//! job whose lease expired is re-queued by any worker node ([`Store::requeue_runs`], counted as a
//! crashed run, like a job the server died in) and another worker resumes it from its last checkpoint.
//!
//! # Bytes in the database
//!
//! Assets, checkpoints and artifacts are stored in the database (SQLite `BLOB`, PostgreSQL `bytea`), so the
//! database is the whole durable state: back up SQLite with `sqlite3 skintight.db ".backup copy.db"`,
//! PostgreSQL with `pg_dump`. A PostgreSQL `bytea` value is at most 1 GiB (its field-size limit), and one is
//! written in one statement, so the writer holds it in memory; the service's assets are capped far below
//! that (`server.max_asset_bytes`, 64 MiB by default) and its largest artifacts are a few MiB. Downloads
//! are read in chunks of [`CHUNK_BYTES`] ([`Store::artifact_chunk`]), never whole.

mod artifacts;
mod assets;
mod engine;
mod events;
mod jobs;
pub mod postgres;
mod rows;
mod runs;
pub mod sqlite;
mod statement;

use std::time::Duration;

use serde_json::Value;

use super::config::DatabaseConfig;
use super::model::{
    ArtifactInfo, Asset, AssetInfo, CancelResult, Claimed, EventRecord, Inserted, JobRow, NewJob,
    Outcome,
};
pub use engine::{Engine, EngineStore};
pub use postgres::{Notice, Notifications, PgStore};
pub use sqlite::SqliteStore;

/// Bytes of an artifact read per query when it is downloaded.
pub const CHUNK_BYTES: i64 = 1 << 20;

/// The service's database; cheap to clone (a connection pool).
#[derive(Clone, Debug)]
pub enum Store {
    Sqlite(SqliteStore),
    Postgres(PgStore),
}

/// Calls the same method on whichever engine `self` is.
macro_rules! dispatch {
    ($self:ident . $method:ident ( $($arg:expr),* )) => {
        match $self {
            Store::Sqlite(s) => s.$method($($arg),*).await,
            Store::Postgres(p) => p.$method($($arg),*).await,
        }
    };
}

/// Why a run's lease was taken back from its worker (the `reason` of the `queued` event, and the start of
/// the `crashed_repeatedly` message).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Requeue {
    /// At the start of a SQLite server: every run left `running` died with the previous process.
    Restart,
    /// A worker stopped renewing its lease (it died or lost the database) and the lease expired.
    LeaseExpired,
}

impl Requeue {
    /// The `reason` of the job's `queued` event.
    pub fn reason(self) -> &'static str {
        match self {
            Requeue::Restart => "recovered after a restart",
            Requeue::LeaseExpired => "the lease of its worker expired",
        }
    }

    /// How the `crashed_repeatedly` message begins: "{cause} N runs of this job …".
    pub fn cause(self) -> &'static str {
        match self {
            Requeue::Restart => "the server died during ",
            Requeue::LeaseExpired => "its worker stopped renewing its lease during ",
        }
    }
}

/// An artifact's description, for the headers of its download.
#[derive(Debug, Clone)]
pub struct ArtifactMeta {
    pub content_type: String,
    pub sha256: String,
    pub bytes: i64,
}

impl Store {
    /// Opens the database `config` names — PostgreSQL when `database.url` is set, else the SQLite file at
    /// `database.path` (created if missing) — and brings its schema up to date. `max_connections` bounds the
    /// pool (a job process needs two).
    pub async fn connect(
        config: &DatabaseConfig,
        max_connections: u32,
    ) -> Result<Store, sqlx::Error> {
        if config.is_postgres() {
            Ok(Store::Postgres(
                PgStore::open(&config.url, max_connections).await?,
            ))
        } else {
            Ok(Store::Sqlite(
                SqliteStore::open(&config.path, max_connections).await?,
            ))
        }
    }

    /// `"sqlite"` or `"postgres"`.
    pub fn engine(&self) -> &'static str {
        match self {
            Store::Sqlite(_) => "sqlite",
            Store::Postgres(_) => "postgres",
        }
    }

    /// A trivial query: whether the database answers (readiness).
    pub async fn ping(&self) -> Result<(), sqlx::Error> {
        dispatch!(self.ping())
    }

    /// Closes every connection (at shutdown).
    pub async fn close(&self) {
        dispatch!(self.close())
    }

    /// The change notifications of other processes (PostgreSQL `LISTEN`): events appended and jobs queued
    /// by any node. `None` for SQLite, whose writers are this process and its job processes, which tell it
    /// themselves.
    pub async fn notifications(&self) -> Result<Option<Notifications>, sqlx::Error> {
        match self {
            Store::Sqlite(_) => Ok(None),
            Store::Postgres(p) => p.notifications().await.map(Some),
        }
    }

    // Assets.

    /// Stores `data` for `tenant` under the new id `id` unless the tenant already has the same bytes;
    /// returns the asset (new or existing) and whether it was inserted.
    pub async fn insert_asset(
        &self,
        id: &str,
        tenant: &str,
        format: &str,
        data: &[u8],
    ) -> Result<(AssetInfo, bool), sqlx::Error> {
        dispatch!(self.insert_asset(id, tenant, format, data))
    }

    /// The metadata of one asset of a tenant.
    pub async fn asset_info(
        &self,
        tenant: &str,
        id: &str,
    ) -> Result<Option<AssetInfo>, sqlx::Error> {
        dispatch!(self.asset_info(tenant, id))
    }

    /// Loads one asset of a tenant, bytes included.
    pub async fn load_asset(&self, tenant: &str, id: &str) -> Result<Option<Asset>, sqlx::Error> {
        dispatch!(self.load_asset(tenant, id))
    }

    // Jobs.

    /// Stores a new job as `queued` and appends its `queued` event, in one transaction.
    pub async fn insert_job(&self, job: &NewJob) -> Result<Inserted, sqlx::Error> {
        dispatch!(self.insert_job(job))
    }

    /// The tenant's job submitted with idempotency key `key`, with the hash of the request that made it.
    pub async fn job_by_idempotency_key(
        &self,
        tenant: &str,
        key: &str,
    ) -> Result<Option<(String, JobRow)>, sqlx::Error> {
        dispatch!(self.job_by_idempotency_key(tenant, key))
    }

    /// Loads one job of a tenant.
    pub async fn get_job(&self, tenant: &str, id: &str) -> Result<Option<JobRow>, sqlx::Error> {
        dispatch!(self.get_job(tenant, id))
    }

    /// Up to `limit` jobs of a tenant with `seq < before`, newest first, optionally of one status.
    pub async fn list_jobs(
        &self,
        tenant: &str,
        before: i64,
        status: Option<&str>,
        limit: i64,
    ) -> Result<Vec<JobRow>, sqlx::Error> {
        dispatch!(self.list_jobs(tenant, before, status, limit))
    }

    /// A job's status, whoever its tenant (`None` for an unknown id).
    pub async fn job_status(&self, id: &str) -> Result<Option<String>, sqlx::Error> {
        dispatch!(self.job_status(id))
    }

    /// Whether a cancel was requested for a job.
    pub async fn cancel_requested(&self, id: &str) -> Result<bool, sqlx::Error> {
        dispatch!(self.cancel_requested(id))
    }

    /// Cancels a tenant's job: a queued one at once (with its `cancelled` event), a running one by setting
    /// `cancel_requested` (its worker ends it).
    pub async fn cancel(&self, tenant: &str, id: &str) -> Result<CancelResult, sqlx::Error> {
        dispatch!(self.cancel(tenant, id))
    }

    /// Jobs per status (for /metrics).
    pub async fn status_counts(&self) -> Result<Vec<(String, i64)>, sqlx::Error> {
        dispatch!(self.status_counts())
    }

    // Events and artifacts.

    /// Up to `limit` events of a job after sequence number `after`, in order.
    pub async fn events_after(
        &self,
        job_id: &str,
        after: i64,
        limit: i64,
    ) -> Result<Vec<EventRecord>, sqlx::Error> {
        dispatch!(self.events_after(job_id, after, limit))
    }

    /// The number of a job's last event (0 when it has none).
    pub async fn last_event(&self, job_id: &str) -> Result<i64, sqlx::Error> {
        dispatch!(self.last_event(job_id))
    }

    /// The artifacts of a job, by name.
    pub async fn list_artifacts(&self, job_id: &str) -> Result<Vec<ArtifactInfo>, sqlx::Error> {
        dispatch!(self.list_artifacts(job_id))
    }

    /// One artifact's content type, SHA-256 and size.
    pub async fn artifact_meta(
        &self,
        job_id: &str,
        name: &str,
    ) -> Result<Option<ArtifactMeta>, sqlx::Error> {
        dispatch!(self.artifact_meta(job_id, name))
    }

    /// Up to `len` bytes of an artifact from byte `offset` (0-based); empty past its end.
    pub async fn artifact_chunk(
        &self,
        job_id: &str,
        name: &str,
        offset: i64,
        len: i64,
    ) -> Result<Vec<u8>, sqlx::Error> {
        dispatch!(self.artifact_chunk(job_id, name, offset, len))
    }

    // Runs, under a lease.

    /// Claims the oldest queued job under the new lease id `lease` for `lease_for`, or `None` when the
    /// queue is empty. Appends its `started` event.
    pub async fn claim(
        &self,
        lease: &str,
        lease_for: Duration,
    ) -> Result<Option<Claimed>, sqlx::Error> {
        dispatch!(self.claim(lease, lease_for))
    }

    /// Extends the lease `lease` on a running job by `lease_for` from now; returns whether a cancel was
    /// requested, or `None` when the lease is gone (expired, or taken back).
    pub async fn renew_lease(
        &self,
        job_id: &str,
        lease: &str,
        lease_for: Duration,
    ) -> Result<Option<bool>, sqlx::Error> {
        dispatch!(self.renew_lease(job_id, lease, lease_for))
    }

    /// The job held under `lease` (what [`Self::claim`] returned to that worker), read again by the job
    /// process that runs it; `None` when the lease is gone.
    pub async fn running_job(
        &self,
        job_id: &str,
        lease: &str,
    ) -> Result<Option<Claimed>, sqlx::Error> {
        dispatch!(self.running_job(job_id, lease))
    }

    /// Records an iteration if the job is still held under `lease` — its `iteration` event, and with
    /// `checkpoint` the run's checkpoint after it, in one transaction —; returns whether a cancel was
    /// requested, or `None` when the lease is gone (and nothing was written).
    pub async fn record_iteration(
        &self,
        job_id: &str,
        lease: &str,
        iteration: u64,
        progress: Option<f64>,
        metrics: &Value,
        checkpoint: Option<&[u8]>,
    ) -> Result<Option<bool>, sqlx::Error> {
        dispatch!(self.record_iteration(job_id, lease, iteration, progress, metrics, checkpoint))
    }

    /// Saves a checkpoint if the job is still held under `lease`; `false` when the lease is gone.
    pub async fn save_checkpoint(
        &self,
        job_id: &str,
        lease: &str,
        iteration: u64,
        data: &[u8],
    ) -> Result<bool, sqlx::Error> {
        dispatch!(self.save_checkpoint(job_id, lease, iteration, data))
    }

    /// Ends a run held under `lease` (storing a completed job's artifacts); returns `false` (and changes
    /// nothing) when the lease is gone.
    pub async fn finish(
        &self,
        job_id: &str,
        lease: &str,
        outcome: Outcome,
    ) -> Result<bool, sqlx::Error> {
        dispatch!(self.finish(job_id, lease, outcome))
    }

    /// Takes back runs from their workers: with [`Requeue::Restart`] every job left `running` (at the
    /// start of a SQLite server, whose previous process owned them all), with [`Requeue::LeaseExpired`]
    /// those whose lease has expired. Each is re-queued, or cancelled if a cancel was asked for, or — once
    /// `max_attempts` runs have crashed — failed with code `crashed_repeatedly` (spec and events kept).
    /// Returns how many were taken back.
    pub async fn requeue_runs(
        &self,
        max_attempts: u32,
        why: Requeue,
    ) -> Result<usize, sqlx::Error> {
        dispatch!(self.requeue_runs(max_attempts, why))
    }

    /// At a worker node's graceful shutdown: re-queues at once the runs still held under leases that start
    /// with `prefix` (this node's), without counting a crash. Returns how many.
    pub async fn hand_back(&self, prefix: &str) -> Result<usize, sqlx::Error> {
        dispatch!(self.hand_back(prefix))
    }
}
