//! Issue 33 over HTTP: a `process` job (operations in order on one stock) end to end,
//! checked against the manual chain (simulate operation 1, upload its stock.stl, simulate
//! operation 2 on it); each operation's program and stock; bad operations refused naming
//! the request's field.

mod common;

use std::time::Duration;

use serde_json::{json, Value};

use common::*;

async fn get_bytes(c: &reqwest::Client, s: &Server, path: &str) -> (u16, Vec<u8>) {
    let res = c.get(s.url(path)).send().await.unwrap();
    let status = res.status().as_u16();
    (status, res.bytes().await.unwrap().to_vec())
}

/// Ø10 slot 3 deep along x at y 0 (10 × 3 × 100 = 3000 mm³).
const ROUGH: &str = "G90 G21\nS8000 M3\nG0 X-10 Y0 Z5\nG1 Z-3 F500\nG1 X110 F800\nG0 Z5\nM30\n";
/// Ø6 at y 3, 5 deep, in the slot the rough left: 1500 mm³.
const FINISH: &str = "G90 G21\nS8000 M3\nG0 X-10 Y3 Z5\nG1 Z-5 F400\nG1 X110 F600\nG0 Z5\nM30\n";

fn rel(a: &Value, b: &Value) -> f64 {
    let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
    (a - b).abs() / b.abs().max(1e-9)
}

