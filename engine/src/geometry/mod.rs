//! Material removal on a tri-dexel stock: the stock grid, the tool's swept envelope and
//! its subtraction from the grid, cutter engagement per step, collision checks, and
//! export of the final stock.
//!
//! Entry point: [`simulate_removal`] over a list of [`Segment`]s (the integrator maps
//! the NC interpreter's moves to them).

pub mod checks;
pub mod compare;
pub mod dexel;
pub mod engagement;
pub mod export;
pub mod path;
pub mod simulate;
pub mod stl;
pub mod stock;
pub mod sweep;

pub use checks::CheckFlags;
pub use compare::{compare_with_part, PartComparison};
pub use dexel::{default_cell, DexelGrid, GridEstimate, GridOptions, DEFAULT_MEMORY_LIMIT};
pub use engagement::{EngagementOptions, StepMetrics};
pub use export::{export_stl, ExportStats};
pub use path::{PathShape, Segment};
pub use simulate::{simulate_removal, BlockGeometry, SimOptions, SimulationReport, StepGeometry};
pub use stl::{Mesh, StlError};
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
