//! [`ToolFrame`]: the tool frame of a step (x the feed across the axis, z the tool axis) in
//! part coordinates.

use serde::{Deserialize, Serialize};

use crate::engagement::Engagement;
use crate::physics::PhysicsError;
use crate::vec3::{cross, dot, norm, scale, sub};

/// Orthonormal tool frame of a step, in part coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ToolFrame {
    /// Feed direction projected perpendicular to the axis (x of the Engagement frame).
    pub x: [f64; 3],
    pub y: [f64; 3],
    /// Tool axis, tip to spindle.
    pub z: [f64; 3],
    /// Component of the unit feed direction across the axis (cos of the ramp angle).
    pub feed_across: f64,
    /// Component of the unit feed direction along the axis (positive: moving up).
    pub feed_along: f64,
}

impl ToolFrame {
    pub const IDENTITY: ToolFrame = ToolFrame {
        x: [1.0, 0.0, 0.0],
        y: [0.0, 1.0, 0.0],
        z: [0.0, 0.0, 1.0],
        feed_across: 1.0,
        feed_along: 0.0,
    };

    /// The Engagement frame: z the tool axis, x the feed direction projected perpendicular to it,
    /// y = z × x. A pure plunge has no such x; then x is the part X (or Y) projected.
    pub fn from_engagement(e: &Engagement) -> Result<ToolFrame, PhysicsError> {
        let z = unit("tool_axis", e.tool_axis)?;
        let f = unit("feed_dir", e.feed_dir)?;
        let along = dot(f, z);
        let h = sub(f, scale(z, along));
        let across = norm(h);
        let x = if across > 1e-9 {
            scale(h, 1.0 / across)
        } else {
            crate::engagement::plunge_x(z)
        };
        let y = cross(z, x);
        Ok(ToolFrame {
            x,
            y,
            z,
            feed_across: across,
            feed_along: along,
        })
    }

    /// A tool-frame vector in part coordinates.
    pub fn to_part(&self, v: [f64; 3]) -> [f64; 3] {
        [
            v[0] * self.x[0] + v[1] * self.y[0] + v[2] * self.z[0],
            v[0] * self.x[1] + v[1] * self.y[1] + v[2] * self.z[1],
            v[0] * self.x[2] + v[1] * self.y[2] + v[2] * self.z[2],
        ]
    }
}

fn unit(field: &str, v: [f64; 3]) -> Result<[f64; 3], PhysicsError> {
    for (i, c) in v.iter().enumerate() {
        if !c.is_finite() {
            return Err(PhysicsError::NotFinite {
                field: format!("{field}[{i}]"),
                value: *c,
            });
        }
    }
    let n = norm(v);
    if n.is_nan() || n <= 1e-12 || !n.is_finite() {
        return Err(PhysicsError::invalid(field, "must be a non-zero vector"));
    }
    Ok(scale(v, 1.0 / n))
}
