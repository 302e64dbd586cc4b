//! `GET /v1/jobs/{id}/events`: the job's event log as server-sent events, read from the `job_events` table.
//!
//! Each event carries `id:` = its sequence number within the job, `event:` = its kind (`queued`, `started`,
//! `iteration`, `completed`, `failed`, `cancelled`) and `data:` = a JSON object. A `Last-Event-ID` header
//! (sent by browsers on reconnect) resumes after that event with no gap; a finished job replays its history
//! and the stream closes after the final event. An id beyond the job's last event is one this stream never
//! sent: a finished job answers it with its final event, a running job with the events after its last.

use std::convert::Infallible;
use std::time::Duration;

use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::response::sse::{Event, KeepAlive, Sse};
use futures_util::Stream;

use super::error::ApiError;
use super::keys::Tenant;
use super::model::is_terminal;
use super::state::AppState;

/// Rows read per database query.
const PAGE: i64 = 256;

/// `GET /v1/jobs/{id}/events`.
pub async fn stream(
    State(state): State<AppState>,
    Tenant(tenant): Tenant,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Sse<impl Stream<Item = Result<Event, Infallible>>>, ApiError> {
    let after: i64 = match headers.get("last-event-id") {
        None => 0,
        Some(v) => v
            .to_str()
            .ok()
            .and_then(|s| s.trim().parse::<i64>().ok())
            .filter(|n| *n >= 0)
            .ok_or_else(|| {
                ApiError::invalid(
                    "Last-Event-ID",
                    "must be the id of an event of this stream (an integer ≥ 0)",
                )
            })?,
    };
    state
        .store
        .get_job(&tenant, &id)
        .await?
        .ok_or_else(|| ApiError::not_found("job", &id))?;
    // An id beyond the job's last event (one this stream never sent): a finished job's stream sends its
    // final event again, so that the client sees how it ended; a running job's goes on from its last.
    let after = if after > 0 {
        // The last event before the status: a job seen finished has its final event among them.
        let last = state.store.last_event(&id).await?;
        let status = state.store.job_status(&id).await?;
        if after <= last {
            after
        } else if status.as_deref().is_some_and(is_terminal) {
            (last - 1).max(0)
        } else {
            last
        }
    } else {
        after
    };

    let stream = async_stream::stream! {
        let mut notify = state.events.subscribe();
        let mut shutdown = state.shutdown.clone();
        let mut last = after;
        // Whether the job was seen ended with no event left to read.
        let mut ended = false;
        'outer: loop {
            notify.borrow_and_update();
            let rows = match state.store.events_after(&id, last, PAGE).await {
                Ok(r) => r,
                Err(e) => {
                    tracing::error!(job = %id, error = %e, "reading events failed; closing the stream");
                    break;
                }
            };
            let n = rows.len() as i64;
            for event in rows {
                last = event.seq;
                yield Ok(Event::default().id(event.seq.to_string()).event(event.kind.as_str()).data(event.data));
                if is_terminal(&event.kind) {
                    break 'outer;
                }
            }
            if n == PAGE {
                continue;
            }
            // The job has ended: its final event is committed with its status, so one more read after
            // seeing the status returns it (the read above may have run just before that commit); a
            // stream resumed after the final event finds nothing and closes.
            if n == 0 {
                let status = state.store.job_status(&id).await.unwrap_or(None);
                if status.as_deref().is_none_or(is_terminal) {
                    if ended {
                        break;
                    }
                    ended = true;
                    continue;
                }
            }
            if *shutdown.borrow() {
                break;
            }
            tokio::select! {
                _ = notify.changed() => {}
                _ = tokio::time::sleep(Duration::from_secs(1)) => {}
                _ = shutdown.changed() => {}
            }
        }
    };
    Ok(Sse::new(stream).keep_alive(KeepAlive::new().interval(Duration::from_secs(15))))
}
