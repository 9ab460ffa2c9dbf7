//! The workpiece: a tri-dexel grid filled from a parametric block or cylinder, or from an
//! STL mesh (see `stl.rs`).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::dexel::{other_axes, DexelGrid, GridEstimate, GridOptions, Intervals};
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
    pub grid: DexelGrid,
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
        let cell = opts
            .cell
            .ok_or_else(|| GeometryError::InvalidGrid("no cell size given".into()))?;
        let (mut min, max) = shape.bounds()?;
        // The top face on a cell boundary: depths are cut from the top, so the X and Y
        // rays then sample a cut's depth from a boundary rather than from a stray
        // fraction of a cell (the bottom takes the fraction instead).
        let nz = DexelGrid::estimate(min, max, cell)?.cells[2];
        min[2] = max[2] - nz as f64 * cell;
        let mut grid = DexelGrid::new(min, max, cell, opts.memory_limit)?;
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
                    if let Some(iv) = shape.ray_interval(a, centers_u[k % nu], centers_v[k / nu]) {
                        *ray = Intervals::from_slice(&[iv]);
                    }
                });
        }
        Ok(Stock { grid })
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
