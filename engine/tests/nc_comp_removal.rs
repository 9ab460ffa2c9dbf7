//! Cutter radius compensation, simulated: a G41 contour around a square boss, programmed on
//! the boss's own outline, leaves the boss at its programmed size (within one grid cell) and
//! cuts a ring one tool diameter wide around it.

mod common;

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

/// The boss contour of the test above, with its tool given as a job gives it.
fn boss_spec(program: &str, tools: &[(u32, f64)]) -> millsim_engine::pipeline::SimulateSpec {
    use millsim_engine::geometry::StockShape;
    use millsim_engine::pipeline::StockSource;
    let mut s = common::simulate::block_spec(program, Tool::flat(6.0, 3), 0.2);
    s.stock = StockSource::Shape(StockShape::Block {
        min: [-12.0, -12.0, -4.0],
        max: [32.0, 32.0, 0.0],
    });
    s.tools = tools.iter().map(|&(n, d)| (n, Tool::flat(d, 3))).collect();
    s
}

#[test]
fn g41_d1_takes_the_radius_of_the_jobs_tool_however_it_is_given() {
    use millsim_engine::job::NoProgress;
    use millsim_engine::pipeline::simulate;
    let body =
        "G21 G17 G90 G40\nT1 M6\nS8000 M3\nG0 X-10 Y-10 Z5\nG1 Z-2 F300\nG41 D1\nG1 X0 Y-5 F600\n\
                G1 Y20\nG1 X20\nG1 Y0\nG1 X0\nG1 Y5\nG40 G1 X-10 Y-10\nG0 Z5\nM30\n";
    let run = |program: &str, tools: &[(u32, f64)]| {
        simulate(&boss_spec(program, tools), &CancelFlag::new(), &NoProgress)
            .unwrap_or_else(|e| panic!("{tools:?}: {e}"))
            .summary
            .removed_volume
    };
    // The contour alone cuts the ring one diameter wide around the 20×20 boss, 2 mm deep,
    // its outside corners rounded at the diameter: (4·20·D + π·D²)·2; the lead-in and out
    // (the plunge at X-10 Y-10 and the ramps on and off, partly in the ring) add under 250 mm³;
    // uncompensated, the tool would straddle the outline and cut less outside it.
    let ring = |d: f64| (80.0 * d + std::f64::consts::PI * d * d) * 2.0;
    let numbered = run(body, &[(1, 6.0)]);
    assert!(
        numbered > ring(6.0) && numbered < ring(6.0) + 250.0,
        "{numbered} vs {}",
        ring(6.0)
    );
    // The job's one tool (given without a number) serves D1 too.
    assert_eq!(run(body, &[(0, 6.0)]), numbered);
    // No tool given: the header comment's tool (Mastercam's form) is cut with and its
    // diameter is the radius G41 D1 takes.
    let header = format!("( T1 |  6. FLAT ENDMILL | H1 )\n{body}");
    assert_eq!(run(&header, &[]), numbered);
    // The simulation's summary lists what the interpreter warned of, with its line.
    let summary = simulate(
        &boss_spec(body, &[(1, 6.0)]),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap()
    .summary;
    assert!(
        summary
            .program_warnings
            .iter()
            .any(|w| w.starts_with("6:1: G41 D1") && w.contains("wear compensation")),
        "{:?}",
        summary.program_warnings
    );
    // The radius taken from the job's tool is said once, with the way to the wear
    // compensation reading; a tool table's radius is the program's own and says nothing.
    let opts = InterpretOptions {
        tool_diameters: [(1, 6.0)].into(),
        ..InterpretOptions::default()
    };
    let twice = body.replace(
        "G0 Z5\nM30",
        "G0 Z5\nG41 D1\nG1 X0 Y-5\nG40 G1 X-10 Y-10\nM30",
    );
    let warned = interpret(&twice, &opts).unwrap().warnings;
    let about: Vec<_> = warned
        .iter()
        .filter(|w| w.message.contains("wear compensation"))
        .collect();
    assert_eq!(about.len(), 1, "{warned:?}");
    assert!(
        about[0].message.contains("G10 L1 P1 R0"),
        "{}",
        about[0].message
    );
    let table = InterpretOptions {
        tool_table: parse_tool_table("T1 P1 Z0 D6.0\n").unwrap(),
        ..InterpretOptions::default()
    };
    let quiet = interpret(body, &table).unwrap().warnings;
    assert!(
        quiet.iter().all(|w| !w.message.contains("wear")),
        "{quiet:?}"
    );
    // A larger tool, a wider ring: the radius follows the tool.
    let wide = run(body, &[(1, 8.0)]);
    assert!(
        wide > ring(8.0) && wide < ring(8.0) + 300.0,
        "{wide} vs {}",
        ring(8.0)
    );
}
