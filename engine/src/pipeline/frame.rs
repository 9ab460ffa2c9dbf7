//! The part frame: the machine's axis positions mapped to the tool tip and axis where the
//! stock is, moves whose rotary axes turn cut into straight pieces, and how a move's feed
//! drives the tip.

use super::rows::MoveRow;
use super::spec::AxisReading;
use crate::geometry::{self, Segment};
use crate::machine::cycle_time::move_length;
use crate::machine::{Kinematics, Machine, MachineKinematics, Pose, RotaryFeedReading};
use crate::nc::{Move, MoveKind};
use crate::optimize;

/// Maps the machine's axis positions to tool tip and axis in the part frame, where the
/// stock is, and cuts moves whose rotary axes turn into pieces short enough that the
/// curved tip path stays within `tolerance` of them.
pub(super) struct PartFrame {
    /// None on a 3-axis machine: the part frame is the machine (G53) frame.
    kinematics: Option<MachineKinematics>,
    reading: AxisReading,
    /// How the control reads F on a move that turns a rotary axis.
    feed_reading: RotaryFeedReading,
    /// Largest distance between the true tip path and its pieces, mm.
    tolerance: f64,
    /// Largest angle between the true tool axis and its interpolation, radians.
    axis_tolerance: f64,
}

/// A move cut into at most 2^MAX_DEPTH pieces.
const MAX_DEPTH: u32 = 12;

/// One straight piece of a move in the part frame.
#[derive(Clone)]
pub(super) struct FramePiece {
    pub(super) segment: Segment,
    /// Where the piece starts along the move: the tip's path, mm, and the machine axes'
    /// length (the unit of the move's F: mm, or degrees on a rotary-only move).
    pub(super) tip_at: f64,
    pub(super) machine_at: f64,
    /// Tip path over machine-axis length on this piece: the tip speed per unit of the
    /// machine-axis feed (exactly 1 when no rotary axis turns).
    pub(super) tip_ratio: f64,
}

impl PartFrame {
    pub(super) fn new(machine: &Machine, reading: AxisReading, cell: f64, reach: f64) -> PartFrame {
        PartFrame {
            kinematics: (machine.kinematics != Kinematics::Xyz)
                .then(|| MachineKinematics::of(machine)),
            reading,
            feed_reading: machine.rotary_feed_reading,
            // As the geometry engine's arcs: chords inside a curve over-cut by their sagitta.
            tolerance: cell / 20.0,
            // The axis error moves the edge by angle × distance from the tip.
            axis_tolerance: cell / 20.0 / reach.max(1.0),
        }
    }

    /// How move `m`'s axis words are read: G43.4 tool-centre-point control reads them as
    /// the tool tip whatever the job's reading.
    fn reading_of(&self, m: &Move) -> AxisReading {
        if m.tool_tip {
            AxisReading::ToolTip
        } else {
            self.reading
        }
    }

    fn pose(&self, axes: &[f64; 6], reading: AxisReading) -> Pose {
        let tip = [axes[0], axes[1], axes[2]];
        match (&self.kinematics, reading) {
            (None, _) => Pose {
                tip,
                axis: [0.0, 0.0, 1.0],
            },
            (Some(k), AxisReading::Machine) => k.forward(axes),
            (Some(k), AxisReading::ToolTip) => Pose {
                tip,
                axis: k.forward(axes).axis,
            },
        }
    }

    /// The move's geometry in the part frame: its pieces, and the tip path length. None for
    /// dwells and tool changes.
    pub(super) fn segments(&self, m: &Move) -> Option<(Vec<FramePiece>, f64)> {
        let machine_segment = segment(m, self.feed_reading)?;
        let reading = self.reading_of(m);
        let whole = |segment: Segment| FramePiece {
            segment,
            tip_at: 0.0,
            machine_at: 0.0,
            tip_ratio: 1.0,
        };
        let Some(_) = &self.kinematics else {
            let length = move_length(m);
            return Some((vec![whole(machine_segment)], length));
        };
        if !m.turns_rotary() {
            // Fixed angles: a rigid motion, so lines stay lines and arcs stay arcs.
            let p0 = self.pose(&m.start, reading);
            let p1 = self.pose(&m.end, reading);
            let mut seg = machine_segment;
            seg.from = p0.tip;
            seg.to = p1.tip;
            seg.axis_from = p0.axis;
            seg.axis_to = p1.axis;
            if let geometry::PathShape::Arc { center, normal, .. } = &mut seg.shape {
                let mut at = m.start;
                at[..3].copy_from_slice(center);
                let c = self.pose(&at, reading).tip;
                at[..3].copy_from_slice(&crate::vec3::add(*center, *normal));
                *normal = crate::vec3::sub(self.pose(&at, reading).tip, c);
                *center = c;
            }
            return Some((vec![whole(seg)], move_length(m)));
        }
        // Rotary axes turn: the control interpolates every axis together, so the tip
        // follows a curve in the part frame. Sample it adaptively.
        let at = |u: f64| -> [f64; 6] {
            match &m.arc {
                Some(arc) => arc.point_at(u),
                None => std::array::from_fn(|i| m.start[i] + (m.end[i] - m.start[i]) * u),
            }
        };
        let mut knots = vec![(0.0, self.pose(&m.start, reading))];
        self.refine(
            &at,
            reading,
            (0.0, self.pose(&m.start, reading)),
            (1.0, self.pose(&m.end, reading)),
            0,
            &mut knots,
        );
        let (feed, rapid) = (machine_segment.feed, machine_segment.rapid);
        let machine_length = move_length(m);
        let mut pieces = Vec::with_capacity(knots.len() - 1);
        let mut along = 0.0;
        for w in knots.windows(2) {
            let ((u0, a), (u1, b)) = (&w[0], &w[1]);
            let tip = crate::vec3::norm(crate::vec3::sub(b.tip, a.tip));
            // The control moves every axis at a constant rate over the machine length, so
            // the tip's speed on this piece is the feed times this ratio (the chip, the MRR).
            let span = (u1 - u0) * machine_length;
            let tip_ratio = if span > 0.0 { tip / span } else { 0.0 };
            let seg = if rapid {
                Segment::rapid(m.block, a.tip, b.tip)
            } else {
                Segment::linear(m.block, a.tip, b.tip, feed * tip_ratio, m.spindle)
            };
            pieces.push(FramePiece {
                segment: seg.with_axes(a.axis, b.axis),
                tip_at: along,
                machine_at: u0 * machine_length,
                tip_ratio,
            });
            along += tip;
        }
        Some((pieces, along))
    }

