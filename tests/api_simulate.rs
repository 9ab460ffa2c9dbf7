//! The simulate job over HTTP: inputs by id, per-move rows, summary, final stock.

mod common;

use std::time::Duration;

use common::*;
use serde_json::json;

/// The blocks.csv columns outside checks read; optimize jobs add OPT_COLUMNS.
const INTERFACE_COLUMNS: &str = "block,line,tool,kind,length_mm,feed_mm_min,spindle_rpm,time_s,removed_mm3,mrr_mm3_s,axial_depth_mm,radial_width_mm,entry_deg,exit_deg,chip_max_mm,force_peak_n,force_mean_n,fx_mean_n,fy_mean_n,fz_mean_n,torque_peak_nm,power_peak_w,energy_j,air_fraction,flags";
const OPT_COLUMNS: &str = "feed_opt_mm_min,time_opt_s,force_peak_opt_n,force_mean_opt_n,torque_peak_opt_nm,power_mean_opt_w,power_peak_opt_w,governing";

/// The block stock (100 × 40 × 10 mm, top at z = 0) and flat D10 4-flute zero-helix tool both
/// tests cut their slot with; returns their ids.
async fn slot_stock_and_tool(c: &reqwest::Client, s: &Server) -> (String, String) {
    let block = slot_block();
    let (st, v) = post_json(c, s, "/v1/stocks", &block).await;
    assert_eq!(st, 201, "{v}");
    (
        v["id"].as_str().unwrap().to_string(),
        post_slot_tool(c, s).await,
    )
}

