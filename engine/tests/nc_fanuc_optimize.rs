//! The feed rewrite on Fanuc macro and subprogram programs: only F words change, and a block
//! executed several times (WHILE loop, M98 repeats, a subprogram called from two places)
//! gets one F that is safe for every execution.

use std::borrow::Cow;
use std::f64::consts::PI;

use millsim_engine::engagement::{EngagedSlice, Engagement};
use millsim_engine::nc::{interpret, InterpretOptions, Move, Program};
use millsim_engine::optimize::{
    optimize_feeds, rewrite_program, verify_rewrite, Cutter, EngagementStep, FeedLimits, FeedScale,
    MoveEngagement, RewriteOptions,
};
use millsim_engine::physics::{CuttingConditions, ForceModel, Material};
use millsim_engine::tool::Tool;

const RPM: f64 = 8000.0;
const MAX_FORCE: f64 = 500.0;

fn tool() -> Tool {
    Tool::flat(10.0, 4)
}

fn cutter() -> Cutter {
    let k = Material::builtin("Al7075-T6").unwrap().coefficients;
    Cutter::new(&tool(), k, 150, 360).unwrap()
}

/// Flat end mill 5 mm deep, engaged on [φst, φex].
fn engagement(phi_st: f64, phi_ex: f64) -> Engagement {
    Engagement {
        slices: (0..25)
            .map(|i| EngagedSlice {
                z: 0.1 + 0.2 * i as f64,
                dz: 0.2,
                arcs: vec![(phi_st, phi_ex)].into(),
            })
            .collect(),
        feed_dir: [1.0, 0.0, 0.0],
        tool_axis: [0.0, 0.0, 1.0],
        end: Vec::new(),
    }
}

fn slot() -> Engagement {
    engagement(0.0, PI)
}
fn half() -> Engagement {
    engagement(PI / 2.0, PI)
}
fn tenth() -> Engagement {
    engagement(PI - (1.0f64 - 0.2).acos(), PI)
}

fn seg(move_index: usize, e: Engagement) -> MoveEngagement<'static> {
    MoveEngagement {
        removes_material: false,
        plunge: false,
        move_index,
        cutter: 0,
        scale: FeedScale::UNIT,
        steps: vec![EngagementStep {
            engagement: Cow::Owned(e.into()),
            spindle_rpm: RPM,
            tip_ratio: 1.0,
            at: 0.0,
            response: None,
        }],
    }
}

fn moves(src: &str) -> Vec<Move> {
    interpret(src, &InterpretOptions::default())
        .unwrap_or_else(|e| panic!("{e}"))
        .moves
}

fn peak_force(e: &Engagement, feed: f64) -> f64 {
    let k = Material::builtin("Al7075-T6").unwrap().coefficients;
    let mut m = ForceModel::new(&tool(), 150, 360).unwrap();
    m.evaluate(
        e,
        &k,
        &CuttingConditions {
            spindle_rpm: RPM,
            feed_per_tooth: feed / (4.0 * RPM),
        },
    )
    .unwrap()
    .force
    .peak
}

/// Lines of `a` and `b` equal once F words (and the blank before each) are removed.
fn same_but_f_words(a: &str, b: &str) {
    let strip = |s: &str| -> Vec<String> {
        s.lines()
            .map(|l| {
                let mut out = String::new();
                let mut chars = l.chars().peekable();
                while let Some(c) = chars.next() {
                    if c == 'F' {
                        while chars
                            .peek()
                            .is_some_and(|c| c.is_ascii_digit() || *c == '.')
                        {
                            chars.next();
                        }
                        while out.ends_with(' ') {
                            out.pop();
                        }
                    } else {
                        out.push(c);
                    }
                }
                out
            })
            .collect()
    };
    assert_eq!(strip(a), strip(b), "{a}\n---\n{b}");
}

