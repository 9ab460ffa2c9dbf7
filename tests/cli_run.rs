//! `millsim run`: the simulate job offline, writing summary.json, blocks.csv, stock.stl.

mod common;

use std::process::Command;

use common::*;

#[test]
fn run_writes_summary_rows_and_final_stock() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("slot.nc");
    std::fs::write(
        &program,
        "G21 G90\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X60 F4000\nG0 Z5\nM30\n",
    )
    .unwrap();
    let tool = dir.path().join("tool.json");
    std::fs::write(
        &tool,
        r#"{"type":"flat","diameter_mm":10,"flutes":4,"helix_deg":0,"flute_length_mm":20,"runout_um":0}"#,
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let out = Command::new(BIN)
        .args([
            "run",
            "--block=0,-20,-10,100,40,10",
            "--material",
            "Al7075-T6",
            "--cell",
            "0.25",
        ])
        .arg("--program")
        .arg(&program)
        .arg("--tool")
        .arg(format!("T1={}", tool.display()))
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("summary.json")).unwrap()).unwrap();
    let analytic = 5.0 * (60.0 * 10.0 + std::f64::consts::PI * 25.0 / 2.0);
    assert!(
        (summary["removed_volume_mm3"].as_f64().unwrap() - analytic).abs() / analytic < 0.005,
        "{summary}"
    );
    assert!(
        summary["cycle_time_s"].as_f64().unwrap() > 60.0 / (4000.0 / 60.0),
        "{summary}"
    );
    for stage in ["interpret_s", "removal_and_engagement_s", "forces_s"] {
        assert!(summary["timings"][stage].as_f64().is_some(), "{summary}");
    }
    let csv = std::fs::read_to_string(out_dir.join("blocks.csv")).unwrap();
    assert_eq!(
        csv.lines().count() as u64,
        1 + summary["moves"].as_u64().unwrap()
    );
    let stl = std::fs::read(out_dir.join("stock.stl")).unwrap();
    assert_eq!(
        stl.len(),
        84 + 50 * u32::from_le_bytes(stl[80..84].try_into().unwrap()) as usize
    );

    // The interface's columns, in the CSV header.
    let header = csv.lines().next().unwrap();
    for col in "block,line,tool,kind,length_mm,feed_mm_min,spindle_rpm,time_s,removed_mm3,mrr_mm3_s,axial_depth_mm,radial_width_mm,entry_deg,exit_deg,chip_max_mm,force_peak_n,force_mean_n,fx_mean_n,fy_mean_n,fz_mean_n,torque_peak_nm,power_peak_w,energy_j,air_fraction,flags".split(',') {
        assert!(header.split(',').any(|h| h == col), "{col} not in {header}");
    }

    // --optimize writes the rewritten program next to the results, named like the input.
    // The material as a file with only the six coefficients (Al7075-T6's), the grid
    // as --resolution.
    let material = dir.path().join("al7075.json");
    std::fs::write(
        &material,
        r#"{"ktc":767.01,"krc":168.8,"kac":222.0,"kte":27.7,"kre":26.6,"kae":0.7}"#,
    )
    .unwrap();
    let out = Command::new(BIN)
        .args([
            "run",
            "--block=0,-20,-10,100,40,10",
            "--material",
            material.to_str().unwrap(),
            "--resolution",
            "0.25",
            "--optimize",
            "max_force=500,air_feed=6000",
        ])
        .arg("--program")
        .arg(&program)
        .arg("--tool")
        .arg(&tool)
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let optimized = std::fs::read_to_string(out_dir.join("slot.opt.nc")).unwrap();
    assert!(
        optimized.contains("G1 X60 F") && !optimized.contains("F4000"),
        "{optimized}"
    );
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("summary.json")).unwrap()).unwrap();
    assert!(
        summary["force_peak_opt_n"].as_f64().unwrap() <= 510.0,
        "{summary}"
    );

    // Bad values name the flag.
    let refuse = |extra: &[&str]| {
        let mut c = Command::new(BIN);
        c.args(["run", "--material", "Al7075-T6", "--out"])
            .arg(&out_dir)
            .arg("--program")
            .arg(&program);
        c.arg("--tool").arg(&tool).args(extra);
        let o = c.output().unwrap();
        assert!(!o.status.success());
        String::from_utf8(o.stderr).unwrap()
    };
    assert!(refuse(&["--block=0,0,0,1,1,1", "--optimize", "max_force"]).contains("NAME=VALUE"));
    assert!(
        refuse(&["--block=0,0,0,1,1,1", "--optimize", "air_feed=3000"])
            .contains("at least one target")
    );
    assert!(refuse(&["--block=0,0,0,1,1"]).contains("six numbers"));
    // A misspelt limit is named by the flag that gave it, without a position in JSON the
    // command wrote itself.
    let misspelt = refuse(&["--block=0,0,0,1,1,1", "--optimize", "max_forse=400"]);
    assert!(
        misspelt.contains("--optimize (options.limits")
            && misspelt.contains("max_forse")
            && !misspelt.contains(" column "),
        "{misspelt}"
    );
    let machine = dir.path().join("machine.json");
    std::fs::write(&machine, r#"{"name":"m","rapid_rate":0,"max_feed":1,"acceleration":[1,1,1],"spindle_min_rpm":0,"spindle_max_rpm":1,"rated_power":1}"#).unwrap();
    assert!(refuse(&[
        "--block=0,0,0,1,1,1",
        "--machine",
        machine.to_str().unwrap()
    ])
    .contains("rapid_rate"));
    assert!(refuse(&["--block=0,0,0,1,1,1", "--cell", "50"]).contains("cell_mm"));
}

