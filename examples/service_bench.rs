//! Service benchmark: job pickup latency, GET /v1/jobs/{id} under 64 concurrent clients,
//! and streaming 100,000 per-block CSV rows. Starts its own server (release build
//! recommended) on 127.0.0.1 with a temporary SQLite file; loopback only, bounded runs.
//!
//!     cargo run --release --example service_bench
//!
//! Prints one line per figure.

use std::time::{Duration, Instant};

use serde_json::{json, Value};

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() as f64 - 1.0) * p).round() as usize]
}

/// The JSON answer to a request.
async fn answer(request: reqwest::RequestBuilder) -> Value {
    request.send().await.unwrap().json().await.unwrap()
}

/// Submits an interpret job of `program` (inline, or a stored program's id); its id.
async fn submit_interpret(c: &reqwest::Client, base: &str, program: &Value) -> String {
    let job = answer(
        c.post(format!("{base}/v1/jobs"))
            .json(&json!({"kind": "interpret", "inputs": {"program": program}})),
    )
    .await;
    job["id"].as_str().expect("job submitted").to_string()
}

/// Polls job `id` every `poll` until it has succeeded; its state then.
async fn wait_succeeded(c: &reqwest::Client, base: &str, id: &str, poll: Duration) -> Value {
    loop {
        let job = answer(c.get(format!("{base}/v1/jobs/{id}"))).await;
        match job["status"].as_str() {
            Some("succeeded") => return job,
            Some("queued" | "running") => tokio::time::sleep(poll).await,
            _ => panic!("job {id} did not succeed: {job}"),
        }
    }
}

#[tokio::main]
async fn main() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("bench.db");
    let db_url = format!("sqlite://{}", db.display());
    let bin = std::env::var("MILLSIM_BIN").unwrap_or_else(|_| "target/release/millsim".into());
    let mut child = std::process::Command::new(&bin)
        .args([
            "serve",
            "--bind",
            "127.0.0.1:0",
            "--database",
            &db_url,
            "--workers",
            "2",
        ])
        .env("RUST_LOG", "warn")
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("start {bin}: {e} (build it with cargo build --release)"));
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
    let c = reqwest::Client::new();

    // 1. Pickup latency with the queue idle: one job at a time, submit -> running, from the
    // server's own timestamps (created_at at insert, started_at at claim; ms resolution),
    // and as the client sees it (submit returns -> first poll that is not queued).
    let program =
        json!({"name": "one.nc", "content": "G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F100\nG1 X10\nM30\n"});
    let mut server_ms = Vec::new();
    for _ in 0..200 {
        let id = submit_interpret(&c, &base, &program).await;
        let done = wait_succeeded(&c, &base, &id, Duration::from_millis(2)).await;
        let t = |k: &str| {
            let s = done[k].as_str().unwrap();
            // ...THH:MM:SS.mmmZ -> seconds of the day, enough for a difference.
            let hms = &s[11..23];
            let (h, m, sec) = (&hms[0..2], &hms[3..5], &hms[6..]);
            h.parse::<f64>().unwrap() * 3600.0
                + m.parse::<f64>().unwrap() * 60.0
                + sec.parse::<f64>().unwrap()
        };
        server_ms.push((t("started_at") - t("created_at")) * 1000.0);
    }
    server_ms.sort_by(f64::total_cmp);
    println!(
        "pickup latency (submit -> running, queue idle, 200 jobs): median {:.1} ms, p99 {:.1} ms, max {:.1} ms",
        percentile(&server_ms, 0.5),
        percentile(&server_ms, 0.99),
        server_ms.last().unwrap()
    );

    // 2. GET /v1/jobs/{id} with 64 concurrent clients for 10 s.
    let id = {
        let (_, page): (u16, Value) = (
            0,
            c.get(format!("{base}/v1/jobs?limit=1"))
                .send()
                .await
                .unwrap()
                .json()
                .await
                .unwrap(),
        );
        page["items"][0]["id"].as_str().unwrap().to_string()
    };
    let url = format!("{base}/v1/jobs/{id}");
    let run_for = Duration::from_secs(10);
    let start = Instant::now();
    let mut tasks = Vec::new();
    for _ in 0..64 {
        let (c, url) = (reqwest::Client::new(), url.clone());
        tasks.push(tokio::spawn(async move {
            let mut lat = Vec::new();
            while start.elapsed() < run_for {
                let t = Instant::now();
                let res = c.get(&url).send().await.unwrap();
                assert_eq!(res.status(), 200);
                res.bytes().await.unwrap();
                lat.push(t.elapsed().as_secs_f64() * 1000.0);
            }
            lat
        }));
    }
    let mut lat = Vec::new();
    for t in tasks {
        lat.extend(t.await.unwrap());
    }
    let secs = start.elapsed().as_secs_f64();
    lat.sort_by(f64::total_cmp);
    println!(
        "GET /v1/jobs/{{id}}, 64 concurrent clients, {secs:.1} s: {:.0} requests/s, median {:.2} ms, p99 {:.2} ms",
        lat.len() as f64 / secs,
        percentile(&lat, 0.5),
        percentile(&lat, 0.99)
    );

    // 3. Stream 100,000 per-block CSV rows: a real interpret job of 100,000 moves (a row
    // each) makes them, and they are stored as every job's are (grouped and compressed).
    let mut text = String::from("G21 G90 G1 F1200 X0.5\n");
    for i in 0..99_999 {
        text.push_str(&format!(
            "X{:.3} Y{:.3}\n",
            1.0 + (i % 1000) as f64 * 0.01,
            (i / 1000) as f64 * 0.1
        ));
    }
    text.push_str("M30\n");
    let program = answer(
        c.post(format!("{base}/v1/programs?name=100k.nc"))
            .header("content-type", "text/plain")
            .body(text),
    )
    .await;
    let seeded = submit_interpret(&c, &base, &program["id"]).await;
    wait_succeeded(&c, &base, &seeded, Duration::from_millis(50)).await;
    // First run right after the job (cold cache, WAL not yet checkpointed), then warm.
    for run in ["cold", "warm"] {
        let t = Instant::now();
        let body = c
            .get(format!("{base}/v1/jobs/{seeded}/blocks?format=csv"))
            .send()
            .await
            .unwrap()
            .bytes()
            .await
            .unwrap();
        let elapsed = t.elapsed().as_secs_f64();
        let lines = body.iter().filter(|&&b| b == b'\n').count();
        assert_eq!(lines, 100_001, "header + 100,000 rows, got {lines} lines");
        println!(
            "CSV stream of 100,000 rows ({run}): {elapsed:.3} s ({:.0} rows/s, {:.1} MB)",
            100_000.0 / elapsed,
            body.len() as f64 / 1e6
        );
    }
    let _ = child.kill();
    let _ = child.wait();
}
