//! The rows the store reads, as the server's plain data types: a job ([`JobRow`]), a claimed job
//! ([`Claimed`]) and an asset's metadata ([`AssetInfo`]). The column types are the same in both engines
//! (`BIGINT`/`INTEGER` as `i64`, text, bytes, doubles); JSON is stored as text.

use serde_json::Value;

use super::statement::Driver;
use crate::server::model::{AssetInfo, Claimed, JobCheckpoint, JobRow};

/// The columns a claim and a running job's read return (for [`claimed`]).
macro_rules! claimed_columns {
    () => {
        "id, tenant, kind, spec, attempts, iterations, cancel_requested, checkpoint, checkpoint_iteration"
    };
}
pub(super) use claimed_columns;

/// A JSON column (`NULL`, or text that does not parse, as `None`).
fn json<E: Driver>(row: &E::Row, col: &str) -> Result<Option<Value>, sqlx::Error> {
    let text: Option<String> = E::get(row, col)?;
    Ok(text.and_then(|t| serde_json::from_str(&t).ok()))
}

/// A [`JobRow`] from a row selected with the engine's `job_columns!()`.
pub(super) fn job<E: Driver>(row: &E::Row) -> Result<JobRow, sqlx::Error> {
    Ok(JobRow {
        seq: E::get(row, "seq")?,
        id: E::get(row, "id")?,
        tenant: E::get(row, "tenant")?,
        kind: E::get(row, "kind")?,
        spec: json::<E>(row, "spec")?.unwrap_or(Value::Null),
        status: E::get(row, "status")?,
        cancel_requested: E::get::<i64>(row, "cancel_requested")? != 0,
        attempts: E::get(row, "attempts")?,
        iterations: E::get(row, "iterations")?,
        progress: E::get(row, "progress")?,
        last_metrics: json::<E>(row, "last_metrics")?,
        summary: json::<E>(row, "summary")?,
        error_code: E::get(row, "error_code")?,
        error_message: E::get(row, "error_message")?,
        created_at: E::get(row, "created_at")?,
        started_at: E::get(row, "started_at")?,
        finished_at: E::get(row, "finished_at")?,
        queued_ms: E::get(row, "queued_ms")?,
        run_ms: E::get(row, "run_ms")?,
    })
}

/// A [`Claimed`] job from a row with the [`claimed_columns`].
pub(super) fn claimed<E: Driver>(row: &E::Row) -> Result<Claimed, sqlx::Error> {
    let checkpoint = match (
        E::get::<Option<Vec<u8>>>(row, "checkpoint")?,
        E::get::<Option<i64>>(row, "checkpoint_iteration")?,
    ) {
        (Some(data), Some(it)) => Some(JobCheckpoint {
            iteration: it.max(0) as u64,
            data,
        }),
        _ => None,
    };
    Ok(Claimed {
        id: E::get(row, "id")?,
        tenant: E::get(row, "tenant")?,
        kind: E::get(row, "kind")?,
        spec: serde_json::from_str(&E::get::<String>(row, "spec")?).unwrap_or(Value::Null),
        attempts: E::get(row, "attempts")?,
        iterations: E::get::<i64>(row, "iterations")?.max(0) as u64,
        cancel_requested: E::get::<i64>(row, "cancel_requested")? != 0,
        checkpoint,
    })
}

/// An [`AssetInfo`] from a row with its columns.
pub(super) fn asset_info<E: Driver>(row: &E::Row) -> Result<AssetInfo, sqlx::Error> {
    Ok(AssetInfo {
        id: E::get(row, "id")?,
        sha256: E::get(row, "sha256")?,
        bytes: E::get(row, "bytes")?,
        format: E::get(row, "format")?,
        created_at: E::get(row, "created_at")?,
    })
}
