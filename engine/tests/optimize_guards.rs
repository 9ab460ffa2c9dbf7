//! Default guards (issue 29): each tool's own chip and force ceilings, by the documented
//! rules (computed here by hand) or its library's feed-per-tooth preset; a small tool held
//! to them on re-simulation; switched off, the user's limits alone; a tighter user limit
//! winning; and each tool's own constant-feed comparison adding up to the job's.

mod common;

use std::collections::BTreeMap;
use std::f64::consts::PI;

use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::optimize::{tool_guards, FeedLimits, GuardSource, MaterialClass, ToolLimits};
use millsim_engine::physics::{CuttingCoefficients, Material};
use millsim_engine::pipeline::{simulate, MoveRow, SimulateSpec, SimulationOutput};
use millsim_engine::tool::Tool;
use millsim_engine::tool_library::ToolLibrary;

fn al7075() -> Material {
    Material::builtin("Al7075-T6").unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * b.abs().max(1.0)
}

#[test]
fn guard_values_follow_the_documented_rules() {
    // Ø12 4-flute carbide end mill in aluminium: flutes 3·D = 36, stick-out 36 + 2·D = 60.
    let t = Tool::flat(12.0, 4);
    let g = tool_guards(&t, &al7075());
    assert_eq!(g.material_class, MaterialClass::LightAlloy);
    assert_eq!(g.chip_source, GuardSource::Rule);
    assert!(close(g.max_chip_thickness, 0.012 * 12.0), "{g:?}");
    let force = 2000.0 * PI * (0.8f64 * 12.0).powi(3) / (32.0 * 60.0);
    assert!(close(g.max_force, force), "{g:?}");
    // What a machinist runs such a tool at stays allowed.
    assert!((0.1..=0.15).contains(&g.max_chip_thickness));
    assert!((1500.0..=4000.0).contains(&g.max_force), "{}", g.max_force);

    // The README's Ø2.65 2-flute tool, 20 mm out of the holder: well under 0.5 mm/tooth
    // and 100 N.
    let readme = Tool {
        stick_out: Some(20.0),
        shank_diameter: Some(3.175),
        flute_length: 14.0,
        ..Tool::flat(2.65, 2)
    };
    let g = tool_guards(&readme, &al7075());
    assert!(close(g.max_chip_thickness, 0.012 * 2.65), "{g:?}");
    assert!(
        close(
            g.max_force,
            2000.0 * PI * (0.8f64 * 2.65).powi(3) / (32.0 * 20.0)
        ),
        "{g:?}"
    );
    assert!(g.max_chip_thickness < 0.05 && g.max_force < 100.0, "{g:?}");

    // A Ø6 ball in titanium (TC6, Ktc 1785): the steel class, 0.8 for the ball.
    let ball = Tool::ball(6.0, 2);
    let g = tool_guards(&ball, &Material::builtin("TC6").unwrap());
    assert_eq!(g.material_class, MaterialClass::Steel);
    assert!(close(g.max_chip_thickness, 0.8 * 0.0075 * 6.0), "{g:?}");
    assert!(
        close(g.max_force, 2000.0 * PI * 4.8f64.powi(3) / (32.0 * 30.0)),
        "{g:?}"
    );

    // Large tools reach the class's cap; a hard material (Ktc ≥ 2200) has its own.
    let g = tool_guards(&Tool::flat(25.0, 4), &al7075());
    assert!(close(g.max_chip_thickness, 1.5 * 0.15), "{g:?}");
    let hard = Material {
        name: "Inconel 718 (test)".into(),
        coefficients: CuttingCoefficients::linear([2800.0, 1200.0, 600.0, 40.0, 50.0, 5.0]),
        taylor: None,
        source: "test".into(),
    };
    let g = tool_guards(&Tool::bull_nose(10.0, 1.0, 4), &hard);
    assert_eq!(g.material_class, MaterialClass::Hard);
    assert!(close(g.max_chip_thickness, 0.006 * 10.0), "{g:?}");

    // A reduced shank thinner than the core is the section that bends.
    let necked = Tool {
        shank_diameter: Some(2.0),
        stick_out: Some(25.0),
        ..Tool::flat(3.0, 2)
    };
    let g = tool_guards(&necked, &al7075());
    assert!(
        close(g.max_force, 2000.0 * PI * 8.0 / (32.0 * 25.0)),
        "{g:?}"
    );

    // A feed-per-tooth preset replaces the chip rule (not the force rule).
    let preset = Tool {
        feed_per_tooth: Some(0.04),
        ..Tool::flat(12.0, 4)
    };
    let g = tool_guards(&preset, &al7075());
    assert_eq!(g.chip_source, GuardSource::LibraryPreset);
    assert_eq!(g.max_chip_thickness, 0.04);
    assert_eq!(g.force_source, GuardSource::Rule);
}