#[tokio::test]
async fn a_two_operation_process_equals_the_manual_chain() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let stock = create(&c, &s, "/v1/stocks", slot_block()).await;
    let d10 = create(&c, &s, "/v1/tools", json!({"type": "flat", "diameter_mm": 10, "flutes": 3, "helix_deg": 30, "flute_length_mm": 20})).await;
    let d6 = create(&c, &s, "/v1/tools", json!({"type": "flat", "diameter_mm": 6, "flutes": 2, "helix_deg": 30, "flute_length_mm": 20})).await;
    let rough = post_program(&c, &s, "rough.nc", ROUGH).await;
    let finish = post_program(&c, &s, "finish.nc", FINISH).await;
    let options = json!({"material": "Al7075-T6", "cell_mm": 0.5});

    let process = json!({"kind": "process",
        "inputs": {"stock": stock, "operations": [
            {"name": "rough", "program": rough, "T1": d10, "options": {"limits": {"max_force": 400}}},
            {"name": "finish", "program": finish, "tool": d6}]},
        "options": {"material": "Al7075-T6", "cell_mm": 0.5, "keep_stocks": true}});
    let job = run_job(&c, &s, &process, Duration::from_secs(300)).await;
    let id = job["id"].as_str().unwrap();
    let summary = &job["summary"];
    let ops = summary["operations"].as_array().unwrap();
    assert_eq!(ops.len(), 2, "{summary}");
    assert_eq!(
        (&ops[0]["name"], &ops[1]["name"]),
        (&json!("rough"), &json!("finish"))
    );
    assert_eq!(
        (&ops[0]["optimized"], &ops[1]["optimized"]),
        (&json!(true), &json!(false))
    );
    // The optimize fields on the optimized one, the simulate ones on both.
    assert!(
        ops[0]["cycle_time_opt_s"].as_f64().unwrap() > 0.0,
        "{}",
        ops[0]
    );
    assert!(ops[0]["optimization"].is_object());
    assert!(ops[1].get("cycle_time_opt_s").is_none());
    assert!(
        rel(&ops[0]["removed_volume_mm3"], &json!(3000.0)) < 0.01,
        "{}",
        ops[0]
    );
    assert!(
        rel(&ops[1]["removed_volume_mm3"], &json!(1500.0)) < 0.01,
        "{}",
        ops[1]
    );
    assert_eq!(ops[1]["stock_volume_before"], ops[0]["stock_volume_after"]);
    assert_eq!(summary["stock_volume_after"], ops[1]["stock_volume_after"]);
    let total =
        ops[0]["cycle_time_opt_s"].as_f64().unwrap() + ops[1]["cycle_time_s"].as_f64().unwrap();
    assert!(
        (summary["cycle_time_opt_s"].as_f64().unwrap() - total).abs() < 1e-9,
        "{summary}"
    );

    // The manual chain: operation 1 alone, its stock uploaded, operation 2 on it.
    let first = run_job(&c, &s, &json!({"kind": "simulate", "inputs": {"program": rough, "stock": stock, "T1": d10}, "options": options}), Duration::from_secs(300)).await;
    let first_id = first["id"].as_str().unwrap();
    let (st, stl) = get_bytes(&c, &s, &format!("/v1/jobs/{first_id}/stock.stl")).await;
    assert_eq!(st, 200);
    let (st, v) = post_stl(&c, &s, "/v1/stocks?name=after-rough.stl", stl.clone()).await;
    assert_eq!(st, 201, "{v}");
    let after_rough = v["id"].as_str().unwrap().to_string();
    let second = run_job(&c, &s, &json!({"kind": "simulate", "inputs": {"program": finish, "stock": after_rough, "tool": d6}, "options": options}), Duration::from_secs(300)).await;
    let m = &second["summary"];
    for k in [
        "removed_volume_mm3",
        "force_peak_n",
        "cycle_time_s",
        "stock_volume_after",
    ] {
        assert!(
            rel(&ops[1][k], &m[k]) < 2e-3,
            "{k}: process {} vs manual {}",
            ops[1][k],
            m[k]
        );
    }
    assert!(
        rel(
            &ops[0]["removed_volume_mm3"],
            &first["summary"]["removed_volume_mm3"]
        ) < 1e-12
    );
    // The process kept the stock after the rough: the same file the simulate job gave.
    let (st, kept) = get_bytes(&c, &s, &format!("/v1/jobs/{id}/stock.stl?operation=1")).await;
    assert_eq!(st, 200);
    assert_eq!(
        kept, stl,
        "the stock after operation 1 is the rough's alone"
    );
    let (_, last) = get_bytes(&c, &s, &format!("/v1/jobs/{id}/stock.stl?operation=2")).await;
    let (_, fin) = get_bytes(&c, &s, &format!("/v1/jobs/{id}/stock.stl")).await;
    assert_eq!(last, fin);
    assert_ne!(fin, stl);
    let (st, _) = get_bytes(&c, &s, &format!("/v1/jobs/{id}/stock.stl?operation=3")).await;
    assert_eq!(st, 404);

    // Each operation's program: the rough's optimized, the finish's as given.
    let (st, p1) = get_bytes(&c, &s, &format!("/v1/jobs/{id}/program?operation=1")).await;
    assert_eq!(st, 200);
    let p1 = String::from_utf8(p1).unwrap();
    assert_ne!(p1, ROUGH, "the rough's feeds rewritten");
    assert!(p1.contains("G1 X110 F"), "{p1}");
    let (st, p2) = get_bytes(&c, &s, &format!("/v1/jobs/{id}/program?operation=2")).await;
    assert_eq!((st, String::from_utf8(p2).unwrap().as_str()), (200, FINISH));
    let (st, _) = get_bytes(&c, &s, &format!("/v1/jobs/{id}/program?operation=3")).await;
    assert_eq!(st, 404);

    // Rows: every one names its operation, and every row has every column of the job.
    let rows = get_json(&c, &s, &format!("/v1/jobs/{id}/blocks?limit=1000")).await["items"]
        .as_array()
        .unwrap()
        .clone();
    assert_eq!(
        rows.len() as u64,
        ops[0]["moves"].as_u64().unwrap() + ops[1]["moves"].as_u64().unwrap()
    );
    let keys = |r: &Value| r.as_object().unwrap().keys().cloned().collect::<Vec<_>>();
    for r in &rows {
        assert_eq!(keys(r), keys(&rows[0]), "{r}");
    }
    let of = |n: u64| rows.iter().filter(|r| r["operation"] == n).count();
    assert_eq!(of(1) as u64, ops[0]["moves"].as_u64().unwrap());
    assert_eq!(of(2) as u64, ops[1]["moves"].as_u64().unwrap());
    assert!(rows.iter().all(|r| r["operation_name"]
        == if r["operation"] == 1 {
            "rough"
        } else {
            "finish"
        }));
    let last_row = rows.last().unwrap();
    assert!(
        last_row.get("feed_opt_mm_min").is_some() && last_row["feed_opt_mm_min"].is_null(),
        "{last_row}"
    );
    let csv = String::from_utf8(
        get_bytes(&c, &s, &format!("/v1/jobs/{id}/blocks?format=csv"))
            .await
            .1,
    )
    .unwrap();
    assert!(
        csv.lines()
            .next()
            .unwrap()
            .starts_with("operation,operation_name,"),
        "{csv}"
    );

    // Without keep_stocks, only the final stock.
    let mut once = process.clone();
    once["options"]["keep_stocks"] = json!(false);
    let job = run_job(&c, &s, &once, Duration::from_secs(300)).await;
    let id = job["id"].as_str().unwrap();
    let (st, body) = get_bytes(&c, &s, &format!("/v1/jobs/{id}/stock.stl?operation=1")).await;
    assert_eq!(st, 404, "{}", String::from_utf8_lossy(&body));
    assert!(String::from_utf8_lossy(&body).contains("keep_stocks"));
}

