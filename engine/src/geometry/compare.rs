//! The finished stock against the design part: gouges (part material that was cut away)
//! and the allowance left on the part.
//!
//! The part mesh is cast onto a grid identical to the stock's (same origin, cell and
//! rays), so the two compare ray by ray: gouge = part minus stock along every ray of the
//! three families (volume as the family mean, like the stock's), allowance = on every Z
//! ray through the part, the stock's top minus the part's top (negative where gouged).

use serde::{Deserialize, Serialize};

use super::dexel::{interval_length, DexelGrid, Intervals};
use super::stl::{fill_grid, Mesh};
use super::stock::Stock;
use super::GeometryError;

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PartComparison {
    /// Volume of part material no longer in the stock, mm³.
    pub gouge_volume: f64,
    /// Longest gouged run along a Z ray, mm.
    pub max_gouge_depth: f64,
    /// Z rays through the part (where the allowance is measured).
    pub part_rays: u64,
    /// Stock top minus part top over the Z rays through the part, mm (along the grid's z:
    /// the tool axis where the grid is turned along a 3+2 program's axis).
    pub allowance_min: f64,
    pub allowance_mean: f64,
    pub allowance_max: f64,
    /// Where the gouges are: the gouged Z rays joined into regions (rays side by side),
    /// the largest first, at most [`MAX_GOUGE_REGIONS`] (`gouge_regions` counts them all).
    /// A gouge into a wall thinner than a cell, seen by the X and Y rays only, counts in
    /// the volume but has no region.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub gouges: Vec<GougeRegion>,
    #[serde(default)]
    pub gouge_regions: usize,
}

/// One gouged region, in the part frame, mm and mm³.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GougeRegion {
    /// The middle of its deepest gouged run along a Z ray.
    pub at: [f64; 3],
    /// That run's length (the region's depth) and the region's volume on the Z rays.
    pub depth: f64,
    pub volume: f64,
    /// The box around it (around its rays' cells and gouged runs).
    pub min: [f64; 3],
    pub max: [f64; 3],
}

/// The summary places at most this many gouge regions (the largest).
pub const MAX_GOUGE_REGIONS: usize = 100;

/// Gouges thinner than this are rounding between the mesh's and the stock's numbers, mm.
const GOUGE_EPS: f64 = 1e-9;

/// Material of `a` not in `b`.
fn difference(a: &Intervals, b: &Intervals) -> Intervals {
    let mut out = a.clone();
    for iv in b.iter() {
        super::dexel::subtract(&mut out, iv[0], iv[1]);
    }
    out.retain(|iv| iv[1] - iv[0] > GOUGE_EPS);
    out
}

/// Compares the stock with the design part (placed in the same frame).
pub fn compare_with_part(stock: &Stock, part: &Mesh) -> Result<PartComparison, GeometryError> {
    let g = &stock.grid;
    let part = part.in_frame(&stock.frame);
    let mut pg = DexelGrid::new(g.origin, g.max_corner(), g.cell, u64::MAX)?;
    // Same cell count as the stock (the constructor rounds the extent up the same way).
    debug_assert_eq!(pg.n, g.n);
    pg.edges = g.edges.clone();
    fill_grid(&mut pg, &part)?;
    let mut gouge = [0.0; 3];
    let mut max_depth: f64 = 0.0;
    for fam in 0..3 {
        for (k, (sr, pr)) in g.families[fam]
            .rays
            .iter()
            .zip(pg.families[fam].rays.iter())
            .enumerate()
        {
            if pr.is_empty() {
                continue;
            }
            let d = difference(pr, sr);
            gouge[fam] += interval_length(&d) * g.ray_area(fam, k);
            if fam == 2 {
                for iv in d.iter() {
                    max_depth = max_depth.max(iv[1] - iv[0]);
                }
            }
        }
    }
    let (gouges, gouge_regions) = gouge_regions(stock, &pg);
    let mut out = PartComparison {
        gouge_volume: (gouge[0] + gouge[1] + gouge[2]) / 3.0,
        max_gouge_depth: max_depth,
        gouges,
        gouge_regions,
        allowance_min: f64::INFINITY,
        allowance_max: f64::NEG_INFINITY,
        ..Default::default()
    };
    let mut sum = 0.0;
    for (sr, pr) in g.families[2].rays.iter().zip(pg.families[2].rays.iter()) {
        let Some(ptop) = pr.last().map(|iv| iv[1]) else {
            continue;
        };
        let stop = sr.last().map_or(f64::NEG_INFINITY, |iv| iv[1]);
        // A ray whose stock is all gone counts from the part's bottom.
        let stop = if stop.is_finite() { stop } else { pr[0][0] };
        let a = stop - ptop;
        out.part_rays += 1;
        sum += a;
        out.allowance_min = out.allowance_min.min(a);
        out.allowance_max = out.allowance_max.max(a);
    }
    if out.part_rays > 0 {
        out.allowance_mean = sum / out.part_rays as f64;
    } else {
        out.allowance_min = 0.0;
        out.allowance_max = 0.0;
    }
    Ok(out)
}

