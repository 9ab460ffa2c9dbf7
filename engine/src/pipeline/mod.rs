//! The simulate pipeline: interpret the program, sweep each move through the tri-dexel
//! stock while recording the engagement before removal, evaluate the cutting forces at
//! every engaged step, and aggregate per move into the rows users read; then the energy,
//! chatter and optimize stages where asked.
//!
//! Frames: the stock is given in the machine (G53) frame, the frame of the interpreter's
//! move end points; with no work offset active the two are the program's own frame.
//!
//! Words: a *block* is a line of the program; a *move* is one motion the interpreter makes of
//! it (a block can make several, or run several times); a *piece* is a straight part of a
//! move in the part frame (several where rotary axes turn); a *step* is where the removal
//! takes the engagement along a piece.

mod fixture_stage;
mod forces;
mod frame;
mod line_forces;
mod optimize_stage;
mod pass_spacing;
mod process;
mod removal;
mod rows;
mod setup;
mod spec;
mod spindle_stage;
mod stages;
mod step_totals;
mod tools;

pub use fixture_stage::{FixtureCollision, FixtureSummary};
pub use line_forces::{simulate_for_identification, LineForce, ProgramCuts, MAX_LINES};
pub use process::{
    run_process, Operation, OperationOutput, ProcessError, ProcessOutput, ProcessSpec,
    MAX_OPERATIONS,
};
pub use removal::DEFAULT_BATCH_STEPS;
pub use rows::{
    row_columns, Collision, EnergyTotals, LimitCount, MoveRow, OptimizationSummary,
    RoughnessSummary, RowJson, SimulationOutput, SimulationSummary, StageTimings, StepSample,
    ToolDeflection, ToolLife, ToolOptimization,
};
pub use spec::{AxisReading, ChatterSpec, SimulateError, SimulateSpec, StlSource, StockSource};
pub use spindle_stage::{simulate_choosing_spindle, simulate_choosing_spindle_on, SpindleSummary};

use std::time::Instant;

use crate::geometry::{self, GridFrame, GridOptions, Stock};
use crate::job::{CancelFlag, Progress};
use crate::machine::cycle_time::cycle_time;
use crate::machine::Kinematics;
use crate::nc::{self, Move};
use crate::tool::Tool;

