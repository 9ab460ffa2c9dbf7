//! Materials library, tool life (extended Taylor) and kinematic roughness against
//! hand-computed values.

use millsim_engine::physics::{
    builtin_materials, cutting_speed_m_per_min, feed_marks, scallop_height, surface_roughness,
    tool_life, BlockWear, Material, SurfaceKind, TaylorLife,
};
use millsim_engine::tool::{Runout, Tool};

#[test]
fn builtin_library_is_exactly_the_sourced_reference_rows() {
    let all = builtin_materials();
    assert_eq!(all.len(), 3);
    let expect = [
        ("TC6", [1785.0, 461.0, 610.0, 26.0, 43.0, 6.0]),
        ("Al7075-T6", [767.01, 168.8, 222.0, 27.7, 26.6, 0.7]),
        ("Al6082-T6", [631.0, 99.0, 273.0, 13.0, 10.0, 2.8]),
    ];
    for (name, k) in expect {
        let m = Material::builtin(name).unwrap();
        let c = m.coefficients;
        assert_eq!([c.ktc, c.krc, c.kac, c.kte, c.kre, c.kae], k, "{name}");
        assert!(!m.source.is_empty() && m.taylor.is_none());
        assert!(m.validate().is_ok());
    }
    assert!(Material::builtin("al 7075 t6").is_some());
    assert!(Material::builtin("Ti-6Al-4V").is_none());
    // User materials must say where their numbers come from.
    let mut m = Material::builtin("TC6").unwrap();
    m.source = " ".into();
    assert_eq!(m.validate().unwrap_err().field(), "source");
    m.source = "lab test 2024-03".into();
    m.coefficients.kac = f64::NAN;
    assert_eq!(m.validate().unwrap_err().field(), "kac");
    // Serializable both ways.
    let json = serde_json::to_string(&Material::builtin("TC6").unwrap()).unwrap();
    let back: Material = serde_json::from_str(&json).unwrap();
    assert_eq!(back, Material::builtin("TC6").unwrap());
}

#[test]
fn extended_taylor_life_per_block() {
    // v·T^n·h^a = C with C = 400, n = 0.25, a = 0.5: at v = 100 m/min, h = 0.04 mm,
    // T = (400 / (100·0.2))^4 = 20^4 = 160000 min; at h = 0.16: (400/(100·0.4))^4 = 10^4.
    let t = TaylorLife {
        c: 400.0,
        n: 0.25,
        a: 0.5,
        source: "test".into(),
    };
    assert!((t.life_minutes(100.0, 0.04).unwrap() - 160_000.0).abs() < 1e-6);
    assert!((t.life_minutes(100.0, 0.16).unwrap() - 10_000.0).abs() < 1e-6);
    assert_eq!(t.life_minutes(0.0, 0.1), None);
    // Classic Taylor (a = 0): 1 min at v = C.
    let classic = TaylorLife {
        c: 250.0,
        n: 0.3,
        a: 0.0,
        source: String::new(),
    };
    assert!((classic.life_minutes(250.0, 0.0).unwrap() - 1.0).abs() < 1e-12);

    assert!((cutting_speed_m_per_min(10.0, 10_000.0) - 314.159_265_358_979_3).abs() < 1e-9);
    let blocks = [
        BlockWear {
            block: 10,
            cutting_speed: 100.0,
            chip_thickness: 0.04,
            engaged_time: 600.0,
        }, // 10 min of 160000
        BlockWear {
            block: 11,
            cutting_speed: 0.0,
            chip_thickness: 0.0,
            engaged_time: 5.0,
        }, // air
        BlockWear {
            block: 12,
            cutting_speed: 100.0,
            chip_thickness: 0.16,
            engaged_time: 1200.0,
        }, // 20 min of 10000
        BlockWear {
            block: 13,
            cutting_speed: 100.0,
            chip_thickness: 0.16,
            engaged_time: 60.0,
        },
    ];
    let r = tool_life(&t, &blocks, 0.1).unwrap();
    let want = [10.0 / 160_000.0, 0.0, 20.0 / 10_000.0, 1.0 / 10_000.0];
    for (b, w) in r.blocks.iter().zip(want) {
        assert!(
            (b.consumed - w).abs() < 1e-15,
            "block {}: {} vs {w}",
            b.block,
            b.consumed
        );
    }
    assert!((r.consumed - want.iter().sum::<f64>()).abs() < 1e-15);
    assert!((r.remaining - (0.9 - want.iter().sum::<f64>())).abs() < 1e-12);
    assert_eq!(r.most_wearing_block, Some(12));
    assert_eq!(r.worn_out_at_block, None);

    // A tool run past its life says where it wore out.
    let long = [BlockWear {
        block: 1,
        cutting_speed: 100.0,
        chip_thickness: 0.16,
        engaged_time: 6000.0 * 60.0,
    }; 2];
    let r = tool_life(&t, &long, 0.0).unwrap();
    assert_eq!(r.worn_out_at_block, Some(1));
    assert!((r.remaining + 0.2).abs() < 1e-12);

    let bad = [BlockWear {
        block: 3,
        cutting_speed: f64::NAN,
        chip_thickness: 0.1,
        engaged_time: 1.0,
    }];
    assert_eq!(
        tool_life(&t, &bad, 0.0).unwrap_err().field(),
        "blocks[0].cutting_speed"
    );
    let bad_t = TaylorLife {
        n: 1.5,
        ..t.clone()
    };
    assert_eq!(
        tool_life(&bad_t, &blocks, 0.0).unwrap_err().field(),
        "taylor.n"
    );
}

