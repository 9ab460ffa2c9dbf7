//! Every job kind is held to the job memory budget at submission (issue 16): interpret and
//! rotary-feed by their program's size, stability and energy by their lobes' transition
//! matrices. Over the budget: 422 resource-limit naming it; under it, 202. Real server,
//! real HTTP, a 64 MiB budget.

mod common;

use serde_json::{json, Value};

use common::*;

fn server(dir: &tempfile::TempDir) -> Server {
    Server::start(
        &dir.path().join("t.db"),
        &["--workers", "1", "--job-memory-mb", "64"],
    )
}

/// Asserts a 422 resource-limit problem naming the 64 MiB budget and the kind.
fn assert_over_budget(status: u16, p: &Value, kind: &str) {
    assert_eq!(status, 422, "{p}");
    assert_eq!(
        p["type"], "https://millsim.dev/problems/resource-limit",
        "{p}"
    );
    assert_eq!(
        (p["limit_name"].as_str(), p["limit"].as_u64()),
        (Some("job_memory_mb"), Some(64)),
        "{p}"
    );
    assert!(p["estimate_mb"].as_u64().unwrap() > 64, "{p}");
    let detail = p["detail"].as_str().unwrap();
    assert!(detail.contains(&format!("the {kind} job")), "{detail}");
    assert!(detail.contains("64 MiB"), "{detail}");
}

/// G-code of `lines` feed moves (about 20 bytes each).
fn program(lines: usize) -> String {
    let mut p = String::from("G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F500\n");
    for i in 0..lines {
        p += &format!("G1 X{}.5 Y{}\n", i % 97, i % 89);
    }
    p + "M30\n"
}

const MACHINE: &str = r#"{"name": "VMC", "rapid_rate": 24000.0, "max_feed": 8000.0,
    "acceleration": [2000.0, 2000.0, 1500.0], "spindle_min_rpm": 500.0, "spindle_max_rpm": 12000.0,
    "rated_power": 5500.0, "efficiency": 0.8, "torque_limit": 30.0, "axis_thrust_limit": 3000.0,
    "energy": {"idle": {"base_rpm": 3000, "below": [823.3, 0.0149, 2e-6], "above": [881.5, -0.0034, 3e-6]}, "aux_power_w": 804}}"#;

fn modes(n: usize) -> Vec<Value> {
    (0..n)
        .map(|i| json!({"freq_hz": 900 + 37 * i, "damping": 0.02, "stiffness_n_m": 2e7}))
        .collect()
}

#[tokio::test]
async fn an_interpret_job_over_the_budget_is_refused_inline_or_stored() {
    let dir = tempfile::tempdir().unwrap();
    let s = server(&dir);
    let c = client();
    // 150,000 lines, 2.5 MB: about 100 MB parsed with its moves and rows.
    let big = program(150_000);
    let body =
        json!({"kind": "interpret", "inputs": {"program": {"name": "big.nc", "content": big}}});
    let (st, p) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_over_budget(st, &p, "interpret");
    // The same program uploaded first: its stored size.
    let path = dir.path().join("big.nc");
    std::fs::write(&path, &big).unwrap();
    let id = upload_program(&c, &s, &path).await;
    let body = json!({"kind": "interpret", "inputs": {"program": id}});
    let (st, p) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_over_budget(st, &p, "interpret");
    // A tenth of it fits.
    let body = json!({"kind": "interpret", "inputs": {"program": {"name": "small.nc", "content": program(15_000)}}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
}

#[tokio::test]
async fn a_rotary_feed_job_over_the_budget_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let s = server(&dir);
    let c = client();
    let machine = create(
        &c,
        &s,
        "/v1/machines",
        serde_json::from_str(MACHINE).unwrap(),
    )
    .await;
    let body = |lines| {
        json!({"kind": "rotary-feed",
            "inputs": {"program": {"name": "p.nc", "content": program(lines)}, "machine": machine}})
    };
    let (st, p) = post_json(&c, &s, "/v1/jobs", &body(150_000)).await;
    assert_over_budget(st, &p, "rotary-feed");
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body(15_000)).await;
    assert_eq!(st, 202, "{job}");
}

#[tokio::test]
async fn a_stability_job_with_many_modes_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let s = server(&dir);
    let c = client();
    let options = |n: usize, method: &str| {
        json!({"method": method, "teeth": 2, "ktc_n_mm2": 600, "krc_n_mm2": 200,
            "radial_immersion": 0.5, "milling": "down", "modes_x": modes(n), "modes_y": modes(n),
            "rpm": {"from": 5000, "to": 6000, "step": 500}, "steps_per_period": 40})
    };
    // The issue's job: 100 modes a direction (a transition matrix of dimension 8400).
    let (st, p) = post_json(
        &c,
        &s,
        "/v1/jobs",
        &json!({"kind": "stability", "options": options(100, "sdm")}),
    )
    .await;
    assert_over_budget(st, &p, "stability");
    assert!(
        p["estimate"]["lobe_matrices_bytes"].as_u64().unwrap() > 1 << 30,
        "{p}"
    );
    // Two modes a direction fit; so do 100 with the zero-order method (no time steps).
    for (n, method) in [(2, "sdm"), (100, "zoa")] {
        let body = json!({"kind": "stability", "options": options(n, method)});
        let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
        assert_eq!(st, 202, "{n} {method}: {job}");
    }
}

#[tokio::test]
async fn an_energy_job_whose_stability_lobes_are_too_large_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let s = server(&dir);
    let c = client();
    let tool = create(
        &c,
        &s,
        "/v1/tools",
        json!({"type": "flat", "diameter_mm": 10.0, "flutes": 4, "helix_deg": 30.0, "flute_length_mm": 25.0}),
    )
    .await;
    let machine = create(
        &c,
        &s,
        "/v1/machines",
        serde_json::from_str(MACHINE).unwrap(),
    )
    .await;
    let body = |n: usize| {
        json!({"kind": "energy", "inputs": {"tool": tool, "machine": machine},
            "options": {"material": "Al7075-T6", "length_mm": 200, "width_mm": 8, "depth_mm": 12,
                "cutting_speed_m_min": {"min": 100, "max": 300}, "feed_per_tooth_mm": {"min": 0.02, "max": 0.2},
                "objective": "min_energy", "modes_x": modes(n), "modes_y": modes(n),
                "stability_method": "sdm", "steps_per_period": 40}})
    };
    let (st, p) = post_json(&c, &s, "/v1/jobs", &body(40)).await;
    assert_over_budget(st, &p, "energy");
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body(2)).await;
    assert_eq!(st, 202, "{job}");
}
