//! The workpiece: a tri-dexel grid filled from a parametric block or cylinder, or from an
//! STL mesh (see `stl.rs`).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::dexel::{other_axes, DexelGrid, GridEstimate, GridOptions, Intervals};
use super::frame::GridFrame;
use super::GeometryError;

/// A parametric stock shape, in the part frame, mm.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StockShape {
    /// Axis-aligned box.
    Block { min: [f64; 3], max: [f64; 3] },
    /// Cylinder with its axis along +z, `base_center` the centre of the bottom face.
    Cylinder {
        base_center: [f64; 3],
        radius: f64,
        height: f64,
    },
}

/// The material being machined.
#[derive(Clone, Debug)]
pub struct Stock {
    /// The rays, in the grid frame.
    pub grid: DexelGrid,
    /// How the grid is turned against the part frame (identity unless a fixed tilted tool
    /// axis asked for the grid along it).
    pub frame: GridFrame,
}

fn check_finite(what: &str, v: &[f64]) -> Result<(), GeometryError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(GeometryError::InvalidStock(format!(
            "{what} must be finite numbers, got {v:?}"
        )))
    }
}

/// Largest stock dimension accepted, mm (10 m): anything bigger is a unit mistake.
pub const MAX_STOCK_SIZE: f64 = 10_000.0;

impl StockShape {
    pub fn bounds(&self) -> Result<([f64; 3], [f64; 3]), GeometryError> {
        let (min, max) = match *self {
            StockShape::Block { min, max } => {
                check_finite(
                    "block corners",
                    &[min[0], min[1], min[2], max[0], max[1], max[2]],
                )?;
                (min, max)
            }
            StockShape::Cylinder {
                base_center: c,
                radius,
                height,
            } => {
                check_finite("cylinder", &[c[0], c[1], c[2], radius, height])?;
                if radius <= 0.0 || height <= 0.0 {
                    return Err(GeometryError::InvalidStock(format!(
                        "cylinder radius and height must be positive, got {radius} and {height}"
                    )));
                }
                (
                    [c[0] - radius, c[1] - radius, c[2]],
                    [c[0] + radius, c[1] + radius, c[2] + height],
                )
            }
        };
        for a in 0..3 {
            let e = max[a] - min[a];
            if !(e > 0.0) {
                return Err(GeometryError::InvalidStock(format!(
                    "stock is empty along {}: min {} max {}",
                    ["x", "y", "z"][a],
                    min[a],
                    max[a]
                )));
            }
            if e > MAX_STOCK_SIZE {
                return Err(GeometryError::InvalidStock(format!(
                    "stock is {e} mm along {}: larger than {MAX_STOCK_SIZE} mm",
                    ["x", "y", "z"][a]
                )));
            }
        }
        Ok((min, max))
    }

    /// Grid size and memory before allocation.
    pub fn estimate(&self, cell: f64) -> Result<GridEstimate, GeometryError> {
        let (min, max) = self.bounds()?;
        DexelGrid::estimate(min, max, cell)
    }