#[test]
fn scallop_heights_by_tool_shape() {
    // Ball R5, step-over 1: 5 − √(25 − 0.25).
    let ball = Tool::ball(10.0, 2);
    assert!((scallop_height(&ball, 1.0).unwrap() - (5.0 - 24.75f64.sqrt())).abs() < 1e-12);
    // Bull-nose D10 R1: flat bottom 8 mm covers step-overs up to 8; at 9 the corners leave
    // w = 0.5 → 1 − √0.75.
    let bull = Tool::bull_nose(10.0, 1.0, 4);
    assert_eq!(scallop_height(&bull, 7.9).unwrap(), 0.0);
    assert!((scallop_height(&bull, 9.0).unwrap() - (1.0 - 0.75f64.sqrt())).abs() < 1e-12);
    assert_eq!(scallop_height(&Tool::flat(10.0, 4), 9.0).unwrap(), 0.0);
    // 45° chamfer with a 2 mm tip flat: w = 1 above the flat, cusp 1 mm high.
    let chamfer = Tool {
        shape: millsim_engine::tool::ToolShape::Chamfer,
        tip_diameter: 2.0,
        taper_half_angle_deg: 45.0,
        ..Tool::flat(10.0, 2)
    };
    assert!((scallop_height(&chamfer, 4.0).unwrap() - 1.0).abs() < 1e-12);
    assert_eq!(
        scallop_height(&ball, 10.5).unwrap_err().field(),
        "step_over"
    );
    assert_eq!(
        scallop_height(&ball, -1.0).unwrap_err().field(),
        "step_over"
    );
}

#[test]
fn feed_marks_with_and_without_runout() {
    // Floor under a bull-nose R1 at fz = 0.1: cusp 1 − √(1 − 0.05²).
    let bull = Tool::bull_nose(10.0, 1.0, 2);
    let m = feed_marks(&bull, 0.1, SurfaceKind::Floor).unwrap();
    let ideal = 1.0 - (1.0 - 0.05f64 * 0.05).sqrt();
    assert!(
        (m.peak_to_valley - ideal).abs() < 0.01 * ideal,
        "{} vs {ideal}",
        m.peak_to_valley
    );
    assert!((m.max_effective_feed - 0.1).abs() < 1e-6);
    assert!(m.ra > 0.0 && m.ra < m.peak_to_valley);
    // Runout 0.02 at tooth 1: marks at 0.02 and 0.1 − 0.02 → gaps 0.06 and 0.14 per revolution;
    // the surface is set by the larger gap.
    let run = Tool {
        runout: Runout {
            offset: 0.02,
            angle_deg: 0.0,
        },
        ..bull.clone()
    };
    let m = feed_marks(&run, 0.1, SurfaceKind::Floor).unwrap();
    let worse = 1.0 - (1.0 - 0.07f64 * 0.07).sqrt();
    assert!(
        (m.max_effective_feed - 0.14).abs() < 1e-3,
        "{}",
        m.max_effective_feed
    );
    assert!(
        (m.peak_to_valley - worse).abs() < 0.01 * worse,
        "{} vs {worse}",
        m.peak_to_valley
    );

    // Wall of a D10 flat at fz = 0.1, 4 teeth: 5 − √(25 − 0.05²). With runout larger than
    // the feed only the longest tooth reaches the wall: marks one revolution (0.4 mm) apart.
    let flat = Tool::flat(10.0, 4);
    let w = feed_marks(&flat, 0.1, SurfaceKind::Wall).unwrap();
    let ideal = 5.0 - (25.0 - 0.0025f64).sqrt();
    assert!(
        (w.peak_to_valley - ideal).abs() < 0.01 * ideal,
        "{} vs {ideal}",
        w.peak_to_valley
    );
    let run = Tool {
        runout: Runout {
            offset: 0.2,
            angle_deg: 0.0,
        },
        ..flat
    };
    let w = feed_marks(&run, 0.1, SurfaceKind::Wall).unwrap();
    assert!(
        (w.max_effective_feed - 0.4).abs() < 1e-3,
        "{}",
        w.max_effective_feed
    );
    let r_long = 5.2;
    assert!((w.peak_to_valley - (r_long - (r_long * r_long - 0.04f64).sqrt())).abs() < 2e-5);

    let r = surface_roughness(&Tool::ball(6.0, 2), 0.3, 0.05).unwrap();
    assert!(r.scallop_height > 0.0 && r.floor_peak_to_valley >= r.scallop_height);
    assert!(surface_roughness(&Tool::ball(6.0, 2), 0.3, f64::NAN).is_err());
}
