//! Tool life used and roughness left, per move and per program, against hand computations:
//! the extended Taylor equation for a slot, the scallop closed form for a ball end mill.

mod common;

use std::f64::consts::PI;

use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::machine::Machine;
use millsim_engine::physics::life::TaylorLife;
use millsim_engine::pipeline::{simulate, MoveRow, SimulateSpec};
use millsim_engine::tool::Tool;

fn spec(program: &str, tool: Tool, cell: f64) -> SimulateSpec {
    SimulateSpec {
        // Accelerations high enough that every move runs at its feed: time = length / F.
        machine: Machine {
            acceleration: [1e9; 3],
            ..Machine::generic()
        },
        force_positions: 180,
        ..common::simulate::block_spec(program, tool, cell)
    }
}

fn row(rows: &[MoveRow], line: u32) -> &MoveRow {
    rows.iter().find(|r| r.line == line).unwrap()
}

#[test]
fn a_slot_uses_the_life_the_taylor_equation_gives() {
    // Flat Ø10, 4 teeth, no helix: a slot at S10000 F4000 (fz 0.1 mm, the thickest chip),
    // cutting speed π·10·10000/1000 m/min, in the cut from x = −5 to 60 (65 mm, 0.975 s).
    let mut tool = Tool::flat(10.0, 4);
    tool.helix_deg = 0.0;
    let program = "G21 G90 G17\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X60 F4000\nG0 Z5\nM30\n";
    let mut s = spec(program, tool, 0.1);
    let taylor = TaylorLife {
        c: 300.0,
        n: 0.25,
        a: 0.2,
        source: "test constants".into(),
    };
    s.material.taylor = Some(taylor.clone());
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let v = PI * 10.0 * 10_000.0 / 1000.0;
    let life_min = (taylor.c / (v * 0.1f64.powf(taylor.a))).powf(1.0 / taylor.n);
    let expected = 65.0 / 4000.0 / life_min;
    let slot = row(&out.rows, 6);
    let used = slot.tool_life_used.unwrap();
    assert!(
        (used - expected).abs() / expected < 0.02,
        "life used {used} vs {expected} by hand"
    );
    let life = out.summary.tool_life.as_ref().unwrap();
    assert_eq!(life.len(), 1);
    assert_eq!(life[0].most_wearing_line, Some(6));
    assert!((life[0].life_used - used).abs() < 1e-12);
    assert!((life[0].life_left - (1.0 - used)).abs() < 1e-12);
    assert_eq!(
        row(&out.rows, 5).tool_life_used,
        Some(0.0),
        "a rapid wears nothing"
    );

    // Without constants the column is absent and the summary says why.
    s.material.taylor = None;
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    assert!(out.rows.iter().all(|r| r.tool_life_used.is_none()));
    let json = serde_json::to_value(&out.rows[0]).unwrap();
    assert!(json.get("tool_life_used").is_none(), "{json}");
    let why = out.summary.tool_life_unavailable.as_deref().unwrap();
    assert!(why.contains("Taylor"), "{why}");
    // The slot's flanks leave feed marks of fz on the wall: R − sqrt(R² − (fz/2)²).
    let marks = 5.0 - (25.0f64 - 0.05 * 0.05).sqrt();
    let slot = row(&out.rows, 6);
    assert!(
        (slot.feed_mark_um - marks * 1000.0).abs() < 1e-9,
        "{}",
        slot.feed_mark_um
    );
    assert_eq!(slot.scallop_um, 0.0, "a lone slot has no neighbour");
}

#[test]
fn a_ball_pass_beside_another_leaves_the_closed_form_scallop() {
    // Ball Ø10 (R = 5) 2 mm deep, two passes 4 mm apart: h = R − sqrt(R² − (s/2)²). The
    // engaged width is found on the engagement's angular bins (about ±0.06 mm here), so the
    // scallop is good to a few per cent.
    let program = "G21 G90 G17\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-2\nG1 X60 F2000\nG0 Z5\nG0 X-10 Y4\nG0 Z-2\nG1 X60 F2000\nG0 Z5\nM30\n";
    let out = simulate(
        &spec(program, Tool::ball(10.0, 2), 0.02),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let h = 5.0 - (25.0f64 - 4.0).sqrt();
    let second = row(&out.rows, 10);
    println!(
        "scallop {} µm vs {} µm (radial width {})",
        second.scallop_um,
        h * 1000.0,
        second.max_radial_width
    );
    assert!(
        (second.scallop_um - h * 1000.0).abs() / (h * 1000.0) < 0.04,
        "{} vs {}",
        second.scallop_um,
        h * 1000.0
    );
    assert_eq!(row(&out.rows, 6).scallop_um, 0.0, "the first pass is alone");
    let r = &out.summary.roughness;
    assert_eq!(r.scallop_line, Some(10));
    assert_eq!(r.scallop_max_um, second.scallop_um);
    assert!(r.feed_mark_max_um > 0.0);
}
