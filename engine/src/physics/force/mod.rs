//! Mechanistic milling force model (Altintas, *Manufacturing Automation*, ch. 2).
//!
//! The cutting edge is cut into axial slices along the real edge (flat, ball, bull-nose,
//! chamfer via [`Tool::edge_point`](crate::tool::Tool::edge_point)). For slice s and tooth j at spindle angle θ the
//! immersion is
//!
//! φ_j(θ, z) = θ − j·2π/N − ψ(z),  ψ(z) = z·tan β / R0,  R0 = D/2,
//!
//! i.e. tooth j trails tooth j−1 by one pitch, and the helix lag ψ is the constant-lead
//! model: a helix of lead 2π·R0/tan β wound on the nominal cylinder, which is also what
//! Altintas uses on the ball part. θ is tooth 1's immersion at the tip.
//!
//! Chip thickness is the feed per tooth projected on the edge's outward normal
//! n = (sin κ sin φ, sin κ cos φ, −cos κ):
//!
//! h = c_h·sin φ·sin κ − c_v·cos κ  (+ runout),
//!
//! c_h and c_v the parts of the feed per tooth across and along the tool axis (c_v ≠ 0 when
//! ramping or 5-axis with the feed not perpendicular to the axis). With radial runout tooth j
//! sweeps r + Δ_j, Δ_j = ρ·cos(λ + j·2π/N) (first order in ρ/r), and cuts the surface left by
//! the last tooth that reached further: h_j = min over m = 1..N of (m·h + (Δ_j − Δ_{j−m})·sin κ)
//! (Kline–DeVor / Altintas). No cut (and no edge force) where h < 0.
//!
//! Elemental forces on the tool: dFt = Ktc·h·db + Kte·ds, dFr = Krc·h·db + Kre·ds,
//! dFa = Kac·h·db + Kae·ds, with db = ds = dz / sin κ (chip width, edge length), rotated
//! into the tool frame:
//!
//! dFx = −dFt·cos φ − (dFr·sin κ + dFa·cos κ)·sin φ
//! dFy = +dFt·sin φ − (dFr·sin κ + dFa·cos κ)·cos φ
//! dFz = dFr·cos κ − dFa·sin κ
//!
//! the generalized end-mill transformation of Lee & Altintas (1996, ball end) and Engin &
//! Altintas (2001, general helical end mills), in which published coefficients (Kac, Kae > 0)
//! are identified: on a helical flank (κ = 90°) the axial force pulls the tool toward the work
//! (F̄z = −(N·a/2π)[−Kac·c·cos φ + Kae·φ] for a flat end mill), at a ball's tip the radial
//! force pushes it back. (Until 2026-11 the engine used +dFa, which matches a flat end mill's
//! |F̄z| but not a ball or bull-nose: a D8R1 slot's mean Fz rose with depth where dynamometers
//! measure it falling.) Within a slice these are
//! integrated over z exactly (see [`EdgeSlice`]) rather than taken at the slice centre: at a
//! ball's tip 1/sin κ is singular and the midpoint value is off by tens of percent on the first
//! slices. The chip's sign (cut or not) is decided at the slice centre.
//!
//! Torque T = Σ dFt·r; power P = T·ω, which is Ft·v with the local cutting speed of each edge
//! point (for a flat end mill exactly Ft·π·D·n/60000).
//!
//! Runout simplifications: the radius change enters the chip only (the torque arm and the
//! tooth's angular position keep their nominal values: effects of order ρ/r).
//!
//! Speed: per-slice geometry comes from a [`ToolEdgeTable`] built once per tool; only the
//! positions where a tooth is inside an engaged arc are visited; without runout, when the
//! tooth pitch is a whole number of positions (360 positions and 1–6, 8, 9, 10, 12 … teeth),
//! tooth 1 is computed and the others are copies shifted by whole pitches.
//!
//! Means are exact time averages up to the midpoint rule: the samples at the bin centres are
//! weighted 1, and the two bins an engaged arc cuts through are integrated over their covered
//! part only, so a 10%-immersion arc is not rounded to whole degrees. Instantaneous samples
//! include a tooth exactly on an arc boundary.

mod accumulate;
mod bending;
mod edge;
mod frame;
mod kernel;
mod model;
mod peak_response;
mod stats;
mod summary;
mod trace;

pub use edge::{EdgeSlice, ToolEdgeTable};
pub use frame::ToolFrame;
pub use model::{cutting_forces, CuttingConditions, ForceModel};
pub use peak_response::{PeakResponse, Peaks};
pub use stats::{AxisStats, ForceResult, ForceSample, MagnitudeStats, ToothStats};
pub use trace::{BlockForces, TracePoint};

/// Angular positions per revolution when the caller has no preference (1° steps).
pub const DEFAULT_POSITIONS: usize = 360;

/// Relative tolerance, in sample-index units, for a tooth exactly on an arc boundary.
const BOUNDARY_EPS: f64 = 1e-9;

/// A tooth on the φ = 0 or π boundary has h = ±1e-17 from rounding; count it as cutting
/// (edge forces on) consistently wherever it is evaluated. With runout the chip carries
/// the teeth's radius steps, so the margin is in mm; without, every chip is the feed per
/// tooth times a shape factor, and the margin scales with the feed so that which samples
/// cut does not depend on the feed (the forces are then exactly affine in it).
const CHIP_EPS: f64 = 1e-12;
/// The margin per mm of feed per tooth without runout.
const CHIP_EPS_PER_FEED: f64 = 1e-10;