#[test]
fn a_fusion_library_preset_becomes_the_tools_chip_ceiling() {
    let lib = ToolLibrary::read(
        r#"{"data":[
 {"type":"flat end mill","unit":"millimeters","geometry":{"DC":6,"NOF":3,"LCF":18},
  "start-values":{"presets":[{"name":"Alu roughing","f_z":0.06,"n":12000},
                             {"name":"Alu finishing","f_z":0.04}]},
  "post-process":{"number":1}},
 {"type":"flat end mill","unit":"inches","geometry":{"DC":0.25,"NOF":2,"LCF":0.75},
  "start-values":{"presets":[{"name":"Default","f_z":0.002}]},
  "post-process":{"number":2}},
 {"type":"ball end mill","unit":"millimeters","geometry":{"DC":8,"NOF":2,"LCF":16},
  "start-values":{"presets":[{"name":"no feed per tooth","n":9000}]},
  "post-process":{"number":3}}
]}"#,
    )
    .unwrap();
    // Several presets: the smallest, said so in the report.
    assert_eq!(lib.tools[&1].feed_per_tooth, Some(0.04));
    assert!(lib
        .report
        .assumed
        .iter()
        .any(|n| n.tool.starts_with("T1 ") && n.field == "start-values.presets.f_z"));
    // The presets' other values are read and reported as not used (the program's S and F
    // are simulated).
    for t in ["T1 ", "T3 "] {
        assert!(
            lib.report.unmodelled.iter().any(|n| n.tool.starts_with(t)
                && n.field == "start-values.presets"
                && n.note.starts_with("n not used")),
            "{t}: {:?}",
            lib.report.unmodelled
        );
    }
    // In the tool's unit.
    assert!(close(lib.tools[&2].feed_per_tooth.unwrap(), 0.002 * 25.4));
    assert_eq!(lib.tools[&3].feed_per_tooth, None);
    let g = tool_guards(&lib.tools[&1], &al7075());
    assert_eq!(
        (g.max_chip_thickness, g.chip_source),
        (0.04, GuardSource::LibraryPreset)
    );

    // A CSV library's column does the same.
    let csv = ToolLibrary::read(
        "number,type,diameter,flutes,feed_per_tooth\n1,flat,6,3,0.03\n2,ball,4,2,\n",
    )
    .unwrap();
    assert_eq!(csv.tools[&1].feed_per_tooth, Some(0.03));
    assert_eq!(csv.tools[&2].feed_per_tooth, None);

    // A preset that is not a feed per tooth is refused, naming the tool and field.
    let err = ToolLibrary::read(
        r#"{"data":[{"type":"flat end mill","geometry":{"DC":6},
            "start-values":{"presets":[{"f_z":-1}]},"post-process":{"number":4}}]}"#,
    )
    .unwrap_err();
    assert!(
        err.to_string().contains("start-values.presets[0].f_z"),
        "{err}"
    );
    let err = ToolLibrary::read(
        r#"{"data":[{"type":"flat end mill","geometry":{"DC":6},
            "start-values":{"presets":[{"f_z":4}]},"post-process":{"number":4}}]}"#,
    )
    .unwrap_err();
    assert!(err.to_string().contains("feed_per_tooth_mm"), "{err}");
}

/// A Ø3 2-flute end mill 30 mm out of the holder slotting 1 mm deep in aluminium at a
/// cautious F300, with a job limit (400 N) written for a large tool.
fn small_tool() -> Tool {
    Tool {
        stick_out: Some(30.0),
        ..Tool::flat(3.0, 2)
    }
}