/// The gouged Z rays of the stock against the part grid `pg`, joined into regions of rays
/// side by side (4-neighbours), the largest by volume first, at most
/// [`MAX_GOUGE_REGIONS`]; and how many regions there are.
fn gouge_regions(stock: &Stock, pg: &DexelGrid) -> (Vec<GougeRegion>, usize) {
    let g = &stock.grid;
    let (sf, pf) = (&g.families[2], &pg.families[2]);
    let (nu, nv) = (sf.nu, sf.nv);
    // Per gouged ray: its gouged length and its deepest run (bottom, top).
    let mut gouged: Vec<(usize, f64, [f64; 2], [f64; 2])> = Vec::new();
    for (r, (sr, pr)) in sf.rays.iter().zip(pf.rays.iter()).enumerate() {
        if pr.is_empty() {
            continue;
        }
        let d = difference(pr, sr);
        if d.is_empty() {
            continue;
        }
        let deepest = d
            .iter()
            .copied()
            .max_by(|a, b| (a[1] - a[0]).total_cmp(&(b[1] - b[0])))
            .expect("not empty");
        let span = [d[0][0], d[d.len() - 1][1]];
        gouged.push((r, interval_length(&d), deepest, span));
    }
    if gouged.is_empty() {
        return (Vec::new(), 0);
    }
    // Labels per Z ray (only where there is a gouge): u32::MAX is none, else the index in
    // `gouged`; then a flood fill over the 4-neighbours.
    let mut at = vec![u32::MAX; nu * nv];
    for (k, &(r, ..)) in gouged.iter().enumerate() {
        at[r] = k as u32;
    }
    let mut seen = vec![false; gouged.len()];
    let mut regions = Vec::new();
    let mut stack = Vec::new();
    let h = g.cell;
    for start in 0..gouged.len() {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut volume = 0.0;
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        // The region's rays: (x, y, its deepest run).
        let mut members: Vec<(f64, f64, [f64; 2])> = Vec::new();
        while let Some(k) = stack.pop() {
            let (r, len, run, span) = gouged[k];
            let (i, j) = (r % nu, r / nu);
            let (x, y) = (g.center(0, i), g.center(1, j));
            volume += len * g.ray_area(2, r);
            for (a, c) in [(0, x), (1, y)] {
                lo[a] = lo[a].min(c - h / 2.0);
                hi[a] = hi[a].max(c + h / 2.0);
            }
            lo[2] = lo[2].min(span[0]);
            hi[2] = hi[2].max(span[1]);
            members.push((x, y, run));
            let mut visit = |n: usize| {
                let m = at[n];
                if m != u32::MAX && !seen[m as usize] {
                    seen[m as usize] = true;
                    stack.push(m as usize);
                }
            };
            if i > 0 {
                visit(r - 1);
            }
            if i + 1 < nu {
                visit(r + 1);
            }
            if j > 0 {
                visit(r - nu);
            }
            if j + 1 < nv {
                visit(r + nu);
            }
        }
        // Where it is deepest: of the rays as deep as the deepest (a flat floor has many),
        // the one nearest their middle.
        let depth = members.iter().map(|m| m.2[1] - m.2[0]).fold(0.0, f64::max);
        let deep: Vec<&(f64, f64, [f64; 2])> = members
            .iter()
            .filter(|m| m.2[1] - m.2[0] >= depth - 1e-9)
            .collect();
        let n = deep.len() as f64;
        let (cx, cy) = (
            deep.iter().map(|m| m.0).sum::<f64>() / n,
            deep.iter().map(|m| m.1).sum::<f64>() / n,
        );
        let mid = deep
            .iter()
            .min_by(|a, b| {
                let d = |m: &&&(f64, f64, [f64; 2])| (m.0 - cx).powi(2) + (m.1 - cy).powi(2);
                d(a).total_cmp(&d(b))
            })
            .expect("a region has a ray");
        let p = [mid.0, mid.1, (mid.2[0] + mid.2[1]) / 2.0];
        // The box in the part frame: around the grid box's eight corners turned back.
        let (mut min, mut max) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for c in 0..8 {
            let q = [0, 1, 2].map(|a| if c & (1 << a) == 0 { lo[a] } else { hi[a] });
            let q = stock.frame.to_part(q);
            for a in 0..3 {
                min[a] = min[a].min(q[a]);
                max[a] = max[a].max(q[a]);
            }
        }
        regions.push(GougeRegion {
            at: stock.frame.to_part(p),
            depth,
            volume,
            min,
            max,
        });
    }
    let count = regions.len();
    regions.sort_by(|a, b| b.volume.total_cmp(&a.volume));
    regions.truncate(MAX_GOUGE_REGIONS);
    (regions, count)
}
