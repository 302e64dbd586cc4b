//! The service's data types: what a job, an asset, an artifact and a job's outcome are, as plain values.
//! No I/O here: [`super::store`] reads and writes them, the route handlers show them, the job pipeline
//! ([`super::queue`], [`super::worker`], [`super::runner`]) moves them along.
//!
//! A job's status is one of [`STATUSES`]: `queued → running → completed | failed | cancelled`, and
//! `running → queued` when a run is interrupted (see [`super::queue`]).

use std::collections::BTreeMap;
use std::sync::atomic::AtomicBool;

use serde_json::{Value, json};
use sha2::{Digest, Sha256};

/// Every job status, in the order of the state machine.
pub const STATUSES: &[&str] = &["queued", "running", "completed", "failed", "cancelled"];

/// Whether a status (or event kind) ends a job.
pub fn is_terminal(status: &str) -> bool {
    matches!(status, "completed" | "failed" | "cancelled")
}

/// Lower-case hex SHA-256: the content address of assets and artifacts, and the request hash of
/// idempotent submissions.
pub fn sha256_hex(data: &[u8]) -> String {
    hex::encode(Sha256::digest(data))
}

/// A spec rejected at submission: `field` is a path inside the spec (`iterations`, `body.scale`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldError {
    pub field: String,
    pub message: String,
}

impl FieldError {
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        FieldError {
            field: field.into(),
            message: message.into(),
        }
    }
}

/// A reference from a spec to an uploaded asset: `field` is its path in the spec.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AssetRef {
    pub field: String,
    pub id: String,
}

/// An uploaded asset handed to a runner.
#[derive(Debug, Clone)]
pub struct Asset {
    pub id: String,
    /// `obj`, `stl`, `ply` or `glb`.
    pub format: String,
    pub sha256: String,
    pub data: Vec<u8>,
}

/// The assets a job's spec refers to, by the spec field that names them.
#[derive(Debug, Clone, Default)]
pub struct Assets {
    pub by_field: BTreeMap<String, Asset>,
}

impl Assets {
    pub fn get(&self, field: &str) -> Option<&Asset> {
        self.by_field.get(field)
    }
}

/// An asset's metadata as the API shows it (`GET /v1/assets/{id}`).
#[derive(Debug, Clone)]
pub struct AssetInfo {
    pub id: String,
    pub sha256: String,
    pub bytes: i64,
    pub format: String,
    pub created_at: String,
}

impl AssetInfo {
    pub fn to_json(&self) -> Value {
        json!({
            "id": self.id,
            "sha256": self.sha256,
            "bytes": self.bytes,
            "format": self.format,
            "created_at": self.created_at,
        })
    }
}

/// A named output of a job.
#[derive(Debug, Clone)]
pub struct Artifact {
    /// File-like name, `[A-Za-z0-9._-]+`, unique within the job (see [`valid_artifact_name`]).
    pub name: String,
    pub content_type: String,
    pub data: Vec<u8>,
}

/// Artifact names are file-like: 1–128 of `[A-Za-z0-9._-]`, not starting with a dot.
pub fn valid_artifact_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 128
        && !name.starts_with('.')
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'.' || b == b'_' || b == b'-')
}

/// A stored artifact's metadata as the artifact list shows it.
#[derive(Debug, Clone)]
pub struct ArtifactInfo {
    pub name: String,
    pub content_type: String,
    pub bytes: i64,
    pub sha256: String,
}

/// What a finished job produced.
#[derive(Debug, Clone, Default)]
pub struct JobOutput {
    pub artifacts: Vec<Artifact>,
    /// A small JSON summary shown with the job.
    pub summary: Value,
    /// What the client must know about a completed job (e.g. a garment that is not admissible): each
    /// becomes a `warning` event, stored with the `completed` event in one transaction, before it.
    pub warnings: Vec<Value>,
}

/// How a job run ended without output.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JobError {
    /// The client cancelled the job.
    #[error("the job was cancelled")]
    Cancelled,
    /// The job ran past the configured time limit.
    #[error("the job ran past its time limit of {limit_s} s")]
    TimedOut { limit_s: u64 },
    /// The server is shutting down (or lost the job's lease); the job is re-queued and resumes from its last
    /// checkpoint later.
    #[error("the job was interrupted and will be resumed")]
    Interrupted,
    /// The inputs turned out unusable while running (e.g. a mesh that does not parse).
    #[error("invalid input {field}: {message}")]
    Invalid { field: String, message: String },
    /// The computation failed.
    #[error("{0}")]
    Failed(String),
}

