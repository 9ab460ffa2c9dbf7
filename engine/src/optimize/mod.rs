//! Feed scheduling (a feed per move from the limits on the force model) and program rewriting (the input with its F words changed).
//!
//! The removal gives, for each move (or part of a move: a [`MoveEngagement`]), the engagement at a
//! series of steps. For every engaged step the optimizer finds the largest feed that keeps every
//! limit (peak |F|, peak power, peak torque, max chip thickness) at or below its target, by a
//! secant iteration on the real [`ForceModel`](crate::physics::ForceModel): the forces are affine in the feed per tooth for a
//! fixed engagement, so f_next = f0 + (f1 − f0)/(G1 − G0)·(1 − G0), with G the largest
//! quantity/target ratio, lands on the target in one or two steps. Every accepted feed has been
//! evaluated on the model and is at or below every limit (within `tolerance` below it).
//!
//! With a size effect (Kienzle exponents m in [0, 0.9)) each sample's force is
//! A·f^(1−m) + E: still increasing in the feed, and concave, so G(f) is monotone and the
//! iteration still converges: on a concave increasing function the secant through two points
//! below the target overshoots by a bounded amount that the bracket (regula falsi when a guess
//! leaves it, `solve.rs`) catches, and the secant's order (≈1.6) holds near the root where G is
//! smooth; it takes a step or two more than the affine case. Only the linear model has the
//! exact per-step response (`PeakResponse`); with a size effect every step is evaluated on the
//! model.
//!
//! A move's limiting feed is the smallest over its steps; air moves go to the air feed; a move
//! that enters material after air (or a rapid) is slowed by `entry_feed_factor`; the rubbing
//! floor (minimum chip thickness) lifts feeds that policies lowered, never above a limit. A block
//! that runs several times (loops, subroutines, canned cycles) gets the smallest feed over its
//! executions. [`rewrite`] turns the block feeds into the output program.
//!
//! Default guards: each tool's own chip and force ceilings ([`guards`]) act beside the
//! user's limits, the tighter binding, unless `tool_guards` is false.
//!
//! Block splitting: [`split_plan`] says where a long move whose engagement varies would be split
//! and at which feeds; [`rewrite::write_splits`] writes those parts as new blocks before the
//! move's own block (which keeps every character but its F).

pub mod energy;
// The path the service, benches and tests import the energy search from.
pub use energy as energy_search;
pub mod guards;
pub mod rewrite;
pub mod spindle;

mod engagement;
mod limits;
mod scale;
mod schedule;
mod solve;
mod split;

pub use engagement::{Cutter, EngagementStep, MoveEngagement, PLUNGE_MIN_SIN};
pub use guards::{tool_guards, GuardSource, MaterialClass, ToolGuards};
pub use limits::{FeedLimits, Governing, OptimizeError, SplitOptions, ToolLimits};
pub use rewrite::{
    rewrite_program, verify_rewrite, verify_splits, write_splits, BlockChange, Rewrite,
    RewriteOptions, SkippedSplit, WrittenSplit,
};
pub use scale::FeedScale;
pub use schedule::{optimize_feeds, optimize_feeds_per_cutter, BlockFeed, FeedSchedule, MoveFeed};
pub use split::{split_plan, SplitPlan};
