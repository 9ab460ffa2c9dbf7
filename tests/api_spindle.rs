//! Issue 33 over HTTP: `options.spindle` on a simulate and an optimize job (the speed chosen
//! out of an unstable region, the rows and the /program result at that speed, the summary's
//! spindle), and bad values refused naming the field.

mod common;

use std::time::Duration;

use serde_json::{json, Value};

use common::*;

#[tokio::test]
async fn the_spindle_speed_is_chosen_out_of_chatter_and_bad_values_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let stock = create(&c, &s, "/v1/stocks", slot_block()).await;
    let tool = create(&c, &s, "/v1/tools", json!({"type": "flat", "diameter_mm": 10, "flutes": 2, "helix_deg": 0, "flute_length_mm": 30})).await;
    let machine = create(&c, &s, "/v1/machines", json!({"name": "hsm", "rapid_rate": 30000, "max_feed": 20000,
        "acceleration": [2000, 2000, 2000], "spindle_min_rpm": 1000, "spindle_max_rpm": 30000, "rated_power": 15000})).await;
    // A 1 mm slot at S10000: the benchmark's mode chatters there (margin ≈ 3).
    let program =
        "G21 G90 G17 G94\nS10000 M3\nG0 X-10 Y0 Z5\nG1 Z-1 F500\nG1 X90 F1000\nG0 Z5\nM5\nM30\n";
    let inputs = json!({"program": {"name": "slot.nc", "content": program}, "stock": stock, "tool": tool, "machine": machine});
    let spindle = json!({"choose": true, "rpm": {"from": 5000, "to": 25000}, "speeds": 41,
        "modes_x": [{"freq_hz": 922, "damping": 0.011, "mass_kg": 0.03993}], "method": "sdm", "steps_per_period": 40});
    let job = run_job(
        &c,
        &s,
        &json!({"kind": "simulate", "inputs": inputs,
        "options": {"material": "Al7075-T6", "cell_mm": 0.25, "spindle": spindle}}),
        Duration::from_secs(300),
    )
    .await;
    let sp = &job["summary"]["spindle"];
    let chosen = sp["chosen_rpm"].as_f64().unwrap();
    assert_eq!(sp["programmed_rpm"], 10000.0, "{sp}");
    assert!(
        sp["chatter_margin_max_before"].as_f64().unwrap() > 1.0,
        "{sp}"
    );
    assert!(
        sp["chatter_margin_max_after"].as_f64().unwrap() < 1.0,
        "{sp}"
    );
    assert_eq!(sp["stable"], true, "{sp}");
    assert!(sp["reason"].as_str().unwrap().contains("pocket"), "{sp}");
    let id = job["id"].as_str().unwrap();
    let rows = get_json(&c, &s, &format!("/v1/jobs/{id}/blocks?limit=100")).await["items"]
        .as_array()
        .unwrap()
        .clone();
    let slot = rows.iter().find(|r| r["line"] == 5).unwrap();
    assert!(slot["chatter_margin"].as_f64().unwrap() < 1.0, "{slot}");
    let text = c
        .get(s.url(&format!("/v1/jobs/{id}/program")))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(text.contains(&format!("S{} M3", chosen as i64)), "{text}");

    // Optimize: the feeds scheduled at the chosen speed, written with the S word.
    let opt = run_job(&c, &s, &json!({"kind": "optimize", "inputs": inputs,
        "options": {"material": "Al7075-T6", "cell_mm": 0.25, "spindle": spindle, "limits": {"max_force": 500}}}), Duration::from_secs(300)).await;
    assert_eq!(opt["summary"]["spindle"]["chosen_rpm"], chosen);
    assert!(
        opt["summary"]["optimization"]["peak_force_after"]
            .as_f64()
            .unwrap()
            <= 500.0 * 1.02
    );

    // Bad values: 422 naming the field.
    for (bad, field) in [
        (
            json!({"rpm": {"from": 9000, "to": 8000}, "modes_x": spindle["modes_x"]}),
            "options.spindle.rpm.to",
        ),
        (
            json!({"rpm": {"from": 5000, "to": 25000}}),
            "options.spindle.modes_x",
        ),
        (
            json!({"rpm": {"from": 5000, "to": 25000}, "speeds": 5000, "modes_x": spindle["modes_x"]}),
            "options.spindle.speeds",
        ),
    ] {
        let (st, v) = post_json(
            &c,
            &s,
            "/v1/jobs",
            &json!({"kind": "simulate", "inputs": inputs,
            "options": {"material": "Al7075-T6", "spindle": bad}}),
        )
        .await;
        assert_eq!(st, 422, "{v}");
        assert!(v.to_string().contains(field), "{field}: {v}");
    }
}

/// `millsim run --spindle` on examples/spindle (the benchmark slot): the report prints the
/// choice and the program at the chosen speed is written beside the summary.
#[test]
fn millsim_run_prints_the_chosen_speed() {
    let dir = tempfile::tempdir().unwrap();
    let ex = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/spindle");
    let out = std::process::Command::new(BIN)
        .arg("run")
        .arg("--stock")
        .arg(ex.join("stock.json"))
        .arg("--program")
        .arg(ex.join("slot.nc"))
        .arg("--tool")
        .arg(format!("T1={}", ex.join("tool.json").display()))
        .arg("--material")
        .arg(ex.join("material.json"))
        .arg("--machine")
        .arg(ex.join("machine.json"))
        .arg("--spindle")
        .arg(ex.join("spindle.json"))
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    let report = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{report}");
    assert!(
        report.contains("spindle: 24750 rpm chosen (10000 programmed), stable"),
        "{report}"
    );
    let summary: Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("summary.json")).unwrap()).unwrap();
    assert!(
        summary["spindle"]["chatter_margin_max_after"]
            .as_f64()
            .unwrap()
            < 1.0
    );
    let text = std::fs::read_to_string(dir.path().join("slot.opt.nc")).unwrap();
    let original = std::fs::read_to_string(ex.join("slot.nc")).unwrap();
    assert_eq!(
        text,
        original
            .replace("S10000", "S24750")
            .replace("F500", "F1237.5")
            .replace("F1000", "F2475")
    );
}
