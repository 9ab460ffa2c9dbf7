//! The dashboard in a real browser: runs tests/browser/dashboard.mjs (playwright-core driving
//! Debian's /usr/bin/chromium, never a downloaded browser) against this build's `millsim`.
//! It skips, saying why, when node, playwright-core (`npm ci` in tests/browser) or chromium
//! is absent; `.ci/run` installs all three, so CI runs it.

use std::path::Path;
use std::process::Command;

#[test]
fn dashboard_in_chromium() {
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
        .arg(dir.join("dashboard.mjs"))
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
        "the browser test failed:\n{stdout}\n{stderr}"
    );
}
