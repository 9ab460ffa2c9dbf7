//! A segment's answer from its evaluated axis: the largest tool of the list that fits
//! (cutter, shank and holder all clear, flutes long enough for the depth), and the plunge
//! points of the tool the roughing program uses, with the heights it moves at.

use super::body::{Level, LevelWalls};
use super::clearing;
use super::evaluate::{Detail, Evaluation};
use super::{angle_deg, AccessRequest, SegmentReach, ToolChoice};
use crate::tool::Tool;
use crate::vec3::{dot, sub};

/// Cells tried for a list tool whose axis does not fit at the largest circle's centre.
const MAX_PLACEMENT_TRIES: usize = 5000;
/// Most plunge points a segment gets (the lattice is widened until it fits).
pub const MAX_PLUNGES: usize = 400;
/// Plunge step-over as a fraction of the tool diameter.
const STEP_OVER: f64 = 0.5;
/// Clearance of the approach and safe heights above the part, mm.
pub const CLEARANCE: f64 = 5.0;

/// The flat end mill the program uses when no tool list is given: the largest tool's
/// diameter rounded down to 0.1 mm, flutes over the whole depth.
pub fn computed_tool(seg: &SegmentReach, request: &AccessRequest) -> Option<Tool> {
    let d = (seg.tool_diameter_mm * 10.0 + 1e-9).floor() / 10.0;
    if d < 0.1 {
        return None;
    }
    let mut t = Tool::flat(d, 3);
    t.name = Some(format!("computed Ø{d:.1} for segment {}", seg.segment));
    // Flutes over the whole depth, within the stick-out when one is given.
    t.flute_length = seg.reach_mm.max(0.0) + CLEARANCE;
    if let Some(s) = request.stickout {
        t.flute_length = t.flute_length.min(s);
    }
    t.stick_out = Some(request.stickout.unwrap_or(t.flute_length + 2.0 * d));
    t.holder = request.holder.clone();
    Some(t)
}

fn placement(
    eval: &Evaluation,
    detail: &Detail,
    walls: &LevelWalls,
    levels: &[Level],
    allowance: f64,
) -> Option<[f64; 2]> {
    let need = levels[0].radius + allowance;
    if let Some(c) = eval.circle {
        if walls.fits(levels, allowance, c.center) {
            return Some(c.center);
        }
    }
    let r = &eval.raster;
    let mut cells: Vec<usize> = (0..r.len())
        .filter(|&k| detail.component[k] && detail.bound[k] >= need)
        .collect();
    cells.sort_unstable_by(|&a, &b| detail.bound[b].total_cmp(&detail.bound[a]).then(a.cmp(&b)));
    cells
        .into_iter()
        .take(MAX_PLACEMENT_TRIES)
        .map(|k| r.center(k))
        .find(|&c| walls.fits(levels, allowance, c))
}

/// Plunge points on a square lattice through `start`, where the body fits in the
/// component, in serpentine order.
fn plunge_points(
    eval: &Evaluation,
    detail: &Detail,
    levels: &[Level],
    allowance: f64,
    start: [f64; 2],
) -> Vec<[f64; 2]> {
    let r = &eval.raster;
    let mut step = (2.0 * levels[0].radius * STEP_OVER).max(r.cell);
    for _ in 0..30 {
        let w = &r.window;
        let i0 = ((w.lo[0] - start[0]) / step).floor() as i64;
        let i1 = ((w.hi[0] - start[0]) / step).ceil() as i64;
        let j0 = ((w.lo[1] - start[1]) / step).floor() as i64;
        let j1 = ((w.hi[1] - start[1]) / step).ceil() as i64;
        if (i1 - i0 + 1) * (j1 - j0 + 1) > 4_000_000 {
            step *= 2.0;
            continue;
        }
        let mut points = Vec::new();
        for (row, j) in (j0..=j1).enumerate() {
            let mut line: Vec<[f64; 2]> = (i0..=i1)
                .map(|i| [start[0] + i as f64 * step, start[1] + j as f64 * step])
                .filter(|&p| {
                    r.cell_of(p).is_some_and(|k| detail.component[k])
                        && detail.walls.fits(levels, allowance, p)
                })
                .collect();
            if row % 2 == 1 {
                line.reverse();
            }
            points.extend(line);
            if points.len() > MAX_PLUNGES {
                break;
            }
        }
        if points.len() <= MAX_PLUNGES {
            return points;
        }
        step *= 1.25;
    }
    Vec::new()
}

