//! The headless HTTP/JSON service (`skintight serve`): uploads meshes, queues jobs of pluggable kinds,
//! streams their progress as server-sent events and serves their artifacts. State lives in one SQLite file.
//!
//! One module per concern: [`config`], [`error`] (the JSON error envelope), [`db`], [`auth`], [`assets`]
//! and [`jobs`] (routes), [`events`] (SSE), [`queue`] (durable job state machine), [`worker`] (blocking
//! worker pool), [`runner`] (the `JobRunner` trait and registry), [`metrics`], [`selftest`] (an operator
//! smoke-test kind).

pub mod assets;
pub mod auth;
pub mod config;
pub mod db;
pub mod design_job;
pub mod error;
pub mod events;
pub mod jobs;
pub mod metrics;
pub mod queue;
pub mod runner;
pub mod selftest;
pub mod simulate_job;
pub mod worker;

use std::collections::HashMap;
use std::net::SocketAddr;
use std::ops::Deref;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use axum::Router;
use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::http::{HeaderName, Method, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use sqlx::SqlitePool;
use tokio::sync::{Notify, watch};
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::timeout::TimeoutLayer;
use tower_http::trace::TraceLayer;

pub use config::Config;
pub use error::ApiError;
pub use runner::{
    Artifact, Asset, AssetRef, Assets, Checkpoint, FieldError, JobContext, JobError, JobOutput,
    JobRegistry, JobRunner,
};

/// The OpenAPI description served at `/openapi.yaml`.
pub const OPENAPI_YAML: &str = include_str!("../../openapi.yaml");

/// Shared state of a running server; cheap to clone.
#[derive(Clone)]
pub struct AppState(Arc<Shared>);

/// What [`AppState`] shares.
pub struct Shared {
    pub pool: SqlitePool,
    pub config: Config,
    pub registry: JobRegistry,
    pub metrics: metrics::Metrics,
    pub keys: auth::Keys,
    /// Bumped after every event row is written; SSE streams wait on it.
    pub events: Arc<watch::Sender<u64>>,
    /// Woken when a job is queued.
    pub job_available: Notify,
    /// Stop flags of the jobs running in this process, by job id.
    pub running: Mutex<HashMap<String, Arc<runner::StopFlags>>>,
    /// `true` once shutdown began.
    pub shutdown: watch::Receiver<bool>,
    /// This process's identity in lease owners.
    pub instance: String,
    pub started: Instant,
}

impl Deref for AppState {
    type Target = Shared;
    fn deref(&self) -> &Shared {
        &self.0
    }
}

impl AppState {
    pub fn bump_events(&self) {
        self.events.send_modify(|v| *v = v.wrapping_add(1));
    }
}

/// The job kinds of a server built from `config`: the built-in ones that the configuration enables.
/// The application's real kinds are registered here too.
pub fn registry_for(config: &Config) -> JobRegistry {
    let mut registry = JobRegistry::new();
    registry.register(Arc::new(simulate_job::SimulateJob));
    registry.register(Arc::new(design_job::DesignJobKind));
    if config.jobs.enable_selftest {
        registry.register(Arc::new(selftest::SelfTest));
    }
    registry
}

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
    let request_id = HeaderName::from_static("x-request-id");
    let mut router = Router::new()
        .nest("/v1", v1)
        .route("/healthz", get(healthz))
        .route("/readyz", get(readyz))
        .route("/metrics", get(metrics::render))
        .route("/openapi.yaml", get(openapi))
        .fallback(not_found)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(middleware::from_fn_with_state(state.clone(), observe))
        .layer(TimeoutLayer::with_status_code(
            StatusCode::REQUEST_TIMEOUT,
            Duration::from_secs(state.config.server.request_timeout_s),
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
    router
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
        .with_state(state)
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

async fn healthz() -> impl IntoResponse {
    axum::Json(serde_json::json!({ "status": "ok" }))
}

async fn readyz(State(state): State<AppState>) -> Result<impl IntoResponse, ApiError> {
    if *state.shutdown.borrow() {
        return Err(ApiError::unavailable("the server is shutting down"));
    }
    sqlx::query("SELECT 1")
        .execute(&state.pool)
        .await
        .map_err(|e| {
            tracing::error!(error = %e, "readiness check: database unavailable");
            ApiError::unavailable("the database is unavailable")
        })?;
    Ok(axum::Json(serde_json::json!({
        "status": "ready",
        "workers": state.config.worker_count(),
        "kinds": state.registry.kinds(),
    })))
}

async fn openapi() -> impl IntoResponse {
    (
        [(axum::http::header::CONTENT_TYPE, "application/yaml")],
        OPENAPI_YAML,
    )
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

/// A failure to start the server.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    #[error(transparent)]
    Config(#[from] config::ConfigError),
    #[error("cannot open database {path}: {source}")]
    Database { path: String, source: sqlx::Error },
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        addr: SocketAddr,
        source: std::io::Error,
    },
    #[error("server failed: {0}")]
    Io(#[from] std::io::Error),
}

/// A started server: listening, with its workers running.
pub struct Server {
    /// The bound address (useful with port 0).
    pub addr: SocketAddr,
    pub state: AppState,
    shutdown_tx: watch::Sender<bool>,
    serve: tokio::task::JoinHandle<std::io::Result<()>>,
    workers: Vec<tokio::task::JoinHandle<()>>,
}

impl Server {
    /// Opens the database (re-queuing jobs a previous process left running), binds, and starts the
    /// workers and the HTTP server.
    pub async fn start(config: Config, registry: JobRegistry) -> Result<Server, ServerError> {
        config.check()?;
        let addr = config.bind_addr()?;
        let pool =
            db::open(&config.database.path)
                .await
                .map_err(|source| ServerError::Database {
                    path: config.database.path.display().to_string(),
                    source,
                })?;
        let recovered = queue::recover(&pool)
            .await
            .map_err(|source| ServerError::Database {
                path: config.database.path.display().to_string(),
                source,
            })?;
        if recovered > 0 {
            tracing::warn!(
                jobs = recovered,
                "re-queued jobs left running by a previous process"
            );
        }
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .map_err(|source| ServerError::Bind { addr, source })?;
        let addr = listener.local_addr()?;
        let (shutdown_tx, shutdown_rx) = watch::channel(false);
        let workers_n = config.worker_count();
        let state = AppState(Arc::new(Shared {
            pool,
            keys: auth::Keys::from_config(&config.auth),
            config,
            registry,
            metrics: metrics::Metrics::default(),
            events: Arc::new(watch::channel(0).0),
            job_available: Notify::new(),
            running: Mutex::new(HashMap::new()),
            shutdown: shutdown_rx.clone(),
            instance: uuid::Uuid::new_v4().to_string(),
            started: Instant::now(),
        }));
        let workers = (0..workers_n)
            .map(|i| tokio::spawn(worker::run_worker(state.clone(), i)))
            .collect();
        let router = app(state.clone());
        let mut stop = shutdown_rx;
        let serve = tokio::spawn(async move {
            axum::serve(listener, router)
                .with_graceful_shutdown(async move {
                    let _ = stop.wait_for(|s| *s).await;
                })
                .await
        });
        tracing::info!(%addr, workers = workers_n, kinds = ?state.registry.kinds(), "skintight serving");
        Ok(Server {
            addr,
            state,
            shutdown_tx,
            serve,
            workers,
        })
    }

    /// Graceful shutdown: stops accepting requests and claiming jobs, ends SSE streams, asks running jobs to
    /// stop at their next iteration (they are re-queued and resume from their checkpoint at the next
    /// start), and waits for them up to `server.shutdown_grace_s`.
    pub async fn shutdown(self) {
        let _ = self.shutdown_tx.send(true);
        for flags in self.state.running.lock().expect("running map").values() {
            flags
                .shutdown
                .store(true, std::sync::atomic::Ordering::SeqCst);
        }
        self.state.bump_events();
        let grace = Duration::from_secs(self.state.config.server.shutdown_grace_s);
        let wait = async {
            for w in self.workers {
                let _ = w.await;
            }
            let _ = self.serve.await;
        };
        if tokio::time::timeout(grace, wait).await.is_err() {
            tracing::warn!(
                "graceful shutdown timed out; jobs still running resume at the next start"
            );
        }
        self.state.pool.close().await;
    }
}

/// Runs `skintight serve` until SIGINT or SIGTERM.
pub async fn serve(config: Config) -> Result<(), ServerError> {
    let registry = registry_for(&config);
    let server = Server::start(config, registry).await?;
    shutdown_signal().await;
    tracing::info!("shutting down");
    server.shutdown().await;
    Ok(())
}

async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => {}
        _ = term => {}
    }
}

/// Installs the tracing subscriber described by `config.log` (text or JSON lines on stderr).
pub fn init_logging(config: &Config) {
    use tracing_subscriber::EnvFilter;
    let filter = EnvFilter::try_from_default_env()
        .or_else(|_| EnvFilter::try_new(&config.log.filter))
        .unwrap_or_else(|_| EnvFilter::new("info"));
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    let _ = if config.log.format == "json" {
        builder.json().try_init()
    } else {
        builder.try_init()
    };
}
