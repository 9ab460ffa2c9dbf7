//! Issue 31 over HTTP: a tool's material and stiffness fields, the rows' deflection
//! columns and the summary's per-tool worst, an optimize job held to a deflection limit
//! alone, and a thin wall's modes refused with the field named when malformed.

mod common;

use std::time::Duration;

use serde_json::json;

use common::*;

#[tokio::test]
async fn a_slender_tool_reports_its_deflection_and_is_held_to_a_limit() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let stock = create(&c, &s, "/v1/stocks", slot_block()).await;
    let tool = create(&c, &s, "/v1/tools", json!({"type": "flat", "diameter_mm": 10, "flutes": 2, "helix_deg": 0,
        "flute_length_mm": 1, "shank_diameter_mm": 10, "stickout_mm": 80, "young_modulus_gpa": 600, "tool_material": "carbide"})).await;
    // Half immersion, 0.5 mm deep, the material on −y.
    let program = "G21 G90\nT1 M6\nS6000 M3\nG0 X-10 Y20 Z5\nG0 Z-0.5\nG1 X110 F600\nG0 Z5\nM30\n";
    let inputs =
        json!({"program": {"name": "wall.nc", "content": program}, "stock": stock, "tool": tool});
    let job = run_job(&c, &s, &json!({"kind": "simulate", "inputs": inputs, "options": {"material": "Al7075-T6", "cell_mm": 0.1}}), Duration::from_secs(120)).await;
    let id = job["id"].as_str().unwrap();
    let rows = get_json(&c, &s, &format!("/v1/jobs/{id}/blocks?limit=100")).await["items"]
        .as_array()
        .unwrap()
        .clone();
    let pass = rows.iter().find(|r| r["line"] == 6).unwrap();
    let deflection = pass["deflection_peak_um"].as_f64().unwrap();
    assert!(deflection > 5.0, "{pass}");
    assert!(pass["form_error_um"].as_f64().unwrap() > 0.0, "{pass}");
    assert!(pass["bending_stress_mpa"].as_f64().unwrap() > 0.0, "{pass}");
    let worst = &job["summary"]["deflection"][0];
    assert_eq!(
        (worst["tool"].as_u64(), worst["deflection_line"].as_u64()),
        (Some(1), Some(6)),
        "{worst}"
    );

    // A deflection limit alone is a target (no force limit needed); the pass is slowed.
    let limit = 0.8 * deflection;
    let opt = run_job(&c, &s, &json!({"kind": "optimize", "inputs": inputs,
        "options": {"material": "Al7075-T6", "cell_mm": 0.1, "limits": {"max_deflection_um": limit, "max_feed": 5000}}}), Duration::from_secs(120)).await;
    let oid = opt["id"].as_str().unwrap();
    let rows = get_json(&c, &s, &format!("/v1/jobs/{oid}/blocks?limit=100")).await["items"]
        .as_array()
        .unwrap()
        .clone();
    let pass = rows.iter().find(|r| r["line"] == 6).unwrap();
    assert_eq!(pass["governing"], "deflection", "{pass}");
    assert!(pass["feed_opt_mm_min"].as_f64().unwrap() < 600.0, "{pass}");

    // A thin wall without modes normal to the feed: 422 naming the field.
    let (st, v) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "simulate", "inputs": inputs,
        "options": {"material": "Al7075-T6", "workpiece": {"allowance": [{"allowance_mm": 1}]}}}),
    )
    .await;
    assert_eq!(st, 422, "{v}");
    assert!(
        v.to_string()
            .contains("options.workpiece.allowance[0].modes_y"),
        "{v}"
    );
}
