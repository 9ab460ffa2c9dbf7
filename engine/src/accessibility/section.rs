//! The section plane of one candidate axis: its origin (the point to reach), the axis
//! (normal to the plane, pointing out of the part) and two in-plane directions, so that a
//! part point reads as a 2-D position on the plane and a height above it.

use crate::vec3::{cross, dot, norm, scale, sub};

type V3 = [f64; 3];

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Section {
    pub origin: V3,
    /// Unit tool axis: from the section towards the inlet.
    pub axis: V3,
    pub e1: V3,
    pub e2: V3,
}

impl Section {
    /// The plane through `origin` normal to the unit vector `axis`. `e1` is the part's x
    /// (or y, when the axis is near x) made normal to the axis, so the in-plane frame turns
    /// smoothly with the axis and pictures of nearby axes line up.
    pub fn new(origin: V3, axis: V3) -> Section {
        let reference = if axis[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let e2 = cross(axis, reference);
        let e2 = scale(e2, 1.0 / norm(e2));
        let e1 = cross(e2, axis);
        Section {
            origin,
            axis,
            e1,
            e2,
        }
    }

    /// A part point as (position on the plane, height above it along the axis).
    #[inline]
    pub fn local(&self, p: V3) -> [f64; 3] {
        let d = sub(p, self.origin);
        [dot(d, self.e1), dot(d, self.e2), dot(d, self.axis)]
    }

    /// The part point at plane position `q`, height `t`.
    pub fn point(&self, q: [f64; 2], t: f64) -> V3 {
        std::array::from_fn(|k| {
            self.origin[k] + q[0] * self.e1[k] + q[1] * self.e2[k] + t * self.axis[k]
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn local_and_point_are_inverse_and_the_frame_is_right_handed() {
        for axis in [
            [0.0, 0.0, 1.0],
            [0.6, 0.0, 0.8],
            [1.0, 0.0, 0.0],
            [0.0, -0.6, -0.8],
        ] {
            let s = Section::new([1.0, 2.0, 3.0], axis);
            let c = cross(s.e1, s.e2);
            assert!((0..3).all(|k| (c[k] - axis[k]).abs() < 1e-12), "{axis:?}");
            let p = [4.0, -5.0, 6.5];
            let l = s.local(p);
            let q = s.point([l[0], l[1]], l[2]);
            assert!((0..3).all(|k| (q[k] - p[k]).abs() < 1e-12));
        }
    }
}
