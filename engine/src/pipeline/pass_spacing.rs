//! The step-over between neighbouring passes, from the tool path. The scallop a ball or
//! bull-nose leaves beside the pass before it is set by that spacing; the engagement, taken on
//! the grid with its test points half a cell out, only approximates it (a D10 ball at a 1 mm
//! step-over read 32.4 µm from the engaged width where the exact scallop is 25.06 µm).

use std::collections::HashMap;

use super::tools::ToolLookup;
use super::SimulateError;
use crate::nc::{Move, MoveKind};
use crate::vec3::{dot, norm, scale, sub};

use super::rows::MoveRow;

/// Passes this close to parallel are neighbours (cos 10°): a raster's zig and zag included.
const PARALLEL_COS: f64 = 0.984_807_753;

/// Cells of the spatial index at most (a path too long for it keeps the engaged width).
const MAX_CELLS: usize = 4_000_000;

/// A feed pass the spacing can be measured on: a straight cut with the tool along Z and no
/// rotary motion.
struct Pass {
    tool: u32,
    a: [f64; 3],
    u: [f64; 3],
    len: f64,
}

/// For every move, the lateral distance to the nearest earlier pass of the same tool that runs
/// beside it (parallel within 10°, its midpoint within the other's span, nearer than the
/// tool's diameter and not on the same line): None where there is none (a first pass, a
/// contour, an arc, a 5-axis move), or where the path is too long to index.
pub(super) fn pass_spacings(
    moves: &[Move],
    rows: &[MoveRow],
    tools: &ToolLookup,
) -> Result<Vec<Option<f64>>, SimulateError> {
    let mut out = vec![None; moves.len()];
    let mut passes: Vec<Option<Pass>> = Vec::with_capacity(moves.len());
    let mut cell_count = 0usize;
    let mut cell_size = f64::INFINITY;
    for (m, r) in moves.iter().zip(rows) {
        let pass = straight_pass(m, r);
        if let Some(p) = &pass {
            let d = tools.tool_for(m)?.diameter;
            cell_size = cell_size.min(d);
            cell_count += (p.len / d) as usize + 2;
        }
        passes.push(pass);
    }
    if cell_count == 0 || cell_count > MAX_CELLS {
        return Ok(out);
    }
    let cell = cell_size;
    let key = |p: [f64; 3]| ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64);
    // Cells each pass crosses, sampled every half cell along it.
    let cells_of = |p: &Pass| -> Vec<(i64, i64)> {
        let n = (2.0 * p.len / cell).ceil() as usize + 1;
        let mut ks: Vec<(i64, i64)> = (0..=n)
            .map(|k| {
                let t = p.len * k as f64 / n as f64;
                key([p.a[0] + p.u[0] * t, p.a[1] + p.u[1] * t, 0.0])
            })
            .collect();
        ks.dedup();
        ks
    };
    let mut index: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for i in 0..moves.len() {
        let Some(p) = &passes[i] else {
            continue;
        };
        let diameter = tools.tool_for(&moves[i])?.diameter;
        let mid = crate::vec3::add(p.a, scale(p.u, 0.5 * p.len));
        let (cx, cy) = key(mid);
        let mut best: Option<f64> = None;
        // The neighbour is within one diameter of the midpoint: the 3×3 cells around it (the
        // cells are at most a diameter wide).
        for dx in -1..=1 {
            for dy in -1..=1 {
                let Some(list) = index.get(&(cx + dx, cy + dy)) else {
                    continue;
                };
                for &j in list {
                    let Some(q) = &passes[j] else {
                        continue;
                    };
                    if q.tool != p.tool || dot(p.u, q.u).abs() < PARALLEL_COS {
                        continue;
                    }
                    let w = sub(mid, q.a);
                    let along = dot(w, q.u);
                    if !(0.0..=q.len).contains(&along) {
                        continue;
                    }
                    let d = norm(sub(w, scale(q.u, along)));
                    // Below a micron it is the same line cut again, not a neighbour.
                    if d > 1e-3 && d < diameter && best.is_none_or(|b| d < b) {
                        best = Some(d);
                    }
                }
            }
        }
        out[i] = best;
        for k in cells_of(p) {
            let list = index.entry(k).or_default();
            if list.last() != Some(&i) {
                list.push(i);
            }
        }
    }
    Ok(out)
}

fn straight_pass(m: &Move, r: &MoveRow) -> Option<Pass> {
    if m.kind != MoveKind::Linear || r.removed_volume <= 0.0 {
        return None;
    }
    let vertical = m.tool_axis.is_none_or(|a| (a[2] - 1.0).abs() < 1e-9);
    let rotary_still = (3..6).all(|k| m.start[k] == m.end[k]);
    if !(vertical && rotary_still) {
        return None;
    }
    let a = [m.start[0], m.start[1], m.start[2]];
    let d = sub([m.end[0], m.end[1], m.end[2]], a);
    let len = norm(d);
    if !(len > 1e-3) {
        return None;
    }
    Some(Pass {
        tool: m.tool,
        a,
        u: scale(d, 1.0 / len),
        len,
    })
}