    /// The shape's bounding box in the grid frame `frame`.
    pub fn bounds_in(&self, frame: &GridFrame) -> Result<([f64; 3], [f64; 3]), GeometryError> {
        let (min, max) = self.bounds()?;
        if frame.is_identity() {
            return Ok((min, max));
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let mut take = |q: [f64; 3], reach: [f64; 3]| {
            for k in 0..3 {
                lo[k] = lo[k].min(q[k] - reach[k]);
                hi[k] = hi[k].max(q[k] + reach[k]);
            }
        };
        match *self {
            StockShape::Block { .. } => {
                for c in 0..8 {
                    let corner =
                        std::array::from_fn(|k| if c >> k & 1 == 0 { min[k] } else { max[k] });
                    take(frame.to_grid(corner), [0.0; 3]);
                }
            }
            StockShape::Cylinder {
                base_center: c,
                radius,
                height,
            } => {
                // Each end circle reaches r·sqrt(1 − w_k²) from its centre along grid axis
                // k, w the cylinder's axis in the grid frame.
                let w = frame.to_grid([0.0, 0.0, 1.0]);
                let reach = w.map(|wk| radius * (1.0 - wk * wk).max(0.0).sqrt());
                take(frame.to_grid(c), reach);
                take(frame.to_grid([c[0], c[1], c[2] + height]), reach);
            }
        }
        Ok((lo, hi))
    }

    /// The material of this shape along the line `p0 + t·d` (part frame, `d` a unit
    /// vector), as a range of t, if any.
    fn line_interval(&self, p0: [f64; 3], d: [f64; 3]) -> Option<[f64; 2]> {
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        // Between two planes normal to part axis k.
        let slab = |k: usize, a: f64, b: f64, lo: &mut f64, hi: &mut f64| {
            if d[k].abs() < 1e-15 {
                if p0[k] < a || p0[k] > b {
                    *hi = f64::NEG_INFINITY;
                }
            } else {
                let (t1, t2) = ((a - p0[k]) / d[k], (b - p0[k]) / d[k]);
                *lo = lo.max(t1.min(t2));
                *hi = hi.min(t1.max(t2));
            }
        };
        match *self {
            StockShape::Block { min, max } => {
                for k in 0..3 {
                    slab(k, min[k], max[k], &mut lo, &mut hi);
                }
            }
            StockShape::Cylinder {
                base_center: c,
                radius,
                height,
            } => {
                slab(2, c[2], c[2] + height, &mut lo, &mut hi);
                let (ex, ey) = (p0[0] - c[0], p0[1] - c[1]);
                let a = d[0] * d[0] + d[1] * d[1];
                let b = 2.0 * (ex * d[0] + ey * d[1]);
                let cc = ex * ex + ey * ey - radius * radius;
                if a < 1e-15 {
                    if cc > 0.0 {
                        return None;
                    }
                } else {
                    let disc = b * b - 4.0 * a * cc;
                    if disc < 0.0 {
                        return None;
                    }
                    let r = disc.sqrt();
                    lo = lo.max((-b - r) / (2.0 * a));
                    hi = hi.min((-b + r) / (2.0 * a));
                }
            }
        }
        (lo <= hi).then_some([lo, hi])
    }

    /// The material interval of this shape along one ray, if any.
    fn ray_interval(&self, axis: usize, u: f64, v: f64) -> Option<[f64; 2]> {
        let (ua, va) = other_axes(axis);
        match *self {
            StockShape::Block { min, max } => {
                if u < min[ua] || u > max[ua] || v < min[va] || v > max[va] {
                    None
                } else {
                    Some([min[axis], max[axis]])
                }
            }
            StockShape::Cylinder {
                base_center: c,
                radius,
                height,
            } => {
                let mut p = [0.0; 3];
                p[ua] = u;
                p[va] = v;
                if axis == 2 {
                    let d2 = (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2);
                    (d2 <= radius * radius).then_some([c[2], c[2] + height])
                } else {
                    if p[2] < c[2] || p[2] > c[2] + height {
                        return None;
                    }
                    // Horizontal ray: chord of the circle at the ray's cross coordinate.
                    let cross = 1 - axis;
                    let d = p[cross] - c[cross];
                    let h2 = radius * radius - d * d;
                    (h2 >= 0.0).then(|| [c[axis] - h2.sqrt(), c[axis] + h2.sqrt()])
                }
            }
        }
    }
}

impl Stock {
    /// Fills a grid from a parametric shape; `opts.cell` must be set (see `default_cell`).
    pub fn from_shape(shape: &StockShape, opts: &GridOptions) -> Result<Stock, GeometryError> {
        Stock::from_shape_in(shape, opts, GridFrame::IDENTITY)
    }

    /// As [`Stock::from_shape`], with the grid turned by `frame`.
    pub fn from_shape_in(
        shape: &StockShape,
        opts: &GridOptions,
        frame: GridFrame,
    ) -> Result<Stock, GeometryError> {
        let cell = opts
            .cell
            .ok_or_else(|| GeometryError::InvalidGrid("no cell size given".into()))?;
        let (lo, max) = shape.bounds_in(&frame)?;
        // The top face on a cell boundary: depths are cut from the top, so the X and Y
        // rays then sample a cut's depth from a boundary rather than from a stray
        // fraction of a cell (the bottom takes the fraction instead).
        let nz = DexelGrid::estimate(lo, max, cell)?.cells[2];
        let mut min = lo;
        min[2] = max[2] - nz as f64 * cell;
        let mut grid = DexelGrid::new(min, max, cell, opts.memory_limit)?;
        grid.set_extent(lo, max);
        for a in 0..3 {
            let (ua, va) = other_axes(a);
            let nu = grid.families[a].nu;
            let centers_u: Vec<f64> = (0..nu).map(|i| grid.center(ua, i)).collect();
            let centers_v: Vec<f64> = (0..grid.families[a].nv)
                .map(|i| grid.center(va, i))
                .collect();
            grid.families[a]
                .rays
                .par_iter_mut()
                .enumerate()
                .for_each(|(k, ray)| {
                    let (u, v) = (centers_u[k % nu], centers_v[k / nu]);
                    let iv = if frame.is_identity() {
                        shape.ray_interval(a, u, v)
                    } else {
                        // The ray's point at grid coordinate 0 along it, in the part frame.
                        let mut q = [0.0; 3];
                        q[ua] = u;
                        q[va] = v;
                        shape.line_interval(frame.to_part(q), frame.axis_in_part(a))
                    };
                    if let Some(iv) = iv {
                        *ray = Intervals::from_slice(&[iv]);
                    }
                });
        }
        Ok(Stock { grid, frame })
    }

    pub fn block(min: [f64; 3], max: [f64; 3], cell: f64) -> Result<Stock, GeometryError> {
        Stock::from_shape(
            &StockShape::Block { min, max },
            &GridOptions {
                cell: Some(cell),
                ..Default::default()
            },
        )
    }

    pub fn cylinder(
        base_center: [f64; 3],
        radius: f64,
        height: f64,
        cell: f64,
    ) -> Result<Stock, GeometryError> {
        Stock::from_shape(
            &StockShape::Cylinder {
                base_center,
                radius,
                height,
            },
            &GridOptions {
                cell: Some(cell),
                ..Default::default()
            },
        )
    }

    /// Current stock volume, mm³ (mean of the three dexel families).
    pub fn volume(&self) -> f64 {
        self.grid.volume()
    }
}
