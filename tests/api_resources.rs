//! Every resource kind: create, get, list (cursor pages), content, delete; and the 4xx
//! answers for bad input.

mod common;

use common::*;
use serde_json::json;
use std::time::Duration;

fn tool() -> serde_json::Value {
    json!({"shape": "bull_nose", "diameter": 8.0, "corner_radius": 1.0, "flutes": 4, "helix_deg": 35.0, "flute_length": 20.0})
}
fn material() -> serde_json::Value {
    json!({"name": "Al7075-T6 (lab)", "coefficients": {"ktc": 767.01, "krc": 168.8, "kac": 222.0, "kte": 27.7, "kre": 26.6, "kae": 0.7}, "source": "test"})
}
fn machine() -> serde_json::Value {
    json!({"name": "VMC", "rapid_rate": 24000.0, "max_feed": 10000.0, "acceleration": [2000.0, 2000.0, 1500.0],
           "spindle_min_rpm": 100.0, "spindle_max_rpm": 12000.0, "rated_power": 11000.0})
}

#[tokio::test]
async fn json_resources_create_get_list_delete() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    for (coll, body) in [
        ("tools", tool()),
        ("materials", material()),
        ("machines", machine()),
        (
            "stocks",
            json!({"kind": "block", "min": [0, 0, -10], "max": [100, 50, 0]}),
        ),
    ] {
        let mut ids = Vec::new();
        for _ in 0..3 {
            let res = c
                .post(s.url(&format!("/v1/{coll}")))
                .json(&body)
                .send()
                .await
                .unwrap();
            let location = res
                .headers()
                .get("location")
                .unwrap()
                .to_str()
                .unwrap()
                .to_string();
            let (status, v) = json(res).await;
            assert_eq!(status, 201, "{coll}: {v}");
            assert_eq!(
                location,
                format!("/v1/{coll}/{}", v["id"].as_str().unwrap())
            );
            ids.push(v["id"].as_str().unwrap().to_string());
        }
        let (status, got) = json(
            c.get(s.url(&format!("/v1/{coll}/{}", ids[0])))
                .send()
                .await
                .unwrap(),
        )
        .await;
        assert_eq!(status, 200);
        assert_eq!(
            got["definition"], body,
            "{coll}: definition stored unchanged"
        );
        // Cursor pages of 2: ids come back in creation order, then the cursor runs out.
        let (_, p1) = json(
            c.get(s.url(&format!("/v1/{coll}?limit=2")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        assert_eq!(p1["items"].as_array().unwrap().len(), 2);
        let cursor = p1["next_cursor"].as_str().unwrap();
        let (_, p2) = json(
            c.get(s.url(&format!("/v1/{coll}?limit=2&cursor={cursor}")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        let all: Vec<&str> = p1["items"]
            .as_array()
            .unwrap()
            .iter()
            .chain(p2["items"].as_array().unwrap())
            .map(|v| v["id"].as_str().unwrap())
            .collect();
        assert_eq!(all, ids.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(p2["next_cursor"].is_null());
        let content = c
            .get(s.url(&format!("/v1/{coll}/{}/content", ids[1])))
            .send()
            .await
            .unwrap()
            .bytes()
            .await
            .unwrap();
        assert_eq!(
            serde_json::from_slice::<serde_json::Value>(&content).unwrap(),
            body
        );
        assert_eq!(
            c.delete(s.url(&format!("/v1/{coll}/{}", ids[0])))
                .send()
                .await
                .unwrap()
                .status(),
            204
        );
        let (status, p) = json(
            c.get(s.url(&format!("/v1/{coll}/{}", ids[0])))
                .send()
                .await
                .unwrap(),
        )
        .await;
        assert_eq!(status, 404);
        assert_eq!(p["status"], 404);
        assert_eq!(
            c.delete(s.url(&format!("/v1/{coll}/{}", ids[0])))
                .send()
                .await
                .unwrap()
                .status(),
            404
        );
    }
}

#[tokio::test]
async fn files_are_stored_unchanged_with_their_names() {
    if !corpus_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "0"]);
    let c = client();
    // A program, raw body.
    let path = corpus("gcode/fanuc_R_arcs_G3R_G1R_G1C.nc");
    let id = upload_program(&c, &s, &path).await;
    let (_, meta) = json(
        c.get(s.url(&format!("/v1/programs/{id}")))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(meta["name"], "fanuc_R_arcs_G3R_G1R_G1C.nc");
    let back = c
        .get(s.url(&format!("/v1/programs/{id}/content")))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    assert_eq!(back.as_ref(), std::fs::read(&path).unwrap().as_slice());
    // An STL, multipart, whose binary header starts with "solid".
    let stl = std::fs::read(corpus("stl/numpystl_Cube_binary_solid_header.stl")).unwrap();
    let (status, v) = post_stl_multipart(&c, &s, stl.clone(), "cube.stl").await;
    assert_eq!(status, 201, "{v}");
    assert_eq!(v["name"], "cube.stl");
    assert_eq!(v["summary"]["triangles"], 12);
    let back = c
        .get(s.url(&format!("/v1/stocks/{}/content", v["id"].as_str().unwrap())))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    assert_eq!(back.as_ref(), stl.as_slice());
    // An ASCII STL and a real part, raw bodies.
    for f in [
        "stl/numpystl_HalfDonut_ascii.stl",
        "stl/numpystl_rear_case_binary_18808tri.stl",
    ] {
        let (status, v) = post_stl(
            &c,
            &s,
            "/v1/stocks?name=x.stl",
            std::fs::read(corpus(f)).unwrap(),
        )
        .await;
        assert_eq!(status, 201, "{f}: {v}");
    }
}

#[tokio::test]
async fn bad_input_is_a_problem_document_naming_what_and_where() {
    if !corpus_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(
        &dir.path().join("t.db"),
        &[
            "--workers",
            "0",
            "--max-upload-bytes",
            "4096",
            "--max-program-bytes",
            "2048",
        ],
    );
    let c = client();
    let problem = |res: reqwest::Response| async move {
        let ct = res
            .headers()
            .get("content-type")
            .map(|v| v.to_str().unwrap().to_string());
        let (status, v) = json(res).await;
        assert_eq!(ct.as_deref(), Some("application/problem+json"), "{v}");
        assert_eq!(v["status"], status);
        (status, v)
    };
    // Malformed JSON: 400 with line and column.
    let (st, v) = problem(
        c.post(s.url("/v1/tools"))
            .header("content-type", "application/json")
            .body("{\"shape\": \"flat\",\n \"diameter\": }")
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 400);
    assert_eq!(v["line"], 2);
    // Bad enum value: 422 naming the field.
    let mut t = tool();
    t["shape"] = json!("flot");
    let (st, v) = problem(c.post(s.url("/v1/tools")).json(&t).send().await.unwrap()).await;
    assert_eq!(st, 422);
    assert_eq!(v["field"], "shape");
    // Absurd number: 422 naming the field.
    let mut t = tool();
    t["flutes"] = json!(0);
    let (st, v) = problem(c.post(s.url("/v1/tools")).json(&t).send().await.unwrap()).await;
    assert_eq!((st, v["field"].as_str()), (422, Some("flutes")));
    let mut m = material();
    m.as_object_mut().unwrap().remove("source");
    let (st, v) = problem(
        c.post(s.url("/v1/materials"))
            .json(&m)
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!((st, v["field"].as_str()), (422, Some("source")), "{v}");
    // Unknown ids.
    for path in [
        "/v1/tools/nope",
        "/v1/programs/nope/content",
        "/v1/jobs/nope",
        "/v1/jobs/nope/blocks",
    ] {
        let (st, _) = problem(c.get(s.url(path)).send().await.unwrap()).await;
        assert_eq!(st, 404, "{path}");
    }
    // Oversized body: 413, whether announced by Content-Length or streamed. The server
    // closes such a connection without reading the rest, so these use their own client.
    let once = || {
        reqwest::Client::builder()
            .pool_max_idle_per_host(0)
            .build()
            .unwrap()
    };
    let (st, v) = problem(
        once()
            .post(s.url("/v1/stocks"))
            .header("content-type", "model/stl")
            .body(vec![0u8; 10_000])
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 413);
    assert_eq!(v["limit_bytes"], 4096);
    // The problem names the server option that raises the limit, and its default.
    assert_eq!(v["setting"], "--max-upload-bytes", "{v}");
    assert!(
        v["detail"]
            .as_str()
            .unwrap()
            .contains("MILLSIM_MAX_UPLOAD_BYTES"),
        "{v}"
    );
    // A program over its own limit likewise, as an upload and inline in a job.
    let big = "G1 X1 Y1 F100\n".repeat(300);
    let (st, v) = problem(
        once()
            .post(s.url("/v1/programs"))
            .header("content-type", "text/plain")
            .body(big.clone())
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 413, "{v}");
    assert_eq!(
        (v["limit_bytes"].as_u64(), v["setting"].as_str()),
        (Some(2048), Some("--max-program-bytes")),
        "{v}"
    );
    let (st, v) = problem(
        once()
            .post(s.url("/v1/jobs"))
            .header("content-type", "application/json")
            .body(serde_json::json!({"kind": "interpret", "inputs": {"program": {"name": "big.nc", "content": big}}}).to_string())
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 413, "{v}");
    assert_eq!(v["setting"], "--max-program-bytes", "{v}");
    let chunks =
        futures_util::stream::iter((0..10).map(|_| Ok::<_, std::io::Error>(vec![0u8; 1000])));
    let (st, _) = problem(
        once()
            .post(s.url("/v1/stocks"))
            .header("content-type", "model/stl")
            .body(reqwest::Body::wrap_stream(chunks))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 413);
    // A broken STL: 422 saying what is wrong.
    let mut stl = std::fs::read(corpus("stl/numpystl_Cube_binary_solid_header.stl")).unwrap();
    stl.truncate(300);
    let (st, v) = problem(
        c.post(s.url("/v1/stocks?name=cut.stl"))
            .header("content-type", "model/stl")
            .body(stl)
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 422);
    assert!(v["detail"].as_str().unwrap().contains("cut.stl"), "{v}");
    // A program with a syntax error: every error with its line.
    let (st, v) = problem(
        c.post(s.url("/v1/programs?name=bad.nc"))
            .body("G0 X1\nG1 X[1+ F100\nG1 Y2 Q\n")
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 422, "{v}");
    assert_eq!(v["file"], "bad.nc");
    assert_eq!(v["errors"][0]["line"], 2);
    // With control flow, a plain line's error stops the program only if the line runs
    // (LinuxCNC): the upload is stored and lists it.
    let res = c
        .post(s.url("/v1/programs?name=branch.ngc"))
        .body("o1 if [0]\nGG1 X1\no1 endif\nG0 X1\nM2\n")
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 201);
    let v: serde_json::Value = res.json().await.unwrap();
    let errs = &v["summary"]["syntax_errors_if_executed"];
    assert_eq!(
        (&errs[0]["line"], &errs[0]["column"]),
        (&2.into(), &2.into()),
        "{v}"
    );
    // Bad query values.
    let (st, v) = problem(c.get(s.url("/v1/jobs?status=done")).send().await.unwrap()).await;
    assert_eq!((st, v["field"].as_str()), (422, Some("status")));
    let (st, v) = problem(c.get(s.url("/v1/tools?limit=0")).send().await.unwrap()).await;
    assert_eq!((st, v["field"].as_str()), (422, Some("limit")));
    let (st, _) = problem(c.get(s.url("/v1/tools?bogus=1")).send().await.unwrap()).await;
    assert_eq!(st, 400);
    // Unknown route and wrong method.
    let (st, _) = problem(c.get(s.url("/v2/anything")).send().await.unwrap()).await;
    assert_eq!(st, 404);
    let (st, _) = problem(c.put(s.url("/v1/tools")).send().await.unwrap()).await;
    assert_eq!(st, 405);
}

#[tokio::test]
async fn download_names_are_cleaned_of_paths_and_control_characters() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    // `../../etc/pass<CR><LF>wd "ö".nc`, percent-encoded in the query.
    let (st, v) = json(
        c.post(s.url("/v1/programs?name=..%2F..%2Fetc%2Fpass%0D%0Awd%20%22%C3%B6%22.nc"))
            .body("G0 X1\n")
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(st, 201, "{v}");
    let res = c
        .get(s.url(&format!(
            "/v1/programs/{}/content",
            v["id"].as_str().unwrap()
        )))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    let cd = res.headers()["content-disposition"].to_str().unwrap();
    assert_eq!(
        cd, "attachment; filename=\"passwd ___.nc\"; filename*=UTF-8''passwd%20%22%C3%B6%22.nc",
        "{cd}"
    );
}

/// A binary STL of the box from `a` to `b`, its triangles wound outwards, or inwards
/// (`inside_out`), each given `copies` times.
fn box_stl(a: [f32; 3], b: [f32; 3], inside_out: bool, copies: usize) -> Vec<u8> {
    let p = |i: usize| [0, 1, 2].map(|k| if (i >> k) & 1 == 1 { b[k] } else { a[k] });
    let faces: [[usize; 3]; 12] = [
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    let mut out = vec![0u8; 80];
    out.extend_from_slice(&((12 * copies) as u32).to_le_bytes());
    for _ in 0..copies {
        for f in faces {
            let f = if inside_out { [f[0], f[2], f[1]] } else { f };
            out.extend_from_slice(&[0u8; 12]);
            for i in f {
                for c in p(i) {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
            out.extend_from_slice(&[0u8; 2]);
        }
    }
    out
}

/// `stl` with its triangle `t` wound the other way (its last two corners swapped).
fn turn_triangle(mut stl: Vec<u8>, t: usize) -> Vec<u8> {
    let at = 84 + 50 * t + 12 + 12;
    let second: Vec<u8> = stl[at..at + 12].to_vec();
    stl.copy_within(at + 12..at + 24, at);
    stl[at + 12..at + 24].copy_from_slice(&second);
    stl
}

/// `stl` with corner `k` of triangle `t` moved by `d` along x.
fn nudge_corner(mut stl: Vec<u8>, t: usize, k: usize, d: f32) -> Vec<u8> {
    let at = 84 + 50 * t + 12 + 12 * k;
    let x = f32::from_le_bytes(stl[at..at + 4].try_into().unwrap()) + d;
    stl[at..at + 4].copy_from_slice(&x.to_le_bytes());
    stl
}

/// Issue 34: an inside-out STL stock (stored before with volume −24,000 mm³, and read by a
/// job as no material), one with every face twice (volume doubled), one with a triangle
/// wound against its neighbours and one with a corner a rounding off are repaired, with a
/// warning in the upload's summary, and a job cuts them as the plain box.
#[tokio::test]
async fn inside_out_and_duplicated_stl_stocks_are_repaired_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let (a, b) = ([0.0, 0.0, -10.0], [60.0, 40.0, 0.0]);
    let mut stocks = Vec::new();
    for (name, stl, warning) in [
        ("plain.stl", box_stl(a, b, false, 1), None),
        ("inside-out.stl", box_stl(a, b, true, 1), Some("inside out")),
        (
            "twice.stl",
            box_stl(a, b, false, 2),
            Some("12 duplicate triangles"),
        ),
        // A triangle wound against its neighbours (its normal pointing in), as sloppy
        // exporters write: turned to match them, not refused as open.
        (
            "one-turned.stl",
            turn_triangle(box_stl(a, b, false, 1), 3),
            Some("1 triangles were wound against their neighbours"),
        ),
        // A corner 0.1 µm off its neighbours' (a rounding in the exporter): merged.
        (
            "rounded.stl",
            nudge_corner(box_stl(a, b, false, 1), 5, 1, 1e-4),
            Some("1 vertices lay within a rounding"),
        ),
    ] {
        let (st, v) = post_stl(&c, &s, &format!("/v1/stocks?name={name}"), stl).await;
        assert_eq!(st, 201, "{name}: {v}");
        let summary = &v["summary"];
        assert_eq!(summary["volume_mm3"], 24_000.0, "{name}: {v}");
        assert_eq!(summary["triangles"], 12, "{name}: {v}");
        let warnings = summary["warnings"].as_array().unwrap();
        match warning {
            None => assert!(warnings.is_empty(), "{name}: {v}"),
            Some(w) => assert!(
                warnings.len() == 1 && warnings[0].as_str().unwrap().contains(w),
                "{name}: {v}"
            ),
        }
        let turned = summary["repairs"]["triangles_turned_to_match"].clone();
        assert_eq!(turned, i32::from(name == "one-turned.stl"), "{name}: {v}");
        let merged = summary["repairs"]["vertices_merged"].clone();
        assert_eq!(merged, i32::from(name == "rounded.stl"), "{name}: {v}");
        assert_eq!(summary["repairs"]["t_junctions_split"], 0, "{name}: {v}");
        stocks.push(v["id"].as_str().unwrap().to_string());
    }
    let (_, tool) = post_json(
        &c,
        &s,
        "/v1/tools",
        &json!({"type": "flat", "diameter_mm": 8, "flutes": 3, "helix_deg": 35, "flute_length_mm": 20}),
    )
    .await;
    let program =
        "G21 G90\nT1 M6\nS10000 M3\nG0 X-10 Y20 Z5\nG1 Z-2 F300\nG1 X70 F600\nG0 Z5\nM30\n";
    let (mut summaries, mut job_warnings) = (Vec::new(), Vec::new());
    for stock in &stocks {
        let body = json!({"kind": "simulate", "inputs": {"program": {"name": "slot.nc", "content": program},
            "stock": stock, "tool": tool["id"]}, "options": {"material": "Al7075-T6"}});
        let done = run_job(&c, &s, &body, Duration::from_secs(60)).await;
        // What the stock decides (the timings differ from run to run).
        let cut: Vec<serde_json::Value> = [
            "stock_volume_before",
            "stock_volume_after",
            "removed_volume_mm3",
            "cutting_moves",
            "force_peak_n",
        ]
        .iter()
        .map(|k| done["summary"][k].clone())
        .collect();
        summaries.push(cut);
        job_warnings.push(done["summary"]["warnings"].to_string());
    }
    // The job says what reading its stock repaired, as the upload did.
    for (i, w) in job_warnings.iter().enumerate() {
        let repaired = [
            (1, "stock STL: the mesh is inside out"),
            (2, "stock STL: 12 duplicate triangles"),
            (3, "stock STL: 1 triangles were wound against"),
            (4, "stock STL: 1 vertices lay within a rounding"),
        ];
        match repaired.iter().find(|(k, _)| *k == i) {
            Some((_, want)) => assert!(w.contains(want), "{i}: {w}"),
            None => assert!(!w.contains("stock STL"), "{i}: {w}"),
        }
    }
    assert!(
        summaries[0][2].as_f64().unwrap() > 900.0,
        "{:?}",
        summaries[0]
    );
    assert_eq!(summaries[1], summaries[0]);
    assert_eq!(summaries[2], summaries[0]);
    assert_eq!(summaries[3], summaries[0]);
    assert_eq!(summaries[4], summaries[0]);
}
