//! Engagement against analytic values: a flat end mill along a straight edge at radial
//! width ae enters/exits at arccos(1 − 2·ae/D) (up milling) or π − that (down milling),
//! within one angular bin; the axial depth is exact to the grid.

use std::f64::consts::PI;

use millsim_engine::geometry::{simulate_removal, Segment, SimOptions, Stock};
use millsim_engine::job::CancelFlag;
use millsim_engine::tool::Tool;

const H: f64 = 0.1;

fn run(stock_y: (f64, f64), ae: f64, ap: f64) -> millsim_engine::geometry::BlockGeometry {
    let d = 10.0;
    let tool = Tool::flat(d, 4);
    let mut stock = Stock::block([0.0, stock_y.0, -10.0], [60.0, stock_y.1, 0.0], H).unwrap();
    // The tool runs along +x at y = 0, entering the stock from outside (x < 0).
    let segs = [Segment::linear(
        7,
        [-10.0, 0.0, -ap],
        [50.0, 0.0, -ap],
        1000.0,
        10000.0,
    )];
    let rep = simulate_removal(
        &mut stock,
        &tool,
        &segs,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let b = rep.blocks.into_iter().next().unwrap();
    assert_eq!(b.block, 7);
    let _ = ae;
    b
}

fn bin() -> f64 {
    2.0 * PI / SimOptions::default().engagement.angular_bins as f64
}

/// Steps in the steady part of the cut (tool fully inside the stock along x).
fn steady(
    b: &millsim_engine::geometry::BlockGeometry,
) -> Vec<&millsim_engine::geometry::StepGeometry> {
    b.steps
        .iter()
        .filter(|s| s.position[0] > 10.0 && s.position[0] < 45.0)
        .collect()
}

#[test]
fn down_milling_straight_edge() {
    for ae in [1.0, 2.5, 5.0, 8.0] {
        // Material on the −y side up to y = −R + ae: with the spindle clockwise the edge
        // exits there (φ = π) — down milling.
        let b = run((-20.0, -5.0 + ae), ae, 2.0);
        let want_entry = PI - (1.0 - 2.0 * ae / 10.0).acos();
        let st = steady(&b);
        assert!(st.len() > 10);
        for s in st {
            assert!(!s.air);
            let m = s.metrics;
            assert!(
                (m.entry_angle - want_entry).abs() <= bin(),
                "ae {ae}: entry {} want {want_entry}",
                m.entry_angle
            );
            assert!(
                (m.exit_angle - PI).abs() <= bin(),
                "ae {ae}: exit {}",
                m.exit_angle
            );
            assert!(
                (m.axial_depth - 2.0).abs() <= H + 1e-9,
                "axial depth {}",
                m.axial_depth
            );
            assert!(
                (m.radial_width - ae).abs() <= 0.02 * 10.0 + H,
                "ae {ae}: radial width {}",
                m.radial_width
            );
            // Every slice of the flank sees the same arcs.
            for sl in &s.engagement.unpack().slices {
                assert_eq!(sl.arcs.len(), 1);
            }
        }
        println!(
            "down milling ae={ae}: entry want {:.2}°, got {:.2}°",
            want_entry.to_degrees(),
            steady(&b)[5].metrics.entry_angle.to_degrees()
        );
    }
}

#[test]
fn up_milling_straight_edge() {
    for ae in [1.0, 2.5, 5.0] {
        let b = run((5.0 - ae, 20.0), ae, 3.0);
        let want_exit = (1.0 - 2.0 * ae / 10.0).acos();
        for s in steady(&b) {
            let m = s.metrics;
            assert!(
                m.entry_angle.abs() <= bin(),
                "ae {ae}: entry {}",
                m.entry_angle
            );
            assert!(
                (m.exit_angle - want_exit).abs() <= bin(),
                "ae {ae}: exit {} want {want_exit}",
                m.exit_angle
            );
            assert!((m.axial_depth - 3.0).abs() <= H + 1e-9);
        }
        println!(
            "up milling ae={ae}: exit want {:.2}°, got {:.2}°",
            want_exit.to_degrees(),
            steady(&b)[5].metrics.exit_angle.to_degrees()
        );
    }
}

#[test]
fn slot_is_half_immersion_both_sides_and_air_is_marked() {
    let tool = Tool::flat(6.0, 2);
    let mut stock = Stock::block([0.0, -10.0, -10.0], [30.0, 10.0, 0.0], H).unwrap();
    let segs = [
        // In air above the stock.
        Segment::linear(1, [-5.0, 0.0, 2.0], [35.0, 0.0, 2.0], 600.0, 6000.0),
        // Full slot 1.5 mm deep.
        Segment::linear(2, [-5.0, 0.0, -1.5], [35.0, 0.0, -1.5], 600.0, 6000.0),
    ];
    let rep = simulate_removal(
        &mut stock,
        &tool,
        &segs,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let air = &rep.blocks[0];
    assert!(air.steps.iter().all(|s| s.air));
    assert!((air.air_fraction - 1.0).abs() < 1e-12);
    assert_eq!(air.removed_volume, 0.0);
    let slot = &rep.blocks[1];
    assert!(
        slot.air_fraction > 0.0 && slot.air_fraction < 0.5,
        "entering from outside: {}",
        slot.air_fraction
    );
    for s in slot
        .steps
        .iter()
        .filter(|s| s.position[0] > 5.0 && s.position[0] < 28.0)
    {
        assert!(s.metrics.entry_angle <= bin() && (s.metrics.exit_angle - PI).abs() <= bin());
        assert!((s.metrics.radial_width - 6.0).abs() < 0.05);
        assert!((s.metrics.axial_depth - 1.5).abs() <= H + 1e-9);
        // Engaged edge length of a flat flank = axial depth (κ = 90°).
        assert!((s.metrics.engaged_edge_length - s.metrics.axial_depth).abs() < 1e-9);
        // MRR of a slot = ap · D · feed.
        assert!(
            (s.mrr - 1.5 * 6.0 * 600.0).abs() < 0.03 * 1.5 * 6.0 * 600.0,
            "mrr {}",
            s.mrr
        );
    }
    // The steps cover the block: lengths add up to the path length.
    let total: f64 = slot.steps.iter().map(|s| s.length).sum();
    assert!((total - 40.0).abs() < 1e-9);
}

#[test]
fn steps_follow_feed_per_tooth_on_short_blocks_and_adapt_on_long_ones() {
    let tool = Tool::flat(6.0, 2);
    let mut stock = Stock::block([0.0, -10.0, -10.0], [200.0, 10.0, 0.0], H).unwrap();
    // fz = 1200 / (6000·2) = 0.1 mm: a 3 mm block gets 30 steps.
    let short = Segment::linear(1, [1.0, 0.0, -1.0], [4.0, 0.0, -1.0], 1200.0, 6000.0);
    // A 190 mm steady slot: far fewer steps than 1900.
    let long = Segment::linear(2, [4.0, 0.0, -1.0], [194.0, 0.0, -1.0], 1200.0, 6000.0);
    let rep = simulate_removal(
        &mut stock,
        &tool,
        &[short, long],
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    assert_eq!(rep.blocks[0].steps.len(), 30);
    let n = rep.blocks[1].steps.len();
    assert!(n < 300 && n > 10, "{n} steps");
    let max_step = rep.blocks[1]
        .steps
        .iter()
        .map(|s| s.length)
        .fold(0.0, f64::max);
    assert!(max_step <= 16.0 * 0.1 + 1e-9);
}

#[test]
fn ball_slot_engages_the_front_half_over_the_depth() {
    // D10 ball, 2 mm deep slot: every slice up to 2 mm engaged on [0, π]; radial width
    // 2·√(R² − (R − a)²) = 8 mm; edge in contact = the profile arc R·acos((R − a)/R).
    let (d, a) = (10.0, 2.0);
    let r = d / 2.0;
    let tool = Tool::ball(d, 2);
    let mut stock = Stock::block([0.0, -10.0, -10.0], [60.0, 10.0, 0.0], H).unwrap();
    let segs = [Segment::linear(
        1,
        [-10.0, 0.0, -a],
        [50.0, 0.0, -a],
        1000.0,
        10000.0,
    )];
    let rep = simulate_removal(
        &mut stock,
        &tool,
        &segs,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let want_edge = r * ((r - a) / r).acos();
    let st = steady(&rep.blocks[0]);
    assert!(st.len() > 10);
    for s in st {
        let m = s.metrics;
        assert!(
            (m.axial_depth - a).abs() <= H + 1e-9,
            "axial depth {}",
            m.axial_depth
        );
        assert!(
            m.entry_angle <= bin() && (m.exit_angle - PI).abs() <= bin(),
            "{m:?}"
        );
        assert!(
            (m.radial_width - 8.0).abs() < 0.1,
            "radial width {}",
            m.radial_width
        );
        assert!(
            ((m.engaged_edge_length - want_edge) / want_edge).abs() < 0.03,
            "edge {} want {want_edge}",
            m.engaged_edge_length
        );
        // Each slice's arc is the front half.
        for sl in &s.engagement.unpack().slices {
            assert_eq!(sl.arcs.len(), 1, "{sl:?}");
            assert!(
                sl.arcs[0].0 <= bin() && (sl.arcs[0].1 - PI).abs() <= bin(),
                "{sl:?}"
            );
        }
    }
}