#[allow(clippy::too_many_arguments)]
pub fn segment_reach(
    segment: usize,
    point: [f64; 3],
    d0: [f64; 3],
    entry: &[f64; 3],
    eval: &Evaluation,
    detail: &Detail,
    request: &AccessRequest,
    tool_levels: &[Vec<Level>],
) -> SegmentReach {
    let s = &eval.section;
    let radius = eval.radius();
    let reach = dot(sub(*entry, point), s.axis);
    let a = request.allowance;
    let mut order: Vec<usize> = (0..request.tools.len()).collect();
    order.sort_by(|&x, &y| {
        request.tools[y]
            .diameter
            .total_cmp(&request.tools[x].diameter)
            .then(x.cmp(&y))
    });
    let mut tool = None;
    for i in order {
        let t = &request.tools[i];
        if t.flute_length < reach || t.radius() > radius {
            continue;
        }
        if let Some(c) = placement(eval, detail, &detail.walls, &tool_levels[i], a) {
            tool = Some((
                ToolChoice {
                    index: i,
                    name: t.name.clone(),
                    diameter_mm: t.diameter,
                    center: s.point(c, 0.0),
                },
                c,
            ));
            break;
        }
    }
    let mut reach_out = SegmentReach {
        segment,
        section_point: point,
        axis: s.axis,
        tilt_deg: angle_deg(s.axis, d0),
        tool_diameter_mm: 2.0 * radius,
        center: eval.circle.map(|c| s.point(c.center, 0.0)),
        free_area_mm2: eval.area,
        reach_mm: reach,
        open: eval.open,
        tool: tool.as_ref().map(|t| t.0.clone()),
        plunges: Vec::new(),
        approach_height_mm: 0.0,
        safe_height_mm: 0.0,
        cell_mm: eval.raster.cell,
        clearing: None,
    };
    // The program's tool: the chosen one, or with no list the computed one.
    let plunge = match (&tool, request.tools.is_empty()) {
        (Some((t, c)), _) => Some((tool_levels[t.index].clone(), *c)),
        (None, true) => computed_tool(&reach_out, request).and_then(|t| {
            let levels = super::body::tool_levels(&t, request.stickout, &request.holder);
            eval.circle.map(|c| (levels, c.center))
        }),
        (None, false) => None,
    };
    let top = detail.local.iter().map(|v| v[2]).fold(0.0, f64::max);
    reach_out.safe_height_mm = top + CLEARANCE;
    if let Some((levels, start)) = plunge {
        let points = plunge_points(eval, detail, &levels, a, start);
        let clearing = clearing::plan(eval, detail, &levels, a, start);
        // The highest part point near the plunges and passes: the rapid stops above it.
        let margin = levels[0].radius + 1.0;
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        let passes = clearing.iter().flat_map(|c| c.passes.iter());
        for p in points.iter().chain(passes.flat_map(|p| p.points.iter())) {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k] - margin);
                hi[k] = hi[k].max(p[k] + margin);
            }
        }
        let near = detail
            .local
            .iter()
            .filter(|v| v[0] >= lo[0] && v[0] <= hi[0] && v[1] >= lo[1] && v[1] <= hi[1])
            .map(|v| v[2])
            .fold(0.0, f64::max);
        reach_out.approach_height_mm = (near + CLEARANCE).min(reach_out.safe_height_mm);
        reach_out.plunges = points.iter().map(|&p| s.point(p, 0.0)).collect();
        reach_out.clearing = clearing;
    }
    reach_out
}
