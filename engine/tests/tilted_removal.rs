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
    let before = stock.grid.volume();
    let stats = remove_sweep(&mut stock.grid, &body, &SubMove { p0, p1, axis });
    let removed = before - stock.grid.volume();
    let expected = 2.0 * half * section_area(&body, length, zt, tilt, zlo, zhi);
    let err = (removed - expected).abs() / expected;
    assert!(
        err < 0.005,
        "{:?} tilt {tilt_deg}° along {}: removed {removed:.4} vs {expected:.4} ({:.3}%)",
        tool.shape,
        if along_y { "Y" } else { "X" },
        100.0 * err
    );
    assert!((stats.volume(cell) - removed).abs() <= 1e-6 * expected);
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
        for (tilt, along_y) in [(15.0, false), (35.0, true), (-20.0, false)] {
            check(tool, tilt, along_y, 0.05);
        }
    }
}
