//! Process isolation of jobs, the server's side: with `jobs.isolation = "process"` a job of a built-in kind
//! runs in a child process — the server's own executable with the hidden subcommand `job-run`
//! ([`super::job_process`]) — under an address-space limit (`jobs.max_memory_bytes`, `RLIMIT_AS`) and a
//! CPU-time limit (`jobs.max_cpu_s`, `RLIMIT_CPU`), so that a job that runs out of memory, aborts or is
//! killed by a signal fails alone (`out_of_memory`, `cpu_limit_exceeded`, `crashed`) and the server goes on.
//!
//! The protocol: the server writes one JSON line ([`ChildJob`]) to the child's standard input, then
//! `cancel` or `shutdown` lines when the job is to stop. The child opens the same database, runs the job
//! under the worker's lease exactly as a worker thread would (iterations, checkpoints, artifacts and the
//! final outcome go to the store), and writes a line to standard output after every event it stored, on
//! which the server wakes its SSE streams. Standard error is the child's log, forwarded to the server's log;
//! its tail tells an allocation failure from other aborts. The child dies with the thread that started it
//! (`PR_SET_PDEATHSIG`), so a server killed with `kill -9` leaves no job process behind.

use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Command, ExitStatus, Stdio};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use super::model::{Claimed, Outcome, StopFlags};
use super::state::AppState;

/// The first line a job process reads: which job to run, under which lease, with which settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ChildJob {
    /// The database file (SQLite).
    pub database: std::path::PathBuf,
    /// The PostgreSQL URL (`database.url`); empty for SQLite.
    #[serde(default)]
    pub database_url: String,
    pub job_id: String,
    /// The worker's lease id (`lease_owner`) the child writes under.
    pub owner: String,
    /// `jobs.time_limit_s`.
    pub time_limit_s: u64,
    /// `jobs.enable_selftest` (the kinds the child knows are the server's built-in ones).
    pub enable_selftest: bool,
    /// `jobs.yarns_dir`.
    #[serde(default)]
    pub yarns_dir: Option<std::path::PathBuf>,
}

/// Whether a job of `kind` runs in a child process on this server.
pub fn applies(state: &AppState, kind: &str) -> bool {
    cfg!(unix) && state.config.jobs.isolation == "process" && state.registry.is_builtin(kind)
}

/// The last bytes a child wrote to standard error (its log, and the message of an abort).
const STDERR_TAIL: usize = 16 * 1024;

/// How a child process ended, as seen by the server.
#[derive(Debug)]
enum ChildEnd {
    /// It exited normally: it stored the job's outcome itself.
    Finished,
    /// The server killed it past the time limit.
    KilledForTime,
    /// Any other end: its status and the tail of its standard error.
    Abnormal { status: ExitStatus, stderr: String },
}

/// Runs the claimed `job` in a child process and waits for it. `None` when the child stored the job's
/// outcome itself; otherwise the outcome the server is to store (the child died).
pub async fn run_in_child(
    state: &AppState,
    owner: &str,
    job: &Claimed,
    flags: Arc<StopFlags>,
) -> Option<Outcome> {
    let cfg = &state.config.jobs;
    let exe = if cfg.runner.is_empty() {
        // On Linux the running executable itself, even after its file was replaced or deleted (an
        // upgrade in place): job processes run the server's own version.
        let own = std::path::Path::new("/proc/self/exe");
        if cfg!(target_os = "linux") && own.exists() {
            own.to_path_buf()
        } else {
            match std::env::current_exe() {
                Ok(p) => p,
                Err(e) => {
                    tracing::error!(error = %e, "cannot find the server's executable for a job process");
                    return Some(internal());
                }
            }
        }
    } else {
        std::path::PathBuf::from(&cfg.runner)
    };
    let request = ChildJob {
        database: state.config.database.path.clone(),
        database_url: state.config.database.url.clone(),
        job_id: job.id.clone(),
        owner: owner.to_string(),
        time_limit_s: cfg.time_limit_s,
        enable_selftest: cfg.enable_selftest,
        yarns_dir: Some(cfg.yarns_dir.clone()),
    };
    let limits = (cfg.max_memory_bytes, cfg.max_cpu_s);
    // The child is watched for a little longer than the time limit it enforces itself.
    let watchdog = Duration::from_secs(cfg.time_limit_s) + Duration::from_secs(10);
    let events_state = state.clone();
    let job_id = job.id.clone();
    let waited = tokio::task::spawn_blocking(move || {
        supervise(&exe, &request, limits, watchdog, &flags, &|| {
            events_state.bump_events()
        })
    })
    .await;
    let end = match waited {
        Ok(Ok(end)) => end,
        Ok(Err(e)) => {
            tracing::error!(job = %job_id, error = %e, "starting a job process failed");
            return Some(internal());
        }
        Err(e) => {
            tracing::error!(job = %job_id, error = %e, "supervising a job process failed");
            return Some(internal());
        }
    };
    match end {
        ChildEnd::Finished => None,
        ChildEnd::KilledForTime => Some(Outcome::Failed {
            code: "time_limit_exceeded",
            message: format!(
                "the job ran past its time limit of {} s",
                state.config.jobs.time_limit_s
            ),
        }),
        ChildEnd::Abnormal { status, stderr } => {
            let outcome = classify(status, &stderr, limits);
            tracing::warn!(job = %job_id, %status, stderr = %stderr.trim_end(), "job process died");
            Some(outcome)
        }
    }
}

