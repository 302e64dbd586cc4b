//! Shared helpers of the server integration tests: a real server on 127.0.0.1:0 with a temporary SQLite
//! file, an HTTP client, an SSE reader, and the `count` test job kind.
//!
//! With `SKINTIGHT_TEST_ENGINE=postgres` the servers use PostgreSQL instead: each SQLite path a test
//! names becomes a throwaway PostgreSQL cluster ([`pg`]), shared by the servers a test starts on
//! the same path. `.ci/run` runs the engine-neutral tests of `server_api` that way too.
#![allow(dead_code)]

pub mod pg;

use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::Deserialize;
use serde_json::{Value, json};
use skintight::server::{
    Artifact, AssetRef, Assets, Config, FieldError, JobContext, JobError, JobOutput, JobRegistry,
    JobRunner, Server,
};

pub const ALICE: &str = "alice-key-0001";
pub const BOB: &str = "bob-key-00002";
pub const OPERATOR: &str = "operator-key-01";

/// The `count` test kind: a deterministic iterative computation `v_k = v_{k-1} + k² mod 1000003` with a
/// checkpoint after every iteration and a per-iteration sleep; optionally reads an asset and fails at an
/// iteration.
pub struct Count;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CountSpec {
    iterations: u64,
    #[serde(default)]
    sleep_ms: u64,
    #[serde(default)]
    fail_at: Option<u64>,
    #[serde(default)]
    mesh: Option<String>,
}

fn count_spec(spec: &Value) -> Result<CountSpec, FieldError> {
    serde_path_to_error::deserialize(spec).map_err(|e| {
        let path = e.path().to_string();
        let msg = e.into_inner().to_string();
        let field = skintight::server::error::field_of(&path, &msg);
        FieldError::new(field, msg)
    })
}

/// The value after `n` iterations, computed directly.
pub fn count_value(n: u64) -> u64 {
    (1..=n).fold(0, |v, k| (v + k * k) % 1_000_003)
}

impl JobRunner for Count {
    type Spec = CountSpec;

    fn kind(&self) -> &'static str {
        "count"
    }
    fn parse(&self, spec: &Value) -> Result<CountSpec, FieldError> {
        count_spec(spec)
    }
    fn validate(&self, s: &CountSpec) -> Result<(), FieldError> {
        if s.iterations == 0 || s.iterations > 10_000 {
            return Err(FieldError::new("iterations", "must be between 1 and 10000"));
        }
        Ok(())
    }
    fn assets(&self, spec: &CountSpec) -> Vec<AssetRef> {
        spec.mesh
            .clone()
            .map(|id| {
                vec![AssetRef {
                    field: "mesh".into(),
                    id,
                }]
            })
            .unwrap_or_default()
    }
    fn run(
        &self,
        s: &CountSpec,
        assets: &Assets,
        ctx: &mut JobContext,
    ) -> Result<JobOutput, JobError> {
        let (mut k, mut v) = match ctx.last_checkpoint() {
            Some(cp) => (
                cp.iteration,
                u64::from_le_bytes(cp.data[..8].try_into().unwrap()),
            ),
            None => (0, 0),
        };
        while k < s.iterations {
            std::thread::sleep(Duration::from_millis(s.sleep_ms));
            k += 1;
            if s.fail_at == Some(k) {
                return Err(JobError::Failed(format!("asked to fail at {k}")));
            }
            v = (v + k * k) % 1_000_003;
            ctx.progress(k as f64 / s.iterations as f64);
            ctx.iteration(json!({ "value": v }))?;
            ctx.checkpoint(v.to_le_bytes().to_vec())?;
        }
        let mesh_bytes = assets.get("mesh").map(|a| a.data.len());
        let summary = json!({ "value": v, "iterations": k, "mesh_bytes": mesh_bytes });
        Ok(JobOutput {
            artifacts: vec![
                Artifact {
                    name: "value.txt".into(),
                    content_type: "text/plain".into(),
                    data: v.to_string().into_bytes(),
                },
                Artifact {
                    name: "summary.json".into(),
                    content_type: "application/json".into(),
                    data: serde_json::to_vec(&summary).unwrap(),
                },
            ],
            summary,
            warnings: Vec::new(),
        })
    }
}

