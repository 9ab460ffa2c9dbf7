//! The dashboard in a real browser: runs the scripts of tests/browser (playwright-core
//! driving Debian's /usr/bin/chromium, never a downloaded browser) against this build's
//! `millsim`. Each skips, saying why, when node, playwright-core (`npm ci` in tests/browser)
//! or chromium is absent; `.ci/run` installs all three, so CI runs them.

mod common;

use std::path::Path;
use std::process::Command;
use std::sync::Mutex;
use std::time::Duration;

use common::*;
use serde_json::json;

/// One browser at a time: the scripts measure frame and paint times, which a second
/// chromium on the same cores would distort.
static ONE_BROWSER: Mutex<()> = Mutex::new(());

fn run_script(script: &str) {
    let _one = ONE_BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser");
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    let node_ok = Command::new("node")
        .arg("--version")
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !node_ok {
        skip("node");
        return;
    }
    if !dir.join("node_modules/playwright-core").is_dir() {
        skip(&format!(
            "playwright-core (run `npm ci` in {})",
            dir.display()
        ));
        return;
    }
    if !Path::new(&chromium).exists() {
        skip(&format!("{chromium} (apt-get install chromium)"));
        return;
    }
    let out = Command::new("node")
        .arg(dir.join(script))
        .env("MILLSIM_BIN", env!("CARGO_BIN_EXE_millsim"))
        .env("CHROMIUM", &chromium)
        .output()
        .expect("run node");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}");
    eprintln!("{stderr}");
    assert!(out.status.success(), "{script} failed:\n{stdout}\n{stderr}");
}

/// The list live, the example optimize job's page, a failed job, the form, API keys.
#[test]
fn dashboard_in_chromium() {
    run_script("dashboard.mjs");
}

/// A page of another origin cannot register a webhook, submit a job or upload a program
/// (403, nothing stored); one allowed by `--cors-origin` can.
#[test]
fn a_page_of_another_origin_is_refused_in_chromium() {
    run_script("cross_origin.mjs");
}

/// Names with bidi controls shown with the controls written out (list, job page, form).
#[test]
fn bidi_controls_in_names_are_shown_escaped_in_chromium() {
    run_script("bidi.mjs");
}

/// Every job kind's view, collisions in 3-D, and cancelling from the page.
#[test]
fn every_job_kind_in_chromium() {
    run_script("kinds.mjs");
}

/// A process job: a card per operation and the plots coloured by operation; the same
/// process submitted through the new-job form.
#[test]
fn process_job_in_chromium() {
    run_script("process.mjs");
}

/// A job of 10^5 blocks: first paint, and zooming and panning its plots without a stall
/// (prints the redraw and frame times).
#[test]
fn large_job_zooms_and_pans_in_chromium() {
    run_script("large.mjs");
}

/// What the 3-D view marks, without a browser: a rapid through the stock is listed with the
/// tool tip's path (`from`, `to`) on a 3-axis machine.
#[tokio::test]
async fn collisions_carry_the_tool_tip_path() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    let (_, stock) = post_json(
        &c,
        &s,
        "/v1/stocks",
        &json!({"kind": "block", "min": [0, 0, -10], "max": [60, 40, 0]}),
    )
    .await;
    let (_, tool) = post_json(&c, &s, "/v1/tools", &json!({"type": "flat", "diameter_mm": 8, "flutes": 3, "helix_deg": 35, "flute_length_mm": 20})).await;
    let program =
        "G21 G90\nT1 M6\nS10000 M3\nG0 X-10 Y20 Z10\nG0 Z-3\nG0 X70\nG1 Y30 F500\nG0 Z10\nM30\n";
    let body = json!({"kind": "simulate", "inputs": {"program": {"name": "crash.nc", "content": program},
        "stock": stock["id"], "tool": tool["id"]}, "options": {"material": "Al7075-T6"}});
    let (st, job) = post_json(&c, &s, "/v1/jobs", &body).await;
    assert_eq!(st, 202, "{job}");
    let done = wait_job(&c, &s, job["id"].as_str().unwrap(), Duration::from_secs(60)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    // Only the rapid on line 6 meets material it must not; the G1 after it cuts.
    assert_eq!(
        done["summary"]["collisions"],
        json!([{"block": 5, "line": 6, "kind": "rapid_in_material", "from": [-10.0, 20.0, -3.0], "to": [70.0, 20.0, -3.0]}])
    );
}
