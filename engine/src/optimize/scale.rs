//! [`FeedScale`]: how a move's machine-axis feed drives the tool tip, and the limits' feed
//! range in that move's machine-axis feeds.

use serde::Serialize;

use super::limits::FeedLimits;

/// How a move's machine-axis feed relates to the tool tip in the part frame. Every feed the
/// optimizer solves for is a machine-axis feed (the rate the control applies to the axes of
/// the move's F: XYZ mm/min, or degrees/min on a rotary-only move), so that block feeds and
/// cycle times stay in the control's terms; the limits' feed range (min, max, air) is of
/// the tip, and the force model sees the tip's feed at every step.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FeedScale {
    /// Mean tip speed per unit of machine-axis feed: tip path / machine-axis length.
    pub tip_ratio: f64,
    /// Fastest machine-axis feed the machine's axes allow on the move (rotary speed,
    /// linear max feed), mm/min.
    pub max_axis_feed: f64,
}

impl FeedScale {
    /// A move whose tip moves with the axes (3-axis, or fixed rotary angles).
    pub const UNIT: FeedScale = FeedScale {
        tip_ratio: 1.0,
        max_axis_feed: f64::INFINITY,
    };

    /// Whether a tip speed maps to a machine-axis feed (false when the tip stands still).
    pub fn schedulable(&self) -> bool {
        self.tip_ratio.is_finite() && self.tip_ratio > 0.0
    }

    /// The limits with their feed range in this move's machine-axis feeds: the tip range
    /// over the tip ratio, and no faster than the axes allow. The unit scale leaves them as
    /// they are.
    pub fn limits(&self, limits: &FeedLimits) -> FeedLimits {
        if !self.schedulable() {
            return limits.clone();
        }
        let mut l = limits.clone();
        l.max_feed = (limits.max_feed / self.tip_ratio).min(self.max_axis_feed);
        l.min_feed = (limits.min_feed / self.tip_ratio).min(l.max_feed);
        l.air_feed = limits
            .air_feed
            .map(|f| (f / self.tip_ratio).min(l.max_feed));
        l.max_plunge_feed = limits
            .max_plunge_feed
            .map(|f| (f / self.tip_ratio).min(l.max_feed));
        l
    }

    /// The range of machine-axis feeds the optimizer may choose on this move.
    pub fn feed_range(&self, limits: &FeedLimits) -> (f64, f64) {
        let l = self.limits(limits);
        (l.min_feed, l.max_feed)
    }
}
