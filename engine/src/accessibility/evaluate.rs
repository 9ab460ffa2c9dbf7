//! One candidate axis, evaluated: the part seen from the section along the axis (walls at
//! every level height), the free region's component that holds the point to reach, its area,
//! and the largest tool radius that clears there.

use rayon::prelude::*;

use super::body::{Level, LevelWalls};
use super::circle::{self, Circle};
pub use super::circle::{FINAL, SEARCHING};
use super::region::{self, Raster};
use super::section::Section;
use super::walls::{Walls, Window};

/// The part's vertices and triangles (borrowed from the mesh, projected per axis), its
/// shells turned outward (`orient`): only the faces facing the axis are projected.
pub struct Part<'m> {
    pub vertices: &'m [[f64; 3]],
    pub triangles: &'m [[u32; 3]],
}

/// What every evaluation shares: the part, the allowance and the holder's levels (the
/// cutter's level, at height 0, is the unknown radius).
pub struct Setup<'a> {
    pub part: &'a Part<'a>,
    pub allowance: f64,
    pub holder: &'a [Level],
}

/// The outcome for one axis.
#[derive(Clone, Debug)]
pub struct Evaluation {
    pub section: Section,
    /// The largest cutter radius that clears (0: none), and where its axis crosses the plane.
    pub circle: Option<Circle>,
    /// Area of the free component holding the point to reach, mm² (to the raster's cells).
    pub area: f64,
    /// The component reaches the window's edge: the passage is not closed around it there.
    pub open: bool,
    /// Farthest reach of the component from the section point, mm.
    pub reach: f64,
    pub raster: Raster,
}

impl Evaluation {
    /// How far the free piece reaches from the section point (to its farthest cell's
    /// corner); `None` when it is empty or reaches the window's edge.
    pub fn extent(&self) -> Option<f64> {
        if self.open || self.area == 0.0 {
            return None;
        }
        Some(self.reach)
    }

    pub fn radius(&self) -> f64 {
        self.circle.map_or(0.0, |c| c.radius)
    }

    /// Larger tool first; on (near) equal tools the larger free area.
    pub fn better_than(&self, other: &Evaluation) -> bool {
        let (a, b) = (self.radius(), other.radius());
        if (a - b).abs() > 1e-7 {
            a > b
        } else {
            self.area > other.area
        }
    }
}

/// The raster and walls of an evaluation, kept for the chosen axes (tool choice, plunge
/// points, pictures).
pub struct Detail {
    pub local: Vec<[f64; 3]>,
    pub covered: Vec<bool>,
    pub component: Vec<bool>,
    pub bound: Vec<f64>,
    pub walls: LevelWalls,
}

/// The projected part's box on the plane (a tool outside it is not in the part at all).
pub fn part_window(local: &[[f64; 3]]) -> Window {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for v in local {
        for a in 0..2 {
            lo[a] = lo[a].min(v[a]);
            hi[a] = hi[a].max(v[a]);
        }
    }
    let margin = 1e-3 * (hi[0] - lo[0]).max(hi[1] - lo[1]) + 1e-6;
    Window {
        lo: [lo[0] - margin, lo[1] - margin],
        hi: [hi[0] + margin, hi[1] + margin],
    }
}

/// Evaluates `axis` for the section through `target`: over `window` (default: the part's
/// projected box) at `cells` cells a side. `extra` lists more levels to build walls for
/// (a tool list's shanks and holders).
pub fn evaluate(
    setup: &Setup,
    target: [f64; 3],
    axis: [f64; 3],
    window: Option<Window>,
    cells: usize,
    extra: &[Level],
    effort: circle::Effort,
) -> (Evaluation, Detail) {
    let section = Section::new(target, axis);
    let local: Vec<[f64; 3]> = setup
        .part
        .vertices
        .par_iter()
        .map(|&v| section.local(v))
        .collect();
    let window = window.unwrap_or_else(|| part_window(&local));
    let raster = Raster::over(window, cells);
    // Each level's walls over the window grown by the level's widest body (the window's
    // edge stands for the part's bounds only for the cutter): every wall that can come
    // within a body's reach of a point of the raster is in.
    let mut levels: Vec<(f64, f64)> = vec![(0.0, 0.0)];
    for l in setup.holder.iter().chain(extra) {
        let reach = l.radius + setup.allowance + 1.0;
        match levels.iter_mut().find(|(h, _)| *h == l.height) {
            Some(e) => e.1 = e.1.max(reach),
            None => levels.push((l.height, reach)),
        }
    }
    levels.sort_by(|a, b| a.0.total_cmp(&b.0));
    let walls = LevelWalls {
        levels: levels
            .iter()
            .map(|&(h, m)| {
                let w = raster.window;
                let grown = Window {
                    lo: [w.lo[0] - m, w.lo[1] - m],
                    hi: [w.hi[0] + m, w.hi[1] + m],
                };
                (
                    h,
                    Walls::build_from(
                        &local,
                        setup.part.triangles,
                        h,
                        if h == 0.0 { w } else { grown },
                        true,
                    ),
                )
            })
            .collect(),
    };
    let covered = region::coverage(&raster, &walls.walls_at(0.0).polygons);
    let component = match raster.cell_of([0.0, 0.0]) {
        Some(start) => region::component(&raster, &covered, start),
        None => vec![false; raster.len()],
    };
    let bound = region::distance_to_walls(&raster, &covered);
    let cutter = walls.walls_at(0.0);
    let allowance = setup.allowance;
    let fit = |c: [f64; 2], floor: f64, cap: f64| {
        let r = cutter.clearance_within(c, floor + allowance, cap) - allowance;
        if r <= floor {
            // Not wanted: no holder check either.
            return floor.min(-1.0);
        }
        if r <= 0.0 || !walls.fits(setup.holder, allowance, c) {
            return -1.0;
        }
        r
    };
    let circle = circle::largest(&raster, &component, &bound, allowance, &fit, effort);
    let count = component.iter().filter(|&&c| c).count();
    let (nx, ny) = (raster.nx, raster.ny);
    let open = (0..raster.len()).any(|k| {
        component[k] && {
            let (x, y) = (k % nx, k / nx);
            x == 0 || y == 0 || x + 1 == nx || y + 1 == ny
        }
    });
    let reach = (0..raster.len())
        .filter(|&k| component[k])
        .map(|k| {
            let c = raster.center(k);
            c[0].hypot(c[1])
        })
        .fold(0.0, f64::max)
        + raster.cell;
    (
        Evaluation {
            section,
            circle,
            area: count as f64 * raster.cell * raster.cell,
            open,
            reach,
            raster,
        },
        Detail {
            local,
            covered,
            component,
            bound,
            walls,
        },
    )
}

/// The window around a component (a few cells of margin), for a finer look at it.
pub fn component_window(e: &Evaluation, d: &Detail) -> Option<Window> {
    let r = &e.raster;
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for k in (0..r.len()).filter(|&k| d.component[k]) {
        let c = r.center(k);
        for a in 0..2 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    (lo[0] <= hi[0]).then(|| {
        let m = 3.0 * r.cell;
        Window {
            lo: [lo[0] - m, lo[1] - m],
            hi: [hi[0] + m, hi[1] + m],
        }
    })
}
