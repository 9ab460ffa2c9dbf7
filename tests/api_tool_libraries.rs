//! Tool libraries over HTTP: upload in each format (Fusion 360 JSON, LinuxCNC table, CSV),
//! the tools and import report back, 422s naming the tool and field, per-key isolation;
//! and the `tool_library` job input: the example job with its tool from a library, explicit
//! tools winning, a T number nothing describes refused by name.

mod common;

use std::time::{Duration, Instant};

use common::*;
use serde_json::{json, Value};

/// A Fusion 360 library in the format its CAM API documents: flat with a three-segment
/// holder, ball, bull nose, chamfer, and an inch tool.
const FUSION: &str = r#"{"data":[
 {"type":"flat end mill","unit":"millimeters","description":"6 mm flat","guid":"a",
  "geometry":{"DC":6,"NOF":3,"LCF":18,"LB":30,"OAL":60,"SFDM":6,"HAND":true,"RE":0,"helix-angle":35},
  "holder":{"segments":[{"height":10,"lower-diameter":20,"upper-diameter":20},
                        {"height":5,"lower-diameter":20,"upper-diameter":32},
                        {"height":40,"lower-diameter":40,"upper-diameter":40}]},
  "post-process":{"number":1,"length-offset":1}},
 {"type":"ball end mill","unit":"millimeters","geometry":{"DC":8,"NOF":2,"LCF":16,"LB":40,"SFDM":8},"post-process":{"number":2}},
 {"type":"bull nose end mill","unit":"millimeters","geometry":{"DC":10,"NOF":4,"LCF":22,"RE":1.5},"post-process":{"number":3}},
 {"type":"chamfer mill","unit":"millimeters","geometry":{"DC":12,"NOF":4,"LCF":8,"TA":45,"tip-diameter":2},"post-process":{"number":4}},
 {"type":"flat end mill","unit":"inches","geometry":{"DC":0.25,"NOF":2,"LCF":0.75,"LB":1.25},"post-process":{"number":5}}
]}"#;

const TBL: &str = "T1 P1 D6.0 Z+25.0 ;6mm ball end mill\nT2 P2 D10 Z+30 ;\n";

const CSV: &str = "number,type,diameter,corner_radius,flutes,flute_length,helix\n4,bull,12,2,4,30,35\n5,ball,6,,2,12,30\n";

/// POSTs a library body with a content type; the status and the response.
async fn upload(
    c: &reqwest::Client,
    s: &Server,
    name: &str,
    content_type: &str,
    body: &str,
) -> (u16, Value) {
    json(
        c.post(s.url(&format!("/v1/tool-libraries?name={name}")))
            .header("content-type", content_type)
            .body(body.to_string())
            .send()
            .await
            .unwrap(),
    )
    .await
}

