//! A node's life: the job kinds it is built with ([`registry_for`]), [`Server::start`] (open the store,
//! recover interrupted jobs, bind, start the workers and the router; [`Server::start_with`] without
//! workers for an API-only node), [`WorkerNode::start`] (workers, and only an optional ops port), the background tasks of
//! both (other nodes' notifications, the re-queuing of expired leases), graceful shutdown, [`serve`] and
//! [`work`] until a signal, and logging.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::watch;

use super::app::{app, ops_app};
use super::config::{self, Config};
use super::connections::{self, ConnectionLimits};
use super::runner::JobRegistry;
use super::state::AppState;
use super::store::{Notice, Requeue, Store};
use super::{design_job, queue, selftest, simulate_job, worker, yarn_simulate_job};

/// The job kinds of a server built from `config`: the built-in ones that the configuration enables.
/// The application's real kinds are registered here too.
pub fn registry_for(config: &Config) -> JobRegistry {
    let mut registry = JobRegistry::new();
    registry.register_builtin(Arc::new(simulate_job::SimulateJob));
    registry.register_builtin(Arc::new(design_job::DesignJobKind));
    registry.register_builtin(Arc::new(yarn_simulate_job::YarnSimulateJob::new(
        config.jobs.yarns_dir.clone(),
    )));
    if config.jobs.enable_selftest {
        registry.register_builtin(Arc::new(selftest::SelfTest));
    }
    registry
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

/// A started server: listening, with its workers running (unless it is an API-only node).
pub struct Server {
    /// The bound address (useful with port 0).
    pub addr: SocketAddr,
    pub state: AppState,
    shutdown_tx: watch::Sender<bool>,
    serve: tokio::task::JoinHandle<std::io::Result<()>>,
    workers: Vec<tokio::task::JoinHandle<()>>,
}

/// The store of `config`, opened, with the jobs a previous SQLite server left running taken back when
/// `recover` (a SQLite file has one owner; PostgreSQL nodes never take back another node's live runs:
/// expired leases are re-queued by [`spawn_lease_reaper`]).
async fn open_store(config: &Config, recover: bool) -> Result<Store, ServerError> {
    let db_error = |source| ServerError::Database {
        path: config.database.display(),
        source,
    };
    let store = Store::connect(&config.database, 8)
        .await
        .map_err(db_error)?;
    if recover && store.engine() == "sqlite" {
        let recovered = queue::recover(&store, config.jobs.max_attempts)
            .await
            .map_err(db_error)?;
        if recovered > 0 {
            tracing::warn!(
                jobs = recovered,
                "re-queued jobs left running by a previous process"
            );
        }
    }
    Ok(store)
}

/// The background tasks of a node: the PostgreSQL notifications of other nodes (events and queued jobs;
/// SSE streams and idle workers also poll, so a lost notification delays, never loses, anything) and, on
/// a node that runs workers, the re-queuing of runs whose lease expired.
fn spawn_background(state: &AppState, workers: bool) -> Vec<tokio::task::JoinHandle<()>> {
    let mut tasks = vec![tokio::spawn(listen(state.clone()))];
    if workers {
        tasks.push(tokio::spawn(reap_expired_leases(state.clone())));
    }
    tasks
}

/// Forwards other nodes' notifications to this node's waiters, reconnecting after errors.
async fn listen(state: AppState) {
    let mut shutdown = state.shutdown.clone();
    loop {
        let mut notes = match state.store.notifications().await {
            Ok(Some(n)) => n,
            Ok(None) => return,
            Err(e) => {
                tracing::warn!(error = %e, "cannot LISTEN for other nodes' events; polling meanwhile");
                tokio::select! {
                    _ = tokio::time::sleep(Duration::from_secs(1)) => continue,
                    _ = shutdown.changed() => return,
                }
            }
        };
        loop {
            let note = tokio::select! {
                n = notes.recv() => n,
                _ = shutdown.changed() => return,
            };
            match note {
                Ok(Notice::Event(_)) => state.bump_events(),
                Ok(Notice::Queued(_)) => state.job_available.notify_one(),
                Err(e) => {
                    tracing::warn!(error = %e, "lost the LISTEN connection; reconnecting");
                    // Whatever was announced meanwhile is found by the polls.
                    state.bump_events();
                    tokio::time::sleep(Duration::from_millis(200)).await;
                    break;
                }
            }
        }
    }
}

/// Every third of `jobs.lease_s`: re-queues the runs whose lease expired (their worker died or lost the
/// database), so that another worker resumes them from their checkpoint.
async fn reap_expired_leases(state: AppState) {
    let mut shutdown = state.shutdown.clone();
    let every = Duration::from_secs(state.config.jobs.lease_s) / 3;
    loop {
        tokio::select! {
            _ = tokio::time::sleep(every) => {}
            _ = shutdown.changed() => return,
        }
        match state
            .store
            .requeue_runs(state.config.jobs.max_attempts, Requeue::LeaseExpired)
            .await
        {
            Ok(0) => {}
            Ok(n) => {
                tracing::warn!(jobs = n, "re-queued jobs whose worker's lease expired");
                state.bump_events();
                state.job_available.notify_waiters();
            }
            Err(e) => tracing::error!(error = %e, "re-queuing expired leases failed"),
        }
    }
}

fn spawn_workers(state: &AppState, n: usize) -> Vec<tokio::task::JoinHandle<()>> {
    (0..n)
        .map(|i| tokio::spawn(worker::run_worker(state.clone(), i)))
        .collect()
}

/// Graceful shutdown of a node's workers: asks running jobs to stop at their next iteration (each is
/// re-queued with its checkpoint), waits for them up to `server.shutdown_grace_s` (with `also`, the HTTP
/// server), then hands back at once the runs still held by this node, so that other workers need not
/// wait for their leases to expire.
async fn stop_workers(
    state: &AppState,
    shutdown_tx: &watch::Sender<bool>,
    tasks: Vec<tokio::task::JoinHandle<()>>,
    also: Option<tokio::task::JoinHandle<std::io::Result<()>>>,
) {
    let _ = shutdown_tx.send(true);
    for flags in state.running.lock().expect("running map").values() {
        flags
            .shutdown
            .store(true, std::sync::atomic::Ordering::SeqCst);
    }
    state.bump_events();
    let grace = Duration::from_secs(state.config.server.shutdown_grace_s);
    let wait = async {
        for w in tasks {
            let _ = w.await;
        }
        if let Some(serve) = also {
            let _ = serve.await;
        }
    };
    if tokio::time::timeout(grace, wait).await.is_err() {
        tracing::warn!("graceful shutdown timed out; handing back the jobs still running");
    }
    match state.store.hand_back(&format!("{}/", state.instance)).await {
        Ok(0) => {}
        Ok(n) => tracing::warn!(jobs = n, "handed back jobs still running at shutdown"),
        Err(e) => tracing::error!(error = %e, "handing back jobs at shutdown failed"),
    }
    state.store.close().await;
}

impl Server {
    /// Opens the database (re-queuing jobs a previous SQLite process left running), binds, and starts the
    /// workers and the HTTP server.
    pub async fn start(config: Config, registry: JobRegistry) -> Result<Server, ServerError> {
        Self::start_with(config, registry, true).await
    }

    /// [`Self::start`], with `workers = false` an API-only node (`skintight serve --no-workers`): it
    /// accepts, lists and streams jobs that worker nodes ([`WorkerNode`]) run.
    pub async fn start_with(
        config: Config,
        registry: JobRegistry,
        workers: bool,
    ) -> Result<Server, ServerError> {
        config.check()?;
        let addr = config.bind_addr()?;
        let store = open_store(&config, true).await?;
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .map_err(|source| ServerError::Bind { addr, source })?;
        let addr = listener.local_addr()?;
        let (shutdown_tx, shutdown_rx) = watch::channel(false);
        let workers_n = if workers { config.worker_count() } else { 0 };
        let state = AppState::new(store, config, registry, shutdown_rx.clone(), workers_n);
        let mut tasks = spawn_workers(&state, workers_n);
        tasks.extend(spawn_background(&state, workers));
        let router = app(state.clone());
        let limits = ConnectionLimits {
            header_timeout: Duration::from_secs(state.config.server.header_timeout_s),
            max_connections: state.config.server.max_connections,
        };
        let serve = tokio::spawn(connections::serve(listener, router, limits, shutdown_rx));
        tracing::info!(%addr, workers = workers_n, engine = state.store.engine(), kinds = ?state.registry.kinds(), "skintight serving");
        Ok(Server {
            addr,
            state,
            shutdown_tx,
            serve,
            workers: tasks,
        })
    }

    /// Graceful shutdown: stops accepting requests and claiming jobs, ends SSE streams, asks running jobs to
    /// stop at their next iteration (they are re-queued and resume from their checkpoint), waits for them up
    /// to `server.shutdown_grace_s`, and hands back the runs still held.
    pub async fn shutdown(self) {
        stop_workers(
            &self.state,
            &self.shutdown_tx,
            self.workers,
            Some(self.serve),
        )
        .await;
    }
}

/// A worker node (`skintight worker`): `jobs.workers` workers claiming jobs from a shared PostgreSQL
/// database, and no API port; with `worker.ops_addr`, an ops port serving `/healthz`, `/readyz` and
/// `/metrics` ([`ops_app`]).
pub struct WorkerNode {
    pub state: AppState,
    /// The bound address of the ops port, if any (useful with port 0).
    pub ops_addr: Option<SocketAddr>,
    shutdown_tx: watch::Sender<bool>,
    tasks: Vec<tokio::task::JoinHandle<()>>,
    ops: Option<tokio::task::JoinHandle<std::io::Result<()>>>,
}

impl WorkerNode {
    /// Opens the database, binds the ops port (`worker.ops_addr`, if set) and starts the workers.
    pub async fn start(config: Config, registry: JobRegistry) -> Result<WorkerNode, ServerError> {
        config.check()?;
        let ops_addr = config.ops_addr()?;
        let store = open_store(&config, false).await?;
        let listener = match ops_addr {
            Some(addr) => Some(
                tokio::net::TcpListener::bind(addr)
                    .await
                    .map_err(|source| ServerError::Bind { addr, source })?,
            ),
            None => None,
        };
        let ops_addr = listener.as_ref().map(|l| l.local_addr()).transpose()?;
        let (shutdown_tx, shutdown_rx) = watch::channel(false);
        let n = config.worker_count();
        let state = AppState::new(store, config, registry, shutdown_rx.clone(), n);
        let mut tasks = spawn_workers(&state, n);
        tasks.extend(spawn_background(&state, true));
        let ops = listener.map(|listener| {
            let limits = ConnectionLimits {
                header_timeout: Duration::from_secs(state.config.server.header_timeout_s),
                max_connections: state.config.server.max_connections,
            };
            tokio::spawn(connections::serve(
                listener,
                ops_app(state.clone()),
                limits,
                shutdown_rx,
            ))
        });
        tracing::info!(workers = n, ops_addr = ?ops_addr, engine = state.store.engine(), kinds = ?state.registry.kinds(), "skintight worker node running");
        Ok(WorkerNode {
            state,
            ops_addr,
            shutdown_tx,
            tasks,
            ops,
        })
    }

    /// Graceful shutdown, as [`Server::shutdown`]'s: running jobs are re-queued at once (the ops port
    /// answers 503 on `/readyz` meanwhile, then closes).
    pub async fn shutdown(self) {
        stop_workers(&self.state, &self.shutdown_tx, self.tasks, self.ops).await;
    }
}

/// Runs `skintight serve` until SIGINT or SIGTERM; `workers = false` for an API-only node.
pub async fn serve(config: Config, workers: bool) -> Result<(), ServerError> {
    let registry = registry_for(&config);
    let server = Server::start_with(config, registry, workers).await?;
    shutdown_signal().await;
    tracing::info!("shutting down");
    server.shutdown().await;
    Ok(())
}

/// Runs `skintight worker` until SIGINT or SIGTERM.
pub async fn work(config: Config) -> Result<(), ServerError> {
    let registry = registry_for(&config);
    let node = WorkerNode::start(config, registry).await?;
    shutdown_signal().await;
    tracing::info!("shutting down");
    node.shutdown().await;
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
    // Colours only on a terminal: a log written to a file or a pipe carries no ANSI escape codes.
    use std::io::IsTerminal;
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr);
    let _ = if config.log.format == "json" {
        builder.json().try_init()
    } else {
        builder.try_init()
    };
}
