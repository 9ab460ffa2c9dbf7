//! Large STL uploads are streamed: checked as they are read and stored in chunks. A bad
//! upload (truncated, over the limit, open, not finite) gets its problem document and
//! leaves no rows; a good one of several chunks comes back byte for byte and a worker
//! runs a job on it.

mod common;

use std::time::Duration;

use common::*;
use serde_json::json;

/// A binary STL of the box `lo`..`hi` whose faces are each cut into `n` × `n` quads
/// (12 n² triangles, outward normals); vertices are computed once per grid index, so
/// faces meeting at an edge share them exactly.
fn subdivided_box(lo: [f64; 3], hi: [f64; 3], n: usize) -> Vec<u8> {
    let c = |a: usize, i: usize| (lo[a] + (hi[a] - lo[a]) * i as f64 / n as f64) as f32;
    let mut tris: Vec<[[f32; 3]; 3]> = Vec::new();
    for a in 0..3 {
        let (u, v) = ((a + 1) % 3, (a + 2) % 3);
        for high in [false, true] {
            let k = if high { n } else { 0 };
            let p = |i: usize, j: usize| {
                let mut q = [0f32; 3];
                q[a] = c(a, k);
                q[u] = c(u, i);
                q[v] = c(v, j);
                q
            };
            for i in 0..n {
                for j in 0..n {
                    let (p00, p10, p11, p01) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
                    if high {
                        tris.push([p00, p10, p11]);
                        tris.push([p00, p11, p01]);
                    } else {
                        tris.push([p00, p11, p10]);
                        tris.push([p00, p01, p11]);
                    }
                }
            }
        }
    }
    let mut out = vec![b' '; 80];
    out.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    for t in &tris {
        out.extend_from_slice(&[0u8; 12]);
        for v in t {
            for x in v {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
        out.extend_from_slice(&[0u8; 2]);
    }
    out
}

/// Rows in `resources` and `resource_chunks` of the server's database.
async fn row_counts(s: &Server) -> (i64, i64) {
    use sqlx::Connection;
    let q = "SELECT (SELECT COUNT(*) FROM resources), (SELECT COUNT(*) FROM resource_chunks)";
    if s.db_url.starts_with("sqlite:") {
        let mut c = sqlx::SqliteConnection::connect(&s.db_url).await.unwrap();
        sqlx::query_as(q).fetch_one(&mut c).await.unwrap()
    } else {
        let mut c = sqlx::PgConnection::connect(&s.db_url).await.unwrap();
        sqlx::query_as(q).fetch_one(&mut c).await.unwrap()
    }
}

const LIMIT: u64 = 8 << 20;

#[tokio::test]
async fn bad_streamed_uploads_are_problems_and_leave_no_rows() {
    let dir = tempfile::tempdir().unwrap();
    let limit = LIMIT.to_string();
    let s = Server::start(
        &dir.path().join("t.db"),
        &[
            "--workers",
            "0",
            "--max-upload-bytes",
            &limit,
            "--job-memory-mb",
            "110",
        ],
    );
    let c = client();
    let good = subdivided_box([0.0, -20.0, -10.0], [100.0, 20.0, 0.0], 80);
    assert!(good.len() > 3 << 20, "several chunks: {}", good.len());
    let before = row_counts(&s).await;

    // Truncated: the last record cut short.
    let cut = good[..good.len() - 25].to_vec();
    let (st, p) = post_stl(&c, &s, "/v1/stocks?name=cut.stl", cut).await;
    assert_eq!(st, 422, "{p}");
    let detail = p["detail"].as_str().unwrap();
    assert!(
        detail.contains("cut.stl") && detail.contains("truncated"),
        "{p}"
    );

    // Over the limit, with and without a Content-Length (chunked transfer).
    let mut big = good.clone();
    big.resize(LIMIT as usize + 1, 0);
    // A Content-Length over the limit is refused before any of the body is read.
    {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let addr = s.base.trim_start_matches("http://").to_string();
        let mut tcp = tokio::net::TcpStream::connect(&addr).await.unwrap();
        let head = format!(
            "POST /v1/stocks HTTP/1.1\r\nHost: {addr}\r\nContent-Type: model/stl\r\nContent-Length: {}\r\n\r\n",
            big.len()
        );
        tcp.write_all(head.as_bytes()).await.unwrap();
        let mut answer = vec![0u8; 4096];
        let n = tokio::time::timeout(Duration::from_secs(10), tcp.read(&mut answer))
            .await
            .expect("an answer before the body")
            .unwrap();
        let answer = String::from_utf8_lossy(&answer[..n]);
        assert!(answer.starts_with("HTTP/1.1 413"), "{answer}");
    }
    // The server may answer and close before the whole body is sent.
    if let Some((st, p)) = post_stl_chunked(&c, &s, &big).await {
        assert_eq!(st, 413, "{p}");
    }

    // Open: the last triangle left out (and the count made to agree).
    let mut open = good[..good.len() - 50].to_vec();
    let n = u32::from_le_bytes(open[80..84].try_into().unwrap()) - 1;
    open[80..84].copy_from_slice(&n.to_le_bytes());
    let (st, p) = post_stl(&c, &s, "/v1/stocks?name=open.stl", open).await;
    assert_eq!(st, 422, "{p}");
    assert!(p["detail"].as_str().unwrap().contains("not closed"), "{p}");

    // A coordinate that is not a number, deep in the file.
    let mut nan = good.clone();
    let at = 84 + 50 * 70_000 + 12 + 4;
    nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let (st, p) = post_stl(&c, &s, "/v1/stocks?name=nan.stl", nan).await;
    assert_eq!(st, 422, "{p}");
    assert!(
        p["detail"].as_str().unwrap().contains("triangle 70000"),
        "{p}"
    );

    // ASCII that breaks off: the line is named.
    let ascii = "solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 zero 0\n";
    let (st, p) = post_stl(&c, &s, "/v1/stocks?name=a.stl", ascii.into()).await;
    assert_eq!(st, 422, "{p}");
    assert!(p["detail"].as_str().unwrap().contains("line 5"), "{p}");

    assert_eq!(row_counts(&s).await, before, "a refused upload left rows");

    // The job's memory estimate counts reading the mesh: 76,800 triangles at about
    // 400 B each (31 MB) put a slot in this box over a 110 MB budget that its grid
    // (a few MB at 0.5 mm) and the fixed 96 MB fit in.
    let (st, v) = post_stl(&c, &s, "/v1/stocks?name=box.stl", good).await;
    assert_eq!(st, 201, "{v}");
    let tool = post_slot_tool(&c, &s).await;
    let prog = post_program(
        &c,
        &s,
        "slot.nc",
        "G0 X-10 Y0 Z-5\nG1 X60 F4000 S10000 M3\nM30\n",
    )
    .await;
    let body = json!({"kind": "simulate", "inputs": {"program": prog, "stock": v["id"], "tool": tool},
                      "options": {"material": "Al7075-T6", "cell_mm": 0.5}});
    let (st, p) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 422, "{p}");
    let mesh_mb = p["estimate"]["mesh_bytes"].as_u64().unwrap() >> 20;
    assert_eq!(mesh_mb, (12 * 80 * 80 * 400) >> 20, "{p}");
    assert!(
        p["detail"].as_str().unwrap().contains("STL mesh read"),
        "{p}"
    );
}

#[tokio::test]
async fn a_large_upload_round_trips_and_a_worker_simulates_on_it() {
    let dir = tempfile::tempdir().unwrap();
    let limit = LIMIT.to_string();
    let s = Server::start(
        &dir.path().join("t.db"),
        &["--workers", "1", "--max-upload-bytes", &limit],
    );
    let c = client();
    let stl = subdivided_box([0.0, -20.0, -10.0], [100.0, 20.0, 0.0], 80);
    let (st, v) = post_stl(&c, &s, "/v1/stocks?name=box.stl", stl.clone()).await;
    assert_eq!(st, 201, "{v}");
    assert_eq!(v["size"], stl.len());
    assert_eq!(v["summary"]["triangles"], 12 * 80 * 80);
    let volume = v["summary"]["volume_mm3"].as_f64().unwrap();
    assert!((volume - 40_000.0).abs() < 1e-6 * 40_000.0, "{volume}");
    let stock = v["id"].as_str().unwrap().to_string();
    let res = c
        .get(s.url(&format!("/v1/stocks/{stock}/content")))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    assert_eq!(
        res.headers()["content-length"],
        stl.len().to_string().as_str()
    );
    let back = res.bytes().await.unwrap();
    assert!(back.as_ref() == stl.as_slice(), "the content differs");
    let (_, chunks) = row_counts(&s).await;
    assert_eq!(chunks as usize, stl.len().div_ceil(1 << 20));

    // A worker loads it and cuts a 5 mm deep, 10 mm wide slot 60 mm long into it.
    let tool = post_slot_tool(&c, &s).await;
    let program = "G21 G90 G17\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X60 F4000\nG0 Z5\nM30\n";
    let prog = post_program(&c, &s, "slot.nc", program).await;
    let body = json!({"kind": "simulate", "inputs": {"program": prog, "stock": stock, "tool": tool},
                      "options": {"material": "Al7075-T6", "cell_mm": 0.5}});
    let done = run_job(&c, &s, &body, Duration::from_secs(120)).await;
    let removed = done["summary"]["removed_volume_mm3"].as_f64().unwrap();
    let analytic = 5.0 * (60.0 * 10.0 + std::f64::consts::PI * 25.0 / 2.0);
    assert!(
        (removed - analytic).abs() / analytic < 0.03,
        "{removed} vs {analytic}"
    );
}

/// An upload that would leave less than the reserve free in the temporary directory is
/// refused 507 before it is spooled (its Content-Length known, or not), naming what is
/// short, and stores nothing; the JSON and program routes, held in memory, are not held
/// to it.
#[tokio::test]
async fn an_upload_the_disk_cannot_spare_is_refused_507() {
    let dir = tempfile::tempdir().unwrap();
    // A reserve of a petabyte: more than any disk here has free.
    let s = Server::start(
        &dir.path().join("t.db"),
        &["--workers", "0", "--upload-disk-reserve-mb", "1000000000"],
    );
    let c = client();
    let stl = subdivided_box([0.0, -20.0, -10.0], [100.0, 20.0, 0.0], 20);
    let before = row_counts(&s).await;
    let check = |st: u16, p: &serde_json::Value| {
        assert_eq!(st, 507, "{p}");
        assert_eq!(
            p["type"],
            "https://millsim.dev/problems/insufficient-storage"
        );
        assert_eq!(p["field"], "file", "{p}");
        assert_eq!(p["limit_name"], "upload_disk_reserve_mb", "{p}");
        assert_eq!(p["reserve_bytes"], 1_000_000_000u64 << 20, "{p}");
        assert!(p["free_bytes"].as_u64().unwrap() > 0, "{p}");
        assert!(
            p["detail"]
                .as_str()
                .unwrap()
                .contains("upload_disk_reserve_mb"),
            "{p}"
        );
    };
    // With a Content-Length: the upload's size is counted.
    let (st, p) = post_stl(&c, &s, "/v1/stocks?name=box.stl", stl.clone()).await;
    check(st, &p);
    assert_eq!(p["needed_bytes"], stl.len(), "{p}");
    // Without one (chunked transfer).
    if let Some((st, p)) = post_stl_chunked(&c, &s, &stl).await {
        check(st, &p);
    }
    // A multipart form. The server answers 507 before the body is read, and may close the
    // connection while the client still writes it: a send that fails so (a broken pipe) is
    // tried again, a few times, as a client would.
    let mut answered = None;
    for _ in 0..5 {
        let form = reqwest::multipart::Form::new().part(
            "file",
            reqwest::multipart::Part::bytes(stl.clone()).file_name("box.stl".to_string()),
        );
        if let Ok(res) = c.post(s.url("/v1/stocks")).multipart(form).send().await {
            answered = Some(json(res).await);
            break;
        }
    }
    match answered {
        Some((st, p)) => check(st, &p),
        None => {
            println!("SKIPPED: the multipart case: every send hit the early close (broken pipe)")
        }
    }
    assert_eq!(row_counts(&s).await, before, "a refused upload left rows");

    // A parametric stock is no upload to spool.
    let block = slot_block();
    let (st, v) = post_json(&c, &s, "/v1/stocks", &block).await;
    assert_eq!(st, 201, "{v}");
}