#[tokio::test]
async fn bad_operations_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let stock = create(&c, &s, "/v1/stocks", slot_block()).await;
    let d10 = create(&c, &s, "/v1/tools", json!({"type": "flat", "diameter_mm": 10, "flutes": 3, "helix_deg": 30, "flute_length_mm": 20})).await;
    let rough = post_program(&c, &s, "rough.nc", ROUGH).await;
    let job = |ops: Value, options: Value| json!({"kind": "process", "inputs": {"stock": stock, "operations": ops}, "options": options});
    let material = json!({"material": "Al7075-T6"});
    let cases = [
        (
            json!([{"program": rough, "tool": d10}, {"program": "nope", "tool": d10}]),
            material.clone(),
            "inputs.operations[1].program",
        ),
        (
            json!([{"program": rough, "tool": d10}, {"tool": d10}]),
            material.clone(),
            "inputs.operations[1].program",
        ),
        (
            json!([{"program": rough, "tool": d10}, {"program": rough, "tool": "nope"}]),
            material.clone(),
            "inputs.operations[1].tool",
        ),
        (
            json!([{"program": rough, "tool": d10, "T1": d10}]),
            material.clone(),
            "inputs.operations[0].tool",
        ),
        (
            json!([{"program": rough, "tool": d10, "spindle": 1}]),
            material.clone(),
            "inputs.operations[0].spindle",
        ),
        (
            json!([{"program": rough, "tool": d10, "options": {"limits": {"max_force": -1}}}]),
            material.clone(),
            "inputs.operations[0].options.limits",
        ),
        (
            json!([{"program": rough, "tool": d10, "options": {"cell_mm": 0.2}}]),
            material.clone(),
            "inputs.operations[0].options.cell_mm",
        ),
        (
            json!([{"program": rough, "tool": d10, "options": {"optimize": true}}]),
            material.clone(),
            "inputs.operations[0].options.limits",
        ),
        (
            json!([{"program": rough, "tool": d10}]),
            json!({}),
            "options.material",
        ),
        (json!([]), material.clone(), "inputs.operations"),
        (
            json!(vec![json!({"program": rough, "tool": d10}); 21]),
            material.clone(),
            "inputs.operations",
        ),
        (
            json!([{"name": "a", "program": rough, "tool": d10}, {"name": "a", "program": rough, "tool": d10}]),
            material.clone(),
            "inputs.operations[1].name",
        ),
    ];
    for (ops, options, field) in cases {
        let (st, v) = post_json(&c, &s, "/v1/jobs", &job(ops.clone(), options)).await;
        assert_eq!(st, 422, "{ops}: {v}");
        assert_eq!(v["field"], field, "{ops}: {v}");
    }
    // The operations belong under inputs.
    let (st, v) = post_json(&c, &s, "/v1/jobs", &json!({"kind": "process", "inputs": {"stock": stock, "operations": [{"program": rough, "tool": d10}]}, "options": {"material": "Al7075-T6", "operations": []}})).await;
    assert_eq!(
        (st, v["field"].as_str()),
        (422, Some("options.operations")),
        "{v}"
    );
}

#[tokio::test]
async fn an_operation_reads_its_program_in_its_setups_work_offsets() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let stock = create(&c, &s, "/v1/stocks", slot_block()).await;
    let d10 = create(&c, &s, "/v1/tools", json!({"type": "flat", "diameter_mm": 10, "flutes": 3, "helix_deg": 30, "flute_length_mm": 20})).await;
    let d6 = create(&c, &s, "/v1/tools", json!({"type": "flat", "diameter_mm": 6, "flutes": 2, "helix_deg": 30, "flute_length_mm": 20})).await;
    // FINISH moved to its own zero: Y0 in G55, the setup's G55 at Y3.
    let finish = "G90 G21\nG55\nS8000 M3\nG0 X-10 Y0 Z5\nG1 Z-5 F400\nG1 X110 F600\nG0 Z5\nM30\n";
    let job = run_job(&c, &s, &json!({"kind": "process",
        "inputs": {"stock": stock, "operations": [
            {"program": {"name": "rough.nc", "content": ROUGH}, "tool": d10},
            {"program": {"name": "finish.nc", "content": finish}, "tool": d6, "options": {"work_offsets": {"G55": [0, 3, 0]}}}]},
        "options": {"material": "Al7075-T6", "cell_mm": 0.5}}), Duration::from_secs(300)).await;
    let ops = job["summary"]["operations"].as_array().unwrap();
    assert!(
        rel(&ops[1]["removed_volume_mm3"], &json!(1500.0)) < 0.01,
        "{}",
        ops[1]
    );
}

