//! What the optimizer is given: the engagement steps of each move ([`MoveEngagement`],
//! [`EngagementStep`]) and each tool's force model with the material ([`Cutter`]).

use std::borrow::Cow;
use std::sync::Arc;

use super::scale::FeedScale;
use crate::engagement::PackedEngagement;
use crate::physics::{CuttingCoefficients, ForceModel, PeakResponse, PhysicsError};
use crate::tool::Tool;

/// The engagement at one step of a move, with the spindle speed there.
#[derive(Clone, Debug, PartialEq)]
pub struct EngagementStep<'a> {
    /// Borrowed from the removal's steps when the caller keeps them (no copy per step).
    pub engagement: Cow<'a, PackedEngagement>,
    pub spindle_rpm: f64,
    /// Tool-tip speed in the part frame per unit of the move's machine-axis feed at this
    /// step: 1 on a 3-axis move; where rotary axes turn, the tip's path over the axes'.
    pub tip_ratio: f64,
    /// Distance from the start of the move in machine-axis length (mm; degrees on a
    /// rotary-only move), used only to place split points.
    pub at: f64,
    /// The model's peaks at this step as exact functions of the feed (a tool without
    /// runout), when the caller has them: evaluations in their range read them instead of
    /// summing the slices again.
    pub response: Option<Arc<PeakResponse>>,
}

/// What the optimizer knows about one move (or one part of a move): the engagement
/// steps along it. No steps, or only air steps, means the move cuts air.
#[derive(Clone, Debug, PartialEq)]
pub struct MoveEngagement<'a> {
    /// Index into the move list.
    pub move_index: usize,
    /// Index into the cutters slice.
    pub cutter: usize,
    /// How the move's machine-axis feed drives the tool tip, and the axes' own bound.
    pub scale: FeedScale,
    pub steps: Vec<EngagementStep<'a>>,
    /// The move removes material (from the removal, whatever the engagement says): it is
    /// never scheduled as air.
    pub removes_material: bool,
    /// The move feeds toward the tool's tip by more than [`PLUNGE_MIN_SIN`] of its length
    /// (a plunge, ramp or helical entry): never sped past its programmed feed.
    pub plunge: bool,
}

/// A move is a plunge or ramp when it descends along the tool axis by more than sin 1° of
/// its length (CAM ramps and helical entries are 1–5°; a contour along a floor is 0°).
pub const PLUNGE_MIN_SIN: f64 = 0.017_452_406_437_283_51; // sin 1°

/// A tool's force model and the work material's coefficients.
#[derive(Clone, Debug)]
pub struct Cutter {
    pub model: ForceModel,
    pub coefficients: CuttingCoefficients,
}

impl Cutter {
    /// `slice_count` slices over the flute length, `positions` angular positions per revolution.
    pub fn new(
        tool: &Tool,
        coefficients: CuttingCoefficients,
        slice_count: usize,
        positions: usize,
    ) -> Result<Cutter, PhysicsError> {
        coefficients.validate()?;
        let model = ForceModel::new(tool, slice_count, positions)?
            .keep_samples(false)
            .with_beam(crate::physics::deflection::ToolBeam::of(tool));
        Ok(Cutter {
            model,
            coefficients,
        })
    }
}
