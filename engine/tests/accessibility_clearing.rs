//! The clearing passes (helical entry, offset spiral) against closed forms: in a polygonal
//! hole of n sides the free region shrunk by the tool's radius plus the allowance is the
//! polygon whose faces lie at the apothem R·cos(π/n) less that radius. Every pass point,
//! at the section and lifted along the tool axis to the hole's top, must satisfy each
//! face's half-plane; the constraints are linear, so the straight moves between the points
//! and the whole tool body between the section and the top do too.

mod parts;

use millsim_engine::accessibility::clearing::{Clearing, Entry};
use millsim_engine::accessibility::{analyze, AccessRequest};
use millsim_engine::geometry::Mesh;
use millsim_engine::job::CancelFlag;
use millsim_engine::tool::Tool;
use parts::{drilled_block, hole_frame, HolePiece};

type V3 = [f64; 3];

const SIDES: usize = 128;
const HEIGHT: f64 = 60.0;

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn tilted(deg: f64) -> V3 {
    let a = deg.to_radians();
    [a.sin(), 0.0, a.cos()]
}

/// A block with a straight hole of `radius` along `d` from `top`.
fn hole(radius: f64, d: V3, top: V3) -> Mesh {
    let piece = HolePiece {
        radius,
        offset: [0.0, 0.0],
        until: 0.0,
    };
    drilled_block(60.0, 50.0, HEIGHT, d, top, &[piece], SIDES)
}

/// How far `p` lies outside the shrunk polygon: the largest face excess (≤ 0 inside).
fn excess(p: V3, d: V3, top: V3, apothem_left: f64) -> f64 {
    let (e1, e2) = hole_frame(d);
    let v = [p[0] - top[0], p[1] - top[1], p[2] - top[2]];
    let (x, y) = (dot(v, e1), dot(v, e2));
    (0..SIDES)
        .map(|j| {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) / SIDES as f64;
            x * phi.cos() + y * phi.sin() - apothem_left
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

fn clearing_of(radius: f64, tool_d: f64, allowance: f64) -> (Clearing, V3, V3, V3) {
    let d = tilted(25.0);
    let top = [0.0, 0.0, HEIGHT];
    let mesh = hole(radius, d, top);
    let target: V3 = std::array::from_fn(|k| top[k] - 40.0 * d[k]);
    let mut request = AccessRequest::new(top, target);
    request.allowance = allowance;
    let mut tool = Tool::flat(tool_d, 3);
    tool.flute_length = 50.0;
    request.tools = vec![tool];
    let report = analyze(&mesh, &request, &CancelFlag::new()).unwrap();
    let seg = report.target();
    assert_eq!(seg.tool.as_ref().map(|t| t.diameter_mm), Some(tool_d));
    let c = seg
        .clearing
        .clone()
        .expect("a clearing for the list's tool");
    (c, d, top, seg.axis)
}

#[test]
fn every_spiral_point_lies_in_the_hole_shrunk_by_the_tool_radius_and_allowance() {
    let (radius, tool_d, allowance) = (15.0, 10.0, 0.5);
    let (c, d, top, axis) = clearing_of(radius, tool_d, allowance);
    let apothem = radius * (std::f64::consts::PI / SIDES as f64).cos();
    let left = apothem - tool_d / 2.0 - allowance;
    let mut points = 0;
    let mut farthest = 0.0f64;
    for p in c.points_3d() {
        // At the section, and lifted along the tool's axis to the block's top.
        let t = (HEIGHT - p[2]) / axis[2];
        let lifted: V3 = std::array::from_fn(|k| p[k] + t * axis[k]);
        for q in [p, lifted] {
            let e = excess(q, d, top, left);
            assert!(e <= 1e-9, "{q:?} is {e} mm outside the shrunk hole");
        }
        let v = [p[0] - top[0], p[1] - top[1], p[2] - top[2]];
        let along = dot(v, d);
        let across = (dot(v, v) - along * along).max(0.0).sqrt();
        farthest = farthest.max(across);
        points += 1;
    }
    // One continuous spiral, entered by a helix, out to within the margin (and a few
    // cells) of the shrunk hole's faces: the passes clear the region, not a dot of it.
    assert_eq!(c.passes.len(), 1, "{:?}", c.passes.len());
    assert!(matches!(c.passes[0].entry, Entry::Helix { .. }));
    assert!(c.rings >= 2, "{} rings", c.rings);
    assert!(
        farthest >= left - c.margin - 0.2,
        "reaches {farthest} of {left} (margin {})",
        c.margin
    );
    // The spiral leaves the centre and winds outwards: its radius at the end is the
    // outer ring's, at the start within the helix.
    let pts: Vec<V3> = c.points_3d().collect();
    let across = |p: V3| {
        let v = [p[0] - top[0], p[1] - top[1], p[2] - top[2]];
        let along = dot(v, d);
        (dot(v, v) - along * along).max(0.0).sqrt()
    };
    assert!(across(pts[0]) < tool_d / 2.0, "starts {}", across(pts[0]));
    assert!(across(*pts.last().unwrap()) > left - c.margin - 0.2);
    eprintln!(
        "hole Ø{}: tool Ø{tool_d}, {} rings, {points} points, {:.1} mm of path, farthest {farthest:.3} of {left:.3} mm",
        2.0 * radius,
        c.rings,
        c.length()
    );
}

#[test]
fn a_tool_that_only_just_fits_gets_a_plunge_and_no_rings() {
    // Ø20 hole, allowance 0.5: Ø18.9 leaves 0.05 mm, under the rings' margin.
    let (c, d, top, _) = clearing_of(10.0, 18.9, 0.5);
    assert_eq!(c.rings, 0);
    assert_eq!(c.passes.len(), 1);
    assert_eq!(c.passes[0].entry, Entry::Plunge);
    let apothem = 10.0 * (std::f64::consts::PI / SIDES as f64).cos();
    for p in c.points_3d() {
        assert!(excess(p, d, top, apothem - 9.45 - 0.5) <= 1e-9);
    }
}
