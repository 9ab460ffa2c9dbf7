//! Kill the server with SIGKILL while jobs run; start it again on the same database:
//! every job ends succeeded exactly once, and the attempts show the re-run.

mod common;

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use common::*;

#[tokio::test]
async fn sigkill_loses_no_job_and_completes_none_twice() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("crash.db");
    let args = ["--workers", "1", "--lease-s", "1"];
    let c = client();
    let mut server = Server::start(&db, &args);
    let program = upload_program(&c, &server, &adaptive_program()).await;
    let mut ids = Vec::new();
    for _ in 0..50 {
        ids.push(
            submit_interpret(&c, &server, &program).await["id"]
                .as_str()
                .unwrap()
                .to_string(),
        );
    }
    // Kill while a job runs; repeat (with restarts) until a kill caught a job mid-run.
    let mut interrupted: Vec<String> = Vec::new();
    for _round in 0..10 {
        let deadline = Instant::now() + Duration::from_secs(60);
        let running = loop {
            let (_, page) = json(
                c.get(server.url("/v1/jobs?status=running"))
                    .send()
                    .await
                    .unwrap(),
            )
            .await;
            if let Some(j) = page["items"].as_array().unwrap().first() {
                break Some(j["id"].as_str().unwrap().to_string());
            }
            let (_, queued) = json(
                c.get(server.url("/v1/jobs?status=queued&limit=1"))
                    .send()
                    .await
                    .unwrap(),
            )
            .await;
            if queued["items"].as_array().unwrap().is_empty() {
                break None;
            }
            assert!(Instant::now() < deadline, "no job started");
            tokio::time::sleep(Duration::from_millis(1)).await;
        };
        let Some(running) = running else { break };
        server.child.kill().unwrap(); // SIGKILL
        server.child.wait().unwrap();
        interrupted.push(running);
        server = Server::start(&db, &args);
        if interrupted.len() >= 2 {
            break;
        }
    }
    assert!(
        !interrupted.is_empty(),
        "the kill never caught a running job"
    );
    let mut succeeded_attempts: BTreeMap<String, usize> = BTreeMap::new();
    for id in &ids {
        let job = wait_job(&c, &server, id, Duration::from_secs(120)).await;
        assert_eq!(job["status"], "succeeded", "{job}");
        let (_, att) = json(
            c.get(server.url(&format!("/v1/jobs/{id}/attempts")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        let items = att["items"].as_array().unwrap();
        let wins = items.iter().filter(|a| a["outcome"] == "succeeded").count();
        succeeded_attempts.insert(id.clone(), wins);
        assert_eq!(
            items.len() as u64,
            job["attempts"].as_u64().unwrap(),
            "{att}"
        );
        // Every row of the result written once: as many rows as moves.
        let (_, page) = json(
            c.get(server.url(&format!("/v1/jobs/{id}/blocks?limit=1")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        assert_eq!(page["items"][0]["line"], 15);
    }
    assert!(
        succeeded_attempts.values().all(|&n| n == 1),
        "{succeeded_attempts:?}"
    );
    let mut rerun = false;
    for id in &interrupted {
        let (_, job) = json(
            c.get(server.url(&format!("/v1/jobs/{id}")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        let (_, att) = json(
            c.get(server.url(&format!("/v1/jobs/{id}/attempts")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        // A job caught mid-run shows two attempts: the lost one and the one that succeeded.
        if job["attempts"].as_u64().unwrap() >= 2 {
            rerun = true;
            assert_eq!(att["items"][0]["outcome"], "lost", "{att}");
        }
    }
    assert!(
        rerun,
        "no interrupted job shows a re-run: the kills all landed between jobs"
    );
    assert_eq!(ids.len(), 50);
}

/// Waits until the job runs its `attempt`-th attempt (a dead worker's job still reads
/// `running` until its lease expires and another worker claims it).
async fn wait_running(c: &reqwest::Client, s: &Server, id: &str, attempt: u64) {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let (_, v) = json(
            c.get(s.url(&format!("/v1/jobs/{id}")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        if v["status"] == "running" && v["attempts"].as_u64() == Some(attempt) {
            return;
        }
        assert!(
            matches!(v["status"].as_str(), Some("queued" | "running")),
            "{v}"
        );
        assert!(Instant::now() < deadline);
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
}

#[tokio::test]
async fn a_job_that_keeps_killing_its_worker_fails_after_max_attempts() {
    if !corpus_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("poison.db");
    let args = ["--workers", "1", "--lease-s", "0.5", "--max-attempts", "2"];
    let c = client();
    let mut server = Server::start(&db, &args);
    let program = upload_program(
        &c,
        &server,
        &corpus("gcode/camotics_cameo_fanuc_Nnumbers_3d.nc"),
    )
    .await;
    let id = submit_interpret(&c, &server, &program).await["id"]
        .as_str()
        .unwrap()
        .to_string();
    for attempt in 1..=2 {
        wait_running(&c, &server, &id, attempt).await;
        server.child.kill().unwrap();
        server.child.wait().unwrap();
        server = Server::start(&db, &args);
    }
    let job = wait_job(&c, &server, &id, Duration::from_secs(30)).await;
    assert_eq!(job["status"], "failed", "{job}");
    assert_eq!(job["attempts"], 2);
    assert_eq!(
        job["error"]["type"],
        "https://millsim.dev/problems/worker-lost"
    );
    assert!(
        job["error"]["detail"].as_str().unwrap().contains("2 times"),
        "{job}"
    );
}

#[tokio::test]
async fn sigterm_gives_a_running_job_back_and_exits_cleanly() {
    if !corpus_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("term.db");
    let c = client();
    let server = Server::start(&db, &["--workers", "1", "--shutdown-grace-s", "0"]);
    let program = upload_program(
        &c,
        &server,
        &corpus("gcode/camotics_cameo_fanuc_Nnumbers_3d.nc"),
    )
    .await;
    let mut gave_back = false;
    let mut server = Some(server);
    for _ in 0..5 {
        let s = server.take().unwrap();
        let id = submit_interpret(&c, &s, &program).await["id"]
            .as_str()
            .unwrap()
            .to_string();
        // A client following the job's events must not keep the server from stopping.
        let events = c
            .get(s.url(&format!("/v1/jobs/{id}/events")))
            .send()
            .await
            .unwrap();
        wait_running(&c, &s, &id, 1).await;
        assert!(s.terminate(), "serve did not exit 0 on SIGTERM");
        drop(events);
        let s = Server::start(&db, &["--workers", "0"]);
        let (_, job) = json(
            c.get(s.url(&format!("/v1/jobs/{id}")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        if job["status"] == "queued" {
            // Given back: the attempt does not count against the job.
            assert_eq!(job["attempts"], 0, "{job}");
            gave_back = true;
            drop(s);
            let s = Server::start(&db, &["--workers", "1"]);
            let done = wait_job(&c, &s, &id, Duration::from_secs(60)).await;
            assert_eq!(
                (done["status"].as_str(), done["attempts"].as_u64()),
                (Some("succeeded"), Some(1))
            );
            break;
        }
        // It finished inside the shutdown window; try again.
        assert_eq!(job["status"], "succeeded", "{job}");
        drop(s);
        server = Some(Server::start(
            &db,
            &["--workers", "1", "--shutdown-grace-s", "0"],
        ));
    }
    assert!(gave_back, "SIGTERM never caught a running job");
}

/// A program that never ends on its own (moves inside an endless loop).
pub const RUNAWAY: &str =
    "G21 G90\nG0 X0 Y0 Z5\no100 while [1 EQ 1]\nG1 X10 F1000\nG1 X0\no100 endwhile\nM30\n";

#[tokio::test]
async fn a_job_cancelled_while_its_worker_is_dead_closes_its_attempt() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("t.db");
    let c = client();
    let mut server = Server::start(&db, &["--workers", "1", "--lease-s", "0.5"]);
    let body = serde_json::json!({"kind": "interpret", "inputs": {"program": {"name": "loop.ngc", "content": RUNAWAY}}});
    let (st, job) = post_json(&c, &server, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap().to_string();
    let deadline = Instant::now() + Duration::from_secs(30);
    while get_json(&c, &server, &format!("/v1/jobs/{id}")).await["status"] != "running" {
        assert!(Instant::now() < deadline, "the job did not start");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    server.child.kill().unwrap(); // SIGKILL: the attempt stays open
    server.child.wait().unwrap();
    // No workers now: nothing reclaims the job; its lease runs out.
    let server = Server::start(&db, &["--workers", "0"]);
    tokio::time::sleep(Duration::from_millis(800)).await;
    let (st, after) = json(
        c.post(server.url(&format!("/v1/jobs/{id}/cancel")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 202, "{after}");
    assert_eq!(after["status"], "cancelled", "{after}");
    let attempts = get_json(&c, &server, &format!("/v1/jobs/{id}/attempts")).await;
    let items = attempts["items"].as_array().unwrap();
    assert_eq!(items.len(), 1, "{attempts}");
    assert_eq!(items[0]["outcome"], "lost", "{attempts}");
    assert!(items[0]["finished_at"].is_string(), "{attempts}");
}