#[test]
fn the_readme_example_runs_as_documented() {
    // The example's files as the README runs them, at a coarse grid to keep the test short.
    let root = env!("CARGO_MANIFEST_DIR");
    let ex = |f: &str| format!("{root}/examples/adaptive/{f}");
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(BIN)
        .args([
            "run",
            "--stock",
            &ex("stock.json"),
            "--program",
            &ex("1055_utab_265bit.nc"),
            "--tool",
            &format!("T1={}", ex("tool.json")),
            "--material",
            "Al7075-T6",
            "--machine",
            &ex("machine.json"),
            "--optimize",
            "max_force=400,air_feed=5000,max_feed=5000",
            "--resolution",
            "0.2",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("summary.json")).unwrap()).unwrap();
    assert!(summary["force_peak_opt_n"].as_f64().unwrap() <= 400.0 * 1.02);
    assert!(dir.path().join("1055_utab_265bit.opt.nc").is_file());
    // As the README says: the Ø2.65 tool's guards (about 0.032 mm of chip and 94 N) bind
    // long before the job's 400 N. The program as written already exceeds them on most
    // moves: those keep their programmed feed (a guard never slows a move below it) and are
    // reported as guards not met; no move is sped up past a guard. Faster than written
    // still, where moves were under the guards.
    let t1 = &summary["optimization"]["tools"][0];
    let before = summary["cycle_time_s"].as_f64().unwrap();
    let after = summary["cycle_time_opt_s"].as_f64().unwrap();
    assert!(after < before, "{summary}");
    let not_met: Vec<&str> = t1["limits_not_met"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|l| l["limit"].as_str())
        .collect();
    assert!(
        not_met.contains(&"guard_force") && not_met.contains(&"guard_chip_thickness"),
        "{t1}"
    );
    assert_eq!(t1["tool"], 1, "{summary}");
    let guards = &t1["guards"];
    assert!(guards["max_force"].as_f64().unwrap() < 100.0, "{guards}");
    assert!(
        guards["max_chip_thickness"].as_f64().unwrap() < 0.05,
        "{guards}"
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("T1: guards: chip"), "{err}");

    // With the guards switched off (`tool_guards=false`) the 400 N limit alone sets the
    // feeds, as before the guards: faster than written.
    let off = tempfile::tempdir().unwrap();
    let out = Command::new(BIN)
        .args([
            "run",
            "--stock",
            &ex("stock.json"),
            "--program",
            &ex("1055_utab_265bit.nc"),
            "--tool",
            &format!("T1={}", ex("tool.json")),
            "--material",
            "Al7075-T6",
            "--machine",
            &ex("machine.json"),
            "--optimize",
            "max_force=400,air_feed=5000,max_feed=5000,tool_guards=false",
            "--resolution",
            "0.2",
            "--out",
        ])
        .arg(off.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(off.path().join("summary.json")).unwrap()).unwrap();
    let off_after = summary["cycle_time_opt_s"].as_f64().unwrap();
    assert!(off_after < after, "{summary}");
    assert!(summary["force_peak_opt_n"].as_f64().unwrap() <= 400.0 * 1.02);
    assert!(summary["optimization"]["tools"][0]["guards"].is_null());
}

