//! How a machine's control reads F on a move that turns a rotary axis. One definition for
//! the cycle time, the simulation, the rotary feed correction and the post, so a program
//! the post writes for a machine is timed the way that machine runs it.
//!
//! In G94 (mm/min) F is a rate along some distance of the move, the move lasts that distance
//! over F, and every axis moves at a constant rate over that time. Which distance depends on
//! the control ([`RotaryFeedReading`]); a move without XYZ travel is always read in degrees
//! (F in degrees/min of the rotary vector), which is what every control does with it. In G93
//! the move lasts 1/F min whatever the reading; in G95 F × spindle speed is the G94 F.

use crate::nc::{FeedMode, Move};
use serde::{Deserialize, Serialize};

/// XYZ travel up to this (mm) is no XYZ travel: the move is rotary-only.
pub const NO_LINEAR_TRAVEL_MM: f64 = 1e-12;

/// The distance a G94 F is the rate of, on a move that turns a rotary axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RotaryFeedReading {
    /// F is the rate of the XYZ path (mm/min); the rotary axes take the same time (Fanuc,
    /// Haas and most controls without a 5-axis feed option). The default: it is the most
    /// common reading, and the one millsim used before machines said which they have.
    #[default]
    LinearOnly,
    /// F is the rate of the combined vector √(ΔX²+ΔY²+ΔZ²+ΔA²+ΔB²+ΔC²), mm and degrees
    /// counted alike (LinuxCNC, Mach).
    Combined,
    /// The control takes a move that turns a rotary axis only in inverse time (G93); the post
    /// and the correction write G93 on every such move. A G94 move with XYZ and rotary travel
    /// met in a program is timed as `linear_only`.
    InverseTimeOnly,
}

/// XYZ path length of a move, mm (arcs by arc length).
pub fn linear_length(m: &Move) -> f64 {
    if let Some(arc) = &m.arc {
        return arc.length();
    }
    (0..3)
        .map(|i| (m.end[i] - m.start[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Rotary travel of a move as the vector √(ΔA²+ΔB²+ΔC²), degrees.
pub fn rotary_length(m: &Move) -> f64 {
    (3..6)
        .map(|i| (m.end[i] - m.start[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The machine path length of a move: its XYZ length, or its rotary length in degrees when
/// X, Y and Z do not move. Motion planning (accelerations, junctions) runs along it.
pub fn path_length(m: &Move) -> f64 {
    let l = linear_length(m);
    if l > NO_LINEAR_TRAVEL_MM {
        l
    } else {
        rotary_length(m)
    }
}

impl RotaryFeedReading {
    /// The distance a G94 F is the rate of on this move (mm, degrees, or both combined).
    pub fn read_length(self, m: &Move) -> f64 {
        let l = linear_length(m);
        if l <= NO_LINEAR_TRAVEL_MM {
            return rotary_length(m);
        }
        match self {
            RotaryFeedReading::Combined => l.hypot(rotary_length(m)),
            RotaryFeedReading::LinearOnly | RotaryFeedReading::InverseTimeOnly => l,
        }
    }

    /// The move's F as a G94 rate of [`Self::read_length`] per minute: F (G94), F × spindle
    /// (G95), F × read length (G93: the move lasts 1/F).
    pub fn per_min_feed(self, m: &Move) -> f64 {
        match m.feed_mode {
            FeedMode::PerMin => m.feed,
            FeedMode::PerRev => m.feed * m.spindle,
            FeedMode::InverseTime => m.feed * self.read_length(m),
        }
    }

    /// Rate along [`path_length`] (mm/min, or degrees/min on a rotary-only move) at which the
    /// control runs a feed move as programmed, before the machine's limits: the length the
    /// planner moves along over the move's programmed time.
    pub fn path_rate(self, m: &Move) -> f64 {
        if m.feed_mode == FeedMode::InverseTime {
            return m.feed * path_length(m);
        }
        let read = self.read_length(m);
        let f = self.per_min_feed(m);
        if read > 0.0 {
            f * path_length(m) / read
        } else {
            f
        }
    }

    /// How long the control takes for a feed move as programmed, min (None when the feed or
    /// the spindle speed of a G95 move is not positive).
    pub fn programmed_time_min(self, m: &Move) -> Option<f64> {
        let f = self.per_min_feed(m);
        match m.feed_mode {
            _ if !(m.feed > 0.0) => None,
            FeedMode::InverseTime => Some(1.0 / m.feed),
            _ if !(f > 0.0) => None,
            _ => Some(self.read_length(m) / f),
        }
    }

    /// Whether a G94 F word is a sound way to write a move that turns a rotary axis and
    /// should last `time_min`, with coordinates written to `linear_step` mm and
    /// `angle_step` degrees and F to `feed_step`. It is not when the control needs G93 for
    /// it, when moving either end by one written step could change the distance F is read
    /// against by more than 1% (a rounding residue of XYZ read as the move's length: the F
    /// word would be tiny and meaningless), or when the F word's own rounding changes the time
    /// by more than 0.1%.
    pub fn g94_sound(
        self,
        m: &Move,
        time_min: f64,
        linear_step: f64,
        angle_step: f64,
        feed_step: f64,
    ) -> bool {
        if !m.turns_rotary() {
            return true;
        }
        if self == RotaryFeedReading::InverseTimeOnly || !(time_min > 0.0) {
            return false;
        }
        let (l, r) = (linear_length(m), rotary_length(m));
        let read = self.read_length(m);
        // One step on each of the three axes at each end: √3 steps on either distance.
        let (dl, dr) = (3f64.sqrt() * linear_step, 3f64.sqrt() * angle_step);
        let spread = if l <= NO_LINEAR_TRAVEL_MM {
            dr
        } else if self == RotaryFeedReading::Combined {
            (l * dl + r * dr) / read
        } else {
            dl
        };
        let f = read / time_min;
        read > 0.0 && spread <= 0.01 * read && 0.5 * feed_step <= 1e-3 * f
    }
}
