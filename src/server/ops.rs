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
    let out = state.metrics.render(
        &counts,
        state.workers,
        state.started.elapsed().as_secs_f64(),
    );
    Ok((
        [(
            axum::http::header::CONTENT_TYPE,
            "text/plain; version=0.0.4; charset=utf-8",
        )],
        out,
    ))
}

/// `GET /openapi.yaml`.
pub async fn openapi() -> impl IntoResponse {
    (
        [(axum::http::header::CONTENT_TYPE, "application/yaml")],
        OPENAPI_YAML,
    )
}
