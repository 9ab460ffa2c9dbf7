//! The `accessibility` job over HTTP and `millsim accessibility INPUT.json`: a block with a
//! Ø20 hole drilled 25° off Z (built here from its definition) gives the hole's axis and
//! diameter; the roughing program, the free-region picture and the rows are served; a
//! parametric part, a target outside the part and bad options are refused naming the field;
//! a target no tool reaches is a diameter of 0.

mod common;

#[path = "../engine/tests/parts/mod.rs"]
mod parts;

use std::time::Duration;

use common::*;
use parts::{drilled_block, stl_bytes, HolePiece};
use serde_json::{json, Value};

fn hole_block() -> (Vec<u8>, [f64; 3], [f64; 3], [f64; 3]) {
    let a = 25f64.to_radians();
    let d = [a.sin(), 0.0, a.cos()];
    let top = [0.0, 0.0, 60.0];
    let piece = HolePiece {
        radius: 10.0,
        offset: [0.0, 0.0],
        until: 0.0,
    };
    let mesh = drilled_block(60.0, 40.0, 60.0, d, top, &[piece], 128);
    let target = std::array::from_fn(|k| top[k] - 40.0 * d[k]);
    (stl_bytes(&mesh), d, top, target)
}

fn angle(a: &Value, b: [f64; 3]) -> f64 {
    let a: Vec<f64> = a
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    (a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

fn machine() -> Value {
    json!({"name": "AC trunnion", "kinematics": "xyz_ac", "rapid_rate": 20000, "max_feed": 10000,
           "acceleration": [2000, 2000, 1500], "spindle_min_rpm": 100, "spindle_max_rpm": 12000,
           "rated_power": 11000})
}

#[tokio::test]
async fn accessibility_job_finds_the_drilled_holes_axis_and_diameter() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let (stl, d, top, target) = hole_block();
    let (st, part) = post_stl(&c, &s, "/v1/stocks?name=hole.stl", stl).await;
    assert_eq!(st, 201, "{part}");
    let part = part["id"].as_str().unwrap().to_string();
    let (st, m) = post_json(&c, &s, "/v1/machines", &machine()).await;
    assert_eq!(st, 201, "{m}");
    let m = m["id"].as_str().unwrap().to_string();
    let body = json!({"kind": "accessibility", "inputs": {"part": part, "machine": m},
        "options": {"entry": top, "target": target, "max_tilt_deg": 20, "allowance_mm": 0.5,
                    "tools": [{"type": "flat", "diameter_mm": 16, "flutes": 3, "flute_length_mm": 50},
                              {"type": "flat", "diameter_mm": 20, "flutes": 3, "flute_length_mm": 50}]}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap().to_string();
    let done = wait_job(&c, &s, &id, Duration::from_secs(300)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let sum = &done["summary"];
    assert!(angle(&sum["axis"], d) < 0.5, "{sum}");
    // Ø20 (a 128-gon inscribed: 20·cos(π/128)) less twice the allowance.
    let expected = 20.0 * (std::f64::consts::PI / 128.0).cos() - 1.0;
    let got = sum["tool_diameter_mm"].as_f64().unwrap();
    assert!((got - expected).abs() / 20.0 < 0.005, "{got} vs {expected}");
    // Ø20 needs 21 with the allowance: the Ø16 is the list's tool.
    assert_eq!(sum["tool"]["diameter_mm"], 16.0, "{sum}");
    // The default strategy: a helical entry about the hole's centre, then the spiral.
    assert_eq!(sum["program"]["strategy"], "spiral", "{sum}");
    assert!(sum["program"]["helices"].as_u64().unwrap() >= 1, "{sum}");
    assert!(
        sum["segments"][0]["spiral"]["length_mm"].as_f64().unwrap() > 0.0,
        "{sum}"
    );
    let program = get_text(&c, &s, &format!("/v1/jobs/{id}/program")).await;
    assert!(
        program.contains("T1 M6") && program.contains(" A") && program.contains("G1 "),
        "{program}"
    );
    let svg = get_text(&c, &s, &format!("/v1/jobs/{id}/free_region.svg")).await;
    assert!(
        svg.starts_with("<svg") && svg.contains("largest tool"),
        "{svg}"
    );
    let rows = get_json(&c, &s, &format!("/v1/jobs/{id}/blocks")).await;
    assert_eq!(rows["items"].as_array().map(Vec::len), Some(1), "{rows}");

    // A target in the material: no tool reaches it, a clear answer.
    let body = json!({"kind": "accessibility", "inputs": {"part": part},
        "options": {"entry": top, "target": [40.0, 20.0, 30.0]}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let done = wait_job(
        &c,
        &s,
        job["id"].as_str().unwrap(),
        Duration::from_secs(300),
    )
    .await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["summary"]["tool_diameter_mm"], 0.0, "{done}");

    // Refusals name the field.
    for (options, field) in [
        (
            json!({"entry": top, "target": [0.0, 0.0, 90.0]}),
            "options.target",
        ),
        (
            json!({"entry": [500.0, 0.0, 60.0], "target": target}),
            "options.entry",
        ),
        (
            json!({"entry": top, "target": target, "segments": 0}),
            "options.segments",
        ),
        (
            json!({"entry": top, "target": target, "max_tilt_deg": 95}),
            "options.max_tilt_deg",
        ),
        (
            json!({"entry": top, "target": target, "tools": [{"type": "flat", "diameter_mm": -2, "flutes": 2, "flute_length_mm": 10}]}),
            "options.tools[0].diameter_mm",
        ),
    ] {
        let body = json!({"kind": "accessibility", "inputs": {"part": part}, "options": options});
        let (st, p) = post_json(&c, &s, "/v1/jobs", &body).await;
        assert_eq!(st, 422, "{p}");
        assert_eq!(p["field"], field, "{p}");
    }
    let (st, block) = post_json(
        &c,
        &s,
        "/v1/stocks",
        &json!({"kind": "block", "min": [0, 0, 0], "max": [10, 10, 10]}),
    )
    .await;
    assert_eq!(st, 201);
    let body = json!({"kind": "accessibility", "inputs": {"part": block["id"]},
        "options": {"entry": [5, 5, 10], "target": [5, 5, 5]}});
    let (st, p) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!((st, p["field"].as_str()), (422, Some("inputs.part")), "{p}");
    // A part that is not closed is refused at upload.
    let (stl, ..) = hole_block();
    let mut open = stl.clone();
    let n = u32::from_le_bytes([open[80], open[81], open[82], open[83]]) - 1;
    open.truncate(open.len() - 50);
    open[80..84].copy_from_slice(&n.to_le_bytes());
    let (st, p) = post_stl(&c, &s, "/v1/stocks?name=open.stl", open).await;
    assert_eq!(st, 422, "{p}");
    assert!(p["detail"].as_str().unwrap().contains("not closed"), "{p}");
    assert!(s.terminate());
}

#[test]
fn accessibility_cli_prints_the_result_as_json() {
    let dir = tempfile::tempdir().unwrap();
    let (stl, d, top, target) = hole_block();
    std::fs::write(dir.path().join("hole.stl"), stl).unwrap();
    std::fs::write(dir.path().join("machine.json"), machine().to_string()).unwrap();
    let input = dir.path().join("input.json");
    std::fs::write(
        &input,
        json!({"part": "hole.stl", "machine": "machine.json", "entry": top, "target": target,
               "allowance_mm": 0.5})
        .to_string(),
    )
    .unwrap();
    let nc = dir.path().join("rough.nc");
    let out = std::process::Command::new(BIN)
        .args([
            "accessibility",
            input.to_str().unwrap(),
            "--program",
            nc.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(angle(&v["axis"], d) < 0.5, "{v}");
    let expected = 20.0 * (std::f64::consts::PI / 128.0).cos() - 1.0;
    let got = v["tool_diameter_mm"].as_f64().unwrap();
    assert!((got - expected).abs() / 20.0 < 0.005, "{got}");
    assert!(std::fs::read_to_string(&nc).unwrap().contains("M30"));

    // A bad field is named with the file.
    std::fs::write(
        &input,
        json!({"part": "hole.stl", "entry": top, "target": [0, 0, 99]}).to_string(),
    )
    .unwrap();
    let out = std::process::Command::new(BIN)
        .args(["accessibility", input.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("input.json") && err.contains("`target`"),
        "{err}"
    );
}
