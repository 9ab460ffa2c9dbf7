//! A process: operations in order on one stock. Checked against the manual chain (each
//! operation simulated alone on the stock the previous one exported as STL) and against
//! the volumes worked out by hand from the slots below.

mod common;

use std::sync::atomic::{AtomicU64, Ordering};

use common::simulate::block_spec;
use millsim_engine::geometry::{self, Stock};
use millsim_engine::job::{CancelFlag, NoProgress, Progress};
use millsim_engine::pipeline::{
    run_process, simulate, MoveRow, Operation, ProcessError, ProcessSpec, SimulateSpec,
    StockSource, MAX_OPERATIONS,
};
use millsim_engine::tool::Tool;

const CELL: f64 = 0.5;

/// Ø10 flat, a slot 3 deep along x at y 0 through the whole 100 mm block: 10 × 3 × 100 =
/// 3000 mm³.
fn rough() -> SimulateSpec {
    block_spec(
        "G90 G21\nS8000 M3\nG0 X-10 Y0 Z5\nG1 Z-3 F500\nG1 X110 F800\nG0 Z5\nM30\n",
        Tool::flat(10.0, 3),
        CELL,
    )
}

/// Ø6 flat at y 3, 5 deep: in the slot the rough left it cuts the wall y 5..6 above z −3
/// (1 × 3 × 100) and the floor y 0..6 from z −3 to −5 (6 × 2 × 100): 1500 mm³, every mm³
/// of it depending on what the first operation left.
fn finish() -> SimulateSpec {
    block_spec(
        "G90 G21\nS8000 M3\nG0 X-10 Y3 Z5\nG1 Z-5 F400\nG1 X110 F600\nG0 Z5\nM30\n",
        Tool::flat(6.0, 2),
        CELL,
    )
}

fn process(ops: Vec<SimulateSpec>) -> ProcessSpec {
    ProcessSpec {
        stock: ops[0].stock.clone(),
        cell: Some(CELL),
        fixture: None,
        operations: ops
            .into_iter()
            .enumerate()
            .map(|(i, spec)| Operation {
                name: format!("op{}", i + 1),
                spec,
                spindle: None,
            })
            .collect(),
    }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-9)
}

fn assert_rows_close(what: &str, a: &[MoveRow], b: &[MoveRow], tol: f64) {
    assert_eq!(a.len(), b.len(), "{what}: row count");
    for (x, y) in a.iter().zip(b) {
        assert_eq!((x.line, x.kind), (y.line, y.kind), "{what}");
        for (name, p, q) in [
            ("removed_volume", x.removed_volume, y.removed_volume),
            ("peak_force", x.peak_force, y.peak_force),
            ("max_axial_depth", x.max_axial_depth, y.max_axial_depth),
            ("time_s", x.time_s, y.time_s),
        ] {
            assert!(
                (p - q).abs() <= tol * q.abs().max(1.0),
                "{what}: line {} {name} {p} vs {q}",
                x.line
            );
        }
    }
}

