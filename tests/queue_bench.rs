//! Queue benchmark (ignored by default; prints a table): claims per second and
//! submit→running latency with 1, 2 and 4 worker processes on tiny jobs, on SQLite and,
//! with MILLSIM_TEST_DATABASE=postgres://..., on PostgreSQL.
//!
//!     cargo test --release --test queue_bench -- --ignored --nocapture
//!
//! (BENCH_WORKERS=1,4 picks the worker counts.)
//!
//! Jobs run with `--job-isolation thread` so the figure is the queue's (claim, heartbeat,
//! commit), not the cost of starting a process per job.

mod common;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use serde_json::json;
use sqlx::Connection;

const JOBS: usize = 1000;
const LATENCY_SAMPLES: usize = 60;

fn start_workers(db_url: &str, n: usize) -> Vec<Child> {
    (0..n)
        .map(|_| {
            Command::new(BIN)
                .args([
                    "worker",
                    "--database",
                    db_url,
                    "--workers",
                    "1",
                    "--job-isolation",
                    "thread",
                ])
                .env("RUST_LOG", "warn")
                .stdout(Stdio::null())
                .spawn()
                .unwrap()
        })
        .collect()
}

fn tiny_job() -> serde_json::Value {
    json!({"kind": "interpret", "inputs": {"program": {"name": "t.nc", "content": "G0 X1 Y1\nG1 X2 F100\n"}}})
}

/// (first claim, last finish, succeeded) from the jobs table, ms.
async fn span(db_url: &str) -> (i64, i64, i64) {
    let q =
        "SELECT MIN(started_at), MAX(finished_at), COUNT(*) FROM jobs WHERE status = 'succeeded'";
    if db_url.starts_with("sqlite:") {
        let mut c = sqlx::SqliteConnection::connect(db_url).await.unwrap();
        let r: (Option<i64>, Option<i64>, i64) = sqlx::query_as(q).fetch_one(&mut c).await.unwrap();
        (r.0.unwrap_or(0), r.1.unwrap_or(0), r.2)
    } else {
        let mut c = sqlx::PgConnection::connect(db_url).await.unwrap();
        let r: (Option<i64>, Option<i64>, i64) = sqlx::query_as(q).fetch_one(&mut c).await.unwrap();
        (r.0.unwrap_or(0), r.1.unwrap_or(0), r.2)
    }
}

