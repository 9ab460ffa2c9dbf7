//! The spindle speed of an operation chosen out of chatter (issue 33).
//!
//! The removal pass gives every cutting block its axial depth and the immersion and direction
//! of its engagement; none of these depend on the spindle speed. So the chatter margin of
//! every block can be evaluated at any speed from the same engagement: on a bounded grid of
//! candidate speeds, the operation's worst margin (its deepest cut against its lowest lobe)
//! splits the range into stable pockets. The speed is taken in the widest pocket where every
//! block keeps the requested margin, placed in it by the objective (least time or least
//! energy, the machine's feed, power and torque limits within it); with no such pocket, the
//! speed whose worst margin is lowest, and the report says so.
//!
//! The feed per tooth is held: at the chosen speed every F word scales with the speed
//! (per-minute and inverse-time feeds; per-revolution feeds stay), so the forces, torque and
//! chip of every block are unchanged and the power scales with the speed.
//!
//! Files: `options` (the job's JSON and its checks), `choose` (the grid, the pockets and the
//! objective), `rewrite` (S and F words written at the chosen speed).

mod choose;
mod options;
mod rewrite;

pub use choose::{
    choose_spindle_speed, ChoiceInput, CuttingBlock, FeedMove, SpeedMargin, SpindleChoice,
};
pub use options::{Objective, RpmBounds, SpindleOptions, MAX_EVALUATIONS, MAX_SPEEDS};
pub use rewrite::{at_spindle_speed, SpeedRewrite};

/// Why a speed cannot be chosen.
#[derive(Debug, thiserror::Error)]
pub enum SpindleError {
    /// An option or the program does not allow a choice; `field` names the option, relative
    /// to `options.spindle` (`rpm.from`, `speeds`, ...).
    #[error("options.spindle.{field}: {message}")]
    Option { field: String, message: String },
    /// The lobe computation refused the modes, or the job was cancelled.
    #[error("{0}")]
    Physics(#[from] crate::physics::PhysicsError),
}

impl SpindleError {
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> SpindleError {
        SpindleError::Option {
            field: field.into(),
            message: message.into(),
        }
    }

    /// The option at fault, relative to `options.spindle` (empty for a physics error).
    pub fn field(&self) -> &str {
        match self {
            SpindleError::Option { field, .. } => field,
            SpindleError::Physics(e) => e.field(),
        }
    }
}
