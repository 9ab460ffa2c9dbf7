//! A process: operations run in order on one stock, each cutting what the last left.
//!
//! The stock is one tri-dexel grid handed from operation to operation (never re-meshed),
//! so:
//! - every operation cuts at one cell size: the process's `cell`, else the finest default
//!   of all the operations' tools (`geometry::default_cell`);
//! - the grid stays in the part frame: a 3+2 operation, which alone would cut a grid turned
//!   along its tool axis, cuts the part-frame grid as it does when a turned grid would be
//!   too large (same removal, less exact on its tilted faces);
//! - one grid is held at a time (two while an operation chooses its spindle speed, whose
//!   first pass cuts a copy); the stock after each operation is shown to the caller
//!   (`after_operation`), who exports what it wants of it;
//! - the process's fixture stands for every operation (one setup).

use std::sync::Arc;

use super::spec::{SimulateError, SimulateSpec, StockSource};
use super::{
    part_frame_stock, simulate_choosing_spindle_on, simulate_on, tool_radii, OptimizationSummary,
    SimulationSummary, StageTimings, StepSample,
};
use crate::geometry::{self, Fixture, Stock};
use crate::job::{CancelFlag, Progress};
use crate::optimize::spindle::SpindleOptions;

/// The most operations one process takes.
pub const MAX_OPERATIONS: usize = 20;

/// One operation: its name, its simulation (program, tools, material, machine, options,
/// limits when optimized), and the spindle speed choice when asked. Its `stock`, `cell`
/// and `fixture` are the process's.
#[derive(Clone)]
pub struct Operation {
    pub name: String,
    pub spec: SimulateSpec,
    pub spindle: Option<SpindleOptions>,
}

pub struct ProcessSpec {
    /// The blank the first operation cuts.
    pub stock: StockSource,
    /// Dexel spacing for every operation, mm; default the finest tool's default.
    pub cell: Option<f64>,
    pub fixture: Option<Arc<Fixture>>,
    pub operations: Vec<Operation>,
}

/// What one operation gave (a simulation's output without its stock, which went on).
pub struct OperationOutput {
    pub name: String,
    pub rows: Vec<super::MoveRow>,
    pub optimized_program: Option<String>,
    pub optimization: Option<OptimizationSummary>,
    pub samples: Vec<Vec<StepSample>>,
    pub summary: SimulationSummary,
    pub timings: StageTimings,
    pub rays_tested: u64,
    pub tool_numbers: Vec<u32>,
}

pub struct ProcessOutput {
    pub operations: Vec<OperationOutput>,
    /// The stock after the last operation.
    pub stock: Stock,
    pub cell: f64,
    /// Wall time of filling the blank's grid (before the first operation), s.
    pub grid_s: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum ProcessError {
    #[error("a process needs at least one operation")]
    NoOperations,
    #[error("{count} operations: a process takes at most {MAX_OPERATIONS}")]
    TooManyOperations { count: usize },
    /// Operation `index` (from 0) failed.
    #[error("operation {} ({name}): {source}", index + 1)]
    Operation {
        index: usize,
        name: String,
        source: SimulateError,
    },
    #[error("cancelled")]
    Cancelled,
}

/// One operation's progress as its share of the whole process, in proportion to its
/// program's length: the one measure of its size known before it is interpreted (a
/// finishing pass of 40,000 lines after a roughing pass of 400 takes most of the time).
struct Share<'a> {
    inner: &'a dyn Progress,
    /// Where its share starts, its width, and the whole, in bytes of program.
    start: u64,
    width: u64,
    whole: u64,
}

impl Progress for Share<'_> {
    fn report(&self, done: u64, total: u64) {
        let part = (u128::from(done.min(total)) * u128::from(self.width))
            .checked_div(u128::from(total))
            .unwrap_or(0) as u64;
        self.inner.report(self.start + part, self.whole);
    }
}

/// Runs the operations in order (see the module's doc). `after_operation(i, stock)` sees
/// the stock after operation `i` (from 0), before the next one cuts it.
pub fn run_process(
    process: &ProcessSpec,
    cancel: &CancelFlag,
    progress: &dyn Progress,
    after_operation: &mut dyn FnMut(usize, &Stock),
) -> Result<ProcessOutput, ProcessError> {
    let ops = &process.operations;
    if ops.is_empty() {
        return Err(ProcessError::NoOperations);
    }
    if ops.len() > MAX_OPERATIONS {
        return Err(ProcessError::TooManyOperations { count: ops.len() });
    }
    let failed = |index: usize| {
        let name = ops[index].name.clone();
        move |source: SimulateError| match source {
            SimulateError::Cancelled => ProcessError::Cancelled,
            source => ProcessError::Operation {
                index,
                name,
                source,
            },
        }
    };
    // One cell for all: the finest any operation's tools would take alone.
    let cell = match process.cell {
        Some(c) => c,
        None => {
            let mut radii = Vec::new();
            for (i, op) in ops.iter().enumerate() {
                radii.extend(tool_radii(&op.spec).map_err(failed(i))?);
            }
            geometry::default_cell(&radii)
        }
    };
    let clock = std::time::Instant::now();
    let mut first = ops[0].spec.clone();
    first.stock = process.stock.clone();
    let mut stock = Some(part_frame_stock(&first, cell).map_err(failed(0))?);
    drop(first);
    let grid_s = clock.elapsed().as_secs_f64();

    let weight = |op: &Operation| op.spec.program.len().max(1) as u64;
    let whole: u64 = ops.iter().map(weight).sum();
    let mut start = 0;
    let mut outputs = Vec::with_capacity(ops.len());
    for (i, op) in ops.iter().enumerate() {
        if cancel.is_cancelled() {
            return Err(ProcessError::Cancelled);
        }
        let mut spec = op.spec.clone();
        spec.cell = Some(cell);
        spec.fixture = process.fixture.clone();
        let share = Share {
            inner: progress,
            start,
            width: weight(op),
            whole,
        };
        start += weight(op);
        let given = stock.take().expect("the stock is handed on");
        let out = match &op.spindle {
            Some(sp) => simulate_choosing_spindle_on(&spec, sp, Some(given), cancel, &share),
            None => simulate_on(&spec, given, cancel, &share),
        }
        .map_err(failed(i))?;
        after_operation(i, &out.stock);
        stock = Some(out.stock);
        outputs.push(OperationOutput {
            name: op.name.clone(),
            rows: out.rows,
            optimized_program: out.optimized_program,
            optimization: out.optimization,
            samples: out.samples,
            summary: out.summary,
            timings: out.timings,
            rays_tested: out.rays_tested,
            tool_numbers: out.tool_numbers,
        });
    }
    Ok(ProcessOutput {
        operations: outputs,
        stock: stock.expect("the last operation's stock"),
        cell,
        grid_s,
    })
}
