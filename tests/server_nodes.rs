//! API nodes and worker nodes apart, against one real PostgreSQL (tests/server_support/pg.rs): two `skintight serve
//! --no-workers` processes take the submissions and three `skintight worker` processes run the jobs.
//!
//! - Every job runs exactly once to completion (one `started` event, attempt 1, the deterministic result),
//!   its event log contiguous, none lost; an SSE subscriber on the API node that did not receive the
//!   submission gets every event, in order: 200 jobs, a few seconds.
//! - A worker killed with `kill -9` in the middle of a design job: once its lease expires another worker
//!   resumes the job from its checkpoint, and the final objective equals an uninterrupted run's.
//! - A worker stopped with SIGTERM hands its job back at once: another worker resumes it long before the
//!   lease could have expired.
//! - A worker started with `--ops-addr` serves `/healthz`, `/readyz` (the store, its leases while a job runs)
//!   and `/metrics` (its lease renewals and claim latency), and nothing else.
//!
//! Without PostgreSQL binaries the tests print why and pass, unless `CI=true`.

mod server_support;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use server_support::{
    ALICE, OPERATOR, SseEvent, assert_contiguous, assert_iterations_unique, read_sse,
};

/// Kills the process when dropped (also when an assertion fails).
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// The nodes' shared configuration file (the database comes from `SKINTIGHT_DATABASE_URL`).
fn write_config(dir: &std::path::Path, jobs: &str) -> std::path::PathBuf {
    let path = dir.join("node.toml");
    std::fs::write(
        &path,
        format!(
            "[jobs]\nenable_selftest = true\n{jobs}\n[auth]\noperator_keys = [\"{OPERATOR}\"]\n\
             keys = [{{ key = \"{ALICE}\", tenant = \"alice\" }}]\n"
        ),
    )
    .unwrap();
    path
}