    /// Appends the knots after `u0` up to and including `u1`, splitting until the midpoint
    /// of each piece is within tolerance of the chord and of the interpolated axis.
    fn refine(
        &self,
        at: &dyn Fn(f64) -> [f64; 6],
        reading: AxisReading,
        (u0, p0): (f64, Pose),
        (u1, p1): (f64, Pose),
        depth: u32,
        out: &mut Vec<(f64, Pose)>,
    ) {
        use crate::vec3::{add, dot, norm, scale, sub};
        let um = 0.5 * (u0 + u1);
        let pm = self.pose(&at(um), reading);
        let chord_mid = scale(add(p0.tip, p1.tip), 0.5);
        let tip_error = norm(sub(pm.tip, chord_mid));
        let axis_mid = add(p0.axis, p1.axis);
        let axis_error = if norm(axis_mid) > 1e-12 {
            let a = scale(axis_mid, 1.0 / norm(axis_mid));
            dot(a, pm.axis).clamp(-1.0, 1.0).acos()
        } else {
            std::f64::consts::PI
        };
        // Depth ≥ 2 first: a symmetric curve can pass through its chord's midpoint.
        let fine = tip_error <= self.tolerance && axis_error <= self.axis_tolerance;
        if depth >= MAX_DEPTH || (depth >= 2 && fine) {
            out.push((u1, p1));
            return;
        }
        self.refine(at, reading, (u0, p0), (um, pm), depth + 1, out);
        self.refine(at, reading, (um, pm), (u1, p1), depth + 1, out);
    }
}

/// How the optimizer's machine-axis feed of move `m` drives the tool tip, and the fastest
/// feed the machine's axes allow on it (the rotary speed limit; the linear axes' max feed
/// where F is their rate).
pub(super) fn feed_scale(
    m: &Move,
    row: &MoveRow,
    machine: &Machine,
    axes: AxisReading,
) -> optimize::FeedScale {
    let rotary = m.rotary_travel();
    if !matches!(m.kind, MoveKind::Linear | MoveKind::Arc) || rotary <= 1e-9 || row.length <= 0.0 {
        return optimize::FeedScale::UNIT;
    }
    let mut max_axis_feed = f64::INFINITY;
    if let Some(w) = machine.max_rotary_speed_deg_min {
        // The move lasts length / F: the fastest rotary axis turns `rotary` degrees in it.
        max_axis_feed = max_axis_feed.min(row.length * w / rotary);
    }
    let linear = (0..3).any(|i| (m.end[i] - m.start[i]).abs() > 1e-12);
    if axes == AxisReading::Machine && !m.tool_tip && linear {
        max_axis_feed = max_axis_feed.min(machine.max_feed);
    }
    optimize::FeedScale {
        tip_ratio: row.tip_length_mm / row.length,
        max_axis_feed,
    }
}

/// The geometry segment of a cutting or positioning move; None for dwells and tool changes.
fn segment(m: &Move, feed_reading: RotaryFeedReading) -> Option<Segment> {
    let (from, to) = (
        [m.start[0], m.start[1], m.start[2]],
        [m.end[0], m.end[1], m.end[2]],
    );
    let seg = match m.kind {
        MoveKind::Rapid => Segment::rapid(m.block, from, to),
        MoveKind::Linear => {
            Segment::linear(m.block, from, to, feed_reading.path_rate(m), m.spindle)
        }
        MoveKind::Arc => {
            let arc = m.arc.as_ref()?;
            let mut s = Segment::arc(
                m.block,
                from,
                to,
                arc.center,
                arc.normal,
                arc.clockwise,
                feed_reading.path_rate(m),
                m.spindle,
            );
            if let geometry::PathShape::Arc { turns, .. } = &mut s.shape {
                *turns = arc.turns.max(1);
            }
            s
        }
        MoveKind::Dwell | MoveKind::ToolChange => return None,
    };
    Some(seg)
}