pub fn registry() -> JobRegistry {
    let mut r = JobRegistry::new();
    r.register(Arc::new(Count));
    // The executable's own kinds: with `jobs.isolation = "process"` they run in job processes.
    r.register_builtin(Arc::new(skintight::server::simulate_job::SimulateJob));
    r.register_builtin(Arc::new(skintight::server::design_job::DesignJobKind));
    r.register_builtin(Arc::new(
        skintight::server::yarn_simulate_job::YarnSimulateJob::new(yarns_dir()),
    ));
    r
}

/// The shared yarn patterns beside the repository (`../shared/data/yarns`).
pub fn yarns_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/yarns")
}

/// A server under test with its temporary directory.
pub struct TestServer {
    pub server: Option<Server>,
    pub base: String,
    pub client: reqwest::Client,
    pub dir: tempfile::TempDir,
    /// The PostgreSQL cluster standing in for the SQLite file (`SKINTIGHT_TEST_ENGINE=postgres`).
    pub postgres: Option<Arc<pg::PgCluster>>,
}

/// Whether the test servers use PostgreSQL (`SKINTIGHT_TEST_ENGINE=postgres`).
pub fn on_postgres() -> bool {
    match std::env::var("SKINTIGHT_TEST_ENGINE").as_deref() {
        Ok("postgres") => true,
        Ok("sqlite") | Err(_) => false,
        Ok(other) => panic!("SKINTIGHT_TEST_ENGINE={other:?}: use sqlite or postgres"),
    }
}

/// The PostgreSQL cluster standing in for the SQLite file `db`: the one already running for it, or a new
/// one.
fn cluster_for(db: &std::path::Path) -> Arc<pg::PgCluster> {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock, Weak};
    static CLUSTERS: OnceLock<Mutex<HashMap<std::path::PathBuf, Weak<pg::PgCluster>>>> =
        OnceLock::new();
    let mut map = CLUSTERS.get_or_init(Default::default).lock().unwrap();
    if let Some(c) = map.get(db).and_then(Weak::upgrade) {
        return c;
    }
    let c = Arc::new(pg::PgCluster::start().expect(
        "SKINTIGHT_TEST_ENGINE=postgres needs PostgreSQL's binaries (see tests/server_support/pg.rs)",
    ));
    map.insert(db.to_path_buf(), Arc::downgrade(&c));
    c
}

pub fn config(db: &std::path::Path, extra: &str) -> Config {
    let text = format!(
        r#"
[server]
bind = "127.0.0.1:0"
max_asset_bytes = 4096
shutdown_grace_s = 5
[database]
path = {db:?}
[jobs]
workers = 2
# The test binary is not `skintight`: jobs run on threads unless a test names the runner executable.
isolation = "thread"
[auth]
operator_keys = ["{OPERATOR}"]
keys = [{{ key = "{ALICE}", tenant = "alice" }}, {{ key = "{BOB}", tenant = "bob" }}]
"#
    );
    // `extra` overrides keys of the text above, table by table.
    let mut base: toml::Table = text.parse().unwrap();
    let extra: toml::Table = extra.parse().unwrap();
    for (section, table) in extra {
        match (base.get_mut(&section), table) {
            (Some(toml::Value::Table(b)), toml::Value::Table(t)) => b.extend(t),
            (_, v) => {
                base.insert(section, v);
            }
        }
    }
    Config::from_toml_overlay(&base.to_string()).expect("test config")
}

impl TestServer {
    pub async fn start(extra: &str) -> TestServer {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("test.db");
        Self::start_in(dir, &db, extra).await
    }

    pub async fn start_in(dir: tempfile::TempDir, db: &std::path::Path, extra: &str) -> TestServer {
        let mut config = config(db, extra);
        let postgres = on_postgres().then(|| cluster_for(db));
        if let Some(pg) = &postgres {
            config.database.url = pg.database("test").await;
        }
        let server = Server::start(config, registry())
            .await
            .expect("server starts");
        let base = format!("http://{}", server.addr);
        TestServer {
            server: Some(server),
            base,
            client: reqwest::Client::new(),
            dir,
            postgres,
        }
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{}", self.base, path)
    }