/// The slot program of these tests with a tool change, so that T numbers matter.
const TWO_TOOLS: &str = "(T1 D=10 CR=0 - flat end mill)\n(T2 D=6 CR=3 - ball end mill)\nG21 G90\nT1 M6\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X60 F4000\nG0 Z5\nT2 M6\nG0 X-10 Y10\nG0 Z-2\nG1 X60 F2000\nG0 Z5\nM30\n";

fn run_two_tools(extra: &[&str]) -> (std::process::Output, Option<serde_json::Value>) {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("two.nc");
    std::fs::write(&program, TWO_TOOLS).unwrap();
    std::fs::write(
        dir.path().join("lib.csv"),
        "number,type,diameter,flutes,flute_length,helix\n1,flat,10,4,20,0\n2,ball,6,2,12,30\n9,flat,0.5,2,2,30\n",
    )
    .unwrap();
    let program = program.to_str().unwrap();
    let args = [
        &["--block=0,-20,-10,100,40,10", "--program", program][..],
        extra,
    ]
    .concat();
    run_in(dir.path(), &args)
}

/// `millsim run --material Al7075-T6` with `args` in `dir`, writing to `dir/out`: its
/// output and the summary it wrote, if any.
fn run_in(
    dir: &std::path::Path,
    args: &[&str],
) -> (std::process::Output, Option<serde_json::Value>) {
    let out_dir = dir.join("out");
    let out = Command::new(BIN)
        .current_dir(dir)
        .args(["run", "--material", "Al7075-T6"])
        .args(args)
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    let summary = std::fs::read(out_dir.join("summary.json"))
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok());
    (out, summary)
}

