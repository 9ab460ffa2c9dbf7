//! Material removal on a tri-dexel stock: the stock grid, the tool's swept envelope and
//! its subtraction from the grid, cutter engagement per step, collision checks, and
//! export of the final stock.
//!
//! Entry point: [`simulate_removal`] over a list of [`Segment`]s (the integrator maps
//! the NC interpreter's moves to them: tool tip positions, arcs with centre/normal/
//! direction/turns, tool axis at both ends, rapid flag, block index, feed and speed).
//!
//! ```
//! use millsim_engine::geometry::{default_cell, simulate_removal, Segment, SimOptions, Stock};
//! use millsim_engine::{job::CancelFlag, tool::Tool};
//!
//! let tool = Tool::flat(6.0, 3);
//! assert_eq!(default_cell(&[tool.radius()]), 0.15); // R/20, the default resolution
//! let cell = 0.1;
//! let mut stock = Stock::block([0.0, 0.0, -10.0], [30.0, 20.0, 0.0], cell).unwrap();
//! let moves = [
//!     Segment::rapid(0, [-5.0, 10.0, 5.0], [-5.0, 10.0, -2.0]),
//!     Segment::linear(1, [-5.0, 10.0, -2.0], [35.0, 10.0, -2.0], 900.0, 9000.0),
//! ];
//! let report =
//!     simulate_removal(&mut stock, &tool, &moves, &SimOptions::default(), &CancelFlag::new())
//!         .unwrap();
//! let slot = &report.blocks[1];
//! // Exact to the grid: the X and Y rays sample the depth in whole cells.
//! assert!((slot.removed_volume - 30.0 * 6.0 * 2.0).abs() < 0.01 * 360.0);
//! assert!((slot.max_axial_depth - 2.0).abs() <= cell);
//! assert!(!report.blocks[0].checks.rapid_in_material);
//! ```
//!
//! Modules: `dexel` (grid, intervals, memory estimate), `stock` (block, cylinder),
//! `stl` (STL import), `path` (segments, arcs, 5-axis sub-steps), `sweep` (swept volume
//! per ray, removal), `engagement` (per step), `checks` (rapid, flutes, shank, holder,
//! fixture grid), `fixture` (clamps and vices as bodies, checked analytically against the
//! whole tool along each move), `compare` (gouge and allowance against a design part),
//! `export` (STL), `voxel_volume` (the stock volume from the three families together).

pub mod checks;
pub mod compare;
pub mod dexel;
mod end_engagement;
pub mod engagement;
pub mod export;
pub mod fixture;
pub mod frame;
pub mod path;
pub mod removal;
pub mod stl;
pub mod stl_read;
mod stl_repair;
pub mod stock;
pub mod sweep;
mod voxel_volume;

pub use checks::CheckFlags;
pub use compare::{compare_with_part, GougeRegion, PartComparison, MAX_GOUGE_REGIONS};
pub use dexel::{default_cell, DexelGrid, GridEstimate, GridOptions, DEFAULT_MEMORY_LIMIT};
pub use engagement::{EngagementOptions, StepMetrics};
pub use export::{export_stl, export_stl_vec, stl_bytes, ExportStats};
pub use fixture::{Fixture, FixtureError, FixtureSpec, MAX_FIXTURE_BODIES};
pub use frame::GridFrame;
pub use path::{PathShape, Segment};
pub use removal::{
    simulate_removal, simulate_removal_with_progress, BlockGeometry, SimOptions, SimulationReport,
    StepGeometry,
};
pub use stl::{Mesh, StlError, StlRepairs};
pub use stock::{Stock, StockShape};
pub use sweep::{remove_sweep, RemovalStats, SubMove, ToolBody};

/// Everything that can go wrong in the geometry engine.
#[derive(Debug, thiserror::Error)]
pub enum GeometryError {
    #[error(
        "grid of {cells:?} cells needs about {bytes} bytes, over the limit of {limit} bytes; use a coarser cell size"
    )]
    GridTooLarge {
        cells: [usize; 3],
        bytes: u64,
        limit: u64,
    },
    #[error("invalid grid: {0}")]
    InvalidGrid(String),
    #[error("invalid stock: {0}")]
    InvalidStock(String),
    #[error("STL: {0}")]
    Stl(#[from] StlError),
    #[error(transparent)]
    Tool(#[from] crate::tool::ToolError),
    #[error("segment {index} (block {block}): {message}")]
    InvalidSegment {
        index: usize,
        block: usize,
        message: String,
    },
    #[error("cancelled after {done} of {total} segments")]
    Cancelled { done: usize, total: usize },
    #[error("writing STL: {0}")]
    Io(#[from] std::io::Error),
}
