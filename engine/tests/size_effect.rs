//! The size effect (Kienzle's K(h) = K·h^(−m)) beyond the force model's own test: the
//! stability models' linearization, and feed optimization converging on a size-effect
//! material (issue 30).

mod common;

use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::optimize::FeedLimits;
use millsim_engine::physics::{CuttingCoefficients, Material};
use millsim_engine::pipeline::simulate;
use millsim_engine::tool::Tool;

/// Al7075-like coefficients at a 0.1 mm chip, with exponents: K = K(0.1)·0.1^m.
fn sized() -> CuttingCoefficients {
    let (mtc, mrc, mac) = (0.25, 0.35, 0.2);
    CuttingCoefficients {
        mtc,
        mrc,
        mac,
        ..CuttingCoefficients::linear([
            767.01 * 0.1f64.powf(mtc),
            168.8 * 0.1f64.powf(mrc),
            222.0 * 0.1f64.powf(mac),
            27.7,
            26.6,
            0.7,
        ])
    }
}

#[test]
fn the_stability_coefficients_are_the_force_laws_tangent_at_the_chip() {
    let k = sized();
    for h in [0.01, 0.05, 0.2] {
        let (kt, kr) = k.linearized_at(h);
        let d = 1e-7;
        let law = |kk: f64, m: f64, h: f64| kk * h.powf(1.0 - m);
        let nt = (law(k.ktc, k.mtc, h + d) - law(k.ktc, k.mtc, h - d)) / (2.0 * d);
        let nr = (law(k.krc, k.mrc, h + d) - law(k.krc, k.mrc, h - d)) / (2.0 * d);
        assert!((kt - nt).abs() < 1e-5 * nt, "{h}: {kt} vs {nt}");
        assert!((kr - nr).abs() < 1e-5 * nr, "{h}: {kr} vs {nr}");
    }
    // Without exponents: the coefficients themselves.
    let lin = Material::builtin("Al7075-T6").unwrap().coefficients;
    assert_eq!(lin.linearized_at(0.05), (lin.ktc, lin.krc));
}

#[test]
fn optimizing_on_a_size_effect_material_lands_on_the_force_limit() {
    // A 3 mm deep, 4 mm wide side cut of a Ø12 end mill; the limit is below its force at
    // the programmed F2400 (0.075 mm a tooth), so the feed is solved, and the optimized program re-simulated
    // must sit at the limit.
    let program = "G21 G90\nS8000 M3\nG0 X-10 Y8 Z5\nG0 Z-3\nG1 X90 F2400\nG0 Z5\nM30\n";
    let tool = Tool {
        flute_length: 30.0,
        ..Tool::flat(12.0, 4)
    };
    let mut spec = common::simulate::block_spec(program, tool, 0.25);
    spec.material.coefficients = sized();
    let plain = simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    let before = plain.rows.iter().find(|r| r.line == 5).unwrap().peak_force;
    let limit = 0.8 * before;
    spec.optimize = Some(FeedLimits {
        max_force: Some(limit),
        max_feed: 5000.0,
        ..FeedLimits::default()
    });
    let out = simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    let row = out.rows.iter().find(|r| r.line == 5).unwrap();
    let f = row.feed_after_mm_min.unwrap();
    // The force falls more slowly than the feed (A·f^(1−m) + E): a 20% lower force needs a
    // feed more than 20% lower.
    assert!(f < 0.8 * 2400.0, "F{f}");
    spec.program = out.optimized_program.clone().unwrap();
    spec.optimize = None;
    let re = simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    let peak = re.rows.iter().find(|r| r.line == 5).unwrap().peak_force;
    eprintln!("size effect: F2400 peak {before:.1} N; limit {limit:.1} N at F{f:.1}; re-simulated {peak:.1} N");
    assert!(
        peak <= limit * 1.005 && peak >= limit * 0.97,
        "{peak} vs {limit}"
    );
}