#[test]
fn run_takes_tools_from_a_library_or_from_the_program_header() {
    // A CSV library: T1 and T2 from it; its T9 (0.5 mm) is not used and does not set the
    // grid (default cell: the smallest used tool's radius / 20 = 0.15 mm).
    let (out, summary) = run_two_tools(&["--tool-library", "lib.csv"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lib = summary.unwrap();
    assert_eq!(lib["cell_mm"], 0.15, "{lib}");
    assert!(lib.get("tool_warnings").is_none(), "{lib}");
    assert!(lib["removed_volume_mm3"].as_f64().unwrap() > 3000.0);

    // No tool at all: both from the header comments, every assumption said.
    let (out, summary) = run_two_tools(&[]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let header = summary.unwrap();
    let warnings = header["tool_warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 2, "{header}");
    assert!(
        warnings[0].as_str().unwrap().starts_with("T1 (line 1)"),
        "{header}"
    );
    // Same cutters (diameters, shapes) as the library's: the same material removed.
    let (a, b) = (
        lib["removed_volume_mm3"].as_f64().unwrap(),
        header["removed_volume_mm3"].as_f64().unwrap(),
    );
    assert!((a - b).abs() < 1e-6 * a, "{a} vs {b}");

    // A program whose T number nothing describes: refused naming the line and the number.
    let (out, _) = run_two_tools(&["--tool-library", "missing.csv"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.csv"));
}

/// A program that calls T3 run with only T1 is refused naming T3 (it ran T1's tool as T3
/// before), and a run ends with its summary on stderr: cycle time, peak force and its
/// line, collisions with their lines.
#[test]
fn run_refuses_a_tool_number_it_was_not_given_and_prints_a_summary() {
    let dir = tempfile::tempdir().unwrap();
    let tool = dir.path().join("tool.json");
    std::fs::write(
        &tool,
        r#"{"type":"flat","diameter_mm":10,"flutes":4,"helix_deg":0,"flute_length_mm":20}"#,
    )
    .unwrap();
    let run = |program: &str| {
        let path = dir.path().join("p.nc");
        std::fs::write(&path, program).unwrap();
        Command::new(BIN)
            .args([
                "run",
                "--block=0,-20,-10,100,40,10",
                "--material",
                "Al7075-T6",
            ])
            .args(["--cell", "0.5", "--program"])
            .arg(&path)
            .arg("--tool")
            .arg(format!("T1={}", tool.display()))
            .arg("--out")
            .arg(dir.path().join("out"))
            .output()
            .unwrap()
    };
    let out = run("G21 G90\nT3 M6\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X60 F4000\nM30\n");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("T3"), "{err}");

    // A rapid into the stock at line 6 and a cut at line 7: both named on stderr.
    let out = run(
        "G21 G90\nT1 M6\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 X10 Z-2\nG1 X60 Z-5 F2000\nG0 Z5\nM30\n",
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("cycle time:"), "{err}");
    assert!(
        err.contains("peak force:") && err.contains("at line 7"),
        "{err}"
    );
    assert!(
        err.contains("COLLISIONS: 1") && err.contains("line 6: rapid_in_material"),
        "{err}"
    );
}

/// Files saved by Windows editors start with a UTF-8 byte-order mark: programs and tool
/// files are read as if it were not there.
#[test]
fn a_byte_order_mark_is_accepted_in_programs_and_tools() {
    let dir = tempfile::tempdir().unwrap();
    let tool = dir.path().join("tool.json");
    std::fs::write(
        &tool,
        "\u{feff}{\"type\":\"flat\",\"diameter_mm\":10,\"flutes\":4,\"flute_length_mm\":20}",
    )
    .unwrap();
    let program = dir.path().join("p.nc");
    std::fs::write(
        &program,
        "\u{feff}G21 G90\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X60 F4000\nM30\n",
    )
    .unwrap();
    let out = Command::new(BIN)
        .args([
            "run",
            "--block=0,-20,-10,100,40,10",
            "--material",
            "Al7075-T6",
        ])
        .args(["--cell", "0.5", "--program"])
        .arg(&program)
        .arg("--tool")
        .arg(&tool)
        .arg("--out")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(
        &std::fs::read(dir.path().join("out").join("summary.json")).unwrap(),
    )
    .unwrap();
    assert!(
        summary["removed_volume_mm3"].as_f64().unwrap() > 2500.0,
        "{summary}"
    );
}

/// `--optimize-tool T1:max_force=300` holds T1 to its own limit (the job's limits.tools), and
/// the plunge of the program is not written faster than programmed.
#[test]
fn run_takes_a_tools_own_limits_and_keeps_plunges_at_their_feed() {
    let dir = tempfile::tempdir().unwrap();
    let tool = dir.path().join("tool.json");
    std::fs::write(
        &tool,
        r#"{"type":"flat","diameter_mm":10,"flutes":4,"flute_length_mm":20}"#,
    )
    .unwrap();
    let program = dir.path().join("p.nc");
    std::fs::write(
        &program,
        "G21 G90\nT1 M6\nS10000 M3\nG0 X50 Y0 Z5\nG0 Z0\nG1 Z-3 F150\nG1 X90 F1000\nG0 Z5\nM30\n",
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let out = Command::new(BIN)
        .args([
            "run",
            "--block=0,-20,-10,100,40,10",
            "--material",
            "Al7075-T6",
        ])
        .args(["--cell", "0.25", "--program"])
        .arg(&program)
        .arg("--tool")
        .arg(format!("T1={}", tool.display()))
        .args([
            "--optimize",
            "max_force=3000,air_feed=5000,max_feed=5000",
            "--optimize-tool",
            "T1:max_force=300",
        ])
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("summary.json")).unwrap()).unwrap();
    let t1 = &summary["optimization"]["tools"][0];
    assert_eq!(t1["tool"], 1, "{summary}");
    assert_eq!(t1["limits"]["max_force"], 300.0, "{summary}");
    let text = std::fs::read_to_string(out_dir.join("p.opt.nc")).unwrap();
    let plunge = text.lines().nth(5).unwrap();
    let f: f64 = plunge.split('F').nth(1).unwrap().trim().parse().unwrap();
    assert!(f <= 150.0, "{plunge}");
    assert!(err.contains("cycle time:"), "{err}");
}

#[test]
fn run_takes_the_program_options_interpret_and_the_jobs_take() {
    // A Fanuc program with implied decimals (X60000 is 60 mm) and a block-delete line that
    // would plunge 50 mm into the block: run as the control runs it with the switch on.
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("o1000.nc");
    std::fs::write(
        &program,
        "O1000\nG21 G90\nS10000 M3\nG0 Z5000\nG0 X-10000 Y0\nG0 Z-5000\n/G1 Z-50000 F100\nG1 X60000 F4000\nG0 Z5000\nM30\n",
    )
    .unwrap();
    let tool = dir.path().join("tool.json");
    std::fs::write(
        &tool,
        r#"{"type":"flat","diameter_mm":10,"flutes":4,"flute_length_mm":20}"#,
    )
    .unwrap();
    let run = |extra: &[&str]| {
        let out_dir = dir.path().join("out");
        let _ = std::fs::remove_dir_all(&out_dir);
        let out = Command::new(BIN)
            .args([
                "run",
                "--block=0,-20,-10,100,40,10",
                "--material",
                "Al7075-T6",
                "--cell",
                "0.25",
            ])
            .args(extra)
            .arg("--program")
            .arg(&program)
            .arg("--tool")
            .arg(format!("T1={}", tool.display()))
            .arg("--out")
            .arg(&out_dir)
            .output()
            .unwrap();
        let summary = std::fs::read(out_dir.join("summary.json"))
            .ok()
            .map(|b| serde_json::from_slice::<serde_json::Value>(&b).unwrap());
        (out, summary)
    };
    let (out, summary) = run(&[
        "--dialect",
        "fanuc",
        "--fanuc-implied-decimal",
        "--block-delete",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary = summary.unwrap();
    let analytic = 5.0 * (60.0 * 10.0 + std::f64::consts::PI * 25.0 / 2.0);
    let removed = summary["removed_volume_mm3"].as_f64().unwrap();
    assert!(
        (removed - analytic).abs() / analytic < 0.005,
        "{removed} vs {analytic}"
    );
    // Without the switch the deleted block runs: 50 mm down through a 10 mm block's floor
    // is refused or flagged, and the removed volume is not the slot's.
    let (_, without) = run(&["--dialect", "fanuc", "--fanuc-implied-decimal"]);
    if let Some(s) = without {
        let r = s["removed_volume_mm3"].as_f64().unwrap();
        assert!((r - analytic).abs() / analytic > 0.01, "{r}");
    }
    // A tool table file that does not read names the file.
    let table = dir.path().join("bad.tbl");
    std::fs::write(&table, "T1 P1 D=oops\n").unwrap();
    let (out, _) = run(&["--tool-table", table.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("tool_table"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `millsim run` in `dir` of `program` (saved as `name`) with one tool, T1 (`tool_json`),
/// the stock and the other options in `args`: its output and the summary it wrote, if any
/// (the results are in `dir/out`).
fn run_with_t1(
    dir: &std::path::Path,
    (name, program): (&str, &[u8]),
    tool_json: &str,
    args: &[&str],
) -> (std::process::Output, Option<serde_json::Value>) {
    let path = dir.join(name);
    std::fs::write(&path, program).unwrap();
    let tool = dir.join("tool.json");
    std::fs::write(&tool, tool_json).unwrap();
    let t1 = format!("T1={}", tool.display());
    let args = [args, &["--program", path.to_str().unwrap(), "--tool", &t1]].concat();
    run_in(dir, &args)
}

#[test]
fn run_takes_a_block_below_zero_and_a_g41_radius_from_its_tool() {
    // A job's checks read the program as the simulation does: `G41 D1` takes the radius of
    // the T1 given on the command line (it was refused as "no radius for tool 1" before the
    // simulation started). And `--block` takes a corner below zero without `=`.
    let dir = tempfile::tempdir().unwrap();
    let (out, summary) = run_with_t1(
        dir.path(),
        (
            "boss.nc",
            b"G21 G17 G90 G40\nT1 M6\nS8000 M3\nG0 X-10 Y-10 Z5\nG1 Z-2 F300\nG41 D1\nG1 X0 Y-5 F600\n\
              G1 Y20\nG1 X20\nG1 Y0\nG1 X0\nG1 Y5\nG40 G1 X-10 Y-10\nG0 Z5\nM30\n",
        ),
        r#"{"type":"flat","diameter_mm":6,"flutes":3,"flute_length_mm":15}"#,
        &["--block", "-12,-12,-4,44,44,4", "--resolution", "0.2"],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary = summary.unwrap();
    // At least the ring one diameter wide around the 20×20 boss, 2 mm deep (its outside
    // corners rounded at the diameter); uncompensated the tool would straddle the outline.
    let ring = (80.0 * 6.0 + std::f64::consts::PI * 36.0) * 2.0;
    let removed = summary["removed_volume_mm3"].as_f64().unwrap();
    assert!(
        removed > ring && removed < ring + 250.0,
        "{removed} vs {ring}"
    );
}

#[test]
fn a_latin1_program_is_read_and_its_optimized_program_keeps_its_bytes() {
    // `(FRÄSER Ø10)` as a Windows editor saves it (ISO 8859-1): read byte for character,
    // and written back the same way, so every byte the feeds do not change is kept.
    let dir = tempfile::tempdir().unwrap();
    let text: &[u8] = b"(FR\xc4SER \xd810)\nG21 G90\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X60 F4000\nG0 Z5\nM30\n";
    let (out, _) = run_with_t1(
        dir.path(),
        ("slot.nc", text),
        r#"{"type":"flat","diameter_mm":10,"flutes":4,"flute_length_mm":20}"#,
        &[
            "--block",
            "0,-20,-10,100,40,10",
            "--resolution",
            "0.5",
            "--optimize",
            "max_force=300",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out_dir = dir.path().join("out");
    let written = std::fs::read(out_dir.join("slot.opt.nc")).unwrap_or_else(|e| {
        panic!(
            "{e}: {:?}",
            std::fs::read_dir(&out_dir).unwrap().collect::<Vec<_>>()
        )
    });
    assert!(written.starts_with(b"(FR\xc4SER \xd810)\n"), "{written:?}");
    // The feed changed (the limit binds), nothing else did.
    assert_ne!(written, text);
    let unchanged: Vec<&[u8]> = text
        .split(|&b| b == b'\n')
        .filter(|l| !l.contains(&b'F'))
        .collect();
    for line in unchanged {
        assert!(
            written.split(|&b| b == b'\n').any(|l| l == line),
            "{line:?} lost"
        );
    }
}

#[test]
fn an_open_stl_stock_is_refused_naming_its_file_and_where_it_is_open() {
    let dir = tempfile::tempdir().unwrap();
    // A closed box as the engine exports it, less its last triangle (50 bytes each after
    // the 80-byte header and the count): three edges left open.
    let mut stl = exported_box_stl([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
    let count = u32::from_le_bytes(stl[80..84].try_into().unwrap());
    stl[80..84].copy_from_slice(&(count - 1).to_le_bytes());
    stl.truncate(stl.len() - 50);
    let stock = dir.path().join("open_part.stl");
    std::fs::write(&stock, stl).unwrap();
    let (out, _) = run_with_t1(
        dir.path(),
        (
            "p.nc",
            b"G21 G90\nS8000 M3\nG0 X0 Y0 Z5\nG1 Z-1 F100\nM30\n",
        ),
        r#"{"type":"flat","diameter_mm":6,"flutes":3}"#,
        &["--stock", stock.to_str().unwrap()],
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("open_part.stl: mesh is not closed: 3 edges") && err.contains("near"),
        "{err}"
    );
    assert!(!err.contains("p.nc:"), "{err}");
}

#[test]
fn an_stl_stock_with_a_triangle_wound_the_wrong_way_runs_and_says_it_was_turned() {
    let dir = tempfile::tempdir().unwrap();
    // The exported box with its first triangle's last two corners swapped: its normal
    // points in, as some exporters write a few.
    let mut stl = exported_box_stl([0.0, 0.0, -10.0], [20.0, 20.0, 0.0]);
    let at = 84 + 12 + 12;
    let second = stl[at..at + 12].to_vec();
    stl.copy_within(at + 12..at + 24, at);
    stl[at + 12..at + 24].copy_from_slice(&second);
    let stock = dir.path().join("turned.stl");
    std::fs::write(&stock, stl).unwrap();
    let (out, summary) = run_with_t1(
        dir.path(),
        (
            "p.nc",
            b"G21 G90\nS8000 M3\nG0 X-5 Y10 Z5\nG1 Z-1 F100\nG1 X25 F500\nG0 Z5\nM30\n",
        ),
        r#"{"type":"flat","diameter_mm":6,"flutes":3,"flute_length_mm":15}"#,
        &["--stock", stock.to_str().unwrap()],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("warning: stock STL: 1 triangles were wound against their neighbours"),
        "{err}"
    );
    // The slot through the 20 mm box, 6 mm wide and 1 mm deep: 120 mm³.
    let removed = summary.unwrap()["removed_volume_mm3"].as_f64().unwrap();
    assert!((removed - 120.0).abs() < 2.0, "{removed}");
}
