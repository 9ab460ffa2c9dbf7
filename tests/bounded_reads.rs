//! GETs of stored content hold a bounded part of the API process's memory whatever is
//! stored (issue 34): a resource's record is read without its content, and content over a
//! chunk is sent a chunk at a time, whether it is stored in chunks (programs and tool
//! libraries uploaded since) or whole in its row (before, and a job's inline program).

mod common;

use std::time::Instant;

use common::*;
use serde_json::json;

/// A G-code program of about `mb` MB that is cheap to read: lines of a long comment.
fn big_program(mb: usize) -> String {
    let line = format!("({})\n", "x".repeat(1022));
    let mut out = String::from("G21 G90\n");
    for _ in 0..mb * 1024 {
        out.push_str(&line);
    }
    out.push_str("G0 X1\nM30\n");
    out
}

/// Eight concurrent readers of each of a 24 MB program's record and content, stored in
/// chunks (an upload) and whole in its row (a job's inline program): the server's peak
/// grows by a few MB, and every reader gets the whole file. Before, every record GET read
/// the content with the row and every content GET held it whole: hundreds of MB.
#[tokio::test]
async fn concurrent_reads_of_a_large_program_stay_within_a_few_megabytes() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let pid = s.child.id();
    let c = client();
    let program = big_program(24);
    let uploaded = post_program(&c, &s, "big.nc", program.clone()).await;
    let (st, job) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "interpret", "inputs": {"program": {"name": "inline.nc", "content": program}}}),
    )
    .await;
    assert_eq!(st, 202, "{job}");
    let inline = job["inputs"]["program"].as_str().unwrap().to_string();
    assert_ne!(inline, uploaded);

    reset_peak_rss(pid);
    let rss = proc_kb(pid, "VmRSS");
    let clock = Instant::now();
    let mut reads = Vec::new();
    for id in [&uploaded, &inline] {
        for path in [
            format!("/v1/programs/{id}"),
            format!("/v1/programs/{id}/content"),
        ] {
            for _ in 0..8 {
                let (c, url) = (c.clone(), s.url(&path));
                reads.push(tokio::spawn(async move {
                    let res = c.get(url).send().await.unwrap();
                    let status = res.status().as_u16();
                    (status, res.bytes().await.unwrap())
                }));
            }
        }
    }
    for (k, read) in reads.into_iter().enumerate() {
        let (status, body) = read.await.unwrap();
        assert_eq!(status, 200);
        if k % 16 < 8 {
            let record: serde_json::Value = serde_json::from_slice(&body).unwrap();
            assert_eq!(record["size"], program.len(), "{record}");
        } else {
            assert!(
                body == program.as_bytes(),
                "content differs from the upload"
            );
        }
    }
    let secs = clock.elapsed().as_secs_f64();
    let peak_mb = proc_kb(pid, "VmHWM").saturating_sub(rss) as f64 / 1024.0;
    println!(
        "32 concurrent GETs of a {} MB program's record and content: {secs:.2} s, peak +{peak_mb:.1} MB",
        program.len() >> 20
    );
    assert!(
        peak_mb < 64.0,
        "the reads took the peak {peak_mb:.1} MB higher"
    );
    // Bounded time too: a reader is never held behind another's whole file.
    assert!(secs < 120.0, "{secs} s");
}

/// A program over a chunk is stored in chunks and a job reads it whole: an interpret job
/// on a 3 MB upload (three chunks and a part) and on the same program inline in the job
/// counts every move, and the content reads back byte for byte.
#[tokio::test]
async fn a_job_runs_on_a_program_stored_in_chunks() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let mut program = String::from("G21 G90 G0 X0 Y0 Z5\n");
    let moves = 300_000;
    for k in 0..moves {
        program.push_str(&format!("G1 X{} F500\n", k % 2));
    }
    program.push_str("M30\n");
    assert!(program.len() > 3 << 20, "{}", program.len());
    let id = post_program(&c, &s, "long.nc", program.clone()).await;
    let content = c
        .get(s.url(&format!("/v1/programs/{id}/content")))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    assert!(
        content == program.as_bytes(),
        "content differs from the upload"
    );
    let mut counted = Vec::new();
    for input in [json!(id), json!({"name": "inline.nc", "content": program})] {
        let job = run_job(
            &c,
            &s,
            &json!({"kind": "interpret", "inputs": {"program": input}}),
            std::time::Duration::from_secs(120),
        )
        .await;
        let summary = get_json(
            &c,
            &s,
            &format!("/v1/jobs/{}/summary", job["id"].as_str().unwrap()),
        )
        .await;
        counted.push(summary["moves"].as_u64().unwrap());
    }
    assert!(counted[0] >= moves, "{counted:?}");
    assert_eq!(counted[0], counted[1]);
}
