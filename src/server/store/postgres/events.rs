//! PostgreSQL announces events and queued jobs with `NOTIFY` (through `pg_notify`), delivered to every
//! node's [`Notifications`](super::Notifications) when the transaction commits, and not at all if it rolls
//! back.

use sqlx::Postgres;

use super::{events_channel, jobs_channel};
use crate::server::store::events::EventsSql;

impl EventsSql for Postgres {
    const ANNOUNCE_EVENT: Option<&'static str> =
        Some(concat!("SELECT pg_notify('", events_channel!(), "', $1)"));
    const ANNOUNCE_QUEUED: Option<&'static str> =
        Some(concat!("SELECT pg_notify('", jobs_channel!(), "', $1)"));
}
