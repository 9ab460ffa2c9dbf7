//! `millsim interpret FILE`: one JSON object per move on stdout, printed as the moves are
//! made; errors as FILE:LINE:COL: message on stderr with a non-zero exit.

mod common;

use std::process::Command;

use common::*;

#[test]
fn prints_one_json_object_per_move_in_the_documented_shape() {
    if !corpus_present() {
        return;
    }
    let file = corpus("gcode/fusion360_2d_pocket_contour_bore_1099.nc");
    let moves = interpret_moves(&file, &[]);
    assert!(moves.len() > 1000);
    for m in &moves {
        for key in [
            "block",
            "line",
            "kind",
            "end",
            "feed",
            "feed_mode",
            "spindle",
            "tool",
        ] {
            assert!(m.get(key).is_some(), "{key} missing in {m}");
        }
        assert_eq!(m["end"].as_array().unwrap().len(), 6);
        assert!(["rapid", "linear", "arc", "dwell", "tool_change"]
            .contains(&m["kind"].as_str().unwrap()));
        assert!(["per_min", "inverse_time", "per_rev"].contains(&m["feed_mode"].as_str().unwrap()));
        if m["kind"] == "arc" {
            assert_eq!(m["center"].as_array().unwrap().len(), 3);
            assert_eq!(m["normal"].as_array().unwrap().len(), 3);
            assert!(m["clockwise"].is_boolean());
        }
    }
    // The block index is the 0-based source line of the block.
    assert!(moves
        .iter()
        .all(|m| m["block"].as_u64().unwrap() + 1 == m["line"].as_u64().unwrap()));
}

#[test]
fn errors_name_file_line_and_column_and_exit_non_zero() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.nc");
    std::fs::write(&file, "G21 G90\nG0 X0 Y0\nG1 X10 Y[2+ F100\nG1 Q5 X1\n").unwrap();
    let out = Command::new(BIN)
        .arg("interpret")
        .arg(&file)
        .output()
        .unwrap();
    assert!(!out.status.success());
    // Moves are printed as they are made (a window of lines at a time): only moves of lines
    // before the error, each a whole JSON object (here none: the error is in the first window).
    let printed: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(
        printed.iter().all(|m| m["line"].as_u64().unwrap() < 3),
        "{printed:?}"
    );
    let err = String::from_utf8(out.stderr).unwrap();
    let first = err.lines().next().unwrap();
    let prefix = format!("{}:3:", file.display());
    assert!(first.starts_with(&prefix), "{err}");
    let col: u32 = first[prefix.len()..]
        .split(':')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(col >= 1);
    let missing = Command::new(BIN)
        .args(["interpret", "/nonexistent/x.nc"])
        .output()
        .unwrap();
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).starts_with("/nonexistent/x.nc:"));
}

#[test]
fn reads_apt_cls_files_too() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("op.cls");
    std::fs::write(
        &file,
        "TLAXIS/0,0,1\nRAPID\nGOTO/0,0,10\nFEDRAT/MMPM,500\nGOTO/0,0,0\nGOTO/10,0,0,0,0,1\n",
    )
    .unwrap();
    let moves = interpret_moves(&file, &[]);
    let last = moves.last().unwrap();
    assert_eq!(last["end"][0], 10.0);
    assert_eq!(last["feed"], 500.0);
    assert_eq!(last["kind"], "linear");
}