/// Optimize with the engagement each move's (line, execution) gets, rewrite, re-interpret:
/// the geometry is the same, and every execution of every block is under the force limit.
fn check(src: &str, engagement_of: impl Fn(u32, usize) -> Option<Engagement>) -> String {
    let mv = moves(src);
    let mut seen = std::collections::HashMap::new();
    let mut engaged = Vec::new();
    for (i, m) in mv.iter().enumerate() {
        let k = seen.entry(m.line).or_insert(0usize);
        if let Some(e) = engagement_of(m.line, *k) {
            engaged.push((i, e));
        }
        *k += 1;
    }
    let segs: Vec<MoveEngagement> = engaged.iter().map(|(i, e)| seg(*i, e.clone())).collect();
    let limits = FeedLimits {
        max_force: Some(MAX_FORCE),
        max_feed: 50_000.0,
        ..Default::default()
    };
    let sched = optimize_feeds(&mv, &segs, &[cutter()], &limits).unwrap();
    let program = Program::parse(src).unwrap();
    let rw = rewrite_program(&program, &mv, &sched, &RewriteOptions::default()).unwrap();
    same_but_f_words(src, &rw.text);
    let mv2 = moves(&rw.text);
    verify_rewrite(&mv, &mv2, &rw).unwrap();
    for (i, e) in &engaged {
        let f = peak_force(e, mv2[*i].feed);
        assert!(
            f <= MAX_FORCE * 1.0001,
            "line {} execution: {f} N at F{}\n{}",
            mv2[*i].line,
            mv2[*i].feed,
            rw.text
        );
    }
    rw.text
}

#[test]
fn a_block_in_a_while_loop_gets_one_safe_feed() {
    // Line 6 runs three times: light, slot, half. One F for all: the slot's.
    let src = "O1\nG21 G90 G94\nG0 X0 Y0 Z0\n#1=0\nWHILE [#1 LT 3] DO1\nG1 X[#1*10+10] F1000\n#1=#1+1\nEND1\nG1 Y20\nM30\n";
    let text = check(src, |line, k| match (line, k) {
        (6, 0) => Some(tenth()),
        (6, 1) => Some(slot()),
        (6, 2) => Some(half()),
        (9, _) => Some(tenth()),
        _ => None,
    });
    assert!(!text.contains("F1000\n#1"), "{text}");
}

#[test]
fn subprogram_blocks_called_several_times_get_one_safe_feed() {
    // O100's G1 runs twice from M98 L2 and once more from a second call, after F-only lines
    // that set different modal feeds: the block after it (no data) keeps what each call had.
    let src = "\
O1
G21 G90 G94
G0 X0 Y0 Z0
F400
M98 P100 L2
F900
M98 P100
M30
O100
G91 G1 X10.
G1 Y1.
G90
M99
";
    check(src, |line, k| match (line, k) {
        (10, 0) => Some(tenth()),
        (10, 1) => Some(slot()),
        (10, 2) => Some(half()),
        _ => None,
    });
    // GOTO loops count as jumps too: the F-only line inside the loop runs before each pass.
    let src = "\
O2
G21 G90 G94
G0 X0 Y0 Z0
#1=0
N10 F300
G91 G1 X5.
G1 Y1.
G90
#1=#1+1
IF [#1 LT 3] GOTO 10
M30
";
    check(src, |line, k| match (line, k) {
        (6, 0) => Some(slot()),
        (6, _) => Some(tenth()),
        _ => None,
    });
    // A forward GOTO to an F-only line further down and back: the F word there runs between
    // two moves that are in file order.
    let src = "\
O3
G21 G90 G94
G0 X0 Y0 Z0
G1 X5. F1000
GOTO 50
N40 G1 Y5.
G1 X20.
M30
N50 F250
GOTO 40
";
    check(src, |line, _| match line {
        4 => Some(tenth()),
        _ => None,
    });
}

/// A line with a syntax error that the program jumps over (it runs on the control) is left
/// byte for byte by the rewrite, even with an F word of its own; only executed F words change.
#[test]
fn a_syntax_error_jumped_over_is_kept_by_the_rewrite() {
    let src = "O3\nG21 G90 G94\nG0 X0 Y0 Z0\nG1 X10 F1000\nGOTO 10\nG1 X20 $ F5\nN10 G1 Y10\nM30\n";
    let text = check(src, |line, _| match line {
        4 | 7 => Some(slot()),
        _ => None,
    });
    assert!(text.contains("\nG1 X20 $ F5\n"), "{text}");
    assert!(!text.contains("F1000"), "the executed F is lowered: {text}");
}