fn ms(rfc: &serde_json::Value) -> f64 {
    // "2026-11-25T14:22:02.123Z": seconds of the day are enough for a difference.
    let t = rfc.as_str().unwrap();
    let h: f64 = t[11..13].parse().unwrap();
    let m: f64 = t[14..16].parse().unwrap();
    let s: f64 = t[17..23].parse().unwrap();
    ((h * 60.0 + m) * 60.0 + s) * 1000.0
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

async fn run(label: &str, path: &std::path::Path, workers: usize) {
    let s = Server::start(path, &["--workers", "0"]);
    let c = client();
    for _ in 0..JOBS {
        let (st, v) = post_json(&c, &s, "/v1/jobs", &tiny_job()).await;
        assert_eq!(st, 202, "{v}");
    }
    let started = Instant::now();
    let mut procs = start_workers(&s.db_url, workers);
    // Counted in the database, a few times a second: polling each job over HTTP would
    // take CPU from the workers on this 2-core machine.
    loop {
        let (_, _, done) = span(&s.db_url).await;
        if done as usize == JOBS {
            break;
        }
        assert!(
            started.elapsed() < Duration::from_secs(600),
            "{done} of {JOBS} done"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let wall = started.elapsed();
    let (first, last, _) = span(&s.db_url).await;
    let rate = JOBS as f64 / ((last - first).max(1) as f64 / 1000.0);
    // Latency: one job at a time into idle workers.
    let mut lat = Vec::new();
    for _ in 0..LATENCY_SAMPLES {
        tokio::time::sleep(Duration::from_millis(20)).await;
        let (_, v) = post_json(&c, &s, "/v1/jobs", &tiny_job()).await;
        let id = v["id"].as_str().unwrap();
        let j = wait_job(&c, &s, id, Duration::from_secs(60)).await;
        lat.push(ms(&j["started_at"]) - ms(&j["created_at"]));
    }
    lat.sort_by(|a, b| a.partial_cmp(b).unwrap());
    println!(
        "{label:<10} workers={workers}  {rate:>7.0} jobs/s claimed and committed ({JOBS} jobs, {:.1} s wall)  submit->running ms: median {:.0}, p95 {:.0}, max {:.0}",
        wall.as_secs_f64(),
        percentile(&lat, 0.5),
        percentile(&lat, 0.95),
        lat[lat.len() - 1]
    );
    for p in &mut procs {
        let _ = p.kill();
        let _ = p.wait();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "benchmark: run with --ignored --nocapture"]
async fn queue_throughput_and_latency() {
    let counts: Vec<usize> = std::env::var("BENCH_WORKERS")
        .map(|v| v.split(',').map(|n| n.trim().parse().unwrap()).collect())
        .unwrap_or_else(|_| vec![1, 2, 4]);
    for workers in counts {
        let dir = tempfile::tempdir().unwrap();
        let label = if test_postgres().is_some() {
            "postgres"
        } else {
            "sqlite"
        };
        run(label, &dir.path().join("bench.db"), workers).await;
    }
}

/// Simulate jobs through the queue: the adaptive example (examples/adaptive, 6.5k lines),
/// SIM_JOBS of them, with 1 and 2 worker processes of one engine thread each (process
/// isolation, as in production). Prints jobs per minute.
///
///     cargo test --release --test queue_bench simulate -- --ignored --nocapture
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "benchmark: run with --ignored --nocapture"]
async fn simulate_throughput() {
    let jobs: usize = std::env::var("SIM_JOBS")
        .map(|v| v.parse().unwrap())
        .unwrap_or(8);
    let label = if test_postgres().is_some() {
        "postgres"
    } else {
        "sqlite"
    };
    let example = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/adaptive");
    let read = |f: &str| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(example.join(f)).unwrap()).unwrap()
    };
    for workers in [1, 2] {
        let dir = tempfile::tempdir().unwrap();
        let s = Server::start(&dir.path().join("sim.db"), &["--workers", "0"]);
        let c = client();
        let mut inputs = serde_json::Map::new();
        for (input, path, file) in [
            ("stock", "/v1/stocks", "stock.json"),
            ("tool", "/v1/tools", "tool.json"),
            ("machine", "/v1/machines", "machine.json"),
        ] {
            let (st, v) = post_json(&c, &s, path, &read(file)).await;
            assert_eq!(st, 201, "{v}");
            inputs.insert(input.into(), v["id"].clone());
        }
        let program = upload_program(&c, &s, &example.join("1055_utab_265bit.nc")).await;
        inputs.insert("program".into(), program.into());
        let body =
            json!({"kind": "simulate", "inputs": inputs, "options": {"material": "Al7075-T6"}});
        let mut ids = Vec::new();
        for _ in 0..jobs {
            let (st, v) = post_json(&c, &s, "/v1/jobs", &body).await;
            assert_eq!(st, 202, "{v}");
            ids.push(v["id"].as_str().unwrap().to_string());
        }
        let mut procs: Vec<Child> = (0..workers)
            .map(|_| {
                Command::new(BIN)
                    .args(["worker", "--database", &s.db_url, "--workers", "1"])
                    .env("RUST_LOG", "warn")
                    .stdout(Stdio::null())
                    .spawn()
                    .unwrap()
            })
            .collect();
        for id in &ids {
            let j = wait_job(&c, &s, id, Duration::from_secs(1800)).await;
            assert_eq!(j["status"], "succeeded", "{j}");
        }
        let (first, last, _) = span(&s.db_url).await;
        let minutes = (last - first) as f64 / 60_000.0;
        println!(
            "{label:<10} simulate, adaptive example: {workers} worker process(es): {jobs} jobs in {:.1} s = {:.1} jobs/min",
            minutes * 60.0,
            jobs as f64 / minutes
        );
        for p in &mut procs {
            let _ = p.kill();
            let _ = p.wait();
        }
    }
}
