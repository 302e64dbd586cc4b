//! The one router: every route of the API (`/v1/…`) and of the operators ([`super::ops`]), the fallbacks,
//! and the layers (body limits — a declared `Content-Length` checked before the body is read —, latency
//! metrics, request timeout, CORS, tracing, request ids — a client's kept only when short and of safe
//! characters —, and the limits on the request head: 414 and 431 in the JSON envelope).

use std::time::{Duration, Instant};

use axum::Router;
use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::http::{HeaderName, Method, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::trace::TraceLayer;

use super::error::ApiError;
use super::state::AppState;
use super::{assets, events, jobs, ops};

/// Builds the router with every route and middleware.
pub fn app(state: AppState) -> Router {
    let json_limit = state.config.server.max_json_bytes;
    let asset_limit = state.config.server.max_asset_bytes;
    let v1 = Router::new()
        .route(
            "/assets",
            post(assets::upload).layer(DefaultBodyLimit::max(asset_limit)),
        )
        .route("/assets/{id}", get(assets::show))
        .route("/jobs", post(jobs::submit).get(jobs::list))
        .route("/jobs/{id}", get(jobs::show))
        .route("/jobs/{id}/cancel", post(jobs::cancel))
        .route("/jobs/{id}/events", get(events::stream))
        .route("/jobs/{id}/artifacts", get(jobs::artifacts))
        .route("/jobs/{id}/artifacts/{name}", get(jobs::artifact))
        .layer(DefaultBodyLimit::max(json_limit));
    let mut router = Router::new()
        .nest("/v1", v1)
        .merge(ops_routes())
        .route("/openapi.yaml", get(ops::openapi));
    router = finish(router, &state).layer(middleware::from_fn_with_state(
        state.clone(),
        declared_length_limit,
    ));
    if !state.config.server.cors_origins.is_empty() {
        let origins: Vec<_> = state
            .config
            .server
            .cors_origins
            .iter()
            .filter_map(|o| o.parse().ok())
            .collect();
        router = router.layer(
            CorsLayer::new()
                .allow_origin(AllowOrigin::list(origins))
                .allow_methods([Method::GET, Method::POST])
                .allow_headers([
                    axum::http::header::AUTHORIZATION,
                    axum::http::header::CONTENT_TYPE,
                    HeaderName::from_static("idempotency-key"),
                    HeaderName::from_static("last-event-id"),
                ]),
        );
    }
    traced(router).with_state(state)
}

/// The router of a worker node's ops port (`worker.ops_addr`): only `/healthz`, `/readyz` and `/metrics`,
/// with the same handlers, fallbacks and layers as [`app`]'s (no CORS: it is not for browsers).
pub fn ops_app(state: AppState) -> Router {
    let router = finish(ops_routes(), &state);
    traced(router).with_state(state)
}

/// The operator routes every node serves.
fn ops_routes() -> Router<AppState> {
    Router::new()
        .route("/healthz", get(ops::healthz))
        .route("/readyz", get(ops::readyz))
        .route("/metrics", get(ops::metrics))
}

/// The JSON-envelope fallbacks, latency metrics and request timeout.
fn finish(router: Router<AppState>, state: &AppState) -> Router<AppState> {
    router
        .fallback(not_found)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(middleware::from_fn_with_state(state.clone(), observe))
        .layer(middleware::from_fn_with_state(
            state.clone(),
            request_timeout,
        ))
}

/// Request spans and request ids, the outermost layers (inside them, the limits on the request head that
/// the connection's parser leaves to the router: [`head_limits`]).
fn traced(router: Router<AppState>) -> Router<AppState> {
    let request_id = HeaderName::from_static("x-request-id");
    router
        .layer(middleware::from_fn(head_limits))
        .layer(
            TraceLayer::new_for_http().make_span_with(|req: &Request| {
                let id = req
                    .headers()
                    .get("x-request-id")
                    .and_then(|v| v.to_str().ok())
                    .unwrap_or("-");
                tracing::info_span!("request", method = %req.method(), uri = %req.uri().path(), request_id = %id)
            }),
        )
        .layer(PropagateRequestIdLayer::new(request_id.clone()))
        .layer(SetRequestIdLayer::new(request_id, MakeRequestUuid))
        .layer(middleware::from_fn(client_request_id))
}

/// The longest `X-Request-Id` a client may choose.
pub const MAX_REQUEST_ID_LEN: usize = 64;

/// A client's `X-Request-Id` is kept (and echoed, and logged) only when it is 1 to
/// [`MAX_REQUEST_ID_LEN`] characters of `A–Z a–z 0–9 - _ . : + / =` (a UUID, a ULID, a base64 token);
/// any other is dropped, so the server makes one of its own.
async fn client_request_id(mut req: Request, next: Next) -> Response {
    let ok = |v: &[u8]| {
        (1..=MAX_REQUEST_ID_LEN).contains(&v.len())
            && v.iter()
                .all(|b| b.is_ascii_alphanumeric() || b"-_.:+/=".contains(b))
    };
    if req
        .headers()
        .get_all("x-request-id")
        .iter()
        .map(|v| ok(v.as_bytes()))
        .ne([true])
    {
        req.headers_mut().remove("x-request-id");
    }
    next.run(req).await
}

/// The longest request target (path and query) answered by the router, bytes; a longer one is answered
/// 414. (Beyond 65 534 bytes the connection's parser answers 414 itself, without the JSON envelope.)
pub const MAX_URI_BYTES: usize = 8192;

/// The most request-head bytes (header names and values) answered by the router; more are answered 431.
/// (Beyond the parser's buffer, about 400 kB, or [`MAX_HEADERS_PARSED`] headers, the connection's parser
/// answers 431 itself, without the JSON envelope.)
pub const MAX_HEADER_BYTES: usize = 32768;

/// The most headers the router answers; more are answered 431.
pub const MAX_HEADERS: usize = 100;

/// The most headers the connection's parser reads (above [`MAX_HEADERS`], so that the router is the one
/// that answers between the two).
pub const MAX_HEADERS_PARSED: usize = 400;

/// 414 and 431 in the JSON envelope, with a request id, for request heads within what the connection's
/// parser reads but beyond the service's limits.
async fn head_limits(req: Request, next: Next) -> Response {
    let target = req.uri().path_and_query().map_or(0, |p| p.as_str().len());
    if target > MAX_URI_BYTES {
        return ApiError::new(
            StatusCode::URI_TOO_LONG,
            "uri_too_long",
            format!(
                "the request target has {target} bytes, more than the limit of {MAX_URI_BYTES}; send \
                 long inputs in a request body"
            ),
        )
        .into_response();
    }
    let count = req.headers().len();
    let bytes: usize = req
        .headers()
        .iter()
        .map(|(k, v)| k.as_str().len() + v.len() + 4)
        .sum();
    if count > MAX_HEADERS || bytes > MAX_HEADER_BYTES {
        return ApiError::new(
            StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
            "headers_too_large",
            format!(
                "the request has {count} headers of {bytes} bytes in all; the limits are {MAX_HEADERS} \
                 headers and {MAX_HEADER_BYTES} bytes"
            ),
        )
        .into_response();
    }
    next.run(req).await
}

/// A declared `Content-Length` above the route's limit (`server.max_asset_bytes` for uploads,
/// `server.max_json_bytes` for everything else) is answered 413 at once, before a byte of the body is
/// read — and so before a client that sent `Expect: 100-continue` is told to continue.
async fn declared_length_limit(
    State(state): State<AppState>,
    req: Request,
    next: Next,
) -> Response {
    let limit = if req.uri().path() == "/v1/assets" {
        state.config.server.max_asset_bytes
    } else {
        state.config.server.max_json_bytes
    };
    if let Some(n) = assets::declared_length(req.headers())
        && n > limit as u64
    {
        return ApiError::too_large(
            "body",
            format!(
                "the request declares a body of {n} bytes (Content-Length), more than the limit of \
                 {limit} bytes"
            ),
        )
        .into_response();
    }
    next.run(req).await
}

/// `server.request_timeout_s`: a request whose response head is not ready in time is answered 408 in the
/// JSON error envelope (a streaming body, such as SSE, is not cut once its head is sent).
async fn request_timeout(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let limit_s = state.config.server.request_timeout_s;
    match tokio::time::timeout(Duration::from_secs(limit_s), next.run(req)).await {
        Ok(resp) => resp,
        Err(_) => ApiError::new(
            StatusCode::REQUEST_TIMEOUT,
            "request_timeout",
            format!(
                "the request took longer than the server's limit of {limit_s} s \
                 (server.request_timeout_s); retry, or send a smaller request"
            ),
        )
        .into_response(),
    }
}

/// Records the latency of every request by method, route template and status.
async fn observe(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let method = req.method().clone();
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map(|p| p.as_str().to_string())
        .unwrap_or_else(|| "(unmatched)".to_string());
    let start = Instant::now();
    let resp = next.run(req).await;
    state.metrics.observe_http(
        method.as_str(),
        &route,
        resp.status().as_u16(),
        start.elapsed().as_secs_f64(),
    );
    resp
}

async fn not_found() -> ApiError {
    ApiError::new(StatusCode::NOT_FOUND, "not_found", "no such route")
}

async fn method_not_allowed() -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        "method_not_allowed",
        "this route does not accept that method",
    )
}
