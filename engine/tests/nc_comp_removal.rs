//! Cutter radius compensation, simulated: a G41 contour around a square boss, programmed on
//! the boss's own outline, leaves the boss at its programmed size (within one grid cell) and
//! cuts a ring one tool diameter wide around it.

use millsim_engine::geometry::{simulate_removal, Segment, SimOptions, Stock};
use millsim_engine::job::CancelFlag;
use millsim_engine::nc::{interpret, parse_tool_table, InterpretOptions, Move, MoveKind};
use millsim_engine::tool::Tool;

fn xyz(p: &[f64; 6]) -> [f64; 3] {
    [p[0], p[1], p[2]]
}

fn segments(moves: &[Move]) -> Vec<Segment> {
    moves
        .iter()
        .filter_map(|m| match m.kind {
            MoveKind::Rapid => Some(Segment::rapid(m.block, xyz(&m.start), xyz(&m.end))),
            MoveKind::Linear => Some(Segment::linear(
                m.block,
                xyz(&m.start),
                xyz(&m.end),
                m.feed,
                8000.0,
            )),
            MoveKind::Arc => Some(Segment::arc(
                m.block,
                xyz(&m.start),
                xyz(&m.end),
                m.center.unwrap(),
                m.normal.unwrap(),
                m.clockwise.unwrap(),
                m.feed,
                8000.0,
            )),
            _ => None,
        })
        .collect()
}

#[test]
fn a_g41_contour_leaves_the_boss_at_its_programmed_size() {
    // The boss is X0..20 Y0..20; the program follows its outline clockwise with the tool
    // (D6) on the left, outside.
    let src = "G21 G17 G90 G40\nT1 M6\nG0 X-10 Y-10 Z5\nG1 Z-2 F300\nG41 D1\nG1 X0 Y-5 F600\n\
               G1 Y20\nG1 X20\nG1 Y0\nG1 X0\nG1 Y5\nG40 G1 X-10 Y-10\nG0 Z5\nM2\n";
    let opts = InterpretOptions {
        tool_table: parse_tool_table("T1 P1 Z0 D6.0\n").unwrap(),
        ..InterpretOptions::default()
    };
    let moves = interpret(src, &opts).unwrap().moves;
    // The tool table's diameter (G41 D1) and a programmed one (G41.1 D6) give the same path.
    let dynamic = interpret(
        &src.replace("G41 D1", "G41.1 D6"),
        &InterpretOptions::default(),
    );
    assert_eq!(dynamic.unwrap().moves, moves);
    // Outside corners are rounded by arcs about the boss corners.
    assert_eq!(moves.iter().filter(|m| m.kind == MoveKind::Arc).count(), 4);
    let cell = 0.2;
    let mut stock = Stock::block([-12.0, -12.0, -4.0], [32.0, 32.0, 0.0], cell).unwrap();
    simulate_removal(
        &mut stock,
        &Tool::flat(6.0, 3),
        &segments(&moves),
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let g = &stock.grid;
    let z = -1.0;
    // Along each side of the boss: material just inside, none just outside (one cell).
    for t in [2.0, 10.0, 18.0] {
        for (inside, outside) in [
            ([cell, t], [-cell, t]),
            ([20.0 - cell, t], [20.0 + cell, t]),
            ([t, cell], [t, -cell]),
            ([t, 20.0 - cell], [t, 20.0 + cell]),
        ] {
            assert!(
                g.material_at([inside[0], inside[1], z]),
                "boss missing at {inside:?}"
            );
            assert!(
                !g.material_at([outside[0], outside[1], z]),
                "not cut at {outside:?}"
            );
        }
    }
    // The corners stay sharp (the tool went around them), and the cut is one diameter wide.
    for c in [
        [cell, cell],
        [20.0 - cell, cell],
        [cell, 20.0 - cell],
        [20.0 - cell, 20.0 - cell],
    ] {
        assert!(g.material_at([c[0], c[1], z]), "corner lost at {c:?}");
    }
    assert!(!g.material_at([-5.8, 10.0, z]));
    assert!(g.material_at([-6.0 - cell, 10.0, z]));
    assert!(!g.material_at([10.0, 25.8, z]));
    assert!(g.material_at([10.0, 26.0 + cell, z]));
    // Below the cut depth the stock is whole.
    assert!(g.material_at([-3.0, 10.0, -2.0 - cell]));
}
