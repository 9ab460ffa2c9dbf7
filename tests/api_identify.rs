//! The `identify` job over HTTP: mean slotting forces synthesized by the engine's own force
//! model (not the closed form the identification inverts) for known coefficients, plus
//! noise, give the coefficients back; the material it makes simulates like the original;
//! bad measurements are refused naming the field.

mod common;

use std::f64::consts::PI;
use std::time::Duration;

use common::*;
use serde_json::{json, Value};

use millsim_engine::engagement::{EngagedSlice, Engagement};
use millsim_engine::physics::{CuttingConditions, ForceModel, Material};
use millsim_engine::tool::Tool;

const FEEDS: [f64; 5] = [0.02, 0.04, 0.06, 0.08, 0.10];
const DEPTH: f64 = 2.0;

/// Mean forces of a full slot at each feed by the engine's force model (a D10 4-flute 30°
/// helix flat end mill, `DEPTH` deep), each axis off by up to ±0.1 N of pseudo-random
/// "measurement noise", as (feed, fx, fy, fz).
fn synthesized(material: &str) -> Vec<[f64; 4]> {
    let truth = Material::builtin(material).unwrap().coefficients;
    let tool = Tool {
        helix_deg: 30.0,
        ..Tool::flat(10.0, 4)
    };
    let mut model = ForceModel::new(&tool, 100, 360).unwrap();
    let n = 40;
    let dz = DEPTH / n as f64;
    let slot = Engagement {
        slices: (0..n)
            .map(|i| EngagedSlice {
                z: (i as f64 + 0.5) * dz,
                dz,
                arcs: vec![(0.0, PI)].into(),
            })
            .collect(),
        feed_dir: [1.0, 0.0, 0.0],
        tool_axis: [0.0, 0.0, 1.0],
        end: Vec::new(),
    };
    // A fixed linear congruential sequence: the same noise at every run.
    let mut seed: u64 = 0x2545_f491_4f6c_dd1d;
    let mut noise = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 33) as f64 / (1u64 << 31) as f64 - 0.5) * 0.2
    };
    FEEDS
        .iter()
        .map(|&c| {
            let r = model
                .evaluate(
                    &slot,
                    &truth,
                    &CuttingConditions {
                        spindle_rpm: 3000.0,
                        feed_per_tooth: c,
                    },
                )
                .unwrap();
            [
                c,
                r.fx.mean + noise(),
                r.fy.mean + noise(),
                r.fz.mean + noise(),
            ]
        })
        .collect()
}

fn as_json(rows: &[[f64; 4]]) -> Value {
    Value::Array(
        rows.iter()
            .map(|r| json!({"feed_per_tooth_mm": r[0], "fx_n": r[1], "fy_n": r[2], "fz_n": r[3]}))
            .collect(),
    )
}

/// The same rows as CSV text, columns in another order than the JSON's.
fn as_csv(rows: &[[f64; 4]]) -> String {
    let mut text = String::from("fz_n,feed_per_tooth_mm,fx_n,fy_n\n");
    for r in rows {
        text += &format!("{},{},{},{}\n", r[3], r[0], r[1], r[2]);
    }
    text
}

async fn upload_tool(c: &reqwest::Client, s: &Server, body: Value) -> String {
    let (st, v) = post_json(c, s, "/v1/tools", &body).await;
    assert_eq!(st, 201, "{v}");
    v["id"].as_str().unwrap().to_string()
}

fn d10_helix30() -> Value {
    json!({"type": "flat", "diameter_mm": 10.0, "flutes": 4, "helix_deg": 30.0, "flute_length_mm": 20.0})
}

fn check_within_one_percent(got: &Value, material: &str) {
    let want = Material::builtin(material).unwrap().coefficients;
    for (name, w) in [
        ("ktc", want.ktc),
        ("krc", want.krc),
        ("kac", want.kac),
        ("kte", want.kte),
        ("kre", want.kre),
        ("kae", want.kae),
    ] {
        let g = got[name]
            .as_f64()
            .unwrap_or_else(|| panic!("{name} in {got}"));
        assert!(
            (g - w).abs() <= 0.01 * w.abs(),
            "{material} {name}: identified {g}, true {w}"
        );
    }
}

