//! Machine kinematics: machine axes (X Y Z in mm, A B C in degrees, the order of
//! [`crate::nc::Move::end`]) to the tool tip and tool axis in the part frame, and back.
//!
//! Conventions (right-handed, angles in degrees at the edges):
//! * The part frame is the machine frame with every rotary axis at zero.
//! * X Y Z are the tool tip in the machine frame (tool length already applied), except on a
//!   head-table machine where they are the tip position the head would have at B = 0 (the
//!   controlled point is the B pivot, `pivot_length` above the tip).
//! * Table axes turn the part: a point fixed to the table at part position p sits in the machine
//!   frame at `q + R(θ)·(p − q)`, with R the right-handed rotation about the axis (A about X,
//!   B about Y, C about Z) and q a point of that axis (`tilt_pivot` for A/B, `rotary_center` for
//!   C). On table-table machines the C table rides on the tilting A/B table.
//! * The spindle points along +Z of the machine frame; a B head tilts it to `Ry(B)·ez`.
//!
//! Tool axis in the part frame per machine (i, j, k):
//! XYZ `(0,0,1)`; A table `(0, sin A, cos A)`; B table `(−sin B, 0, cos B)`; AC table-table
//! `(sin A·sin C, sin A·cos C, cos A)`; BC table-table `(−sin B·cos C, sin B·sin C, cos B)`;
//! B head + C table `(sin B·cos C, −sin B·sin C, cos B)`.

use super::{Kinematics, Machine};
use crate::vec3::{add, scale, sub};
use serde::{Deserialize, Serialize};

/// Offsets, pivot length and rotary limits of a multi-axis machine. All lengths in mm in the
/// machine frame at zero angles; limits in degrees `[min, max]`.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KinematicChain {
    /// A point on the tilting table axis (A about X or B about Y).
    #[serde(default)]
    pub tilt_pivot: [f64; 3],
    /// A point on the C table axis (about Z).
    #[serde(default)]
    pub rotary_center: [f64; 3],
    /// Head-table machines: distance from the B head pivot to the tool tip along the tool axis.
    #[serde(default)]
    pub pivot_length: f64,
    #[serde(default)]
    pub a_limits: Option<[f64; 2]>,
    #[serde(default)]
    pub b_limits: Option<[f64; 2]>,
    #[serde(default)]
    pub c_limits: Option<[f64; 2]>,
}

/// Tool tip (mm) and unit tool axis (pointing from the tip into the spindle), part frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Pose {
    pub tip: [f64; 3],
    pub axis: [f64; 3],
}

/// Something worth knowing about one pose of a path.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PoseIssue {
    /// Index of the pose in the list given to [`MachineKinematics::inverse_path`] (or the move
    /// index when the caller passes moves).
    pub index: usize,
    pub kind: PoseIssueKind,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum PoseIssueKind {
    /// The tool axis is (nearly) parallel to the rotary axis that turns about it: that axis'
    /// angle is free; the previous value was kept.
    Singular { axis: char },
    /// The solution nearest the previous one puts an axis outside its limits.
    LimitViolation {
        axis: char,
        value: f64,
        min: f64,
        max: f64,
    },
}

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum KinematicsError {
    #[error("pose {index}: tool axis ({:.6}, {:.6}, {:.6}) cannot be reached on a {kinematics:?} machine", axis[0], axis[1], axis[2])]
    Unreachable {
        index: usize,
        axis: [f64; 3],
        kinematics: Kinematics,
    },
    #[error("pose {index}: tool axis is not a finite non-zero vector")]
    BadAxis { index: usize },
}

/// One inverse solution.
#[derive(Clone, Debug, PartialEq)]
pub struct InverseSolution {
    pub axes: [f64; 6],
    /// Issues of this pose (their `index` is the one passed to [`MachineKinematics::inverse`]).
    pub issues: Vec<PoseIssue>,
}

