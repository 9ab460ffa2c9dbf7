//! Jobs over HTTP: submission, idempotency, cancellation, progress events, results.

mod common;

use std::time::Duration;

use common::*;
use serde_json::{json, Value};

#[tokio::test]
async fn interpret_job_runs_and_serves_its_rows_as_json_pages_and_csv() {
    if !corpus_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let program = upload_program(
        &c,
        &s,
        &corpus("gcode/fusion360_2d_pocket_contour_bore_1099.nc"),
    )
    .await;
    let res = c
        .post(s.url("/v1/jobs"))
        .json(&json!({"kind": "interpret", "inputs": {"program": program}}))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 202);
    let location = res.headers()["location"].to_str().unwrap().to_string();
    let (_, job) = json(res).await;
    assert_eq!(
        location,
        format!("/v1/jobs/{}", job["id"].as_str().unwrap())
    );
    assert_eq!(job["status"], "queued");
    let id = job["id"].as_str().unwrap();
    let done = wait_job(&c, &s, id, Duration::from_secs(60)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["attempts"], 1);
    let moves = done["summary"]["moves"].as_u64().unwrap();
    assert!(moves > 1000);
    assert_eq!(done["progress"]["done"].as_u64(), Some(moves));

    // JSON pages: walk every page; the rows are the engine's moves in order.
    let mut rows = Vec::new();
    let mut cursor: Option<String> = None;
    loop {
        let q = cursor
            .as_ref()
            .map(|c| format!("&cursor={c}"))
            .unwrap_or_default();
        let (st, page) = json(
            c.get(s.url(&format!("/v1/jobs/{id}/blocks?limit=1000{q}")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        assert_eq!(st, 200);
        rows.extend(page["items"].as_array().unwrap().iter().cloned());
        match page["next_cursor"].as_str() {
            Some(n) => cursor = Some(n.to_string()),
            None => break,
        }
    }
    assert_eq!(rows.len() as u64, moves);
    assert!(rows
        .iter()
        .any(|r| r["kind"] == "arc" && r["center"].is_array()));
    // Every row has every column: a straight move's centre is there, null.
    let columns = done["summary"]["row_columns"].as_array().unwrap();
    for r in &rows {
        for c in columns {
            let c = c.as_str().unwrap();
            assert!(r.get(c).is_some(), "row {r} lacks {c}");
        }
    }
    assert!(rows
        .iter()
        .any(|r| r["kind"] == "linear" && r.get("center") == Some(&Value::Null)));
    assert!(rows
        .windows(2)
        .all(|w| w[0]["line"].as_u64() <= w[1]["line"].as_u64()));

    // CSV: a header, then one line per move, arcs with their centre columns.
    let res = c
        .get(s.url(&format!("/v1/jobs/{id}/blocks?format=csv")))
        .send()
        .await
        .unwrap();
    assert_eq!(res.headers()["content-type"], "text/csv; charset=utf-8");
    let csv = res.text().await.unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    for col in [
        "block",
        "line",
        "kind",
        "end_x",
        "end_c",
        "feed",
        "center_x",
        "clockwise",
    ] {
        assert!(header.contains(&col), "{col} missing from {header:?}");
    }
    let body: Vec<&str> = lines.collect();
    assert_eq!(body.len() as u64, moves);
    assert!(body.iter().all(|l| l.split(',').count() == header.len()));

    // Results this kind does not produce are a clear 404.
    let (st, p) = json(
        c.get(s.url(&format!("/v1/jobs/{id}/program")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 404, "{p}");
    let (st, _) = json(
        c.get(s.url(&format!("/v1/jobs/{id}/stock.stl")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 404);
    let (st, summary) = json(
        c.get(s.url(&format!("/v1/jobs/{id}/summary")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!((st, summary["moves"].as_u64()), (200, Some(moves)));
}

#[tokio::test]
async fn idempotency_key_returns_the_same_job_and_refuses_another_body() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    let body = json!({"kind": "interpret", "inputs": {"program": {"name": "a.nc", "content": "G0 X1 Y2\nG1 Z-1 F100\nM30\n"}}});
    let post = |b: serde_json::Value| {
        c.post(s.url("/v1/jobs"))
            .header("Idempotency-Key", "mes-order-42")
            .json(&b)
            .send()
    };
    let (st1, j1) = json(post(body.clone()).await.unwrap()).await;
    let res = post(body.clone()).await.unwrap();
    assert_eq!(res.headers()["idempotent-replayed"], "true");
    let (st2, j2) = json(res).await;
    assert_eq!((st1, st2), (202, 202));
    assert_eq!(j1["id"], j2["id"]);
    let (_, list) = json(c.get(s.url("/v1/jobs")).send().await.unwrap()).await;
    assert_eq!(
        list["items"].as_array().unwrap().len(),
        1,
        "one job for one key"
    );
    let (_, programs) = json(c.get(s.url("/v1/programs")).send().await.unwrap()).await;
    assert_eq!(
        programs["items"].as_array().unwrap().len(),
        1,
        "the inline program is stored once"
    );
    let mut other = body.clone();
    other["inputs"]["program"]["content"] = json!("G0 X5\n");
    let (st3, p) = json(post(other).await.unwrap()).await;
    assert_eq!(st3, 409);
    assert_eq!(p["job_id"], j1["id"]);
    // Concurrent first use of one key still makes one job.
    let key_body = json!({"kind": "interpret", "inputs": {"program": {"content": "G0 X9\n"}}});
    let futs = (0..8).map(|_| {
        c.post(s.url("/v1/jobs"))
            .header("Idempotency-Key", "race")
            .json(&key_body)
            .send()
    });
    let results = futures_util::future::join_all(futs).await;
    let mut ids = std::collections::BTreeSet::new();
    for r in results {
        let (st, v) = json(r.unwrap()).await;
        assert_eq!(st, 202, "{v}");
        ids.insert(v["id"].as_str().unwrap().to_string());
    }
    assert_eq!(ids.len(), 1);
}

#[tokio::test]
async fn jobs_are_validated_at_submission() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    let cases = [
        (json!({"kind": "interpret"}), 422, "inputs.program"),
        (
            json!({"kind": "interpret", "inputs": {"program": "missing-id"}}),
            422,
            "inputs.program",
        ),
        (
            json!({"kind": "interpret", "inputs": {"program": {"content": "G0 X1\n"}}, "options": {"dialect": "heidenhain"}}),
            422,
            "options.dialect",
        ),
        (
            json!({"kind": "interpret", "inputs": {"program": {"content": "G0 X1\n"}}, "options": {"speed": 1}}),
            422,
            "options.",
        ),
        (
            json!({"kind": "interpret", "inputs": {"program": {"content": "G0 X1\n"}, "stock": "x"}}),
            422,
            "inputs.stock",
        ),
        (json!({"kind": "teleport"}), 422, "kind"),
        (json!({"kind": "energy"}), 422, "inputs.tool"),
        (
            json!({"kind": "simulate", "inputs": {"program": {"content": "G0 X1\n"}}}),
            422,
            "inputs.stock",
        ),
        (
            json!({"kind": "simulate", "inputs": {"program": {"content": "G0 X1\n"}, "T0": "x"}}),
            422,
            "inputs.T0",
        ),
        (json!({"kind": "interpret", "extra": 1}), 422, "extra"),
    ];
    for (body, status, field) in cases {
        let (st, p) = post_json(&c, &s, "/v1/jobs", &body).await;
        assert_eq!(st, status, "{body} -> {p}");
        assert!(
            p["field"].as_str().unwrap_or("").starts_with(field),
            "{body} -> {p}"
        );
    }
    // identify runs now (tests/api_identify.rs): without its tool it is refused naming it.
    let (st, p) = post_json(&c, &s, "/v1/jobs", &json!({"kind": "identify"})).await;
    assert_eq!(
        (st, p["type"].as_str(), p["field"].as_str()),
        (
            422,
            Some("https://millsim.dev/problems/invalid-field"),
            Some("inputs.tool")
        )
    );
}

#[tokio::test]
async fn a_program_that_does_not_interpret_fails_with_its_line_and_is_not_retried() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    // Syntax is fine (it uploads); G41 D1 with no radius for number 1 (no tool table, no
    // G10) is refused by the interpreter, naming the line.
    let job = submit_interpret(&c, &s, &{
        let (st, v) = json(
            c.post(s.url("/v1/programs?name=comp.nc"))
                .body("G21 G90\nG0 X0 Y0\nG41 D1 G1 X10 F100\nM30\n")
                .send()
                .await
                .unwrap(),
        )
        .await;
        assert_eq!(st, 201, "{v}");
        v["id"].as_str().unwrap().to_string()
    })
    .await;
    let done = wait_job(&c, &s, job["id"].as_str().unwrap(), Duration::from_secs(30)).await;
    assert_eq!(done["status"], "failed", "{done}");
    assert_eq!(done["attempts"], 1);
    assert_eq!(done["error"]["errors"][0]["line"], 3, "{done}");
    assert_eq!(done["error"]["file"], "comp.nc");
    // With the job's tool for number 1 (input T1, a Ø10 tool), G41 D1 takes its radius:
    // the X10 entry line ends 5 mm to its left, at Y5.
    let (st, t1) = post_json(
        &c,
        &s,
        "/v1/tools",
        &json!({"type": "flat", "diameter_mm": 10.0, "flutes": 3, "flute_length_mm": 20.0}),
    )
    .await;
    assert_eq!(st, 201, "{t1}");
    let (st, job) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "interpret", "inputs": {"program": {"name": "comp.nc", "content": "G21 G90\nG0 X0 Y0\nG41 D1 G1 X10 F100\nM30\n"}, "T1": t1["id"]}}),
    )
    .await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    let done = wait_job(&c, &s, id, Duration::from_secs(30)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let (_, page) = json(
        c.get(s.url(&format!("/v1/jobs/{id}/blocks?limit=10")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    let last = page["items"].as_array().unwrap().last().unwrap().clone();
    let end = last["end"].as_array().unwrap();
    let (x, y) = (end[0].as_f64().unwrap(), end[1].as_f64().unwrap());
    assert!((x - 10.0).abs() < 1e-9 && (y - 5.0).abs() < 1e-9, "{page}");
}

#[tokio::test]
async fn cancel_a_queued_job_and_refuse_to_cancel_a_finished_one() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    let job = c
        .post(s.url("/v1/jobs"))
        .json(&json!({"kind": "interpret", "inputs": {"program": {"content": "G0 X1\n"}}}))
        .send()
        .await
        .unwrap();
    let (_, job) = json(job).await;
    let id = job["id"].as_str().unwrap();
    let (st, j) = json(
        c.post(s.url(&format!("/v1/jobs/{id}/cancel")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!((st, j["status"].as_str()), (202, Some("cancelled")));
    let (st, p) = json(
        c.post(s.url(&format!("/v1/jobs/{id}/cancel")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!((st, p["status"].as_u64()), (409, Some(409)));
    let (st, _) = json(
        c.get(s.url(&format!("/v1/jobs/{id}/blocks")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 409, "no results for a cancelled job");
    let (_, list) = json(
        c.get(s.url("/v1/jobs?status=cancelled"))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(list["items"].as_array().unwrap().len(), 1);
    let (_, list) = json(
        c.get(s.url("/v1/jobs?status=queued&kind=interpret"))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(list["items"].as_array().unwrap().len(), 0);
    assert_eq!(
        c.delete(s.url(&format!("/v1/jobs/{id}")))
            .send()
            .await
            .unwrap()
            .status(),
        204
    );
}

#[tokio::test]
async fn cancel_a_running_job_stops_it() {
    let dir = tempfile::tempdir().unwrap();
    // One worker; a long program keeps it busy while we cancel.
    let s = Server::start(
        &dir.path().join("t.db"),
        &["--workers", "1", "--lease-s", "0.6"],
    );
    let c = client();
    // A simulation that takes seconds on any build (a 10 mm tool zigzagging over a block on
    // a 0.05 mm grid, hundreds of passes): it is still running when the cancel comes, and
    // the removal checks for it after every move.
    let mut ids = Vec::new();
    for (path, body) in [
        (
            "/v1/stocks",
            json!({"kind": "block", "min": [0, 0, -10], "max": [60, 60, 0]}),
        ),
        (
            "/v1/tools",
            json!({"type": "flat", "diameter_mm": 10.0, "flutes": 4, "flute_length_mm": 20.0}),
        ),
    ] {
        let (st, v) = post_json(&c, &s, path, &body).await;
        assert_eq!(st, 201, "{path}: {v}");
        ids.push(v["id"].as_str().unwrap().to_string());
    }
    let mut program = String::from("G21 G90 S8000 M3\nG0 X-6 Y0 Z5\nG1 Z-2 F1000\n");
    for pass in 0..400 {
        let y = (pass % 60) as f64;
        let x = if pass % 2 == 0 { 66.0 } else { -6.0 };
        program += &format!("G1 X{x} Y{y} F3000\n");
    }
    program += "G0 Z5\nM30\n";
    let (st, prog) = json(
        c.post(s.url("/v1/programs?name=zigzag.nc"))
            .body(program)
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 201, "{prog}");
    let body = json!({"kind": "simulate",
        "inputs": {"program": prog["id"], "stock": ids[0], "tool": ids[1]},
        "options": {"material": "Al7075-T6", "cell_mm": 0.05}});
    let mut cancelled_running = false;
    for _ in 0..5 {
        let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
        assert_eq!(st, 202, "{job}");
        let id = job["id"].as_str().unwrap().to_string();
        // Wait until it runs, then cancel.
        let deadline = std::time::Instant::now() + Duration::from_secs(30);
        loop {
            let (_, v) = json(
                c.get(s.url(&format!("/v1/jobs/{id}")))
                    .send()
                    .await
                    .unwrap(),
            )
            .await;
            if v["status"] != "queued" {
                break;
            }
            assert!(std::time::Instant::now() < deadline);
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
        let (st, j) = json(
            c.post(s.url(&format!("/v1/jobs/{id}/cancel")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        if st == 409 {
            continue; // it finished first; try again
        }
        assert_eq!(j["cancel_requested"], true);
        let done = wait_job(&c, &s, &id, Duration::from_secs(60)).await;
        if done["status"] == "cancelled" {
            cancelled_running = true;
            let (_, att) = json(
                c.get(s.url(&format!("/v1/jobs/{id}/attempts")))
                    .send()
                    .await
                    .unwrap(),
            )
            .await;
            assert_eq!(att["items"][0]["outcome"], "cancelled");
            break;
        }
    }
    assert!(cancelled_running, "never managed to cancel a running job");
}

#[tokio::test]
async fn server_sent_events_deliver_progress_and_the_final_state() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    let program = upload_program(&c, &s, &adaptive_program()).await;
    let job = submit_interpret(&c, &s, &program).await;
    let id = job["id"].as_str().unwrap().to_string();
    // Subscribe while the job is still queued, then start a worker process on the same database.
    let res = c
        .get(s.url(&format!("/v1/jobs/{id}/events")))
        .send()
        .await
        .unwrap();
    assert_eq!(res.headers()["content-type"], "text/event-stream");
    let mut worker = std::process::Command::new(BIN)
        .args(["worker", "--database", &s.db_url, "--workers", "1"])
        .env("RUST_LOG", "warn")
        .spawn()
        .unwrap();
    let text = tokio::time::timeout(Duration::from_secs(60), res.text())
        .await
        .expect("stream ends after the final state")
        .unwrap();
    let _ = worker.kill();
    let _ = worker.wait();
    let events: Vec<(String, serde_json::Value)> = text
        .split("\n\n")
        .filter_map(|ev| {
            let name = ev.lines().find_map(|l| l.strip_prefix("event: "))?;
            let data = ev.lines().find_map(|l| l.strip_prefix("data: "))?;
            Some((name.to_string(), serde_json::from_str(data).unwrap()))
        })
        .collect();
    assert_eq!(
        events.first().map(|e| e.0.as_str()),
        Some("progress"),
        "{text}"
    );
    assert_eq!(events[0].1["status"], "queued");
    let (last_name, last) = events.last().unwrap();
    assert_eq!(last_name, "status");
    assert_eq!(last["status"], "succeeded");
    assert_eq!(last["id"], id.as_str());
    assert_eq!(events.iter().filter(|e| e.0 == "status").count(), 1);
}

#[tokio::test]
async fn stability_job_serves_lobes_as_rows_and_csv() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    // REFERENCE.md's 1-DOF benchmark, slot, zero-order: the lobes' floor is the absolute
    // limit 0.298 mm.
    let options = json!({"method": "zoa", "teeth": 2, "ktc_n_mm2": 600, "krc_n_mm2": 200, "radial_immersion": 1.0, "milling": "down",
        "modes_x": [{"freq_hz": 922, "damping": 0.011, "stiffness_n_m": 1.34005e6}], "modes_y": [],
        "rpm": {"from": 5000, "to": 25000, "step": 50}, "steps_per_period": 40});
    let (st, job) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "stability", "options": options}),
    )
    .await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    let done = wait_job(&c, &s, id, Duration::from_secs(60)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["summary"]["speeds"], 401);
    let min = done["summary"]["minimum"]["depth_mm"].as_f64().unwrap();
    assert!((min - 0.298).abs() / 0.298 < 0.02, "{done}");
    let csv = get_text(&c, &s, &format!("/v1/jobs/{id}/blocks?format=csv")).await;
    assert_eq!(csv.lines().next(), Some("rpm,depth_mm"));
    assert_eq!(csv.lines().count(), 402);
    // Bad options are refused at submission, naming the field.
    let mut bad = options.clone();
    bad["teeth"] = json!(0);
    let (st, p) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "stability", "options": bad}),
    )
    .await;
    assert_eq!(st, 422, "{p}");
    assert!(p["field"].as_str().unwrap().contains("teeth"), "{p}");
    let mut bad = options.clone();
    bad["method"] = json!("guess");
    let (st, p) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "stability", "options": bad}),
    )
    .await;
    assert_eq!(
        (st, p["field"].as_str()),
        (422, Some("options.method")),
        "{p}"
    );
}

/// A 4-axis machine with a B table, pivot at the origin.
fn b_table_machine() -> serde_json::Value {
    json!({"name": "B table", "kinematics": "xyz_b", "rapid_rate": 20000.0, "max_feed": 10000.0,
        "acceleration": [1000.0, 1000.0, 1000.0], "spindle_min_rpm": 0.0, "spindle_max_rpm": 12000.0, "rated_power": 10000.0})
}

#[tokio::test]
async fn rotary_feed_job_corrects_f_so_the_tool_tip_moves_at_the_programmed_feed() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let machine = b_table_machine();
    let (st, m) = post_json(&c, &s, "/v1/machines", &machine).await;
    assert_eq!(st, 201, "{m}");
    // The tip sits 50 mm from the B axis and turns 90° at F500: it travels π/2·50 mm, so the
    // move must take (π/2·50)/500 min and F (deg/min) = 90 / that.
    let program = "G21 G90 G94\nG0 X50 Y0 Z0 B0\nG1 B90 F500\nM30\n";
    let body = json!({"kind": "rotary-feed", "inputs": {"program": {"name": "b.nc", "content": program}, "machine": m["id"]}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    let done = wait_job(&c, &s, id, Duration::from_secs(60)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let expected = 90.0 / (std::f64::consts::FRAC_PI_2 * 50.0 / 500.0);
    let (_, rows) = json(
        c.get(s.url(&format!("/v1/jobs/{id}/blocks")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    let row = rows["items"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["line"] == 3)
        .unwrap();
    assert!(
        (row["feed"].as_f64().unwrap() - expected).abs() / expected < 0.01,
        "{row} vs {expected}"
    );
    let res = c
        .get(s.url(&format!("/v1/jobs/{id}/program")))
        .send()
        .await
        .unwrap();
    assert!(res.headers()["content-disposition"]
        .to_str()
        .unwrap()
        .contains("b.rotary.nc"));
    let text = res.text().await.unwrap();
    let line3 = text.lines().nth(2).unwrap();
    let f: f64 = line3
        .split_whitespace()
        .find_map(|w| w.strip_prefix('F'))
        .unwrap()
        .parse()
        .unwrap();
    assert!((f - expected).abs() / expected < 0.01, "{line3}");
    assert_eq!(
        text.lines().nth(1),
        program.lines().nth(1),
        "other lines unchanged"
    );
}

#[tokio::test]
async fn rotary_feed_job_posts_a_cls_file_to_one_program_per_operation() {
    use millsim_engine::machine::{Machine, MachineKinematics};
    use millsim_engine::nc::{interpret, InterpretOptions};
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let mut machine = b_table_machine();
    machine["max_rotary_speed_deg_min"] = json!(20000.0);
    let (st, m) = post_json(&c, &s, "/v1/machines", &machine).await;
    assert_eq!(st, 201, "{m}");
    // Two operations, the tool axis leaning ±30° in XZ (B = ∓30° on this table).
    let cls = "TOOL PATH/OP1,TOOL,EM10\nLOADTL/1\nSPINDL/RPM,8000,CLW\nRAPID\nGOTO/50,0,10,0,0,1\nFEDRAT/MMPM,500\nGOTO/50,0,0,0,0,1\nGOTO/40,0,0,0.5,0,0.8660254038\n\
TOOL PATH/OP2,TOOL,BALL6\nLOADTL/2\nSPINDL/RPM,12000,CLW\nRAPID\nGOTO/10,0,5,0,0,1\nFEDRAT/MMPM,400\nGOTO/10,5,0,0,0,1\nGOTO/0,10,0,-0.5,0,0.8660254038\nRAPID\nGOTO/0,10,50,0,0,1\n";
    let body = json!({"kind": "rotary-feed", "inputs": {"program": {"name": "part.cls", "content": cls}, "machine": m["id"]},
                      "options": {"decimals": 7}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    let done = wait_job(&c, &s, id, Duration::from_secs(60)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["summary"]["operations"].as_array().unwrap().len(), 2);
    let kin = MachineKinematics::of(&serde_json::from_value::<Machine>(machine).unwrap());
    // Each operation's program re-interprets, through the forward kinematics, to its last
    // CLS point.
    for (op, file, last) in [
        (1, "part.op1.nc", [40.0, 0.0, 0.0]),
        (2, "part.op2.nc", [0.0, 10.0, 50.0]),
    ] {
        let res = c
            .get(s.url(&format!("/v1/jobs/{id}/program?operation={op}")))
            .send()
            .await
            .unwrap();
        assert_eq!(res.status(), 200);
        assert!(res.headers()["content-disposition"]
            .to_str()
            .unwrap()
            .contains(file));
        let text = res.text().await.unwrap();
        let moves = interpret(&text, &InterpretOptions::default())
            .unwrap()
            .moves;
        let tip = kin.forward(&moves.last().unwrap().end).tip;
        let d = (0..3)
            .map(|i| (tip[i] - last[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            d < 1e-6,
            "operation {op}: ends at {tip:?}, CLS {last:?}\n{text}"
        );
    }
    let res = c
        .get(s.url(&format!("/v1/jobs/{id}/program?operation=3")))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 404);
    let res = c
        .get(s.url(&format!("/v1/jobs/{id}/program?operation=0")))
        .send()
        .await
        .unwrap();
    assert!(res.status().is_client_error());
}

/// Issue 29: a ball end pass around a cylinder edge at FEDRAT 400, C turning about the tool
/// tip (X Y Z still, up to the CLS's rounding) and then A, C and X Y Z together, posted by the
/// rotary-feed job for a machine of each rotary feed reading: the posted program, re-timed on
/// the same machine, moves the tip at 400 mm/min.
#[tokio::test]
async fn rotary_feed_job_posts_a_cls_whose_tip_runs_at_fedrat_in_the_machines_reading() {
    use millsim_engine::machine::cycle_time::cycle_time;
    use millsim_engine::machine::rotary_feed::{tool_tip_speeds, RotaryFeedOptions};
    use millsim_engine::machine::Machine;
    use millsim_engine::nc::{interpret, InterpretOptions};
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let mut cls = String::from("LOADTL/3\nSPINDL/RPM,10000,CLW\nRAPID\nGOTO/40,0,25,0.707107,0,0.707107\nFEDRAT/MMPM,400\n");
    for k in 0..=36 {
        let (t, lean) = (
            (5.0 * k as f64).to_radians(),
            if k <= 18 {
                45.0f64
            } else {
                45.0 - 25.0 * (k - 18) as f64 / 18.0
            }
            .to_radians(),
        );
        cls.push_str(&format!(
            "GOTO/{:.4},{:.4},20,{:.6},{:.6},{:.6}\n",
            40.0 * t.cos(),
            40.0 * t.sin(),
            lean.sin() * t.cos(),
            lean.sin() * t.sin(),
            lean.cos()
        ));
    }
    for reading in [None, Some("combined"), Some("inverse_time_only")] {
        let mut machine = json!({"name": "AC trunnion", "kinematics": "xyz_ac", "rapid_rate": 30000.0, "max_feed": 20000.0,
            "acceleration": [1e7, 1e7, 1e7], "spindle_min_rpm": 0.0, "spindle_max_rpm": 12000.0, "rated_power": 10000.0,
            "kinematic_chain": {"tilt_pivot": [0.0, 0.0, -80.0], "rotary_center": [0.0, 0.0, 0.0], "pivot_length": 0.0}});
        if let Some(r) = reading {
            machine["rotary_feed_reading"] = json!(r);
        }
        let (st, m) = post_json(&c, &s, "/v1/machines", &machine).await;
        assert_eq!(st, 201, "{m}");
        let body = json!({"kind": "rotary-feed", "inputs": {"program": {"name": "edge.cls", "content": cls}, "machine": m["id"]}});
        let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
        assert_eq!(st, 202, "{job}");
        let id = job["id"].as_str().unwrap();
        let done = wait_job(&c, &s, id, Duration::from_secs(60)).await;
        assert_eq!(done["status"], "succeeded", "{done}");
        let text = c
            .get(s.url(&format!("/v1/jobs/{id}/program")))
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        let machine: Machine = serde_json::from_value(machine).unwrap();
        let moves = interpret(&text, &InterpretOptions::default())
            .unwrap()
            .moves;
        let speeds = tool_tip_speeds(&moves, &machine, &RotaryFeedOptions::default());
        let times = cycle_time(&moves, &machine, None).unwrap();
        assert!(speeds.len() >= 36, "{text}");
        for sp in &speeds {
            let timed = sp.tip_length / (times.per_move_s[sp.move_index] / 60.0);
            assert!(
                (sp.speed - 400.0).abs() <= 4.0 && (timed - 400.0).abs() <= 4.0,
                "{reading:?} line {}: tip {} mm/min (cycle time {timed})\n{text}",
                sp.line,
                sp.speed
            );
        }
        // The 5 mm plunge and 180° of a 40 mm radius at 400 mm/min: about 19.6 s of cutting,
        // not millions.
        let want = (std::f64::consts::PI * 40.0 + 5.0) / 400.0 * 60.0;
        assert!(
            (times.cutting_s - want).abs() <= 0.02 * want,
            "{reading:?}: {} s",
            times.cutting_s
        );
    }
}

#[tokio::test]
async fn energy_job_finds_a_feasible_point_and_a_pareto_front() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let mut ids = Vec::new();
    // A 5.5 kW machine (η = 0.8) with the REFERENCE.md idle-power fit and a 3 kN thrust limit.
    for (path, body) in [
        (
            "/v1/tools",
            json!({"type": "flat", "diameter_mm": 10.0, "flutes": 4, "helix_deg": 30.0, "flute_length_mm": 25.0}),
        ),
        (
            "/v1/machines",
            json!({"name": "VMC", "rapid_rate": 24000.0, "max_feed": 8000.0, "acceleration": [2000.0, 2000.0, 1500.0],
            "spindle_min_rpm": 500.0, "spindle_max_rpm": 12000.0, "rated_power": 5500.0, "efficiency": 0.8,
            "torque_limit": 30.0, "axis_thrust_limit": 3000.0,
            "energy": {"idle": {"base_rpm": 3000, "below": [823.3, 0.0149, 2e-6], "above": [881.5, -0.0034, 3e-6]}, "aux_power_w": 804}}),
        ),
    ] {
        let (st, v) = post_json(&c, &s, path, &body).await;
        assert_eq!(st, 201, "{path}: {v}");
        ids.push(v["id"].as_str().unwrap().to_string());
    }
    let options = json!({"material": "Al7075-T6", "length_mm": 200, "width_mm": 8, "depth_mm": 12,
        "cutting_speed_m_min": {"min": 100, "max": 300}, "feed_per_tooth_mm": {"min": 0.02, "max": 0.2},
        "objective": "min_energy", "pareto": true});
    let inputs = json!({"tool": ids[0], "machine": ids[1]});
    // Bad options name the field at submission.
    let mut bad = options.clone();
    bad["length_mm"] = json!(-1);
    let (st, p) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "energy", "inputs": inputs, "options": bad}),
    )
    .await;
    assert_eq!(
        (st, p["field"].as_str()),
        (422, Some("options.length_mm")),
        "{p}"
    );
    let (st, job) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "energy", "inputs": inputs, "options": options}),
    )
    .await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    let done = wait_job(&c, &s, id, Duration::from_secs(120)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let best = &done["summary"]["best"];
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    // Every constraint at the returned point.
    assert!(f(best, "cutting_power_w") <= 0.8 * 5500.0 + 1e-6, "{best}");
    assert!(f(best, "peak_force_n") <= 3000.0 + 1e-6, "{best}");
    assert!(f(best, "peak_torque_nm") <= 30.0 + 1e-6, "{best}");
    let vc = f(best, "cutting_speed_m_min");
    assert!((100.0 - 1e-6..=300.0 + 1e-6).contains(&vc), "{best}");
    assert!(f(best, "feed_mm_min") <= 8000.0 + 1e-6);
    // ap is an even split of the depth.
    let passes = best["axial_passes"].as_u64().unwrap() as f64;
    assert!((f(best, "axial_depth_mm") * passes - 12.0).abs() < 1e-9);
    // The rows are the front: by increasing time, energy never increasing.
    let page = get_json(&c, &s, &format!("/v1/jobs/{id}/blocks?limit=1000")).await;
    let front = page["items"].as_array().unwrap();
    assert!(!front.is_empty());
    for w in front.windows(2) {
        assert!(f(&w[0], "time_s") <= f(&w[1], "time_s"));
        assert!(f(&w[0], "energy_j") >= f(&w[1], "energy_j") - 1e-9);
    }
    let min_energy = front
        .iter()
        .map(|p| f(p, "energy_j"))
        .fold(f64::INFINITY, f64::min);
    assert!(f(best, "energy_j") <= min_energy * (1.0 + 1e-9), "{best}");
}

#[tokio::test]
async fn stability_job_recommends_a_speed_and_computes_3d_lobes() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let run = |options: serde_json::Value| {
        let c = c.clone();
        let url = s.url("/v1/jobs");
        async move {
            let (st, job) = json(
                c.post(url)
                    .json(&json!({"kind": "stability", "options": options}))
                    .send()
                    .await
                    .unwrap(),
            )
            .await;
            assert_eq!(st, 202, "{job}");
            job["id"].as_str().unwrap().to_string()
        }
    };
    let mut options = json!({"method": "zoa", "teeth": 2, "ktc_n_mm2": 600, "krc_n_mm2": 200, "radial_immersion": 1.0, "milling": "down",
        "modes_x": [{"freq_hz": 922, "damping": 0.011, "stiffness_n_m": 1.34005e6}], "modes_y": [],
        "rpm": {"from": 5000, "to": 25000, "step": 50}});
    options["recommend"] = json!({"near_rpm": 15000, "depth_mm": 0.5, "window_rpm": 5000});
    let id = run(options.clone()).await;
    let done = wait_job(&c, &s, &id, Duration::from_secs(60)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let r = &done["summary"]["recommendation"];
    let rpm = r["rpm"].as_f64().unwrap();
    let (from, to) = (
        r["pocket_from_rpm"].as_f64().unwrap(),
        r["pocket_to_rpm"].as_f64().unwrap(),
    );
    assert!(
        from <= rpm && rpm <= to && (rpm - 15000.0).abs() <= 5000.0,
        "{r}"
    );
    assert!(r["stable_depth_mm"].as_f64().unwrap() > 0.5, "{r}");
    // Every speed of the pocket is stable at 0.5 mm on the job's own lobes.
    let page = get_json(&c, &s, &format!("/v1/jobs/{id}/blocks?limit=1000")).await;
    for p in page["items"].as_array().unwrap() {
        let (n, d) = (p["rpm"].as_f64().unwrap(), p["depth_mm"].as_f64().unwrap());
        if (from..=to).contains(&n) {
            assert!(d > 0.5, "{n} rpm: {d} mm in the pocket {from}..{to}");
        }
    }

    // 3-D lobes: a rigid tool on a workpiece whose X mode stiffens with the allowance
    // (2e6 N/m at 0.5 mm, 8e6 at 3 mm, 5e6 interpolated at 1.75 mm). For one mode the
    // zero-order lobes scale with the stiffness, so the floors go 2 : 5 : 8.
    let mut surface = options.clone();
    surface.as_object_mut().unwrap().remove("recommend");
    surface["modes_x"] = json!([]);
    surface["allowance"] = json!([
        {"allowance_mm": 0.5, "modes_x": [{"freq_hz": 600, "damping": 0.02, "stiffness_n_m": 2.0e6}]},
        {"allowance_mm": 3.0, "modes_x": [{"freq_hz": 600, "damping": 0.02, "stiffness_n_m": 8.0e6}]}
    ]);
    surface["allowances_mm"] = json!([0.5, 1.75, 3.0]);
    let id = run(surface).await;
    let done = wait_job(&c, &s, &id, Duration::from_secs(60)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["summary"]["points"], 3 * 401);
    let csv = get_text(&c, &s, &format!("/v1/jobs/{id}/blocks?format=csv")).await;
    assert_eq!(csv.lines().next(), Some("allowance_mm,rpm,depth_mm"));
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 3 * 401);
    let floor = |a: f64| {
        rows.iter()
            .filter(|r| r[0] == a)
            .map(|r| r[2])
            .fold(f64::INFINITY, f64::min)
    };
    let (f0, f1, f2) = (floor(0.5), floor(1.75), floor(3.0));
    assert!(
        (f1 / f0 - 2.5).abs() < 1e-6 && (f2 / f0 - 4.0).abs() < 1e-6,
        "{f0} {f1} {f2}"
    );
}

#[tokio::test]
async fn queued_jobs_per_key_are_limited_with_429_and_retry_after_but_replays_pass() {
    let dir = tempfile::tempdir().unwrap();
    // No workers: every submission stays queued.
    let s = Server::start(
        &dir.path().join("t.db"),
        &["--workers", "0", "--max-queued-per-key", "2"],
    );
    let c = client();
    let body = |n: u32| json!({"kind": "interpret", "inputs": {"program": {"name": "a.nc", "content": format!("G0 X{n}\n")}}});
    let submit = |n: u32, key: &str| {
        c.post(s.url("/v1/jobs"))
            .header("idempotency-key", key.to_string())
            .json(&body(n))
            .send()
    };
    let (st, first) = json(submit(1, "k1").await.unwrap()).await;
    assert_eq!(st, 202, "{first}");
    let (st, _) = json(submit(2, "k2").await.unwrap()).await;
    assert_eq!(st, 202);

    let res = submit(3, "k3").await.unwrap();
    assert_eq!(res.status(), 429);
    let retry: u64 = res.headers()["retry-after"]
        .to_str()
        .unwrap()
        .parse()
        .unwrap();
    assert!(retry >= 1);
    assert_eq!(res.headers()["content-type"], "application/problem+json");
    let (_, p) = json(res).await;
    assert_eq!(p["status"], 429);
    assert_eq!(p["limit"], 2);
    assert!(
        p["detail"].as_str().unwrap().contains("max_queued_per_key"),
        "{p}"
    );

    // Replaying a job that exists is not a new job: it is answered as before.
    let res = submit(1, "k1").await.unwrap();
    assert_eq!(res.status(), 202);
    assert_eq!(res.headers()["idempotent-replayed"], "true");
    let (_, again) = json(res).await;
    assert_eq!(again["id"], first["id"]);

    // Once a queued job leaves the queue, there is room again.
    let id = first["id"].as_str().unwrap();
    let (st, _) = json(
        c.post(s.url(&format!("/v1/jobs/{id}/cancel")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 202);
    let (st, v) = json(submit(3, "k3").await.unwrap()).await;
    assert_eq!(st, 202, "{v}");
}

/// Moves inside an endless loop: only the move cap (10 million) would end it.
const RUNAWAY: &str =
    "G21 G90\nG0 X0 Y0 Z5\no100 while [1 EQ 1]\nG1 X10 F1000\nG1 X0\no100 endwhile\nM30\n";

#[tokio::test]
async fn an_interpret_job_in_a_runaway_loop_is_cancelled_within_a_second() {
    let dir = tempfile::tempdir().unwrap();
    // The default lease: cancel must not wait for a long heartbeat either.
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let body = json!({"kind": "interpret", "inputs": {"program": {"name": "loop.ngc", "content": RUNAWAY}}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    while get_json(&c, &s, &format!("/v1/jobs/{id}")).await["status"] != "running" {
        assert!(
            std::time::Instant::now() < deadline,
            "the job did not start"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    // Let it run into the loop.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let asked = std::time::Instant::now();
    let (st, _) = json(
        c.post(s.url(&format!("/v1/jobs/{id}/cancel")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 202);
    let done = wait_job(&c, &s, id, Duration::from_secs(60)).await;
    let took = asked.elapsed();
    assert_eq!(done["status"], "cancelled", "{done}");
    assert!(took < Duration::from_secs(1), "cancel took {took:?}");
}

#[tokio::test]
async fn a_long_stability_job_is_cancelled_within_a_second_and_reports_progress() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let (st, job) = post_json(&c, &s, "/v1/jobs", &long_stability_job()).await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    // Progress counts speeds while it runs (it stayed 0/0 before).
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    loop {
        let now = get_json(&c, &s, &format!("/v1/jobs/{id}")).await;
        if now["progress"]["done"].as_u64().unwrap_or(0) > 0 {
            assert_eq!(now["status"], "running", "{now}");
            assert_eq!(now["progress"]["total"], 20001, "{now}");
            break;
        }
        assert!(std::time::Instant::now() < deadline, "no progress: {now}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let asked = std::time::Instant::now();
    let (st, _) = json(
        c.post(s.url(&format!("/v1/jobs/{id}/cancel")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 202);
    let done = wait_job(&c, &s, id, Duration::from_secs(300)).await;
    let took = asked.elapsed();
    assert_eq!(done["status"], "cancelled", "{done}");
    assert!(took < Duration::from_secs(1), "cancel took {took:?}");
}
