//! The removal hands its steps to the forces, rows, wear and optimizer in batches so that
//! a program's step records are never held at once: the results must not depend on the
//! batch size. Every row, sample, summary figure and the optimized program are compared
//! exactly (their JSON, where floats are written in full) between one step per batch, small
//! batches and the whole program in one batch.

mod common;

use std::collections::BTreeMap;

use millsim_engine::geometry::StockShape;
use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::machine::{Kinematics, Machine};
use millsim_engine::nc::InterpretOptions;
use millsim_engine::optimize::{FeedLimits, SplitOptions};
use millsim_engine::physics::energy::EnergyModel;
use millsim_engine::physics::life::TaylorLife;
use millsim_engine::physics::Material;
use millsim_engine::pipeline::{
    simulate_in_batches, ChatterSpec, SimulateSpec, SimulationOutput, StockSource,
    DEFAULT_BATCH_STEPS,
};
use millsim_engine::tool::Tool;

use common::simulate::block_spec;

/// Everything a job's user reads, as text (floats in full), timings aside.
fn figures(out: &SimulationOutput) -> Vec<String> {
    let json = |v: serde_json::Result<String>| v.unwrap();
    let mut summary = serde_json::to_value(&out.summary).unwrap();
    summary.as_object_mut().unwrap().remove("timings");
    let mut all = vec![
        json(serde_json::to_string(&summary)),
        json(serde_json::to_string(&out.optimization)),
        out.optimized_program.clone().unwrap_or_default(),
        format!("{} {:?}", out.rays_tested, out.tool_numbers),
        format!("{}", out.stock.volume()),
    ];
    for (row, samples) in out.rows.iter().zip(&out.samples) {
        all.push(json(serde_json::to_string(row)));
        all.push(json(serde_json::to_string(samples)));
    }
    all
}

fn assert_same(a: &SimulationOutput, b: &SimulationOutput, what: &str) {
    let (fa, fb) = (figures(a), figures(b));
    assert_eq!(fa.len(), fb.len(), "{what}");
    for (i, (x, y)) in fa.iter().zip(&fb).enumerate() {
        assert_eq!(x, y, "{what}: item {i} differs");
    }
}

fn run(spec: &SimulateSpec, batch: usize) -> SimulationOutput {
    simulate_in_batches(spec, batch, &CancelFlag::new(), &NoProgress).unwrap()
}

/// Two tools, lines and arcs in a block, with energy, chatter, tool life and an optimize
/// run that splits moves: every stage that reads the steps.
fn two_tool_spec() -> SimulateSpec {
    let mut t1 = Tool::flat(10.0, 4);
    t1.flute_length = 20.0;
    let mut t2 = Tool::ball(6.0, 2);
    t2.flute_length = 12.0;
    let program = "G21 G90 G17\nT1 M6\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-3\n\
        G1 X40 F3000\nG1 Y8\nG1 X90 Y10\nG2 X90 Y-10 I0 J-10\nG1 X140 F2000\nG0 Z5\n\
        T2 M6\nS12000 M3\nG0 X-5 Y-12\nG0 Z-2\nG1 X50 Y-6 F2500\nG3 X70 Y14 I0 J20\nG1 X-5\nG0 Z5\nM30\n";
    let modes = r#"[{"freq_hz":922,"damping":0.011,"stiffness_n_m":1.34005e6}]"#;
    let mut material = Material::builtin("Al7075-T6").unwrap();
    material.taylor = Some(TaylorLife {
        c: 300.0,
        n: 0.25,
        a: 0.2,
        source: "test constants".into(),
    });
    SimulateSpec {
        tools: BTreeMap::from([(1, t1), (2, t2)]),
        material,
        machine: Machine {
            energy: Some(EnergyModel::reference_example()),
            ..Machine::generic()
        },
        force_positions: 90,
        optimize: Some(FeedLimits {
            max_force: Some(500.0),
            air_feed: Some(6000.0),
            max_feed: 6000.0,
            split: Some(SplitOptions::default()),
            ..FeedLimits::default()
        }),
        workpiece: None,
        chatter: Some(ChatterSpec {
            modes_x: serde_json::from_str(modes).unwrap(),
            modes_y: serde_json::from_str(modes).unwrap(),
            method: millsim_engine::physics::stability::Method::Sdm,
            steps_per_period: 20,
        }),
        // The block, the cell and the rest as every cutting test has them.
        ..block_spec(program, Tool::flat(10.0, 4), 0.25)
    }
}

