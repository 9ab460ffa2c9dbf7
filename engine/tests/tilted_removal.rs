//! Tilted-tool removal against a closed-form volume, for every tool shape.
//!
//! A solid of revolution projected along a direction perpendicular to its axis covers
//! exactly its meridian section (|ρ| ≤ r(z)). So a tool whose axis lies in the YZ plane,
//! moving along X right through a block (starting and ending clear of it), removes the
//! block's X length times the area of the meridian section, placed at the tool's tilt,
//! that lies inside the block's YZ section. Same with X and Y swapped.

use millsim_engine::geometry::{remove_sweep, Stock, SubMove, ToolBody};
use millsim_engine::tool::{Tool, ToolShape};

fn chamfer(diameter: f64, tip: f64, half_angle: f64) -> Tool {
    let mut t = Tool::flat(diameter, 2);
    t.shape = ToolShape::Chamfer;
    t.tip_diameter = tip;
    t.taper_half_angle_deg = half_angle;
    t
}

/// Area of the meridian section {(ρ, z): |ρ| ≤ r(z), 0 ≤ z ≤ L} placed with its tip at
/// height `zt`, its axis tilted by `tilt` from +Z, between heights `zlo` and `zhi`.
fn section_area(body: &ToolBody, length: f64, zt: f64, tilt: f64, zlo: f64, zhi: f64) -> f64 {
    let (s, c) = tilt.sin_cos();
    let n = 200_000;
    let dz = length / n as f64;
    let mut area = 0.0;
    for i in 0..n {
        let z = (i as f64 + 0.5) * dz;
        let r = body.radius_at(z);
        // Height of the point (ρ, z): zt + z·cos + ρ·sin, linear in ρ.
        let h0 = zt + z * c;
        let (mut a, mut b) = (-r, r);
        if s.abs() > 1e-15 {
            let (p, q) = ((zlo - h0) / s, (zhi - h0) / s);
            a = a.max(p.min(q));
            b = b.min(p.max(q));
        } else if h0 < zlo || h0 > zhi {
            continue;
        }
        if b > a {
            area += (b - a) * dz;
        }
    }
    area
}

fn check(tool: &Tool, tilt_deg: f64, along_y: bool, cell: f64) {
    let body = ToolBody::cutting_part(tool);
    let length = tool.flute_length;
    let tilt = tilt_deg.to_radians();
    let (zlo, zhi) = (-10.0, 0.0);
    let zt = -4.0;
    let half = 5.0;
    // Axis in the plane across the motion, tilted from +Z.
    let (s, c) = tilt.sin_cos();
    let (axis, p0, p1, min, max) = if along_y {
        (
            [-s, 0.0, c],
            [0.0, -15.0, zt],
            [0.0, 15.0, zt],
            [-20.0, -half, zlo],
            [20.0, half, zhi],
        )
    } else {
        (
            [0.0, -s, c],
            [-15.0, 0.0, zt],
            [15.0, 0.0, zt],
            [-half, -20.0, zlo],
            [half, 20.0, zhi],
        )
    };
    let mut stock = Stock::block(min, max, cell).unwrap();
    let mean =
        |g: &millsim_engine::geometry::DexelGrid| g.family_volumes().iter().sum::<f64>() / 3.0;
    let (before, before_mean) = (stock.grid.volume(), mean(&stock.grid));
    let stats = remove_sweep(&mut stock.grid, &body, &SubMove { p0, p1, axis });
    let removed = before - stock.grid.volume();
    let removed_mean = before_mean - mean(&stock.grid);
    let expected = 2.0 * half * section_area(&body, length, zt, tilt, zlo, zhi);
    let err = (removed - expected).abs() / expected;
    assert!(
        err < 0.005,
        "{:?} tilt {tilt_deg}° along {}: removed {removed:.4} vs {expected:.4} ({:.3}%)",
        tool.shape,
        if along_y { "Y" } else { "X" },
        100.0 * err
    );
    // The sweep's statistics are the families' mean (the voxel reading is the stock's).
    assert!((stats.volume() - removed_mean).abs() <= 1e-6 * expected);
    let err_mean = (removed_mean - expected).abs() / expected;
    println!(
        "tilt {tilt_deg}°: voxel reading {:.4}%, families' mean {:.4}%",
        100.0 * err,
        100.0 * err_mean
    );
}

