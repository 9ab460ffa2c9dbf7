//! Issue 29 over HTTP: a drill cycle carries the lips' thrust and torque, a tool without
//! center cutting that plunges is a collision, and an optimize job reports each tool's
//! default guards (switched off with `tool_guards: false`).

mod common;

use std::time::Duration;

use serde_json::{json, Value};

use common::*;

async fn create(c: &reqwest::Client, s: &Server, path: &str, body: Value) -> (String, Value) {
    let (st, v) = post_json(c, s, path, &body).await;
    assert_eq!(st, 201, "{path}: {v}");
    (v["id"].as_str().unwrap().to_string(), v)
}

async fn block(c: &reqwest::Client, s: &Server) -> String {
    create(
        c,
        s,
        "/v1/stocks",
        json!({"kind": "block", "min": [0, -20, -20], "max": [100, 20, 0]}),
    )
    .await
    .0
}

async fn rows(c: &reqwest::Client, s: &Server, job: &Value) -> Vec<Value> {
    let id = job["id"].as_str().unwrap();
    get_json(c, s, &format!("/v1/jobs/{id}/blocks?limit=1000")).await["items"]
        .as_array()
        .unwrap()
        .clone()
}

#[tokio::test]
async fn a_drill_cycle_has_thrust_and_a_plunge_without_center_cutting_is_a_collision() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let stock = block(&c, &s).await;
    let (drill, _) = create(&c, &s, "/v1/tools", json!({"type": "drill", "diameter_mm": 8, "point_angle_deg": 118, "flutes": 2, "flute_length_mm": 40})).await;
    let program =
        "G21 G90 G17\nS3000 M3\nG0 X50 Y0 Z5\nG98 G81 X50 Y0 Z-12 R2 F240\nG80\nG0 Z20\nM30\n";
    let job = run_job(&c, &s, &json!({"kind": "simulate", "inputs": {"program": {"name": "drill.nc", "content": program}, "stock": stock, "tool": drill},
        "options": {"material": "Al7075-T6", "cell_mm": 0.2}}), Duration::from_secs(120)).await;
    let rs = rows(&c, &s, &job).await;
    let feed_in = rs
        .iter()
        .max_by(|a, b| {
            a["removed_mm3"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["removed_mm3"].as_f64().unwrap())
        })
        .unwrap();
    // The lips' closed form at 0.04 mm a lip (engine/tests/plunge_forces.rs): thrust
    // N·[(Krc·c·sin p + Kre)·R − (Kac·c·sin p + Kae)·R·cot p], torque N·(Ktc·c·sin p + Kte)·R²/(2 sin p).
    let (ktc, krc, kac, kte, kre, kae) = (767.01, 168.8, 222.0, 27.7, 26.6, 0.7);
    let (p, c_, r) = (59f64.to_radians(), 0.04, 4.0);
    let thrust = 2.0 * ((krc * c_ * p.sin() + kre) * r - (kac * c_ * p.sin() + kae) * r / p.tan());
    let torque = 2.0 * (ktc * c_ * p.sin() + kte) * r * r / (2.0 * p.sin()) / 1000.0;
    let fz = feed_in["fz_mean_n"].as_f64().unwrap();
    let t = feed_in["torque_peak_nm"].as_f64().unwrap();
    assert!(
        fz > 0.5 * thrust && fz <= 1.02 * thrust,
        "Fz {fz} vs {thrust}: {feed_in}"
    );
    assert!(
        (t - torque).abs() < 0.03 * torque,
        "T {t} vs {torque}: {feed_in}"
    );
    assert!(
        !feed_in["flags"].as_str().unwrap().contains("air"),
        "{feed_in}"
    );

    // An end mill whose end teeth stop short of the centre, plunging: a collision.
    let (nc, _) = create(&c, &s, "/v1/tools", json!({"type": "flat", "diameter_mm": 12, "flutes": 4, "flute_length_mm": 30, "center_cutting": false})).await;
    let plunge = "G21 G90\nS8000 M3\nG0 X50 Y0 Z5\nG0 Z0\nG1 Z-3 F100\nG1 X60 F400\nG0 Z5\nM30\n";
    let job = run_job(&c, &s, &json!({"kind": "simulate", "inputs": {"program": {"name": "plunge.nc", "content": plunge}, "stock": stock, "tool": nc},
        "options": {"material": "Al7075-T6", "cell_mm": 0.25}}), Duration::from_secs(120)).await;
    let kinds: Vec<(u64, String)> = job["summary"]["collisions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["line"].as_u64().unwrap(),
                c["kind"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    assert_eq!(
        kinds,
        vec![(5, "non_center_cutting_plunge".to_string())],
        "{}",
        job["summary"]
    );
}

/// The optimized slot's row (line 6).
async fn slot(c: &reqwest::Client, s: &Server, job: &Value) -> Value {
    rows(c, s, job)
        .await
        .into_iter()
        .find(|r| r["line"] == 6)
        .unwrap()
}

#[tokio::test]
async fn an_optimize_job_reports_each_tools_guards_and_they_can_be_switched_off() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let stock = block(&c, &s).await;
    let (tool, _) = create(&c, &s, "/v1/tools", json!({"type": "flat", "diameter_mm": 3, "flutes": 2, "flute_length_mm": 10, "stickout_mm": 30})).await;
    // A Ø3 slot 1 mm deep at F300 (0.015 mm a tooth): the 400 N limit alone would take it to
    // the max feed; the tool's guards stop it well before.
    let program = "G21 G90\nT1 M6\nS10000 M3\nG0 X-5 Y0 Z5\nG0 Z-1\nG1 X60 F300\nG0 Z5\nM30\n";
    let body = |guards: bool| {
        json!({"kind": "optimize", "inputs": {"program": {"name": "slot.nc", "content": program}, "stock": stock, "T1": tool},
        "options": {"material": "Al7075-T6", "cell_mm": 0.1, "limits": {"max_force": 400, "max_feed": 5000, "tool_guards": guards}}})
    };
    let on = run_job(&c, &s, &body(true), Duration::from_secs(120)).await;
    let t1 = &on["summary"]["optimization"]["tools"][0];
    let g = &t1["guards"];
    assert!(
        g["max_chip_thickness"].as_f64().unwrap() > 0.0 && g["max_force"].as_f64().unwrap() < 400.0,
        "{t1}"
    );
    let guarded = slot(&c, &s, &on).await;
    assert!(
        guarded["governing"].as_str().unwrap().starts_with("guard_"),
        "{guarded}"
    );
    let off = run_job(&c, &s, &body(false), Duration::from_secs(120)).await;
    assert!(
        off["summary"]["optimization"]["tools"][0]["guards"].is_null(),
        "{}",
        off["summary"]
    );
    let free = slot(&c, &s, &off).await;
    assert!(
        free["feed_opt_mm_min"].as_f64().unwrap() > guarded["feed_opt_mm_min"].as_f64().unwrap(),
        "{free} vs {guarded}"
    );
}