    pub async fn get(&self, key: &str, path: &str) -> (u16, Value) {
        let r = self
            .client
            .get(self.url(path))
            .bearer_auth(key)
            .send()
            .await
            .unwrap();
        let status = r.status().as_u16();
        let text = r.text().await.unwrap();
        (
            status,
            serde_json::from_str(&text).unwrap_or(Value::String(text)),
        )
    }

    pub async fn post_json(&self, key: &str, path: &str, body: &Value) -> (u16, Value) {
        self.post_raw(
            key,
            path,
            body.to_string().into_bytes(),
            "application/json",
            None,
        )
        .await
    }

    pub async fn post_raw(
        &self,
        key: &str,
        path: &str,
        body: Vec<u8>,
        content_type: &str,
        idempotency_key: Option<&str>,
    ) -> (u16, Value) {
        let mut req = self
            .client
            .post(self.url(path))
            .bearer_auth(key)
            .header("content-type", content_type)
            .body(body);
        if let Some(k) = idempotency_key {
            req = req.header("idempotency-key", k);
        }
        let r = req.send().await.unwrap();
        let status = r.status().as_u16();
        let text = r.text().await.unwrap();
        (
            status,
            serde_json::from_str(&text).unwrap_or(Value::String(text)),
        )
    }

    pub async fn submit(&self, key: &str, spec: Value) -> String {
        self.submit_kind(key, "count", spec).await
    }

    /// Submits a job of `kind`; expects 201 and returns its id.
    pub async fn submit_kind(&self, key: &str, kind: &str, spec: Value) -> String {
        let (s, job) = self
            .post_json(key, "/v1/jobs", &json!({ "kind": kind, "spec": spec }))
            .await;
        assert_eq!(s, 201, "{job}");
        job["id"].as_str().unwrap().to_string()
    }

    /// Uploads the body surface `regular_1k.obj` (the server needs `server.max_asset_bytes` ≥ 100 kB);
    /// returns the asset.
    pub async fn upload_body(&self, key: &str) -> Value {
        let (s, asset) = self
            .post_raw(key, "/v1/assets", body_obj(), "model/obj", None)
            .await;
        assert!(s == 201 || s == 200, "{s} {asset}");
        asset
    }

    /// GETs raw bytes: status, content type, body.
    pub async fn get_bytes(&self, key: &str, path: &str) -> (u16, String, Vec<u8>) {
        let r = self
            .client
            .get(self.url(path))
            .bearer_auth(key)
            .send()
            .await
            .unwrap();
        let status = r.status().as_u16();
        let ct = r
            .headers()
            .get("content-type")
            .map(|v| v.to_str().unwrap().to_string())
            .unwrap_or_default();
        (status, ct, r.bytes().await.unwrap().to_vec())
    }