/// The notes of a report list as (tool, field) pairs.
fn pairs(notes: &Value) -> Vec<(String, String)> {
    notes
        .as_array()
        .unwrap()
        .iter()
        .map(|n| {
            (
                n["tool"].as_str().unwrap().to_string(),
                n["field"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

#[tokio::test]
async fn libraries_in_each_format_come_back_with_their_tools_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();

    // Fusion 360, raw JSON body.
    let res = c
        .post(s.url("/v1/tool-libraries?name=shop.json"))
        .header("content-type", "application/json")
        .body(FUSION)
        .send()
        .await
        .unwrap();
    let location = res.headers()["location"].to_str().unwrap().to_string();
    let (st, fusion) = json(res).await;
    assert_eq!(st, 201, "{fusion}");
    let fusion_id = fusion["id"].as_str().unwrap().to_string();
    assert_eq!(location, format!("/v1/tool-libraries/{fusion_id}"));
    assert_eq!(fusion["kind"], "tool_library");
    assert_eq!(fusion["name"], "shop.json");
    assert_eq!(fusion["media_type"], "application/json");
    assert_eq!(fusion["summary"]["format"], "fusion360");
    assert_eq!(fusion["summary"]["tools"], 5);

    let got = get_json(&c, &s, &location).await;
    assert_eq!(got["format"], "fusion360");
    assert!(got.get("definition").is_none(), "{got}");
    let tools = got["tools"].as_object().unwrap();
    assert_eq!(
        tools.keys().collect::<Vec<_>>(),
        ["T1", "T2", "T3", "T4", "T5"]
    );
    // Every mapped field, in the API's tool JSON.
    let t1 = &tools["T1"];
    assert_eq!(t1["name"], "6 mm flat");
    assert_eq!(t1["type"], "flat");
    assert_eq!(
        (
            t1["diameter_mm"].as_f64(),
            t1["flutes"].as_u64(),
            t1["flute_length_mm"].as_f64()
        ),
        (Some(6.0), Some(3), Some(18.0))
    );
    assert_eq!(
        (
            t1["stickout_mm"].as_f64(),
            t1["shank_diameter_mm"].as_f64(),
            t1["helix_deg"].as_f64()
        ),
        (Some(30.0), Some(6.0), Some(35.0))
    );
    assert_eq!(
        t1["holder"],
        json!([
            {"length_mm": 10.0, "bottom_diameter_mm": 20.0, "top_diameter_mm": 20.0},
            {"length_mm": 5.0, "bottom_diameter_mm": 20.0, "top_diameter_mm": 32.0},
            {"length_mm": 40.0, "bottom_diameter_mm": 40.0, "top_diameter_mm": 40.0}
        ])
    );
    let t2 = &tools["T2"];
    assert_eq!(
        (t2["type"].as_str(), t2["diameter_mm"].as_f64()),
        (Some("ball"), Some(8.0))
    );
    assert_eq!(t2["corner_radius_mm"], 4.0);
    assert_eq!(t2["stickout_mm"], 40.0);
    let t3 = &tools["T3"];
    assert_eq!(
        (t3["type"].as_str(), t3["corner_radius_mm"].as_f64()),
        (Some("bull"), Some(1.5))
    );
    let t4 = &tools["T4"];
    assert_eq!(
        (
            t4["type"].as_str(),
            t4["taper_half_angle_deg"].as_f64(),
            t4["tip_diameter_mm"].as_f64()
        ),
        (Some("chamfer"), Some(45.0), Some(2.0))
    );
    // Inches converted to mm.
    let t5 = &tools["T5"];
    assert!(
        (t5["diameter_mm"].as_f64().unwrap() - 6.35).abs() < 1e-9,
        "{t5}"
    );
    assert!((t5["flute_length_mm"].as_f64().unwrap() - 19.05).abs() < 1e-9);
    assert!((t5["stickout_mm"].as_f64().unwrap() - 31.75).abs() < 1e-9);
    // Each tool is one POST /v1/tools takes.
    let (st, v) = post_json(&c, &s, "/v1/tools", t1).await;
    assert_eq!(st, 201, "{v}");
    // What is not modelled is listed, and what is assumed, with the value.
    let unmodelled = pairs(&got["report"]["unmodelled"]);
    for field in ["geometry.OAL", "geometry.HAND"] {
        assert!(
            unmodelled.contains(&("T1 (data[0])".into(), field.into())),
            "{unmodelled:?}"
        );
    }
    let assumed = pairs(&got["report"]["assumed"]);
    assert!(assumed.contains(&("T2 (data[1])".into(), "helix_deg".into())));
    assert!(
        !assumed.contains(&("T1 (data[0])".into(), "helix_deg".into())),
        "T1 gives its helix: {assumed:?}"
    );

    // LinuxCNC, text/plain: the shape from the comment, the rest assumed and said.
    let (st, tbl) = upload(&c, &s, "shop.tbl", "text/plain", TBL).await;
    assert_eq!(st, 201, "{tbl}");
    assert_eq!(tbl["summary"]["format"], "linuxcnc");
    let got = get_json(
        &c,
        &s,
        &format!("/v1/tool-libraries/{}", tbl["id"].as_str().unwrap()),
    )
    .await;
    assert_eq!(got["tools"]["T1"]["type"], "ball");
    assert_eq!(got["tools"]["T1"]["diameter_mm"], 6.0);
    assert_eq!(got["tools"]["T2"]["type"], "flat");
    let assumed = pairs(&got["report"]["assumed"]);
    assert!(
        assumed.contains(&("T2 (line 2)".into(), "type".into())),
        "{assumed:?}"
    );
    assert!(assumed.contains(&("T1 (line 1)".into(), "flutes".into())));

    // CSV as a multipart file part: the part's file name is kept.
    let form = reqwest::multipart::Form::new().part(
        "file",
        reqwest::multipart::Part::bytes(CSV.as_bytes().to_vec()).file_name("tools.csv"),
    );
    let (st, csv) = json(
        c.post(s.url("/v1/tool-libraries"))
            .multipart(form)
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 201, "{csv}");
    assert_eq!(csv["name"], "tools.csv");
    assert_eq!(csv["media_type"], "text/csv");
    let csv_id = csv["id"].as_str().unwrap().to_string();
    let got = get_json(&c, &s, &format!("/v1/tool-libraries/{csv_id}")).await;
    let t4 = &got["tools"]["T4"];
    assert_eq!(
        (
            t4["type"].as_str(),
            t4["diameter_mm"].as_f64(),
            t4["corner_radius_mm"].as_f64(),
            t4["flutes"].as_u64(),
            t4["flute_length_mm"].as_f64(),
            t4["helix_deg"].as_f64()
        ),
        (
            Some("bull"),
            Some(12.0),
            Some(2.0),
            Some(4),
            Some(30.0),
            Some(35.0)
        )
    );
    assert_eq!(got["tools"]["T5"]["corner_radius_mm"], 3.0);

    // Listed in cursor pages like every resource, oldest first.
    let (_, p1) = json(
        c.get(s.url("/v1/tool-libraries?limit=2"))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(p1["items"].as_array().unwrap().len(), 2);
    assert_eq!(p1["items"][0]["id"], fusion_id.as_str());
    assert!(
        p1["items"][0].get("tools").is_none(),
        "lists carry metadata only"
    );
    let cursor = p1["next_cursor"].as_str().unwrap();
    let p2 = get_json(
        &c,
        &s,
        &format!("/v1/tool-libraries?limit=2&cursor={cursor}"),
    )
    .await;
    assert_eq!(p2["items"][0]["id"], csv_id.as_str());
    assert!(p2["next_cursor"].is_null());

    // The file exactly as uploaded, then deleted.
    let res = c
        .get(s.url(&format!("/v1/tool-libraries/{csv_id}/content")))
        .send()
        .await
        .unwrap();
    assert_eq!(res.headers()["content-type"], "text/csv");
    assert_eq!(res.text().await.unwrap(), CSV);
    let url = s.url(&format!("/v1/tool-libraries/{csv_id}"));
    assert_eq!(c.delete(&url).send().await.unwrap().status(), 204);
    let (st, p) = json(c.get(&url).send().await.unwrap()).await;
    assert_eq!((st, p["status"].as_u64()), (404, Some(404)));
    assert_eq!(c.delete(&url).send().await.unwrap().status(), 404);
}

#[tokio::test]
async fn a_library_that_does_not_read_is_a_422_naming_the_tool_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    let thread_mill =
        r#"{"data":[{"type":"thread mill","geometry":{"DC":6},"post-process":{"number":7}}]}"#;
    let bull_without_radius = r#"{"data":[{"type":"bull nose end mill","geometry":{"DC":6},"post-process":{"number":1}}]}"#;
    for (name, body, tool, field, line) in [
        ("a.json", thread_mill, "T7 (data[0])", "type", None),
        (
            "b.json",
            bull_without_radius,
            "T1 (data[0])",
            "geometry.RE",
            None,
        ),
        ("c.tbl", "T1 P1 D6\nT3 P3 Dx\n", "line 2", "D", Some(2)),
        (
            "d.csv",
            "number,diameter,colour\n1,6,red\n",
            "header",
            "colour",
            None,
        ),
        (
            "e.csv",
            "number,type,diameter\n1,flat,6\n2,flat,-3\n",
            "T2 (line 3)",
            "geometry",
            Some(3),
        ),
    ] {
        let res = c
            .post(s.url(&format!("/v1/tool-libraries?name={name}")))
            .body(body)
            .send()
            .await
            .unwrap();
        assert_eq!(
            res.headers()["content-type"],
            "application/problem+json",
            "{name}"
        );
        let (st, p) = json(res).await;
        assert_eq!(st, 422, "{name}: {p}");
        assert_eq!(p["status"], 422);
        assert_eq!(
            (p["tool"].as_str(), p["field"].as_str()),
            (Some(tool), Some(field)),
            "{name}: {p}"
        );
        assert_eq!(p["file"], name);
        assert!(p["detail"].as_str().unwrap().starts_with(name), "{p}");
        assert_eq!(p["line"].as_u64(), line, "{name}: {p}");
    }
    // Not text: the line and column of the first byte that is not UTF-8.
    let (st, p) = json(
        c.post(s.url("/v1/tool-libraries?name=f.tbl"))
            .body(b"T1 P1 D6\nT2 D\xff\n".to_vec())
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 422, "{p}");
    assert_eq!(
        (p["line"].as_u64(), p["column"].as_u64()),
        (Some(2), Some(5))
    );
    // Nothing stored of any of them.
    let list = get_json(&c, &s, "/v1/tool-libraries").await;
    assert_eq!(list["items"], json!([]));
    // A job input that is not a tool library's id is refused naming the input.
    let (_, stock) = post_json(
        &c,
        &s,
        "/v1/stocks",
        &json!({"kind": "block", "min": [0, 0, -5], "max": [10, 10, 0]}),
    )
    .await;
    let (_, tool) = post_json(
        &c,
        &s,
        "/v1/tools",
        &json!({"type": "flat", "diameter_mm": 6, "flutes": 2, "flute_length_mm": 12}),
    )
    .await;
    let (st, p) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "simulate", "inputs": {"program": {"content": "G0 X1\n"}, "stock": stock["id"], "tool_library": tool["id"]}, "options": {"material": "TC6"}}),
    )
    .await;
    assert_eq!(
        (st, p["field"].as_str()),
        (422, Some("inputs.tool_library")),
        "{p}"
    );
    let (st, p) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "interpret", "inputs": {"program": {"content": "G0 X1\n"}, "tool_library": "x"}}),
    )
    .await;
    assert_eq!(
        (st, p["field"].as_str()),
        (422, Some("inputs.tool_library")),
        "{p}"
    );
}