#[test]
fn two_operations_equal_the_manual_chain_through_an_exported_stock() {
    let cancel = CancelFlag::new();
    // By hand: operation 1 alone, its stock exported as STL, operation 2 on that STL.
    let manual1 = simulate(&rough(), &cancel, &NoProgress).unwrap();
    let (stl, _) = geometry::export_stl_vec(&manual1.stock).unwrap();
    let mut second = finish();
    second.stock = StockSource::Stl(stl.into());
    let manual2 = simulate(&second, &cancel, &NoProgress).unwrap();

    let out = run_process(
        &process(vec![rough(), finish()]),
        &cancel,
        &NoProgress,
        &mut |_, _| {},
    )
    .unwrap();
    assert_eq!(out.operations.len(), 2);
    assert_eq!(out.cell, CELL);
    // Operation 1 is the simulation alone, bit for bit.
    let op1 = &out.operations[0];
    assert_rows_close("op 1", &op1.rows, &manual1.rows, 0.0);
    assert_eq!(
        op1.summary.stock_volume_after,
        manual1.summary.stock_volume_after
    );
    // Operation 2 cut the grid handed over where the manual chain re-read a mesh of it.
    let op2 = &out.operations[1];
    assert_rows_close("op 2", &op2.rows, &manual2.rows, 2e-3);
    assert!(
        rel(op2.summary.removed_volume, manual2.summary.removed_volume) < 2e-3,
        "{} vs {}",
        op2.summary.removed_volume,
        manual2.summary.removed_volume
    );
    assert!(rel(op2.summary.cycle_time_s, manual2.summary.cycle_time_s) < 1e-9);
    assert!(rel(op2.summary.peak_force, manual2.summary.peak_force) < 2e-3);
    // What the finish removes depends on the rough: alone on the blank it would take the
    // full 6 × 5 × 100 mm.
    let alone = simulate(&finish(), &cancel, &NoProgress).unwrap();
    assert!(rel(alone.summary.removed_volume, 3000.0) < 0.01);
    assert!(
        rel(op2.summary.removed_volume, 1500.0) < 0.01,
        "{}",
        op2.summary.removed_volume
    );
    assert!(
        op2.summary.peak_force < 0.9 * alone.summary.peak_force,
        "the finish cuts less after the rough: {} vs {}",
        op2.summary.peak_force,
        alone.summary.peak_force
    );
}

#[test]
fn the_stock_after_each_operation_has_lost_what_each_cut() {
    let mut volumes = Vec::new();
    let out = run_process(
        &process(vec![rough(), finish()]),
        &CancelFlag::new(),
        &NoProgress,
        &mut |i, stock: &Stock| volumes.push((i, stock.volume())),
    )
    .unwrap();
    let blank = 100.0 * 40.0 * 10.0;
    assert_eq!(volumes.len(), 2);
    assert_eq!(volumes[0].0, 0);
    assert!(rel(volumes[0].1, blank - 3000.0) < 1e-3, "{:?}", volumes);
    assert!(rel(volumes[1].1, blank - 4500.0) < 1e-3, "{:?}", volumes);
    let [a, b] = [&out.operations[0].summary, &out.operations[1].summary];
    assert!(rel(a.stock_volume_before, blank) < 1e-9);
    // Each operation starts from what the last left.
    assert_eq!(b.stock_volume_before, a.stock_volume_after);
    assert_eq!(a.stock_volume_after, volumes[0].1);
    assert_eq!(b.stock_volume_after, volumes[1].1);
    assert_eq!(out.stock.volume(), volumes[1].1);
}

#[test]
fn the_cell_is_the_finest_tools_default_for_every_operation() {
    let mut ops = vec![rough(), finish()];
    for op in &mut ops {
        op.cell = Some(0.8);
    }
    let mut p = process(ops);
    p.cell = None;
    let out = run_process(&p, &CancelFlag::new(), &NoProgress, &mut |_, _| {}).unwrap();
    // Ø6 → radius 3 / 20, finer than the Ø10's 0.25; the operations' own 0.8 is not taken.
    let expected = geometry::default_cell(&[3.0]);
    assert_eq!(out.cell, expected);
    for op in &out.operations {
        assert_eq!(op.summary.cell_mm, expected);
    }
}

#[test]
fn a_cancel_between_operations_stops_before_the_next_one_cuts() {
    let cancel = CancelFlag::new();
    let mut seen = Vec::new();
    let err = run_process(
        &process(vec![rough(), finish()]),
        &cancel,
        &NoProgress,
        &mut |i, _| {
            seen.push(i);
            cancel.cancel();
        },
    )
    .err()
    .expect("cancelled");
    assert!(matches!(err, ProcessError::Cancelled), "{err}");
    assert_eq!(seen, vec![0], "operation 2 never finished");
}

/// Cancels once the progress passes `at` of the whole.
struct CancelAt {
    cancel: CancelFlag,
    at: f64,
    last: AtomicU64,
}

