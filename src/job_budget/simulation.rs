//! What a simulate/optimize job (and each process operation) is held to before the
//! pipeline runs: the program's moves inside the machine's travel, and the engine's
//! memory estimate (`millsim_engine::budget::estimate_simulation`) within the budget; at
//! submission, without the program, the grid and the stock export alone.

use std::collections::BTreeMap;

use serde_json::Value;

use millsim_engine::budget::{self, MemoryEstimate, SimulationSize};
use millsim_engine::geometry;
use millsim_engine::machine::Machine;
use millsim_engine::nc::{self, Move};
use millsim_engine::pipeline::{AxisReading, StockSource};
use millsim_engine::tool::Tool;
use millsim_engine::tool_library::tools_from_header;

use super::problems::{over_budget_problem, travel_problem};
use super::JobLimits;
use crate::problem::Problem;

/// The grid spacing a simulation will use: the one asked for, else the engine's default
/// from the radii of the tools the program uses (given, from the library, or described in
/// its header).
fn cell_and_tools(
    cell: Option<f64>,
    program: &str,
    moves: &[Move],
    tools: &BTreeMap<u32, Tool>,
) -> (f64, Vec<Tool>) {
    let header = tools_from_header(program);
    let mut used: Vec<u32> = moves.iter().map(|m| m.tool).filter(|t| *t != 0).collect();
    used.sort_unstable();
    used.dedup();
    let mut found: Vec<Tool> = match tools.get(&0) {
        Some(t) => vec![t.clone()],
        None => used
            .iter()
            .filter_map(|n| tools.get(n).or_else(|| header.tools.get(n)).cloned())
            .collect(),
    };
    if found.is_empty() {
        found = tools
            .values()
            .chain(header.tools.values())
            .cloned()
            .collect();
    }
    let radii: Vec<f64> = found.iter().map(Tool::radius).collect();
    (
        cell.unwrap_or_else(|| geometry::default_cell(&radii)),
        found,
    )
}

/// The stock's bounds and, for an STL stock, its triangle count.
fn stock_bounds(stock: &StockSource) -> Option<([f64; 3], [f64; 3], u64)> {
    match stock {
        StockSource::Shape(shape) => shape.bounds().ok().map(|(lo, hi)| (lo, hi, 0)),
        StockSource::Stl(source) => source.mesh().ok().map(|m| {
            let (lo, hi) = m.bounds();
            (lo, hi, m.triangles.len() as u64)
        }),
    }
}

/// What a simulate/optimize job checks before the pipeline runs.
pub struct SimulationCheck<'a> {
    pub file: &'a str,
    pub program: &'a str,
    pub interpret: &'a nc::InterpretOptions,
    pub machine: &'a Machine,
    pub axes: AxisReading,
    pub stock: &'a StockSource,
    pub tools: &'a BTreeMap<u32, Tool>,
    pub cell: Option<f64>,
    /// An optimize job (the optimizer keeps a record of every step).
    pub optimize: bool,
    /// Triangles of the design part's mesh (0 without one).
    pub part_triangles: u64,
}

/// Why a simulation may not start.
pub enum Refusal {
    /// The program does not interpret (the pipeline would say the same).
    Program(nc::Diagnostics),
    /// A problem: out of travel, or over the memory budget.
    Problem(Problem),
}

/// What [`check_simulation`] found.
pub struct Checked {
    /// The memory estimate (None for a stock or grid the pipeline itself reports).
    pub estimate: Option<MemoryEstimate>,
    /// The radii of the tools the program cuts with, given by id, from a tool library or
    /// from its header comments: the finest sets the default cell.
    pub tool_radii: Vec<f64>,
    /// The cell the estimate is at: the check's, else the tools' default.
    pub cell: f64,
}

