//! Scale-out on PostgreSQL: API and worker processes (as on separate hosts) share one
//! database. Several processes starting at once migrate it once; 400 jobs submitted to two
//! API processes run exactly once on four workers while two of them are SIGKILLed mid-job
//! (one restarted), and no job ever runs on two workers at once. Skipped, saying so,
//! without MILLSIM_TEST_DATABASE=postgres://...

mod common;

use std::collections::{BTreeMap, HashMap};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use serde_json::json;
use sqlx::Connection;

/// A program that runs for a few tens of milliseconds (a bounded loop), so kills land
/// mid-job often.
const SHORT_LOOP: &str = "G21 G90\nG0 X0 Y0 Z5\n#1=0\no100 while [#1 LT 400]\nG1 X10 F1000\nG1 X0\n#1=[#1+1]\no100 endwhile\nM30\n";

type Worker = KilledOnDrop;

fn start_worker(db_url: &str) -> Worker {
    KilledOnDrop(
        Command::new(BIN)
            .args([
                "worker",
                "--database",
                db_url,
                "--workers",
                "1",
                "--lease-s",
                "1",
            ])
            .env("RUST_LOG", "warn")
            .stdout(Stdio::null())
            .spawn()
            .expect("start millsim worker"),
    )
}

/// Starts `millsim serve` against an existing database URL.
fn start_api(db_url: &str) -> Server {
    let mut child = Command::new(BIN)
        .args([
            "serve",
            "--bind",
            "127.0.0.1:0",
            "--database",
            db_url,
            "--workers",
            "0",
        ])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .spawn()
        .expect("start millsim serve");
    let mut line = String::new();
    std::io::BufRead::read_line(
        &mut std::io::BufReader::new(child.stdout.take().unwrap()),
        &mut line,
    )
    .unwrap();
    let base = line
        .trim()
        .strip_prefix("millsim listening on ")
        .unwrap_or_else(|| panic!("serve did not start: {line:?}"))
        .to_string();
    Server {
        child,
        base,
        db_url: db_url.to_string(),
    }
}

