//! What a revolution's forces come to: [`ForceResult`] and its parts ([`AxisStats`],
//! [`MagnitudeStats`], [`ToothStats`], [`ForceSample`]).

use serde::{Deserialize, Serialize};

use super::frame::ToolFrame;

/// Mean, minimum and maximum of one force component over a revolution, N.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AxisStats {
    pub mean: f64,
    pub min: f64,
    pub max: f64,
}

impl AxisStats {
    /// Largest magnitude reached.
    pub fn peak(&self) -> f64 {
        self.min.abs().max(self.max.abs())
    }
}

/// Mean and peak of a non-negative quantity (|F|, torque, power).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MagnitudeStats {
    pub mean: f64,
    pub peak: f64,
}

/// What one tooth does over the revolution.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ToothStats {
    /// 1-based tooth number (tooth 1 is the runout angle's reference).
    pub tooth: usize,
    /// Largest |F| of this tooth's own contribution, N.
    pub peak_force: f64,
    /// Largest chip thickness this tooth cuts, mm.
    pub max_chip_thickness: f64,
}

/// The force at one angular position, in the tool (Engagement) frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ForceSample {
    /// Spindle angle θ (tooth 1's immersion at the tip), rad.
    pub angle: f64,
    pub fx: f64,
    pub fy: f64,
    pub fz: f64,
    /// N·m.
    pub torque: f64,
}

/// Forces of one engagement state over one spindle revolution.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ForceResult {
    pub positions: usize,
    /// One sample per angular position (empty when the model was told not to keep them).
    pub samples: Vec<ForceSample>,
    /// Tool frame (x feed, z tool axis): components.
    pub fx: AxisStats,
    pub fy: AxisStats,
    pub fz: AxisStats,
    /// |F|: mean of the sampled magnitude, and peak.
    pub force: MagnitudeStats,
    /// |F| in the plane perpendicular to the tool axis (what bends the tool).
    pub force_xy: MagnitudeStats,
    /// Part-frame X, Y, Z components.
    pub part: [AxisStats; 3],
    /// Mean force vector in part coordinates, N.
    pub mean_force_part: [f64; 3],
    /// Force vector at the sample with the largest |F|, part coordinates, N.
    pub peak_force_part: [f64; 3],
    /// Spindle torque, N·m.
    pub torque: MagnitudeStats,
    /// Cutting power P = T·ω, W.
    pub power: MagnitudeStats,
    /// Largest uncut chip thickness over teeth, slices and positions, mm.
    pub max_chip_thickness: f64,
    pub per_tooth: Vec<ToothStats>,
    /// The tool frame in part coordinates.
    pub frame: Option<ToolFrame>,
    /// How the tool bends (zero when the model has no beam).
    #[serde(default)]
    pub deflection: crate::physics::deflection::Deflection,
    /// Engagement slices that contributed / that lay outside the flutes (no edge there).
    pub engaged_slices: usize,
    pub skipped_slices: usize,
}

impl ForceResult {
    /// No tooth cut anything.
    pub fn is_air(&self) -> bool {
        self.engaged_slices == 0
    }
}