/// Interprets the program and checks its moves against the machine's travel (under
/// tool-tip reading, X Y Z are the tip in the part frame: the generic travel then) and
/// the simulation's memory estimate against the budget. Returns the estimate and the
/// tools it was made for.
pub fn check_simulation(c: &SimulationCheck, limits: &JobLimits) -> Result<Checked, Refusal> {
    let interpretation = nc::interpret(c.program, c.interpret).map_err(Refusal::Program)?;
    let moves = &interpretation.moves;
    let travel = match c.axes {
        AxisReading::Machine => budget::travel_of(c.machine),
        AxisReading::ToolTip => budget::travel_of(&Machine::generic()),
    };
    budget::check_travel(moves, travel)
        .map_err(|e| Refusal::Problem(travel_problem(c.file, &e, travel)))?;
    let (cell, tools) = cell_and_tools(c.cell, c.program, moves, c.tools);
    let mut checked = Checked {
        estimate: None,
        tool_radii: tools.iter().map(Tool::radius).collect(),
        cell,
    };
    let Some((stock_min, stock_max, stock_triangles)) = stock_bounds(c.stock) else {
        // The pipeline reports an unreadable stock.
        return Ok(checked);
    };
    let size = SimulationSize {
        stock_min,
        stock_max,
        cell,
        moves,
        tool_radius: tools.iter().map(Tool::radius).fold(0.0, f64::max),
        optimize: c.optimize,
        mesh_triangles: stock_triangles + c.part_triangles,
    };
    let Ok(estimate) = budget::estimate_simulation(&size) else {
        // An absurd grid: the pipeline's own grid check names it.
        return Ok(checked);
    };
    if estimate.peak_bytes > limits.memory_bytes {
        return Err(Refusal::Problem(over_budget_problem(
            Some(c.file),
            &estimate,
            limits,
        )));
    }
    checked.estimate = Some(estimate);
    Ok(checked)
}

/// At submission, without the program: the grid and the stock export alone, for a stock
/// whose bounds are known and a cell that is (given, or from the tools' diameters).
/// Some(estimate) when it is over the budget.
pub fn submission_estimate(
    stock_bounds: ([f64; 3], [f64; 3]),
    stock_triangles: u64,
    cell: Option<f64>,
    tool_diameters: &[f64],
    limits: &JobLimits,
) -> Option<MemoryEstimate> {
    let cell = match cell {
        Some(c) => c,
        None if !tool_diameters.is_empty() => {
            let radii: Vec<f64> = tool_diameters.iter().map(|d| d / 2.0).collect();
            geometry::default_cell(&radii)
        }
        None => return None,
    };
    let size = SimulationSize {
        stock_min: stock_bounds.0,
        stock_max: stock_bounds.1,
        cell,
        moves: &[],
        tool_radius: 0.0,
        optimize: false,
        mesh_triangles: stock_triangles,
    };
    let estimate = budget::estimate_simulation(&size).ok()?;
    (estimate.peak_bytes > limits.memory_bytes).then_some(estimate)
}

/// Bounds of a stored stock from its summary (`{"bounds":{"min":..,"max":..}}`).
pub fn summary_bounds(summary: &Value) -> Option<([f64; 3], [f64; 3])> {
    let corner = |v: &Value| -> Option<[f64; 3]> {
        let a = v.as_array()?;
        Some([
            a.first()?.as_f64()?,
            a.get(1)?.as_f64()?,
            a.get(2)?.as_f64()?,
        ])
    };
    Some((
        corner(&summary["bounds"]["min"])?,
        corner(&summary["bounds"]["max"])?,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fine_grid_on_a_large_stock_is_over_a_small_budget_at_submission() {
        let limits = JobLimits {
            memory_bytes: 2 << 30,
        };
        let cube = ([0.0; 3], [27.0; 3]);
        let e = submission_estimate(cube, 0, Some(0.005), &[], &limits).unwrap();
        let p = over_budget_problem(None, &e, &limits).to_json();
        assert_eq!(p["limit"], 2048);
        // The grid alone is 4 GB (5400 rays a side, three families); the stock file
        // goes to disk, a band of its triangles at a time.
        assert!(p["estimate_mb"].as_u64().unwrap() > 4_000, "{p}");
        assert!(submission_estimate(cube, 0, Some(0.1), &[], &limits).is_none());
        assert!(submission_estimate(cube, 0, None, &[], &limits).is_none());
    }
}