#[test]
fn batches_of_any_size_give_the_same_results_on_lines_arcs_and_two_tools() {
    let spec = two_tool_spec();
    let whole = run(&spec, usize::MAX);
    // The figures are real: material removed, forces, a split, life used.
    assert!(whole.summary.removed_volume > 1000.0, "{:?}", whole.summary);
    assert!(whole.summary.peak_force > 100.0);
    let opt = whole.optimization.as_ref().unwrap();
    assert!(opt.changed_blocks > 0, "{opt:?}");
    assert!(whole.summary.tool_life.is_some());
    assert!(whole.summary.chatter_moves.is_some());
    for batch in [1, 7, 100, 1000] {
        assert_same(&whole, &run(&spec, batch), &format!("batch {batch}"));
    }
}

#[test]
fn batches_split_the_pieces_of_a_rotary_move_without_changing_it() {
    // One C turn is many pieces in the part frame (the tip circles the table): batches of
    // one step end inside the move, between its pieces. A ball end leaves a scallop that
    // varies along the spiral (the move's median must be over all its pieces).
    let mut tool = Tool::ball(10.0, 3);
    tool.flute_length = 20.0;
    let program = "G21 G90 S10000 M3\nG0 Z10 A0 C0\nG0 X13 Y0\nG1 Z-3.5 F300\nG1 C360 F3600\nG1 X12 C720\nG0 Z10\n";
    let spec = SimulateSpec {
        program: program.into(),
        interpret: InterpretOptions::default(),
        stock: StockSource::Shape(StockShape::Cylinder {
            base_center: [0.0, 0.0, -40.5],
            radius: 10.0,
            height: 40.0,
        }),
        tools: BTreeMap::from([(0, tool)]),
        material: Material::builtin("Al7075-T6").unwrap(),
        machine: Machine {
            kinematics: Kinematics::XyzAc,
            ..Machine::generic()
        },
        cell: Some(0.2),
        memory_limit: 1 << 30,
        force_positions: 90,
        optimize: Some(FeedLimits {
            max_force: Some(300.0),
            ..FeedLimits::default()
        }),
        axes: Default::default(),
        workpiece: None,
        chatter: None,
        part: None,
        fixture: None,
    };
    let whole = run(&spec, usize::MAX);
    assert!(whole.rows.iter().any(|r| r.removed_volume > 100.0));
    assert!(whole.rows.iter().any(|r| r.scallop_um > 0.0));
    for batch in [1, 50] {
        assert_same(&whole, &run(&spec, batch), &format!("batch {batch}"));
    }
}

#[test]
fn the_adaptive_example_gives_the_same_blocks_in_small_batches() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/adaptive");
    let read = |f: &str| std::fs::read_to_string(format!("{dir}/{f}")).unwrap();
    let machine: Machine = serde_json::from_str(&read("machine.json")).unwrap();
    let stock: serde_json::Value = serde_json::from_str(&read("stock.json")).unwrap();
    let tool: Tool = serde_json::from_str(&read("tool.json")).unwrap();
    let spec = SimulateSpec {
        program: read("1055_utab_265bit.nc"),
        interpret: InterpretOptions::default(),
        stock: StockSource::Shape(StockShape::Block {
            min: serde_json::from_value(stock["min"].clone()).unwrap(),
            max: serde_json::from_value(stock["max"].clone()).unwrap(),
        }),
        tools: BTreeMap::from([(0, tool)]),
        material: Material::builtin("Al7075-T6").unwrap(),
        machine,
        cell: Some(0.1),
        memory_limit: 1 << 30,
        force_positions: 90,
        optimize: Some(FeedLimits {
            max_force: Some(400.0),
            air_feed: Some(5000.0),
            max_feed: 5000.0,
            ..FeedLimits::default()
        }),
        axes: Default::default(),
        workpiece: None,
        chatter: None,
        part: None,
        fixture: None,
    };
    let whole = run(&spec, usize::MAX);
    assert!(
        whole.summary.force_evaluations > 10_000,
        "{:?}",
        whole.summary
    );
    assert_same(&whole, &run(&spec, 2000), "batch 2000");
}

