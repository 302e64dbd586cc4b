//! The headless HTTP/JSON service (`skintight serve`): uploads meshes, queues jobs of pluggable kinds,
//! streams their progress as server-sent events and serves their artifacts. State lives in one SQLite file,
//! or in a PostgreSQL database shared by API nodes (`serve --no-workers`) and worker nodes (`worker`).
//!
//! One module per concern, listed from the bottom of the dependency order up (a module imports only
//! modules above it in this list, so no two import each other):
//!
//! - [`asset_budget`] (the server-wide byte budget of the meshes read inside the server), [`config`]
//!   (settings), [`error`] (the JSON error envelope), [`model`] (the data types: jobs, assets,
//!   artifacts, events, outcomes; no I/O), [`metrics`] (histograms and the Prometheus text);
//! - [`store`]: all SQL, behind one `Store` with two engines (SQLite, PostgreSQL), and the leases under
//!   which jobs run;
//! - [`keys`] (API keys and the `Tenant`/`Operator` extractors), [`request`] (query strings, bodies);
//! - [`runner`] (the `JobRunner` trait, the registry of kinds, the running job's `JobContext`, and the
//!   one-parse path of a spec);
//! - [`state`] (`AppState`);
//! - the job pipeline: [`queue`] (state transitions and their wake-ups), [`isolation`] (running a job in a
//!   child process under memory and CPU limits), [`worker`] (the worker pool), [`job_process`] (the child's
//!   side: `skintight job-run`);
//! - the kinds: [`simulate_job`], [`design_job`], [`selftest`] (an operator smoke-test kind);
//! - the routes: [`assets`], [`jobs`], [`events`] (SSE), [`ops`] (health, readiness, metrics, OpenAPI);
//! - [`mod@app`] (the one router), [`connections`] (accepting connections: header-read timeout,
//!   connection limit), [`lifecycle`] (start, shutdown, `serve`).
//!
//! The path of a job, from `POST /v1/jobs` to its artifacts: [`jobs::submit`] parses and validates the
//! spec once ([`runner::JobRegistry::accept`]), checks its assets and stores it ([`queue::submit`] →
//! `Store::insert_job`); a worker ([`worker::run_worker`]) claims it (`Store::claim`), parses the stored
//! spec once ([`runner::JobRegistry::load`]), loads its assets and runs it on a blocking thread
//! ([`runner::ParsedSpec::run`] → the kind's [`JobRunner::run`], e.g. [`simulate_job`] →
//! [`crate::simulate`]), reporting iterations through [`JobContext`]; [`queue::finish`] stores the outcome
//! and artifacts (`Store::finish`).

pub mod app;
pub mod asset_budget;
pub mod assets;
pub mod config;
pub mod connections;
pub mod design_job;
pub mod error;
pub mod events;
pub mod isolation;
pub mod job_process;
pub mod jobs;
pub mod keys;
pub mod lifecycle;
pub mod metrics;
pub mod model;
pub mod ops;
pub mod queue;
pub mod request;
pub mod runner;
pub mod selftest;
pub mod simulate_job;
pub mod state;
pub mod store;
pub mod worker;
pub mod yarn_simulate_job;

pub use app::app;
pub use config::Config;
pub use error::ApiError;
pub use lifecycle::{Server, ServerError, WorkerNode, init_logging, registry_for, serve, work};
pub use model::{
    Artifact, Asset, AssetRef, Assets, FieldError, JobCheckpoint, JobError, JobOutput,
};
pub use ops::OPENAPI_YAML;
pub use runner::{JobContext, JobRegistry, JobRunner, ParsedSpec};
pub use state::AppState;
