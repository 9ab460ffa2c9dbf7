//! Collision checks, each reported on the block where it happens.

use std::sync::Arc;

use millsim_engine::geometry::{simulate_removal, Segment, SimOptions, Stock};
use millsim_engine::job::CancelFlag;
use millsim_engine::tool::{HolderSegment, Tool};

const H: f64 = 0.1;

fn sim(
    stock: &mut Stock,
    tool: &Tool,
    segs: &[Segment],
    opts: &SimOptions,
) -> Vec<millsim_engine::geometry::CheckFlags> {
    simulate_removal(stock, tool, segs, opts, &CancelFlag::new())
        .unwrap()
        .blocks
        .iter()
        .map(|b| b.checks)
        .collect()
}

#[test]
fn rapid_through_the_stock_is_reported_on_its_block() {
    let tool = Tool::flat(6.0, 3);
    let mut stock = Stock::block([0.0, 0.0, -10.0], [40.0, 40.0, 0.0], H).unwrap();
    let segs = [
        Segment::rapid(10, [-10.0, 20.0, 5.0], [50.0, 20.0, 5.0]), // above: fine
        Segment::linear(11, [-5.0, 10.0, -2.0], [45.0, 10.0, -2.0], 800.0, 8000.0), // cut
        Segment::rapid(12, [45.0, 10.0, -2.0], [45.0, 30.0, -2.0]), // beside the stock: fine
        Segment::rapid(13, [45.0, 30.0, -2.0], [-5.0, 30.0, -2.0]), // through the stock
        Segment::rapid(14, [-5.0, 30.0, -2.0], [-5.0, 30.0, 5.0]),
    ];
    let rep = simulate_removal(
        &mut stock,
        &tool,
        &segs,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let flagged: Vec<usize> = rep
        .blocks
        .iter()
        .filter(|b| b.checks.rapid_in_material)
        .map(|b| b.block)
        .collect();
    assert_eq!(flagged, vec![13]);
    assert!(rep.blocks[3].removed_volume > 0.0);
    // A rapid reports no engagement (no force model applies); its steps that removed
    // material are not air.
    assert!(rep.blocks[3]
        .steps
        .iter()
        .all(|s| s.engagement.unpack().slices.is_empty()));
    assert!(rep.blocks[3].air_fraction < 1.0);
    assert_eq!(rep.blocks[0].air_fraction, 1.0);
}

#[test]
fn holder_hitting_a_wall_is_reported_on_its_block() {
    // Flutes 40 mm, holder face 40 mm above the tip, holder Ø40.
    let mut tool = Tool::flat(10.0, 4);
    tool.flute_length = 40.0;
    tool.stick_out = Some(40.0);
    tool.holder = vec![HolderSegment {
        length: 30.0,
        bottom_diameter: 40.0,
        top_diameter: 40.0,
    }];
    let mut stock = Stock::block([0.0, -20.0, -60.0], [60.0, 20.0, 0.0], H).unwrap();
    let segs = [
        // A shallow cut in the middle: the holder is 38 mm above the top.
        Segment::linear(1, [-10.0, 0.0, -2.0], [70.0, 0.0, -2.0], 800.0, 8000.0),
        Segment::rapid(2, [70.0, 0.0, -2.0], [70.0, 28.0, 10.0]),
        // Down beside the stock, 3 mm clear of its side wall (y = 20): the tool cuts air
        // but the Ø40 holder, 40 mm above the tip at z = −45, overlaps the wall.
        Segment::linear(3, [70.0, 28.0, 10.0], [30.0, 28.0, -45.0], 800.0, 8000.0),
        Segment::linear(4, [30.0, 28.0, -45.0], [30.0, 28.0, 10.0], 800.0, 8000.0),
        Segment::rapid(5, [30.0, 28.0, 10.0], [30.0, 60.0, 10.0]),
    ];
    let flags = sim(&mut stock, &tool, &segs, &SimOptions::default());
    let hit: Vec<usize> = flags
        .iter()
        .enumerate()
        .filter(|(_, f)| f.holder_contact)
        .map(|(i, _)| i + 1)
        .collect();
    assert_eq!(hit, vec![3, 4]);
    assert!(flags
        .iter()
        .all(|f| !f.flute_length_exceeded && !f.rapid_in_material && !f.shank_contact));
}

#[test]
fn cutting_deeper_than_the_flutes_is_reported_on_its_block() {
    let mut tool = Tool::flat(6.0, 3);
    tool.flute_length = 5.0;
    tool.stick_out = Some(25.0);
    let mut stock = Stock::block([0.0, -20.0, -20.0], [40.0, 20.0, 0.0], H).unwrap();
    let segs = [
        Segment::linear(1, [-5.0, -10.0, -4.0], [45.0, -10.0, -4.0], 800.0, 8000.0), // 4 mm: fine
        Segment::linear(2, [-5.0, 0.0, -8.0], [45.0, 0.0, -8.0], 800.0, 8000.0), // 8 mm: too deep
        Segment::linear(3, [-5.0, 10.0, -3.0], [45.0, 10.0, -3.0], 800.0, 8000.0), // fine again
    ];
    let flags = sim(&mut stock, &tool, &segs, &SimOptions::default());
    let deep: Vec<usize> = flags
        .iter()
        .enumerate()
        .filter(|(_, f)| f.flute_length_exceeded)
        .map(|(i, _)| i + 1)
        .collect();
    assert_eq!(deep, vec![2]);
    assert!(flags.iter().all(|f| !f.holder_contact && !f.shank_contact));
}

#[test]
fn wide_shank_touching_the_stock_is_reported() {
    // Ø4 cutter on a Ø8 shank: a 6 mm deep slot with 5 mm flutes rubs the shank.
    let mut tool = Tool::flat(4.0, 2);
    tool.flute_length = 5.0;
    tool.shank_diameter = Some(8.0);
    tool.stick_out = Some(30.0);
    let mut stock = Stock::block([0.0, -20.0, -20.0], [40.0, 20.0, 0.0], H).unwrap();
    let segs = [
        Segment::linear(1, [-5.0, -10.0, -4.0], [45.0, -10.0, -4.0], 800.0, 8000.0),
        Segment::linear(2, [-5.0, 10.0, -6.0], [45.0, 10.0, -6.0], 800.0, 8000.0),
    ];
    let flags = sim(&mut stock, &tool, &segs, &SimOptions::default());
    assert!(!flags[0].shank_contact && !flags[0].flute_length_exceeded);
    assert!(flags[1].shank_contact && flags[1].flute_length_exceeded);
}

#[test]
fn tool_touching_the_fixture_is_reported() {
    let tool = Tool::flat(6.0, 3);
    let mut stock = Stock::block([0.0, -20.0, -10.0], [40.0, 20.0, 0.0], H).unwrap();
    // A clamp on the stock's top near x = 30..35, y = 10..20.
    let clamp = Stock::block([30.0, 10.0, 0.0], [35.0, 20.0, 8.0], H).unwrap();
    let opts = SimOptions {
        fixture: Some(Arc::new(clamp)),
        ..Default::default()
    };
    let segs = [
        Segment::linear(1, [-5.0, 0.0, -1.0], [45.0, 0.0, -1.0], 800.0, 8000.0),
        Segment::linear(2, [-5.0, 12.0, -1.0], [45.0, 12.0, -1.0], 800.0, 8000.0),
    ];
    let flags = sim(&mut stock, &tool, &segs, &opts);
    assert!(!flags[0].fixture_contact);
    assert!(flags[1].fixture_contact);
}

#[test]
fn bad_input_and_cancellation_are_clear_errors() {
    use millsim_engine::geometry::GeometryError;
    let tool = Tool::flat(6.0, 3);
    let mut stock = Stock::block([0.0, 0.0, -10.0], [40.0, 40.0, 0.0], 0.5).unwrap();
    let good = Segment::linear(3, [0.0, 0.0, 1.0], [10.0, 0.0, 1.0], 800.0, 8000.0);
    let bad = Segment::linear(4, [0.0, f64::NAN, 1.0], [10.0, 0.0, 1.0], 800.0, 8000.0);
    let e = simulate_removal(
        &mut stock,
        &tool,
        &[good.clone(), bad],
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            GeometryError::InvalidSegment {
                index: 1,
                block: 4,
                ..
            }
        ),
        "{e}"
    );
    let tilted = good.clone().with_axes([0.0, 0.0, 2.0], [0.0, 0.0, 1.0]);
    let e = simulate_removal(
        &mut stock,
        &tool,
        &[tilted],
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("unit vector"), "{e}");
    let mut broken = tool.clone();
    broken.flutes = 0;
    let e = simulate_removal(
        &mut stock,
        &broken,
        &[good.clone()],
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap_err();
    assert!(matches!(e, GeometryError::Tool(_)), "{e}");
    let cancel = CancelFlag::new();
    cancel.cancel();
    let e =
        simulate_removal(&mut stock, &tool, &[good], &SimOptions::default(), &cancel).unwrap_err();
    assert!(
        matches!(e, GeometryError::Cancelled { done: 0, total: 1 }),
        "{e}"
    );
    // Parametric stock errors name what is wrong.
    let e = Stock::block([0.0, 0.0, 0.0], [10.0, 0.0, 5.0], 0.1).unwrap_err();
    assert!(e.to_string().contains("empty along y"), "{e}");
}
