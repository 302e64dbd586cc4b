//! Prometheus text exposition (format 0.0.4) for `/metrics`, written by hand: jobs per status (queue depth,
//! running jobs) read from the database at scrape time, a job-duration histogram and an HTTP-latency
//! histogram kept in memory since the process started. The route is [`super::ops::metrics`]; this module
//! keeps the histograms and writes the text, without I/O.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;

/// Upper bounds of the HTTP latency buckets, s.
const HTTP_BUCKETS: &[f64] = &[
    0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0,
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

    fn write(&self, out: &mut String, name: &str, labels: &str) {
        let mut cum = 0;
        for (i, b) in self.bounds.iter().enumerate() {
            cum += self.counts[i];
            let _ = writeln!(out, "{name}_bucket{{{labels},le=\"{b}\"}} {cum}");
        }
        cum += self.counts[self.bounds.len()];
        let _ = writeln!(out, "{name}_bucket{{{labels},le=\"+Inf\"}} {cum}");
        let _ = writeln!(out, "{name}_sum{{{labels}}} {}", self.sum);
        let _ = writeln!(out, "{name}_count{{{labels}}} {}", self.count);
    }
}

/// In-memory metrics of one process.
#[derive(Default)]
pub struct Metrics {
    http: Mutex<BTreeMap<(String, String, u16), Histogram>>,
    jobs: Mutex<BTreeMap<(String, String), Histogram>>,
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
    }
}
