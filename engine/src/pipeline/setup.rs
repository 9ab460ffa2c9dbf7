//! Where the machine stands when the program starts, and whether the program's size fits
//! its stock: what the interpreter alone cannot know.

use crate::geometry::{self, GridFrame};
use crate::machine::Machine;
use crate::nc::{Move, MoveKind, ToolChangeTo};

use super::spec::{SimulateError, SimulateSpec, StockSource};

/// The stock's bounds in `frame`, mm (the mesh is read by the caller once).
pub(super) fn stock_bounds(
    spec: &SimulateSpec,
    mesh: Option<&geometry::Mesh>,
    frame: &GridFrame,
) -> Result<([f64; 3], [f64; 3]), SimulateError> {
    Ok(match (&spec.stock, mesh) {
        (StockSource::Shape(shape), _) => shape.bounds_in(frame)?,
        (_, Some(mesh)) => mesh.bounds_in(frame),
        _ => unreachable!("an STL stock has its mesh"),
    })
}

/// The interpreter's start and tool-change positions on this machine over this stock: the
/// machine's own when it gives them, else the tip `clearance_mm` above the stock's top over
/// program zero's X and Y, and tool changes that retract Z to that height. A real machine
/// never starts a program at program zero inside the stock.
pub(super) fn start_positions(
    machine: &Machine,
    stock_top: f64,
) -> (Option<[f64; 3]>, Option<ToolChangeTo>) {
    let height = stock_top + machine.clearance_mm;
    let start = machine.start_position_mm.unwrap_or([0.0, 0.0, height]);
    let change = match machine.tool_change_position_mm {
        Some(p) => ToolChangeTo::Position(p),
        None => ToolChangeTo::RaiseTo(height),
    };
    (Some(start), Some(change))
}

/// A warning when the cutting moves' extent and the stock's differ by an order of magnitude
/// or more: most often an inch program read as millimetres (no G20), or the other way.
pub(super) fn size_mismatch_warning(
    moves: &[Move],
    (lo, hi): ([f64; 3], [f64; 3]),
) -> Option<String> {
    let mut plo = [f64::INFINITY; 3];
    let mut phi = [f64::NEG_INFINITY; 3];
    for m in moves
        .iter()
        .filter(|m| matches!(m.kind, MoveKind::Linear | MoveKind::Arc))
    {
        for p in [m.start, m.end] {
            for i in 0..3 {
                plo[i] = plo[i].min(p[i]);
                phi[i] = phi[i].max(p[i]);
            }
        }
    }
    if !plo[0].is_finite() {
        return None;
    }
    // The largest extent across X and Y (a program may not span the stock's height).
    let span = |a: [f64; 3], b: [f64; 3]| (b[0] - a[0]).max(b[1] - a[1]);
    let (program, stock) = (span(plo, phi), span(lo, hi));
    if !(program > 0.0 && stock > 0.0) {
        return None;
    }
    let ratio = program / stock;
    if ratio < 0.1 {
        Some(format!(
            "the feed moves span {program:.3} mm in X/Y but the stock spans {stock:.1} mm \
             ({:.0}× smaller): is this an inch program without G20? (25.4× smaller if so)",
            1.0 / ratio
        ))
    } else if ratio > 10.0 {
        Some(format!(
            "the feed moves span {program:.1} mm in X/Y but the stock spans {stock:.3} mm \
             ({ratio:.0}× larger): is this a millimetre program read in inches (G20), or a \
             stock given in inches?"
        ))
    } else {
        None
    }
}

/// A grid handed over by a previous operation: in the part frame, and at the cell this
/// simulation asks for (when it asks for one).
pub(super) fn check_given_grid(
    spec: &SimulateSpec,
    stock: &geometry::Stock,
) -> Result<(), SimulateError> {
    if !stock.frame.is_identity() {
        return Err(SimulateError::GivenGrid(
            "the stock handed over is turned (a 3+2 operation's grid); only a grid in the part frame can be cut on".into(),
        ));
    }
    if let Some(cell) = spec.cell {
        if (cell - stock.grid.cell).abs() > 1e-12 * cell.max(1.0) {
            return Err(SimulateError::GivenGrid(format!(
                "the stock handed over has cells of {} mm, the simulation asks for {cell} mm: every operation on one stock uses one cell size",
                stock.grid.cell
            )));
        }
    }
    Ok(())
}

/// The bounds of a grid's stock as its next operation starts: its faces across, and its
/// highest material on top (where the machine starts above it, as above a stock read
/// from the previous operation's exported STL).
pub(super) fn grid_bounds(stock: &geometry::Stock) -> ([f64; 3], [f64; 3]) {
    let g = &stock.grid;
    let lo = [0, 1, 2].map(|a| g.edges[a][0]);
    let mut hi = [0, 1, 2].map(|a| g.edges[a][g.n[a]]);
    let top = g.max_z();
    if top.is_finite() {
        hi[2] = top;
    }
    (lo, hi)
}
