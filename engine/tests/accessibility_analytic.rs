//! Accessibility against closed forms: drilled holes whose largest tool and axis are known
//! from their definition (the polygonal hole of n sides has the inscribed radius
//! R·cos(π/n)).

mod parts;

use millsim_engine::accessibility::{analyze, angle_deg, AccessError, AccessRequest};
use millsim_engine::geometry::Mesh;
use millsim_engine::job::CancelFlag;
use millsim_engine::tool::{HolderSegment, Tool};
use parts::{drilled_block, hole_frame, HolePiece};

const SIDES: usize = 256;

fn tilted(deg: f64) -> [f64; 3] {
    let a = deg.to_radians();
    [a.sin(), 0.0, a.cos()]
}

fn down(top: [f64; 3], d: [f64; 3], lambda: f64) -> [f64; 3] {
    std::array::from_fn(|k| top[k] - lambda * d[k])
}

fn apothem(r: f64) -> f64 {
    r * (std::f64::consts::PI / SIDES as f64).cos()
}

/// A 60 × 40 × 60 block with a hole along `d` from `top`: Ø30 for 20 mm, then Ø16 through.
fn stepped_hole(d: [f64; 3], top: [f64; 3]) -> Mesh {
    let pieces = [
        HolePiece {
            radius: 15.0,
            offset: [0.0, 0.0],
            until: 20.0,
        },
        HolePiece {
            radius: 8.0,
            offset: [0.0, 0.0],
            until: 0.0,
        },
    ];
    drilled_block(60.0, 40.0, 60.0, d, top, &pieces, SIDES)
}