/// The 100 × 40 × 10 block, a Ø10 and a Ø6 flat end mill: their ids.
async fn block_and_tools(c: &reqwest::Client, s: &Server) -> (String, String, String) {
    let stock = create(c, s, "/v1/stocks", slot_block()).await;
    let d10 = create(c, s, "/v1/tools", json!({"type": "flat", "diameter_mm": 10, "flutes": 3, "helix_deg": 30, "flute_length_mm": 20})).await;
    let d6 = create(c, s, "/v1/tools", json!({"type": "flat", "diameter_mm": 6, "flutes": 2, "helix_deg": 30, "flute_length_mm": 20})).await;
    (stock, d10, d6)
}

#[tokio::test]
async fn the_stocks_kept_count_in_the_memory_estimate() {
    let job = |stock: &str, d10: &str, d6: &str, keep: bool| {
        json!({"kind": "process",
            "inputs": {"stock": stock, "operations": [
                {"program": {"name": "rough.nc", "content": ROUGH}, "tool": d10},
                {"program": {"name": "finish.nc", "content": FINISH}, "tool": d6}]},
            "options": {"material": "Al7075-T6", "cell_mm": 0.1, "keep_stocks": keep}})
    };
    let dir = tempfile::tempdir().unwrap();
    let c = client();
    // The estimate with the stock after the rough kept, on a server with room for it.
    let roomy = Server::start(&dir.path().join("a.db"), &["--workers", "1"]);
    let (stock, d10, d6) = block_and_tools(&c, &roomy).await;
    let done = run_job(
        &c,
        &roomy,
        &job(&stock, &d10, &d6, true),
        Duration::from_secs(300),
    )
    .await;
    let e = &done["summary"]["memory"]["estimate"];
    let (total, kept) = (
        e["peak_bytes"].as_u64().unwrap(),
        e["kept_stocks_bytes"].as_u64().unwrap(),
    );
    assert!(kept > 4 << 20, "the kept stock's export is counted: {e}");
    drop(roomy);
    // A budget between the process without the kept stock and with it.
    let budget = ((total - kept) >> 20) + 2;
    assert!(budget << 20 < total, "{e}");
    let tight = Server::start(
        &dir.path().join("b.db"),
        &["--workers", "1", "--job-memory-mb", &budget.to_string()],
    );
    let (stock, d10, d6) = block_and_tools(&c, &tight).await;
    run_job(
        &c,
        &tight,
        &job(&stock, &d10, &d6, false),
        Duration::from_secs(300),
    )
    .await;
    let (st, v) = post_json(&c, &tight, "/v1/jobs", &job(&stock, &d10, &d6, true)).await;
    assert_eq!(st, 202, "{v}");
    let failed = wait_job(
        &c,
        &tight,
        v["id"].as_str().unwrap(),
        Duration::from_secs(300),
    )
    .await;
    assert_eq!(failed["status"], "failed", "{failed}");
    let detail = failed["error"]["detail"].as_str().unwrap();
    assert!(
        detail.contains("the stocks kept") && detail.contains("keep_stocks false"),
        "{detail}"
    );
}

/// A Ø2 cut along the slot the rough left, T2 loaded: its tool from a library or a header.
const FINE: &str =
    "G90 G21\nT2 M6\nS12000 M3\nG0 X-10 Y3 Z5\nG1 Z-4 F300\nG1 X110 F600\nG0 Z5\nM30\n";

