//! Cutting physics: mechanistic milling forces (with helix, runout, ball/torus/chamfer
//! edges and tilted axes), torque and power, work materials and coefficient
//! identification, tool life, and surface roughness.
//!
//! Inputs are the shared [`crate::tool::Tool`] and [`crate::engagement::Engagement`];
//! angles follow the Engagement convention (φ clockwise from +y seen from the spindle,
//! x the feed direction, z the tool axis). Units: mm, N, N·m, W, rpm, radians.
//!
//! - [`force`]: [`ToolEdgeTable`], [`ForceModel`], [`cutting_forces`], [`ForceResult`],
//!   [`BlockForces`] (per-block aggregate and down-sampled trace).
//! - [`material`]: [`CuttingCoefficients`], [`Material`], [`builtin_materials`].
//! - [`identify`]: [`identify_coefficients`] (average-force method) and
//!   [`closed_form_mean_force`]; [`identify_from_cuts`] (least squares on the model's unit
//!   responses: any tool, any cut, linear or exponential law) and [`fit_unit_forces`].
//! - [`life`]: [`TaylorLife`], [`tool_life`] (life consumed per block, remaining life).
//! - [`roughness`]: [`scallop_height`], [`feed_marks`], [`surface_roughness`].
//! - [`stability`]: chatter stability lobes (zero-order, semi- and full discretization) and
//!   3-D lobes over the remaining allowance; [`chatter`]: the memoized per-block chatter
//!   margin ([`ChatterModel`]).
//! - [`energy`]: [`EnergyModel`] (idle and auxiliary power), [`program_energy`] (per block
//!   and per program, utilization U); the `energy` job's parameter search and Pareto front
//!   live with the optimizer ([`crate::optimize::energy`]).
//! - [`deflection`]: the tool as a stepped cantilever ([`deflection::ToolBeam`]), the form
//!   error a pass leaves and a thin wall's give ([`deflection::WorkpieceModes`]).
//!
//! Typical use at every engagement step of a program:
//!
//! ```
//! use millsim_engine::engagement::{EngagedSlice, Engagement};
//! use millsim_engine::physics::{CuttingConditions, ForceModel, ForceResult, Material};
//! use millsim_engine::tool::Tool;
//!
//! let tool = Tool::flat(10.0, 4);
//! let k = Material::builtin("Al7075-T6").unwrap().coefficients;
//! // Once per tool: edge table with 0.2 mm slices over the flutes, 360 positions per revolution.
//! let mut model = ForceModel::new(&tool, 150, 360).unwrap();
//! let step = Engagement {
//!     slices: (0..25)
//!         .map(|i| EngagedSlice { z: 0.1 + 0.2 * i as f64, dz: 0.2, arcs: vec![(0.0, std::f64::consts::PI)].into() })
//!         .collect(),
//!     feed_dir: [0.0, 1.0, 0.0],
//!     tool_axis: [0.0, 0.0, 1.0],
//!     end: Vec::new(),
//! };
//! let mut out = ForceResult::default();
//! model
//!     .evaluate_into(&step, &k, &CuttingConditions { spindle_rpm: 8000.0, feed_per_tooth: 0.08 }, &mut out)
//!     .unwrap();
//! assert!(out.force.peak > 0.0 && out.power.mean > 0.0);
//! ```

pub mod chatter;
pub mod deflection;
pub mod energy;
pub mod force;
pub mod identify;
pub mod life;
pub mod material;
pub mod roughness;
pub mod stability;

pub use chatter::{arc_immersion, ChatterMargin, ChatterModel};
pub use energy::{
    program_energy, BlockEnergy, EnergyBlock, EnergyModel, IdlePowerCurve, ProgramEnergy,
};
pub use force::{
    cutting_forces, AxisStats, BlockForces, CuttingConditions, EdgeSlice, ForceModel, ForceResult,
    ForceSample, MagnitudeStats, PeakResponse, Peaks, ToolEdgeTable, ToolFrame, ToothStats,
    TracePoint, DEFAULT_POSITIONS,
};
pub use identify::{
    closed_form_mean_force, fit_unit_forces, identify_coefficients, identify_from_cuts,
    steady_cut_engagement, unit_coefficients, AxisFit, AxisQuality, Estimate, ForceLaw,
    ForceMeasurement, Identification, IdentificationCut, IdentificationSetup, Immersion,
    ModelIdentification, UnitForces,
};
pub use life::{
    cutting_speed_m_per_min, effective_diameter, tool_life, BlockLife, BlockWear, LifeReport,
    TaylorLife,
};
pub use material::{builtin_materials, CuttingCoefficients, Material};
pub use roughness::{
    feed_marks, scallop_height, surface_roughness, FeedMarks, Roughness, SurfaceKind,
};

use crate::tool::ToolError;

/// Everything that can be wrong with the inputs of the physics functions. Each variant
/// names the offending field (with an index path such as `slices[3].arcs[0]` where useful).
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum PhysicsError {
    #[error("`{field}` must be a finite number, got {value}")]
    NotFinite { field: String, value: f64 },
    #[error("`{field}` {message}")]
    Invalid { field: String, message: String },
    #[error(
        "identification needs mean forces at at least 2 different feeds per tooth, got {distinct}"
    )]
    TooFewFeeds { distinct: usize },
    #[error("identification: immersion {entry_rad}..{exit_rad} rad does not separate the {what} coefficients")]
    Unidentifiable {
        what: &'static str,
        entry_rad: f64,
        exit_rad: f64,
    },
    #[error(transparent)]
    Tool(#[from] ToolError),
    /// The caller's cancel flag was set during a long computation.
    #[error("cancelled")]
    Cancelled,
}

impl PhysicsError {
    pub(crate) fn invalid(field: impl Into<String>, message: impl Into<String>) -> PhysicsError {
        PhysicsError::Invalid {
            field: field.into(),
            message: message.into(),
        }
    }

    /// The same error with its field under `prefix` (`prefix.field`).
    pub fn prefixed(self, prefix: &str) -> PhysicsError {
        match self {
            PhysicsError::NotFinite { field, value } => PhysicsError::NotFinite {
                field: format!("{prefix}.{field}"),
                value,
            },
            PhysicsError::Invalid { field, message } => PhysicsError::Invalid {
                field: format!("{prefix}.{field}"),
                message,
            },
            other => other,
        }
    }

    /// The field the error is about.
    pub fn field(&self) -> &str {
        match self {
            PhysicsError::NotFinite { field, .. } | PhysicsError::Invalid { field, .. } => field,
            PhysicsError::TooFewFeeds { .. } => "measurements",
            PhysicsError::Unidentifiable { .. } => "setup",
            PhysicsError::Tool(e) => e.field,
            PhysicsError::Cancelled => "",
        }
    }
}

pub(crate) fn finite(field: impl Into<String>, v: f64) -> Result<f64, PhysicsError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(PhysicsError::NotFinite {
            field: field.into(),
            value: v,
        })
    }
}

pub(crate) fn positive(field: impl Into<String>, v: f64) -> Result<f64, PhysicsError> {
    let field = field.into();
    finite(field.clone(), v)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(PhysicsError::invalid(
            field,
            format!("must be positive, got {v}"),
        ))
    }
}

pub(crate) fn non_negative(field: impl Into<String>, v: f64) -> Result<f64, PhysicsError> {
    let field = field.into();
    finite(field.clone(), v)?;
    if v >= 0.0 {
        Ok(v)
    } else {
        Err(PhysicsError::invalid(
            field,
            format!("must not be negative, got {v}"),
        ))
    }
}
