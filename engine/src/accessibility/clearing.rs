//! The clearing passes of a segment's free region for one tool: offset paths of the region
//! by the tool's radius plus the allowance, stepping inward by a stepover, joined into one
//! continuous spiral from the centre out, entered by a helix.
//!
//! The offsets are level curves of the tool's margin g(c): the least, over the tool's
//! cutter and holder levels, of the exact clearance of its walls at c less the level's
//! radius and the allowance. Where g ≥ 0 the whole body plunged along the axis touches no
//! wall, and g is a distance less constants, so 1-Lipschitz: its level curves are the
//! region's inward offsets, and a straight move from a to b is safe when g(a) + g(b) ≥ |ab|
//! (every point of it is within |ab|/2 of an end). Every move of every pass is certified so
//! (split in halves until it is, or refused), which is what keeps the passes inside the
//! region whatever the raster's interpolation does. A ring pair the spiral cannot join
//! safely is joined by the inner ring's full loop and a certified link; failing that, the
//! pass ends and the next starts with a plunge.

use rayon::prelude::*;

use super::body::Level;
use super::contour::{contains, loops, signed_area2};
use super::evaluate::{Detail, Evaluation};
use super::section::Section;

/// Stepover between offset rings, as a fraction of the tool diameter.
pub const STEPOVER: f64 = 0.4;
/// The outer ring's margin over the exact offset, in raster cells (the interpolated level
/// curve's points are within a cell of the level, its chords within another 0.71).
const MARGIN_CELLS: f64 = 2.5;
/// Halvings a move may take to be certified.
const CERTIFY_DEPTH: u32 = 18;
/// Most rings (a bound on the work whatever the region).
const MAX_RINGS: usize = 200;

/// How a pass is entered from above.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Entry {
    /// A helical descent about `center` of `radius`, ending at the pass's first point.
    Helix { center: [f64; 2], radius: f64 },
    /// Straight down along the axis at the pass's first point.
    Plunge,
}

/// One continuous pass at a depth: plane points, each with its margin g.
#[derive(Clone, Debug)]
pub struct Pass {
    pub entry: Entry,
    pub points: Vec<[f64; 2]>,
}

/// A segment's clearing passes (the same at every depth of the program).
#[derive(Clone, Debug)]
pub struct Clearing {
    pub section: Section,
    pub tool_radius: f64,
    pub allowance: f64,
    pub stepover: f64,
    /// The outer ring's level: how much more than the allowance is left on the walls.
    pub margin: f64,
    pub rings: usize,
    pub passes: Vec<Pass>,
}

impl Clearing {
    /// Length of the passes' moves at one depth, mm.
    pub fn length(&self) -> f64 {
        self.passes
            .iter()
            .map(|p| p.points.windows(2).map(|w| dist(w[0], w[1])).sum::<f64>())
            .sum()
    }

