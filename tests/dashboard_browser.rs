//! The dashboard in a real browser: runs the scripts of tests/browser (playwright-core
//! driving Debian's /usr/bin/chromium, never a downloaded browser) against this build's
//! `millsim`. Each skips, saying why, when node, playwright-core (`npm ci` in tests/browser)
//! or chromium is absent; `.ci/run` installs all three, so CI runs them.

use std::path::Path;
use std::process::Command;
use std::sync::Mutex;

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
        println!("skipped: node is not installed");
        return;
    }
    if !dir.join("node_modules/playwright-core").is_dir() {
        println!(
            "skipped: playwright-core is not installed (run `npm ci` in {})",
            dir.display()
        );
        return;
    }
    if !Path::new(&chromium).exists() {
        println!("skipped: {chromium} is absent (apt-get install chromium)");
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
    assert!(
        out.status.success(),
        "{script} failed:\n{stdout}\n{stderr}"
    );
}

/// The list live, the example optimize job's page, a failed job, the form, API keys.
#[test]
fn dashboard_in_chromium() {
    run_script("dashboard.mjs");
}

/// Every job kind's view, collisions in 3-D, and cancelling from the page.
#[test]
fn every_job_kind_in_chromium() {
    run_script("kinds.mjs");
}

/// A job of 10^5 blocks: first paint, and zooming and panning its plots without a stall
/// (prints the redraw and frame times).
#[test]
fn large_job_zooms_and_pans_in_chromium() {
    run_script("large.mjs");
}
