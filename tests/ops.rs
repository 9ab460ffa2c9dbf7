//! Operations: health, readiness, metrics, request logs, API keys.

mod common;

use std::io::Read;
use std::process::{Command, Stdio};

use common::*;

#[tokio::test]
async fn health_readiness_and_metrics() {
    if !corpus_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    assert_eq!(c.get(s.url("/healthz")).send().await.unwrap().status(), 200);
    let (st, v) = json(c.get(s.url("/readyz")).send().await.unwrap()).await;
    assert_eq!((st, v["status"].as_str()), (200, Some("ready")));
    let _ = submit_interpret(
        &c,
        &s,
        &upload_program(&c, &s, &corpus("gcode/fanuc_R_arcs_G3R_G1R_G1C.nc")).await,
    )
    .await;
    let text = get_text(&c, &s, "/metrics").await;
    assert!(text.contains("millsim_jobs{status=\"queued\"} 1"), "{text}");
    assert!(text.contains("millsim_queue_depth 1"), "{text}");
    assert!(
        text.contains(
            "millsim_http_requests_total{method=\"POST\",route=\"/v1/jobs\",status=\"202\"} 1"
        ),
        "{text}"
    );
    assert!(
        text.contains("millsim_http_request_duration_seconds_count"),
        "{text}"
    );
}

#[tokio::test]
async fn json_logs_carry_the_request_id() {
    let dir = tempfile::tempdir().unwrap();
    let db = db_url(&dir.path().join("t.db"));
    let mut child = Command::new(BIN)
        .args([
            "serve",
            "--bind",
            "127.0.0.1:0",
            "--database",
            &db,
            "--workers",
            "0",
            "--log-format",
            "json",
        ])
        .env("RUST_LOG", "info")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufRead::read_line(
        &mut std::io::BufReader::new(child.stdout.take().unwrap()),
        &mut line,
    )
    .unwrap();
    let base = line
        .trim()
        .strip_prefix("millsim listening on ")
        .unwrap()
        .to_string();
    let res = client()
        .get(format!("{base}/v1/tools"))
        .header("x-request-id", "req-abc-123")
        .send()
        .await
        .unwrap();
    assert_eq!(
        res.headers()["x-request-id"],
        "req-abc-123",
        "the request id is echoed"
    );
    unsafe_kill(child.id() as i32, 15);
    child.wait().unwrap();
    let mut logs = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut logs)
        .unwrap();
    let lines: Vec<serde_json::Value> = logs
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|_| panic!("not JSON: {l}")))
        .collect();
    assert!(
        lines
            .iter()
            .any(|l| l["span"]["request_id"] == "req-abc-123"
                && l["fields"]["status"].as_u64() == Some(200)),
        "{logs}"
    );
}

#[tokio::test]
async fn api_keys_separate_owners_and_guard_non_loopback_binds() {
    let dir = tempfile::tempdir().unwrap();
    // Two keys, made by the CLI.
    let mut file = String::new();
    let mut keys = Vec::new();
    for name in ["cam", "mes"] {
        let out = Command::new(BIN).args(["api-key", name]).output().unwrap();
        let text = String::from_utf8(out.stdout).unwrap();
        keys.push(
            text.lines()
                .next()
                .unwrap()
                .strip_prefix("key: ")
                .unwrap()
                .to_string(),
        );
        file.push_str(
            text.lines()
                .nth(1)
                .unwrap()
                .strip_prefix("key file line: ")
                .unwrap(),
        );
        file.push('\n');
    }
    assert!(
        !file.contains(&keys[0]),
        "the key file holds hashes, not keys"
    );
    let key_file = dir.path().join("keys");
    std::fs::write(&key_file, &file).unwrap();
    let s = Server::start(
        &dir.path().join("t.db"),
        &[
            "--workers",
            "0",
            "--api-key-file",
            key_file.to_str().unwrap(),
        ],
    );
    let c = client();
    let (st, p) = json(c.get(s.url("/v1/programs")).send().await.unwrap()).await;
    assert_eq!((st, p["status"].as_u64()), (401, Some(401)));
    let (st, _) = json(
        c.get(s.url("/v1/programs"))
            .bearer_auth("wrong")
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 401);
    assert_eq!(
        c.get(s.url("/healthz")).send().await.unwrap().status(),
        200,
        "health needs no key"
    );
    let (st, prog) = json(
        c.post(s.url("/v1/programs?name=a.nc"))
            .bearer_auth(&keys[0])
            .body("G0 X1\n")
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 201);
    let id = prog["id"].as_str().unwrap();
    let (st, _) = json(
        c.get(s.url(&format!("/v1/programs/{id}")))
            .header("x-api-key", &keys[0])
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 200);
    // The other key sees nothing of it.
    let (st, _) = json(
        c.get(s.url(&format!("/v1/programs/{id}")))
            .bearer_auth(&keys[1])
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 404);
    let (_, list) = json(
        c.get(s.url("/v1/programs"))
            .bearer_auth(&keys[1])
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(list["items"].as_array().unwrap().len(), 0);
    let (st, _) = json(
        c.post(s.url("/v1/jobs"))
            .bearer_auth(&keys[1])
            .json(&serde_json::json!({"kind": "interpret", "inputs": {"program": id}}))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 422, "another owner's program is not an input");

    // A non-loopback bind without keys is refused before it listens.
    let out = Command::new(BIN)
        .args([
            "serve",
            "--bind",
            "0.0.0.0:0",
            "--database",
            &format!("sqlite://{}", dir.path().join("u.db").display()),
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--api-key-file"));
}
