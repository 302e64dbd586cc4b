//! Operator routes: `/healthz` (the process answers), `/readyz` (accepting work: not shutting down, the
//! database answers), `/metrics` (Prometheus text, operator key) and `/openapi.yaml` (the API description).

use axum::extract::State;
use axum::response::IntoResponse;

use super::error::ApiError;
use super::keys::Operator;
use super::state::AppState;

/// The OpenAPI description served at `/openapi.yaml`.
pub const OPENAPI_YAML: &str = include_str!("../../openapi.yaml");

/// `GET /healthz`.
pub async fn healthz() -> impl IntoResponse {
    axum::Json(serde_json::json!({ "status": "ok" }))
}

/// `GET /readyz`: 503 while shutting down or when the database does not answer. Reports the store's engine
/// and, on a node that runs workers, its leases: how many jobs its workers hold and how long ago one was
/// last renewed (a node that holds jobs but has not renewed for longer than `jobs.lease_s` has lost them).
pub async fn readyz(State(state): State<AppState>) -> Result<impl IntoResponse, ApiError> {
    if *state.shutdown.borrow() {
        return Err(ApiError::unavailable("the server is shutting down"));
    }
    state.store.ping().await.map_err(|e| {
        tracing::error!(error = %e, "readiness check: database unavailable");
        ApiError::unavailable("the database is unavailable")
    })?;
    let mut body = serde_json::json!({
        "status": "ready",
        "workers": state.workers,
        "kinds": state.registry.kinds(),
        "store": { "engine": state.store.engine() },
    });
    if state.workers > 0 {
        let held = state.running.lock().expect("running map").len();
        body["leases"] = serde_json::json!({
            "held": held,
            "lease_s": state.config.jobs.lease_s,
            "last_renewed_s_ago": state.metrics.since_last_renewal(),
        });
    }
    Ok(axum::Json(body))
}

/// `GET /metrics` (operator key).
pub async fn metrics(
    State(state): State<AppState>,
    _op: Operator,
) -> Result<impl IntoResponse, ApiError> {
    let counts = state.store.status_counts().await?;
    let mut out = state.metrics.render(
        &counts,
        state.workers,
        state.started.elapsed().as_secs_f64(),
    );
    out.push_str(&memory_metrics(&state));
    Ok((
        [(
            axum::http::header::CONTENT_TYPE,
            "text/plain; version=0.0.4; charset=utf-8",
        )],
        out,
    ))
}

/// The server process's own memory (`/proc/self/status`, where there is one) and its budget for meshes
/// ([`super::asset_budget`]), in Prometheus text.
fn memory_metrics(state: &AppState) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let kib = |key: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(key))
            .and_then(|v| v.trim().strip_suffix("kB"))
            .and_then(|v| v.trim().parse::<u64>().ok())
            .map(|k| k * 1024)
    };
    if let Some(rss) = kib("VmRSS:") {
        let _ = writeln!(
            out,
            "# HELP process_resident_memory_bytes Resident memory of the server process.\n\
             # TYPE process_resident_memory_bytes gauge\nprocess_resident_memory_bytes {rss}"
        );
    }
    if let Some(peak) = kib("VmHWM:") {
        let _ = writeln!(
            out,
            "# HELP skintight_resident_memory_peak_bytes Peak resident memory of the server process.\n\
             # TYPE skintight_resident_memory_peak_bytes gauge\nskintight_resident_memory_peak_bytes {peak}"
        );
    }
    let _ = writeln!(
        out,
        "# HELP skintight_server_max_memory_bytes The server process's memory bound \
         (server.max_memory_bytes).\n# TYPE skintight_server_max_memory_bytes gauge\n\
         skintight_server_max_memory_bytes {}",
        state.config.server.max_memory_bytes
    );
    let b = &state.asset_budget;
    let _ = writeln!(
        out,
        "# HELP skintight_asset_check_budget_bytes The budget of the meshes read inside the server \
         (server.asset_check_memory_bytes).\n# TYPE skintight_asset_check_budget_bytes gauge\n\
         skintight_asset_check_budget_bytes {}\n\
         # HELP skintight_asset_check_bytes Bytes of that budget held by mesh reads now.\n\
         # TYPE skintight_asset_check_bytes gauge\nskintight_asset_check_bytes {}\n\
         # HELP skintight_asset_check_peak_bytes The most bytes of that budget held at once.\n\
         # TYPE skintight_asset_check_peak_bytes gauge\nskintight_asset_check_peak_bytes {}",
        b.bytes(),
        b.in_use(),
        b.peak()
    );
    out
}

/// `GET /openapi.yaml`: `application/yaml`, or `text/yaml` to a client whose `Accept` asks for that and
/// not `application/yaml`.
pub async fn openapi(headers: axum::http::HeaderMap) -> impl IntoResponse {
    let own = "application/yaml";
    let content_type = if super::request::accept_instead(&headers, "text/yaml", own) {
        "text/yaml"
    } else {
        own
    };
    (
        [(axum::http::header::CONTENT_TYPE, content_type)],
        OPENAPI_YAML,
    )
}
