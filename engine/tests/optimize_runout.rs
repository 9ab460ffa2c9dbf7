//! Feed scheduling where the quantities are not homogeneous in the feed: a ball end mill with
//! radial runout (the chip is the thinnest of several surfaces, piecewise affine), and per-rev
//! (G95) blocks.

use std::borrow::Cow;
use std::f64::consts::PI;

use millsim_engine::engagement::{EngagedSlice, Engagement};
use millsim_engine::nc::{interpret, InterpretOptions, Program};
use millsim_engine::optimize::{
    optimize_feeds, rewrite_program, verify_rewrite, Cutter, EngagementStep, FeedLimits, FeedScale,
    Governing, MoveEngagement, RewriteOptions,
};
use millsim_engine::physics::{CuttingConditions, ForceModel, Material};
use millsim_engine::tool::{Runout, Tool};

const RPM: f64 = 10_000.0;

fn tool() -> Tool {
    let mut t = Tool::ball(10.0, 2);
    t.runout = Runout {
        offset: 0.01,
        angle_deg: 30.0,
    };
    t
}

fn engagement(depth: f64, st: f64, ex: f64) -> Engagement {
    Engagement {
        slices: (0..(depth / 0.2).round() as usize)
            .map(|i| EngagedSlice {
                z: 0.1 + 0.2 * i as f64,
                dz: 0.2,
                arcs: vec![(st, ex)].into(),
            })
            .collect(),
        feed_dir: [1.0, 0.0, 0.0],
        tool_axis: [0.0, 0.0, 1.0],
        end: Vec::new(),
    }
}

fn result_at(e: &Engagement, v: f64) -> millsim_engine::physics::ForceResult {
    let k = Material::builtin("TC6").unwrap().coefficients;
    ForceModel::new(&tool(), 150, 360)
        .unwrap()
        .evaluate(
            e,
            &k,
            &CuttingConditions {
                spindle_rpm: RPM,
                feed_per_tooth: v / (2.0 * RPM),
            },
        )
        .unwrap()
}

fn setup(
    src: &str,
    es: &[Engagement],
) -> (
    Vec<millsim_engine::nc::Move>,
    Vec<MoveEngagement<'static>>,
    Vec<Cutter>,
) {
    let mv = interpret(src, &InterpretOptions::default()).unwrap().moves;
    let k = Material::builtin("TC6").unwrap().coefficients;
    let cutters = vec![Cutter::new(&tool(), k, 150, 360).unwrap()];
    let feed_moves: Vec<usize> = (0..mv.len())
        .filter(|&i| mv[i].kind != millsim_engine::nc::MoveKind::Rapid)
        .collect();
    let segs = feed_moves
        .iter()
        .zip(es)
        .map(|(&i, e)| MoveEngagement {
            removes_material: false,
            plunge: false,
            move_index: i,
            cutter: 0,
            scale: FeedScale::UNIT,
            steps: vec![EngagementStep {
                engagement: Cow::Owned(e.clone().into()),
                spindle_rpm: RPM,
                tip_ratio: 1.0,
                at: 0.0,
                response: None,
            }],
        })
        .collect();
    (mv, segs, cutters)
}

#[test]
fn ball_with_runout_meets_force_target_and_rubbing_floor() {
    let es = [
        engagement(3.0, 0.0, PI),
        engagement(3.0, PI / 2.0, PI),
        engagement(1.0, PI - 0.6435, PI),
    ];
    let (mv, segs, cutters) = setup("G21 G90 G94 S10000 M3\nG0 Z1\nG1 X10 F500\nX20\nX30\n", &es);
    let target = 600.0;
    let limits = FeedLimits {
        max_force: Some(target),
        max_feed: 20_000.0,
        ..Default::default()
    };
    let s = optimize_feeds(&mv, &segs, &cutters, &limits).unwrap();
    for (sf, e) in s.moves.iter().zip(&es) {
        let f = result_at(e, sf.feed).force.peak;
        assert!(
            (0.99 * target..=target).contains(&f),
            "feed {} gives {f} N ({:?})",
            sf.feed,
            sf.governing
        );
        println!(
            "ball+runout: {:.1} mm/min, {f:.2} N, {} evaluations",
            sf.feed, sf.evaluations
        );
    }
    // Rubbing floor through the secant path (runout: the chip is not proportional to the feed).
    let hmin = 0.02;
    let limits = FeedLimits {
        min_chip_thickness: Some(hmin),
        entry_feed_factor: 0.05,
        ..limits
    };
    let s = optimize_feeds(&mv, &segs, &cutters, &limits).unwrap();
    let first = &s.moves[0];
    assert!(first.entry);
    assert_eq!(first.governing, Governing::RubbingFloor);
    let h = result_at(&es[0], first.feed).max_chip_thickness;
    assert!(h >= hmin * (1.0 - 1e-9) && h <= hmin * 1.01, "{h}");
}

#[test]
fn per_rev_blocks_are_written_in_mm_per_rev() {
    let es = [engagement(3.0, PI / 2.0, PI), engagement(3.0, PI / 2.0, PI)];
    let src = "G21 G90 S10000 M3\nG0 Z1\nG95 G1 X10 F0.01\nX20\n";
    let (mv, segs, cutters) = setup(src, &es);
    let limits = FeedLimits {
        max_force: Some(600.0),
        max_feed: 20_000.0,
        ..Default::default()
    };
    let s = optimize_feeds(&mv, &segs, &cutters, &limits).unwrap();
    let rw = rewrite_program(
        &Program::parse(src).unwrap(),
        &mv,
        &s,
        &RewriteOptions {
            feed_step: Some(1.0),
        },
    )
    .unwrap();
    // Block 2 has F: changed in place; block 3 inherits it, same engagement, so it either
    // gets its own F or (when equal after rounding) none.
    let c = rw.changes.iter().find(|c| c.block == 2).unwrap();
    let want = s.moves[0].feed / RPM;
    assert!(
        c.written <= want && c.written > want - 1e-4,
        "{} vs {want}",
        c.written
    );
    let mv2 = interpret(&rw.text, &InterpretOptions::default())
        .unwrap()
        .moves;
    verify_rewrite(&mv, &mv2, &rw).unwrap();
    for (m, sf) in mv2.iter().filter(|m| m.line >= 3).zip(&s.moves) {
        let f = result_at(&es[0], m.feed * RPM).force.peak;
        assert!(f <= 600.0 && m.feed * RPM <= sf.feed);
    }
}