/// Starts `skintight <args> --config <config>` on the database `url`, its output appended to `log`.
fn spawn(
    args: &[&str],
    config: &std::path::Path,
    url: &str,
    port: Option<u16>,
    log: &std::path::Path,
) -> Proc {
    let tmp = config.parent().unwrap().join("tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
        .unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_skintight"));
    cmd.args(args)
        .arg("--config")
        .arg(config)
        .env("SKINTIGHT_DATABASE_URL", url)
        .env("SKINTIGHT_LOG_FILTER", "warn")
        .env("TMPDIR", tmp)
        .env_remove("RUST_LOG")
        .stdin(Stdio::null())
        .stdout(log.try_clone().unwrap())
        .stderr(log);
    if let Some(port) = port {
        cmd.env("SKINTIGHT_BIND", format!("127.0.0.1:{port}"));
    }
    Proc(cmd.spawn().expect("the skintight binary starts"))
}

async fn wait_ready(client: &reqwest::Client, base: &str, log: &std::path::Path) -> Value {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        if let Ok(r) = client.get(format!("{base}/readyz")).send().await
            && r.status().is_success()
        {
            return r.json().await.unwrap();
        }
        assert!(
            Instant::now() < deadline,
            "node did not become ready; log:\n{}",
            std::fs::read_to_string(log).unwrap_or_default()
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

async fn submit(client: &reqwest::Client, base: &str, submission: &Value) -> String {
    let r = client
        .post(format!("{base}/v1/jobs"))
        .bearer_auth(ALICE)
        .json(submission)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 201);
    r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string()
}

async fn job(client: &reqwest::Client, base: &str, id: &str) -> Value {
    client
        .get(format!("{base}/v1/jobs/{id}"))
        .bearer_auth(ALICE)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap()
}

async fn wait_finished(client: &reqwest::Client, base: &str, id: &str, limit: Duration) -> Value {
    let deadline = Instant::now() + limit;
    loop {
        let j = job(client, base, id).await;
        if j["status"] != "queued" && j["status"] != "running" {
            return j;
        }
        assert!(Instant::now() < deadline, "job did not finish: {j}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

async fn events(
    client: &reqwest::Client,
    base: &str,
    id: &str,
    after: Option<i64>,
    max: usize,
) -> Vec<SseEvent> {
    read_sse(
        client,
        &format!("{base}/v1/jobs/{id}/events"),
        ALICE,
        after,
        max,
    )
    .await
}

/// Two API nodes, three worker processes (two workers each), `n` selftest jobs.
async fn jobs_through_two_api_nodes_and_three_workers(n: usize) {
    let Some(pg) = server_support::pg::PgCluster::start() else {
        return;
    };
    let url = pg.database("nodes").await;
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(
        dir.path(),
        "workers = 2\nisolation = \"thread\"\nlease_s = 5",
    );
    let log = dir.path().join("nodes.log");
    let client = reqwest::Client::new();
    let ports = [free_port(), free_port()];
    let bases: Vec<String> = ports
        .iter()
        .map(|p| format!("http://127.0.0.1:{p}"))
        .collect();
    let _api: Vec<Proc> = ports
        .iter()
        .map(|p| spawn(&["serve", "--no-workers"], &config, &url, Some(*p), &log))
        .collect();
    for base in &bases {
        let ready = wait_ready(&client, base, &log).await;
        assert_eq!(ready["workers"], 0, "{ready}");
        assert_eq!(ready["store"]["engine"], "postgres", "{ready}");
        assert!(ready.get("leases").is_none(), "{ready}");
    }
    let _workers: Vec<Proc> = (0..3)
        .map(|_| spawn(&["worker"], &config, &url, None, &log))
        .collect();

    let started = Instant::now();
    let iterations = 5u64;
    let mut ids = Vec::with_capacity(n);
    let mut followers = Vec::new();
    for i in 0..n {
        let (to, other) = (&bases[i % 2], &bases[(i + 1) % 2]);
        let spec = json!({ "iterations": iterations, "sleep_ms": 10, "seed": i });
        let id = submit(&client, to, &json!({ "kind": "selftest", "spec": spec })).await;
        // Subscribers on the node that did not receive the submission, from the start.
        if i < 20 {
            let (client, other, id) = (client.clone(), other.clone(), id.clone());
            followers.push(tokio::spawn(async move {
                events(&client, &other, &id, None, 10_000).await
            }));
        }
        ids.push((id, i as u64));
    }
    for (id, _) in &ids {
        let done = wait_finished(&client, &bases[1], id, Duration::from_secs(300)).await;
        assert_eq!(done["status"], "completed", "{done}");
    }
    let elapsed = started.elapsed();
    eprintln!(
        "{n} selftest jobs through 2 API nodes and 3 worker processes in {:.1} s ({:.0} jobs/min)",
        elapsed.as_secs_f64(),
        n as f64 / elapsed.as_secs_f64() * 60.0
    );

    for (i, f) in followers.into_iter().enumerate() {
        let ev = f.await.unwrap();
        assert_contiguous(&ev, 1);
        assert_iterations_unique(&ev);
        let kinds: Vec<&str> = ev.iter().map(|e| e.event.as_str()).collect();
        let mut expect = vec!["queued", "started"];
        expect.extend(std::iter::repeat_n("iteration", iterations as usize));
        expect.push("completed");
        assert_eq!(kinds, expect, "the subscriber of job {i} on the other node");
    }
    for (id, seed) in &ids {
        let j = job(&client, &bases[0], id).await;
        assert_eq!(j["attempts"], 1, "run once: {j}");
        let x = *skintight::server::selftest::trajectory(*seed, iterations)
            .last()
            .unwrap();
        assert!(
            (j["summary"]["x"].as_f64().unwrap() - x).abs() < 1e-12,
            "{j}"
        );
        let ev = events(&client, &bases[(*seed as usize) % 2], id, None, 10_000).await;
        assert_contiguous(&ev, 1);
        assert_iterations_unique(&ev);
        assert_eq!(
            ev.iter().filter(|e| e.event == "started").count(),
            1,
            "{ev:?}"
        );
        assert_eq!(ev.len(), iterations as usize + 3, "{ev:?}");
    }
    // Nothing is left over, and each node counts the same database.
    for base in &bases {
        let metrics = client
            .get(format!("{base}/metrics"))
            .bearer_auth(OPERATOR)
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        assert!(metrics.contains("skintight_queue_depth 0\n"), "{metrics}");
        assert!(metrics.contains("skintight_jobs_running 0\n"), "{metrics}");
        assert!(
            metrics.contains(&format!("skintight_jobs{{status=\"completed\"}} {n}\n")),
            "{metrics}"
        );
    }
}

/// The acceptance run (a few seconds: selftest jobs of five short iterations).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_hundred_jobs_through_two_api_nodes_and_three_workers_each_run_once() {
    jobs_through_two_api_nodes_and_three_workers(200).await;
}

/// A small Gauss-Newton design on a procedural cylinder (no assets): seven iterations of a few seconds.
/// Its solves start from the last equilibrium and are tight (`predictor` and `inexact_solves` off), so that a
/// resumed run is the uninterrupted one to the bit, which the test checks; a design with the predictor
/// resumes to the equilibrium tolerance instead (`tests/design_resume.rs`).
fn cylinder_design_spec() -> Value {
    let mut spec: Value =
        serde_json::from_str(include_str!("design_support/small_cylinder.json")).unwrap();
    spec["optimizer"] = json!({"method": "gauss_newton", "max_iterations": 7, "mode_levels": [6],
                               "level_iterations": 2, "gradient_tolerance": 1e-12,
                               "predictor": false, "inexact_solves": false});
    spec
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_killed_mid_design_job_is_resumed_by_another_from_its_checkpoint() {
    let Some(pg) = server_support::pg::PgCluster::start() else {
        return;
    };
    let url = pg.database("kill9").await;
    let dir = tempfile::tempdir().unwrap();
    // Job processes (the default isolation), one worker per node, short leases.
    let config = write_config(dir.path(), "workers = 1\nlease_s = 3");
    let log = dir.path().join("nodes.log");
    let client = reqwest::Client::new();
    let port = free_port();
    let base = format!("http://127.0.0.1:{port}");
    let _api = spawn(&["serve", "--no-workers"], &config, &url, Some(port), &log);
    wait_ready(&client, &base, &log).await;
    let first = spawn(&["worker"], &config, &url, None, &log);

    let submission = json!({ "kind": "design", "spec": cylinder_design_spec() });
    let id = submit(&client, &base, &submission).await;
    let before = events(&client, &base, &id, None, 5).await;
    assert_eq!(
        before.iter().map(|e| e.event.as_str()).collect::<Vec<_>>(),
        ["queued", "started", "iteration", "iteration", "iteration"]
    );
    // (The checkpoint of an iteration is stored just after its event.)
    tokio::time::sleep(Duration::from_millis(300)).await;
    drop(first); // SIGKILL; its job process dies with it.
    let killed_at = Instant::now();
    let _second = spawn(&["worker"], &config, &url, None, &log);

    let last_seen = before.last().unwrap().id;
    let after = events(&client, &base, &id, Some(last_seen), 10_000).await;
    assert_contiguous(&after, last_seen + 1);
    assert_eq!(after.last().unwrap().event, "completed", "{after:?}");
    let requeued = after
        .iter()
        .position(|e| e.event == "queued")
        .expect("the job was queued again");
    assert!(
        after[..requeued].iter().all(|e| e.event == "iteration"),
        "{after:?}"
    );
    assert_eq!(
        after[requeued].data["reason"],
        skintight::server::store::Requeue::LeaseExpired.reason()
    );
    let restarted = &after[requeued + 1];
    assert_eq!(restarted.event, "started");
    assert_eq!(restarted.data["attempt"], 2);
    let resumed_from = restarted.data["resumed_from_iteration"]
        .as_u64()
        .unwrap_or(0);
    let announced = before
        .iter()
        .chain(&after[..requeued])
        .filter_map(|e| e.data["iteration"].as_u64())
        .max()
        .unwrap();
    assert!(
        (3..=announced).contains(&resumed_from),
        "resumed from {resumed_from}, {announced} announced: {restarted:?}"
    );
    eprintln!(
        "completed by another worker {:.1} s after the kill (lease 3 s)",
        killed_at.elapsed().as_secs_f64()
    );
    let mut all = before;
    all.extend(after);
    assert_contiguous(&all, 1);
    assert_iterations_unique(&all);
    let done = job(&client, &base, &id).await;
    assert_eq!(done["status"], "completed", "{done}");
    assert_eq!(done["attempts"], 2, "{done}");

    // The same design run without interruption ends with the same objective, after as many iterations.
    let again = submit(&client, &base, &submission).await;
    let whole = wait_finished(&client, &base, &again, Duration::from_secs(300)).await;
    assert_eq!(whole["status"], "completed", "{whole}");
    let (resumed, uninterrupted) = (
        done["summary"]["final_objective"].as_f64().unwrap(),
        whole["summary"]["final_objective"].as_f64().unwrap(),
    );
    assert!(
        (resumed - uninterrupted).abs() <= 1e-9 * uninterrupted.abs(),
        "final objective: resumed {resumed}, uninterrupted {uninterrupted}"
    );
    assert_eq!(
        done["summary"]["iterations"],
        whole["summary"]["iterations"]
    );
    assert_eq!(
        all.iter().filter(|e| e.event == "iteration").count() as u64,
        done["summary"]["iterations"].as_u64().unwrap()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_stopped_gracefully_hands_its_job_back_at_once() {
    let Some(pg) = server_support::pg::PgCluster::start() else {
        return;
    };
    let url = pg.database("handback").await;
    let dir = tempfile::tempdir().unwrap();
    // A lease far longer than the test: the job must come back through the hand-back, not an expiry.
    let config = write_config(dir.path(), "workers = 1\nlease_s = 120");
    let log = dir.path().join("nodes.log");
    let client = reqwest::Client::new();
    let port = free_port();
    let base = format!("http://127.0.0.1:{port}");
    let _api = spawn(&["serve", "--no-workers"], &config, &url, Some(port), &log);
    wait_ready(&client, &base, &log).await;
    let first = spawn(&["worker"], &config, &url, None, &log);
    let spec = json!({ "iterations": 60, "sleep_ms": 50, "seed": 7 });
    let id = submit(&client, &base, &json!({ "kind": "selftest", "spec": spec })).await;
    let before = events(&client, &base, &id, None, 5).await;
    assert_eq!(before[4].event, "iteration", "{before:?}");
    // SIGTERM: a graceful stop.
    let stopped = Instant::now();
    // SAFETY: kill(2) on the pid of a child this test started.
    assert_eq!(unsafe { libc::kill(first.0.id() as i32, libc::SIGTERM) }, 0);
    let _second = spawn(&["worker"], &config, &url, None, &log);
    let after = events(&client, &base, &id, Some(before[4].id), 10_000).await;
    let mut all = before;
    all.extend(after);
    assert_contiguous(&all, 1);
    assert_iterations_unique(&all);
    let requeued = all
        .iter()
        .find(|e| e.event == "queued" && e.data["reason"].is_string())
        .expect("handed back");
    assert!(
        requeued.data["reason"]
            .as_str()
            .unwrap()
            .contains("shutdown"),
        "{requeued:?}"
    );
    let restarted = all.iter().filter(|e| e.event == "started").nth(1).unwrap();
    assert_eq!(restarted.data["attempt"], 2);
    assert!(restarted.data["resumed_from_iteration"].as_u64().unwrap() >= 3);
    let done = job(&client, &base, &id).await;
    assert_eq!(done["status"], "completed", "{done}");
    let x = *skintight::server::selftest::trajectory(7, 60)
        .last()
        .unwrap();
    assert!(
        (done["summary"]["x"].as_f64().unwrap() - x).abs() < 1e-12,
        "{done}"
    );
    // The other worker took it over long before the 120 s lease could have expired.
    assert!(
        stopped.elapsed() < Duration::from_secs(60),
        "{:?}",
        stopped.elapsed()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_with_an_ops_port_reports_its_store_leases_and_metrics() {
    let Some(pg) = server_support::pg::PgCluster::start() else {
        return;
    };
    let url = pg.database("opsport").await;
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "workers = 1\nlease_s = 3");
    let log = dir.path().join("nodes.log");
    let client = reqwest::Client::new();
    let port = free_port();
    let base = format!("http://127.0.0.1:{port}");
    let _api = spawn(&["serve", "--no-workers"], &config, &url, Some(port), &log);
    wait_ready(&client, &base, &log).await;
    let ops_port = free_port();
    let ops = format!("http://127.0.0.1:{ops_port}");
    let ops_addr = format!("127.0.0.1:{ops_port}");
    let _worker = spawn(
        &["worker", "--ops-addr", &ops_addr],
        &config,
        &url,
        None,
        &log,
    );
    let ready = wait_ready(&client, &ops, &log).await;
    assert_eq!(ready["store"]["engine"], "postgres", "{ready}");
    assert_eq!(ready["workers"], 1, "{ready}");
    assert_eq!(ready["leases"]["held"], 0, "{ready}");
    assert_eq!(ready["leases"]["lease_s"], 3, "{ready}");
    let healthz = client.get(format!("{ops}/healthz")).send().await.unwrap();
    assert_eq!(healthz.status().as_u16(), 200);
    // Only the ops routes: the API is the API nodes', in the JSON error envelope.
    for path in ["/v1/jobs", "/openapi.yaml"] {
        let r = client
            .get(format!("{ops}{path}"))
            .bearer_auth(ALICE)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status().as_u16(), 404, "{path}");
        let body: Value = r.json().await.unwrap();
        assert_eq!(body["error"]["code"], "not_found", "{path}: {body}");
    }
    // While a job runs on this node its lease is listed and renewed (every second with lease_s = 3).
    let spec = json!({ "iterations": 60, "sleep_ms": 50, "seed": 3 });
    let id = submit(&client, &base, &json!({ "kind": "selftest", "spec": spec })).await;
    let deadline = Instant::now() + Duration::from_secs(20);
    let ready = loop {
        let r: Value = client
            .get(format!("{ops}/readyz"))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        if r["leases"]["held"] == 1 && r["leases"]["last_renewed_s_ago"].is_number() {
            break r;
        }
        assert!(Instant::now() < deadline, "no lease renewed: {r}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert!(
        ready["leases"]["last_renewed_s_ago"].as_f64().unwrap() < 3.0,
        "{ready}"
    );
    // /metrics needs an operator key, as on the API nodes.
    let r = client
        .get(format!("{ops}/metrics"))
        .bearer_auth(ALICE)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 403);
    let r = client
        .get(format!("{ops}/metrics"))
        .bearer_auth(OPERATOR)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 200);
    let text = r.text().await.unwrap();
    let value = |name: &str| -> f64 {
        text.lines()
            .find_map(|l| l.strip_prefix(name)?.strip_prefix(' ')?.parse().ok())
            .unwrap_or_else(|| panic!("no {name} in:\n{text}"))
    };
    assert!(value("skintight_lease_renewals_total") >= 1.0, "{text}");
    assert!(
        value("skintight_claim_duration_seconds_count") >= 1.0,
        "{text}"
    );
    assert_eq!(value("skintight_workers"), 1.0, "{text}");
    assert!(text.contains("skintight_queue_depth"), "{text}");
    assert!(text.contains("skintight_jobs_running"), "{text}");
    let done = wait_finished(&client, &base, &id, Duration::from_secs(60)).await;
    assert_eq!(done["status"], "completed", "{done}");
}

#[test]
fn separate_nodes_need_postgres() {
    let dir = tempfile::tempdir().unwrap();
    for args in [&["worker"][..], &["serve", "--no-workers"][..]] {
        let out = Command::new(env!("CARGO_BIN_EXE_skintight"))
            .args(args)
            .env("SKINTIGHT_AUTH_DISABLED", "true")
            .env("SKINTIGHT_DATABASE", dir.path().join("x.db"))
            .env_remove("SKINTIGHT_DATABASE_URL")
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.starts_with("error: ")
                && err.contains("database.url")
                && err.contains("postgres://"),
            "{err}"
        );
    }
}

/// What one benchmark configuration measured.
struct Measured {
    selftest_per_min: f64,
    sleeve_per_min: f64,
    /// Median and largest time from submission to start of a job submitted to idle workers, ms.
    pickup_ms: (f64, f64),
}

/// Runs the benchmark's jobs against the API node at `base` (its workers idle): `n` selftest jobs at once,
/// then `sleeves` calf-sleeve simulate jobs at once, then 15 selftest jobs one at a time.
async fn measure(client: &reqwest::Client, base: &str, n: usize, sleeves: usize) -> Measured {
    async fn all_done(client: &reqwest::Client, base: &str, ids: &[String]) {
        for id in ids {
            let j = wait_finished(client, base, id, Duration::from_secs(900)).await;
            assert_eq!(j["status"], "completed", "{j}");
        }
    }
    let t = Instant::now();
    let mut ids = Vec::new();
    for i in 0..n {
        let spec = json!({ "iterations": 10, "seed": i });
        ids.push(submit(client, base, &json!({ "kind": "selftest", "spec": spec })).await);
    }
    all_done(client, base, &ids).await;
    let selftest_per_min = n as f64 / t.elapsed().as_secs_f64() * 60.0;

    let r = client
        .post(format!("{base}/v1/assets"))
        .bearer_auth(ALICE)
        .header("content-type", "model/obj")
        .body(server_support::body_obj())
        .send()
        .await
        .unwrap();
    assert!(r.status().is_success());
    let asset = r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let t = Instant::now();
    let mut ids = Vec::new();
    for _ in 0..sleeves {
        let spec = server_support::calf_sleeve_spec(&asset);
        ids.push(submit(client, base, &json!({ "kind": "simulate", "spec": spec })).await);
    }
    all_done(client, base, &ids).await;
    let sleeve_per_min = sleeves as f64 / t.elapsed().as_secs_f64() * 60.0;

    let mut pickup = Vec::new();
    for i in 0..15 {
        let spec = json!({ "iterations": 1, "seed": i });
        let id = submit(client, base, &json!({ "kind": "selftest", "spec": spec })).await;
        let j = wait_finished(client, base, &id, Duration::from_secs(60)).await;
        pickup.push(j["timings"]["queued_ms"].as_f64().unwrap());
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    pickup.sort_by(f64::total_cmp);
    Measured {
        selftest_per_min,
        sleeve_per_min,
        pickup_ms: (pickup[pickup.len() / 2], *pickup.last().unwrap()),
    }
}

/// docs/BENCHMARKS.md, "PostgreSQL against SQLite": jobs per minute and the pickup latency with 1, 2 and 3
/// worker processes, each engine: `cargo test --test server_nodes -- --ignored --nocapture benchmark`.
/// SQLite: one `skintight serve` with `jobs.workers` = 1, 2, 3 (each job in a job process of its own);
/// PostgreSQL: one API node and 1, 2, 3 `skintight worker` processes of one worker each.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "a benchmark of several minutes; its figures are in docs/BENCHMARKS.md"]
async fn benchmark_sqlite_against_postgres_with_one_two_three_workers() {
    let pg = server_support::pg::PgCluster::start().expect("the benchmark needs PostgreSQL");
    let client = reqwest::Client::new();
    let (n, sleeves) = (60, 6);
    let mut rows = Vec::new();
    for k in 1..=3usize {
        for engine in ["sqlite", "postgres"] {
            let dir = tempfile::tempdir().unwrap();
            let log = dir.path().join("bench.log");
            let port = free_port();
            let base = format!("http://127.0.0.1:{port}");
            let _procs: Vec<Proc> = if engine == "sqlite" {
                let config = write_config(
                    dir.path(),
                    &format!(
                        "workers = {k}\n[database]\npath = {:?}",
                        dir.path().join("bench.db")
                    ),
                );
                // (An empty SKINTIGHT_DATABASE_URL is SQLite at database.path.)
                vec![spawn(&["serve"], &config, "", Some(port), &log)]
            } else {
                let url = pg.database(&format!("bench{k}")).await;
                let config = write_config(dir.path(), "workers = 1");
                let mut procs = vec![spawn(
                    &["serve", "--no-workers"],
                    &config,
                    &url,
                    Some(port),
                    &log,
                )];
                procs.extend((0..k).map(|_| spawn(&["worker"], &config, &url, None, &log)));
                procs
            };
            wait_ready(&client, &base, &log).await;
            let m = measure(&client, &base, n, sleeves).await;
            let row = format!(
                "| {engine} | {k} | {:.0} | {:.1} | {:.0} / {:.0} |",
                m.selftest_per_min, m.sleeve_per_min, m.pickup_ms.0, m.pickup_ms.1
            );
            eprintln!("{row}");
            rows.push(row);
        }
    }
    eprintln!(
        "| engine | workers | selftest jobs/min | calf-sleeve jobs/min | pickup ms (median / max) |\n\
         | --- | --- | --- | --- | --- |\n{}",
        rows.join("\n")
    );
}
