//! Integration tests of the HTTP service: a real server on 127.0.0.1:0 with a temporary SQLite file, talked
//! to over HTTP.

mod server_support;

use std::collections::HashSet;
use std::time::Duration;

use serde_json::{Value, json};
use server_support::*;

const CUBE_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn upload_submit_follow_and_download() {
    let mut t = TestServer::start("").await;
    // Upload, content-addressed: the same bytes again are the same asset.
    let (s, asset) = t
        .post_raw(ALICE, "/v1/assets", CUBE_OBJ.into(), "model/obj", None)
        .await;
    assert_eq!(s, 201, "{asset}");
    assert_eq!(asset["format"], "obj");
    assert_eq!(asset["bytes"], CUBE_OBJ.len());
    assert_eq!(asset["sha256"].as_str().unwrap().len(), 64);
    let (s, again) = t
        .post_raw(
            ALICE,
            "/v1/assets?filename=body.OBJ",
            CUBE_OBJ.into(),
            "application/octet-stream",
            None,
        )
        .await;
    assert_eq!(s, 200, "{again}");
    assert_eq!(again["id"], asset["id"]);
    let (s, shown) = t
        .get(
            ALICE,
            &format!("/v1/assets/{}", asset["id"].as_str().unwrap()),
        )
        .await;
    assert_eq!((s, &shown["sha256"]), (200, &asset["sha256"]));

    let id = t
        .submit(
            ALICE,
            json!({ "iterations": 5, "sleep_ms": 5, "mesh": asset["id"] }),
        )
        .await;
    let events = t.events(ALICE, &id, None, 1000).await;
    assert_contiguous(&events, 1);
    let kinds: Vec<&str> = events.iter().map(|e| e.event.as_str()).collect();
    assert_eq!(
        kinds,
        [
            "queued",
            "started",
            "iteration",
            "iteration",
            "iteration",
            "iteration",
            "iteration",
            "completed"
        ]
    );
    assert_iterations_unique(&events);
    assert_eq!(events[6].data["metrics"]["value"], count_value(5));
    assert_eq!(events[7].data["summary"]["mesh_bytes"], CUBE_OBJ.len());

    let job = t.wait_finished(ALICE, &id).await;
    assert_eq!(job["status"], "completed");
    assert_eq!(job["progress"]["iterations"], 5);
    assert_eq!(job["progress"]["fraction"], 1.0);
    assert_eq!(job["metrics"]["value"], count_value(5));
    assert!(job["timings"]["run_ms"].as_i64().unwrap() >= 20, "{job}");
    assert!(job["error"].is_null());

    let (s, list) = t.get(ALICE, &format!("/v1/jobs/{id}/artifacts")).await;
    assert_eq!(s, 200);
    let names: Vec<&str> = list["artifacts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["summary.json", "value.txt"]);
    let r = t
        .client
        .get(t.url(&format!("/v1/jobs/{id}/artifacts/value.txt")))
        .bearer_auth(ALICE)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 200);
    assert_eq!(r.headers()["content-type"], "text/plain");
    assert!(r.headers().contains_key("x-request-id"));
    assert_eq!(r.text().await.unwrap(), count_value(5).to_string());
    let (s, e) = t
        .get(ALICE, &format!("/v1/jobs/{id}/artifacts/nope.bin"))
        .await;
    assert_eq!((s, e["error"]["code"].as_str()), (404, Some("not_found")));

    // Metrics for the operator only.
    let r = t
        .client
        .get(t.url("/metrics"))
        .bearer_auth(OPERATOR)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 200);
    let text = r.text().await.unwrap();
    for needle in [
        "skintight_queue_depth 0",
        "skintight_jobs_running 0",
        "skintight_job_duration_seconds_count{kind=\"count\",outcome=\"completed\"} 1",
        "skintight_http_request_duration_seconds_bucket{method=\"POST\",route=\"/v1/jobs\",status=\"201\",le=\"+Inf\"} 1",
    ] {
        assert!(text.contains(needle), "{needle} missing from\n{text}");
    }
    let (s, e) = t.get(ALICE, "/metrics").await;
    assert_eq!((s, e["error"]["code"].as_str()), (403, Some("forbidden")));
    t.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn last_event_id_resumes_without_gaps() {
    let mut t = TestServer::start("").await;
    let id = t
        .submit(ALICE, json!({ "iterations": 12, "sleep_ms": 15 }))
        .await;
    // Read a few events of the running job, drop the connection, resume from the last id seen.
    let first = t.events(ALICE, &id, None, 4).await;
    assert_eq!(first.len(), 4);
    let rest = t.events(ALICE, &id, Some(first[3].id), 1000).await;
    let mut joined = first.clone();
    joined.extend(rest);
    assert_contiguous(&joined, 1);
    assert_eq!(joined.last().unwrap().event, "completed");
    assert_iterations_unique(&joined);
    // A finished job replays its whole history and closes; resuming mid-way replays the tail exactly.
    let replay = t.events(ALICE, &id, None, 1000).await;
    assert_eq!(replay, joined);
    let tail = t.events(ALICE, &id, Some(7), 1000).await;
    assert_eq!(tail, joined[7..].to_vec());
    // Resuming after the final event closes at once.
    assert!(
        t.events(ALICE, &id, Some(joined.last().unwrap().id), 1000)
            .await
            .is_empty()
    );
    t.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancel_running_queued_and_finished_jobs() {
    let mut t = TestServer::start("[jobs]\nworkers = 1\n").await;
    let running = t
        .submit(ALICE, json!({ "iterations": 2000, "sleep_ms": 10 }))
        .await;
    let queued = t.submit(ALICE, json!({ "iterations": 3 })).await;
    // Wait until the first job iterates.
    let seen = t.events(ALICE, &running, None, 4).await;
    assert_eq!(seen[3].event, "iteration");
    // The second waits behind it (one worker) and is cancelled at once.
    let (s, job) = t
        .post_json(ALICE, &format!("/v1/jobs/{queued}/cancel"), &json!({}))
        .await;
    assert_eq!(
        (s, job["status"].as_str()),
        (200, Some("cancelled")),
        "{job}"
    );
    let ev = t.events(ALICE, &queued, None, 100).await;
    assert_eq!(
        ev.iter().map(|e| e.event.as_str()).collect::<Vec<_>>(),
        ["queued", "cancelled"]
    );
    // The running one stops within an iteration.
    let (s, job) = t
        .post_json(ALICE, &format!("/v1/jobs/{running}/cancel"), &json!({}))
        .await;
    assert_eq!(s, 202, "{job}");
    assert_eq!(job["cancel_requested"], true);
    let job = t.wait_finished(ALICE, &running).await;
    assert_eq!(job["status"], "cancelled");
    assert_eq!(job["error"]["code"], "cancelled");
    assert!(
        job["progress"]["iterations"].as_u64().unwrap() < 200,
        "{job}"
    );
    let ev = t.events(ALICE, &running, None, 10_000).await;
    assert_eq!(ev.last().unwrap().event, "cancelled");
    assert_contiguous(&ev, 1);
    // A finished job cannot be cancelled.
    let (s, e) = t
        .post_json(ALICE, &format!("/v1/jobs/{running}/cancel"), &json!({}))
        .await;
    assert_eq!(
        (s, e["error"]["code"].as_str()),
        (409, Some("already_finished"))
    );
    // Failures are events too.
    let failing = t
        .submit(ALICE, json!({ "iterations": 5, "fail_at": 3 }))
        .await;
    let job = t.wait_finished(ALICE, &failing).await;
    assert_eq!(job["status"], "failed");
    assert_eq!(job["error"]["code"], "job_failed");
    let ev = t.events(ALICE, &failing, None, 100).await;
    assert_eq!(ev.last().unwrap().event, "failed");
    assert_eq!(
        ev.last().unwrap().data["error"]["message"],
        "asked to fail at 3"
    );
    t.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn time_limit_fails_the_job() {
    let mut t = TestServer::start("[jobs]\ntime_limit_s = 1\n").await;
    let id = t
        .submit(ALICE, json!({ "iterations": 1000, "sleep_ms": 20 }))
        .await;
    let job = t.wait_finished(ALICE, &id).await;
    assert_eq!(job["status"], "failed");
    assert_eq!(job["error"]["code"], "time_limit_exceeded");
    let n = job["progress"]["iterations"].as_u64().unwrap();
    assert!((10..200).contains(&n), "{job}");
    t.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tenants_are_isolated() {
    let mut t = TestServer::start("").await;
    let (_, asset) = t
        .post_raw(ALICE, "/v1/assets", CUBE_OBJ.into(), "model/obj", None)
        .await;
    let aid = asset["id"].as_str().unwrap();
    let id = t
        .submit(ALICE, json!({ "iterations": 2, "mesh": aid }))
        .await;
    t.wait_finished(ALICE, &id).await;
    for path in [
        format!("/v1/jobs/{id}"),
        format!("/v1/jobs/{id}/artifacts"),
        format!("/v1/jobs/{id}/artifacts/value.txt"),
        format!("/v1/jobs/{id}/events"),
        format!("/v1/assets/{aid}"),
    ] {
        let (s, e) = t.get(BOB, &path).await;
        assert_eq!(
            (s, e["error"]["code"].as_str()),
            (404, Some("not_found")),
            "{path}"
        );
    }
    let (s, _) = t
        .post_json(BOB, &format!("/v1/jobs/{id}/cancel"), &json!({}))
        .await;
    assert_eq!(s, 404);
    let (s, list) = t.get(BOB, "/v1/jobs").await;
    assert_eq!((s, list["jobs"].as_array().unwrap().len()), (200, 0));
    // Bob cannot use Alice's asset; uploading the same bytes makes his own.
    let (s, e) = t
        .post_json(
            BOB,
            "/v1/jobs",
            &json!({ "kind": "count", "spec": { "iterations": 1, "mesh": aid } }),
        )
        .await;
    assert_eq!(
        (s, e["error"]["code"].as_str(), e["error"]["field"].as_str()),
        (422, Some("unknown_asset"), Some("spec.mesh"))
    );
    let (s, bobs) = t
        .post_raw(BOB, "/v1/assets", CUBE_OBJ.into(), "model/obj", None)
        .await;
    assert_eq!(s, 201);
    assert_ne!(bobs["id"], asset["id"]);
    assert_eq!(bobs["sha256"], asset["sha256"]);
    // No key, a wrong key, a wrong scheme.
    let r = t.client.get(t.url("/v1/jobs")).send().await.unwrap();
    assert_eq!(r.status().as_u16(), 401);
    assert_eq!(r.headers()["www-authenticate"], "Bearer");
    let (s, e) = t.get("not-a-key-at-all", "/v1/jobs").await;
    assert_eq!(
        (s, e["error"]["code"].as_str()),
        (401, Some("unauthorized"))
    );
    let r = t
        .client
        .get(t.url("/v1/jobs"))
        .header("authorization", format!("Basic {ALICE}"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 401);
    // Health and the API description need no key.
    assert_eq!(
        t.client
            .get(t.url("/healthz"))
            .send()
            .await
            .unwrap()
            .status()
            .as_u16(),
        200
    );
    assert_eq!(
        t.client
            .get(t.url("/readyz"))
            .send()
            .await
            .unwrap()
            .status()
            .as_u16(),
        200
    );
    t.shutdown().await;
}

/// Asserts an error envelope with status, code and field.
fn assert_error(got: (u16, Value), status: u16, code: &str, field: Option<&str>) {
    let (s, body) = got;
    assert_eq!(s, status, "{body}");
    assert_eq!(body["error"]["code"], code, "{body}");
    assert_eq!(body["error"]["field"].as_str(), field, "{body}");
    assert!(!body["error"]["message"].as_str().unwrap().is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_inputs_get_4xx_naming_the_field() {
    let mut t = TestServer::start("[jobs]\nmax_spec_bytes = 200\n").await;
    let post = |body: &str| {
        t.post_raw(
            ALICE,
            "/v1/jobs",
            body.as_bytes().to_vec(),
            "application/json",
            None,
        )
    };
    assert_error(
        post(r#"{"kind": "count", "spec": {"#).await,
        400,
        "malformed_json",
        None,
    );
    assert_error(
        post(r#"{"kind": "count", "spec": {"iterations": 2}, "color": 1}"#).await,
        422,
        "invalid_field",
        Some("color"),
    );
    assert_error(
        post(r#"{"spec": {"iterations": 2}}"#).await,
        422,
        "invalid_field",
        Some("kind"),
    );
    assert_error(
        post(r#"{"kind": 7, "spec": {}}"#).await,
        422,
        "invalid_field",
        Some("kind"),
    );
    assert_error(
        post(r#"{"kind": "paint", "spec": {}}"#).await,
        422,
        "invalid_field",
        Some("kind"),
    );
    assert_error(
        post(r#"{"kind": "count", "spec": {"iterations": "two"}}"#).await,
        422,
        "invalid_field",
        Some("spec.iterations"),
    );
    assert_error(
        post(r#"{"kind": "count", "spec": {"iterations": 2, "bogus": 1}}"#).await,
        422,
        "invalid_field",
        Some("spec.bogus"),
    );
    assert_error(
        post(r#"{"kind": "count", "spec": {"iterations": 0}}"#).await,
        422,
        "invalid_field",
        Some("spec.iterations"),
    );
    assert_error(
        post(r#"{"kind": "count", "spec": {"iterations": 2, "mesh": "0000"}}"#).await,
        422,
        "unknown_asset",
        Some("spec.mesh"),
    );
    let big = json!({ "kind": "count", "spec": { "iterations": 1, "mesh": "x".repeat(300) } })
        .to_string();
    assert_error(post(&big).await, 413, "too_large", Some("spec"));
    // Nothing above was queued.
    let (_, list) = t.get(ALICE, "/v1/jobs").await;
    assert!(list["jobs"].as_array().unwrap().is_empty());

    // Unknown ids, unknown routes, wrong methods.
    assert_error(
        t.get(ALICE, "/v1/jobs/00000000-0000-0000-0000-000000000000")
            .await,
        404,
        "not_found",
        None,
    );
    assert_error(t.get(ALICE, "/v1/nothing").await, 404, "not_found", None);
    let r = t
        .client
        .delete(t.url("/v1/jobs"))
        .bearer_auth(ALICE)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 405);
    // Query parameters.
    assert_error(
        t.get(ALICE, "/v1/jobs?status=done").await,
        422,
        "invalid_field",
        Some("status"),
    );
    assert_error(
        t.get(ALICE, "/v1/jobs?limit=many").await,
        422,
        "invalid_field",
        Some("limit"),
    );
    assert_error(
        t.get(ALICE, "/v1/jobs?limit=0").await,
        422,
        "invalid_field",
        Some("limit"),
    );
    assert_error(
        t.get(ALICE, "/v1/jobs?cursor=abc").await,
        422,
        "invalid_field",
        Some("cursor"),
    );
    assert_error(
        t.get(ALICE, "/v1/jobs?sort=asc").await,
        422,
        "invalid_field",
        Some("sort"),
    );
    // Assets: too large (server.max_asset_bytes = 4096), empty, unknown format.
    assert_error(
        t.post_raw(ALICE, "/v1/assets", vec![b'v'; 5000], "model/obj", None)
            .await,
        413,
        "too_large",
        Some("body"),
    );
    assert_error(
        t.post_raw(ALICE, "/v1/assets", vec![], "model/obj", None)
            .await,
        422,
        "invalid_field",
        Some("body"),
    );
    assert_error(
        t.post_raw(ALICE, "/v1/assets", b"x".to_vec(), "image/png", None)
            .await,
        422,
        "invalid_field",
        Some("Content-Type"),
    );
    assert_error(
        t.post_raw(
            ALICE,
            "/v1/assets?filename=body.docx",
            b"x".to_vec(),
            "model/obj",
            None,
        )
        .await,
        422,
        "invalid_field",
        Some("filename"),
    );
    assert_error(
        t.post_raw(
            ALICE,
            "/v1/assets?format=fbx",
            b"x".to_vec(),
            "model/obj",
            None,
        )
        .await,
        422,
        "invalid_field",
        Some("format"),
    );
    // Idempotency: same key and body → the same job; same key, other body → 409.
    let body = json!({ "kind": "count", "spec": { "iterations": 1, "sleep_ms": 0 } }).to_string();
    let reordered =
        json!({ "spec": { "sleep_ms": 0, "iterations": 1 }, "kind": "count" }).to_string();
    let (s1, j1) = t
        .post_raw(
            ALICE,
            "/v1/jobs",
            body.clone().into(),
            "application/json",
            Some("k-1"),
        )
        .await;
    let (s2, j2) = t
        .post_raw(
            ALICE,
            "/v1/jobs",
            reordered.into(),
            "application/json",
            Some("k-1"),
        )
        .await;
    assert_eq!((s1, s2), (201, 200));
    assert_eq!(j1["id"], j2["id"]);
    let other = json!({ "kind": "count", "spec": { "iterations": 2 } }).to_string();
    assert_error(
        t.post_raw(
            ALICE,
            "/v1/jobs",
            other.into(),
            "application/json",
            Some("k-1"),
        )
        .await,
        409,
        "idempotency_key_reused",
        Some("Idempotency-Key"),
    );
    // The same key is independent per tenant.
    let (s3, j3) = t
        .post_raw(
            BOB,
            "/v1/jobs",
            body.into(),
            "application/json",
            Some("k-1"),
        )
        .await;
    assert_eq!(s3, 201);
    assert_ne!(j3["id"], j1["id"]);
    // A bad Last-Event-ID.
    let id = j1["id"].as_str().unwrap();
    let r = t
        .client
        .get(t.url(&format!("/v1/jobs/{id}/events")))
        .bearer_auth(ALICE)
        .header("last-event-id", "yesterday")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 422);
    let e: Value = r.json().await.unwrap();
    assert_eq!(e["error"]["field"], "Last-Event-ID");
    t.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fifty_concurrent_submissions_none_lost() {
    let mut t = TestServer::start("[jobs]\nworkers = 4\n").await;
    let mut tasks = Vec::new();
    for i in 0..50u64 {
        let client = t.client.clone();
        let url = t.url("/v1/jobs");
        tasks.push(tokio::spawn(async move {
            let r = client
                .post(url)
                .bearer_auth(ALICE)
                .json(&json!({ "kind": "count", "spec": { "iterations": 1 + i % 4 } }))
                .send()
                .await
                .unwrap();
            assert_eq!(r.status().as_u16(), 201);
            let job: Value = r.json().await.unwrap();
            (job["id"].as_str().unwrap().to_string(), 1 + i % 4)
        }));
    }
    let mut submitted = Vec::new();
    for task in tasks {
        submitted.push(task.await.unwrap());
    }
    let ids: HashSet<_> = submitted.iter().map(|(id, _)| id.clone()).collect();
    assert_eq!(ids.len(), 50);
    for (id, n) in &submitted {
        let job = t.wait_finished(ALICE, id).await;
        assert_eq!(job["status"], "completed", "{job}");
        assert_eq!(job["summary"]["value"], count_value(*n));
        assert_eq!(job["attempts"], 1);
    }
    // Paginate newest first, 7 at a time: every job exactly once, in decreasing creation order.
    let mut seen = Vec::new();
    let mut cursor: Option<String> = None;
    loop {
        let path = match &cursor {
            Some(c) => format!("/v1/jobs?limit=7&status=completed&cursor={c}"),
            None => "/v1/jobs?limit=7&status=completed".to_string(),
        };
        let (s, page) = t.get(ALICE, &path).await;
        assert_eq!(s, 200, "{page}");
        let jobs = page["jobs"].as_array().unwrap();
        assert!(jobs.len() <= 7);
        seen.extend(jobs.iter().map(|j| {
            (
                j["id"].as_str().unwrap().to_string(),
                j["timings"]["created_at"].clone(),
            )
        }));
        match page["next_cursor"].as_str() {
            Some(c) => cursor = Some(c.to_string()),
            None => break,
        }
    }
    assert_eq!(seen.len(), 50);
    assert_eq!(
        seen.iter()
            .map(|(id, _)| id.clone())
            .collect::<HashSet<_>>(),
        ids
    );
    let created: Vec<String> = seen
        .iter()
        .map(|(_, c)| c.as_str().unwrap().to_string())
        .collect();
    assert!(
        created.windows(2).all(|w| w[0] >= w[1]),
        "not newest first: {created:?}"
    );
    let (_, none) = t.get(ALICE, "/v1/jobs?status=queued").await;
    assert!(none["jobs"].as_array().unwrap().is_empty());
    t.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn graceful_shutdown_requeues_and_resumes_from_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("restart.db");
    let dir2 = tempfile::tempdir().unwrap();
    let mut t = TestServer::start_in(dir2, &db, "").await;
    let id = t
        .submit(ALICE, json!({ "iterations": 30, "sleep_ms": 20 }))
        .await;
    let first = t.events(ALICE, &id, None, 6).await;
    assert_eq!(first[5].event, "iteration");
    t.shutdown().await;
    // The job went back to the queue with its checkpoint.
    let t2 = TestServer::start_in(tempfile::tempdir().unwrap(), &db, "").await;
    let job = t2.wait_finished(ALICE, &id).await;
    assert_eq!(job["status"], "completed", "{job}");
    assert_eq!(job["summary"]["value"], count_value(30));
    assert_eq!(job["attempts"], 2);
    let ev = t2.events(ALICE, &id, None, 10_000).await;
    assert_contiguous(&ev, 1);
    assert_iterations_unique(&ev);
    let requeued = ev
        .iter()
        .find(|e| e.event == "queued" && e.data["reason"].is_string())
        .expect("re-queue event");
    assert!(
        requeued.data["reason"]
            .as_str()
            .unwrap()
            .contains("shutdown")
    );
    let second_start = ev
        .iter()
        .filter(|e| e.event == "started")
        .nth(1)
        .expect("second start");
    assert!(
        second_start.data["resumed_from_iteration"]
            .as_u64()
            .unwrap()
            >= 4,
        "{second_start:?}"
    );
    let mut t2 = t2;
    t2.shutdown().await;
    drop(dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn openapi_paths_are_routed_and_responses_carry_required_fields() {
    let mut t = TestServer::start("").await;
    let (_, asset) = t
        .post_raw(ALICE, "/v1/assets", CUBE_OBJ.into(), "model/obj", None)
        .await;
    let id = t.submit(ALICE, json!({ "iterations": 2 })).await;
    let job = t.wait_finished(ALICE, &id).await;
    let doc: Value =
        serde_norway::from_str(skintight::server::OPENAPI_YAML).expect("openapi.yaml parses");
    assert!(doc["openapi"].as_str().unwrap().starts_with("3.1"));
    let paths = doc["paths"].as_object().unwrap();
    let mut checked = 0;
    for (path, item) in paths {
        for (method, _op) in item.as_object().unwrap() {
            if !["get", "post"].contains(&method.as_str()) {
                continue;
            }
            let concrete = path
                .replace(
                    "{id}",
                    if path.starts_with("/v1/assets") {
                        asset["id"].as_str().unwrap()
                    } else {
                        &id
                    },
                )
                .replace("{name}", "value.txt");
            let url = t.url(&concrete);
            let req = match method.as_str() {
                "get" => t.client.get(&url),
                _ => t
                    .client
                    .post(&url)
                    .header("content-type", "application/json")
                    .body("{}"),
            };
            let key = if path == "/metrics" { OPERATOR } else { ALICE };
            let r = req.bearer_auth(key).send().await.unwrap();
            let s = r.status().as_u16();
            assert!(s != 404 && s != 405, "{method} {path} answered {s}");
            checked += 1;
        }
    }
    assert!(checked >= 12, "only {checked} operations documented");

    // Required fields of the main responses, as documented.
    let schemas = &doc["components"]["schemas"];
    let required = |name: &str| -> Vec<String> {
        schemas[name]["required"]
            .as_array()
            .unwrap_or_else(|| panic!("schema {name} lists required fields"))
            .iter()
            .map(|v| v.as_str().unwrap().to_string())
            .collect()
    };
    let check = |name: &str, v: &Value| {
        for f in required(name) {
            assert!(
                v.get(&f).is_some(),
                "{name} response lacks required {f}: {v}"
            );
        }
    };
    check("Job", &job);
    check("Asset", &asset);
    let (_, list) = t.get(ALICE, "/v1/jobs").await;
    check("JobList", &list);
    let (_, arts) = t.get(ALICE, &format!("/v1/jobs/{id}/artifacts")).await;
    check("ArtifactList", &arts);
    check("Artifact", &arts["artifacts"][0]);
    let (_, err) = t.get(ALICE, "/v1/jobs/nope").await;
    check("Error", &err);
    check("ErrorBody", &err["error"]);
    check("Progress", &job["progress"]);
    check("Timings", &job["timings"]);
    t.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sse_stream_follows_a_job_that_is_still_queued() {
    // A job submitted while the only worker is busy: its stream waits, then follows it to the end.
    let mut t = TestServer::start("[jobs]\nworkers = 1\n").await;
    let blocker = t
        .submit(ALICE, json!({ "iterations": 10, "sleep_ms": 10 }))
        .await;
    let id = t.submit(ALICE, json!({ "iterations": 3 })).await;
    let ev = t.events(ALICE, &id, None, 100).await;
    assert_eq!(
        ev.iter().map(|e| e.event.as_str()).collect::<Vec<_>>(),
        [
            "queued",
            "started",
            "iteration",
            "iteration",
            "iteration",
            "completed"
        ]
    );
    assert_eq!(
        t.wait_finished(ALICE, &blocker).await["status"],
        "completed"
    );
    tokio::time::sleep(Duration::from_millis(1)).await;
    t.shutdown().await;
}

/// A small cylinder scene (no mesh asset needed): two half-tube panels, both cuffs pinned.
fn small_cylinder_scene() -> Value {
    let mut scene: Value = serde_json::from_str(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/examples/cylinder.json"
        ))
        .unwrap(),
    )
    .unwrap();
    scene["body"]["source"]["radial_segments"] = json!(12);
    scene["body"]["source"]["rings"] = json!(2);
    scene["body"]["source"]["layers"] = json!(8);
    scene["garment"]["edge_length"] = json!(0.015);
    scene
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_simulate_job_runs_to_equilibrium_and_serves_its_artifacts() {
    let t = TestServer::start("").await;
    let (s, job) = t
        .post_json(
            ALICE,
            "/v1/jobs",
            &json!({ "kind": "simulate", "spec": small_cylinder_scene() }),
        )
        .await;
    assert_eq!(s, 201, "{job}");
    let id = job["id"].as_str().unwrap().to_string();
    let events = t.events(ALICE, &id, None, 10_000).await;
    assert_contiguous(&events, 1);
    assert_eq!(events.last().unwrap().event, "completed", "{events:?}");
    assert!(
        events
            .iter()
            .any(|e| e.event == "iteration" && e.data["metrics"]["residual"].is_number())
    );
    let job = t.wait_finished(ALICE, &id).await;
    assert_eq!(job["status"], "completed", "{job}");
    let (s, list) = t.get(ALICE, &format!("/v1/jobs/{id}/artifacts")).await;
    assert_eq!(s, 200);
    let names: HashSet<String> = list
        .as_array()
        .or_else(|| list["artifacts"].as_array())
        .unwrap()
        .iter()
        .map(|a| a["name"].as_str().unwrap().to_string())
        .collect();
    for name in ["result.json", "garment.glb", "body.glb", "patterns.svg"] {
        assert!(names.contains(name), "{name} missing from {list}");
    }
    let (s, result) = t
        .get(ALICE, &format!("/v1/jobs/{id}/artifacts/result.json"))
        .await;
    assert_eq!(s, 200);
    assert_eq!(result["converged"], true, "{}", result["stop_reason"]);
    assert_eq!(result["slack_elements"], 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bad_simulate_spec_is_refused_naming_the_field() {
    let t = TestServer::start("").await;
    let mut scene = small_cylinder_scene();
    scene["garment"]["fabric"]["poisson_ratio"] = json!(0.7);
    let (s, body) = t
        .post_json(
            ALICE,
            "/v1/jobs",
            &json!({ "kind": "simulate", "spec": scene }),
        )
        .await;
    assert_eq!(s, 422, "{body}");
    assert!(
        body.to_string().contains("garment.fabric.poisson_ratio"),
        "{body}"
    );
}
