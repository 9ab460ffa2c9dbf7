//! The grid's orientation against the part frame.
//!
//! A tri-dexel grid removes a vertical tool fast: each Z ray meets it in one interval of
//! closed form, and the engagement reads one ray per angular bin. A tool on a fixed tilted
//! axis (a 3+2 setup) meets every ray along a line instead, and costs several times more.
//! Turning the grid so that its z is that fixed axis makes the tilted tool a vertical one
//! in the grid: the same exact removal at the vertical tool's speed. Everything entering
//! the geometry engine (stock, tool path) is turned into the grid frame and everything
//! leaving it (step positions, engagement directions, the exported mesh) back.

use crate::vec3::{cross, dot, norm, scale};

/// A grid turned along a tool axis holds more rays than one along the part's axes (a tall
/// box turned 15° is taller); over this factor the grid stays along the part's axes (the
/// job's memory estimate allows for it).
pub const MAX_TURNED_GRID_GROWTH: f64 = 1.5;

/// A rotation from the part frame into the grid frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridFrame {
    /// The grid's axes in part coordinates (the rows of the rotation).
    rows: [[f64; 3]; 3],
}

impl Default for GridFrame {
    fn default() -> Self {
        GridFrame::IDENTITY
    }
}

impl GridFrame {
    /// The grid along the part's axes.
    pub const IDENTITY: GridFrame = GridFrame {
        rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    };

    /// The smallest rotation that takes the unit vector `axis` to the grid's +z (a tilt
    /// about the horizontal line normal to the axis: a tilt about x keeps x). `None` for a
    /// vector that is not finite and of unit length.
    pub fn with_z_along(axis: [f64; 3]) -> Option<GridFrame> {
        let n = norm(axis);
        if !n.is_finite() || (n - 1.0).abs() > 1e-9 {
            return None;
        }
        let a = scale(axis, 1.0 / n);
        if (a[2] - 1.0).abs() < 1e-15 {
            return Some(GridFrame::IDENTITY);
        }
        let z = [0.0, 0.0, 1.0];
        let k = cross(a, z);
        let s = norm(k);
        let c = a[2];
        if s < 1e-15 {
            // Pointing down: a half turn about x.
            return Some(GridFrame {
                rows: [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            });
        }
        let k = scale(k, 1.0 / s);
        // Rodrigues: R v = v cos θ + (k × v) sin θ + k (k·v)(1 − cos θ), applied to e_j
        // gives the columns.
        let col = |e: [f64; 3]| {
            let kv = cross(k, e);
            let kd = dot(k, e) * (1.0 - c);
            [
                e[0] * c + kv[0] * s + k[0] * kd,
                e[1] * c + kv[1] * s + k[1] * kd,
                e[2] * c + kv[2] * s + k[2] * kd,
            ]
        };
        let cols = [
            col([1.0, 0.0, 0.0]),
            col([0.0, 1.0, 0.0]),
            col([0.0, 0.0, 1.0]),
        ];
        Some(GridFrame {
            rows: std::array::from_fn(|i| [cols[0][i], cols[1][i], cols[2][i]]),
        })
    }

    pub fn is_identity(&self) -> bool {
        *self == GridFrame::IDENTITY
    }

    /// A point or direction of the part frame in grid coordinates.
    pub fn to_grid(&self, p: [f64; 3]) -> [f64; 3] {
        [
            dot(self.rows[0], p),
            dot(self.rows[1], p),
            dot(self.rows[2], p),
        ]
    }

    /// A point or direction of the grid frame in part coordinates.
    pub fn to_part(&self, q: [f64; 3]) -> [f64; 3] {
        let r = &self.rows;
        std::array::from_fn(|k| q[0] * r[0][k] + q[1] * r[1][k] + q[2] * r[2][k])
    }

    /// Grid axis `a` (0, 1, 2) in part coordinates.
    pub fn axis_in_part(&self, a: usize) -> [f64; 3] {
        self.rows[a]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_axis_becomes_z_and_lengths_and_handedness_stay() {
        let t = 15f64.to_radians();
        for axis in [
            [0.0, -t.sin(), t.cos()],
            [0.3, 0.4, (1.0f64 - 0.25).sqrt()],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, -1.0],
            [-0.6, 0.0, -0.8],
        ] {
            let f = GridFrame::with_z_along(axis).unwrap();
            let z = f.to_grid(axis);
            assert!((z[0]).abs() < 1e-12 && (z[1]).abs() < 1e-12 && (z[2] - 1.0).abs() < 1e-12);
            let p = [3.0, -7.0, 11.0];
            let q = f.to_grid(p);
            assert!((norm(q) - norm(p)).abs() < 1e-12);
            let back = f.to_part(q);
            assert!((0..3).all(|k| (back[k] - p[k]).abs() < 1e-12));
            // A rotation, not a reflection: x × y = z in both frames.
            let (x, y) = (f.axis_in_part(0), f.axis_in_part(1));
            let zz = cross(x, y);
            assert!((0..3).all(|k| (zz[k] - f.axis_in_part(2)[k]).abs() < 1e-12));
        }
        // A tilt about x keeps x.
        let f = GridFrame::with_z_along([0.0, -t.sin(), t.cos()]).unwrap();
        assert_eq!(f.axis_in_part(0), [1.0, 0.0, 0.0]);
        assert!(GridFrame::with_z_along([0.0, 0.0, 1.0])
            .unwrap()
            .is_identity());
        assert!(GridFrame::with_z_along([0.0, 0.0, 2.0]).is_none());
    }
}