    /// Polls a job until it is finished.
    pub async fn wait_finished(&self, key: &str, id: &str) -> Value {
        let deadline = Instant::now() + Duration::from_secs(90);
        loop {
            let (s, job) = self.get(key, &format!("/v1/jobs/{id}")).await;
            assert_eq!(s, 200, "{job}");
            if matches!(
                job["status"].as_str(),
                Some("completed" | "failed" | "cancelled")
            ) {
                return job;
            }
            assert!(Instant::now() < deadline, "job {id} did not finish: {job}");
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    /// Reads the job's SSE stream until it closes (or `max` events arrived).
    pub async fn events(
        &self,
        key: &str,
        id: &str,
        last_event_id: Option<i64>,
        max: usize,
    ) -> Vec<SseEvent> {
        read_sse(
            &self.client,
            &self.url(&format!("/v1/jobs/{id}/events")),
            key,
            last_event_id,
            max,
        )
        .await
    }

    pub async fn shutdown(&mut self) {
        if let Some(s) = self.server.take() {
            s.shutdown().await;
        }
    }
}

/// One parsed server-sent event.
#[derive(Debug, Clone, PartialEq)]
pub struct SseEvent {
    pub id: i64,
    pub event: String,
    pub data: Value,
}

/// Reads an SSE stream until it closes or `max` events arrived (90 s limit: a simulate job on a loaded
/// machine).
pub async fn read_sse(
    client: &reqwest::Client,
    url: &str,
    key: &str,
    last_event_id: Option<i64>,
    max: usize,
) -> Vec<SseEvent> {
    let mut req = client.get(url).bearer_auth(key);
    if let Some(id) = last_event_id {
        req = req.header("last-event-id", id.to_string());
    }
    let mut resp = req.send().await.unwrap();
    assert_eq!(resp.status().as_u16(), 200);
    assert!(
        resp.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/event-stream"),
        "{:?}",
        resp.headers()
    );
    let mut buf = String::new();
    let mut out = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(90);
    loop {
        while let Some(pos) = buf.find("\n\n") {
            let block: String = buf.drain(..pos + 2).collect();
            let (mut id, mut event, mut data) = (None, String::new(), String::new());
            for line in block.lines() {
                if let Some(v) = line.strip_prefix("id:") {
                    id = Some(v.trim().parse::<i64>().unwrap());
                } else if let Some(v) = line.strip_prefix("event:") {
                    event = v.trim().to_string();
                } else if let Some(v) = line.strip_prefix("data:") {
                    data.push_str(v.trim_start());
                }
            }
            if let Some(id) = id {
                out.push(SseEvent {
                    id,
                    event,
                    data: serde_json::from_str(&data).unwrap(),
                });
                if out.len() >= max {
                    return out;
                }
            }
        }
        let left = deadline.saturating_duration_since(Instant::now());
        assert!(!left.is_zero(), "SSE stream did not close; got {out:?}");
        match tokio::time::timeout(left, resp.chunk()).await {
            Ok(Ok(Some(chunk))) => buf.push_str(std::str::from_utf8(&chunk).unwrap()),
            Ok(Ok(None)) => return out,
            Ok(Err(e)) => panic!("SSE read failed: {e}"),
            Err(_) => panic!("SSE stream did not close; got {out:?}"),
        }
    }
}

/// Event ids strictly increase by one from `first`.
pub fn assert_contiguous(events: &[SseEvent], first: i64) {
    for (i, e) in events.iter().enumerate() {
        assert_eq!(e.id, first + i as i64, "gap or repeat in {events:?}");
    }
}

/// Iteration numbers of `iteration` events are 1, 2, … with no repeats.
pub fn assert_iterations_unique(events: &[SseEvent]) {
    let its: Vec<u64> = events
        .iter()
        .filter(|e| e.event == "iteration")
        .map(|e| e.data["iteration"].as_u64().unwrap())
        .collect();
    let expect: Vec<u64> = (1..=its.len() as u64).collect();
    assert_eq!(its, expect, "iteration numbers repeat or skip");
}

/// The iteration a job's second attempt resumed from: the `resumed_from_iteration` of its second `started`
/// event (panics when there is none, or it started afresh).
pub fn second_attempt_resumed_from(events: &[SseEvent]) -> u64 {
    let second_start = events
        .iter()
        .filter(|e| e.event == "started")
        .nth(1)
        .expect("second start");
    second_start.data["resumed_from_iteration"]
        .as_u64()
        .unwrap_or_else(|| panic!("the second attempt did not resume: {second_start:?}"))
}

/// The folder of the body scans, `shared/data/bodies` next to the checkout (as the examples expect).
pub fn bodies_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join("shared/data/bodies"))
        .find(|d| d.is_dir())
        .expect("shared/data/bodies next to the checkout (the examples need it too)")
}

/// The bytes of `regular_1k.obj`, a closed body surface of 1229 vertices (70 kB).
pub fn body_obj() -> Vec<u8> {
    std::fs::read(bodies_dir().join("regular_1k.obj")).unwrap()
}

/// `examples/calf_sleeve.json` (a two-panel sleeve on the calf of `regular_1k`, a few seconds and seven
/// Newton iterations in the test build) as a `simulate` spec on the uploaded body `asset_id`.
pub fn calf_sleeve_spec(asset_id: &str) -> Value {
    let mut scene: Value = serde_json::from_str(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/examples/calf_sleeve.json"
        ))
        .unwrap(),
    )
    .unwrap();
    scene["body"]["source"]["path"] = json!(asset_id);
    scene
}

/// The server's cap on asset bytes for tests that upload a body scan.
pub const BIG_ASSETS: &str = "[server]\nmax_asset_bytes = 1048576\n";

/// The magic number that starts a binary glTF file.
pub const GLB_MAGIC: &[u8] = b"glTF";