#[tokio::test]
async fn another_api_key_cannot_see_a_library() {
    let dir = tempfile::tempdir().unwrap();
    let mut file = String::new();
    let mut keys = Vec::new();
    for name in ["cam", "mes"] {
        let out = std::process::Command::new(BIN)
            .args(["api-key", name])
            .output()
            .unwrap();
        let text = String::from_utf8(out.stdout).unwrap();
        let mut lines = text.lines();
        keys.push(
            lines
                .next()
                .unwrap()
                .strip_prefix("key: ")
                .unwrap()
                .to_string(),
        );
        file.push_str(
            lines
                .next()
                .unwrap()
                .strip_prefix("key file line: ")
                .unwrap(),
        );
        file.push('\n');
    }
    let key_file = dir.path().join("keys");
    std::fs::write(&key_file, &file).unwrap();
    let s = Server::start(
        &dir.path().join("t.db"),
        &[
            "--workers",
            "0",
            "--api-key-file",
            key_file.to_str().unwrap(),
        ],
    );
    let c = client();
    let (st, _) = json(
        c.post(s.url("/v1/tool-libraries"))
            .body(TBL)
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 401, "no key, no upload");
    let (st, lib) = json(
        c.post(s.url("/v1/tool-libraries?name=shop.tbl"))
            .bearer_auth(&keys[0])
            .body(TBL)
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 201, "{lib}");
    let id = lib["id"].as_str().unwrap();
    let url = s.url(&format!("/v1/tool-libraries/{id}"));
    let status = |req: reqwest::RequestBuilder| async move { req.send().await.unwrap().status() };
    assert_eq!(status(c.get(&url).bearer_auth(&keys[0])).await, 200);
    // The other key: not found, not listed, not an input, not deletable.
    assert_eq!(status(c.get(&url).bearer_auth(&keys[1])).await, 404);
    assert_eq!(
        status(c.get(format!("{url}/content")).bearer_auth(&keys[1])).await,
        404
    );
    let (_, list) = json(
        c.get(s.url("/v1/tool-libraries"))
            .bearer_auth(&keys[1])
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(list["items"], json!([]));
    let (_, stock) = json(
        c.post(s.url("/v1/stocks"))
            .bearer_auth(&keys[1])
            .json(&json!({"kind": "block", "min": [0, 0, -5], "max": [10, 10, 0]}))
            .send()
            .await
            .unwrap(),
    )
    .await;
    let (st, p) = json(
        c.post(s.url("/v1/jobs"))
            .bearer_auth(&keys[1])
            .json(&json!({"kind": "simulate", "inputs": {"program": {"content": "G0 X1\n"}, "stock": stock["id"], "tool_library": id}, "options": {"material": "TC6"}}))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(
        (st, p["field"].as_str()),
        (422, Some("inputs.tool_library")),
        "{p}"
    );
    assert_eq!(status(c.delete(&url).bearer_auth(&keys[1])).await, 404);
    assert_eq!(status(c.get(&url).bearer_auth(&keys[0])).await, 200);
}

/// Submits a job and waits for its end.
async fn run_job(c: &reqwest::Client, s: &Server, body: &Value) -> Value {
    let (st, job) = post_json(c, s, "/v1/jobs", body).await;
    assert_eq!(st, 202, "{job}");
    wait_job(c, s, job["id"].as_str().unwrap(), Duration::from_secs(300)).await
}

#[tokio::test]
async fn the_example_job_takes_its_tool_from_a_library_with_the_same_forces() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let ex = |f: &str| {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("examples/adaptive")
            .join(f)
    };
    let program = upload_program(&c, &s, &adaptive_program()).await;
    let read = |f: &str| serde_json::from_slice::<Value>(&std::fs::read(ex(f)).unwrap()).unwrap();
    let (_, stock) = post_json(&c, &s, "/v1/stocks", &read("stock.json")).await;
    let (_, tool) = post_json(&c, &s, "/v1/tools", &read("tool.json")).await;
    // examples/adaptive/tool.json as Fusion 360 writes it, with a tool the program never uses.
    let library = r#"{"data":[
      {"type":"flat end mill","unit":"millimeters","description":"2.65 mm 2-flute flat end mill",
       "geometry":{"DC":2.65,"NOF":2,"LCF":14,"LB":20,"SFDM":3.175,"helix-angle":30,"OAL":50},
       "holder":{"segments":[{"height":25,"lower-diameter":20,"upper-diameter":20}]},
       "post-process":{"number":1}},
      {"type":"ball end mill","unit":"millimeters","geometry":{"DC":0.5,"NOF":2,"LCF":1},"post-process":{"number":9}}]}"#;
    let (st, lib) = upload(&c, &s, "shop.json", "application/json", library).await;
    assert_eq!(st, 201, "{lib}");
    // A coarse grid and few force positions keep it short; both jobs run the same.
    let options = json!({"material": "Al7075-T6", "cell_mm": 0.3, "force_positions": 36});
    let with = |tools: Value| {
        let mut inputs = json!({"program": program, "stock": stock["id"]});
        inputs
            .as_object_mut()
            .unwrap()
            .extend(tools.as_object().unwrap().clone());
        json!({"kind": "simulate", "inputs": inputs, "options": options})
    };
    let reference = run_job(&c, &s, &with(json!({"tool": tool["id"]}))).await;
    let from_library = run_job(&c, &s, &with(json!({"tool_library": lib["id"]}))).await;
    assert_eq!(reference["status"], "succeeded", "{reference}");
    assert_eq!(from_library["status"], "succeeded", "{from_library}");
    let (a, b) = (&reference["summary"], &from_library["summary"]);
    for key in [
        "force_peak_n",
        "removed_volume_mm3",
        "cycle_time_s",
        "cell_mm",
    ] {
        assert_eq!(a[key], b[key], "{key}");
    }
    let rows = |job: &Value| format!("/v1/jobs/{}/blocks?format=csv", job["id"].as_str().unwrap());
    assert_eq!(
        get_text(&c, &s, &rows(&reference)).await,
        get_text(&c, &s, &rows(&from_library)).await
    );
    // The summary says where T1 came from and what of it is not modelled; T9 is not used.
    let section = &b["tool_library"];
    assert_eq!(section["file"], "shop.json");
    assert_eq!(section["format"], "fusion360");
    assert_eq!(section["tools"], json!(["T1"]));
    assert_eq!(
        pairs(&section["unmodelled"]),
        [("T1 (data[0])".to_string(), "geometry.OAL".to_string())]
    );
    let warnings = b["tool_warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{b}");
    let w = warnings[0].as_str().unwrap();
    assert!(
        w.starts_with("T1 (data[0]): from the tool library `shop.json`")
            && w.contains("geometry.OAL"),
        "{w}"
    );
    assert!(
        a.get("tool_library").is_none() && a.get("tool_warnings").is_none(),
        "{a}"
    );
}

