//! The database failing under a running server: a worker that cannot load a job's inputs
//! gives the job back instead of failing it, and an event stream that cannot read its job
//! says so in a last event. Faults are made by renaming a table from another connection.

mod common;

use std::time::{Duration, Instant};

use common::*;
use serde_json::json;

fn inline_job() -> serde_json::Value {
    json!({"kind": "interpret", "inputs": {"program": {"name": "a.nc", "content": "G21 G90\nG0 X0 Y0 Z5\nG1 X10 F500\n"}}})
}

#[tokio::test]
async fn a_storage_error_while_loading_inputs_gives_the_job_back_instead_of_failing_it() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("t.db");
    let c = client();
    let s = Server::start(&db, &["--workers", "0"]);
    let (st, job) = post_json(&c, &s, "/v1/jobs", &inline_job()).await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap().to_string();
    let db_url = s.db_url.clone();
    assert!(s.terminate());

    // Inputs unreadable, jobs readable: a storage fault, not a fault of the job's.
    sql(&db_url, "ALTER TABLE resources RENAME TO resources_away").await;
    let s = Server::start(&db, &["--workers", "1"]);
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let now = get_json(&c, &s, &format!("/v1/jobs/{id}")).await;
    assert!(
        matches!(now["status"].as_str(), Some("queued" | "running")),
        "a storage error must not end the job: {now}"
    );
    sql(&db_url, "ALTER TABLE resources_away RENAME TO resources").await;
    let done = wait_job(&c, &s, &id, Duration::from_secs(30)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    // The attempts given back do not count.
    assert_eq!(done["attempts"], 1, "{done}");
}

#[tokio::test]
async fn the_event_stream_ends_with_an_error_event_when_its_job_cannot_be_read() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    let (st, job) = post_json(&c, &s, "/v1/jobs", &inline_job()).await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    let mut res = c
        .get(s.url(&format!("/v1/jobs/{id}/events")))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    let mut text = String::new();
    while !text.contains("event: progress") {
        let chunk = res.chunk().await.unwrap().expect("a progress event");
        text.push_str(&String::from_utf8_lossy(&chunk));
    }
    sql(&s.db_url, "ALTER TABLE jobs RENAME TO jobs_away").await;
    let deadline = Instant::now() + Duration::from_secs(10);
    while let Some(chunk) = tokio::time::timeout_at(deadline.into(), res.chunk())
        .await
        .expect("the stream ends")
        .unwrap()
    {
        text.push_str(&String::from_utf8_lossy(&chunk));
    }
    assert!(text.contains("event: error"), "no final event: {text}");
    let data = text
        .split("event: error\n")
        .nth(1)
        .and_then(|rest| rest.lines().next())
        .and_then(|l| l.strip_prefix("data: "))
        .unwrap();
    let problem: serde_json::Value = serde_json::from_str(data).unwrap();
    assert_eq!(problem["status"], 503, "{problem}");
}
