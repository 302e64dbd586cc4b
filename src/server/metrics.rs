//! Prometheus text exposition (format 0.0.4) for `/metrics`, written by hand: jobs per status (queue depth,
//! running jobs) read from the database at scrape time (all nodes' jobs), and, kept in memory since this
//! process started (this node's own): a job-duration histogram, an HTTP-latency histogram, the claim
//! latency of its workers and the count of their lease renewals. The route is [`super::ops::metrics`]; this module
//! keeps the histograms and writes the text, without I/O.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Upper bounds of the HTTP latency buckets, s.
const HTTP_BUCKETS: &[f64] = &[
    0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0,
];
/// Upper bounds of the claim latency buckets, s.
const CLAIM_BUCKETS: &[f64] = &[
    0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 1.0,
];
/// Upper bounds of the job duration buckets, s.
const JOB_BUCKETS: &[f64] = &[0.1, 0.5, 1.0, 5.0, 10.0, 30.0, 60.0, 300.0, 900.0, 3600.0];

/// A cumulative histogram with fixed buckets.
#[derive(Debug, Clone)]
struct Histogram {
    bounds: &'static [f64],
    /// Non-cumulative count per bucket; one extra for +Inf.
    counts: Vec<u64>,
    sum: f64,
    count: u64,
}

impl Histogram {
    fn new(bounds: &'static [f64]) -> Self {
        Histogram {
            bounds,
            counts: vec![0; bounds.len() + 1],
            sum: 0.0,
            count: 0,
        }
    }

    fn observe(&mut self, v: f64) {
        let i = self
            .bounds
            .iter()
            .position(|b| v <= *b)
            .unwrap_or(self.bounds.len());
        self.counts[i] += 1;
        self.sum += v;
        self.count += 1;
    }

    /// Writes the histogram's lines; `labels` may be empty.
    fn write(&self, out: &mut String, name: &str, labels: &str) {
        let (sep, braced) = if labels.is_empty() {
            ("", String::new())
        } else {
            (",", format!("{{{labels}}}"))
        };
        let mut cum = 0;
        for (i, b) in self.bounds.iter().enumerate() {
            cum += self.counts[i];
            let _ = writeln!(out, "{name}_bucket{{{labels}{sep}le=\"{b}\"}} {cum}");
        }
        cum += self.counts[self.bounds.len()];
        let _ = writeln!(out, "{name}_bucket{{{labels}{sep}le=\"+Inf\"}} {cum}");
        let _ = writeln!(out, "{name}_sum{braced} {}", self.sum);
        let _ = writeln!(out, "{name}_count{braced} {}", self.count);
    }
}

/// In-memory metrics of one process.
pub struct Metrics {
    http: Mutex<BTreeMap<(String, String, u16), Histogram>>,
    jobs: Mutex<BTreeMap<(String, String), Histogram>>,
    /// The claims of this node's workers that found a job: the time of the claim's transaction.
    claims: Mutex<Histogram>,
    lease_renewals: AtomicU64,
    leases_lost: AtomicU64,
    /// When a lease was last renewed.
    last_renewal: Mutex<Option<Instant>>,
}

impl Default for Metrics {
    fn default() -> Self {
        Metrics {
            http: Mutex::default(),
            jobs: Mutex::default(),
            claims: Mutex::new(Histogram::new(CLAIM_BUCKETS)),
            lease_renewals: AtomicU64::new(0),
            leases_lost: AtomicU64::new(0),
            last_renewal: Mutex::new(None),
        }
    }
}