#[test]
fn a_move_longer_than_a_batch_is_swept_in_parts_like_its_parts_written_as_moves() {
    // A 400-turn helix down 4 mm around an R5 circle at 0.25 mm cells: 50,000 cells of
    // path, over a default batch, so it is swept in two parts (its steps handed on
    // as they come, not held whole). The same helix written as two 200-turn moves is
    // those two parts: the same figures, within rounding of the split point.
    let program = |helix: &str| {
        format!("G21 G90 G17\nT1 M6\nS10000 M3\nG0 X5 Y0 Z2\nG1 Z0 F600\n{helix}G0 Z5\nM30\n")
    };
    let spec_for = |program: String| {
        let mut spec = two_tool_spec();
        spec.program = program;
        spec.optimize = None;
        spec.chatter = None;
        spec.stock = StockSource::Shape(StockShape::Block {
            min: [-10.0, -10.0, -10.0],
            max: [10.0, 10.0, -1.0],
        });
        spec
    };
    // The default batch, as `simulate` runs it.
    let one = run(
        &spec_for(program("G2 X5 Y0 Z-4 I-5 J0 P400\n")),
        DEFAULT_BATCH_STEPS,
    );
    let two = run(
        &spec_for(program(
            "G2 X5 Y0 Z-2 I-5 J0 P200\nG2 X5 Y0 Z-4 I-5 J0 P200\n",
        )),
        usize::MAX,
    );
    let at_line =
        |out: &SimulationOutput, line: u32| out.rows.iter().position(|r| r.line == line).unwrap();
    let (h, k) = (at_line(&one, 6), at_line(&two, 6));
    assert_eq!(two.rows[k + 1].line, 7);
    let (helix, halves) = (&one.rows[h], &two.rows[k..k + 2]);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0);
    let volume: f64 = halves.iter().map(|r| r.removed_volume).sum();
    // 3 mm of the helix's 4 in the block: the Ø10 tool around the R5 circle clears a
    // disc of radius 10, 3 mm deep.
    let disc = std::f64::consts::PI * 10.0f64.powi(2) * 3.0;
    assert!(
        (helix.removed_volume - disc).abs() < 0.005 * disc,
        "{helix:?}"
    );
    assert!(
        close(helix.removed_volume, volume),
        "{} vs {volume}",
        helix.removed_volume
    );
    let peak = halves.iter().map(|r| r.peak_force).fold(0.0, f64::max);
    assert!(
        close(helix.peak_force, peak),
        "{} vs {peak}",
        helix.peak_force
    );
    assert_eq!(helix.steps, halves.iter().map(|r| r.steps).sum::<usize>());
    // The helix's samples are the halves', the second's placed after the first's length.
    let (samples, first, second) = (&one.samples[h], &two.samples[k], &two.samples[k + 1]);
    assert_eq!(samples.len(), first.len() + second.len());
    let offset = halves[0].tip_length_mm;
    for (s, t) in samples.iter().zip(first.iter().chain(second)) {
        assert!(close(s.peak_force, t.peak_force), "{s:?} vs {t:?}");
    }
    for (s, t) in samples[first.len()..].iter().zip(second) {
        assert!((s.at - (t.at + offset)).abs() < 1e-6, "{s:?} vs {t:?}");
    }
}
