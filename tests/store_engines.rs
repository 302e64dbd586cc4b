//! The two engines of the store, SQLite and PostgreSQL, kept in step: the same migrations (versions and
//! names), the same tables and columns after migrating, and one conformance test of the run semantics —
//! claims, leases, heartbeats, fencing, the re-queuing of expired leases, hand-back, artifacts read in
//! chunks — run against both. The PostgreSQL halves need a PostgreSQL installation
//! (tests/server_support/pg.rs).

mod server_support;

use std::collections::BTreeSet;
use std::time::Duration;

use serde_json::{Value, json};
use skintight::server::config::DatabaseConfig;
use skintight::server::model::{Artifact, CancelResult, Inserted, NewJob, Outcome};
use skintight::server::store::{Requeue, Store};
use sqlx::Row;

fn migration_names(engine: &str) -> Vec<String> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("migrations")
        .join(engine);
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".sql"))
        .collect();
    names.sort();
    names
}

#[test]
fn the_migrations_of_both_engines_have_the_same_versions_and_names() {
    let sqlite = migration_names("sqlite");
    let postgres = migration_names("postgres");
    assert!(sqlite.len() >= 3, "{sqlite:?}");
    assert_eq!(
        sqlite, postgres,
        "migrations/sqlite and migrations/postgres must hold the same migrations, one per version, in both \
         dialects"
    );
}

/// A column's type class, common to both dialects.
fn class(sql_type: &str) -> &'static str {
    match sql_type.to_ascii_lowercase().as_str() {
        "integer" | "bigint" => "integer",
        "text" => "text",
        "blob" | "bytea" => "bytes",
        "real" | "double precision" => "real",
        other => panic!("a column type not mapped between the engines: {other}"),
    }
}