#[test]
fn tilted_sweeps_through_a_block_remove_the_closed_form_volume() {
    let mut flat = Tool::flat(6.0, 2);
    flat.flute_length = 12.0;
    let mut ball = Tool::ball(6.0, 2);
    ball.flute_length = 12.0;
    let mut bull = Tool::bull_nose(6.0, 1.5, 2);
    bull.flute_length = 12.0;
    let mut cham = chamfer(6.0, 1.0, 30.0);
    cham.flute_length = 12.0;
    for tool in [&flat, &ball, &bull, &cham] {
        // At 90° the axis lies along a grid axis, across the rays of one family's rows.
        for (tilt, along_y) in [
            (15.0, false),
            (35.0, true),
            (-20.0, false),
            (90.0, true),
            (90.0, false),
        ] {
            check(tool, tilt, along_y, 0.05);
        }
    }
}

/// The same cuts with the grid turned so that its z is the tool axis (what the pipeline
/// does for a 3+2 program): the tool is vertical in the grid, the volume is the closed
/// form's, and what comes out (step positions and directions, the exported mesh) is in
/// the part frame.
#[test]
fn cuts_in_a_grid_turned_along_the_tool_remove_the_closed_form_volume() {
    use millsim_engine::engagement::Engagement;
    use millsim_engine::geometry::{
        export_stl_vec, simulate_removal, GridFrame, GridOptions, Mesh, PathShape, Segment,
        SimOptions, StockShape,
    };
    use millsim_engine::job::CancelFlag;

    let cell = 0.05;
    let mut flat = Tool::flat(6.0, 2);
    flat.flute_length = 12.0;
    let mut bull = Tool::bull_nose(6.0, 1.5, 2);
    bull.flute_length = 12.0;
    for tool in [&flat, &bull] {
        for tilt_deg in [15.0f64, -20.0] {
            let body = ToolBody::cutting_part(tool);
            let tilt = tilt_deg.to_radians();
            let (s, c) = tilt.sin_cos();
            let (zlo, zhi, zt, half) = (-10.0, 0.0, -4.0, 5.0);
            let axis = [0.0, -s, c];
            let (min, max) = ([-half, -20.0, zlo], [half, 20.0, zhi]);
            let frame = GridFrame::with_z_along(axis).unwrap();
            let opts = GridOptions {
                cell: Some(cell),
                ..Default::default()
            };
            let mut stock =
                Stock::from_shape_in(&StockShape::Block { min, max }, &opts, frame).unwrap();
            assert_eq!(stock.frame, frame);
            let before = stock.volume();
            let block = 2.0 * half * 40.0 * 10.0;
            assert!(
                (before - block).abs() < 0.005 * block,
                "{before} vs {block}"
            );
            let seg = Segment {
                block: 0,
                shape: PathShape::Linear,
                from: [-15.0, 0.0, zt],
                to: [15.0, 0.0, zt],
                axis_from: axis,
                axis_to: axis,
                rapid: false,
                feed: 1000.0,
                spindle: 10000.0,
            };
            let report = simulate_removal(
                &mut stock,
                tool,
                &[seg],
                &SimOptions::default(),
                &CancelFlag::new(),
            )
            .unwrap();
            let removed = before - stock.volume();
            let expected = 2.0 * half * section_area(&body, tool.flute_length, zt, tilt, zlo, zhi);
            let err = (removed - expected).abs() / expected;
            assert!(
                err < 0.005,
                "{:?} {tilt_deg}°: {removed} vs {expected}",
                tool.shape
            );
            let b = &report.blocks[0];
            assert!((b.removed_volume - removed).abs() < 0.005 * expected);
            // Steps in the part frame: on the programmed line, with the programmed axis; the
            // engagement's axis and feed direction too.
            let engaged = b.steps.iter().filter(|st| !st.air).count();
            assert!(engaged > 20, "{engaged}");
            for st in &b.steps {
                assert!(st.position[1].abs() < 1e-6 && (st.position[2] - zt).abs() < 1e-6);
                assert!((0..3).all(|k| (st.axis[k] - axis[k]).abs() < 1e-12));
                let e = Engagement::from(st.engagement.clone());
                if !st.air {
                    assert!((0..3).all(|k| (e.tool_axis[k] - axis[k]).abs() < 1e-12));
                    assert!((e.feed_dir[0] - 1.0).abs() < 1e-9, "{:?}", e.feed_dir);
                }
            }
            // The exported mesh is the part-frame stock: its bounds are the block's, its
            // volume the grid's.
            let (bytes, _) = export_stl_vec(&stock).unwrap();
            let mesh = Mesh::from_stl_bytes(&bytes).unwrap();
            let (lo, hi) = mesh.bounds();
            for k in 0..3 {
                assert!((lo[k] - min[k]).abs() < 2.0 * cell, "{lo:?} {min:?}");
                assert!((hi[k] - max[k]).abs() < 2.0 * cell, "{hi:?} {max:?}");
            }
            let v = mesh.volume();
            assert!(
                (v - stock.volume()).abs() < 0.005 * v,
                "{v} vs {}",
                stock.volume()
            );
        }
    }
}

