//! Process isolation of jobs, the child's side: `skintight job-run` (hidden), started by the server
//! ([`super::isolation`]) with the job on its standard input. It opens the server's database, takes the job
//! the worker claimed (under that worker's lease, which the worker keeps renewing), runs it exactly as a worker thread would
//! ([`super::worker::execute`]) and stores its outcome ([`super::queue::finish`]). Every stored event is
//! announced by a line on standard output; `cancel` and `shutdown` lines on standard input stop the job
//! within one iteration.
//!
//! Exit status: 0 when the job's outcome was stored (or the lease had been taken away), 2 for a bad
//! request line, 1 when the database could not be used.

use std::io::BufRead;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::Ordering;

use super::config::Config;
use super::isolation::ChildJob;
use super::lifecycle::registry_for;
use super::model::StopFlags;
use super::state::AppState;
use super::store::Store;
use super::{queue, worker};

/// Runs `skintight job-run`.
pub fn child_main() -> ExitCode {
    let mut first = String::new();
    if std::io::stdin().lock().read_line(&mut first).is_err() {
        eprintln!("job-run: no job on standard input");
        return ExitCode::from(2);
    }
    let request: ChildJob = match serde_json::from_str(first.trim()) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("job-run: the job line is not valid: {e}");
            return ExitCode::from(2);
        }
    };
    // The server's settings that matter to a run; nothing here listens or authenticates.
    let overlay = format!(
        "[auth]\ndisabled = true\n[database]\npath = {:?}\nurl = {:?}\n[jobs]\nworkers = 1\n\
         isolation = \"thread\"\ntime_limit_s = {}\nenable_selftest = {}\n{}[log]\nfilter = \"warn\"\n",
        request.database,
        request.database_url,
        request.time_limit_s.max(1),
        request.enable_selftest,
        request
            .yarns_dir
            .as_ref()
            .map(|d| format!("yarns_dir = {:?}\n", d.display().to_string()))
            .unwrap_or_default()
    );
    let config = match Config::from_toml_overlay(&overlay) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("job-run: {e}");
            return ExitCode::from(2);
        }
    };
    super::lifecycle::init_logging(&config);
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            eprintln!("job-run: cannot start the async runtime: {e}");
            return ExitCode::from(1);
        }
    };
    match runtime.block_on(run(config, request)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("job-run: {e}");
            ExitCode::from(1)
        }
    }
}

async fn run(config: Config, request: ChildJob) -> Result<(), String> {
    let store = Store::connect(&config.database, 2)
        .await
        .map_err(|e| format!("cannot open the database: {e}"))?;
    let Some(job) = store
        .running_job(&request.job_id, &request.owner)
        .await
        .map_err(|e| format!("cannot read the job: {e}"))?
    else {
        // The lease was taken away (the server restarted): nothing to do.
        return Ok(());
    };
    let registry = registry_for(&config);
    let (_shutdown_tx, shutdown_rx) = tokio::sync::watch::channel(false);
    let state = AppState::new(store, config, registry, shutdown_rx, 1);
    // Stop requests from the server, one per line.
    let flags = Arc::new(StopFlags::default());
    if job.cancel_requested {
        flags.cancel.store(true, Ordering::SeqCst);
    }
    let control = flags.clone();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines() {
            match line.as_deref().map(str::trim) {
                Ok("cancel") => control.cancel.store(true, Ordering::SeqCst),
                Ok("shutdown") => control.shutdown.store(true, Ordering::SeqCst),
                Ok(_) => {}
                // The server is gone: stop as at a shutdown (the job is re-queued at its next start).
                Err(_) => break,
            }
        }
        control.shutdown.store(true, Ordering::SeqCst);
    });
    // Every stored event: a line for the server, which wakes its SSE streams.
    let mut events = state.events.subscribe();
    tokio::spawn(async move {
        use std::io::Write;
        while events.changed().await.is_ok() {
            let mut out = std::io::stdout().lock();
            if writeln!(out, "event").and_then(|_| out.flush()).is_err() {
                break;
            }
        }
    });
    let outcome = worker::execute(&state, &request.owner, &job, flags).await;
    queue::finish(&state, &job.id, &request.owner, outcome).await;
    state.store.close().await;
    Ok(())
}