fn internal() -> Outcome {
    Outcome::Failed {
        code: "internal",
        message: "the job could not be started; the details are in the server log".into(),
    }
}

/// Address space the dense linear algebra reserves on top of a job's own memory, which `RLIMIT_AS` would
/// otherwise count against `jobs.max_memory_bytes` (bytes): faer's x86 matrix kernels (private-gemm-x86)
/// keep, per thread that runs one, a packing buffer of twice the L3 cache the CPU reports — 960 MiB on a
/// virtual Xeon that reports a 480 MiB L3, where a small cloth job then failed a 768 MiB limit at its first
/// factorization — reserved at once and touched only in part. Allowed for every thread of the machine.
fn dense_kernel_reservation() -> u64 {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
    l3_cache_bytes().saturating_mul(2 * threads)
}

/// The largest L3 (or higher-level) cache the first CPU reports, from Linux's sysfs (bytes); 0 where
/// that is not readable.
fn l3_cache_bytes() -> u64 {
    let dir = std::path::Path::new("/sys/devices/system/cpu/cpu0/cache");
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let read = |p: std::path::PathBuf| std::fs::read_to_string(p).unwrap_or_default();
    entries
        .flatten()
        .filter(|e| {
            read(e.path().join("level"))
                .trim()
                .parse::<u32>()
                .is_ok_and(|l| l >= 3)
        })
        .filter_map(|e| cache_size_bytes(&read(e.path().join("size"))))
        .max()
        .unwrap_or(0)
}

/// A sysfs cache size (`491520K`, `32M`, `1024`) in bytes.
fn cache_size_bytes(text: &str) -> Option<u64> {
    let t = text.trim();
    let (digits, unit) = match t.char_indices().find(|(_, c)| !c.is_ascii_digit()) {
        Some((k, _)) => t.split_at(k),
        None => (t, ""),
    };
    let n: u64 = digits.parse().ok()?;
    let scale = match unit {
        "" => 1,
        "K" => 1 << 10,
        "M" => 1 << 20,
        "G" => 1 << 30,
        _ => return None,
    };
    n.checked_mul(scale)
}

/// The outcome of a child that died: an allocation failure (or the kernel's OOM kill) is `out_of_memory`,
/// the CPU-time signal `cpu_limit_exceeded`, anything else `crashed`.
fn classify(status: ExitStatus, stderr: &str, (mem, cpu): (u64, u64)) -> Outcome {
    #[cfg(unix)]
    let signal = std::os::unix::process::ExitStatusExt::signal(&status);
    #[cfg(not(unix))]
    let signal: Option<i32> = None;
    let out_of_memory = stderr.contains("memory allocation of")
        || stderr.contains("out of memory")
        || stderr.contains("Cannot allocate memory");
    if out_of_memory {
        return Outcome::Failed {
            code: "out_of_memory",
            message: format!(
                "the job ran out of memory: its process may use at most {mem} bytes of address space \
                 (jobs.max_memory_bytes) beyond what its linear algebra reserves; use a coarser spec (a \
                 larger garment.edge_length, a coarser body)"
            ),
        };
    }
    #[cfg(unix)]
    if signal == Some(libc::SIGXCPU) {
        return Outcome::Failed {
            code: "cpu_limit_exceeded",
            message: format!(
                "the job used more than its CPU time limit of {cpu} s (jobs.max_cpu_s)"
            ),
        };
    }
    let _ = cpu;
    let how = match (signal, status.code()) {
        (Some(s), _) => format!("was ended by signal {s}"),
        (None, Some(101)) => "failed unexpectedly (a panic)".to_string(),
        (None, Some(c)) => format!("exited with status {c}"),
        (None, None) => "ended abnormally".to_string(),
    };
    Outcome::Failed {
        code: "crashed",
        message: format!("the job's process {how}; the details are in the server log"),
    }
}