const SLOT: &str = "G21 G90\nT1 M6\nS10000 M3\nG0 X-5 Y0 Z5\nG0 Z-1\nG1 X60 F300\nG0 Z5\nM30\n";

fn job_limits() -> FeedLimits {
    FeedLimits {
        max_force: Some(400.0),
        air_feed: Some(5000.0),
        max_feed: 5000.0,
        ..FeedLimits::default()
    }
}

fn slot_spec(limits: FeedLimits) -> SimulateSpec {
    program_spec(SLOT, limits)
}

fn program_spec(program: &str, limits: FeedLimits) -> SimulateSpec {
    let mut spec = common::simulate::block_spec(program, small_tool(), 0.1);
    spec.tools = BTreeMap::from([(1, small_tool())]);
    spec.optimize = Some(limits);
    spec
}

/// The optimized program run again: the slot's row (line 6).
fn resimulated(out: &SimulationOutput) -> MoveRow {
    resimulated_program(out, 6)
}

fn resimulated_program(out: &SimulationOutput, line: u32) -> MoveRow {
    let text = out.optimized_program.clone().unwrap();
    let mut again = common::simulate::block_spec(&text, small_tool(), 0.1);
    again.tools = BTreeMap::from([(1, small_tool())]);
    let re = simulate(&again, &CancelFlag::new(), &NoProgress).unwrap();
    re.rows.into_iter().find(|r| r.line == line).unwrap()
}

/// What set the slot's new feed.
fn governing(out: &SimulationOutput) -> String {
    let row = out.rows.iter().find(|r| r.line == 6).unwrap();
    row.governing.clone().unwrap_or_default()
}

fn limited_by(out: &SimulationOutput) -> Vec<String> {
    out.optimization.as_ref().unwrap().tools[0]
        .limited_by
        .iter()
        .map(|l| l.limit.clone())
        .collect()
}

