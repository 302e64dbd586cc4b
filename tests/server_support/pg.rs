//! A throwaway PostgreSQL cluster for the tests: `initdb` in a temporary folder, `postgres` on a free
//! loopback port, torn down (`pg_ctl stop -m immediate`) when dropped.
//!
//! The binaries are looked up in `SKINTIGHT_PG_BIN` (a folder), then beside `initdb` on `PATH`, then in
//! Debian's `/usr/lib/postgresql/<version>/bin` (the newest). Without them a test prints why and skips —
//! unless `CI=true`, where it fails (`.ci/run` installs Debian's `postgresql` package). PostgreSQL refuses
//! to run as root: as root, the cluster belongs to the `postgres` user (or `nobody`) and its commands run
//! through `runuser`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// A running cluster; its superuser is `skintight`, with trust authentication on loopback.
pub struct PgCluster {
    dir: tempfile::TempDir,
    bin: PathBuf,
    run_as: Option<String>,
    pub port: u16,
}

/// The folder holding `initdb`, `pg_ctl` and `postgres`, if any.
pub fn find_bin() -> Option<PathBuf> {
    let complete = |d: &Path| {
        ["initdb", "pg_ctl", "postgres"]
            .iter()
            .all(|b| d.join(b).is_file())
    };
    if let Some(d) = std::env::var_os("SKINTIGHT_PG_BIN") {
        let d = PathBuf::from(d);
        return complete(&d).then_some(d);
    }
    if let Some(path) = std::env::var_os("PATH") {
        for d in std::env::split_paths(&path) {
            if complete(&d) {
                return Some(d);
            }
        }
    }
    let mut debian: Vec<(u32, PathBuf)> = std::fs::read_dir("/usr/lib/postgresql")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let v = e.file_name().to_string_lossy().parse::<u32>().ok()?;
            let d = e.path().join("bin");
            complete(&d).then_some((v, d))
        })
        .collect();
    debian.sort();
    debian.pop().map(|(_, d)| d)
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// The user to run PostgreSQL as when this process is root.
fn unprivileged_user() -> Option<String> {
    // SAFETY: geteuid has no preconditions.
    if unsafe { libc::geteuid() } != 0 {
        return None;
    }
    for user in ["postgres", "nobody"] {
        let found = Command::new("id")
            .arg("-u")
            .arg(user)
            .output()
            .is_ok_and(|o| o.status.success());
        if found {
            return Some(user.to_string());
        }
    }
    panic!(
        "running as root, and neither a `postgres` nor a `nobody` user exists to run PostgreSQL as"
    )
}

impl PgCluster {
    /// Starts a cluster, or `None` (having printed why) when no PostgreSQL binaries are installed and
    /// `CI` is not `true`.
    pub fn start() -> Option<PgCluster> {
        let Some(bin) = find_bin() else {
            let why = "no PostgreSQL binaries (initdb, pg_ctl, postgres) in SKINTIGHT_PG_BIN, on PATH or \
                       under /usr/lib/postgresql/*/bin; install Debian's `postgresql` package";
            if std::env::var("CI").as_deref() == Ok("true") {
                panic!("{why} (CI=true: PostgreSQL tests may not skip)");
            }
            eprintln!("skipping a PostgreSQL test: {why}");
            return None;
        };
        let run_as = unprivileged_user();
        let dir = tempfile::Builder::new()
            .prefix("skintight-pg-")
            .tempdir()
            .unwrap();
        if let Some(user) = &run_as {
            let ok = Command::new("chown")
                .arg(user)
                .arg(dir.path())
                .status()
                .unwrap()
                .success();
            assert!(ok, "cannot give {} to {user}", dir.path().display());
        }
        let mut cluster = PgCluster {
            dir,
            bin,
            run_as,
            port: 0,
        };
        let init = cluster
            .command("initdb")
            .arg("-D")
            .arg(cluster.data())
            .args([
                "-A",
                "trust",
                "-U",
                "skintight",
                "-E",
                "UTF8",
                "--no-locale",
                "--no-sync",
            ])
            .output()
            .unwrap();
        assert!(
            init.status.success(),
            "initdb failed: {}",
            String::from_utf8_lossy(&init.stderr)
        );
        // A port found free may be taken before the server binds it: try a few.
        for _ in 0..5 {
            cluster.port = free_port();
            let options = format!(
                "-p {} -k {} -c listen_addresses=127.0.0.1 -c fsync=off -c synchronous_commit=off \
                 -c full_page_writes=off -c max_connections=300",
                cluster.port,
                cluster.dir.path().display()
            );
            let started = cluster
                .command("pg_ctl")
                .arg("-D")
                .arg(cluster.data())
                .arg("-l")
                .arg(cluster.dir.path().join("postgres.log"))
                .args(["-w", "-t", "60", "-o", &options, "start"])
                .output()
                .unwrap();
            if started.status.success() {
                return Some(cluster);
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        panic!(
            "PostgreSQL did not start; its log:\n{}",
            std::fs::read_to_string(cluster.dir.path().join("postgres.log")).unwrap_or_default()
        );
    }

    fn data(&self) -> PathBuf {
        self.dir.path().join("data")
    }

    fn command(&self, program: &str) -> Command {
        let exe = self.bin.join(program);
        match &self.run_as {
            Some(user) => {
                let mut c = Command::new("runuser");
                c.args(["-u", user, "--"]).arg(exe);
                c
            }
            None => Command::new(exe),
        }
    }

    /// The URL of database `name` (created if missing).
    pub async fn database(&self, name: &str) -> String {
        use sqlx::Connection;
        let admin = format!("postgres://skintight@127.0.0.1:{}/postgres", self.port);
        let mut conn = sqlx::PgConnection::connect(&admin).await.unwrap();
        let exists: Option<i32> =
            sqlx::query_scalar("SELECT 1 FROM pg_database WHERE datname = $1")
                .bind(name)
                .fetch_optional(&mut conn)
                .await
                .unwrap();
        if exists.is_none() {
            sqlx::query(sqlx::AssertSqlSafe(format!("CREATE DATABASE \"{name}\"")))
                .execute(&mut conn)
                .await
                .unwrap();
        }
        conn.close().await.unwrap();
        format!("postgres://skintight@127.0.0.1:{}/{name}", self.port)
    }
}

impl Drop for PgCluster {
    fn drop(&mut self) {
        let _ = self
            .command("pg_ctl")
            .arg("-D")
            .arg(self.data())
            .args(["-m", "immediate", "stop"])
            .output();
    }
}
