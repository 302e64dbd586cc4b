//! The shared state of a running server, [`AppState`]: the store, the configuration, the job kinds, the
//! keys, the metrics, and the in-process signals of the job pipeline (event and work notifications, the
//! stop flags of running jobs, the shutdown flag).
//!
//! Extractors that need only a part of it take that part through [`FromRef`] (the keys: `Arc<Keys>`).

use std::collections::HashMap;
use std::ops::Deref;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use axum::extract::FromRef;
use tokio::sync::{Notify, watch};

use super::asset_budget::AssetBudget;
use super::config::Config;
use super::keys::Keys;
use super::metrics::Metrics;
use super::model::StopFlags;
use super::runner::JobRegistry;
use super::store::Store;

/// Shared state of a running server; cheap to clone.
#[derive(Clone)]
pub struct AppState(Arc<Shared>);

/// What [`AppState`] shares.
pub struct Shared {
    pub store: Store,
    pub config: Config,
    pub registry: JobRegistry,
    pub metrics: Metrics,
    pub keys: Arc<Keys>,
    /// The byte budget of the meshes read inside this process (`server.asset_check_memory_bytes`).
    pub asset_budget: AssetBudget,
    /// Bumped after every event row is written; SSE streams wait on it.
    pub events: Arc<watch::Sender<u64>>,
    /// Woken when a job is queued.
    pub job_available: Notify,
    /// Stop flags of the jobs running in this process, by job id.
    pub running: Mutex<HashMap<String, Arc<StopFlags>>>,
    /// `true` once shutdown began.
    pub shutdown: watch::Receiver<bool>,
    /// This process's identity: the start of its workers' lease ids.
    pub instance: String,
    /// The workers this process runs (0 on an API-only node).
    pub workers: usize,
    pub started: Instant,
}

impl Deref for AppState {
    type Target = Shared;
    fn deref(&self) -> &Shared {
        &self.0
    }
}

impl AppState {
    /// The state of a server that starts now, with a fresh instance id and empty metrics.
    pub fn new(
        store: Store,
        config: Config,
        registry: JobRegistry,
        shutdown: watch::Receiver<bool>,
        workers: usize,
    ) -> AppState {
        AppState(Arc::new(Shared {
            store,
            keys: Arc::new(Keys::from_config(&config.auth)),
            asset_budget: AssetBudget::new(
                config.server.asset_budget_bytes(),
                std::time::Duration::from_secs(config.server.asset_check_wait_s),
            ),
            config,
            registry,
            metrics: Metrics::default(),
            events: Arc::new(watch::channel(0).0),
            job_available: Notify::new(),
            running: Mutex::new(HashMap::new()),
            shutdown,
            instance: uuid::Uuid::new_v4().to_string(),
            workers,
            started: Instant::now(),
        }))
    }

    /// Wakes the SSE streams after an event row was written.
    pub fn bump_events(&self) {
        self.events.send_modify(|v| *v = v.wrapping_add(1));
    }
}

impl FromRef<AppState> for Arc<Keys> {
    fn from_ref(state: &AppState) -> Arc<Keys> {
        state.keys.clone()
    }
}