#[tokio::test]
async fn simulate_a_slot_and_fetch_rows_summary_and_final_stock() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let id = |v: serde_json::Value| v["id"].as_str().unwrap().to_string();
    let (stock, tool) = slot_stock_and_tool(&c, &s).await;
    let program = "G21 G90 G17\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X60 F4000\nG0 Z5\nM30\n";
    let prog = post_program(&c, &s, "slot.nc", program).await;
    // A design part up to z = −3 (STL, as a stock resource): the 5 mm slot gouges it 2 mm.
    let part =
        millsim_engine::geometry::Stock::block([0.0, -20.0, -10.0], [100.0, 20.0, -3.0], 0.25)
            .unwrap();
    let (stl, _) = millsim_engine::geometry::export_stl_vec(&part).unwrap();
    let (st, part) = post_stl(&c, &s, "/v1/stocks", stl).await;
    assert_eq!(st, 201, "{part}");
    let body = json!({"kind": "simulate", "inputs": {"program": prog, "stock": stock, "tool": tool, "part": id(part)},
                      "options": {"material": "Al7075-T6", "cell_mm": 0.25}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let job_id = id(job);
    let done = wait_job(&c, &s, &job_id, Duration::from_secs(120)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let summary = &done["summary"];
    let analytic = 5.0 * (60.0 * 10.0 + std::f64::consts::PI * 25.0 / 2.0);
    let removed = summary["removed_volume_mm3"].as_f64().unwrap();
    let gouge = 2.0 * (60.0 * 10.0 + std::f64::consts::PI * 25.0 / 2.0);
    let got = summary["part"]["gouge_volume"].as_f64().unwrap();
    assert!((got - gouge).abs() / gouge < 0.01, "{got} vs {gouge}");
    // Where: one region, the slot's footprint in the stock (x 0..65 with the D10's round
    // end, y −5..5, to within a cell) from the part's top (−3) to the slot's floor (−5).
    let part = &summary["part"];
    assert_eq!(part["gouge_regions"], 1, "{part}");
    let g = &part["gouges"][0];
    let v = |k: &str, i: usize| g[k][i].as_f64().unwrap();
    for (got, want) in [
        (v("min", 0), 0.0),
        (v("max", 0), 65.0),
        (v("min", 1), -5.0),
        (v("max", 1), 5.0),
        (v("min", 2), -5.0),
        (v("max", 2), -3.0),
        (v("at", 2), -4.0),
        (g["depth"].as_f64().unwrap(), 2.0),
    ] {
        assert!((got - want).abs() <= 0.25 + 1e-9, "{got} vs {want}: {g}");
    }
    assert!(
        (g["volume"].as_f64().unwrap() - gouge).abs() / gouge < 0.01,
        "{g}"
    );
    assert!((removed - analytic).abs() / analytic < 0.005, "{summary}");
    assert_eq!(summary["force_peak_line"], 6);
    assert_eq!(summary["rapid_in_material_moves"], 0);
    assert_eq!(summary["collisions"], json!([]));
    assert!(summary["blocks"].as_u64().unwrap() >= 8, "{summary}");
    assert!(
        summary["force_peak_n"].as_f64().unwrap() > 600.0,
        "{summary}"
    );

    let csv = get_text(&c, &s, &format!("/v1/jobs/{job_id}/blocks?format=csv")).await;
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    // The interface outside checks read (issue 6), in this order of importance.
    for col in INTERFACE_COLUMNS.split(',') {
        assert!(header.contains(&col), "{col} not in {header:?}");
    }
    let page = get_json(&c, &s, &format!("/v1/jobs/{job_id}/blocks")).await;
    let cut = page["items"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["line"] == 6)
        .unwrap();
    assert!(cut["force_peak_n"].as_f64().unwrap() > 600.0, "{cut}");
    // Every CSV field is the JSON row's value: words as they are, numbers with the digits
    // they were stored with (a JSON reader may round the last bit), null empty.
    let items = page["items"].as_array().unwrap();
    let body: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(body.len(), items.len());
    for (line, item) in body.iter().zip(items) {
        let fields: Vec<&str> = line.split(',').collect();
        assert_eq!(fields.len(), header.len(), "{line}");
        for (h, f) in header.iter().zip(&fields) {
            match &item[*h] {
                serde_json::Value::Null => assert_eq!(*f, "", "{h}"),
                serde_json::Value::String(w) => assert_eq!(f, w, "{h}"),
                v => {
                    let (a, b) = (f.parse::<f64>().unwrap(), v.as_f64().unwrap());
                    assert!((a - b).abs() <= 4e-16 * a.abs(), "{h}: {f} vs {v}");
                }
            }
        }
    }
    // Some columns only, in the rows' order; a column the rows lack is named.
    let picked = get_text(
        &c,
        &s,
        &format!("/v1/jobs/{job_id}/blocks?format=csv&columns=force_peak_n,line,kind"),
    )
    .await;
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let want: Vec<String> = std::iter::once("line,kind,force_peak_n".to_string())
        .chain(body.iter().map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            [f[col("line")], f[col("kind")], f[col("force_peak_n")]].join(",")
        }))
        .collect();
    assert_eq!(picked.lines().collect::<Vec<_>>(), want);
    // Six significant digits: each number within half a unit of its sixth digit.
    let short = get_text(
        &c,
        &s,
        &format!("/v1/jobs/{job_id}/blocks?format=csv&digits=6"),
    )
    .await;
    assert!(short.len() < csv.len(), "{} vs {}", short.len(), csv.len());
    for (a, b) in short.lines().zip(csv.lines()).skip(1) {
        for (x, y) in a.split(',').zip(b.split(',')) {
            match (x.parse::<f64>(), y.parse::<f64>()) {
                (Ok(x), Ok(y)) => assert!((x - y).abs() <= 5e-6 * y.abs(), "{x} vs {y}"),
                _ => assert_eq!(x, y),
            }
        }
    }
    for (query, field) in [
        ("format=csv&columns=line,forse", "columns"),
        ("columns=line", "columns"),
        ("format=csv&digits=0", "digits"),
        ("format=csv&digits=x", "digits"),
        ("digits=6", "digits"),
    ] {
        let (st, p) = json(
            c.get(s.url(&format!("/v1/jobs/{job_id}/blocks?{query}")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        assert_eq!(
            (st, p["field"].as_str()),
            (422, Some(field)),
            "{query}: {p}"
        );
    }

    // Per-step samples of a row range; their largest peak is the row's peak.
    let (st, samples) = json(
        c.get(s.url(&format!("/v1/jobs/{job_id}/blocks/0-100/samples")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 200, "{samples}");
    let rows = page["items"].as_array().unwrap();
    let cut_seq = rows.iter().position(|r| r["line"] == 6).unwrap();
    let item = samples["items"]
        .as_array()
        .unwrap()
        .iter()
        .find(|i| i["row"] == cut_seq)
        .unwrap();
    let steps = item["samples"].as_array().unwrap();
    assert!(steps.len() > 10);
    let max = steps
        .iter()
        .map(|x| x["peak_force"].as_f64().unwrap())
        .fold(0.0, f64::max);
    assert_eq!(max, cut["force_peak_n"].as_f64().unwrap());
    assert!(steps
        .windows(2)
        .all(|w| w[0]["at"].as_f64() < w[1]["at"].as_f64()));
    for bad in ["5-2", "x-3", "0-20000"] {
        let (st, p) = json(
            c.get(s.url(&format!("/v1/jobs/{job_id}/blocks/{bad}/samples")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        assert_eq!(
            (st, p["field"].as_str()),
            (422, Some("range")),
            "{bad}: {p}"
        );
    }

    let res = c
        .get(s.url(&format!("/v1/jobs/{job_id}/stock.stl")))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    assert!(res.headers()["content-disposition"]
        .to_str()
        .unwrap()
        .contains("slot.stock.stl"));
    let stl = res.bytes().await.unwrap();
    let triangles = u32::from_le_bytes(stl[80..84].try_into().unwrap()) as usize;
    assert!(triangles > 12);
    assert_eq!(stl.len(), 84 + 50 * triangles, "binary STL layout");

    // Options are checked at submission, naming the option.
    let bad = json!({"kind": "simulate", "inputs": {"program": {"content": "G0 X1\n"}, "stock": "x", "tool": "y"}, "options": {"material": "Unobtainium"}});
    let (st, p) = post_json(&c, &s, "/v1/jobs", &bad).await;
    assert_eq!(
        (st, p["field"].as_str()),
        (422, Some("inputs.stock")),
        "{p}"
    );
}

#[tokio::test]
async fn optimize_job_serves_the_rewritten_program_and_before_after_rows() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let id = |v: serde_json::Value| v["id"].as_str().unwrap().to_string();
    let (stock, tool) = slot_stock_and_tool(&c, &s).await;
    let program = "G21 G90\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X60 F4000\nG0 Z5\nG0 X-10\nG0 Z-3\nG1 X60 F1000\nG0 Z5\nM30\n";
    let (_, prog) = json(
        c.post(s.url("/v1/programs?name=part.nc"))
            .body(program)
            .send()
            .await
            .unwrap(),
    )
    .await;
    let inputs = json!({"program": id(prog), "stock": stock, "tool": tool});
    // Limits are required for optimize and refused for simulate, naming the option.
    for (kind, opts) in [
        ("optimize", json!({"material": "Al7075-T6"})),
        (
            "simulate",
            json!({"material": "Al7075-T6", "limits": {"max_force": 500}}),
        ),
    ] {
        let (st, p) = post_json(
            &c,
            &s,
            "/v1/jobs",
            &json!({"kind": kind, "inputs": inputs, "options": opts}),
        )
        .await;
        assert_eq!(
            (st, p["field"].as_str()),
            (422, Some("options.limits")),
            "{p}"
        );
    }
    let body = json!({"kind": "optimize", "inputs": inputs,
                      "options": {"material": "Al7075-T6", "cell_mm": 0.25, "limits": {"max_force": 500, "air_feed": 6000}}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let job_id = id(job);
    let done = wait_job(&c, &s, &job_id, Duration::from_secs(120)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let opt = &done["summary"]["optimization"];
    assert!(opt["peak_force_after"].as_f64().unwrap() <= 510.0, "{opt}");
    assert!(
        opt["cycle_time_after_s"].as_f64().unwrap()
            <= opt["cycle_time_constant_feed_s"].as_f64().unwrap() + 1e-9
    );

    let res = c
        .get(s.url(&format!("/v1/jobs/{job_id}/program")))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    assert!(res.headers()["content-type"]
        .to_str()
        .unwrap()
        .starts_with("text/plain"));
    assert!(res.headers()["content-disposition"]
        .to_str()
        .unwrap()
        .contains("part.opt.nc"));
    let text = res.text().await.unwrap();
    assert_eq!(text.lines().count(), program.lines().count());
    for (a, b) in program.lines().zip(text.lines()) {
        // Only F words change.
        let strip = |l: &str| {
            l.split_whitespace()
                .filter(|w| !w.starts_with('F'))
                .collect::<Vec<_>>()
                .join(" ")
        };
        assert_eq!(strip(a), strip(b));
    }
    let page = get_json(&c, &s, &format!("/v1/jobs/{job_id}/blocks")).await;
    let air = page["items"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["line"] == 10)
        .unwrap();
    assert_eq!(air["feed_opt_mm_min"], 6000.0, "{air}");
    assert_eq!(air["governing"], "air");
    assert_eq!(air["flags"], "air", "{air}");
    let summary = &done["summary"];
    assert_eq!(
        summary["cycle_time_opt_s"], opt["cycle_time_after_s"],
        "{summary}"
    );
    assert_eq!(summary["force_peak_opt_n"], opt["peak_force_after"]);
    let csv = get_text(&c, &s, &format!("/v1/jobs/{job_id}/blocks?format=csv")).await;
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    for col in INTERFACE_COLUMNS.split(',').chain(OPT_COLUMNS.split(',')) {
        assert!(header.contains(&col), "{col} not in {header:?}");
    }

    // Re-simulate the optimized program with the same inputs: no move above the limit by
    // more than 2%, and the same path (same removed volume).
    let (st, opt_prog) = json(
        c.post(s.url("/v1/programs?name=part.opt.nc"))
            .body(text)
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 201);
    let mut again = inputs.clone();
    again["program"] = opt_prog["id"].clone();
    let (_, job) = post_json(&c, &s, "/v1/jobs", &json!({"kind": "simulate", "inputs": again, "options": {"material": "Al7075-T6", "cell_mm": 0.25}})).await;
    let resim = wait_job(
        &c,
        &s,
        job["id"].as_str().unwrap(),
        Duration::from_secs(120),
    )
    .await;
    assert_eq!(resim["status"], "succeeded", "{resim}");
    assert!(
        resim["summary"]["force_peak_n"].as_f64().unwrap() <= 500.0 * 1.02,
        "{resim}"
    );
    let (v0, v1) = (
        done["summary"]["removed_volume_mm3"].as_f64().unwrap(),
        resim["summary"]["removed_volume_mm3"].as_f64().unwrap(),
    );
    assert_eq!(v0, v1);
}

#[tokio::test]
async fn each_tool_number_gets_its_own_tool_input() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let (stock, t1) = slot_stock_and_tool(&c, &s).await;
    // T2: a Ø6 bull-nose in the older field names, which stay accepted.
    let (st, t2) = post_json(&c, &s, "/v1/tools", &json!({"shape": "bull_nose", "diameter": 6.0, "corner_radius": 0.5, "flutes": 3, "flute_length": 15.0})).await;
    assert_eq!(st, 201, "{t2}");
    let program = "G21 G90\nT1 M6\nS10000 M3\nG0 Z5\nG0 X10 Y-10\nG0 Z-5\nG1 X50 F2000\nG0 Z5\nT2 M6\nS12000 M3\nG0 X10 Y10\nG0 Z-3\nG1 X50 F1500\nG0 Z5\nM30\n";
    let inline = json!({"name": "two.nc", "content": program});
    let both = json!({"program": inline, "stock": stock, "tool": t1, "T2": t2["id"]});
    let (st, p) = json(
        c.post(s.url("/v1/jobs"))
            .json(
                &json!({"kind": "simulate", "inputs": both, "options": {"material": "Al7075-T6"}}),
            )
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!((st, p["field"].as_str()), (422, Some("inputs.tool")), "{p}");
    let inputs = json!({"program": inline, "stock": stock, "T1": t1, "T2": t2["id"]});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &json!({"kind": "simulate", "inputs": inputs, "options": {"material": "Al7075-T6", "cell_mm": 0.25}})).await;
    assert_eq!(st, 202, "{job}");
    let done = wait_job(
        &c,
        &s,
        job["id"].as_str().unwrap(),
        Duration::from_secs(120),
    )
    .await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let page = get_json(
        &c,
        &s,
        &format!("/v1/jobs/{}/blocks?limit=100", job["id"].as_str().unwrap()),
    )
    .await;
    let rows = page["items"].as_array().unwrap();
    let at = |line: u32| rows.iter().find(|r| r["line"] == line).unwrap();
    assert_eq!(
        (at(7)["tool"].clone(), at(13)["tool"].clone()),
        (json!(1), json!(2))
    );
    // Each slot as wide as its own tool.
    assert!((at(7)["radial_width_mm"].as_f64().unwrap() - 10.0).abs() <= 0.25);
    assert!((at(13)["radial_width_mm"].as_f64().unwrap() - 6.0).abs() <= 0.25);
}

/// A 3+2 program as posts write it (G68.2 / G53.1 / G69) simulated on the job's A/C
/// machine: G53.1 turns the table within its A limits; without rotary axes the job fails
/// naming G53.1's line.
#[tokio::test]
async fn a_tilted_working_plane_runs_on_the_jobs_machine() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let mut ids = Vec::new();
    for (route, body) in [
        (
            "/v1/stocks",
            json!({"kind": "block", "min": [-25, -25, -20], "max": [25, 25, 0]}),
        ),
        (
            "/v1/tools",
            json!({"type": "flat", "diameter_mm": 6.0, "flutes": 3, "flute_length_mm": 20.0}),
        ),
        (
            "/v1/machines",
            json!({"name": "AC trunnion", "kinematics": "xyz_ac", "rapid_rate": 24000.0, "max_feed": 10000.0,
                   "acceleration": [2000.0, 2000.0, 1500.0], "spindle_min_rpm": 0.0, "spindle_max_rpm": 20000.0,
                   "rated_power": 11000.0, "kinematic_chain": {"a_limits": [0.0, 110.0]}}),
        ),
    ] {
        let (st, v) = post_json(&c, &s, route, &body).await;
        assert_eq!(st, 201, "{route}: {v}");
        ids.push(v["id"].as_str().unwrap().to_string());
    }
    let program = "G21 G90 G94 S9000 M3\nG0 X0 Y0 Z60\nG68.2 X0 Y0 Z0 I0 J30 K0\nG53.1\nG0 X-8 Y0 Z10\nG1 Z-2 F300\nG1 X8 F800\nG0 Z10\nG69\nM30\n";
    let inputs = json!({"program": {"name": "tilt.nc", "content": program}, "stock": ids[0], "tool": ids[1], "machine": ids[2]});
    let done = run_job(
        &c,
        &s,
        &json!({"kind": "simulate", "inputs": inputs, "options": {"material": "Al7075-T6", "cell_mm": 0.25}}),
        Duration::from_secs(120),
    )
    .await;
    let id = done["id"].as_str().unwrap();
    let page = get_json(&c, &s, &format!("/v1/jobs/{id}/blocks?limit=100")).await;
    let rows = page["items"].as_array().unwrap();
    let at = |line: u32| rows.iter().find(|r| r["line"] == line).unwrap();
    // A ≥ 0 leaves A30 C±180 (not the nearer A−30 C0): √(30² + 180²) degrees of travel.
    let turn = at(4)["rotary_deg"].as_f64().unwrap();
    assert!(
        (turn - (30f64.powi(2) + 180f64.powi(2)).sqrt()).abs() < 1e-6,
        "{}",
        at(4)
    );
    assert!(at(7)["removed_mm3"].as_f64().unwrap() > 10.0, "{}", at(7));

    // The generic 3-axis machine has no rotary axes to turn.
    let inputs = json!({"program": {"name": "tilt.nc", "content": program}, "stock": ids[0], "tool": ids[1]});
    let (st, job) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "simulate", "inputs": inputs, "options": {"material": "Al7075-T6", "cell_mm": 0.25}}),
    )
    .await;
    assert_eq!(st, 202, "{job}");
    let done = wait_job(&c, &s, job["id"].as_str().unwrap(), Duration::from_secs(60)).await;
    assert_eq!(done["status"], "failed", "{done}");
    assert_eq!(done["error"]["errors"][0]["line"], 4, "{done}");
    let message = done["error"]["errors"][0]["message"].as_str().unwrap();
    assert!(message.contains("no rotary axes"), "{message}");
}
