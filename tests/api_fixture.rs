//! Fixtures over HTTP: `options.fixture` on a simulate job (a block clamp and an STL body
//! from a `fixture/<name>` input), the collision read back from the summary and the rows,
//! and bad fixtures refused at submission naming the field.

mod common;

use std::time::Duration;

use common::*;
use serde_json::{json, Value};

#[tokio::test]
async fn a_rapid_through_a_clamp_is_named_in_the_summary_and_the_rows() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let id = |v: &Value| v["id"].as_str().unwrap().to_string();
    let (st, stock) = post_json(&c, &s, "/v1/stocks", &slot_block()).await;
    assert_eq!(st, 201, "{stock}");
    let tool = post_slot_tool(&c, &s).await;
    // A jaw as an STL stock resource: x 60..70, y −32..−22, up to z 6.
    let (st, jaw) = post_stl(
        &c,
        &s,
        "/v1/stocks",
        exported_box_stl([60.0, -32.0, -10.0], [70.0, -22.0, 6.0]),
    )
    .await;
    assert_eq!(st, 201, "{jaw}");
    // Line 4 rapids along y 27 at z 5 through clamp 1 (x 40..50, y 22..32, up to z 8);
    // line 6 along y −27 through the jaw; line 10 feeds along y 16, 1 mm from clamp 1.
    let program = "G21 G90 G17\nS10000 M3\nG0 X-10 Y27 Z5\nG0 X120\nG0 X120 Y-27\nG0 X-10\n\
        G0 Z20\nG0 X-10 Y16\nG1 Z-2 F600\nG1 X120 F1000\nG0 Z20\nM30\n";
    let prog = post_program(&c, &s, "clamped.nc", program).await;
    let fixture = json!({"bodies":[
        {"name":"clamp 1","kind":"block","min":[40,22,-10],"max":[50,32,8]},
        {"name":"jaw","kind":"stl","input":"fixture/jaw"}]});
    let body = json!({"kind":"simulate",
        "inputs":{"program":prog,"stock":id(&stock),"tool":tool,"fixture/jaw":id(&jaw)},
        "options":{"material":"Al7075-T6","cell_mm":0.5,"fixture":fixture}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let done = wait_job(&c, &s, &id(&job), Duration::from_secs(120)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let fx = &done["summary"]["fixture"];
    assert_eq!(fx["bodies"], json!(["clamp 1", "jaw"]), "{fx}");
    assert_eq!(fx["collision_moves"], 2, "{fx}");
    let first = &fx["collisions"][0];
    assert_eq!(
        (
            &first["body"],
            &first["line"],
            &first["kind"],
            &first["part"]
        ),
        (
            &json!("clamp 1"),
            &json!(4),
            &json!("rapid"),
            &json!("flutes")
        ),
        "{first}"
    );
    // The slot tool is a flat Ø10: its edge (x + 5) reaches the clamp's face x 40 at x 35.
    let tip: Vec<f64> = serde_json::from_value(first["tip"].clone()).unwrap();
    assert!(
        (tip[0] - 35.0).abs() < 1e-6 && (tip[1] - 27.0).abs() < 1e-9,
        "{first}"
    );
    assert!(
        (first["point"][0].as_f64().unwrap() - 40.0).abs() < 1e-6,
        "{first}"
    );
    // Back along y −27 from x 120: the edge (x − 5) meets the jaw's face x 70 at x 75.
    let second = &fx["collisions"][1];
    assert_eq!(
        (&second["body"], &second["line"]),
        (&json!("jaw"), &json!(6)),
        "{second}"
    );
    assert!(
        (second["tip"][0].as_f64().unwrap() - 75.0).abs() < 1e-6,
        "{second}"
    );
    assert!(done["summary"]["collisions"]
        .as_array()
        .unwrap()
        .iter()
        .any(|k| k["kind"] == "fixture_contact" && k["line"] == 4));

    let page = get_json(&c, &s, &format!("/v1/jobs/{}/blocks", id(&job))).await;
    let rows = page["items"].as_array().unwrap();
    for r in rows {
        // Every row names the column; only the two rapids have a body.
        assert!(r.get("fixture_body").is_some(), "{r}");
        let flagged = r["flags"].as_str().unwrap().contains("fixture_contact");
        match r["line"].as_u64().unwrap() {
            4 => assert_eq!(
                (flagged, &r["fixture_body"]),
                (true, &json!("clamp 1")),
                "{r}"
            ),
            6 => assert_eq!((flagged, &r["fixture_body"]), (true, &json!("jaw")), "{r}"),
            _ => assert_eq!((flagged, &r["fixture_body"]), (false, &Value::Null), "{r}"),
        }
    }
}

#[tokio::test]
async fn a_bad_fixture_is_refused_at_submission_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let (_, stock) = post_json(&c, &s, "/v1/stocks", &slot_block()).await;
    let tool = post_slot_tool(&c, &s).await;
    let prog = post_program(&c, &s, "p.nc", "G0 X0 Y0 Z5\nM30\n").await;
    let (_, jaw) = post_stl(
        &c,
        &s,
        "/v1/stocks",
        exported_box_stl([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
    )
    .await;
    let block = json!({"kind":"block","min":[0,0,0],"max":[1,1,1]});
    let submit = |fixture: Value, extra: Option<(&str, &Value)>| {
        let mut inputs = json!({"program":prog,"stock":stock["id"],"tool":tool});
        if let Some((name, v)) = extra {
            inputs[name] = v["id"].clone();
        }
        json!({"kind":"simulate","inputs":inputs,
            "options":{"material":"Al7075-T6","fixture":fixture}})
    };
    for (body, field) in [
        (
            submit(
                json!({"bodies":[block, block,
                    {"kind":"block","min":[0,0,5],"max":[1,1,4]}]}),
                None,
            ),
            "options.fixture.bodies[2].max",
        ),
        (
            submit(
                json!({"bodies":[{"kind":"stl","input":"fixture/jaw"}]}),
                None,
            ),
            "options.fixture.bodies[0].input",
        ),
        (
            submit(json!({"bodies":[block]}), Some(("fixture/jaw", &jaw))),
            "inputs.fixture/jaw",
        ),
        (
            submit(json!({"bodies":vec![block.clone(); 65]}), None),
            "options.fixture.bodies",
        ),
    ] {
        let (st, p) = post_json(&c, &s, "/v1/jobs", &body).await;
        assert_eq!((st, p["field"].as_str()), (422, Some(field)), "{p}");
    }
}