#[test]
fn interpreter_options_reach_the_cli() {
    if !corpus_present() {
        return;
    }
    let impeller = corpus("gcode/linuxcnc_5axis_impeller_7bl_xyzac_g93.ngc");
    // A non-standard M code is run as a no-op with a warning naming it (the engine's
    // strict_m_codes refuses it); --passthrough-m silences the warning.
    let warned = Command::new(BIN)
        .arg("interpret")
        .arg(&impeller)
        .output()
        .unwrap();
    assert!(warned.status.success());
    let stderr = String::from_utf8_lossy(&warned.stderr);
    assert!(
        stderr.contains("M428") && stderr.contains("(warning)"),
        "{stderr}"
    );
    let out = Command::new(BIN)
        .arg("interpret")
        .arg(&impeller)
        .args(["--passthrough-m", "428,429"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let moves = String::from_utf8(out.stdout).unwrap();
    assert!(moves.lines().count() > 4000);
    assert!(moves.lines().any(|l| l.contains("\"inverse_time\"")));
    let fanuc = corpus("gcode/fanuc_R_arcs_G3R_G1R_G1C.nc");
    let out = Command::new(BIN)
        .arg("interpret")
        .arg(&fanuc)
        .args(["--dialect", "fanuc", "--fanuc-corners-without-comma"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn post_writes_one_program_per_operation_that_re_interprets_to_the_cls_points() {
    let dir = tempfile::tempdir().unwrap();
    let cls = dir.path().join("part.cls");
    std::fs::write(
        &cls,
        "LOADTL/1\nTLAXIS/0,0,1\nRAPID\nGOTO/0,0,10\nFEDRAT/MMPM,800\nGOTO/0,0,-1\nGOTO/20.5,0,-1\nGOTO/20.5,7.25,-1\nLOADTL/2\nRAPID\nGOTO/5,5,10\nFEDRAT/MMPM,300\nGOTO/5,5,-2.125\n",
    )
    .unwrap();
    let machine = dir.path().join("m.json");
    std::fs::write(&machine, r#"{"name":"3-axis","rapid_rate":20000,"max_feed":10000,"acceleration":[1000,1000,1000],"spindle_min_rpm":0,"spindle_max_rpm":12000,"rated_power":10000}"#).unwrap();
    let out_dir = dir.path().join("out");
    let out = Command::new(BIN)
        .arg("post")
        .arg(&cls)
        .arg("--machine")
        .arg(&machine)
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let expected: [&[[f64; 3]]; 2] = [
        &[
            [0.0, 0.0, 10.0],
            [0.0, 0.0, -1.0],
            [20.5, 0.0, -1.0],
            [20.5, 7.25, -1.0],
        ],
        &[[5.0, 5.0, 10.0], [5.0, 5.0, -2.125]],
    ];
    for (op, points) in expected.iter().enumerate() {
        let nc = out_dir.join(format!("part.op{}.nc", op + 1));
        let ends: Vec<[f64; 3]> = interpret_moves(&nc, &[])
            .into_iter()
            .filter(|m| m["kind"] == "rapid" || m["kind"] == "linear")
            .map(|m| {
                [
                    m["end"][0].as_f64().unwrap(),
                    m["end"][1].as_f64().unwrap(),
                    m["end"][2].as_f64().unwrap(),
                ]
            })
            .collect();
        let tail = &ends[ends.len() - points.len()..];
        for (a, b) in tail.iter().zip(points.iter()) {
            assert!(
                (0..3).all(|i| (a[i] - b[i]).abs() < 1e-6),
                "op {}: {a:?} vs {b:?}",
                op + 1
            );
        }
    }
    assert!(!out_dir.join("part.op3.nc").exists());
}

/// `--library DIR`: `M98 P1000` runs `DIR/O1000.nc`; its moves are on the call's line with
/// their own file and line; without the folder the call is an error naming the program.
#[test]
fn library_folder_runs_called_programs() {
    let dir = std::env::temp_dir().join(format!("millsim-cli-lib-{}", std::process::id()));
    let lib = dir.join("lib");
    std::fs::create_dir_all(&lib).unwrap();
    std::fs::write(
        lib.join("O1000.nc"),
        "%\nO1000\nG91 G1 X10 F500\nY10\nG90\nM99\n%\n",
    )
    .unwrap();
    // Not a program: left out of the library.
    std::fs::write(lib.join("part.stl"), [0u8, 159, 146, 150]).unwrap();
    let main = dir.join("main.nc");
    std::fs::write(&main, "O0001\nG0 X0 Y0 Z1\nM98 P1000 L2\nM30\n").unwrap();
    let moves = interpret_moves(&main, &["--library", lib.to_str().unwrap()]);
    let ends: Vec<(f64, f64)> = moves
        .iter()
        .map(|m| (m["end"][0].as_f64().unwrap(), m["end"][1].as_f64().unwrap()))
        .collect();
    assert_eq!(
        ends,
        [
            (0.0, 0.0),
            (10.0, 0.0),
            (10.0, 10.0),
            (20.0, 10.0),
            (20.0, 20.0)
        ]
    );
    assert!(moves[0].get("source_file").is_none());
    for (m, line) in moves[1..].iter().zip([3, 4, 3, 4]) {
        assert_eq!(m["line"], 3);
        assert_eq!(m["source_file"], 0);
        assert_eq!(m["source_line"], line);
    }
    let out = Command::new(BIN)
        .arg("interpret")
        .arg(&main)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(
            "main.nc:3:1: M98 P1000: program O1000 is not in this file nor in its program library"
        ),
        "{stderr}"
    );
}

/// `--tool T1=tool.json`: cutter compensation G41 D1 takes tool 1's radius when the program
/// has no tool table; without it the program is refused naming the tool.
#[test]
fn tool_option_gives_the_compensation_radius() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("comp.nc");
    std::fs::write(
        &file,
        "G21 G90 G17 G40\nG0 X0 Y-20 Z0\nG41 D1 G1 Y0 F100\nG1 X50\nG40 G0 Z10\nM2\n",
    )
    .unwrap();
    let tool = dir.path().join("d10.json");
    std::fs::write(
        &tool,
        r#"{"name":"10 mm flat","type":"flat","diameter_mm":10,"flutes":3,"helix_deg":30,"flute_length_mm":20,"stickout_mm":30}"#,
    )
    .unwrap();
    let moves = interpret_moves(&file, &["--tool", &format!("T1={}", tool.display())]);
    let ends: Vec<(String, f64, f64)> = moves
        .iter()
        .map(|m| {
            let e = m["end"].as_array().unwrap();
            let r = |v: &serde_json::Value| (v.as_f64().unwrap() * 1e6).round() / 1e6 + 0.0;
            (m["kind"].as_str().unwrap().to_string(), r(&e[0]), r(&e[1]))
        })
        .collect();
    // Entry along +Y ends 5 mm left of (0, 0); the outside corner to +X is an arc to (0, 5);
    // the X50 line runs 5 mm to its left.
    let want = [
        ("rapid", 0.0, -20.0),
        ("linear", -5.0, 0.0),
        ("arc", 0.0, 5.0),
        ("linear", 50.0, 5.0),
    ];
    for (k, (kind, x, y)) in want.iter().enumerate() {
        assert_eq!(ends[k], (kind.to_string(), *x, *y), "{ends:?}");
    }
    let out = Command::new(BIN)
        .arg("interpret")
        .arg(&file)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no radius for tool 1"), "{err}");
    let out = Command::new(BIN)
        .arg("interpret")
        .arg(&file)
        .args(["--tool", "X1=d10.json"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a tool number like T1"));
}
