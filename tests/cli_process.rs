//! `millsim process process.json --out DIR`: the process job offline, from the service's
//! request with file paths relative to the document.

mod common;

use std::path::Path;
use std::process::Command;

use common::*;
use serde_json::{json, Value};

/// Ø10 slot 3 deep along x at y 0, then Ø6 at y 3, 5 deep, in what the slot left.
fn write_inputs(dir: &Path) {
    let w = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    w(
        "stock.json",
        r#"{"kind":"block","min":[0,-20,-10],"max":[100,20,0]}"#,
    );
    w(
        "rough.nc",
        "G90 G21\nS8000 M3\nG0 X-10 Y0 Z5\nG1 Z-3 F500\nG1 X110 F800\nG0 Z5\nM30\n",
    );
    w(
        "finish.nc",
        "G90 G21\nS8000 M3\nG0 X-10 Y3 Z5\nG1 Z-5 F400\nG1 X110 F600\nG0 Z5\nM30\n",
    );
    std::fs::create_dir_all(dir.join("tools")).unwrap();
    w(
        "tools/d10.json",
        r#"{"type":"flat","diameter_mm":10,"flutes":3,"helix_deg":30,"flute_length_mm":20}"#,
    );
    w(
        "tools/d6.json",
        r#"{"type":"flat","diameter_mm":6,"flutes":2,"helix_deg":30,"flute_length_mm":20}"#,
    );
}

fn process(dir: &Path, doc: &Value, out: &Path) -> std::process::Output {
    let path = dir.join("process.json");
    std::fs::write(&path, doc.to_string()).unwrap();
    Command::new(BIN)
        .arg("process")
        .arg(&path)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn process_writes_every_operations_results_and_the_stocks() {
    let dir = tempfile::tempdir().unwrap();
    write_inputs(dir.path());
    let doc = json!({"kind": "process",
        "inputs": {"stock": "stock.json", "operations": [
            {"name": "rough", "program": "rough.nc", "T1": "tools/d10.json", "options": {"limits": {"max_force": 400}}},
            {"name": "finish", "program": "finish.nc", "tool": "tools/d6.json"}]},
        "options": {"material": "Al7075-T6", "cell_mm": 0.5, "keep_stocks": true}});
    let out_dir = dir.path().join("out");
    let out = process(dir.path(), &doc, &out_dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("operation 1 (rough)") && stderr.contains("operation 2 (finish)"),
        "{stderr}"
    );
    let summary: Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("summary.json")).unwrap()).unwrap();
    let ops = summary["operations"].as_array().unwrap();
    assert_eq!(ops.len(), 2);
    let removed = |o: &Value| o["removed_volume_mm3"].as_f64().unwrap();
    assert!((removed(&ops[0]) - 3000.0).abs() < 30.0, "{}", ops[0]);
    assert!((removed(&ops[1]) - 1500.0).abs() < 15.0, "{}", ops[1]);
    assert_eq!(ops[1]["stock_volume_before"], ops[0]["stock_volume_after"]);
    let csv = std::fs::read_to_string(out_dir.join("blocks.csv")).unwrap();
    assert!(csv.starts_with("operation,operation_name,"), "{csv}");
    assert_eq!(
        csv.lines().count() as u64,
        1 + summary["moves"].as_u64().unwrap()
    );
    assert!(csv.lines().any(|l| l.starts_with("2,finish,")));
    // Each operation's program under its own name: the rough's optimized, the finish as given.
    let rough = std::fs::read_to_string(out_dir.join("rough.op1.opt.nc")).unwrap();
    assert_ne!(
        rough,
        std::fs::read_to_string(dir.path().join("rough.nc")).unwrap()
    );
    assert_eq!(
        std::fs::read_to_string(out_dir.join("finish.op2.nc")).unwrap(),
        std::fs::read_to_string(dir.path().join("finish.nc")).unwrap()
    );
    for stl in ["stock.stl", "stock.op1.stl"] {
        let bytes = std::fs::read(out_dir.join(stl)).unwrap();
        let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize;
        assert_eq!(bytes.len(), 84 + 50 * n, "{stl}");
    }
    assert_ne!(
        std::fs::read(out_dir.join("stock.stl")).unwrap(),
        std::fs::read(out_dir.join("stock.op1.stl")).unwrap()
    );
}

