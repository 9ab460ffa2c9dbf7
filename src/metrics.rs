//! Prometheus metrics, rendered by hand: a few counters and two histograms do not need
//! a metrics framework.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::time::Duration;

use crate::store::workers::WorkerReport;

const REQUEST_BUCKETS: [f64; 10] = [0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.5, 1.0, 5.0];
const JOB_BUCKETS: [f64; 10] = [0.01, 0.05, 0.1, 0.5, 1.0, 2.0, 5.0, 30.0, 120.0, 600.0];

#[derive(Default)]
struct Histogram {
    counts: Vec<u64>,
    sum: f64,
    count: u64,
}

impl Histogram {
    fn observe(&mut self, buckets: &[f64], v: f64) {
        if self.counts.is_empty() {
            self.counts = vec![0; buckets.len()];
        }
        for (i, b) in buckets.iter().enumerate() {
            if v <= *b {
                self.counts[i] += 1;
            }
        }
        self.sum += v;
        self.count += 1;
    }

    fn render(&self, out: &mut String, name: &str, labels: &str, buckets: &[f64]) {
        let sep = if labels.is_empty() { "" } else { "," };
        for (i, b) in buckets.iter().enumerate() {
            let c = self.counts.get(i).copied().unwrap_or(0);
            let _ = writeln!(out, "{name}_bucket{{{labels}{sep}le=\"{b}\"}} {c}");
        }
        let _ = writeln!(
            out,
            "{name}_bucket{{{labels}{sep}le=\"+Inf\"}} {}",
            self.count
        );
        let _ = writeln!(out, "{name}_sum{{{labels}}} {}", self.sum);
        let _ = writeln!(out, "{name}_count{{{labels}}} {}", self.count);
    }
}

#[derive(Default)]
pub struct Metrics {
    requests: Mutex<BTreeMap<(String, String, u16), u64>>,
    request_seconds: Mutex<Histogram>,
    job_seconds: Mutex<BTreeMap<(String, String), Histogram>>,
}

impl Metrics {
    pub fn observe_request(&self, method: &str, route: &str, status: u16, elapsed: Duration) {
        *self
            .requests
            .lock()
            .unwrap()
            .entry((method.to_string(), route.to_string(), status))
            .or_default() += 1;
        self.request_seconds
            .lock()
            .unwrap()
            .observe(&REQUEST_BUCKETS, elapsed.as_secs_f64());
    }

    pub fn observe_job(&self, kind: &str, outcome: &str, elapsed: Duration) {
        self.job_seconds
            .lock()
            .unwrap()
            .entry((kind.to_string(), outcome.to_string()))
            .or_default()
            .observe(&JOB_BUCKETS, elapsed.as_secs_f64());
    }

    /// Prometheus text format; `job_counts` are (status, count) and `workers` the live
    /// workers of every process, both from the database.
    pub fn render(&self, job_counts: &[(String, i64)], workers: &[WorkerReport]) -> String {
        let mut out = String::new();
        out.push_str(
            "# HELP millsim_http_requests_total HTTP requests by method, route and status.\n",
        );
        out.push_str("# TYPE millsim_http_requests_total counter\n");
        for ((m, r, s), n) in self.requests.lock().unwrap().iter() {
            let _ = writeln!(
                out,
                "millsim_http_requests_total{{method=\"{m}\",route=\"{r}\",status=\"{s}\"}} {n}"
            );
        }
        out.push_str("# HELP millsim_http_request_duration_seconds HTTP request latency.\n");
        out.push_str("# TYPE millsim_http_request_duration_seconds histogram\n");
        self.request_seconds.lock().unwrap().render(
            &mut out,
            "millsim_http_request_duration_seconds",
            "",
            &REQUEST_BUCKETS,
        );
        out.push_str(
            "# HELP millsim_jobs Jobs in the database by status.\n# TYPE millsim_jobs gauge\n",
        );
        for status in crate::store::JobStatus::ALL {
            let n = job_counts
                .iter()
                .find(|(s, _)| s == status.as_str())
                .map(|(_, n)| *n)
                .unwrap_or(0);
            let _ = writeln!(out, "millsim_jobs{{status=\"{}\"}} {n}", status.as_str());
        }
        let queued = job_counts
            .iter()
            .find(|(s, _)| s == "queued")
            .map(|(_, n)| *n)
            .unwrap_or(0);
        out.push_str("# HELP millsim_queue_depth Jobs waiting for a worker.\n# TYPE millsim_queue_depth gauge\n");
        let _ = writeln!(out, "millsim_queue_depth {queued}");
        render_workers(&mut out, workers);
        out.push_str(
            "# HELP millsim_job_duration_seconds Wall time of job attempts run by this process.\n",
        );
        out.push_str("# TYPE millsim_job_duration_seconds histogram\n");
        for ((kind, outcome), h) in self.job_seconds.lock().unwrap().iter() {
            h.render(
                &mut out,
                "millsim_job_duration_seconds",
                &format!("kind=\"{kind}\",outcome=\"{outcome}\""),
                &JOB_BUCKETS,
            );
        }
        out
    }
}

/// A label value with `\`, `"` and newlines escaped (the exposition format's rule).
fn label(v: &str) -> String {
    v.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

/// Every live worker of every process sharing the database, with its counts.
fn render_workers(out: &mut String, workers: &[WorkerReport]) {
    out.push_str("# HELP millsim_workers Live workers in all processes sharing the database.\n# TYPE millsim_workers gauge\n");
    let _ = writeln!(out, "millsim_workers {}", workers.len());
    out.push_str("# HELP millsim_worker_running Whether the worker runs a job now (1) or waits (0).\n# TYPE millsim_worker_running gauge\n");
    for w in workers {
        let _ = writeln!(
            out,
            "millsim_worker_running{{worker=\"{}\",host=\"{}\"}} {}",
            label(&w.id),
            label(&w.host),
            w.running
        );
    }
    out.push_str("# HELP millsim_worker_jobs_claimed_total Jobs the worker claimed since it started.\n# TYPE millsim_worker_jobs_claimed_total counter\n");
    for w in workers {
        let _ = writeln!(
            out,
            "millsim_worker_jobs_claimed_total{{worker=\"{}\"}} {}",
            label(&w.id),
            w.claimed
        );
    }
    out.push_str("# HELP millsim_worker_jobs_finished_total Jobs the worker ended since it started, by outcome (abandoned: lease lost, given back or not committed).\n# TYPE millsim_worker_jobs_finished_total counter\n");
    for w in workers {
        for (outcome, n) in [
            ("succeeded", w.succeeded),
            ("failed", w.failed),
            ("cancelled", w.cancelled),
            ("abandoned", w.abandoned),
        ] {
            let _ = writeln!(
                out,
                "millsim_worker_jobs_finished_total{{worker=\"{}\",outcome=\"{outcome}\"}} {n}",
                label(&w.id)
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn label_values_are_escaped() {
        assert_eq!(label(r#"a"b\c"#), r#"a\"b\\c"#);
        assert_eq!(label("x\ny"), "x\\ny");
    }
}
