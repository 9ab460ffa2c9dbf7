//! Files a job produces are stored in chunks and streamed back: the exported stock of a
//! fine grid (several MiB, several chunks) downloads byte for byte as `millsim run`
//! writes it offline from the same inputs, and is stored as chunk rows, not one blob.

mod common;

use std::time::Duration;

use common::*;
use serde_json::json;

/// A ball-end raster over a ramp: a surface whose height changes from cell to cell, so
/// the exported stock has many triangles (about 4.5 MB at a 0.1 mm cell).
fn raster_program() -> String {
    let mut p = String::from("G21 G90 G17\nS10000 M3\nG0 Z5\nG0 X-10 Y-20\nG1 Z-1 F2000\n");
    for i in 0..58 {
        let y = -20.0 + 0.7 * f64::from(i);
        if i % 2 == 0 {
            p.push_str(&format!("G1 X110 Y{y:.3} Z-4 F4000\n"));
        } else {
            p.push_str(&format!("G1 X-10 Y{y:.3} Z-1 F4000\n"));
        }
        p.push_str(&format!("G1 Y{:.3}\n", y + 0.7));
    }
    p.push_str("G0 Z5\nM30\n");
    p
}

const BALL: &str =
    r#"{"type":"ball","diameter_mm":10.0,"flutes":2,"helix_deg":30.0,"flute_length_mm":20.0}"#;
const CELL: f64 = 0.1;

/// The stock.stl artifact's chunk count, and its chunk rows, in the server's database.
async fn stored_chunks(s: &Server, job: &str) -> (i64, i64, i64) {
    use sqlx::Connection;
    let q = "SELECT chunks, size, (SELECT COUNT(*) FROM job_artifact_chunks c WHERE c.job_id = a.job_id AND c.name = a.name)
             FROM job_artifacts a WHERE job_id = $1 AND name = 'stock.stl'";
    if s.db_url.starts_with("sqlite:") {
        let mut c = sqlx::SqliteConnection::connect(&s.db_url).await.unwrap();
        sqlx::query_as(q).bind(job).fetch_one(&mut c).await.unwrap()
    } else {
        let mut c = sqlx::PgConnection::connect(&s.db_url).await.unwrap();
        sqlx::query_as(q).bind(job).fetch_one(&mut c).await.unwrap()
    }
}

#[tokio::test]
async fn a_large_produced_stock_downloads_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let program = raster_program();
    let program_file = dir.path().join("raster.nc");
    std::fs::write(&program_file, &program).unwrap();
    let tool_file = dir.path().join("ball.json");
    std::fs::write(&tool_file, BALL).unwrap();

    // Offline: the file the engine writes for these inputs.
    let out = dir.path().join("offline");
    let run = std::process::Command::new(BIN)
        .args([
            "run",
            "--block",
            "0,-20,-10,100,40,10",
            "--material",
            "Al7075-T6",
        ])
        .arg("--program")
        .arg(&program_file)
        .arg("--tool")
        .arg(&tool_file)
        .args(["--resolution", &CELL.to_string()])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let expected = std::fs::read(out.join("stock.stl")).unwrap();
    assert!(
        expected.len() > 3 << 20,
        "the stock should span several chunks: {} bytes",
        expected.len()
    );

    // In a job process (the default) and on a worker thread: both write the stock to the
    // job's directory.
    for isolation in ["process", "thread"] {
        println!("job isolation {isolation}");
        let db = dir.path().join(format!("{isolation}.db"));
        let s = Server::start(&db, &["--workers", "1", "--job-isolation", isolation]);
        download_matches(&s, &program, &expected).await;
    }
}

/// Runs the raster job on `s`, downloads its stock and compares it with `expected`; checks
/// its rows in the database, and that deleting the job removes them.
async fn download_matches(s: &Server, program: &str, expected: &[u8]) {
    let c = client();
    let block = slot_block();
    let (st, stock) = post_json(&c, s, "/v1/stocks", &block).await;
    assert_eq!(st, 201, "{stock}");
    let (st, tool) = post_json(&c, s, "/v1/tools", &serde_json::from_str(BALL).unwrap()).await;
    assert_eq!(st, 201, "{tool}");
    let prog = post_program(&c, s, "raster.nc", program.to_string()).await;
    let body = json!({"kind": "simulate",
        "inputs": {"program": prog, "stock": stock["id"], "tool": tool["id"]},
        "options": {"material": "Al7075-T6", "cell_mm": CELL}});
    let done = run_job(&c, s, &body, Duration::from_secs(300)).await;
    let id = done["id"].as_str().unwrap();

    let res = c
        .get(s.url(&format!("/v1/jobs/{id}/stock.stl")))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    assert_eq!(
        res.headers()["content-length"].to_str().unwrap(),
        expected.len().to_string()
    );
    assert!(res.headers()["content-disposition"]
        .to_str()
        .unwrap()
        .contains("raster.stock.stl"));
    let got = res.bytes().await.unwrap();
    assert_eq!(got.len(), expected.len());
    assert!(
        got[..] == expected[..],
        "the download differs from the file"
    );

    let (chunks, size, rows) = stored_chunks(s, id).await;
    assert_eq!(size as usize, expected.len());
    assert_eq!(chunks as usize, expected.len().div_ceil(1 << 20));
    assert_eq!(rows, chunks, "one row per chunk");

    // Deleting the job removes its chunks.
    let res = c
        .delete(s.url(&format!("/v1/jobs/{id}")))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 204);
    let left = {
        use sqlx::Connection;
        let q = "SELECT COUNT(*) FROM job_artifact_chunks";
        if s.db_url.starts_with("sqlite:") {
            let mut c = sqlx::SqliteConnection::connect(&s.db_url).await.unwrap();
            sqlx::query_scalar::<_, i64>(q)
                .fetch_one(&mut c)
                .await
                .unwrap()
        } else {
            let mut c = sqlx::PgConnection::connect(&s.db_url).await.unwrap();
            sqlx::query_scalar::<_, i64>(q)
                .fetch_one(&mut c)
                .await
                .unwrap()
        }
    };
    assert_eq!(left, 0);
}