#[test]
fn a_bad_document_names_the_field_and_the_file() {
    let dir = tempfile::tempdir().unwrap();
    write_inputs(dir.path());
    let out_dir = dir.path().join("out");
    let no_program = json!({"inputs": {"stock": "stock.json", "operations": [
        {"program": "rough.nc", "tool": "tools/d10.json"}, {"tool": "tools/d6.json"}]},
        "options": {"material": "Al7075-T6"}});
    let out = process(dir.path(), &no_program, &out_dir);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("process.json: inputs.operations[1].program"),
        "{stderr}"
    );
    let missing = json!({"inputs": {"stock": "stock.json", "operations": [
        {"program": "rough.nc", "tool": "tools/d10.json"}, {"program": "nope.nc", "tool": "tools/d6.json"}]},
        "options": {"material": "Al7075-T6"}});
    let out = process(dir.path(), &missing, &out_dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("inputs.operations[1].program") && stderr.contains("nope.nc"),
        "{stderr}"
    );
}

/// `millsim process` takes the program options `interpret` and `run` take: `--block-delete`
/// skips the rough program's `/` line (its row is gone), and an option the document
/// contradicts is refused naming both.
#[test]
fn program_options_reach_the_process() {
    let dir = tempfile::tempdir().unwrap();
    write_inputs(dir.path());
    std::fs::write(
        dir.path().join("rough.nc"),
        "G90 G21\nS8000 M3\nG0 X-10 Y0 Z5\nG1 Z-3 F500\n/G1 X20 F800\nG1 X110 F800\nG0 Z5\nM30\n",
    )
    .unwrap();
    let doc = json!({"kind": "process",
        "inputs": {"stock": "stock.json", "operations": [
            {"name": "rough", "program": "rough.nc", "tool": "tools/d10.json"}]},
        "options": {"material": "Al7075-T6", "cell_mm": 1.0}});
    let lines = |with: &[&str]| -> Vec<String> {
        let out_dir = dir.path().join(format!("out{}", with.len()));
        let path = dir.path().join("process.json");
        std::fs::write(&path, doc.to_string()).unwrap();
        let out = Command::new(BIN)
            .arg("process")
            .arg(&path)
            .arg("--out")
            .arg(&out_dir)
            .args(with)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let csv = std::fs::read_to_string(out_dir.join("blocks.csv")).unwrap();
        let mut rows = csv.lines();
        let header: Vec<&str> = rows.next().unwrap().split(',').collect();
        let at = header
            .iter()
            .position(|h| *h == "line")
            .expect("a line column");
        rows.map(|r| r.split(',').nth(at).unwrap().to_string())
            .collect()
    };
    assert!(lines(&[]).contains(&"5".to_string()));
    assert!(!lines(&["--block-delete"]).contains(&"5".to_string()));
    let contradicted = json!({"kind": "process",
        "inputs": {"stock": "stock.json", "operations": [
            {"program": "rough.nc", "tool": "tools/d10.json"}]},
        "options": {"material": "Al7075-T6", "dialect": "linuxcnc"}});
    let path = dir.path().join("process.json");
    std::fs::write(&path, contradicted.to_string()).unwrap();
    let out = Command::new(BIN)
        .arg("process")
        .arg(&path)
        .arg("--out")
        .arg(dir.path().join("out9"))
        .args(["--dialect", "fanuc"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("options.dialect is \"linuxcnc\"") && stderr.contains("\"fanuc\""),
        "{stderr}"
    );
}