#[test]
fn a_small_tool_is_held_to_its_guards_on_re_simulation() {
    let out = simulate(&slot_spec(job_limits()), &CancelFlag::new(), &NoProgress).unwrap();
    let summary = out.optimization.as_ref().unwrap();
    let t1 = &summary.tools[0];
    let g = t1.guards.as_ref().expect("guards on by default");
    // The rule's values for this tool (see the test above).
    assert!(close(g.max_chip_thickness, 0.036));
    assert!(close(
        g.max_force,
        2000.0 * PI * 2.4f64.powi(3) / (32.0 * 30.0)
    ));
    // The slot is sped up from F300 until a guard binds, not to the 400 N limit.
    let governing = governing(&out);
    assert!(governing.starts_with("guard_"), "{governing}");
    assert!(t1.limits_not_met.is_empty(), "{:?}", t1.limits_not_met);
    // Programmed faster than the guards allow: a guard never slows a move below its
    // programmed feed (the programmer's F stands; only the user's own limits may lower it),
    // and the report says the guard is not met.
    let guard_feed = out
        .rows
        .iter()
        .find(|r| r.line == 6)
        .unwrap()
        .feed_after_mm_min
        .unwrap();
    let fast = simulate(
        &program_spec(&SLOT.replace("F300", "F3000"), job_limits()),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let fast_row = fast.rows.iter().find(|r| r.line == 6).unwrap();
    let fast_feed = fast_row.feed_after_mm_min.unwrap();
    assert!(
        fast_feed > 1.01 * guard_feed && fast_feed <= 3000.0,
        "F{fast_feed} vs guard F{guard_feed}"
    );
    let fast_gov = fast_row.governing.clone().unwrap_or_default();
    if fast_gov.starts_with("guard_") {
        assert_eq!(fast_feed, 3000.0, "{fast_row:?}");
        let not_met: Vec<String> = fast.optimization.as_ref().unwrap().tools[0]
            .limits_not_met
            .iter()
            .map(|l| l.limit.clone())
            .collect();
        assert!(not_met.contains(&fast_gov), "{not_met:?}");
    } else {
        assert_eq!(fast_gov, "force", "{fast_row:?}");
    }

    let row = resimulated(&out);
    assert!(
        row.peak_force <= g.max_force * 1.02,
        "{} N over the guard {} N",
        row.peak_force,
        g.max_force
    );
    assert!(
        row.max_chip_thickness <= g.max_chip_thickness * 1.02,
        "{} mm over the guard {} mm",
        row.max_chip_thickness,
        g.max_chip_thickness
    );
    // The guard binds: the slot runs close to one of them, not far below.
    assert!(
        row.peak_force >= 0.9 * g.max_force || row.max_chip_thickness >= 0.9 * g.max_chip_thickness,
        "{row:?}"
    );
}

#[test]
fn guards_switched_off_leave_the_users_limits_alone() {
    let on = simulate(&slot_spec(job_limits()), &CancelFlag::new(), &NoProgress).unwrap();
    let guard = on.optimization.as_ref().unwrap().tools[0]
        .guards
        .clone()
        .unwrap();
    // For the job, or for the tool alone.
    let job_off = FeedLimits {
        tool_guards: false,
        ..job_limits()
    };
    let mut tool_off = job_limits();
    tool_off.tools.insert(
        "T1".into(),
        ToolLimits {
            tool_guards: Some(false),
            ..Default::default()
        },
    );
    for limits in [job_off, tool_off] {
        let out = simulate(&slot_spec(limits), &CancelFlag::new(), &NoProgress).unwrap();
        let t1 = &out.optimization.as_ref().unwrap().tools[0];
        assert!(t1.guards.is_none());
        assert!(!t1.limits.tool_guards);
        let names = limited_by(&out);
        assert!(!names.iter().any(|n| n.starts_with("guard_")), "{names:?}");
        // As before the guards: the 400 N limit or the feed range alone, so the small
        // tool is driven far past what its section carries.
        let row = resimulated(&out);
        assert!(
            row.peak_force > 2.0 * guard.max_force && row.peak_force <= 400.0 * 1.02,
            "{} N",
            row.peak_force
        );
        assert!(row.max_chip_thickness > 2.0 * guard.max_chip_thickness);
    }
    // A tool may have them back where the job switched them off.
    let mut back = FeedLimits {
        tool_guards: false,
        ..job_limits()
    };
    back.tools.insert(
        "T1".into(),
        ToolLimits {
            tool_guards: Some(true),
            ..Default::default()
        },
    );
    let out = simulate(&slot_spec(back), &CancelFlag::new(), &NoProgress).unwrap();
    assert!(out.optimization.as_ref().unwrap().tools[0].guards.is_some());
}

#[test]
fn a_user_limit_tighter_than_the_guard_wins() {
    let out = simulate(&slot_spec(job_limits()), &CancelFlag::new(), &NoProgress).unwrap();
    let guard = out.optimization.as_ref().unwrap().tools[0]
        .guards
        .clone()
        .unwrap();
    // Above the edge forces alone (about 40 N at this depth), below the guard.
    let tight = 0.7 * guard.max_force;
    let mut limits = job_limits();
    limits.tools.insert(
        "T1".into(),
        ToolLimits {
            max_force: Some(tight),
            ..Default::default()
        },
    );
    let out = simulate(&slot_spec(limits), &CancelFlag::new(), &NoProgress).unwrap();
    assert_eq!(governing(&out), "force");
    let row = resimulated(&out);
    assert!(
        row.peak_force <= tight * 1.02 && row.peak_force >= tight * 0.9,
        "{} N for a {tight} N limit",
        row.peak_force
    );

    // The same for the chip.
    let tight = 0.5 * guard.max_chip_thickness;
    let limits = FeedLimits {
        max_chip_thickness: Some(tight),
        ..job_limits()
    };
    let out = simulate(&slot_spec(limits), &CancelFlag::new(), &NoProgress).unwrap();
    assert_eq!(governing(&out), "chip_thickness");
    let row = resimulated(&out);
    assert!(
        row.max_chip_thickness <= tight * 1.02,
        "{} mm",
        row.max_chip_thickness
    );
}

#[test]
fn each_tools_constant_feed_comparison_adds_up_to_the_jobs() {
    // A Ø12 roughing pass and a Ø6 ball finishing pass, one job limit.
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
    let mut spec = common::simulate::block_spec(program, Tool::flat(12.0, 4), 0.25);
    spec.tools = tools;
    spec.optimize = Some(FeedLimits {
        max_force: Some(1500.0),
        air_feed: Some(5000.0),
        max_feed: 5000.0,
        ..FeedLimits::default()
    });
    let out = simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    let job = out.optimization.as_ref().unwrap();
    assert_eq!(job.tools.len(), 2);
    // Every move is made with T1 or T2 (the program loads T1 first): the tools' times are
    // the job's, and each tool's time as written is its rows'.
    let total = |f: fn(&millsim_engine::pipeline::ToolOptimization) -> f64| -> f64 {
        job.tools.iter().map(f).sum()
    };
    let near = |a: f64, b: f64| (a - b).abs() <= 1e-6 * b.max(1.0);
    assert!(near(
        total(|t| t.cycle_time_before_s),
        job.cycle_time_before_s
    ));
    assert!(near(
        total(|t| t.cycle_time_after_s),
        job.cycle_time_after_s
    ));
    assert!(near(
        total(|t| t.cycle_time_ideal_s),
        job.cycle_time_ideal_s
    ));
    for t in &job.tools {
        let rows: f64 = out
            .rows
            .iter()
            .filter(|r| r.tool == t.tool)
            .map(|r| r.time_s)
            .sum();
        assert!(near(t.cycle_time_before_s, rows), "T{}", t.tool);
        assert!(t.best_constant_feed_mm_min <= 5000.0);
    }
    // The job's best constant feed is the slowest tool's; each tool at its own is no slower
    // than the whole job at the job's.
    let slowest = job
        .tools
        .iter()
        .map(|t| t.best_constant_feed_mm_min)
        .fold(f64::INFINITY, f64::min);
    assert!(near(job.best_constant_feed_mm_min, slowest), "{job:?}");
    assert!(
        job.tools[0].best_constant_feed_mm_min != job.tools[1].best_constant_feed_mm_min,
        "two tools, two constant feeds"
    );
    assert!(total(|t| t.cycle_time_constant_feed_s) <= job.cycle_time_constant_feed_s + 1e-6);
    // The slowest tool's moves take the same time at its feed as in the job's comparison;
    // the other's are faster: strictly less in all.
    assert!(total(|t| t.cycle_time_constant_feed_s) < job.cycle_time_constant_feed_s);
}

#[test]
fn a_force_guard_the_edge_forces_alone_exceed_holds_the_programmed_feed() {
    // 3 mm deep: the edge forces of the slot alone are over the Ø3 tool's force guard, at
    // any feed. Slowing to the minimum feed would not bring it under; the move keeps its
    // programmed feed, the guard is reported not met, and the chip guard still holds.
    let deep = |f: u32| {
        format!("G21 G90\nT1 M6\nS10000 M3\nG0 X-5 Y0 Z5\nG0 Z-3\nG1 X60 F{f}\nG0 Z5\nM30\n")
    };
    let out = simulate(
        &program_spec(&deep(300), job_limits()),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let t1 = &out.optimization.as_ref().unwrap().tools[0];
    let guard = t1.guards.clone().unwrap();
    let row = out.rows.iter().find(|r| r.line == 6).unwrap();
    assert!(row.peak_force > guard.max_force, "{row:?}");
    assert_eq!(row.feed_after_mm_min, Some(300.0), "{row:?}");
    assert_eq!(row.governing.as_deref(), Some("guard_force"));
    let not_met: Vec<&str> = t1.limits_not_met.iter().map(|l| l.limit.as_str()).collect();
    assert_eq!(not_met, vec!["guard_force"]);

    // Programmed at 0.15 mm per tooth, over the chip guard: the guard does not slow it (the
    // programmer's F stands); the user's own 400 N limit does, and the optimized program
    // re-simulates at it.
    let out = simulate(
        &program_spec(&deep(3000), job_limits()),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let row = out.rows.iter().find(|r| r.line == 6).unwrap();
    assert_eq!(row.governing.as_deref(), Some("force"), "{row:?}");
    let f = row.feed_after_mm_min.unwrap();
    assert!(f > 100.0 && f < 3000.0, "F{f}");
    let row = resimulated_program(&out, 6);
    assert!(row.peak_force <= 400.0 * 1.005, "{row:?}");
}