/// The pid inside a worker id (`host-PID-suffix-wN`).
fn pid_of(worker: &str) -> u32 {
    let (rest, _) = worker.rsplit_once("-w").unwrap();
    let (rest, _suffix) = rest.rsplit_once('-').unwrap();
    rest.rsplit_once('-').unwrap().1.parse().unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn processes_starting_together_migrate_once() {
    let Some(_) = require_postgres() else { return };
    let dir = tempfile::tempdir().unwrap();
    let url = db_url(&dir.path().join("fresh"));
    // Four processes on an empty database at the same moment: each waits for the
    // migration lock instead of applying the schema twice.
    let children: Vec<std::thread::JoinHandle<Server>> = (0..4)
        .map(|_| {
            let url = url.clone();
            std::thread::spawn(move || start_api(&url))
        })
        .collect();
    let servers: Vec<Server> = children.into_iter().map(|h| h.join().unwrap()).collect();
    let c = client();
    for s in &servers {
        let res = c.get(s.url("/readyz")).send().await.unwrap();
        assert_eq!(res.status(), 200);
    }
    let mut conn = sqlx::PgConnection::connect(&url).await.unwrap();
    let (applied,): (i64,) = sqlx::query_as("SELECT COUNT(*) FROM _sqlx_migrations")
        .fetch_one(&mut conn)
        .await
        .unwrap();
    let files = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/migrations/postgres"))
        .unwrap()
        .count();
    assert_eq!(applied as usize, files);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn four_workers_two_apis_two_killed_every_job_once() {
    let Some(_) = require_postgres() else { return };
    let dir = tempfile::tempdir().unwrap();
    let url = db_url(&dir.path().join("crash"));
    let apis = [start_api(&url), start_api(&url)];
    let c = client();

    // 400 jobs, alternately to each API; every tenth is sent to both with one key: the
    // second is a replay, not a second job.
    let mut ids = Vec::new();
    for i in 0..400 {
        let body = json!({"kind": "interpret", "inputs": {"program": {"name": "loop.ngc", "content": SHORT_LOOP}}});
        let api = &apis[i % 2];
        let key = format!("order-{i}");
        let res = c
            .post(api.url("/v1/jobs"))
            .header("idempotency-key", &key)
            .json(&body)
            .send()
            .await
            .unwrap();
        let (st, job) = json(res).await;
        assert_eq!(st, 202, "{job}");
        let id = job["id"].as_str().unwrap().to_string();
        if i % 10 == 0 {
            let other = &apis[(i + 1) % 2];
            let res = c
                .post(other.url("/v1/jobs"))
                .header("idempotency-key", &key)
                .json(&body)
                .send()
                .await
                .unwrap();
            let (_, replay) = json(res).await;
            assert_eq!(replay["id"], job["id"], "a replay made a second job");
        }
        ids.push(id);
    }

    // The queue depth is the database's: either API process counts every job queued.
    for api in &apis {
        let text = get_text(&c, api, "/metrics").await;
        assert!(text.contains("\nmillsim_queue_depth 400\n"), "{text}");
    }
    let mut workers: Vec<Worker> = (0..4).map(|_| start_worker(&url)).collect();

    // Kill two worker processes while each has an attempt open (mid-job), then restart one.
    let mut conn = sqlx::PgConnection::connect(&url).await.unwrap();
    let mut killed: Vec<(u32, String)> = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(60);
    while killed.len() < 2 {
        assert!(Instant::now() < deadline, "no worker was caught mid-job");
        let open: Vec<(String, String)> = sqlx::query_as(
            "SELECT worker, job_id FROM job_attempts WHERE outcome IS NULL ORDER BY started_at DESC",
        )
        .fetch_all(&mut conn)
        .await
        .unwrap();
        for (worker, job) in open {
            let pid = pid_of(&worker);
            if killed.iter().any(|(p, _)| *p == pid) {
                continue;
            }
            if let Some(w) = workers.iter_mut().find(|w| w.id() == pid) {
                w.kill().unwrap(); // SIGKILL
                w.wait().unwrap();
                killed.push((pid, job));
                break;
            }
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    workers.retain(|w| !killed.iter().any(|(p, _)| *p == w.id()));
    workers.push(start_worker(&url));

    for (n, id) in ids.iter().enumerate() {
        let job = wait_job(&c, &apis[n % 2], id, Duration::from_secs(300)).await;
        assert_eq!(job["status"], "succeeded", "{job}");
    }

    // No job doubled or lost.
    let (jobs,): (i64,) = sqlx::query_as("SELECT COUNT(*) FROM jobs")
        .fetch_one(&mut conn)
        .await
        .unwrap();
    assert_eq!(jobs, 400);
    // Every job succeeded exactly once, by the attempts log; every attempt but the
    // succeeded one was lost with a killed worker.
    type Attempt = (String, i64, String, i64, Option<i64>, Option<String>);
    let attempts: Vec<Attempt> = sqlx::query_as(
        "SELECT job_id, attempt, worker, started_at, finished_at, outcome FROM job_attempts ORDER BY job_id, attempt",
    )
    .fetch_all(&mut conn)
    .await
    .unwrap();
    let mut wins: HashMap<&str, usize> = HashMap::new();
    for (job, _, worker, _, finished, outcome) in &attempts {
        assert!(finished.is_some(), "an attempt was left open: {job}");
        match outcome.as_deref() {
            Some("succeeded") => *wins.entry(job).or_default() += 1,
            Some("lost") => assert!(
                killed.iter().any(|(p, _)| *p == pid_of(worker)),
                "an attempt of a live worker was lost: {job} {worker}"
            ),
            other => panic!("attempt of {job} ended {other:?}"),
        }
    }
    assert_eq!(wins.len(), 400);
    assert!(wins.values().all(|&n| n == 1), "a job succeeded twice");
    // The jobs caught mid-run were run again.
    for (_, job) in &killed {
        let n = attempts.iter().filter(|a| &a.0 == job).count();
        assert_eq!(n, 2, "job {job} caught mid-run shows {n} attempts");
    }
    // No worker ran two jobs at once, and no job ran on two workers at once: attempts
    // (claim to end) of one worker, and of one job, never overlap.
    let mut by_worker: BTreeMap<&str, Vec<(i64, i64)>> = BTreeMap::new();
    let mut by_job: BTreeMap<&str, Vec<(i64, i64)>> = BTreeMap::new();
    for (job, _, worker, started, finished, _) in &attempts {
        let span = (*started, finished.unwrap());
        by_worker.entry(worker).or_default().push(span);
        by_job.entry(job).or_default().push(span);
    }
    for (what, spans) in by_worker.iter().chain(by_job.iter()) {
        let mut spans = spans.clone();
        spans.sort();
        for w in spans.windows(2) {
            assert!(w[0].1 <= w[1].0, "{what} ran two attempts at once: {w:?}");
        }
    }
    // Every result row written once: the loop's 802 moves for every job. Rows are stored
    // in groups of consecutive seqs; a second commit of a job would add its groups again,
    // so the groups' row counts would add up to twice the seqs they span.
    let rows: Vec<(i64, i64, i64)> = sqlx::query_as(
        "SELECT SUM(last_seq - first_seq + 1)::BIGINT, MIN(first_seq), MAX(last_seq)
         FROM job_row_groups GROUP BY job_id",
    )
    .fetch_all(&mut conn)
    .await
    .unwrap();
    assert_eq!(rows.len(), 400);
    let first = rows[0].0;
    assert!(first > 800, "{first} rows");
    assert!(
        rows.iter()
            .all(|&(n, lo, hi)| n == first && lo == 0 && hi == first - 1),
        "rows lost or doubled: {rows:?}"
    );
    assert!(
        by_worker.len() >= 5,
        "the restarted worker took no work: {by_worker:?}"
    );
    for mut w in workers {
        common::unsafe_kill(w.id() as i32, 15);
        assert!(w.wait().unwrap().success());
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_submission_is_announced_and_wakes_an_idle_worker_on_another_process() {
    let Some(_) = require_postgres() else { return };
    let dir = tempfile::tempdir().unwrap();
    let url = db_url(&dir.path().join("notify"));
    let api = start_api(&url);
    let c = client();
    let mut listener = sqlx::postgres::PgListener::connect(&url).await.unwrap();
    listener
        .listen_all(["millsim_job_queued", "millsim_job_changed"])
        .await
        .unwrap();
    let body =
        json!({"kind": "interpret", "inputs": {"program": {"name": "a.nc", "content": "G0 X1\n"}}});
    let (st, job) = post_json(&c, &api, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap().to_string();
    // The trigger announces the new job to idle workers, at its commit; its changes are
    // announced only once an event stream follows it (a NOTIFY serializes commits).
    let n = tokio::time::timeout(Duration::from_secs(5), listener.recv())
        .await
        .expect("no notification within 5 s")
        .unwrap();
    assert_eq!((n.channel(), n.payload()), ("millsim_job_queued", ""));
    let quiet = tokio::time::timeout(Duration::from_millis(500), listener.recv()).await;
    assert!(
        quiet.is_err(),
        "an unfollowed job's change was announced: {quiet:?}"
    );
    // A stream follows it: its cancel is announced, and pushed to the stream at once
    // (the stream's fallback re-read is 5 s away).
    let mut stream = c
        .get(api.url(&format!("/v1/jobs/{id}/events")))
        .send()
        .await
        .unwrap();
    assert_eq!(stream.status(), 200);
    let first = stream.chunk().await.unwrap().unwrap();
    assert!(
        String::from_utf8_lossy(&first).contains("queued"),
        "{first:?}"
    );
    let asked = Instant::now();
    let res = c
        .post(api.url(&format!("/v1/jobs/{id}/cancel")))
        .send()
        .await
        .unwrap();
    assert!(res.status().is_success(), "{}", res.status());
    let n = tokio::time::timeout(Duration::from_secs(5), listener.recv())
        .await
        .expect("the followed job's change was not announced")
        .unwrap();
    assert_eq!(
        (n.channel(), n.payload()),
        ("millsim_job_changed", id.as_str())
    );
    let mut text = String::new();
    while !text.contains("cancelled") {
        let chunk = tokio::time::timeout(Duration::from_secs(10), stream.chunk())
            .await
            .expect("the stream did not report the cancel")
            .unwrap()
            .expect("the stream ended before the cancel");
        text.push_str(&String::from_utf8_lossy(&chunk));
    }
    assert!(
        asked.elapsed() < Duration::from_secs(2),
        "the cancel reached the stream after {:?} (not pushed)",
        asked.elapsed()
    );
    drop(stream);

    // An idle worker in another process starts each job at once: idle workers poll
    // every 250 ms, so polling alone would put the median near 125 ms.
    let mut worker = start_worker(&url);
    let mut waits = Vec::new();
    for _ in 0..15 {
        tokio::time::sleep(Duration::from_millis(100)).await;
        let (_, j) = post_json(&c, &api, "/v1/jobs", &body).await;
        let done = wait_job(&c, &api, j["id"].as_str().unwrap(), Duration::from_secs(30)).await;
        let ms = |k: &str| -> i64 {
            let t = done[k].as_str().unwrap();
            let secs: f64 = t[17..23].parse().unwrap();
            let mins: i64 = t[14..16].parse().unwrap();
            mins * 60_000 + (secs * 1000.0).round() as i64
        };
        waits.push((ms("started_at") - ms("created_at")).rem_euclid(3_600_000));
    }
    waits.sort();
    println!("submit -> running, ms: {waits:?}");
    assert!(
        waits[waits.len() / 2] < 60,
        "median {} ms: {waits:?}",
        waits[waits.len() / 2]
    );
    worker.kill().unwrap();
    worker.wait().unwrap();
}
