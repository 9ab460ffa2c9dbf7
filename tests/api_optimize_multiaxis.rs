//! An optimize job on a simultaneous 5-axis program over HTTP: LinuxCNC's impeller sample
//! (G93, tool-centre-point reading) on an xyz_ac machine.

mod common;

use std::collections::BTreeMap;
use std::time::Duration;

use common::*;
use serde_json::json;

/// Per line of a blocks.csv: the values of the named columns.
fn columns(csv: &str, names: &[&str]) -> BTreeMap<u32, Vec<f64>> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let at: Vec<usize> = names
        .iter()
        .map(|n| header.iter().position(|h| h == n).unwrap())
        .collect();
    let line = header.iter().position(|h| *h == "line").unwrap();
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (
                f[line].parse().unwrap(),
                at.iter().map(|&i| f[i].parse().unwrap_or(0.0)).collect(),
            )
        })
        .collect()
}

#[tokio::test]
async fn optimize_the_corpus_impeller_at_the_tool_tip_and_resimulate_it() {
    let path = corpus("gcode/linuxcnc_5axis_impeller_7bl_xyzac_g93.ngc");
    if !path.exists() {
        skip(&format!("{} (the shared corpus)", path.display()));
        return;
    }
    let original = std::fs::read_to_string(&path).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let mut ids = Vec::new();
    for (route, body) in [
        (
            "/v1/stocks",
            json!({"kind": "cylinder", "base_center": [0, 0, 0], "radius": 45, "height": 30}),
        ),
        (
            "/v1/tools",
            json!({"type": "ball", "diameter_mm": 6.0, "flutes": 2, "flute_length_mm": 20.0}),
        ),
        (
            "/v1/machines",
            json!({"name": "AC trunnion", "kinematics": "xyz_ac", "rapid_rate": 24000.0, "max_feed": 10000.0,
                   "acceleration": [2000.0, 2000.0, 1500.0], "spindle_min_rpm": 0.0, "spindle_max_rpm": 20000.0,
                   "rated_power": 11000.0, "max_rotary_speed_deg_min": 20000.0}),
        ),
    ] {
        let (st, v) = post_json(&c, &s, route, &body).await;
        assert_eq!(st, 201, "{route}: {v}");
        ids.push(v["id"].as_str().unwrap().to_string());
    }
    let program = upload_program(&c, &s, &path).await;
    let inputs = json!({"program": program, "stock": ids[0], "tool": ids[1], "machine": ids[2]});
    let options = json!({"material": "TC6", "cell_mm": 0.5, "axes": "tool_tip",
                         "passthrough_m_codes": [428, 429]});
    let limit = 800.0;
    let mut opt_options = options.clone();
    opt_options["limits"] = json!({"max_force": limit});
    let (st, job) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "optimize", "inputs": inputs, "options": opt_options}),
    )
    .await;
    assert_eq!(st, 202, "{job}");
    let job_id = job["id"].as_str().unwrap().to_string();
    let done = wait_job(&c, &s, &job_id, Duration::from_secs(300)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let opt = &done["summary"]["optimization"];
    println!(
        "impeller at {limit} N: cycle time {:.0} s -> {:.0} s; unreachable {}",
        opt["cycle_time_before_s"], opt["cycle_time_after_s"], opt["force_limit_unreachable_moves"]
    );

    // Only F words change, and every G93 feed block keeps its F (not modal in G93).
    let text = get_text(&c, &s, &format!("/v1/jobs/{job_id}/program")).await;
    let strip = |l: &str| -> String {
        l.split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")
            .split(" F")
            .next()
            .unwrap()
            .to_string()
    };
    assert_eq!(text.lines().count(), original.lines().count());
    let mut changed = 0;
    for (a, b) in original.lines().zip(text.lines()) {
        assert_eq!(strip(a), strip(b));
        assert_eq!(a.contains('F'), b.contains('F'), "{a} / {b}");
        changed += usize::from(a != b);
    }
    assert!(changed > 1000, "{changed} blocks changed");

    // The optimized program simulated again: every move at the peak the optimizer
    // predicted, so at most 0.5 % over the limit unless it is listed as unreachable.
    let predicted = columns(
        &get_text(&c, &s, &format!("/v1/jobs/{job_id}/blocks?format=csv")).await,
        &["force_peak_opt_n"],
    );
    let (st, again) = json(
        c.post(s.url("/v1/programs?name=impeller.opt.ngc"))
            .body(text)
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 201, "{again}");
    let mut resim_inputs = inputs.clone();
    resim_inputs["program"] = again["id"].clone();
    let (st, job) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "simulate", "inputs": resim_inputs, "options": options}),
    )
    .await;
    assert_eq!(st, 202, "{job}");
    let resim_id = job["id"].as_str().unwrap().to_string();
    let resim = wait_job(&c, &s, &resim_id, Duration::from_secs(300)).await;
    assert_eq!(resim["status"], "succeeded", "{resim}");
    let peaks = columns(
        &get_text(&c, &s, &format!("/v1/jobs/{resim_id}/blocks?format=csv")).await,
        &["force_peak_n"],
    );
    let mut unreachable = 0;
    for (line, p) in &peaks {
        let (peak, expected) = (p[0], predicted[line][0]);
        assert!(
            (peak - expected).abs() <= 0.005 * limit,
            "line {line}: {peak} N re-simulated vs {expected} N predicted"
        );
        if peak > limit * 1.005 {
            unreachable += 1;
        }
    }
    assert_eq!(
        opt["force_limit_unreachable_moves"].as_u64().unwrap(),
        unreachable,
        "{opt}"
    );
    let listed: Vec<u64> = opt["force_limit_unreachable_lines"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    for line in &listed {
        assert!(peaks[&(*line as u32)][0] > limit * 1.005, "line {line}");
    }
}
