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

#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
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
}

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
    fill_grid(&mut pg, &part)?;
    let h2 = g.cell * g.cell;
    let mut gouge = [0.0; 3];
    let mut max_depth: f64 = 0.0;
    for fam in 0..3 {
        for (sr, pr) in g.families[fam]
            .rays
            .iter()
            .zip(pg.families[fam].rays.iter())
        {
            if pr.is_empty() {
                continue;
            }
            let d = difference(pr, sr);
            gouge[fam] += interval_length(&d);
            if fam == 2 {
                for iv in d.iter() {
                    max_depth = max_depth.max(iv[1] - iv[0]);
                }
            }
        }
    }
    let mut out = PartComparison {
        gouge_volume: (gouge[0] + gouge[1] + gouge[2]) / 3.0 * h2,
        max_gouge_depth: max_depth,
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