#[tokio::test]
async fn synthesized_forces_give_the_coefficients_back_and_the_material_simulates_like_the_original(
) {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let tool = upload_tool(&c, &s, d10_helix30()).await;
    let rows = synthesized("TC6");

    // JSON measurements, with a material made from the result.
    let body = json!({"kind": "identify", "inputs": {"tool": tool},
        "options": {"depth_mm": DEPTH, "measurements": as_json(&rows),
                    "create_material": {"name": "TC6 lot 7", "tests": "bench 2, 2026-11-25"}}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let done = wait_job(&c, &s, job["id"].as_str().unwrap(), Duration::from_secs(60)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let summary = &done["summary"];
    check_within_one_percent(&summary["coefficients"], "TC6");
    for axis in ["x", "y", "z"] {
        let fit = &summary["fit"][axis];
        assert!(fit["r_squared"].as_f64().unwrap() > 0.999, "{fit}");
        assert_eq!(fit["residuals_n"].as_array().unwrap().len(), FEEDS.len());
        // The noise is at most 0.1 N: so are the residuals of a straight line through it.
        assert!(fit["rms_residual_n"].as_f64().unwrap() < 0.1, "{fit}");
    }
    // Per-measurement rows with the residuals, as JSON pages and CSV.
    let csv = get_text(
        &c,
        &s,
        &format!("/v1/jobs/{}/blocks?format=csv", job["id"].as_str().unwrap()),
    )
    .await;
    assert!(
        csv.starts_with(
            "feed_per_tooth_mm,fx_n,fy_n,fz_n,fx_residual_n,fy_residual_n,fz_residual_n\n"
        ),
        "{csv}"
    );
    assert_eq!(csv.lines().count(), 1 + FEEDS.len());

    // The material it made: listed with the key's resources, sourced from the tests.
    let material_id = summary["material"]["id"].as_str().unwrap().to_string();
    let material = get_json(&c, &s, &format!("/v1/materials/{material_id}")).await;
    assert_eq!(material["summary"]["name"], "TC6 lot 7", "{material}");
    let source = material["summary"]["source"].as_str().unwrap();
    assert!(
        source.starts_with("identified from 5 slotting tests") && source.contains("bench 2"),
        "{source}"
    );
    let content = get_json(&c, &s, &format!("/v1/materials/{material_id}/content")).await;
    check_within_one_percent(&content["coefficients"], "TC6");

    // The same measurements as CSV text give the same coefficients.
    let body = json!({"kind": "identify", "inputs": {"tool": tool},
        "options": {"depth_mm": DEPTH, "measurements": as_csv(&rows)}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let from_csv = wait_job(&c, &s, job["id"].as_str().unwrap(), Duration::from_secs(60)).await;
    assert_eq!(from_csv["status"], "succeeded", "{from_csv}");
    for k in ["ktc", "krc", "kac", "kte", "kre", "kae"] {
        let (a, b) = (
            summary["coefficients"][k].as_f64().unwrap(),
            from_csv["summary"]["coefficients"][k].as_f64().unwrap(),
        );
        assert!((a - b).abs() <= 1e-9 * a.abs(), "{k}: {a} vs {b}");
    }
    assert!(from_csv["summary"].get("material").is_none());

    // A slot simulated with the identified material cuts with the forces of the original.
    let (st, stock) = post_json(&c, &s, "/v1/stocks", &slot_block()).await;
    assert_eq!(st, 201, "{stock}");
    let program = "G21 G90 G17\nS3000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-2\nG1 X60 F960\nG0 Z5\nM30\n";
    let mut peaks = Vec::new();
    for (inputs_material, options_material) in
        [(Some(material_id.as_str()), None), (None, Some("TC6"))]
    {
        let mut inputs = json!({"program": {"name": "slot.nc", "content": program},
                                "stock": stock["id"], "tool": tool});
        let mut options = json!({"cell_mm": 0.25});
        if let Some(m) = inputs_material {
            inputs["material"] = json!(m);
        }
        if let Some(m) = options_material {
            options["material"] = json!(m);
        }
        let (st, job) = post_json(
            &c,
            &s,
            "/v1/jobs",
            &json!({"kind": "simulate", "inputs": inputs, "options": options}),
        )
        .await;
        assert_eq!(st, 202, "{job}");
        let done = wait_job(
            &c,
            &s,
            job["id"].as_str().unwrap(),
            Duration::from_secs(120),
        )
        .await;
        assert_eq!(done["status"], "succeeded", "{done}");
        peaks.push(done["summary"]["force_peak_n"].as_f64().unwrap());
    }
    assert!(peaks[1] > 100.0, "the TC6 slot cuts: {peaks:?}");
    assert!(
        (peaks[0] - peaks[1]).abs() <= 0.01 * peaks[1],
        "identified vs built-in TC6 peak force: {peaks:?}"
    );
}

#[tokio::test]
async fn bad_measurements_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let tool = upload_tool(&c, &s, d10_helix30()).await;
    let rows = synthesized("Al6082-T6");
    let same_feed: Vec<[f64; 4]> = rows.iter().map(|r| [0.05, r[1], r[2], r[3]]).collect();
    let mut nan_csv = as_csv(&rows);
    nan_csv = nan_csv.replacen(
        &format!("{},{},{}", rows[1][0], rows[1][1], rows[1][2]),
        &format!("{},NaN,{}", rows[1][0], rows[1][2]),
        1,
    );
    // Dynamometer readings (the reaction on the part) given as they are: every force
    // negated, so the fit gives negative coefficients.
    let reaction: Vec<[f64; 4]> = rows.iter().map(|r| [r[0], -r[1], -r[2], -r[3]]).collect();
    let cases: Vec<(Value, &str, &str)> = vec![
        (
            as_json(&rows[..1]),
            "options.measurements",
            "at least 2 different feeds",
        ),
        (as_json(&same_feed), "options.measurements", "got 1"),
        (json!(nan_csv), "options.measurements[1].fx_n", "finite"),
        (
            json!("feed_per_tooth_mm,fx_n,fy_n\n0.1,1,2\n"),
            "options.measurements",
            "no column `fz_n`",
        ),
        (
            json!([{"feed_per_tooth_mm": 0.1, "fx_n": 1, "fy_n": 2}]),
            "options.measurements[0]",
            "fz_n",
        ),
        (as_json(&reaction), "options.measurements", "negative"),
        (json!(42), "options.measurements", "CSV"),
    ];
    for (measurements, field, says) in cases {
        let body = json!({"kind": "identify", "inputs": {"tool": tool},
            "options": {"depth_mm": DEPTH, "measurements": measurements}});
        let (st, p) = post_json(&c, &s, "/v1/jobs", &body).await;
        assert_eq!(st, 422, "{body} -> {p}");
        assert_eq!(p["field"], field, "{body} -> {p}");
        assert!(
            p["detail"].as_str().unwrap().contains(says),
            "{body} -> {p}"
        );
    }
    let (st, p) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "identify", "inputs": {"tool": tool},
                "options": {"depth_mm": -1, "measurements": as_json(&rows)}}),
    )
    .await;
    assert_eq!(
        (st, p["field"].as_str()),
        (422, Some("options.depth_mm")),
        "{p}"
    );
    let (st, p) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "identify", "options": {"depth_mm": DEPTH, "measurements": as_json(&rows)}}),
    )
    .await;
    assert_eq!((st, p["field"].as_str()), (422, Some("inputs.tool")), "{p}");
    // A ball end mill is not what the method models: the job fails, naming the tool.
    let ball = upload_tool(
        &c,
        &s,
        json!({"type": "ball", "diameter_mm": 10.0, "flutes": 2, "flute_length_mm": 20.0}),
    )
    .await;
    let (st, job) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "identify", "inputs": {"tool": ball},
                "options": {"depth_mm": DEPTH, "measurements": as_json(&rows)}}),
    )
    .await;
    assert_eq!(st, 202, "{job}");
    let done = wait_job(&c, &s, job["id"].as_str().unwrap(), Duration::from_secs(60)).await;
    assert_eq!(done["status"], "failed", "{done}");
    assert_eq!(done["error"]["field"], "inputs.tool", "{done}");
    assert_eq!(done["attempts"], 1);
}