/// The finest tool of a process comes from a tool library (or a program's header comment),
/// not from a tool given by id: the process's one cell is that tool's default (Ø2: 0.05 mm,
/// where the Ø10 alone would take 0.25), and every operation's memory is estimated at it,
/// so a budget the coarse estimate fits refuses the process.
#[tokio::test]
async fn a_library_or_header_tool_sets_the_cell_the_memory_is_estimated_at() {
    let process = |stock: &str, d10: &str, fine: Value, cell: Option<f64>| {
        let mut options = json!({"material": "Al7075-T6"});
        if let Some(c) = cell {
            options["cell_mm"] = json!(c);
        }
        let mut finish = fine;
        finish["name"] = json!("fine");
        json!({"kind": "process",
            "inputs": {"stock": stock, "operations": [
                {"name": "rough", "program": {"name": "rough.nc", "content": ROUGH}, "tool": d10},
                finish]},
            "options": options})
    };
    let library = |c: &reqwest::Client, s: &Server| {
        let req = c
            .post(s.url("/v1/tool-libraries?name=shop.tbl"))
            .header("content-type", "text/plain")
            .body("T2 P2 D2 Z0 ;flat end mill\n");
        async move {
            let (st, v) = json(req.send().await.unwrap()).await;
            assert_eq!(st, 201, "{v}");
            v["id"].as_str().unwrap().to_string()
        }
    };
    let by_library =
        |lib: &str| json!({"program": {"name": "fine.nc", "content": FINE}, "tool_library": lib});
    let dir = tempfile::tempdir().unwrap();
    let c = client();
    let roomy = Server::start(&dir.path().join("a.db"), &["--workers", "1"]);
    let (stock, d10, _) = block_and_tools(&c, &roomy).await;
    let lib = library(&c, &roomy).await;
    let wait = Duration::from_secs(300);
    let done = run_job(
        &c,
        &roomy,
        &process(&stock, &d10, by_library(&lib), None),
        wait,
    )
    .await;
    let s = &done["summary"];
    assert_eq!(s["cell_mm"], json!(0.05), "{s}");
    let estimate = &s["memory"]["estimate"];
    // The fine operation alone, as a simulate job, is estimated at the same cell.
    let alone = run_job(
        &c,
        &roomy,
        &json!({"kind": "simulate",
            "inputs": {"stock": stock, "program": {"name": "fine.nc", "content": FINE}, "tool_library": lib},
            "options": {"material": "Al7075-T6"}}),
        wait,
    )
    .await;
    assert_eq!(
        estimate["operations"][1], alone["summary"]["memory"]["estimate"],
        "{estimate}"
    );
    // The same tool from the program's header comment: the same cell and estimate.
    let header = format!("(T2 D=2. CR=0. - ZMIN=-4. - flat end mill)\n{FINE}");
    let done = run_job(
        &c,
        &roomy,
        &process(
            &stock,
            &d10,
            json!({"program": {"name": "fine.nc", "content": header}}),
            None,
        ),
        wait,
    )
    .await;
    assert_eq!(
        done["summary"]["cell_mm"],
        json!(0.05),
        "{}",
        done["summary"]
    );
    let by_header = &done["summary"]["memory"]["estimate"];
    assert_eq!(
        by_header["peak_bytes"], estimate["peak_bytes"],
        "{by_header}"
    );
    // What the process would have been estimated at with the Ø10's cell.
    let coarse = run_job(
        &c,
        &roomy,
        &process(&stock, &d10, by_library(&lib), Some(0.25)),
        wait,
    )
    .await;
    let coarse = coarse["summary"]["memory"]["estimate"]["peak_bytes"]
        .as_u64()
        .unwrap();
    let fine = estimate["peak_bytes"].as_u64().unwrap();
    let budget = (coarse >> 20) + 2;
    assert!(budget << 20 < fine, "coarse {coarse}, fine {fine}");
    drop(roomy);
    // A budget the coarse estimate fits: admitted at submission (the tools given by id),
    // refused by the job's check, naming the budget.
    let tight = Server::start(
        &dir.path().join("b.db"),
        &["--workers", "1", "--job-memory-mb", &budget.to_string()],
    );
    let (stock, d10, _) = block_and_tools(&c, &tight).await;
    let lib = library(&c, &tight).await;
    let (st, v) = post_json(
        &c,
        &tight,
        "/v1/jobs",
        &process(&stock, &d10, by_library(&lib), None),
    )
    .await;
    assert_eq!(st, 202, "{v}");
    let failed = wait_job(&c, &tight, v["id"].as_str().unwrap(), wait).await;
    assert_eq!(failed["status"], "failed", "{failed}");
    let error = &failed["error"];
    assert_eq!(error["limit"], json!(budget), "{error}");
    assert!(
        error["detail"]
            .as_str()
            .unwrap()
            .contains("over the job memory budget"),
        "{error}"
    );
}
