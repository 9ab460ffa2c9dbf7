//! An optimized program a machinist can run (issue 29): plunges are not sped up, a cut the
//! model did not see is never air, and each tool is held to its own limits on re-simulation.

mod common;

use std::collections::BTreeMap;

use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::optimize::{FeedLimits, ToolLimits};
use millsim_engine::pipeline::{simulate, SimulateSpec};
use millsim_engine::tool::Tool;

fn limits(max_force: f64) -> FeedLimits {
    FeedLimits {
        max_force: Some(max_force),
        air_feed: Some(5000.0),
        max_feed: 5000.0,
        ..FeedLimits::default()
    }
}

/// The F word the optimized program writes on `line` (1-based).
fn f_on(text: &str, line: usize) -> f64 {
    let l = text.lines().nth(line - 1).unwrap();
    let at = l
        .find('F')
        .unwrap_or_else(|| panic!("no F on line {line}: {l}"));
    l[at + 1..]
        .split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

fn plunge_spec(l: FeedLimits) -> SimulateSpec {
    let program = "G21 G90\nS8000 M3\nG0 X50 Y0 Z5\nG0 Z0\nG1 Z-3 F100\nG1 X70 F400\nG0 Z5\nM30\n";
    let tool = Tool {
        flute_length: 30.0,
        ..Tool::flat(12.0, 4)
    };
    let mut spec = common::simulate::block_spec(program, tool, 0.25);
    spec.optimize = Some(l);
    spec
}

#[test]
fn a_plunge_into_solid_is_never_sped_up_past_its_programmed_feed() {
    // Before: the plunge read as air and was written at the air feed (F5000).
    let out = simulate(
        &plunge_spec(limits(3000.0)),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let text = out.optimized_program.unwrap();
    let f = f_on(&text, 5);
    assert!(f <= 100.0, "plunge written at F{f}:\n{text}");
    let row = out.rows.iter().find(|r| r.line == 5).unwrap();
    assert!(row.peak_force > 500.0, "{row:?}");
    assert_ne!(row.governing.as_deref(), Some("air"), "{row:?}");
    // The side cut that follows may still be sped up.
    assert!(f_on(&text, 6) > 400.0, "{text}");

    // With max_plunge_feed the plunge may go faster, up to it and the force limit.
    let out = simulate(
        &plunge_spec(FeedLimits {
            max_plunge_feed: Some(300.0),
            ..limits(3000.0)
        }),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let f = f_on(out.optimized_program.as_deref().unwrap(), 5);
    assert!(f > 100.0 && f <= 300.0, "F{f}");

    // A force limit below the plunge's thrust slows it down.
    let out = simulate(&plunge_spec(limits(400.0)), &CancelFlag::new(), &NoProgress).unwrap();
    let f = f_on(out.optimized_program.as_deref().unwrap(), 5);
    assert!(f < 100.0, "F{f}");
}

#[test]
fn each_tool_is_held_to_its_own_limits_on_re_simulation() {
    // A Ø12 roughing tool and a Ø6 finishing tool, one job limit and a tighter one for T2.
    let program = "G21 G90\nT1 M6\nS8000 M3\nG0 X-10 Y-10 Z5\nG0 Z-3\nG1 X110 F600\nG0 Z5\n\
                   T2 M6\nS10000 M3\nG0 X-10 Y10 Z5\nG0 Z-0.5\nG1 X110 F960\nG0 Z5\nM30\n";
    let tools = BTreeMap::from([
        (
            1,
            Tool {
                flute_length: 30.0,
                ..Tool::flat(12.0, 4)
            },
        ),
        (
            2,
            Tool {
                flute_length: 20.0,
                ..Tool::ball(6.0, 2)
            },
        ),
    ]);
    let spec = |own: bool| {
        // The tools' default guards off: this checks the user's per-tool limits, and the
        // guards would hold T2 under 150 N without them (optimize_guards checks those).
        let mut l = FeedLimits {
            tool_guards: false,
            ..limits(1500.0)
        };
        if own {
            l.tools.insert(
                "T2".into(),
                ToolLimits {
                    max_force: Some(120.0),
                    ..Default::default()
                },
            );
        }
        let mut spec = common::simulate::block_spec(program, Tool::flat(12.0, 4), 0.25);
        spec.tools = tools.clone();
        spec.optimize = Some(l);
        spec
    };
    let out = simulate(&spec(true), &CancelFlag::new(), &NoProgress).unwrap();
    let text = out.optimized_program.clone().unwrap();
    let summary = out.optimization.as_ref().unwrap();
    let t2 = summary.tools.iter().find(|t| t.tool == 2).unwrap();
    assert_eq!(t2.limits.max_force, Some(120.0));
    let t1 = summary.tools.iter().find(|t| t.tool == 1).unwrap();
    assert_eq!(t1.limits.max_force, Some(1500.0));
    // Under the job's limit alone, T2 would be driven well past 120 N.
    let loose = simulate(&spec(false), &CancelFlag::new(), &NoProgress).unwrap();
    let loose_t2 = loose.rows.iter().find(|r| r.line == 12).unwrap();
    assert!(loose_t2.peak_force_after.unwrap() > 150.0, "{loose_t2:?}");

    // The optimized program run again at its own feeds.
    let mut again = common::simulate::block_spec(&text, Tool::flat(12.0, 4), 0.25);
    again.tools = tools.clone();
    let re = simulate(&again, &CancelFlag::new(), &NoProgress).unwrap();
    let peak = |line: u32| re.rows.iter().find(|r| r.line == line).unwrap().peak_force;
    assert!(peak(12) <= 120.0 * 1.02, "T2 at {} N", peak(12));
    assert!(
        peak(12) >= 120.0 * 0.9,
        "T2 at {} N: the limit should bind",
        peak(12)
    );
    assert!(
        peak(6) > 300.0 && peak(6) <= 1500.0 * 1.02,
        "T1 at {} N",
        peak(6)
    );

    // A tool's own entry factor slows that tool's entries only.
    let mut entry = spec(true);
    let own = entry
        .optimize
        .as_mut()
        .unwrap()
        .tools
        .get_mut("T2")
        .unwrap();
    own.entry_feed_factor = Some(0.5);
    let out = simulate(&entry, &CancelFlag::new(), &NoProgress).unwrap();
    let governing = |line: u32| {
        out.rows
            .iter()
            .find(|r| r.line == line)
            .unwrap()
            .governing
            .clone()
    };
    assert_eq!(governing(12).as_deref(), Some("entry"));
    assert_ne!(governing(6).as_deref(), Some("entry"));

    // A tool's limits keyed by something else than its number are refused, naming it.
    let mut bad = limits(1500.0);
    bad.tools.insert("tool2".into(), ToolLimits::default());
    assert!(bad
        .validate()
        .unwrap_err()
        .to_string()
        .contains("tools.tool2"));
}