pub fn simulate(
    spec: &SimulateSpec,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<SimulationOutput, SimulateError> {
    simulate_in_batches(spec, DEFAULT_BATCH_STEPS, cancel, progress)
}

/// [`simulate`], the removal handing its steps on about `batch_steps` cells of path at a
/// time (the forces, rows and wear inputs are added up batch by batch, and only what the
/// optimizer reads is kept of each step). The results do not depend on the batch size.
pub fn simulate_in_batches(
    spec: &SimulateSpec,
    batch_steps: usize,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<SimulationOutput, SimulateError> {
    run(spec, batch_steps, cancel, progress, false, None).map(|(out, _, _)| out)
}

/// [`simulate`] on a grid handed over (the stock a previous operation left): `spec.stock`
/// is not read, the grid is cut as it is (no re-meshing) and comes back in the output's
/// `stock`. The grid's cell is the simulation's (`spec.cell` must be unset or the same),
/// and its frame must be the identity (a turned grid belongs to one operation's tool axis).
pub fn simulate_on(
    spec: &SimulateSpec,
    stock: Stock,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<SimulationOutput, SimulateError> {
    run(
        spec,
        DEFAULT_BATCH_STEPS,
        cancel,
        progress,
        false,
        Some(stock),
    )
    .map(|(out, _, _)| out)
}

/// The pipeline; with `keep_steps` it also gives every cutting step (where, at what
/// conditions, its engagement and its time weight) and the force models, for
/// identification; with chatter modes, the chatter models and every cutting row's
/// conditions (for the spindle speed choice).
fn run(
    spec: &SimulateSpec,
    batch_steps: usize,
    cancel: &CancelFlag,
    progress: &dyn Progress,
    keep_steps: bool,
    given: Option<Stock>,
) -> Result<
    (
        SimulationOutput,
        Option<line_forces::KeptCuts>,
        Option<stages::ChatterSetup>,
    ),
    SimulateError,
> {
    let mut timings = StageTimings::default();
    // The STL stock read once, for its bounds (where the machine starts) and its grid.
    // A grid handed over is cut as it is: its cell is the simulation's, its frame the part's.
    if let Some(g) = &given {
        setup::check_given_grid(spec, g)?;
    }
    let (mesh, stock_repairs) = match (&spec.stock, &given) {
        (_, Some(_)) | (StockSource::Shape(_), None) => (None, Default::default()),
        (StockSource::Stl(source), None) => {
            let (mesh, repairs) = source.repaired().map_err(geometry::GeometryError::from)?;
            (Some(mesh), repairs)
        }
    };
    let bounds = match &given {
        Some(g) => setup::grid_bounds(g),
        None => setup::stock_bounds(spec, mesh.as_deref(), &GridFrame::IDENTITY)?,
    };
    let interpret = spec.interpret_options(setup::start_positions(&spec.machine, bounds.1[2]));
    let clock = Instant::now();
    let interpretation =
        nc::interpret(&spec.program, &interpret).map_err(SimulateError::Program)?;
    timings.interpret_s = clock.elapsed().as_secs_f64();
    let moves = &interpretation.moves;
    let mut warnings: Vec<String> = setup::size_mismatch_warning(moves, bounds)
        .into_iter()
        .collect();
    warnings.extend(stl_warnings("stock", &stock_repairs));
    let tools = tools::ToolLookup::new(spec, moves, &interpretation.selected_tools)?;
    check_inputs(spec, moves, &tools)?;

    let radii: Vec<f64> = tools.all().map(Tool::radius).collect();
    let cell = match &given {
        Some(g) => g.grid.cell,
        None => spec.cell.unwrap_or_else(|| geometry::default_cell(&radii)),
    };
    let times = cycle_time(moves, &spec.machine, None)?;
    let mut rows = rows::initial_rows(
        &spec.program,
        moves,
        &times,
        spec.machine.rotary_feed_reading,
    );
    // A program that selects its one tool without loading it (T1, no M6): its moves carry
    // no number, the rows say the tool that cut them.
    for (row, m) in rows.iter_mut().zip(moves) {
        row.tool = tools.number(m);
    }
    let clock = Instant::now();
    let plan = removal::plan_removal(spec, moves, &tools, cell, &mut rows)?;
    let plan_s = clock.elapsed().as_secs_f64();
    let clock = Instant::now();
    let fixture = match &spec.fixture {
        Some(f) => Some(fixture_stage::check_fixture(
            f, &plan, moves, &tools, &mut rows,
        )?),
        None => None,
    };
    let mut warnings = warnings;
    warnings.extend(fixture.as_ref().and_then(fixture_stage::warning));
    timings.fixture_s = clock.elapsed().as_secs_f64();

    // The grid's frame follows the plan's pieces (along a 3+2 program's tool axis).
    let clock = Instant::now();
    let mut stock = match given {
        Some(g) => g,
        None => stock(spec, mesh.as_deref(), cell, plan.grid_frame(moves))?,
    };
    let volume_before = stock.volume();
    timings.stock_s = clock.elapsed().as_secs_f64();

    let clock = Instant::now();
    let (scales, feed_ranges) = forces::feed_scales(spec, moves, &rows);
    let context = step_totals::BatchContext {
        moves,
        tools: &tools,
        models: &plan.models,
        coefficients: spec.material.coefficients,
        feed_ranges: feed_ranges.as_deref(),
    };
    let mut totals =
        step_totals::StepTotals::new(moves.len(), spec.optimize.is_some() || keep_steps);
    // The forces of each batch are computed as it comes; their time is counted apart.
    let mut batch_forces_s = 0.0;
    let rays_tested = removal::remove_material(
        &plan,
        moves,
        &tools,
        cell,
        &mut stock,
        &mut rows,
        batch_steps.max(1),
        cancel,
        progress,
        &mut |rows, steps| {
            let clock = Instant::now();
            let added = totals.add_batch(&context, rows, steps);
            batch_forces_s += clock.elapsed().as_secs_f64();
            added
        },
    )?;
    // The rows' volumes are the three families' mean, batch by batch; the stock read voxel
    // by voxel before and after gives the program's total (see `voxel_scale`).
    let volume_after = stock.volume();
    warnings.extend(rows::spindle_warning(&rows, moves));
    let removed: f64 = rows.iter().map(|r| r.removed_volume).sum();
    let scale = geometry::removal::voxel_scale(volume_before - volume_after, removed);
    for row in rows.iter_mut() {
        row.removed_volume *= scale;
        row.max_mrr *= scale;
    }
    timings.removal_and_engagement_s = plan_s + clock.elapsed().as_secs_f64() - batch_forces_s;

    let clock = Instant::now();
    if cancel.is_cancelled() {
        return Err(SimulateError::Cancelled);
    }
    let step_totals::Totals {
        samples,
        evaluations,
        diameters,
        scallops,
        kept,
    } = totals.finish(&mut rows);
    let energy = match &spec.machine.energy {
        Some(model) => Some(stages::block_energy(model, moves, &mut rows)?),
        None => None,
    };
    let (chatter, chatter_setup) = match &spec.chatter {
        Some(c) => {
            let (margins, setup) = stages::chatter_margins(c, spec, moves, &mut rows, &tools)?;
            (Some(margins), Some(setup))
        }
        None => (None, None),
    };
    // The scallop beside a neighbouring pass from the path's spacing where the path has one.
    let mut scallops = scallops;
    for (i, spacing) in pass_spacing::pass_spacings(moves, &rows, &tools)?
        .into_iter()
        .enumerate()
    {
        if let Some(s) = spacing {
            scallops[i] = crate::physics::roughness::scallop_height(tools.tool_for(&moves[i])?, s)?;
        }
    }
    let tool_life =
        stages::wear_and_roughness(spec, moves, &mut rows, (&diameters, &scallops), &tools)?;
    for row in rows.iter_mut() {
        row.set_flags();
    }
    let total = moves.len() as u64;
    progress.report(total, total);
    timings.forces_s = batch_forces_s + clock.elapsed().as_secs_f64();

    let clock = Instant::now();
    let (optimized_program, optimization) = match &spec.optimize {
        Some(limits) => {
            let (text, summary) = optimize_stage::optimize_stage(
                spec,
                limits,
                moves,
                &mut rows,
                (kept.as_deref().unwrap_or_default(), &scales),
                (
                    &plan.models,
                    &plan
                        .models
                        .keys()
                        .map(|&k| (k, tools.key_number(k)))
                        .collect(),
                ),
                &times,
                &interpret,
                &mut timings,
            )?;
            (Some(text), Some(summary))
        }
        None => (None, None),
    };
    timings.optimize_s = clock.elapsed().as_secs_f64();
    for row in rows.iter_mut() {
        row.set_axis_rates();
    }

    let part = match &spec.part {
        Some(source) => {
            let (mesh, repairs) = source.repaired().map_err(geometry::GeometryError::from)?;
            warnings.extend(stl_warnings("part", &repairs));
            Some(geometry::compare_with_part(&stock, &mesh)?)
        }
        None => None,
    };
    let summary = rows::summarize(
        &rows,
        (moves.len(), interpretation.block_count),
        cell,
        (volume_before, volume_after),
        evaluations,
        &times,
        rows::SummaryExtras {
            energy,
            tool_life,
            tool_warnings: tools.warnings,
            warnings,
            program_warnings: rows::program_warnings(&interpretation.warnings),
            chatter,
            part,
            fixture,
        },
    );
    let kept_cuts = match (keep_steps, kept) {
        (true, Some(kept)) => Some(line_forces::KeptCuts::new(
            kept,
            moves,
            &rows,
            plan.models.clone(),
        )),
        _ => None,
    };
    let output = SimulationOutput {
        rows,
        optimized_program,
        optimization,
        samples,
        summary,
        stock,
        timings,
        rays_tested,
        tool_numbers: tools.numbers,
    };
    Ok((output, kept_cuts, chatter_setup))
}

/// What can be refused before any work: rotary axes on a 3-axis machine, tools and
/// material that cannot exist.
fn check_inputs(
    spec: &SimulateSpec,
    moves: &[Move],
    tools: &tools::ToolLookup,
) -> Result<(), SimulateError> {
    if let Some(m) = moves.iter().find(|m| m.turns_rotary()) {
        if spec.machine.kinematics == Kinematics::Xyz {
            return Err(SimulateError::RotaryAxes { line: m.line });
        }
    }
    for t in tools.all() {
        t.validate().map_err(crate::physics::PhysicsError::from)?;
    }
    spec.material.validate()?;
    if let Some(w) = &spec.workpiece {
        w.compliance().map_err(|e| e.prefixed("workpiece"))?;
    }
    Ok(())
}

/// The stock's grid at dexel spacing `cell`, turned by `frame` unless that grows it by more
/// than `geometry::frame::MAX_TURNED_GRID_GROWTH` or past the memory limit.
fn stock(
    spec: &SimulateSpec,
    mesh: Option<&geometry::Mesh>,
    cell: f64,
    frame: GridFrame,
) -> Result<Stock, SimulateError> {
    let grid = GridOptions {
        cell: Some(cell),
        memory_limit: spec.memory_limit,
    };
    let bounds = |frame: &GridFrame| setup::stock_bounds(spec, mesh, frame);
    let build = |frame: GridFrame| -> Result<Stock, geometry::GeometryError> {
        match (&spec.stock, &mesh) {
            (StockSource::Shape(shape), _) => Stock::from_shape_in(shape, &grid, frame),
            (_, Some(mesh)) => Stock::from_mesh_in(mesh, &grid, frame),
            _ => unreachable!("an STL stock has its mesh"),
        }
    };
    if !frame.is_identity() {
        let bytes = |(lo, hi): ([f64; 3], [f64; 3])| {
            geometry::DexelGrid::estimate(lo, hi, cell).map(|e| e.bytes as f64)
        };
        let (turned, straight) = (bytes(bounds(&frame)?), bytes(bounds(&GridFrame::IDENTITY)?));
        if let (Ok(t), Ok(s)) = (turned, straight) {
            if t <= geometry::frame::MAX_TURNED_GRID_GROWTH * s {
                if let Ok(stock) = build(frame) {
                    return Ok(stock);
                }
            }
        }
    }
    Ok(build(GridFrame::IDENTITY)?)
}

/// The radii of every tool the spec's program cuts with (as the simulation will look them
/// up), for a cell size shared by several operations.
pub(super) fn tool_radii(spec: &SimulateSpec) -> Result<Vec<f64>, SimulateError> {
    let interpretation = nc::interpret(&spec.program, &spec.interpret_options_for_checks())
        .map_err(SimulateError::Program)?;
    let tools =
        tools::ToolLookup::new(spec, &interpretation.moves, &interpretation.selected_tools)?;
    Ok(tools.all().map(Tool::radius).collect())
}

/// What reading the STL of the job's `input` (stock, part) repaired, as the summary's
/// warnings.
fn stl_warnings(input: &str, repairs: &geometry::StlRepairs) -> Vec<String> {
    repairs
        .warnings()
        .into_iter()
        .map(|w| format!("{input} STL: {w}"))
        .collect()
}

/// The stock of `spec` as a grid in the part frame at cell `cell`, for operations that
/// hand it on.
pub(super) fn part_frame_stock(spec: &SimulateSpec, cell: f64) -> Result<Stock, SimulateError> {
    let mesh = match &spec.stock {
        StockSource::Shape(_) => None,
        StockSource::Stl(source) => Some(source.mesh().map_err(geometry::GeometryError::from)?),
    };
    stock(spec, mesh.as_deref(), cell, GridFrame::IDENTITY)
}