/// Forward and inverse kinematics of one machine.
#[derive(Clone, Debug, PartialEq)]
pub struct MachineKinematics {
    pub kinematics: Kinematics,
    pub chain: KinematicChain,
    /// Linear travel [min, max] for X, Y, Z, if known.
    pub travel: Option<[[f64; 2]; 3]>,
    /// How far (sin of the angle) the tool axis may be from the reachable set (4-axis machines)
    /// before it counts as unreachable.
    pub axis_tolerance: f64,
    /// Below this sin(tilt), the pose is singular (C free).
    pub singular_tolerance: f64,
}

type V3 = [f64; 3];

/// Right-handed rotation of `v` about the coordinate axis `k` (0 X, 1 Y, 2 Z) by `deg`.
fn rot(k: usize, deg: f64, v: V3) -> V3 {
    let (s, c) = deg.to_radians().sin_cos();
    match k {
        0 => [v[0], c * v[1] - s * v[2], s * v[1] + c * v[2]],
        1 => [c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]],
        _ => [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]],
    }
}

fn rot_about(k: usize, deg: f64, pivot: V3, p: V3) -> V3 {
    add(pivot, rot(k, deg, sub(p, pivot)))
}

/// `θ + 360·n` nearest `prev`.
pub fn unwrap_deg(theta: f64, prev: f64) -> f64 {
    theta + 360.0 * ((prev - theta) / 360.0).round()
}

const AXIS_NAMES: [char; 6] = ['X', 'Y', 'Z', 'A', 'B', 'C'];

impl MachineKinematics {
    pub fn new(kinematics: Kinematics, chain: KinematicChain) -> Self {
        MachineKinematics {
            kinematics,
            chain,
            travel: None,
            axis_tolerance: 1e-6,
            singular_tolerance: 1e-7,
        }
    }

    /// The machine's kinematics, chain (default: all pivots at the origin, no limits) and travel.
    pub fn of(machine: &Machine) -> Self {
        let mut k = Self::new(
            machine.kinematics,
            machine.kinematic_chain.clone().unwrap_or_default(),
        );
        k.travel = machine.travel;
        k
    }

    /// Table rotations from the base outwards: (coordinate axis, axis slot, pivot).
    fn tables(&self) -> Vec<(usize, usize, V3)> {
        let c = &self.chain;
        match self.kinematics {
            Kinematics::Xyz => vec![],
            Kinematics::XyzA => vec![(0, 3, c.tilt_pivot)],
            Kinematics::XyzB => vec![(1, 4, c.tilt_pivot)],
            Kinematics::XyzAc => vec![(0, 3, c.tilt_pivot), (2, 5, c.rotary_center)],
            Kinematics::XyzBc => vec![(1, 4, c.tilt_pivot), (2, 5, c.rotary_center)],
            Kinematics::HeadTable => vec![(2, 5, c.rotary_center)],
        }
    }

