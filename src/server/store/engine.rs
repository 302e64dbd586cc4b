//! What an engine supplies to the store ([`Engine`]) and the store over one engine ([`EngineStore`]): a
//! connection pool whose operations — in `assets.rs`, `jobs.rs`, `events.rs`, `artifacts.rs` and
//! `runs.rs` — are written once for both engines.
//!
//! An engine is a sqlx database type ([`sqlx::Sqlite`], [`sqlx::Postgres`]) that is a
//! [`Driver`](super::statement::Driver), gives the statement that opens a writing transaction and, per
//! concern, the SQL text in which its dialect differs from the other's (`JobsSql`, `EventsSql`,
//! `ArtifactsSql`, `RunsSql`, each declared beside the operations that run it; each engine's
//! implementations stand in `sqlite/` and `postgres/`, one file per concern). Statements both dialects
//! share are written once, beside the operations that run them.

use sqlx::pool::PoolConnection;
use sqlx::{Pool, Transaction};

use super::statement::{Driver, Statement};

/// A database engine of the store: its driver, and how it opens a writing transaction. The SQL of each
/// concern is a trait of its own (`JobsSql`, …), which the concern's operations ask of the engine beside
/// this one.
pub trait Engine: Driver {
    /// The statement that opens a transaction that writes. SQLite: `BEGIN IMMEDIATE`, which takes the
    /// database's one write lock at once, so that the transaction's reads see what its writes will change
    /// and two writers never deadlock upgrading read locks. PostgreSQL: `BEGIN`; its statements lock the
    /// rows they touch.
    const BEGIN_WRITE: &'static str;
}

/// The store on one engine; cheap to clone (a connection pool).
pub struct EngineStore<E: Engine> {
    pub(super) pool: Pool<E>,
}

impl<E: Engine> Clone for EngineStore<E> {
    fn clone(&self) -> Self {
        EngineStore {
            pool: self.pool.clone(),
        }
    }
}

impl<E: Engine> std::fmt::Debug for EngineStore<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EngineStore")
            .field("pool", &self.pool)
            .finish()
    }
}

impl<E: Engine> EngineStore<E> {
    /// [`Store::ping`](super::Store::ping) on this engine.
    pub async fn ping(&self) -> Result<(), sqlx::Error> {
        Statement::<E>::new("SELECT 1")
            .execute(&mut *self.conn().await?)
            .await?;
        Ok(())
    }

    /// [`Store::close`](super::Store::close) on this engine.
    pub async fn close(&self) {
        self.pool.close().await;
    }

    /// A connection of the pool, for reads and single-statement writes.
    pub(super) async fn conn(&self) -> Result<PoolConnection<E>, sqlx::Error> {
        self.pool.acquire().await
    }

    /// A transaction that writes ([`Engine::BEGIN_WRITE`]).
    pub(super) async fn begin_write(&self) -> Result<Transaction<'static, E>, sqlx::Error> {
        self.pool.begin_with(E::BEGIN_WRITE).await
    }
}
