//! `scripts/scale-out.sh`, the README's way to run what docker-compose.yml runs without
//! Docker: one API and N worker processes on one PostgreSQL database. The script as a user
//! runs it starts them, its API takes jobs its workers run, `/metrics` lists every worker,
//! and SIGTERM to the script stops every process it started. Skipped, saying so, without
//! MILLSIM_TEST_DATABASE=postgres://...

mod common;

use std::io::BufRead;
use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use serde_json::json;

/// The script's process group, killed whatever way the test ends.
struct Script(Child);

impl Drop for Script {
    fn drop(&mut self) {
        if let Ok(None) = self.0.try_wait() {
            // `kill -9 -PGID` kills nothing with procps-ng's kill: the group goes after `--`.
            let _ = Command::new("kill")
                .args(["-s", "KILL", "--", &format!("-{}", self.0.id())])
                .status();
            let _ = self.0.wait();
        }
    }
}

fn alive(pid: i32) -> bool {
    std::path::Path::new(&format!("/proc/{pid}")).exists()
        && !std::fs::read_to_string(format!("/proc/{pid}/stat"))
            .map(|s| s.split_whitespace().nth(2) == Some("Z"))
            .unwrap_or(true)
}

#[tokio::test]
async fn the_scale_out_script_runs_an_api_and_workers_and_stops_them_all() {
    let Some(_) = require_postgres() else { return };
    let dir = tempfile::tempdir().unwrap();
    let db = db_url(&dir.path().join("scale-out-script"));
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/scale-out.sh");
    let mut child = Command::new("bash")
        .args([script, &db, "3", &format!("127.0.0.1:{port}")])
        .env("MILLSIM_BIN", BIN)
        .env("MILLSIM_WORKERS", "1")
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .expect("start scripts/scale-out.sh");
    let stderr = child.stderr.take().unwrap();
    let script = Script(child);
    // "scale-out: API on http://ADDR (pid P), N worker processes (pids P1 P2 ...)"
    let mut lines = std::io::BufReader::new(stderr).lines();
    let started = lines
        .by_ref()
        .map_while(Result::ok)
        .find(|l| l.starts_with("scale-out:"))
        .expect("the script says what it started");
    std::thread::spawn(move || lines.for_each(drop)); // keep the pipe drained
    let inside = |open: &str| -> Vec<i32> {
        let from = started.find(open).expect(open) + open.len();
        let to = from + started[from..].find(')').unwrap();
        started[from..to]
            .split_whitespace()
            .map(|p| p.parse().unwrap())
            .collect()
    };
    let mut pids = inside("(pid ");
    pids.extend(inside("(pids "));
    assert_eq!(pids.len(), 4, "one API and 3 workers: {started}");

    let base = format!("http://127.0.0.1:{port}");
    let c = client();
    let deadline = Instant::now() + Duration::from_secs(60);
    while c
        .get(format!("{base}/readyz"))
        .send()
        .await
        .map(|r| r.status().as_u16())
        .ok()
        != Some(200)
    {
        assert!(Instant::now() < deadline, "the API did not become ready");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let mut ids = Vec::new();
    for i in 0..6 {
        let body = json!({"kind": "interpret", "inputs": {"program": {"name": "p.nc", "content": format!("G21 G90 G1 F100 X{i}\nY1\nM30\n")}}});
        let res = c
            .post(format!("{base}/v1/jobs"))
            .json(&body)
            .send()
            .await
            .unwrap();
        let (status, job) = json(res).await;
        assert_eq!(status, 202, "{job}");
        ids.push(job["id"].as_str().unwrap().to_string());
    }
    let deadline = Instant::now() + Duration::from_secs(60);
    for id in &ids {
        loop {
            let (_, job) = json(c.get(format!("{base}/v1/jobs/{id}")).send().await.unwrap()).await;
            match job["status"].as_str() {
                Some("succeeded") => break,
                Some("queued" | "running") if Instant::now() < deadline => {
                    tokio::time::sleep(Duration::from_millis(50)).await
                }
                _ => panic!("job {id} did not succeed: {job}"),
            }
        }
    }
    // Every worker process reports its worker: three, on the API's /metrics.
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let metrics = c
            .get(format!("{base}/metrics"))
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        if metrics.lines().any(|l| l == "millsim_workers 3") {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "not 3 workers in /metrics:\n{metrics}"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }

    // SIGTERM to the script stops every process it started, gracefully.
    let mut script = script;
    unsafe_kill(script.0.id() as i32, 15);
    let deadline = Instant::now() + Duration::from_secs(40);
    while script.0.try_wait().unwrap().is_none() {
        assert!(Instant::now() < deadline, "the script did not stop");
        std::thread::sleep(Duration::from_millis(50));
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    while pids.iter().any(|&p| alive(p)) {
        assert!(
            Instant::now() < deadline,
            "processes left running: {:?}",
            pids.iter().filter(|&&p| alive(p)).collect::<Vec<_>>()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}