    /// Rotary slots this machine uses (3 A, 4 B, 5 C).
    pub fn rotary_slots(&self) -> &'static [usize] {
        match self.kinematics {
            Kinematics::Xyz => &[],
            Kinematics::XyzA => &[3],
            Kinematics::XyzB => &[4],
            Kinematics::XyzAc => &[3, 5],
            Kinematics::XyzBc | Kinematics::HeadTable => &[4, 5],
        }
    }

    /// Tool tip in the machine frame and spindle axis in the machine frame.
    fn head(&self, axes: &[f64; 6]) -> (V3, V3) {
        let p = [axes[0], axes[1], axes[2]];
        if self.kinematics == Kinematics::HeadTable {
            let u = rot(1, axes[4], [0.0, 0.0, 1.0]);
            let l = self.chain.pivot_length;
            (add(add(p, [0.0, 0.0, l]), scale(u, -l)), u)
        } else {
            (p, [0.0, 0.0, 1.0])
        }
    }

    /// Machine axes → tool tip and axis in the part frame.
    pub fn forward(&self, axes: &[f64; 6]) -> Pose {
        let (mut tip, mut axis) = self.head(axes);
        for (k, slot, pivot) in self.tables() {
            tip = rot_about(k, -axes[slot], pivot, tip);
            axis = rot(k, -axes[slot], axis);
        }
        Pose { tip, axis }
    }

    /// Candidate rotary angles (degrees, slots 3..6) for a unit part-frame axis, and whether
    /// the pose is singular. `None`: unreachable.
    fn angle_candidates(&self, u: V3, prev: &[f64; 6]) -> Option<(Vec<[f64; 3]>, bool)> {
        let tol = self.axis_tolerance;
        let deg = f64::to_degrees;
        let mut out = Vec::new();
        let mut singular = false;
        let mut rest = [prev[3], prev[4], prev[5]];
        match self.kinematics {
            Kinematics::Xyz => {
                if u[0].hypot(u[1]) > tol || u[2] < 0.0 {
                    return None;
                }
                out.push(rest);
            }
            Kinematics::XyzA => {
                if u[0].abs() > tol {
                    return None;
                }
                rest[0] = deg(u[1].atan2(u[2]));
                out.push(rest);
            }
            Kinematics::XyzB => {
                if u[1].abs() > tol {
                    return None;
                }
                rest[1] = deg((-u[0]).atan2(u[2]));
                out.push(rest);
            }
            Kinematics::XyzAc | Kinematics::XyzBc | Kinematics::HeadTable => {
                let tilt_slot = if self.kinematics == Kinematics::XyzAc {
                    0
                } else {
                    1
                };
                let s = u[0].hypot(u[1]);
                let tilt = deg(s.atan2(u[2]));
                let c = match self.kinematics {
                    Kinematics::XyzAc => u[0].atan2(u[1]),
                    Kinematics::XyzBc => u[1].atan2(-u[0]),
                    _ => (-u[1]).atan2(u[0]),
                };
                if s < self.singular_tolerance {
                    singular = true;
                    let mut r = rest;
                    r[tilt_slot] = tilt;
                    out.push(r);
                    r[tilt_slot] = -tilt;
                    out.push(r);
                } else {
                    let mut r = rest;
                    r[tilt_slot] = tilt;
                    r[2] = deg(c);
                    out.push(r);
                    r[tilt_slot] = -tilt;
                    r[2] = deg(c) + 180.0;
                    out.push(r);
                }
            }
        }
        Some((out, singular))
    }

    fn limits(&self, slot: usize) -> Option<[f64; 2]> {
        match slot {
            0..=2 => self.travel.map(|t| t[slot]),
            3 => self.chain.a_limits,
            4 => self.chain.b_limits,
            _ => self.chain.c_limits,
        }
    }

    /// Tool tip and axis (part frame) → machine axes, the solution nearest `previous` (each
    /// angle unwrapped to within 180° of its previous value, or moved by whole turns into its
    /// limits when that is possible). Axes the machine does not have keep `previous`' value.
    pub fn inverse(
        &self,
        pose: &Pose,
        previous: &[f64; 6],
        index: usize,
    ) -> Result<InverseSolution, KinematicsError> {
        let n = (pose.axis[0].powi(2) + pose.axis[1].powi(2) + pose.axis[2].powi(2)).sqrt();
        if !(n.is_finite() && n > 1e-12) {
            return Err(KinematicsError::BadAxis { index });
        }
        let u = scale(pose.axis, 1.0 / n);
        let (cands, singular) =
            self.angle_candidates(u, previous)
                .ok_or(KinematicsError::Unreachable {
                    index,
                    axis: u,
                    kinematics: self.kinematics,
                })?;
        let slots = self.rotary_slots();
        let mut best: Option<([f64; 6], usize, f64)> = None;
        for cand in cands {
            let mut axes = *previous;
            let mut score = 0.0;
            for &s in slots {
                let mut v = unwrap_deg(cand[s - 3], previous[s]);
                if let Some([lo, hi]) = self.limits(s) {
                    if v < lo || v > hi {
                        // Whole turns into the limits, nearest the previous value.
                        let mut alt: Option<f64> = None;
                        for k in -3..=3 {
                            let w = v + 360.0 * k as f64;
                            if w >= lo
                                && w <= hi
                                && alt.is_none_or(|a| {
                                    (w - previous[s]).abs() < (a - previous[s]).abs()
                                })
                            {
                                alt = Some(w);
                            }
                        }
                        if let Some(w) = alt {
                            v = w;
                        }
                    }
                }
                axes[s] = v;
                score += (v - previous[s]).abs();
            }
            let tip_m = self.tip_machine(&axes, pose.tip, u);
            axes[0] = tip_m[0];
            axes[1] = tip_m[1];
            axes[2] = tip_m[2];
            let violations = (0..6)
                .filter(|&s| {
                    self.limits(s)
                        .is_some_and(|[lo, hi]| axes[s] < lo - 1e-9 || axes[s] > hi + 1e-9)
                })
                .count();
            if best
                .as_ref()
                .is_none_or(|b| (violations, score) < (b.1, b.2))
            {
                best = Some((axes, violations, score));
            }
        }
        let (axes, _, _) = best.expect("at least one candidate");
        let mut issues = Vec::new();
        if singular {
            issues.push(PoseIssue {
                index,
                kind: PoseIssueKind::Singular { axis: 'C' },
            });
        }
        for s in 0..6 {
            if let Some([lo, hi]) = self.limits(s) {
                if axes[s] < lo - 1e-9 || axes[s] > hi + 1e-9 {
                    issues.push(PoseIssue {
                        index,
                        kind: PoseIssueKind::LimitViolation {
                            axis: AXIS_NAMES[s],
                            value: axes[s],
                            min: lo,
                            max: hi,
                        },
                    });
                }
            }
        }
        Ok(InverseSolution { axes, issues })
    }

    /// The machine axes that put the tip at part-frame `tip` with the rotary angles of
    /// `angles` (its X Y Z are ignored): the inverse of [`Self::forward`]'s tip at fixed angles.
    pub fn machine_axes(&self, tip: [f64; 3], angles: &[f64; 6]) -> [f64; 6] {
        let mut axes = *angles;
        axes[..3].copy_from_slice(&self.tip_machine(angles, tip, [0.0, 0.0, 1.0]));
        axes
    }

    /// Machine X Y Z for a part-frame tip once the angles in `axes` are chosen.
    fn tip_machine(&self, axes: &[f64; 6], tip: V3, _u: V3) -> V3 {
        let mut p = tip;
        for (k, slot, pivot) in self.tables().into_iter().rev() {
            p = rot_about(k, axes[slot], pivot, p);
        }
        if self.kinematics == Kinematics::HeadTable {
            let h = rot(1, axes[4], [0.0, 0.0, 1.0]);
            let l = self.chain.pivot_length;
            p = add(sub(p, [0.0, 0.0, l]), scale(h, l));
        }
        p
    }

    /// Inverse kinematics along a path, each pose solved nearest the previous solution
    /// (starting from `start`). Issues carry the pose index.
    pub fn inverse_path(
        &self,
        poses: &[Pose],
        start: [f64; 6],
    ) -> Result<(Vec<[f64; 6]>, Vec<PoseIssue>), KinematicsError> {
        let mut prev = start;
        let mut out = Vec::with_capacity(poses.len());
        let mut issues = Vec::new();
        for (i, p) in poses.iter().enumerate() {
            let s = self.inverse(p, &prev, i)?;
            prev = s.axes;
            out.push(s.axes);
            issues.extend(s.issues);
        }
        Ok((out, issues))
    }
}

/// Distance between two poses' tips.
pub fn tip_distance(a: &Pose, b: &Pose) -> f64 {
    let d = sub(a.tip, b.tip);
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}