/// A saved intermediate state: the iteration it was taken after and the runner's bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct JobCheckpoint {
    pub iteration: u64,
    pub data: Vec<u8>,
}

/// Why a running job should stop, shared between the worker, the cancel route and shutdown.
#[derive(Debug, Default)]
pub struct StopFlags {
    pub cancel: AtomicBool,
    pub shutdown: AtomicBool,
}

/// A job as stored.
#[derive(Debug, Clone)]
pub struct JobRow {
    pub seq: i64,
    pub id: String,
    pub tenant: String,
    pub kind: String,
    pub spec: Value,
    pub status: String,
    pub cancel_requested: bool,
    pub attempts: i64,
    pub iterations: i64,
    pub progress: Option<f64>,
    pub last_metrics: Option<Value>,
    pub summary: Option<Value>,
    pub error_code: Option<String>,
    pub error_message: Option<String>,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
    pub queued_ms: Option<i64>,
    pub run_ms: Option<i64>,
}

impl JobRow {
    /// The job as the API shows it.
    pub fn to_json(&self) -> Value {
        json!({
            "id": self.id,
            "kind": self.kind,
            "status": self.status,
            "spec": self.spec,
            "cancel_requested": self.cancel_requested,
            "attempts": self.attempts,
            "progress": {
                "iterations": self.iterations,
                "fraction": self.progress,
            },
            "metrics": self.last_metrics,
            "summary": self.summary,
            "error": self.error_code.as_ref().map(|code| json!({
                "code": code,
                "message": self.error_message,
            })),
            "timings": {
                "created_at": self.created_at,
                "started_at": self.started_at,
                "finished_at": self.finished_at,
                "queued_ms": self.queued_ms,
                "run_ms": self.run_ms,
            },
        })
    }

    pub fn is_finished(&self) -> bool {
        is_terminal(&self.status)
    }
}

/// A job to be stored as `queued`: its spec already parsed and validated by its kind (see
/// [`super::runner`]), kept as the canonical JSON text that the worker parses again.
#[derive(Debug, Clone)]
pub struct NewJob {
    pub id: String,
    pub tenant: String,
    pub kind: String,
    /// The spec's JSON text (keys sorted, no insignificant whitespace).
    pub spec: String,
    pub idempotency_key: Option<String>,
    /// SHA-256 of the canonical `{"kind", "spec"}` document, to tell a replay from a reused key.
    pub request_hash: String,
}

/// A job the worker claimed.
#[derive(Debug, Clone)]
pub struct Claimed {
    pub id: String,
    pub tenant: String,
    pub kind: String,
    /// The spec as stored (validated at submission).
    pub spec: Value,
    pub attempts: i64,
    pub iterations: u64,
    pub cancel_requested: bool,
    pub checkpoint: Option<JobCheckpoint>,
}

/// How a run ended, as the queue records it.
#[derive(Debug)]
pub enum Outcome {
    Completed {
        artifacts: Vec<Artifact>,
        summary: Value,
        /// Each a `warning` event's data, stored before `completed`.
        warnings: Vec<Value>,
    },
    Failed {
        code: &'static str,
        message: String,
    },
    Cancelled,
    /// Back to the queue (shutdown); resumes from the last checkpoint.
    Requeued {
        reason: &'static str,
    },
}

impl Outcome {
    pub fn label(&self) -> &'static str {
        match self {
            Outcome::Completed { .. } => "completed",
            Outcome::Failed { .. } => "failed",
            Outcome::Cancelled => "cancelled",
            Outcome::Requeued { .. } => "requeued",
        }
    }
}

/// Result of a cancel request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CancelResult {
    NotFound,
    /// Cancelled while queued (final now).
    Cancelled,
    /// Running: the flag is set and the runner stops within one iteration.
    Requested,
    AlreadyFinished(String),
}

/// What storing a new job did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Inserted {
    /// Stored as `queued`, with its `queued` event.
    Queued,
    /// Nothing stored: the tenant already has a job with this idempotency key (a concurrent request with
    /// the same key won the race).
    KeyTaken,
}

/// One row of a job's event log: `seq` is the SSE `id:`, `kind` the SSE `event:`, `data` JSON text.
#[derive(Debug, Clone)]
pub struct EventRecord {
    pub seq: i64,
    pub kind: String,
    pub data: String,
}