/// Mean forces of a D10 two-flute ball slotting at two depths and three feeds each, by the
/// engine's force model on its own fine engagement (0.005 mm slices, 720 positions; the job
/// builds coarser ones), for Al7075-T6: (depth, feed, fx, fy, fz).
fn ball_slot_cuts() -> Vec<[f64; 5]> {
    let truth = Material::builtin("Al7075-T6").unwrap().coefficients;
    let tool = Tool::ball(10.0, 2);
    let mut model = ForceModel::new(&tool, 50, 720).unwrap();
    let mut out = Vec::new();
    for depth in [1.0, 2.5] {
        let n = (depth / 0.005_f64).round() as usize;
        let dz = depth / n as f64;
        let slot = Engagement {
            slices: (0..n)
                .map(|i| EngagedSlice {
                    z: (i as f64 + 0.5) * dz,
                    dz,
                    arcs: vec![(0.0, PI)].into(),
                })
                .collect(),
            feed_dir: [1.0, 0.0, 0.0],
            tool_axis: [0.0, 0.0, 1.0],
            end: Vec::new(),
        };
        for c in [0.03, 0.06, 0.1] {
            let r = model
                .evaluate(
                    &slot,
                    &truth,
                    &CuttingConditions {
                        spindle_rpm: 8000.0,
                        feed_per_tooth: c,
                    },
                )
                .unwrap();
            out.push([depth, c, r.fx.mean, r.fy.mean, r.fz.mean]);
        }
    }
    out
}

