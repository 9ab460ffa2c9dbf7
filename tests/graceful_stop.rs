//! A graceful stop loses no result: a `millsim worker` process running many tiny jobs is
//! sent SIGTERM mid-stream; every result it had computed (on PostgreSQL, small results
//! commit while the worker claims the next job, up to four in flight) is committed
//! before it exits. Every job is then either succeeded exactly once with its rows, or
//! queued again, never running with a dead owner; a new worker finishes the rest.

mod common;

use std::collections::HashMap;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use serde_json::json;

const JOBS: usize = 300;
/// Three moves: rows 0..3 of every job.
const PROGRAM: &str = "G21 G90\nG0 X0 Y0 Z5\nG1 X10 F1000\nG1 Y10\nM30\n";

type Worker = KilledOnDrop;

/// Waits until `n` jobs have succeeded (well into the stream, not at its end).
async fn wait_for_successes(db_url: &str, n: usize) {
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        let (jobs, _) = queue_state(db_url).await;
        let done = jobs.values().filter(|v| *v == "succeeded").count();
        if done >= n {
            return;
        }
        assert!(Instant::now() < deadline, "{done} jobs succeeded in 120 s");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

fn start_worker(db_url: &str) -> Worker {
    // A long lease: a job left running by the stopped worker would stay visibly so. The
    // flags' old spellings (`-secs`) are kept here on purpose: they must still be read.
    KilledOnDrop(
        Command::new(BIN)
            .args(["worker", "--database", db_url, "--workers", "2"])
            .args(["--lease-secs", "60", "--shutdown-grace-secs", "30"])
            .env("RUST_LOG", "warn")
            .stdout(Stdio::null())
            .spawn()
            .expect("start millsim worker"),
    )
}

/// SIGTERM, then the exit status (within 40 s).
fn stop(mut w: Worker) -> bool {
    unsafe_kill(w.0.id() as i32, 15);
    let deadline = Instant::now() + Duration::from_secs(40);
    loop {
        if let Some(status) = w.0.try_wait().unwrap() {
            return status.success();
        }
        assert!(Instant::now() < deadline, "the worker did not stop");
        std::thread::sleep(Duration::from_millis(20));
    }
}

type Attempt = (String, i64, Option<i64>, Option<String>);

/// Jobs by status, and every attempt, read from the database.
async fn queue_state(url: &str) -> (HashMap<String, String>, Vec<Attempt>) {
    use sqlx::Connection;
    let jobs = "SELECT id, status FROM jobs";
    let attempts = "SELECT job_id, attempt, finished_at, outcome FROM job_attempts";
    let (jobs, attempts): (Vec<(String, String)>, Vec<Attempt>) = if url.starts_with("sqlite:") {
        let mut c = sqlx::SqliteConnection::connect(url).await.unwrap();
        (
            sqlx::query_as(jobs).fetch_all(&mut c).await.unwrap(),
            sqlx::query_as(attempts).fetch_all(&mut c).await.unwrap(),
        )
    } else {
        let mut c = sqlx::PgConnection::connect(url).await.unwrap();
        (
            sqlx::query_as(jobs).fetch_all(&mut c).await.unwrap(),
            sqlx::query_as(attempts).fetch_all(&mut c).await.unwrap(),
        )
    };
    (jobs.into_iter().collect(), attempts)
}

/// Every succeeded job has one attempt, succeeded, and its three rows; every other job
/// is queued with no attempt open. Returns the count succeeded.
async fn check_each_job_once_or_queued(c: &reqwest::Client, s: &Server) -> usize {
    let (jobs, attempts) = queue_state(&s.db_url).await;
    assert_eq!(jobs.len(), JOBS, "a job was lost or doubled");
    let mut succeeded = 0;
    for (id, status) in &jobs {
        let mine: Vec<&Attempt> = attempts.iter().filter(|a| &a.0 == id).collect();
        match status.as_str() {
            "succeeded" => {
                succeeded += 1;
                assert_eq!(mine.len(), 1, "job {id}: attempts {mine:?}");
                assert_eq!(mine[0].3.as_deref(), Some("succeeded"), "{mine:?}");
                assert!(mine[0].2.is_some(), "{mine:?}");
                let page = get_json(c, s, &format!("/v1/jobs/{id}/blocks")).await;
                let rows = page["items"].as_array().unwrap();
                assert_eq!(rows.len(), 3, "job {id}: {page}");
            }
            "queued" => {
                assert!(
                    mine.iter().all(|a| a.3.is_some()),
                    "queued job {id} has an open attempt: {mine:?}"
                );
            }
            other => panic!("job {id} is {other} after the worker stopped"),
        }
    }
    succeeded
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_commits_every_result_in_flight() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    let body =
        json!({"kind": "interpret", "inputs": {"program": {"name": "p.nc", "content": PROGRAM}}});
    for _ in 0..JOBS {
        let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
        assert_eq!(st, 202, "{job}");
    }

    let worker = start_worker(&s.db_url);
    // Stop it once it is well into the stream.
    wait_for_successes(&s.db_url, 40).await;
    assert!(
        stop(worker),
        "the worker's exit after SIGTERM was not clean"
    );
    let succeeded = check_each_job_once_or_queued(&c, &s).await;
    println!("stopped after {succeeded} of {JOBS} jobs");
    assert!(succeeded >= 40);
    assert!(
        succeeded < JOBS,
        "every job ran before the stop: nothing was tested"
    );

    // A new worker runs the rest; still each exactly once.
    let worker = start_worker(&s.db_url);
    let deadline = Instant::now() + Duration::from_secs(180);
    loop {
        let (jobs, _) = queue_state(&s.db_url).await;
        if jobs.values().all(|v| v == "succeeded") {
            break;
        }
        assert!(Instant::now() < deadline, "the rest did not finish");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(stop(worker));
    assert_eq!(check_each_job_once_or_queued(&c, &s).await, JOBS);
}

/// The same inside `millsim serve` (API and workers in one process).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_to_serve_commits_every_result_in_flight() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.db");
    // Submitted first (to an API without workers), so that the stop comes mid-stream.
    let s = Server::start(&path, &["--workers", "0"]);
    let c = client();
    let body =
        json!({"kind": "interpret", "inputs": {"program": {"name": "p.nc", "content": PROGRAM}}});
    for _ in 0..JOBS {
        let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
        assert_eq!(st, 202, "{job}");
    }
    assert!(s.terminate());
    let s = Server::start(
        &path,
        &[
            "--workers",
            "2",
            "--lease-s",
            "60",
            "--shutdown-grace-s",
            "30",
        ],
    );
    wait_for_successes(&s.db_url, 40).await;
    assert!(s.terminate(), "serve's exit after SIGTERM was not clean");
    // An API alone to read the rows back.
    let s = Server::start(&path, &["--workers", "0"]);
    let succeeded = check_each_job_once_or_queued(&c, &s).await;
    println!("stopped after {succeeded} of {JOBS} jobs");
    assert!((40..JOBS).contains(&succeeded), "{succeeded}");
}