    /// Every pass point on the section plane, in 3-D.
    pub fn points_3d(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        self.passes
            .iter()
            .flat_map(|p| p.points.iter().map(|&q| self.section.point(q, 0.0)))
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn lerp(a: [f64; 2], b: [f64; 2], t: f64) -> [f64; 2] {
    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
}

/// The tool's margin at a point.
struct Margin<'a> {
    detail: &'a Detail,
    levels: &'a [Level],
    allowance: f64,
    cap: f64,
}

impl Margin<'_> {
    fn at(&self, c: [f64; 2]) -> f64 {
        self.levels
            .iter()
            .map(|l| {
                let need = l.radius + self.allowance;
                self.detail
                    .walls
                    .walls_at(l.height)
                    .clearance_below(c, need + self.cap)
                    - need
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Whether the straight move a → b (margins ga, gb) keeps g ≥ 0.
    fn certify(&self, a: [f64; 2], ga: f64, b: [f64; 2], gb: f64, depth: u32) -> bool {
        if ga < 0.0 || gb < 0.0 {
            return false;
        }
        if ga + gb >= dist(a, b) {
            return true;
        }
        if depth == 0 {
            return false;
        }
        let m = lerp(a, b, 0.5);
        let gm = self.at(m);
        self.certify(a, ga, m, gm, depth - 1) && self.certify(m, gm, b, gb, depth - 1)
    }

    /// Whether every move of `path` (after `from`) is safe.
    fn certify_path(&self, from: ([f64; 2], f64), path: &[([f64; 2], f64)]) -> bool {
        let mut prev = from;
        for &p in path {
            if !self.certify(prev.0, prev.1, p.0, p.1, CERTIFY_DEPTH) {
                return false;
            }
            prev = p;
        }
        true
    }
}

/// A closed ring by arc length: the point at fraction u of its length from vertex `start`.
struct Ring {
    points: Vec<[f64; 2]>,
    cumulative: Vec<f64>,
}

impl Ring {
    fn new(loop_points: &[[f64; 2]], start: usize) -> Ring {
        let n = loop_points.len();
        let points: Vec<[f64; 2]> = (0..=n).map(|k| loop_points[(start + k) % n]).collect();
        let mut cumulative = vec![0.0];
        for w in points.windows(2) {
            cumulative.push(cumulative.last().unwrap() + dist(w[0], w[1]));
        }
        Ring { points, cumulative }
    }

    fn length(&self) -> f64 {
        *self.cumulative.last().unwrap()
    }

    fn at(&self, u: f64) -> [f64; 2] {
        let s = u.clamp(0.0, 1.0) * self.length();
        let k = self
            .cumulative
            .partition_point(|&c| c <= s)
            .clamp(1, self.points.len() - 1);
        let (c0, c1) = (self.cumulative[k - 1], self.cumulative[k]);
        let t = if c1 > c0 { (s - c0) / (c1 - c0) } else { 0.0 };
        lerp(self.points[k - 1], self.points[k], t)
    }
}

fn nearest(points: &[[f64; 2]], c: [f64; 2]) -> usize {
    (0..points.len())
        .min_by(|&a, &b| dist(points[a], c).total_cmp(&dist(points[b], c)))
        .unwrap_or(0)
}

/// Douglas–Peucker within `tol`, keeping only chords that are certified safe.
fn simplify(m: &Margin, path: &[([f64; 2], f64)], tol: f64) -> Vec<([f64; 2], f64)> {
    if path.len() <= 2 {
        return path.to_vec();
    }
    let mut keep = vec![false; path.len()];
    keep[0] = true;
    keep[path.len() - 1] = true;
    let mut stack = vec![(0, path.len() - 1)];
    while let Some((i, j)) = stack.pop() {
        if j <= i + 1 {
            continue;
        }
        let (a, b) = (path[i].0, path[j].0);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = dx.hypot(dy);
        let (mut worst, mut at) = (0.0, i + 1);
        for (k, p) in path.iter().enumerate().take(j).skip(i + 1) {
            let d = if len > 0.0 {
                ((p.0[0] - a[0]) * dy - (p.0[1] - a[1]) * dx).abs() / len
            } else {
                dist(p.0, a)
            };
            if d > worst {
                worst = d;
                at = k;
            }
        }
        if worst > tol || !m.certify(a, path[i].1, b, path[j].1, CERTIFY_DEPTH) {
            keep[at] = true;
            stack.push((i, at));
            stack.push((at, j));
        }
    }
    path.iter()
        .zip(keep)
        .filter(|(_, k)| *k)
        .map(|(p, _)| *p)
        .collect()
}

/// Plans the clearing of the evaluated component for a tool of `levels` (cutter first),
/// spiralling out from `start` (a point where the tool fits). `None` when the tool fits
/// nowhere with the margin.
pub fn plan(
    eval: &Evaluation,
    detail: &Detail,
    levels: &[Level],
    allowance: f64,
    start: [f64; 2],
) -> Option<Clearing> {
    let r = &eval.raster;
    let tool_radius = levels[0].radius;
    let need0 = tool_radius + allowance;
    let top = (0..r.len())
        .filter(|&k| detail.component[k])
        .map(|k| detail.bound[k])
        .fold(0.0, f64::max);
    let m = Margin {
        detail,
        levels,
        allowance,
        cap: (top - need0).max(0.0) + r.cell,
    };
    // The margin at every cell centre of the component near where the tool fits (the
    // transform's bound spares the exact look elsewhere: it is below −2 cells there).
    let field: Vec<f64> = (0..r.len())
        .into_par_iter()
        .map(|k| {
            if !detail.component[k] {
                return -r.cell;
            }
            let upper = detail.bound[k] - need0;
            if upper < -2.0 * r.cell {
                return upper;
            }
            m.at(r.center(k))
        })
        .collect();
    let margin = MARGIN_CELLS * r.cell;
    let stepover = STEPOVER * 2.0 * tool_radius;
    let g_start = m.at(start);
    let (centre, g_centre) = match (0..r.len()).max_by(|&a, &b| field[a].total_cmp(&field[b])) {
        Some(k) if field[k] > g_start => (r.center(k), field[k]),
        _ => (start, g_start),
    };
    if g_centre < 0.0 {
        return None;
    }
    // Rings outside in: level margin + k·stepover, while the centre is inside.
    let mut main: Vec<Vec<[f64; 2]>> = Vec::new();
    let mut side: Vec<Vec<[f64; 2]>> = Vec::new();
    for k in 0..MAX_RINGS {
        let level = margin + k as f64 * stepover;
        if level >= g_centre {
            break;
        }
        let mut found = false;
        for lp in loops(r, &field, level) {
            if signed_area2(&lp) <= 0.0 {
                continue; // a hole's ring: the rings around it keep off it
            }
            if !found && contains(&lp, centre) {
                main.push(lp);
                found = true;
            } else {
                side.push(lp);
            }
        }
        if !found {
            break;
        }
    }
    let mut passes = Vec::new();
    let with_g = |p: [f64; 2]| (p, m.at(p));
    // The helix: about the centre, within its margin (every point of the circle keeps
    // g ≥ g(centre) − radius), at most half the tool's radius.
    let helix_radius = (0.5 * tool_radius).min(0.8 * g_centre);
    let (entry, first) = if helix_radius >= 0.05 {
        (
            Entry::Helix {
                center: centre,
                radius: helix_radius,
            },
            [centre[0] + helix_radius, centre[1]],
        )
    } else {
        (Entry::Plunge, centre)
    };
    let mut pass = Pass {
        entry,
        points: vec![first],
    };
    let mut cur = with_g(first);
    // The ring the tool is on (None: the helix's end), from the inside out.
    let mut on: Option<Ring> = None;
    let step = 2.0 * r.cell;
    for lp in main.iter().rev() {
        let s = nearest(lp, cur.0);
        let outer = Ring::new(lp, s);
        let mut joined = false;
        if let Some(inner) = &on {
            // The spiral: a turn from the inner ring to the outer, matched by arc length.
            let n = ((inner.length().max(outer.length()) / step).ceil() as usize).max(8);
            let turn: Vec<([f64; 2], f64)> = (1..=n)
                .map(|i| {
                    let u = i as f64 / n as f64;
                    with_g(lerp(inner.at(u), outer.at(u), u))
                })
                .collect();
            if m.certify_path(cur, &turn) {
                pass.points.extend(turn.iter().map(|p| p.0));
                cur = *turn.last().unwrap();
                joined = true;
            } else {
                // The inner ring's full loop, then a link out.
                let lap: Vec<([f64; 2], f64)> =
                    inner.points[1..].iter().map(|&p| with_g(p)).collect();
                if m.certify_path(cur, &lap) {
                    pass.points.extend(lap.iter().map(|p| p.0));
                    cur = *lap.last().unwrap();
                }
            }
        }
        if !joined {
            let to = with_g(outer.points[0]);
            if m.certify(cur.0, cur.1, to.0, to.1, CERTIFY_DEPTH) {
                pass.points.push(to.0);
            } else {
                passes.push(std::mem::replace(
                    &mut pass,
                    Pass {
                        entry: Entry::Plunge,
                        points: vec![to.0],
                    },
                ));
            }
            cur = to;
        }
        on = Some(outer);
    }
    // The outermost ring's full loop finishes the walls.
    if let Some(last) = &on {
        let lap: Vec<([f64; 2], f64)> = last.points[1..].iter().map(|&p| with_g(p)).collect();
        if m.certify_path(cur, &lap) {
            pass.points.extend(lap.iter().map(|p| p.0));
        }
    }
    passes.push(pass);
    // Pieces of the region the centre's rings do not reach: each ring its own loop,
    // plunged into at its first point, inner rings first.
    for lp in side.iter().rev() {
        let pts: Vec<([f64; 2], f64)> = lp
            .iter()
            .chain(std::iter::once(&lp[0]))
            .map(|&p| with_g(p))
            .collect();
        if pts[0].1 >= 0.0 && m.certify_path(pts[0], &pts[1..]) {
            passes.push(Pass {
                entry: Entry::Plunge,
                points: pts.iter().map(|p| p.0).collect(),
            });
        }
    }
    // Fewer moves: chords within a tenth of a cell, each certified again.
    for p in passes.iter_mut() {
        let path: Vec<([f64; 2], f64)> = p.points.iter().map(|&q| with_g(q)).collect();
        p.points = simplify(&m, &path, 0.1 * r.cell)
            .into_iter()
            .map(|q| q.0)
            .collect();
    }
    Some(Clearing {
        section: eval.section,
        tool_radius,
        allowance,
        stepover,
        margin,
        rings: main.len() + side.len(),
        passes,
    })
}