/// (table, column, type class, not null) of every table of the service.
type Columns = BTreeSet<(String, String, &'static str, bool)>;

fn sqlite_config(dir: &std::path::Path) -> DatabaseConfig {
    DatabaseConfig {
        path: dir.join("engines.db"),
        url: String::new(),
    }
}

fn pg_config(url: String) -> DatabaseConfig {
    DatabaseConfig {
        path: "unused.db".into(),
        url,
    }
}

const OWN_TABLES: &[&str] = &["assets", "jobs", "job_events", "artifacts"];

async fn sqlite_columns(path: &std::path::Path) -> Columns {
    use sqlx::Connection;
    let mut conn = sqlx::SqliteConnection::connect(&format!("sqlite://{}", path.display()))
        .await
        .unwrap();
    let mut out = Columns::new();
    for table in OWN_TABLES {
        let rows = sqlx::query("SELECT name, type, \"notnull\", pk FROM pragma_table_info(?1)")
            .bind(table)
            .fetch_all(&mut conn)
            .await
            .unwrap();
        for r in rows {
            let name: String = r.get("name");
            let ty: String = r.get("type");
            // A SQLite primary key column (other than an INTEGER PRIMARY KEY) may hold NULL unless declared
            // NOT NULL; PostgreSQL's never does. Both are not null in use.
            let not_null = r.get::<i64, _>("notnull") != 0 || r.get::<i64, _>("pk") != 0;
            out.insert((table.to_string(), name, class(&ty), not_null));
        }
    }
    out
}

async fn pg_columns(url: &str) -> Columns {
    use sqlx::Connection;
    let mut conn = sqlx::PgConnection::connect(url).await.unwrap();
    let rows = sqlx::query(
        "SELECT table_name::text AS t, column_name::text AS c, data_type::text AS ty, is_nullable::text AS n \
         FROM information_schema.columns WHERE table_schema = 'public' AND table_name = ANY($1)",
    )
    .bind(OWN_TABLES)
    .fetch_all(&mut conn)
    .await
    .unwrap();
    rows.iter()
        .map(|r| {
            let ty: String = r.get("ty");
            (
                r.get::<String, _>("t"),
                r.get::<String, _>("c"),
                class(&ty),
                r.get::<String, _>("n") == "NO",
            )
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn both_engines_have_the_same_tables_and_columns_after_migrating() {
    let Some(pg) = server_support::pg::PgCluster::start() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let sqlite = sqlite_config(dir.path());
    Store::connect(&sqlite, 2).await.unwrap().close().await;
    let url = pg.database("columns").await;
    Store::connect(&pg_config(url.clone()), 2)
        .await
        .unwrap()
        .close()
        .await;
    let (s, p) = (sqlite_columns(&sqlite.path).await, pg_columns(&url).await);
    assert!(s.len() > 30, "{s:?}");
    let only_sqlite: Vec<_> = s.difference(&p).collect();
    let only_pg: Vec<_> = p.difference(&s).collect();
    assert!(
        only_sqlite.is_empty() && only_pg.is_empty(),
        "the engines' schemas diverge: only in SQLite {only_sqlite:?}, only in PostgreSQL {only_pg:?}"
    );
}

fn new_job(id: &str, key: Option<&str>) -> NewJob {
    NewJob {
        id: id.to_string(),
        tenant: "alice".into(),
        kind: "count".into(),
        spec: json!({ "iterations": 3 }).to_string(),
        idempotency_key: key.map(str::to_string),
        request_hash: format!("hash-{id}"),
    }
}

async fn events(store: &Store, id: &str) -> Vec<(i64, String, Value)> {
    store
        .events_after(id, 0, 1000)
        .await
        .unwrap()
        .into_iter()
        .map(|e| (e.seq, e.kind, serde_json::from_str(&e.data).unwrap()))
        .collect()
}

fn kinds(ev: &[(i64, String, Value)]) -> Vec<&str> {
    ev.iter().map(|(_, k, _)| k.as_str()).collect()
}

fn assert_contiguous(ev: &[(i64, String, Value)]) {
    for (i, (seq, _, _)) in ev.iter().enumerate() {
        assert_eq!(*seq, i as i64 + 1, "{ev:?}");
    }
}

/// The run semantics every engine must have.
async fn conformance(store: Store) {
    let lease = Duration::from_millis(1500);
    for id in ["job-a", "job-b"] {
        assert_eq!(
            store.insert_job(&new_job(id, None)).await.unwrap(),
            Inserted::Queued
        );
    }
    assert_eq!(
        store
            .insert_job(&new_job("job-k", Some("key-1")))
            .await
            .unwrap(),
        Inserted::Queued
    );
    assert_eq!(
        store
            .insert_job(&new_job("job-k2", Some("key-1")))
            .await
            .unwrap(),
        Inserted::KeyTaken
    );
    assert!(store.get_job("alice", "job-k2").await.unwrap().is_none());
    // The key's job is cancelled while queued, so the claims below see A and B only.
    assert_eq!(
        store.cancel("alice", "job-k").await.unwrap(),
        CancelResult::Cancelled
    );

    // Claims take the oldest queued job, each once.
    let a = store.claim("n1/0/l1", lease).await.unwrap().unwrap();
    assert_eq!((a.id.as_str(), a.attempts), ("job-a", 1));
    let b = store.claim("n1/1/l2", lease).await.unwrap().unwrap();
    assert_eq!(b.id, "job-b");
    assert!(store.claim("n2/0/l3", lease).await.unwrap().is_none());

    // Writes under the lease pass; under any other lease id they change nothing. An iteration and its
    // checkpoint are written together (one transaction), or neither.
    assert_eq!(
        store
            .record_iteration("job-a", "n1/0/l1", 1, Some(0.3), &json!({ "v": 1 }), None)
            .await
            .unwrap(),
        Some(false)
    );
    assert!(
        store
            .save_checkpoint("job-a", "n1/0/l1", 1, b"one")
            .await
            .unwrap()
    );
    assert_eq!(
        store
            .record_iteration(
                "job-a",
                "n1/0/l1",
                2,
                None,
                &json!({ "v": 2 }),
                Some(&b"two"[..])
            )
            .await
            .unwrap(),
        Some(false)
    );
    assert_eq!(
        store
            .record_iteration(
                "job-a",
                "n1/0/other",
                3,
                None,
                &json!({}),
                Some(&b"three"[..])
            )
            .await
            .unwrap(),
        None
    );
    assert!(
        !store
            .save_checkpoint("job-a", "n1/1/l2", 3, b"three")
            .await
            .unwrap()
    );
    let held = store
        .running_job("job-a", "n1/0/l1")
        .await
        .unwrap()
        .unwrap();
    let cp = held.checkpoint.expect("the checkpoint of iteration 2");
    assert_eq!((cp.iteration, cp.data.as_slice()), (2, &b"two"[..]));
    let iterations: Vec<u64> = events(&store, "job-a")
        .await
        .iter()
        .filter(|e| e.1 == "iteration")
        .map(|e| e.2["iteration"].as_u64().unwrap())
        .collect();
    assert_eq!(iterations, [1, 2], "no event of the refused iteration 3");
    assert!(
        store
            .running_job("job-a", "n1/1/l2")
            .await
            .unwrap()
            .is_none()
    );

    // A cancel of a running job reaches its worker through the heartbeat.
    assert_eq!(
        store.cancel("alice", "job-b").await.unwrap(),
        CancelResult::Requested
    );
    assert_eq!(
        store.renew_lease("job-b", "n1/1/l2", lease).await.unwrap(),
        Some(true)
    );
    assert_eq!(
        store.renew_lease("job-a", "n1/0/l1", lease).await.unwrap(),
        Some(false)
    );
    assert_eq!(
        store.requeue_runs(3, Requeue::LeaseExpired).await.unwrap(),
        0,
        "no lease has expired yet"
    );

    // Once the leases expire their holders may write nothing, and any node takes the runs back.
    tokio::time::sleep(lease + Duration::from_millis(300)).await;
    assert_eq!(
        store.renew_lease("job-a", "n1/0/l1", lease).await.unwrap(),
        None
    );
    assert_eq!(
        store
            .record_iteration("job-a", "n1/0/l1", 3, None, &json!({}), Some(&b"three"[..]))
            .await
            .unwrap(),
        None
    );
    assert!(
        !store
            .finish("job-a", "n1/0/l1", Outcome::Cancelled)
            .await
            .unwrap()
    );
    assert_eq!(
        store.requeue_runs(3, Requeue::LeaseExpired).await.unwrap(),
        2
    );
    assert_eq!(
        store.job_status("job-b").await.unwrap().as_deref(),
        Some("cancelled")
    );

    // Another worker resumes A from its checkpoint.
    let again = store.claim("n2/0/l4", lease).await.unwrap().unwrap();
    assert_eq!(again.id, "job-a");
    assert_eq!(again.attempts, 2);
    let cp = again.checkpoint.expect("the checkpoint of iteration 2");
    assert_eq!((cp.iteration, cp.data.as_slice()), (2, b"two".as_slice()));
    assert_eq!(again.iterations, 2);

    // It completes with an artifact larger than one download chunk, read back chunk by chunk.
    let big: Vec<u8> = (0..(2 * skintight::server::store::CHUNK_BYTES + 12345))
        .map(|i| (i * 7 % 251) as u8)
        .collect();
    let done = store
        .finish(
            "job-a",
            "n2/0/l4",
            Outcome::Completed {
                artifacts: vec![Artifact {
                    name: "big.bin".into(),
                    content_type: "application/octet-stream".into(),
                    data: big.clone(),
                }],
                summary: json!({ "ok": true }),
                warnings: vec![json!({ "message": "a warning" })],
            },
        )
        .await
        .unwrap();
    assert!(done);
    let meta = store
        .artifact_meta("job-a", "big.bin")
        .await
        .unwrap()
        .unwrap();
    assert_eq!(meta.bytes, big.len() as i64);
    let mut read = Vec::new();
    loop {
        let chunk = store
            .artifact_chunk(
                "job-a",
                "big.bin",
                read.len() as i64,
                skintight::server::store::CHUNK_BYTES,
            )
            .await
            .unwrap();
        if chunk.is_empty() {
            break;
        }
        read.extend(chunk);
    }
    assert!(read == big, "the chunks reassemble the artifact");
    assert!(
        store
            .artifact_meta("job-a", "nope")
            .await
            .unwrap()
            .is_none()
    );
    let listed = store.list_artifacts("job-a").await.unwrap();
    assert_eq!(listed.len(), 1);
    assert_eq!(listed[0].sha256, meta.sha256);

    let ev = events(&store, "job-a").await;
    assert_contiguous(&ev);
    assert_eq!(
        kinds(&ev),
        [
            "queued",
            "started",
            "iteration",
            "iteration",
            "queued",
            "started",
            "warning",
            "completed"
        ]
    );
    assert_eq!(ev[4].2["reason"], Requeue::LeaseExpired.reason());
    assert_eq!(ev[4].2["resume_from_iteration"], 2);
    assert_eq!(ev[5].2["resumed_from_iteration"], 2);
    let row = store.get_job("alice", "job-a").await.unwrap().unwrap();
    assert_eq!((row.status.as_str(), row.attempts), ("completed", 2));
    assert!(
        row.queued_ms.unwrap() >= 0 && row.run_ms.unwrap() >= 0,
        "{row:?}"
    );
    assert!(
        row.created_at.ends_with('Z') && row.created_at.len() == 24,
        "{}",
        row.created_at
    );
    let ev = events(&store, "job-b").await;
    assert_contiguous(&ev);
    assert_eq!(kinds(&ev), ["queued", "started", "cancelled"]);

    // A worker node shutting down hands its runs back at once, without counting a crash.
    store.insert_job(&new_job("job-c", None)).await.unwrap();
    store.claim("n3/0/l5", lease).await.unwrap().unwrap();
    assert_eq!(store.hand_back("n9/").await.unwrap(), 0);
    assert_eq!(store.hand_back("n3/").await.unwrap(), 1);
    let ev = events(&store, "job-c").await;
    assert_eq!(kinds(&ev), ["queued", "started", "queued"]);
    assert!(
        ev[2].2["reason"]
            .as_str()
            .unwrap()
            .contains("shutting down")
    );

    // A job whose runs keep dying fails once it reaches max_attempts.
    store.claim("n3/0/l6", lease).await.unwrap().unwrap();
    assert_eq!(store.requeue_runs(1, Requeue::Restart).await.unwrap(), 1);
    let row = store.get_job("alice", "job-c").await.unwrap().unwrap();
    assert_eq!(row.status, "failed");
    assert_eq!(row.error_code.as_deref(), Some("crashed_repeatedly"));
    assert!(
        row.error_message
            .as_deref()
            .unwrap()
            .contains("jobs.max_attempts = 1"),
        "{row:?}"
    );
    let counts = store.status_counts().await.unwrap();
    let count = |s: &str| counts.iter().find(|(k, _)| k == s).map_or(0, |(_, n)| *n);
    assert_eq!(
        (count("completed"), count("cancelled"), count("failed")),
        (1, 2, 1)
    );
    assert_eq!(
        store
            .list_jobs("alice", i64::MAX, Some("cancelled"), 10)
            .await
            .unwrap()
            .len(),
        2
    );
    store.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sqlite_runs_jobs_under_leases() {
    let dir = tempfile::tempdir().unwrap();
    let store = Store::connect(&sqlite_config(dir.path()), 4).await.unwrap();
    assert_eq!(store.engine(), "sqlite");
    conformance(store).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_runs_jobs_under_leases() {
    let Some(pg) = server_support::pg::PgCluster::start() else {
        return;
    };
    let url = pg.database("conformance").await;
    let store = Store::connect(&pg_config(url), 4).await.unwrap();
    assert_eq!(store.engine(), "postgres");
    conformance(store).await;
}

/// Concurrent claims on PostgreSQL never hand one job to two workers, nor skip one.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_concurrent_claims_take_each_job_once() {
    let Some(pg) = server_support::pg::PgCluster::start() else {
        return;
    };
    let url = pg.database("claims").await;
    let store = Store::connect(&pg_config(url), 16).await.unwrap();
    let n = 120;
    for i in 0..n {
        store
            .insert_job(&new_job(&format!("job-{i:03}"), None))
            .await
            .unwrap();
    }
    let mut tasks = Vec::new();
    for w in 0..8 {
        let store = store.clone();
        tasks.push(tokio::spawn(async move {
            let mut got = Vec::new();
            while let Some(job) = store
                .claim(&format!("n/{w}/{}", got.len()), Duration::from_secs(30))
                .await
                .unwrap()
            {
                got.push(job.id);
            }
            got
        }));
    }
    let mut all = Vec::new();
    for t in tasks {
        all.extend(t.await.unwrap());
    }
    all.sort();
    let expect: Vec<String> = (0..n).map(|i| format!("job-{i:03}")).collect();
    assert_eq!(all, expect, "every job claimed exactly once");
    store.close().await;
}
