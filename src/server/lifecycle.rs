//! A server's life: the job kinds it is built with ([`registry_for`]), [`Server::start`] (open the store,
//! recover interrupted jobs, bind, start the workers and the router), graceful [`Server::shutdown`],
//! [`serve`] until a signal, and logging.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::watch;

use super::app::app;
use super::config::{self, Config};
use super::connections::{self, ConnectionLimits};
use super::runner::JobRegistry;
use super::state::AppState;
use super::store::Store;
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
        let store =
            Store::open(&config.database.path)
                .await
                .map_err(|source| ServerError::Database {
                    path: config.database.path.display().to_string(),
                    source,
                })?;
        let recovered = queue::recover(&store, config.jobs.max_attempts)
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
        let state = AppState::new(store, config, registry, shutdown_rx.clone());
        let workers = (0..workers_n)
            .map(|i| tokio::spawn(worker::run_worker(state.clone(), i)))
            .collect();
        let router = app(state.clone());
        let limits = ConnectionLimits {
            header_timeout: Duration::from_secs(state.config.server.header_timeout_s),
            max_connections: state.config.server.max_connections,
        };
        let serve = tokio::spawn(connections::serve(listener, router, limits, shutdown_rx));
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
        self.state.store.close().await;
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