#[test]
fn a_hole_drilled_25_degrees_off_z_gives_its_axis_and_diameter() {
    let d = tilted(25.0);
    let top = [0.0, 0.0, 60.0];
    let piece = HolePiece {
        radius: 10.0,
        offset: [0.0, 0.0],
        until: 0.0,
    };
    let mesh = drilled_block(60.0, 40.0, 60.0, d, top, &[piece], SIDES);
    // Entry 3 mm off the hole's axis on the top face: the cone's centre is 4° off the hole.
    let entry = [3.0, 0.0, 60.0];
    let target = down(top, d, 40.0);
    let mut request = AccessRequest::new(entry, target);
    request.allowance = 0.5;
    let report = analyze(&mesh, &request, &CancelFlag::new()).unwrap();
    let r = report.target();
    let off = angle_deg(r.axis, d);
    assert!(off < 0.5, "axis {:?} is {off}° off the hole's", r.axis);
    let expected = 2.0 * apothem(10.0) - 2.0 * 0.5;
    assert!(
        (r.tool_diameter_mm - expected).abs() / 20.0 < 0.005,
        "diameter {} vs {expected}",
        r.tool_diameter_mm
    );
    // In fact far better than 0.5 %: the exact fit is refined.
    assert!(
        (r.tool_diameter_mm - expected).abs() < 0.02,
        "{}",
        r.tool_diameter_mm
    );
    let c = r.center.unwrap();
    let on_axis = down(top, d, 40.0);
    let miss = (0..3)
        .map(|k| (c[k] - on_axis[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(miss < 0.1, "centre {c:?}");
    // The free region is the hole's disk: π·(R − 0)² to the raster.
    let disk = std::f64::consts::PI * 100.0;
    assert!(
        (r.free_area_mm2 - disk).abs() / disk < 0.02,
        "{}",
        r.free_area_mm2
    );
    // Depth along the axis below the entry (3 mm off the hole's axis on the tilted top).
    let reach: f64 = (0..3).map(|k| (entry[k] - target[k]) * d[k]).sum();
    assert!(
        (r.reach_mm - reach).abs() < 0.01,
        "{} vs {reach}",
        r.reach_mm
    );
    assert!(!r.open);
}

#[test]
fn a_stepped_hole_reached_past_its_step_gives_the_small_diameter_and_the_holder_counts() {
    let d = tilted(10.0);
    let top = [0.0, 0.0, 60.0];
    let mesh = stepped_hole(d, top);
    let target = down(top, d, 28.0);
    let request = AccessRequest::new(top, target);
    let report = analyze(&mesh, &request, &CancelFlag::new()).unwrap();
    let r = report.target();
    let expected = 2.0 * apothem(8.0);
    assert!(
        (r.tool_diameter_mm - expected).abs() / 16.0 < 0.005,
        "{} vs {expected}",
        r.tool_diameter_mm
    );
    assert!(angle_deg(r.axis, d) < 0.5, "{:?}", r.axis);

    // A Ø24 holder 12 mm above the tip passes inside the Ø30 bore: still 16.
    let holder = |dia: f64| {
        vec![HolderSegment {
            length: 40.0,
            bottom_diameter: dia,
            top_diameter: dia,
        }]
    };
    let mut request = AccessRequest::new(top, target);
    request.stickout = Some(12.0);
    request.holder = holder(24.0);
    let r = analyze(&mesh, &request, &CancelFlag::new())
        .unwrap()
        .target()
        .clone();
    assert!(
        (r.tool_diameter_mm - expected).abs() / 16.0 < 0.005,
        "{}",
        r.tool_diameter_mm
    );
    // A Ø32 holder there does not: no tool reaches (a clear answer, not an error).
    request.holder = holder(32.0);
    let r = analyze(&mesh, &request, &CancelFlag::new())
        .unwrap()
        .target()
        .clone();
    assert_eq!(r.tool_diameter_mm, 0.0);
    assert!(r.center.is_none());
    // With 35 mm out of the holder it stays above the block: the top face, tilted 10° to
    // the axis, rises from 28 mm above the section at the axis to 35 mm only 39.7 mm to the
    // side (7/tan 10°), far outside the holder's 12 mm. (At 30 mm it would meet the face
    // 11.3 mm to the side, inside the holder's radius: less than 16 would fit.)
    request.stickout = Some(35.0);
    let r = analyze(&mesh, &request, &CancelFlag::new())
        .unwrap()
        .target()
        .clone();
    assert!(
        (r.tool_diameter_mm - expected).abs() / 16.0 < 0.005,
        "{}",
        r.tool_diameter_mm
    );
}

#[test]
fn a_side_pocket_below_a_lip_is_reached_with_the_lips_clearance() {
    let d = tilted(0.0);
    let top = [0.0, 0.0, 60.0];
    let (e1, _) = hole_frame(d);
    let pieces = [
        HolePiece {
            radius: 15.0,
            offset: [0.0, 0.0],
            until: 15.0,
        },
        // The lip: Ø16 over 5 mm.
        HolePiece {
            radius: 8.0,
            offset: [0.0, 0.0],
            until: 20.0,
        },
        // The pocket: Ø40, 8 mm to the side.
        HolePiece {
            radius: 20.0,
            offset: [8.0, 0.0],
            until: 35.0,
        },
        HolePiece {
            radius: 8.0,
            offset: [0.0, 0.0],
            until: 0.0,
        },
    ];
    let mesh = drilled_block(60.0, 40.0, 60.0, d, top, &pieces, SIDES);
    // Into the pocket, 6 mm to its side, 10 mm below the lip.
    let target: [f64; 3] = std::array::from_fn(|k| top[k] - 30.0 * d[k] + 6.0 * e1[k]);
    let request = AccessRequest::new(top, target);
    let report = analyze(&mesh, &request, &CancelFlag::new()).unwrap();
    let r = report.target();
    let expected = 2.0 * apothem(8.0);
    assert!(
        (r.tool_diameter_mm - expected).abs() / 16.0 < 0.005,
        "{} vs {expected}",
        r.tool_diameter_mm
    );
    // Without the lip the pocket's own Ø40 would be the answer: the lip is what limits it.
    assert!(r.tool_diameter_mm < 17.0);
}

#[test]
fn a_target_in_the_material_is_reached_by_no_tool_and_bad_points_are_named() {
    let d = tilted(25.0);
    let top = [0.0, 0.0, 60.0];
    let piece = HolePiece {
        radius: 10.0,
        offset: [0.0, 0.0],
        until: 0.0,
    };
    let mesh = drilled_block(60.0, 40.0, 60.0, d, top, &[piece], 64);
    let request = AccessRequest::new(top, [40.0, 20.0, 30.0]);
    let r = analyze(&mesh, &request, &CancelFlag::new()).unwrap();
    assert_eq!(r.target().tool_diameter_mm, 0.0);
    assert_eq!(r.target().free_area_mm2, 0.0);

    let outside = AccessRequest::new(top, [0.0, 0.0, 80.0]);
    match analyze(&mesh, &outside, &CancelFlag::new()) {
        Err(AccessError::Invalid { field, message }) => {
            assert_eq!(field, "target");
            assert!(message.contains("outside the part's bounds"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    let mut bad = AccessRequest::new(top, down(top, d, 20.0));
    bad.tools = vec![Tool::flat(-3.0, 2)];
    match analyze(&mesh, &bad, &CancelFlag::new()) {
        Err(AccessError::Invalid { field, .. }) => assert_eq!(field, "tools[0].diameter_mm"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn segments_and_the_tool_list_pick_the_largest_tool_that_fits_each_depth() {
    // The stepped hole straight down: the upper segment is in the Ø30 bore, the lower past
    // the step in the Ø16 one.
    let d = tilted(0.0);
    let top = [0.0, 0.0, 60.0];
    let mesh = stepped_hole(d, top);
    let mut request = AccessRequest::new(top, down(top, d, 32.0));
    request.segments = 2;
    request.allowance = 0.2;
    let tool = |dia: f64, flutes_long: f64| {
        let mut t = Tool::flat(dia, 3);
        t.flute_length = flutes_long;
        t.name = Some(format!("D{dia}"));
        t
    };
    request.tools = vec![
        tool(10.0, 40.0),
        tool(25.0, 40.0),
        tool(29.8, 40.0),
        tool(14.0, 40.0),
        tool(15.0, 40.0),
    ];
    let report = analyze(&mesh, &request, &CancelFlag::new()).unwrap();
    let (s1, s2) = (&report.segments[0], &report.segments[1]);
    assert!((s1.reach_mm - 16.0).abs() < 1e-6 && (s2.reach_mm - 32.0).abs() < 1e-6);
    assert!(
        (s1.tool_diameter_mm - (2.0 * apothem(15.0) - 0.4)).abs() < 0.05,
        "{}",
        s1.tool_diameter_mm
    );
    assert!(
        (s2.tool_diameter_mm - (2.0 * apothem(8.0) - 0.4)).abs() < 0.05,
        "{}",
        s2.tool_diameter_mm
    );
    // Ø29.8 needs 30.2 with the allowance: Ø25 is the largest for the bore; Ø15 past the step.
    assert_eq!(s1.tool.as_ref().unwrap().diameter_mm, 25.0);
    assert_eq!(s2.tool.as_ref().unwrap().diameter_mm, 15.0);
    assert!(!s1.plunges.is_empty() && !s2.plunges.is_empty());
}
