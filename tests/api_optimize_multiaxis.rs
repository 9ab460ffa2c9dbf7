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

/// An optimized 5-axis program that starts with a tool change: the tool change's row has no
/// optimized tip speed, yet every row of a page names every column of the job (null where
/// it has no value), and the CSV's column filter takes the column.
#[tokio::test]
async fn a_tool_change_first_optimize_names_every_column_in_every_row() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let mut ids = Vec::new();
    for (route, body) in [
        (
            "/v1/stocks",
            json!({"kind": "cylinder", "base_center": [0, 0, -40.5], "radius": 10, "height": 40}),
        ),
        (
            "/v1/tools",
            json!({"type": "flat", "diameter_mm": 6.0, "flutes": 3, "flute_length_mm": 20.0}),
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
    // Tool-centre-point control: a tilting cut into the cylinder, then a C turn.
    let program = "G21 G90 G94\nT1 M6\nS8000 M3\nG0 Z30\nG43.4 H0\nG0 A90 C0\nG0 X0 Y30 Z-5\nG0 Y8\nG1 Z-15 A80 F600\nG1 C20 F400\nG0 Y30\nG0 Z40\nG49\nM30\n";
    let inputs = json!({"program": {"name": "tc.nc", "content": program}, "stock": ids[0], "tool": ids[1], "machine": ids[2]});
    let done = run_job(
        &c,
        &s,
        &json!({"kind": "optimize", "inputs": inputs,
                "options": {"material": "Al7075-T6", "cell_mm": 0.25, "limits": {"max_force": 300}}}),
        Duration::from_secs(120),
    )
    .await;
    let id = done["id"].as_str().unwrap();
    let declared: Vec<String> =
        serde_json::from_value(done["summary"]["row_columns"].clone()).unwrap();
    assert!(
        declared.iter().any(|c| c == "tip_speed_opt_mm_min"),
        "{declared:?}"
    );
    let mut want: Vec<&str> = declared.iter().map(String::as_str).collect();
    want.sort_unstable();
    // A page that starts with the tool change, and the whole job on one page.
    for limit in [1, 100] {
        let page = get_json(&c, &s, &format!("/v1/jobs/{id}/blocks?limit={limit}")).await;
        let items = page["items"].as_array().unwrap();
        assert_eq!(items[0]["kind"], "tool_change", "{}", items[0]);
        assert!(items[0]["tip_speed_opt_mm_min"].is_null());
        for row in items {
            let mut keys: Vec<&str> = row
                .as_object()
                .unwrap()
                .keys()
                .map(String::as_str)
                .collect();
            keys.sort_unstable();
            assert_eq!(keys, want, "{row}");
        }
        if limit == 100 {
            let cut = items.iter().find(|r| r["line"] == 9).unwrap();
            assert!(cut["tip_speed_opt_mm_min"].as_f64().unwrap() > 0.0, "{cut}");
        }
    }
    let csv = get_text(
        &c,
        &s,
        &format!("/v1/jobs/{id}/blocks?format=csv&columns=line,tip_speed_opt_mm_min"),
    )
    .await;
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("line,tip_speed_opt_mm_min"), "{csv}");
    let cut = lines.find(|l| l.starts_with("9,")).unwrap();
    assert!(cut[2..].parse::<f64>().unwrap() > 0.0, "{cut}");
}
