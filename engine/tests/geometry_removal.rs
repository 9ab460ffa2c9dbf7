//! Removal bookkeeping: the X and Y dexel families are cut in batches of steps (only the
//! Z family is read between steps), so these check that per-step figures still add up to
//! the block's and that an error part-way leaves every family cut by the blocks before.

use millsim_engine::geometry::{simulate_removal, GeometryError, Segment, SimOptions, Stock};
use millsim_engine::job::CancelFlag;
use millsim_engine::tool::Tool;

/// A zig-zag facing pass at 2 mm depth: 8 long blocks of many steps each.
fn zigzag() -> Vec<Segment> {
    let mut segs = Vec::new();
    for k in 0..8 {
        let y = 2.0 + 3.0 * k as f64;
        let (x0, x1) = if k % 2 == 0 {
            (-4.0, 34.0)
        } else {
            (34.0, -4.0)
        };
        segs.push(Segment::linear(
            k,
            [x0, y, -2.0],
            [x1, y, -2.0],
            900.0,
            9000.0,
        ));
    }
    segs
}

fn stock() -> Stock {
    Stock::block([0.0, 0.0, -6.0], [30.0, 24.0, 0.0], 0.1).unwrap()
}

#[test]
fn step_volumes_add_up_to_the_block_volume() {
    let mut s = stock();
    let before = s.volume();
    let rep = simulate_removal(
        &mut s,
        &Tool::flat(6.0, 3),
        &zigzag(),
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let mut total = 0.0;
    for b in &rep.blocks {
        let steps: f64 = b.steps.iter().map(|st| st.removed_volume).sum();
        assert!(
            (steps - b.removed_volume).abs() <= 1e-9 * b.removed_volume.max(1.0),
            "block {}: steps {steps} vs block {}",
            b.block,
            b.removed_volume
        );
        total += b.removed_volume;
    }
    // Enough steps for several batches, some spanning two blocks.
    let steps: usize = rep.blocks.iter().map(|b| b.steps.len()).sum();
    assert!(steps > 3 * 32, "{steps} steps");
    // The removed volume is what the stock lost, and each family saw about the same.
    assert!((before - s.volume() - total).abs() < 1e-6 * total);
    let v = s.grid.family_volumes();
    for a in 0..3 {
        assert!((v[a] - s.volume()).abs() < 0.005 * s.volume(), "{v:?}");
    }
}

#[test]
fn an_error_part_way_leaves_all_families_cut_by_the_blocks_before_it() {
    let tool = Tool::flat(6.0, 3);
    let good = zigzag();
    // A short last block: its steps are still waiting for the X and Y families when the
    // next segment turns out to be invalid.
    let mut good = good;
    good.push(Segment::linear(
        8,
        [5.0, 20.0, -3.0],
        [6.0, 20.0, -3.0],
        900.0,
        9000.0,
    ));
    let mut done = stock();
    simulate_removal(
        &mut done,
        &tool,
        &good,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let mut bad = good.clone();
    bad.push(Segment::linear(
        99,
        [0.0, 0.0, -2.0],
        [10.0, 0.0, -2.0],
        f64::NAN,
        9000.0,
    ));
    let mut failed = stock();
    let e = simulate_removal(
        &mut failed,
        &tool,
        &bad,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap_err();
    assert!(
        matches!(e, GeometryError::InvalidSegment { index: 9, .. }),
        "{e}"
    );
    assert_eq!(failed.grid.family_volumes(), done.grid.family_volumes());
}