impl Progress for CancelAt {
    fn report(&self, done: u64, total: u64) {
        assert!(done <= total);
        // Progress across operations never goes back.
        let scaled = done * 1_000_000 / total.max(1);
        assert!(scaled >= self.last.swap(scaled, Ordering::Relaxed));
        if done as f64 > self.at * total as f64 {
            self.cancel.cancel();
        }
    }
}

#[test]
fn a_cancel_inside_the_second_operation_stops_it() {
    let cancel = CancelFlag::new();
    let progress = CancelAt {
        cancel: cancel.clone(),
        at: 0.5,
        last: AtomicU64::new(0),
    };
    let mut seen = Vec::new();
    let err = run_process(
        &process(vec![rough(), finish()]),
        &cancel,
        &progress,
        &mut |i, _| seen.push(i),
    )
    .err()
    .expect("cancelled");
    assert!(matches!(err, ProcessError::Cancelled), "{err}");
    // Half the progress is the first operation's: it finished, the second did not.
    assert_eq!(seen, vec![0]);
}

#[test]
fn an_operation_that_fails_is_named_and_too_many_are_refused() {
    let mut bad = finish();
    bad.program = "G90\nG1 X10 Q\n".into();
    let err = run_process(
        &process(vec![rough(), bad]),
        &CancelFlag::new(),
        &NoProgress,
        &mut |_, _| {},
    )
    .err()
    .expect("a bad program fails");
    match &err {
        ProcessError::Operation { index, name, .. } => {
            assert_eq!((*index, name.as_str()), (1, "op2"))
        }
        other => panic!("{other}"),
    }
    assert!(err.to_string().starts_with("operation 2 (op2): "), "{err}");
    let many = process(vec![rough(); MAX_OPERATIONS + 1]);
    assert!(matches!(
        run_process(&many, &CancelFlag::new(), &NoProgress, &mut |_, _| {}),
        Err(ProcessError::TooManyOperations { count }) if count == MAX_OPERATIONS + 1
    ));
}

#[test]
fn each_operation_reads_its_program_in_the_work_offsets_its_setup_defines() {
    // The finish written from its own zero (Y0 in G55), the setup's G55 3 mm over in Y:
    // the same cut as `finish()` at Y3 in G54.
    let mut offset = finish();
    offset.program =
        "G90 G21\nG55\nS8000 M3\nG0 X-10 Y0 Z5\nG1 Z-5 F400\nG1 X110 F600\nG0 Z5\nM30\n".into();
    offset.interpret.work_offsets = vec![(1, [0.0, 3.0, 0.0])];
    let run = |second: SimulateSpec| {
        run_process(
            &process(vec![rough(), second]),
            &CancelFlag::new(),
            &NoProgress,
            &mut |_, _| {},
        )
        .unwrap()
    };
    let (a, b) = (run(finish()), run(offset));
    let (fa, fb) = (&a.operations[1].summary, &b.operations[1].summary);
    assert!(
        rel(fb.removed_volume, 1500.0) < 0.01,
        "{}",
        fb.removed_volume
    );
    assert!(rel(fb.removed_volume, fa.removed_volume) < 1e-9);
    assert!(rel(fb.peak_force, fa.peak_force) < 1e-9);
    // Without the offset the same program cuts at Y0: the slot's floor only, 6 × 2 × 100 + 0.
    let mut plain = finish();
    plain.program =
        "G90 G21\nS8000 M3\nG0 X-10 Y0 Z5\nG1 Z-5 F400\nG1 X110 F600\nG0 Z5\nM30\n".into();
    let c = run(plain);
    assert!(
        rel(c.operations[1].summary.removed_volume, 1200.0) < 0.01,
        "{}",
        c.operations[1].summary.removed_volume
    );
}