/// A slot with each of two tools, loaded with M6, and no header comments.
const TWO_TOOLS: &str = "G21 G90\nT1 M6\nS10000 M3\nG0 Z5\nG0 X-10 Y-10\nG0 Z-5\nG1 X60 F2000\nG0 Z5\nT2 M6\nS12000 M3\nG0 X-10 Y10\nG0 Z-3\nG1 X60 F1500\nG0 Z5\nM30\n";

#[tokio::test]
async fn explicit_tools_win_over_the_library_and_an_unknown_number_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let (_, stock) = post_json(&c, &s, "/v1/stocks", &slot_block()).await;
    // The table's T1 (Ø10, flutes and helix assumed) and T2 (Ø6).
    let (st, lib) = upload(
        &c,
        &s,
        "shop.tbl",
        "text/plain",
        "T1 P1 D10 Z0 ;flat end mill\nT2 P2 D6 Z0 ;flat end mill\n",
    )
    .await;
    assert_eq!(st, 201, "{lib}");
    let (_, t2) = post_json(
        &c,
        &s,
        "/v1/tools",
        &json!({"type": "flat", "diameter_mm": 4.0, "flutes": 2, "flute_length_mm": 12.0}),
    )
    .await;
    let options = json!({"material": "Al7075-T6", "cell_mm": 0.25});
    let program = json!({"name": "two.nc", "content": TWO_TOOLS});
    let done = run_job(
        &c,
        &s,
        &json!({"kind": "simulate", "inputs": {"program": program, "stock": stock["id"], "tool_library": lib["id"], "T2": t2["id"]}, "options": options}),
    )
    .await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let id = done["id"].as_str().unwrap();
    let page = get_json(&c, &s, &format!("/v1/jobs/{id}/blocks?limit=100")).await;
    let rows = page["items"].as_array().unwrap();
    let at = |line: u32| rows.iter().find(|r| r["line"] == line).unwrap();
    // T1 from the library (Ø10), T2 the explicit Ø4: each slot as wide as its tool.
    assert!(
        (at(7)["radial_width_mm"].as_f64().unwrap() - 10.0).abs() <= 0.25,
        "{}",
        at(7)
    );
    assert!(
        (at(13)["radial_width_mm"].as_f64().unwrap() - 4.0).abs() <= 0.25,
        "{}",
        at(13)
    );
    let summary = &done["summary"];
    assert_eq!(summary["tool_library"]["tools"], json!(["T1"]), "{summary}");
    let assumed = pairs(&summary["tool_library"]["assumed"]);
    assert!(
        assumed.iter().all(|(t, _)| t == "T1 (line 1)"),
        "{assumed:?}"
    );
    assert!(assumed.contains(&("T1 (line 1)".into(), "flutes".into())));
    let warnings = summary["tool_warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{summary}");
    assert!(warnings[0]
        .as_str()
        .unwrap()
        .starts_with("T1 (line 1): from the tool library `shop.tbl`"));

    // One `tool` serves every number: the library gives none.
    let one = "G21 G90\nT2 M6\nS12000 M3\nG0 X-10 Y10 Z5\nG0 Z-3\nG1 X60 F1500\nG0 Z5\nM30\n";
    let done = run_job(
        &c,
        &s,
        &json!({"kind": "simulate", "inputs": {"program": {"content": one}, "stock": stock["id"], "tool_library": lib["id"], "tool": t2["id"]}, "options": options}),
    )
    .await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["summary"]["tool_library"]["tools"], json!([]));
    let id = done["id"].as_str().unwrap();
    let page = get_json(&c, &s, &format!("/v1/jobs/{id}/blocks?limit=100")).await;
    let cut = page["items"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["line"] == 6)
        .unwrap()
        .clone();
    assert!(
        (cut["radial_width_mm"].as_f64().unwrap() - 4.0).abs() <= 0.25,
        "{cut}"
    );

    // A T number in no input, no library and no header comment: refused, naming it and
    // its line; loaded with M6 or only selected.
    for (program, line) in [
        (
            "G21 G90\nT5 M6\nS10000 M3\nG0 X-10 Y0 Z5\nG0 Z-2\nG1 X60 F1000\nM30\n",
            "line 4",
        ),
        (
            "G21 G90\nT7\nS10000 M3\nG0 X-10 Y0 Z5\nG0 Z-2\nG1 X60 F1000\nM30\n",
            "line 6",
        ),
    ] {
        let failed = run_job(
            &c,
            &s,
            &json!({"kind": "simulate", "inputs": {"program": {"content": program}, "stock": stock["id"], "tool_library": lib["id"]}, "options": options}),
        )
        .await;
        assert_eq!(failed["status"], "failed", "{failed}");
        let detail = failed["error"]["detail"].as_str().unwrap();
        let number = &program[8..10];
        assert!(
            detail.contains(&format!("{line}: tool {number} is used but not defined")),
            "{detail}"
        );
        assert_eq!(failed["error"]["status"], 422);
    }
}