/// A turned cylinder stock holds the cylinder's volume.
#[test]
fn a_cylinder_in_a_turned_grid_holds_its_volume() {
    use millsim_engine::geometry::{GridFrame, GridOptions, StockShape};
    let shape = StockShape::Cylinder {
        base_center: [1.0, 2.0, -30.0],
        radius: 20.0,
        height: 30.0,
    };
    let opts = GridOptions {
        cell: Some(0.25),
        ..Default::default()
    };
    for axis in [
        [0.0, -0.2588190451025208, 0.9659258262890683],
        [0.3, 0.4, 0.8660254037844386],
    ] {
        let frame = GridFrame::with_z_along(axis).unwrap();
        let stock = Stock::from_shape_in(&shape, &opts, frame).unwrap();
        let exact = std::f64::consts::PI * 400.0 * 30.0;
        let v = stock.volume();
        assert!(
            (v - exact).abs() < 0.005 * exact,
            "{axis:?}: {v} vs {exact}"
        );
    }
}

/// The design-part comparison of a turned grid: the part (in the part frame) is turned into
/// the grid, so an untouched stock gouges nothing and a tilted cut through the part's top
/// gouges the closed-form volume.
#[test]
fn a_turned_grid_is_compared_with_the_part_in_the_part_frame() {
    use millsim_engine::geometry::{
        compare_with_part, export_stl_vec, simulate_removal, GridFrame, GridOptions, Mesh,
        PathShape, Segment, SimOptions, StockShape,
    };
    use millsim_engine::job::CancelFlag;

    let cell = 0.05;
    // The design part: a box 3 mm below the stock's top, as an exact mesh.
    let (plo, phi) = ([0.0, -10.0, -10.0], [40.0, 10.0, -3.0]);
    let (bytes, _) = export_stl_vec(&Stock::block(plo, phi, cell).unwrap()).unwrap();
    let part = Mesh::from_stl_bytes(&bytes).unwrap();
    let tilt = 15f64.to_radians();
    let (s, c) = tilt.sin_cos();
    let axis = [0.0, -s, c];
    let frame = GridFrame::with_z_along(axis).unwrap();
    let opts = GridOptions {
        cell: Some(cell),
        ..Default::default()
    };
    let shape = StockShape::Block {
        min: [0.0, -10.0, -10.0],
        max: [40.0, 10.0, 0.0],
    };
    let mut stock = Stock::from_shape_in(&shape, &opts, frame).unwrap();
    let c0 = compare_with_part(&stock, &part).unwrap();
    assert!(c0.gouge_volume < 1e-6, "{c0:?}");
    assert!(c0.part_rays > 0);
    // A tilted flat mill right through along X with its tip 1 mm into the part.
    let mut tool = Tool::flat(6.0, 2);
    tool.flute_length = 12.0;
    let zt = -4.0;
    let seg = Segment {
        block: 0,
        shape: PathShape::Linear,
        from: [-15.0, 0.0, zt],
        to: [55.0, 0.0, zt],
        axis_from: axis,
        axis_to: axis,
        rapid: false,
        feed: 1000.0,
        spindle: 10000.0,
    };
    simulate_removal(
        &mut stock,
        &tool,
        &[seg],
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let body = ToolBody::cutting_part(&tool);
    let want = 40.0 * section_area(&body, tool.flute_length, zt, tilt, -10.0, -3.0);
    let c1 = compare_with_part(&stock, &part).unwrap();
    assert!(
        (c1.gouge_volume - want).abs() < 0.01 * want,
        "{} vs {want}",
        c1.gouge_volume
    );
}
