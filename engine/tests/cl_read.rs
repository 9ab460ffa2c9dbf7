//! APT/CLS reader.

use millsim_engine::cl::read_cls;
use millsim_engine::nc::{FeedMode, MoveKind, SpindleDir};

const CLS: &str = "TOOL PATH/ROUGH,TOOL,D10R1
TLDATA/MILL,10.0000,1.0000,75.0000,0.0000,0.0000
MSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000
$$ centerline data
PAINT/PATH
LOADTL/3
CUTTER/10.0000,1.0000
SPINDL/RPM,3000.0000,CLW
RAPID
GOTO/0.0000,0.0000,50.0000,0.0000000,0.0000000,1.0000000
FEDRAT/MMPM,500.0000
GOTO/10.0000,0.0000,5.0000
CIRCLE/0.0000,0.0000,5.0000,0.0000000,0.0000000,1.0000000,10.0000,0.0600,0.5000,10.0000,0.0000
GOTO/0.0000,10.0000,5.0000
CIRCLE/0.0000,0.0000,5.0000,0.0000000,0.0000000,-1.0000000,10.0000
GOTO/10.0000,0.0000,5.0000
MULTAX/ON
GOTO/20.0000,0.0000,5.0000,0.0000000,0.7071068,$
0.7071068 $$ continued
FEDRAT/IPM,10
TLAXIS/0,0,1
GOTO/30,0,5
DELAY/2
SPINDL/OFF
END-OF-PATH
";

#[test]
fn reads_moves_in_part_frame_with_tool_axes() {
    let i = read_cls(CLS).unwrap();
    let k: Vec<MoveKind> = i.moves.iter().map(|m| m.kind).collect();
    use MoveKind::*;
    assert_eq!(
        k,
        vec![ToolChange, Rapid, Linear, Arc, Arc, Linear, Linear, Dwell]
    );
    let m = &i.moves;
    assert_eq!(m[0].tool, 3);
    assert_eq!(
        (m[1].end, m[1].tool_axis),
        ([0.0, 0.0, 50.0, 0.0, 0.0, 0.0], Some([0.0, 0.0, 1.0]))
    );
    assert_eq!((m[1].spindle, m[1].spindle_dir), (3000.0, SpindleDir::Cw));
    assert_eq!(
        (m[2].feed, m[2].feed_mode, m[2].line),
        (500.0, FeedMode::PerMin, 12)
    );
    // CIRCLE with axis +Z: counterclockwise quarter.
    assert_eq!(m[3].center, Some([0.0, 0.0, 5.0]));
    assert_eq!(m[3].clockwise, Some(false));
    assert!((m[3].arc.as_ref().unwrap().sweep - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    assert_eq!(m[3].end, [0.0, 10.0, 5.0, 0.0, 0.0, 0.0]);
    // Axis -Z: clockwise back.
    assert_eq!(m[4].clockwise, Some(true));
    assert!((m[4].arc.as_ref().unwrap().sweep + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    // `$` continuation: the 5-axis GOTO spans two lines and reports the first.
    let a = m[5].tool_axis.unwrap();
    assert!((a[1] - 0.5f64.sqrt()).abs() < 1e-6 && (a[2] - 0.5f64.sqrt()).abs() < 1e-6);
    assert_eq!(m[5].line, 18);
    assert!((m[6].feed - 254.0).abs() < 1e-9);
    assert_eq!(m[6].tool_axis, Some([0.0, 0.0, 1.0]));
    assert_eq!(m[7].seconds, Some(2.0));
    // JSON rows carry the tool axis.
    let row = serde_json::to_string(&m[5]).unwrap();
    assert!(row.contains("\"tool_axis\":[0.0,0.7071067"), "{row}");
}

#[test]
fn inch_units() {
    let i = read_cls("UNITS/INCHES\nFEDRAT/10\nGOTO/1,2,3\n").unwrap();
    assert_eq!(
        i.moves[0].end,
        [25.4, 50.8, 76.19999999999999, 0.0, 0.0, 0.0]
    );
}

#[test]
fn errors_name_each_bad_record() {
    let e = read_cls("GOTO/1,2,3\nFOO/1\nFEDRAT/100\nGOTO/1,2\nCIRCLE/0,0,0,1,1,0,5\nGOTO/1,x,3\n")
        .unwrap_err();
    let got: Vec<(u32, String)> = e.0.iter().map(|d| (d.line, d.message.clone())).collect();
    assert_eq!(got.len(), 5, "{e}");
    assert!(got[0].1.contains("before any FEDRAT"));
    assert!(got[1].1.contains("unsupported CLS record FOO"));
    assert_eq!(got[2].0, 4);
    assert_eq!(got[3].0, 6, "{e}");
    assert!(got[4].1.contains("CIRCLE is not followed by a GOTO"), "{e}");
}