/// A Fusion 360 library of `tools` flat end mills, each with `fields` geometry fields
/// millsim does not model (`x0`, `x1`, ...): the shape of the library that killed the
/// server in issue 34 (10,000 tools × 700 fields, 60 MB).
fn big_fusion_library(tools: usize, fields: usize) -> String {
    let unknown: Vec<String> = (0..fields).map(|k| format!(r#""x{k}":{k}"#)).collect();
    let unknown = unknown.join(",");
    let mut out = String::from(r#"{"data":["#);
    for n in 1..=tools {
        if n > 1 {
            out.push(',');
        }
        out.push_str(&format!(
            r#"{{"type":"flat end mill","unit":"millimeters","geometry":{{"DC":6,"NOF":3,"LCF":18,{unknown}}},"post-process":{{"number":{n}}}}}"#
        ));
    }
    out.push_str("]}");
    out
}

/// Issue 34: a library's GET answers from what its upload read (stored beside the file),
/// never reading the file again: with the stored file cut short under the server, the
/// GET answers as before. A library stored before that (no stored view) is read at its
/// first GET, under the one-at-a-time reader, and its view stored then.
#[tokio::test]
async fn a_librarys_get_answers_from_what_its_upload_read() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    let (st, lib) = upload(&c, &s, "shop.json", "application/json", FUSION).await;
    assert_eq!(st, 201, "{lib}");
    let id = lib["id"].as_str().unwrap();
    let url = format!("/v1/tool-libraries/{id}");
    let before = get_json(&c, &s, &url).await;
    assert_eq!(before["tools"].as_object().unwrap().len(), 5, "{before}");
    // Every note counted by its field.
    assert_eq!(
        before["report"]["unmodelled_by_field"]["geometry.OAL"], 1,
        "{before}"
    );

    // A library as stored before views were: read at its GET, the same answer, and its
    // view stored for the next.
    sql(&s.db_url, "DELETE FROM resource_views").await;
    assert_eq!(get_json(&c, &s, &url).await, before);
    let views = sql_i64(&s.db_url, "SELECT COUNT(*) FROM resource_views").await;
    assert_eq!(views, 1);

    // The file cut short: it no longer reads, and the GET does not read it.
    sql(
        &s.db_url,
        &format!("UPDATE resources SET content = substr(content, 1, 5) WHERE id = '{id}'"),
    )
    .await;
    assert_eq!(get_json(&c, &s, &url).await, before);
    // The listing carries the summary only, as before.
    let list = get_json(&c, &s, "/v1/tool-libraries").await;
    assert_eq!(list["items"][0]["summary"], lib["summary"], "{list}");
    assert!(list["items"][0].get("tools").is_none(), "{list}");
}

/// Issue 34: three concurrent GETs of a large Fusion library (3,000 tools × 700 fields
/// millsim does not model, 21 MB) add a few MB to the server's peak memory, not the
/// library's parse tree each (hundreds of MB before; 2.9 GB a GET at 60 MB, and three
/// killed the server); the upload reads the tools one at a time (its whole tree before).
#[tokio::test]
async fn concurrent_reads_of_a_large_library_stay_within_a_few_megabytes() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let pid = s.child.id();
    let c = client();
    let (tools, fields) = (3_000, 700);
    let body = big_fusion_library(tools, fields);
    let mb = |kb: u64| kb as f64 / 1024.0;

    reset_peak_rss(pid);
    let rss = proc_kb(pid, "VmRSS");
    let clock = Instant::now();
    let (st, lib) = upload(&c, &s, "big.json", "application/json", &body).await;
    assert_eq!(st, 201, "{lib}");
    let upload_s = clock.elapsed().as_secs_f64();
    let upload_peak = proc_kb(pid, "VmHWM").saturating_sub(rss);
    assert_eq!(lib["summary"]["unmodelled"], tools * fields, "{lib}");
    let id = lib["id"].as_str().unwrap().to_string();

    reset_peak_rss(pid);
    let rss = proc_kb(pid, "VmRSS");
    let clock = Instant::now();
    let reads = (0..3).map(|_| {
        let (c, url) = (c.clone(), s.url(&format!("/v1/tool-libraries/{id}")));
        tokio::spawn(async move {
            let started = Instant::now();
            let (st, v) = json(c.get(url).send().await.unwrap()).await;
            (st, v, started.elapsed().as_secs_f64())
        })
    });
    let mut latencies = Vec::new();
    for read in reads.collect::<Vec<_>>() {
        let (st, v, secs) = read.await.unwrap();
        assert_eq!(st, 200, "{v}");
        assert_eq!(v["tools"].as_object().unwrap().len(), tools);
        let report = &v["report"];
        assert_eq!(report["unmodelled"].as_array().unwrap().len(), 500);
        assert_eq!(report["unmodelled_omitted"], tools * fields - 500);
        // The first 500 fields by name, the other 200 together.
        let by_field = &report["unmodelled_by_field"];
        assert_eq!(by_field["geometry.x0"], tools);
        assert_eq!(by_field["(other fields)"], tools * (fields - 500));
        latencies.push(secs);
    }
    let reads_s = clock.elapsed().as_secs_f64();
    let reads_peak = proc_kb(pid, "VmHWM").saturating_sub(rss);
    println!(
        "{} MB library: upload {upload_s:.2} s, peak +{:.1} MB; 3 concurrent GETs {reads_s:.2} s (each {latencies:.2?} s), peak +{:.1} MB",
        body.len() >> 20,
        mb(upload_peak),
        mb(reads_peak)
    );
    assert!(
        reads_peak < 32 * 1024,
        "3 GETs took the server's peak {:.1} MB higher",
        mb(reads_peak)
    );
    assert!(
        upload_peak < 100 * 1024,
        "the upload took the server's peak {:.1} MB higher",
        mb(upload_peak)
    );
}