#[test]
fn the_processs_fixture_stands_for_every_operation() {
    // A clamp beside the block's left end, from y 5.5: the rough's Ø10 at y 0 (to y 5)
    // passes it, the finish's Ø6 plunging at X−10 Y3 (to y 6) meets it.
    let clamp = millsim_engine::geometry::FixtureSpec::from_json(
        &serde_json::json!({"bodies":[{"name":"clamp","kind":"block","min":[-20.0,5.5,-10.0],"max":[-8.0,10.0,2.0]}]}),
        "path",
    )
    .unwrap()
    .build("path", |r| Err(format!("no mesh {r}")))
    .unwrap();
    let mut p = process(vec![rough(), finish()]);
    p.fixture = Some(std::sync::Arc::new(clamp));
    let out = run_process(&p, &CancelFlag::new(), &NoProgress, &mut |_, _| {}).unwrap();
    let fixture = |i: usize| out.operations[i].summary.fixture.as_ref().expect("checked");
    assert_eq!(fixture(0).collision_moves, 0);
    assert!(fixture(1).collision_moves >= 1);
    assert_eq!(fixture(1).collisions[0].body, "clamp");
    // The plunge at line 4 of the finish.
    assert_eq!(fixture(1).collisions[0].line, 4);
}

#[test]
fn an_operation_that_chooses_its_spindle_speed_cuts_what_the_last_left_once() {
    // Both passes of the choice (as written, then at the chosen speed) cut the stock the
    // rough left: the first a copy of it.
    let spindle: millsim_engine::optimize::spindle::SpindleOptions =
        serde_json::from_value(serde_json::json!({
        "choose": true, "rpm": {"from": 5000, "to": 25000}, "speeds": 21,
        "modes_x": [{"freq_hz": 922, "damping": 0.011, "mass_kg": 0.03993}], "method": "zoa"}))
        .unwrap();
    let mut p = process(vec![rough(), finish()]);
    p.operations[1].spindle = Some(spindle);
    let out = run_process(&p, &CancelFlag::new(), &NoProgress, &mut |_, _| {}).unwrap();
    let s = &out.operations[1].summary;
    let sp = s.spindle.as_ref().expect("a speed chosen");
    assert!(
        sp.chosen_rpm >= 5000.0 && sp.chosen_rpm <= 25000.0,
        "{}",
        sp.chosen_rpm
    );
    assert!(rel(s.removed_volume, 1500.0) < 0.01, "{}", s.removed_volume);
    assert!(rel(out.stock.volume(), 40000.0 - 4500.0) < 1e-3);
    assert!(out.operations[1]
        .optimized_program
        .as_deref()
        .unwrap()
        .contains(&format!("S{}", sp.chosen_rpm as i64)));
}

/// Records the last progress report.
#[derive(Default)]
struct Last(std::sync::Mutex<(u64, u64)>);

impl Progress for Last {
    fn report(&self, done: u64, total: u64) {
        *self.0.lock().unwrap() = (done, total);
    }
}

#[test]
fn progress_gives_each_operation_its_programs_share() {
    // A finish whose program is five times the rough's: when the rough is done, a sixth of
    // the process is (an equal share would say half).
    let rough = rough();
    let mut finish = finish();
    let moves = "G1 X-10 F600\nG1 X110\n".repeat(5 * rough.program.len() / 22 + 1);
    finish.program = format!("G90 G21\nS8000 M3\nG0 X-10 Y3 Z5\nG1 Z-5 F400\n{moves}G0 Z5\nM30\n");
    let (l0, l1) = (rough.program.len() as f64, finish.program.len() as f64);
    assert!(l1 > 4.0 * l0, "{l0} {l1}");
    let progress = Last::default();
    let mut at_first = None;
    run_process(
        &process(vec![rough, finish]),
        &CancelFlag::new(),
        &progress,
        &mut |i, _| {
            if i == 0 {
                at_first = Some(*progress.0.lock().unwrap());
            }
        },
    )
    .expect("the process runs");
    let (done, total) = at_first.expect("operation 1 finished");
    let share = done as f64 / total as f64;
    assert!(
        (share - l0 / (l0 + l1)).abs() < 1e-3,
        "{share} vs {}",
        l0 / (l0 + l1)
    );
    let (done, total) = *progress.0.lock().unwrap();
    assert_eq!(done, total, "the whole process is done at its end");
}