/// Starts the child, hands it the job, forwards stop requests, wakes the SSE streams on its events, and
/// waits for it (on the calling blocking thread, which must outlive the child: the child's parent-death
/// signal is tied to it).
fn supervise(
    exe: &std::path::Path,
    request: &ChildJob,
    (mem, cpu): (u64, u64),
    watchdog: Duration,
    flags: &StopFlags,
    on_event: &(dyn Fn() + Sync),
) -> std::io::Result<ChildEnd> {
    // The address space of the job's own memory plus what the dense linear algebra reserves.
    let address_space = mem.saturating_add(dense_kernel_reservation());
    let mut cmd = Command::new(exe);
    cmd.arg("job-run")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        // glibc reserves 64 MiB of address space per malloc arena (up to 8 per core): keep that small so
        // that the address-space limit measures the job's own memory.
        .env("MALLOC_ARENA_MAX", "2");
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        // SAFETY: only async-signal-safe calls (setrlimit, prctl) between fork and exec.
        unsafe {
            cmd.pre_exec(move || {
                let set = |resource, soft: u64, hard: u64| {
                    let lim = libc::rlimit {
                        rlim_cur: soft as libc::rlim_t,
                        rlim_max: hard as libc::rlim_t,
                    };
                    if libc::setrlimit(resource, &lim) != 0 {
                        return Err(std::io::Error::last_os_error());
                    }
                    Ok(())
                };
                set(libc::RLIMIT_AS, address_space, address_space)?;
                // SIGXCPU at the soft limit, SIGKILL a little after.
                set(libc::RLIMIT_CPU, cpu, cpu.saturating_add(5))?;
                set(libc::RLIMIT_CORE, 0, 0)?;
                #[cfg(target_os = "linux")]
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL as libc::c_ulong);
                Ok(())
            });
        }
    }
    let mut child = cmd.spawn()?;
    let mut stdin = child.stdin.take().expect("piped stdin");
    let stdout = child.stdout.take().expect("piped stdout");
    let mut stderr = child.stderr.take().expect("piped stderr");
    let line = serde_json::to_string(request).map_err(std::io::Error::other)?;
    // A child that died at once makes this fail; its exit status says why.
    let _ = writeln!(stdin, "{line}").and_then(|_| stdin.flush());

    let tail = Arc::new(Mutex::new(Vec::<u8>::new()));
    std::thread::scope(|scope| {
        scope.spawn(|| {
            for l in BufReader::new(stdout).lines() {
                if l.is_err() {
                    break;
                }
                on_event();
            }
        });
        let tail_w = tail.clone();
        scope.spawn(move || {
            let mut buf = [0u8; 4096];
            loop {
                match stderr.read(&mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(n) => {
                        let mut t = tail_w.lock().expect("stderr tail");
                        t.extend_from_slice(&buf[..n]);
                        let len = t.len();
                        if len > STDERR_TAIL {
                            t.drain(..len - STDERR_TAIL);
                        }
                    }
                }
            }
        });
        let start = Instant::now();
        let (mut cancel_sent, mut shutdown_sent) = (false, false);
        let mut killed_for_time = false;
        let status = loop {
            match child.try_wait() {
                Ok(Some(status)) => break Ok(status),
                Ok(None) => {}
                Err(e) => break Err(e),
            }
            if !cancel_sent && flags.cancel.load(Ordering::SeqCst) {
                cancel_sent = writeln!(stdin, "cancel")
                    .and_then(|_| stdin.flush())
                    .is_ok();
            }
            if !shutdown_sent && flags.shutdown.load(Ordering::SeqCst) {
                shutdown_sent = writeln!(stdin, "shutdown")
                    .and_then(|_| stdin.flush())
                    .is_ok();
            }
            if !killed_for_time && start.elapsed() > watchdog {
                killed_for_time = true;
                let _ = child.kill();
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        drop(stdin);
        let status = status?;
        // The readers end when the child's pipes close (the scope joins them).
        Ok((status, killed_for_time))
    })
    .map(|(status, killed_for_time)| {
        if status.success() {
            ChildEnd::Finished
        } else if killed_for_time {
            ChildEnd::KilledForTime
        } else {
            let stderr = String::from_utf8_lossy(&tail.lock().expect("stderr tail")).into_owned();
            ChildEnd::Abnormal { status, stderr }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sysfs_cache_sizes_are_read_in_bytes() {
        assert_eq!(cache_size_bytes("491520K\n"), Some(491_520 << 10));
        assert_eq!(cache_size_bytes("32M"), Some(32 << 20));
        assert_eq!(cache_size_bytes("1024"), Some(1024));
        assert_eq!(cache_size_bytes("12Q"), None);
        assert_eq!(cache_size_bytes(""), None);
        assert_eq!(cache_size_bytes("99999999999999999999G"), None);
    }

    #[cfg(unix)]
    #[test]
    fn deaths_are_told_apart() {
        use std::os::unix::process::ExitStatusExt;
        let limits = (1 << 30, 60);
        let abort = ExitStatus::from_raw(libc::SIGABRT);
        let code = |o: Outcome| match o {
            Outcome::Failed { code, message } => (code, message),
            other => panic!("{other:?}"),
        };
        let (c, m) = code(classify(
            abort,
            "memory allocation of 400000000 bytes failed\n",
            limits,
        ));
        assert_eq!(c, "out_of_memory");
        assert!(m.contains("jobs.max_memory_bytes"), "{m}");
        assert_eq!(code(classify(abort, "", limits)).0, "crashed");
        let (c, m) = code(classify(ExitStatus::from_raw(libc::SIGXCPU), "", limits));
        assert_eq!(c, "cpu_limit_exceeded");
        assert!(m.contains("jobs.max_cpu_s"), "{m}");
        let (c, m) = code(classify(ExitStatus::from_raw(101 << 8), "", limits));
        assert_eq!(c, "crashed");
        assert!(m.contains("panic"), "{m}");
    }
}