/// Escapes a label value.
fn esc(v: &str) -> String {
    v.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

impl Metrics {
    /// One HTTP request: method, route template (`/v1/jobs/{id}`), status, seconds.
    pub fn observe_http(&self, method: &str, route: &str, status: u16, secs: f64) {
        let mut m = self.http.lock().expect("metrics lock");
        m.entry((method.to_string(), route.to_string(), status))
            .or_insert_with(|| Histogram::new(HTTP_BUCKETS))
            .observe(secs);
    }

    /// One job run: kind, outcome (`completed`, `failed`, `cancelled`, `requeued`), seconds.
    pub fn observe_job(&self, kind: &str, outcome: &str, secs: f64) {
        let mut m = self.jobs.lock().expect("metrics lock");
        m.entry((kind.to_string(), outcome.to_string()))
            .or_insert_with(|| Histogram::new(JOB_BUCKETS))
            .observe(secs);
    }
}

impl Metrics {
    /// One claim that found a job, seconds.
    pub fn observe_claim(&self, secs: f64) {
        self.claims.lock().expect("metrics lock").observe(secs);
    }

    /// A lease renewed by a heartbeat.
    pub fn lease_renewed(&self) {
        self.lease_renewals.fetch_add(1, Ordering::Relaxed);
        *self.last_renewal.lock().expect("metrics lock") = Some(Instant::now());
    }

    /// A lease found gone by its heartbeat.
    pub fn lease_lost(&self) {
        self.leases_lost.fetch_add(1, Ordering::Relaxed);
    }

    /// Seconds since a lease was last renewed here (`None`: never).
    pub fn since_last_renewal(&self) -> Option<f64> {
        self.last_renewal
            .lock()
            .expect("metrics lock")
            .map(|t| t.elapsed().as_secs_f64())
    }

    /// The exposition text: the job counts per status `counts` (from the database), the worker count,
    /// the uptime in seconds and the histograms kept here.
    pub fn render(&self, counts: &[(String, i64)], workers: usize, uptime_s: f64) -> String {
        let mut out = String::with_capacity(4096);
        let get = |s: &str| counts.iter().find(|(k, _)| k == s).map_or(0, |(_, n)| *n);
        out.push_str(
            "# HELP skintight_queue_depth Jobs waiting to run.\n# TYPE skintight_queue_depth gauge\n",
        );
        let _ = writeln!(out, "skintight_queue_depth {}", get("queued"));
        out.push_str(
            "# HELP skintight_jobs_running Jobs running now.\n# TYPE skintight_jobs_running gauge\n",
        );
        let _ = writeln!(out, "skintight_jobs_running {}", get("running"));
        out.push_str(
            "# HELP skintight_jobs Jobs in the database by status.\n# TYPE skintight_jobs gauge\n",
        );
        for status in ["queued", "running", "completed", "failed", "cancelled"] {
            let _ = writeln!(out, "skintight_jobs{{status=\"{status}\"}} {}", get(status));
        }
        let _ = writeln!(
            out,
            "# HELP skintight_workers Worker threads.\n# TYPE skintight_workers gauge\nskintight_workers {}",
            workers
        );
        let _ = writeln!(
            out,
            "# HELP skintight_uptime_seconds Seconds since the process started.\n# TYPE skintight_uptime_seconds gauge\nskintight_uptime_seconds {}",
            uptime_s
        );
        let _ = writeln!(
            out,
            "# HELP skintight_lease_renewals_total Leases renewed by this node's workers.\n\
             # TYPE skintight_lease_renewals_total counter\nskintight_lease_renewals_total {}",
            self.lease_renewals.load(Ordering::Relaxed)
        );
        let _ = writeln!(
            out,
            "# HELP skintight_leases_lost_total Leases this node's workers found expired and taken back.\n\
             # TYPE skintight_leases_lost_total counter\nskintight_leases_lost_total {}",
            self.leases_lost.load(Ordering::Relaxed)
        );
        out.push_str(
            "# HELP skintight_claim_duration_seconds Time of the claims of this node's workers that found a job.\n\
             # TYPE skintight_claim_duration_seconds histogram\n",
        );
        self.claims.lock().expect("metrics lock").write(
            &mut out,
            "skintight_claim_duration_seconds",
            "",
        );
        out.push_str(
            "# HELP skintight_job_duration_seconds Wall-clock time of job runs by kind and outcome.\n\
             # TYPE skintight_job_duration_seconds histogram\n",
        );
        for ((kind, outcome), h) in self.jobs.lock().expect("metrics lock").iter() {
            let labels = format!("kind=\"{}\",outcome=\"{}\"", esc(kind), esc(outcome));
            h.write(&mut out, "skintight_job_duration_seconds", &labels);
        }
        out.push_str(
            "# HELP skintight_http_request_duration_seconds HTTP request latency until the response head.\n\
             # TYPE skintight_http_request_duration_seconds histogram\n",
        );
        for ((method, route, status), h) in self.http.lock().expect("metrics lock").iter() {
            let labels = format!(
                "method=\"{}\",route=\"{}\",status=\"{status}\"",
                esc(method),
                esc(route)
            );
            h.write(&mut out, "skintight_http_request_duration_seconds", &labels);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_buckets_are_cumulative() {
        let mut h = Histogram::new(&[1.0, 2.0]);
        for v in [0.5, 1.5, 1.75, 9.0] {
            h.observe(v);
        }
        let mut out = String::new();
        h.write(&mut out, "x", "a=\"b\"");
        assert!(out.contains("x_bucket{a=\"b\",le=\"1\"} 1\n"), "{out}");
        assert!(out.contains("x_bucket{a=\"b\",le=\"2\"} 3\n"), "{out}");
        assert!(out.contains("x_bucket{a=\"b\",le=\"+Inf\"} 4\n"), "{out}");
        assert!(out.contains("x_count{a=\"b\"} 4\n"), "{out}");
        assert!(out.contains("x_sum{a=\"b\"} 12.75\n"), "{out}");
        let mut bare = String::new();
        h.write(&mut bare, "y", "");
        assert!(bare.contains("y_bucket{le=\"1\"} 1\n"), "{bare}");
        assert!(bare.contains("y_count 4\n"), "{bare}");
    }
}
