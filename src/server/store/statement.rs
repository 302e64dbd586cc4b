//! One SQL statement of either engine: its text, the values bound to its parameters, how it runs on a
//! connection, and how its rows' columns are read — the four things the store's one control flow asks of
//! a sqlx driver.
//!
//! The control flow (`assets.rs`, `jobs.rs`, `events.rs`, `artifacts.rs`, `runs.rs`) is generic over the
//! engine, but sqlx states what a driver can bind and decode as bounds on each Rust type (`i64: Encode<'_,
//! DB> + Type<DB>`, `for<'c> &'c mut DB::Connection: Executor<'c, Database = DB>`, …), and Rust does not
//! carry such bounds from a trait to its users: every generic function would repeat a dozen lines of
//! them. Instead [`Driver`] asks for the same capabilities as methods, implemented for [`Sqlite`] and
//! [`Postgres`] by one macro where the types are concrete and sqlx's own bounds hold. Values keep their
//! native types in each engine (`BIGINT`/`INTEGER`, `double precision`/`REAL`, `bytea`/`BLOB`, `boolean`
//! /integer); nothing goes through sqlx's `Any` driver and its common type set.
//!
//! Parameters are numbered `$1`, `$2`, … in both dialects: PostgreSQL's form, which sqlx's SQLite driver
//! reads as SQLite's `?NNN` (the same number binds the same value however often it appears).

use std::future::Future;

use sqlx::query::Query;
use sqlx::{Database, Decode, Encode, Postgres, Sqlite, Type};

/// A value a statement binds: a type both engines encode natively (text, integers, doubles, booleans,
/// bytes, and their `Option`s, `None` binding `NULL`).
pub trait Param<'t>:
    Type<Sqlite> + Type<Postgres> + Encode<'t, Sqlite> + Encode<'t, Postgres>
{
}

impl<'t, T> Param<'t> for T where
    T: Type<Sqlite> + Type<Postgres> + Encode<'t, Sqlite> + Encode<'t, Postgres>
{
}

/// A value read from a column: a type both engines decode natively.
pub trait Column:
    Sized + Type<Sqlite> + Type<Postgres> + for<'r> Decode<'r, Sqlite> + for<'r> Decode<'r, Postgres>
{
}

impl<T> Column for T where
    T: Sized
        + Type<Sqlite>
        + Type<Postgres>
        + for<'r> Decode<'r, Sqlite>
        + for<'r> Decode<'r, Postgres>
{
}

/// A query of the engine `E` before it runs.
type Pending<E> = Query<'static, E, <E as Database>::Arguments>;

/// What the control flow needs of a sqlx driver: binding a [`Param`], running a statement on a connection
/// (a pooled one, or a transaction's), and reading a [`Column`] of a row by name.
pub trait Driver: Database {
    fn bind<'t>(query: Pending<Self>, value: impl Param<'t>) -> Pending<Self>;
    fn execute(
        conn: &mut Self::Connection,
        query: Pending<Self>,
    ) -> impl Future<Output = Result<Self::QueryResult, sqlx::Error>> + Send;
    fn fetch_one(
        conn: &mut Self::Connection,
        query: Pending<Self>,
    ) -> impl Future<Output = Result<Self::Row, sqlx::Error>> + Send;
    fn fetch_optional(
        conn: &mut Self::Connection,
        query: Pending<Self>,
    ) -> impl Future<Output = Result<Option<Self::Row>, sqlx::Error>> + Send;
    fn fetch_all(
        conn: &mut Self::Connection,
        query: Pending<Self>,
    ) -> impl Future<Output = Result<Vec<Self::Row>, sqlx::Error>> + Send;
    /// The column `name` of `row`.
    fn get<T: Column>(row: &Self::Row, name: &str) -> Result<T, sqlx::Error>;
    /// How many rows a statement changed.
    fn rows_affected(result: &Self::QueryResult) -> u64;
}

/// Implements [`Driver`] for a concrete sqlx database by calling sqlx itself.
macro_rules! driver {
    ($db:ty) => {
        impl Driver for $db {
            fn bind<'t>(query: Pending<Self>, value: impl Param<'t>) -> Pending<Self> {
                query.bind(value)
            }
            fn execute(
                conn: &mut Self::Connection,
                query: Pending<Self>,
            ) -> impl Future<Output = Result<Self::QueryResult, sqlx::Error>> + Send {
                query.execute(conn)
            }
            fn fetch_one(
                conn: &mut Self::Connection,
                query: Pending<Self>,
            ) -> impl Future<Output = Result<Self::Row, sqlx::Error>> + Send {
                query.fetch_one(conn)
            }
            fn fetch_optional(
                conn: &mut Self::Connection,
                query: Pending<Self>,
            ) -> impl Future<Output = Result<Option<Self::Row>, sqlx::Error>> + Send {
                query.fetch_optional(conn)
            }
            fn fetch_all(
                conn: &mut Self::Connection,
                query: Pending<Self>,
            ) -> impl Future<Output = Result<Vec<Self::Row>, sqlx::Error>> + Send {
                query.fetch_all(conn)
            }
            fn get<T: Column>(row: &Self::Row, name: &str) -> Result<T, sqlx::Error> {
                sqlx::Row::try_get(row, name)
            }
            fn rows_affected(result: &Self::QueryResult) -> u64 {
                result.rows_affected()
            }
        }
    };
}

driver!(Sqlite);
driver!(Postgres);

/// One statement of the engine `E` with its bound values, built like a sqlx query:
/// `Statement::<E>::new(sql).bind(a).bind(b).fetch_optional(&mut tx)`.
pub struct Statement<E: Driver>(Pending<E>);

impl<E: Driver> Statement<E> {
    /// The statement `sql`, its parameters numbered `$1`, `$2`, … in the order of the binds.
    pub fn new(sql: &'static str) -> Self {
        Statement(sqlx::query(sql))
    }

    /// Binds the next parameter.
    pub fn bind<'t>(self, value: impl Param<'t>) -> Self {
        Statement(E::bind(self.0, value))
    }

    /// Runs the statement; returns how many rows it changed.
    pub async fn execute(self, conn: &mut E::Connection) -> Result<u64, sqlx::Error> {
        Ok(E::rows_affected(&E::execute(conn, self.0).await?))
    }

    /// Runs the statement; its one row (`RowNotFound` if none).
    pub async fn fetch_one(self, conn: &mut E::Connection) -> Result<E::Row, sqlx::Error> {
        E::fetch_one(conn, self.0).await
    }

    /// Runs the statement; its first row, if any.
    pub async fn fetch_optional(
        self,
        conn: &mut E::Connection,
    ) -> Result<Option<E::Row>, sqlx::Error> {
        E::fetch_optional(conn, self.0).await
    }

    /// Runs the statement; all its rows.
    pub async fn fetch_all(self, conn: &mut E::Connection) -> Result<Vec<E::Row>, sqlx::Error> {
        E::fetch_all(conn, self.0).await
    }
}
