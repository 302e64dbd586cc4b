//! SQLite announces nothing: its writers are one server and that server's job processes, which tell it
//! themselves.

use sqlx::Sqlite;

use crate::server::store::events::EventsSql;

impl EventsSql for Sqlite {
    const ANNOUNCE_EVENT: Option<&'static str> = None;
    const ANNOUNCE_QUEUED: Option<&'static str> = None;
}