#[tokio::test]
async fn cuts_of_a_ball_end_mill_give_the_coefficients_back_with_intervals() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let ball = upload_tool(
        &c,
        &s,
        json!({"type": "ball", "diameter_mm": 10.0, "flutes": 2, "helix_deg": 30.0, "flute_length_mm": 20.0}),
    )
    .await;
    let rows = ball_slot_cuts();
    // CSV with the slot's angles given on every row but one (the default is the slot).
    let mut csv = String::from("depth_mm,feed_per_tooth_mm,entry_deg,exit_deg,fx_n,fy_n,fz_n\n");
    for (i, r) in rows.iter().enumerate() {
        let angles = if i == 0 {
            ",".to_string()
        } else {
            "0,180".to_string()
        };
        csv += &format!("{},{},{angles},{},{},{}\n", r[0], r[1], r[2], r[3], r[4]);
    }
    let body = json!({"kind": "identify", "inputs": {"tool": ball},
        "options": {"cuts": csv, "create_material": {"name": "Al7075 ball tests"}}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    let done = wait_job(&c, &s, id, Duration::from_secs(60)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let summary = &done["summary"];
    assert_eq!(summary["method"], "force model least squares", "{summary}");
    assert_eq!(summary["model"], "linear");
    check_within_one_percent(&summary["coefficients"], "Al7075-T6");
    assert_eq!(summary["degrees_of_freedom"], 3 * rows.len() - 6);
    let want = Material::builtin("Al7075-T6").unwrap().coefficients;
    for (name, w) in [("ktc", want.ktc), ("kte", want.kte), ("kac", want.kac)] {
        let ci = &summary["confidence_95"][name];
        let (lo, hi) = (ci["low"].as_f64().unwrap(), ci["high"].as_f64().unwrap());
        assert!(
            lo < hi && ci["standard_error"].as_f64().unwrap() > 0.0,
            "{ci}"
        );
        // Noise-free forces: the interval is the models' discretization difference, tight.
        assert!((hi - lo) < 0.02 * w.abs(), "{name}: {ci}");
    }
    for axis in ["x", "y", "z"] {
        assert!(
            summary["fit"][axis]["r_squared"].as_f64().unwrap() > 0.9999,
            "{summary}"
        );
    }
    assert!(summary["tests"]
        .as_str()
        .unwrap()
        .starts_with("6 cuts at 3 feeds"));
    let csv_out = get_text(&c, &s, &format!("/v1/jobs/{id}/blocks?format=csv")).await;
    assert!(
        csv_out.starts_with("cut,depth_mm,feed_per_tooth_mm,"),
        "{csv_out}"
    );
    assert_eq!(csv_out.lines().count(), 1 + rows.len());
    let material = summary["material"]["id"].as_str().unwrap();
    let content = get_json(&c, &s, &format!("/v1/materials/{material}/content")).await;
    check_within_one_percent(&content["coefficients"], "Al7075-T6");

    // Ill-posed sets are refused at submission, naming the option: the exponential law
    // needs three feeds, these cuts have two; and one feed never separates the terms.
    let two_feeds: Vec<Value> = rows
        .iter()
        .filter(|r| r[1] < 0.08)
        .map(|r| json!({"depth_mm": r[0], "feed_per_tooth_mm": r[1], "fx_n": r[2], "fy_n": r[3], "fz_n": r[4]}))
        .collect();
    let one_feed: Vec<Value> = rows
        .iter()
        .filter(|r| r[1] == 0.06)
        .map(|r| json!({"depth_mm": r[0], "feed_per_tooth_mm": r[1], "fx_n": r[2], "fy_n": r[3], "fz_n": r[4]}))
        .collect();
    for (options, says) in [
        (
            json!({"cuts": two_feeds, "model": "exponential"}),
            "at least 3 different feeds",
        ),
        (json!({"cuts": one_feed}), "single feed"),
        (
            json!({"cuts": [{"depth_mm": 1, "feed_per_tooth_mm": 0.1, "fx_n": 1, "fy_n": 2, "fz_n": 3, "width_mm": 2}]}),
            "milling",
        ),
        (json!({"cuts": two_feeds, "depth_mm": 2}), "not both"),
    ] {
        let body = json!({"kind": "identify", "inputs": {"tool": ball}, "options": options});
        let (st, p) = post_json(&c, &s, "/v1/jobs", &body).await;
        assert_eq!(st, 422, "{body} -> {p}");
        assert!(
            p["field"].as_str().unwrap().starts_with("options.cuts"),
            "{body} -> {p}"
        );
        assert!(
            p["detail"].as_str().unwrap().contains(says),
            "{body} -> {p}"
        );
    }
}

#[tokio::test]
async fn a_programs_measured_line_forces_give_the_coefficients_back() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let tool = upload_tool(
        &c,
        &s,
        json!({"type": "bull", "diameter_mm": 8.0, "corner_radius_mm": 1.0, "flutes": 4, "flute_length_mm": 20.0}),
    )
    .await;
    let (st, stock) = post_json(&c, &s, "/v1/stocks", &slot_block()).await;
    assert_eq!(st, 201, "{stock}");
    // Slots at 1 and 2 mm at four feeds, then a side cut beside the deeper slot.
    let program = "G21 G90 G17\nS8000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-1\nG1 X30 F800\nG1 X60 F2400\nG0 Z5\nG0 X-10 Y-10\nG0 Z-2\nG1 X30 F1600\nG1 X60 F3200\nG0 Z5\nG0 X-10 Y-15\nG0 Z-2\nG1 X60 F2000\nG0 Z5\nM30\n";
    let inputs = json!({"program": {"name": "dyno.nc", "content": program},
                        "stock": stock["id"], "tool": tool});
    // The "dynamometer": a simulate job with TC6, its rows' mean forces per line.
    let (st, job) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "simulate", "inputs": inputs,
                "options": {"material": "TC6", "cell_mm": 0.25, "force_positions": 360}}),
    )
    .await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    let done = wait_job(&c, &s, id, Duration::from_secs(120)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let rows = get_json(&c, &s, &format!("/v1/jobs/{id}/blocks?limit=1000")).await;
    let mut csv = String::from("line,fx_n,fy_n,fz_n\n");
    let mut count = 0;
    for r in rows["items"].as_array().unwrap() {
        if r["force_mean_n"].as_f64().unwrap_or(0.0) > 0.0 {
            csv += &format!(
                "{},{},{},{}\n",
                r["line"], r["fx_mean_n"], r["fy_mean_n"], r["fz_mean_n"]
            );
            count += 1;
        }
    }
    assert_eq!(count, 5, "{csv}");

    let body = json!({"kind": "identify", "inputs": inputs,
        "options": {"line_forces": csv, "simulation": {"cell_mm": 0.25, "force_positions": 360},
                    "create_material": {"name": "TC6 from the dyno program"}}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let id = job["id"].as_str().unwrap();
    let done = wait_job(&c, &s, id, Duration::from_secs(120)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let summary = &done["summary"];
    assert_eq!(summary["lines"], 5, "{summary}");
    check_within_one_percent(&summary["coefficients"], "TC6");
    let csv_out = get_text(&c, &s, &format!("/v1/jobs/{id}/blocks?format=csv")).await;
    assert!(csv_out.starts_with("line,feed_per_tooth_mm,"), "{csv_out}");
    assert!(summary["material"]["source"]
        .as_str()
        .unwrap()
        .contains("5 lines of dyno.nc"));

    // A line that does not cut has no cutting force to fit: refused naming it.
    let air = csv.replacen("\n6,", "\n3,", 1);
    let body = json!({"kind": "identify", "inputs": inputs, "options": {"line_forces": air}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let done = wait_job(
        &c,
        &s,
        job["id"].as_str().unwrap(),
        Duration::from_secs(120),
    )
    .await;
    assert_eq!(done["status"], "failed", "{done}");
    assert_eq!(
        done["error"]["field"], "options.line_forces[0].line",
        "{done}"
    );
    // Without the program: refused naming the input.
    let body =
        json!({"kind": "identify", "inputs": {"tool": tool}, "options": {"line_forces": csv}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    if st == 202 {
        let done = wait_job(&c, &s, job["id"].as_str().unwrap(), Duration::from_secs(60)).await;
        assert_eq!(done["error"]["field"], "inputs.program", "{done}");
    } else {
        assert_eq!(st, 422, "{job}");
    }
}

#[tokio::test]
async fn slot_measurements_fit_the_exponential_law() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let tool = upload_tool(&c, &s, d10_helix30()).await;
    // Kienzle-type coefficients (K at a 1 mm chip) with exponents, slot forces by the
    // engine's model at 720 positions (the job uses 360).
    let truth = millsim_engine::physics::CuttingCoefficients {
        ktc: 1100.0,
        krc: 380.0,
        kac: 260.0,
        kte: 24.0,
        kre: 43.0,
        kae: 5.0,
        mtc: 0.22,
        mrc: 0.38,
        mac: 0.18,
    };
    let t = Tool {
        helix_deg: 30.0,
        ..Tool::flat(10.0, 4)
    };
    let mut model = ForceModel::new(&t, 100, 720).unwrap();
    let n = 400;
    let dz = DEPTH / n as f64;
    let slot = Engagement {
        slices: (0..n)
            .map(|i| EngagedSlice {
                z: (i as f64 + 0.5) * dz,
                dz,
                arcs: vec![(0.0, PI)].into(),
            })
            .collect(),
        feed_dir: [1.0, 0.0, 0.0],
        tool_axis: [0.0, 0.0, 1.0],
        end: Vec::new(),
    };
    let rows: Vec<[f64; 4]> = [0.02, 0.04, 0.07, 0.1, 0.14]
        .iter()
        .map(|&f| {
            let r = model
                .evaluate(
                    &slot,
                    &truth,
                    &CuttingConditions {
                        spindle_rpm: 3000.0,
                        feed_per_tooth: f,
                    },
                )
                .unwrap();
            [f, r.fx.mean, r.fy.mean, r.fz.mean]
        })
        .collect();
    let body = json!({"kind": "identify", "inputs": {"tool": tool},
        "options": {"depth_mm": DEPTH, "measurements": as_json(&rows), "model": "exponential"}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let done = wait_job(&c, &s, job["id"].as_str().unwrap(), Duration::from_secs(60)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let summary = &done["summary"];
    assert_eq!(summary["model"], "exponential", "{summary}");
    let k = &summary["coefficients"];
    for (name, want, tol) in [
        ("ktc", truth.ktc, 0.01),
        ("krc", truth.krc, 0.01),
        ("kac", truth.kac, 0.01),
        ("kte", truth.kte, 0.01),
        ("kre", truth.kre, 0.01),
        ("kae", truth.kae, 0.01),
        ("mtc", truth.mtc, 0.01),
        ("mrc", truth.mrc, 0.01),
        ("mac", truth.mac, 0.01),
    ] {
        let got = k[name].as_f64().unwrap_or_else(|| panic!("{name} in {k}"));
        assert!(
            (got - want).abs() <= tol * want,
            "{name}: identified {got}, true {want}"
        );
    }
    assert!(summary["confidence_95"]["mrc"].is_object(), "{summary}");
    // Two feeds cannot give the exponents: refused at submission.
    let body = json!({"kind": "identify", "inputs": {"tool": tool},
        "options": {"depth_mm": DEPTH, "measurements": as_json(&rows[..2]), "model": "exponential"}});
    let (st, p) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 422, "{p}");
    assert_eq!(p["field"], "options.measurements", "{p}");
}

/// Issue 34: conditions outside a milling test's range are refused at submission, naming
/// the field (feeds of 1e308 were answered with all-zero coefficients, a depth of 1e-300
/// with a ktc of 2e304), and so is a fit whose coefficients no material has.
#[tokio::test]
async fn conditions_outside_a_milling_tests_range_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let tool = upload_tool(&c, &s, d10_helix30()).await;
    let rows = synthesized("Al6082-T6");
    let huge_feeds: Vec<[f64; 4]> = rows
        .iter()
        .enumerate()
        .map(|(i, r)| [1e308 / (i + 1) as f64, r[1], r[2], r[3]])
        .collect();
    let mut huge_force = rows.clone();
    huge_force[2][1] = 2e6;
    let mut wide_feed = rows.clone();
    wide_feed[3][0] = 20.0;
    let measured =
        |depth: f64, rows: &[[f64; 4]]| json!({"depth_mm": depth, "measurements": as_json(rows)});
    let cut = |depth: f64, fz: f64| {
        json!({"cuts": [
            {"depth_mm": depth, "feed_per_tooth_mm": 0.05, "fx_n": -100, "fy_n": 300, "fz_n": fz},
            {"depth_mm": depth, "feed_per_tooth_mm": 0.1, "fx_n": -150, "fy_n": 500, "fz_n": fz}]})
    };
    let mut exponential = measured(DEPTH, &wide_feed);
    exponential["model"] = json!("exponential");
    let cases: Vec<(Value, &str, &str)> = vec![
        (
            measured(DEPTH, &huge_feeds),
            "options.measurements[0].feed_per_tooth_mm",
            "feed per tooth",
        ),
        (measured(1e-300, &rows), "options.depth_mm", "axial depth"),
        (measured(500.0, &rows), "options.depth_mm", "axial depth"),
        (
            measured(DEPTH, &huge_force),
            "options.measurements[2].fx_n",
            "force",
        ),
        (
            exponential,
            "options.measurements[3].feed_per_tooth_mm",
            "feed per tooth",
        ),
        (
            cut(1e-300, -20.0),
            "options.cuts[0].depth_mm",
            "axial depth",
        ),
        (cut(2.0, -5e6), "options.cuts[0].fz_n", "force"),
        // A 2 mm test's forces given for a 1 µm depth: every number in range, a ktc of
        // about 10^6 N/mm².
        (
            measured(1e-3, &rows),
            "options.measurements",
            "beyond any material",
        ),
    ];
    for (options, field, says) in cases {
        let body = json!({"kind": "identify", "inputs": {"tool": tool}, "options": options});
        let res = c.post(s.url("/v1/jobs")).json(&body).send().await.unwrap();
        let kind = res
            .headers()
            .get("content-type")
            .map(|v| v.to_str().unwrap().to_string());
        let (st, p) = json(res).await;
        assert_eq!(st, 422, "{body} -> {p}");
        assert_eq!(kind.as_deref(), Some("application/problem+json"));
        assert_eq!(p["field"], field, "{body} -> {p}");
        assert!(
            p["detail"].as_str().unwrap().contains(says),
            "{body} -> {p}"
        );
    }
    // The same rows at their own depth still fit.
    let body =
        json!({"kind": "identify", "inputs": {"tool": tool}, "options": measured(DEPTH, &rows)});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
}
