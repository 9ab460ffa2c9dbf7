//! `/metrics` shows every live worker of every process sharing the database, with its
//! claimed/finished counts: two `millsim worker` processes run jobs submitted to an API
//! process that runs none, and the API's /metrics must agree with the attempts log. Runs
//! on SQLite, and on PostgreSQL with MILLSIM_TEST_DATABASE=postgres://...

mod common;

use std::collections::BTreeMap;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use serde_json::json;

const JOBS: usize = 30;

fn start_worker(db_url: &str) -> Child {
    Command::new(BIN)
        .args(["worker", "--database", db_url, "--workers", "1"])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .spawn()
        .expect("start millsim worker")
}

/// Per worker: (claimed, succeeded) read from the metrics text.
fn per_worker(text: &str) -> BTreeMap<String, (i64, i64)> {
    let mut out: BTreeMap<String, (i64, i64)> = BTreeMap::new();
    for line in text.lines() {
        let value = |l: &str| l.rsplit_once(' ').unwrap().1.parse::<i64>().unwrap();
        let worker = |l: &str| {
            let start = l.find("worker=\"").unwrap() + 8;
            l[start..start + l[start..].find('"').unwrap()].to_string()
        };
        if line.starts_with("millsim_worker_jobs_claimed_total{") {
            out.entry(worker(line)).or_default().0 = value(line);
        } else if line.starts_with("millsim_worker_jobs_finished_total{")
            && line.contains("outcome=\"succeeded\"")
        {
            out.entry(worker(line)).or_default().1 = value(line);
        }
    }
    out
}

fn gauge(text: &str, name: &str) -> i64 {
    text.lines()
        .find_map(|l| l.strip_prefix(&format!("{name} ")))
        .unwrap_or_else(|| panic!("no {name} in {text}"))
        .parse()
        .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metrics_count_every_workers_jobs_across_processes() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("m.db"), &["--workers", "0"]);
    let c = client();
    let mut workers = [start_worker(&s.db_url), start_worker(&s.db_url)];
    let mut ids = Vec::new();
    for i in 0..JOBS {
        let program = format!("G0 X{i} Y1\nG1 X{} F100\n", i + 1);
        let body = json!({"kind": "interpret", "inputs": {"program": {"name": "t.nc", "content": program}}});
        let (st, v) = post_json(&c, &s, "/v1/jobs", &body).await;
        assert_eq!(st, 202, "{v}");
        ids.push(v["id"].as_str().unwrap().to_string());
        // Spread over time, so both workers are idle at some submissions and take some.
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    // Who ran what, from the attempts log.
    let mut expected: BTreeMap<String, (i64, i64)> = BTreeMap::new();
    for id in &ids {
        let job = wait_job(&c, &s, id, Duration::from_secs(60)).await;
        assert_eq!(job["status"], "succeeded", "{job}");
        let att = get_json(&c, &s, &format!("/v1/jobs/{id}/attempts")).await;
        let worker = att["items"][0]["worker"].as_str().unwrap().to_string();
        let e = expected.entry(worker).or_default();
        e.0 += 1;
        e.1 += 1;
    }
    assert_eq!(expected.values().map(|v| v.0).sum::<i64>(), JOBS as i64);

    // The API process runs no worker: what it shows comes from the two worker
    // processes' reports (every second).
    let deadline = Instant::now() + Duration::from_secs(10);
    let text = loop {
        let text = get_text(&c, &s, "/metrics").await;
        let shown = per_worker(&text);
        if shown.len() == 2 && shown.values().map(|v| v.1).sum::<i64>() == JOBS as i64 {
            break text;
        }
        assert!(Instant::now() < deadline, "{text}");
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    assert_eq!(gauge(&text, "millsim_workers"), 2, "{text}");
    let shown = per_worker(&text);
    // Each shown worker's counts are those of the attempts log (a worker that took no
    // job is shown with zeros).
    for (worker, counts) in &shown {
        assert_eq!(
            expected.get(worker).copied().unwrap_or((0, 0)),
            *counts,
            "{worker}: {text}"
        );
    }
    for worker in expected.keys() {
        assert!(shown.contains_key(worker), "{worker} not shown: {text}");
    }
    assert!(text.contains("millsim_worker_running{worker=\""), "{text}");

    // A worker that stops is no longer shown: at once when it stops cleanly (SIGTERM),
    // within a few seconds when it is killed (its reports stop).
    unsafe_kill(workers[0].id() as i32, 15);
    assert!(workers[0].wait().unwrap().success());
    unsafe_kill(workers[1].id() as i32, 9);
    let _ = workers[1].wait();
    let deadline = Instant::now() + Duration::from_secs(15);
    loop {
        let text = get_text(&c, &s, "/metrics").await;
        if gauge(&text, "millsim_workers") == 0 {
            assert!(per_worker(&text).is_empty(), "{text}");
            break;
        }
        assert!(Instant::now() < deadline, "{text}");
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
}
