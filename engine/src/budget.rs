//! What a job is held to before it runs: every move inside the machine's travel, and an
//! estimate of a simulation's memory, buffer by buffer, to compare with the job's budget.
//!
//! Both read the interpreted moves (the interpreter itself is not touched): a move to
//! `X1000000000000` or a kilometre-long cut is refused here, naming its line, before the
//! removal allocates a step record per cell of its length.

use serde::Serialize;

use crate::geometry::frame::MAX_TURNED_GRID_GROWTH;
use crate::geometry::{export, DexelGrid, GeometryError};
use crate::machine::cycle_time::move_length;
use crate::machine::Machine;
use crate::nc::{Move, MoveKind};
use crate::pipeline::MoveRow;

/// Travel of each linear axis when the machine gives none: ±2 m, larger than any
/// machining centre's table but small enough that a unit mistake or a runaway
/// coordinate is caught.
pub const DEFAULT_TRAVEL_MM: f64 = 2000.0;

/// The machine's linear travel [min, max] for X, Y, Z, mm, or the generic default.
pub fn travel_of(machine: &Machine) -> [[f64; 2]; 3] {
    machine
        .travel
        .unwrap_or([[-DEFAULT_TRAVEL_MM, DEFAULT_TRAVEL_MM]; 3])
}

/// A move that leaves the travel.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("line {line}: {axis} reaches {value} mm, outside the machine's travel [{min}, {max}] mm")]
pub struct TravelError {
    pub line: u32,
    /// `X`, `Y` or `Z`.
    pub axis: char,
    pub value: f64,
    pub min: f64,
    pub max: f64,
}

const AXES: [char; 3] = ['X', 'Y', 'Z'];

/// Checks that every move's end point, and every arc's extreme points in its plane, lie
/// inside `travel`; the first one outside is named with its line and axis. Not a number
/// counts as outside.
pub fn check_travel(moves: &[Move], travel: [[f64; 2]; 3]) -> Result<(), TravelError> {
    let check = |line: u32, axis: usize, value: f64| {
        let [min, max] = travel[axis];
        if value >= min && value <= max {
            Ok(())
        } else {
            Err(TravelError {
                line,
                axis: AXES[axis],
                value,
                min,
                max,
            })
        }
    };
    for m in moves {
        for axis in 0..3 {
            check(m.line, axis, m.end[axis])?;
        }
        if let Some(arc) = &m.arc {
            let [a, b, _] = arc.axes;
            let r = arc.start_radius.max(arc.end_radius);
            let theta0 = (arc.start[b] - arc.center[b]).atan2(arc.start[a] - arc.center[a]);
            // The arc reaches an axis' extreme where its angle passes 0, 90, 180 or 270°.
            for k in 0..4 {
                let phi = k as f64 * std::f64::consts::FRAC_PI_2;
                let turned = if arc.sweep >= 0.0 {
                    (phi - theta0).rem_euclid(std::f64::consts::TAU)
                } else {
                    (theta0 - phi).rem_euclid(std::f64::consts::TAU)
                };
                if !(arc.sweep.abs() >= std::f64::consts::TAU || turned <= arc.sweep.abs()) {
                    continue;
                }
                check(m.line, a, arc.center[a] + r * phi.cos())?;
                check(m.line, b, arc.center[b] + r * phi.sin())?;
            }
        }
    }
    Ok(())
}

/// Bytes a simulation is expected to hold, by buffer, and its peak.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct MemoryEstimate {
    /// The tri-dexel grid: one ray header per ray of the three families.
    pub grid_bytes: u64,
    /// The removal pass's summary of each ray (its material's extent and the gap the tool
    /// is in), held while the program is swept.
    pub summaries_bytes: u64,
    /// The interpreted moves.
    pub moves_bytes: u64,
    /// Step records held at once: the removal hands its steps on in batches
    /// (`pipeline::DEFAULT_BATCH_STEPS` cells of path; a single longer move in parts of
    /// that), so this is one batch's.
    pub steps_bytes: u64,
    /// What every step keeps until the job ends: its force sample (and the sample's JSON),
    /// and in an optimize job what the optimizer reads of it.
    pub kept_bytes: u64,
    /// Per-block rows, as structs and as the JSON text stored.
    pub rows_bytes: u64,
    /// The stock export: the voxel columns, the triangles, and the file.
    pub export_bytes: u64,
    /// Reading an STL stock (and part) and filling the grid from it (see
    /// [`MESH_BUILD_BYTES_PER_TRIANGLE`]).
    pub mesh_bytes: u64,
    /// The largest of the three phases: the stock read (grid and meshes), removal (grid, ray summaries, moves, a batch of steps, what the
    /// steps keep, rows) and export (grid, rows, samples, export), plus a fixed allowance
    /// for the program text, the force tables and the process.
    pub peak_bytes: u64,
}

/// Fixed allowance for what does not grow with the job (code, runtime, force tables).
pub const FIXED_BYTES: u64 = 96 << 20;

/// JSON text of one stored row, bytes (a simulate row has about 40 fields).
const ROW_JSON_BYTES: u64 = 1400;

/// Bytes one removal step of a straight move holds while its batch is swept and
/// evaluated (its geometry, packed engagement, the removal pass's record, its force
/// result). Calibrated when every step lived until the end: the adaptive example (81,000
/// cells of path, 295 MB peak RSS) held 2 to 2.5 KB per cut step before engagements were
/// packed, 1.07 KB of heap per step after (131.7 MB peak heap, 91 MB of it the grid,
/// 37,900 steps); a flank cut 8 mm deep at 0.1 mm (80 slices a step, packed into runs)
/// 0.56 KB.
pub const STEP_BYTES: u64 = 2048;

/// The same for a step of an arc (its sampled pieces too). Measured: a 1000-turn circle of
/// radius 5 mm in a block (D10 flat, 0.25 mm cells, 125,600 steps, one move, so one batch)
/// peaked 420 MB over the same program's 100 turns, 3.3 to 3.7 KB per step (heaptrack puts
/// 400 of its 457 MB heap in the removal pass's per-step records).
pub const ARC_STEP_BYTES: u64 = 3584;

/// Bytes every step keeps after its batch: its force sample (48 B) and the sample's JSON
/// in the stored rows (about 130 B). Measured: 3000 one-turn circles hold 3 MB more heap
/// than 1000 (146,000 more steps, most in air: 21 B each with their rows); the adaptive
/// example's 31,000 samples 1.5 MB.
pub const KEPT_STEP_BYTES: u64 = 256;

/// Bytes the optimizer keeps of each step (its place and tip ratio, the packed engagement
/// and peak response of a cutting step, and the schedule's per-step records). Measured
/// (heaptrack, peak heap of optimize over simulate): 3000 one-turn circles over 1000, 333 B
/// per added (air) step; the adaptive example, 362 B per step (37,900 steps, 31,200 cut).
pub const OPTIMIZER_STEP_BYTES: u64 = 512;

/// Cells of path per batch of steps (`pipeline::DEFAULT_BATCH_STEPS`).
const BATCH_CELLS: u64 = crate::pipeline::DEFAULT_BATCH_STEPS as u64;

/// Length of the straight segment `a`–`b` (X Y Z) inside the box `[lo, hi]`.
fn clipped_length(a: &[f64; 6], b: &[f64; 6], lo: [f64; 3], hi: [f64; 3]) -> f64 {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..3 {
        let d = b[k] - a[k];
        if d.abs() < 1e-300 {
            if a[k] < lo[k] || a[k] > hi[k] {
                return 0.0;
            }
            continue;
        }
        let (u, v) = ((lo[k] - a[k]) / d, (hi[k] - a[k]) / d);
        t0 = t0.max(u.min(v));
        t1 = t1.min(u.max(v));
    }
    if t1.partial_cmp(&t0) != Some(std::cmp::Ordering::Greater) {
        return 0.0;
    }
    let len = (0..3).map(|k| (b[k] - a[k]).powi(2)).sum::<f64>().sqrt();
    len * (t1 - t0)
}

/// How a simulation will run, as far as its memory goes.
pub struct SimulationSize<'a> {
    /// Bounds of the stock, mm.
    pub stock_min: [f64; 3],
    pub stock_max: [f64; 3],
    /// Dexel spacing, mm.
    pub cell: f64,
    pub moves: &'a [Move],
    /// The largest tool radius, mm: how far from the stock a step can still engage.
    pub tool_radius: f64,
    /// An optimize job: the optimizer keeps a compact record of every step.
    pub optimize: bool,
    /// Triangles of the STL meshes read (the stock's and the design part's; 0 for
    /// parametric stock and no part).
    pub mesh_triangles: u64,
}

/// Bytes per triangle while an STL stock is read and its grid filled: the merged mesh,
/// the vertex index built while reading, the ray caster's copy and its BVH. Measured
/// (job process VmHWM, boxes of 1.08 M, 3.0 M and 6.0 M triangles cut by a slot on a
/// 0.5 mm grid of a few MB): 428, 1165 and 2337 MB, 384-388 B a triangle.
pub const MESH_BUILD_BYTES_PER_TRIANGLE: u64 = 400;

/// Bytes per triangle of a mesh held for the rest of the job (vertices, about half a
/// vertex a triangle at 24 B, and 12 B of indices).
pub const MESH_HELD_BYTES_PER_TRIANGLE: u64 = 24;

/// The memory estimate of a simulation (see [`MemoryEstimate`]).
pub fn estimate_simulation(size: &SimulationSize) -> Result<MemoryEstimate, GeometryError> {
    let mut grid = DexelGrid::estimate(size.stock_min, size.stock_max, size.cell)?;
    // A program on rotary axes may get its grid turned along a fixed tool axis, up to
    // `MAX_TURNED_GRID_GROWTH` times larger (see `geometry::frame`).
    if size
        .moves
        .iter()
        .any(|m| m.end[3..].iter().any(|&a| a != 0.0))
    {
        grid.bytes = (grid.bytes as f64 * MAX_TURNED_GRID_GROWTH).ceil() as u64;
    }
    let [nx, ny, nz] = grid.cells.map(|n| n as u64);
    let moves_bytes = size.moves.len() as u64 * std::mem::size_of::<Move>() as u64
        + size.moves.iter().filter(|m| m.arc.is_some()).count() as u64 * 160;
    let rows_bytes =
        size.moves.len() as u64 * (std::mem::size_of::<MoveRow>() as u64 + ROW_JSON_BYTES);

    // Steps are one cell long (longer only where nothing changes), recorded only where the
    // tool can reach the stock: one record per cell of the path inside the stock's box
    // grown by the tool's radius.
    let reach = size.tool_radius.max(0.0);
    let lo = size.stock_min.map(|v| v - reach);
    let hi = size.stock_max.map(|v| v + reach);
    // Steps held at once: a batch of BATCH_CELLS cells of path, or a part of that size of
    // one longer move; every step then keeps its sample (and the optimizer's record).
    let kept_per_step = KEPT_STEP_BYTES
        + if size.optimize {
            OPTIMIZER_STEP_BYTES
        } else {
            0
        };
    let (mut all_steps, mut all_bytes, mut longest_move) = (0u64, 0u64, 0u64);
    for m in size.moves {
        if matches!(m.kind, MoveKind::Dwell | MoveKind::ToolChange) {
            continue;
        }
        let inside = match &m.arc {
            // An arc whose box meets the stock's: all of it (it may wind many times).
            Some(arc) => {
                let [a, b, _] = arc.axes;
                let r = arc.start_radius.max(arc.end_radius);
                let mut amin = [0.0; 3];
                let mut amax = [0.0; 3];
                for k in 0..3 {
                    amin[k] = m.start[k].min(m.end[k]);
                    amax[k] = m.start[k].max(m.end[k]);
                }
                for k in [a, b] {
                    amin[k] = arc.center[k] - r;
                    amax[k] = arc.center[k] + r;
                }
                let meets = (0..3).all(|k| amin[k] <= hi[k] && amax[k] >= lo[k]);
                if meets {
                    move_length(m)
                } else {
                    0.0
                }
            }
            None => clipped_length(&m.start, &m.end, lo, hi),
        };
        let n = if inside.is_finite() {
            (inside / size.cell).ceil().min(1e15) as u64
        } else {
            u64::MAX / 4
        };
        let per_step = if m.arc.is_some() {
            ARC_STEP_BYTES
        } else {
            STEP_BYTES
        };
        let bytes = n.saturating_mul(per_step);
        all_steps = all_steps.saturating_add(n);
        all_bytes = all_bytes.saturating_add(bytes);
        // A move longer than a batch is swept in parts of a batch (and a cell).
        longest_move = longest_move.max(n.min(BATCH_CELLS + 1).saturating_mul(per_step));
    }
    // A batch of the program's own mix of straight and arc steps.
    let batch = if all_steps > BATCH_CELLS {
        all_bytes / all_steps * BATCH_CELLS
    } else {
        all_bytes
    };
    let steps_bytes = batch.max(longest_move);
    let kept_bytes = all_steps.saturating_mul(kept_per_step);
    let samples_bytes = all_steps.saturating_mul(KEPT_STEP_BYTES);

    // Export: the voxel bit columns (layers 0..=nz) of a band of rows at a time, and the
    // triangles, a strip per run of boundary faces (about a quarter of the faces of the
    // stock's box, two triangles each), held in the band's rows until the band is
    // written. The file goes to disk (a job writes it in its directory, `millsim run` in
    // its output folder), so only a band's share of it is in memory: counted four times
    // over (rows are uneven: a slot's rows hold more than a flat floor's), twice for the
    // growth of the rows' buffers, and never more than the whole file twice.
    let row_bytes = nx * (nz + 1).div_ceil(64) * 8;
    let voxels = (ny * row_bytes).min(export::BAND_BYTES as u64 + 3 * row_bytes);
    let boundary_faces = 2 * (nx * ny + ny * nz + nz * nx);
    let stl = export::stl_bytes(2 * boundary_faces / 4);
    let band_rows = (4 * export::BAND_ROWS as u64).min(ny + 1);
    let band_stl = stl / (ny + 1) * band_rows;
    // And the file's write buffer.
    let export_bytes = voxels + 2 * band_stl + (1 << 20);

    let mesh_bytes = size.mesh_triangles * MESH_BUILD_BYTES_PER_TRIANGLE;
    let held = size.mesh_triangles * MESH_HELD_BYTES_PER_TRIANGLE;
    let build = grid.bytes.saturating_add(mesh_bytes);
    // One summary beside each ray header (of the turned grid too, where it grew).
    let summaries_bytes = {
        use crate::geometry::dexel::{Intervals, RaySummary};
        use std::mem::size_of;
        grid.bytes / size_of::<Intervals>() as u64 * size_of::<RaySummary>() as u64
    };
    let removal = grid
        .bytes
        .saturating_add(summaries_bytes)
        .saturating_add(held)
        .saturating_add(moves_bytes)
        .saturating_add(steps_bytes)
        .saturating_add(kept_bytes)
        .saturating_add(rows_bytes);
    let export = grid
        .bytes
        .saturating_add(held)
        .saturating_add(rows_bytes)
        .saturating_add(samples_bytes)
        .saturating_add(export_bytes);
    Ok(MemoryEstimate {
        grid_bytes: grid.bytes,
        summaries_bytes,
        moves_bytes,
        steps_bytes,
        kept_bytes,
        rows_bytes,
        export_bytes,
        mesh_bytes,
        peak_bytes: removal.max(export).max(build).saturating_add(FIXED_BYTES),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nc::{interpret, InterpretOptions};

    fn moves(program: &str) -> Vec<Move> {
        interpret(program, &InterpretOptions::default())
            .unwrap()
            .moves
    }

    #[test]
    fn a_move_past_the_travel_is_named_by_line_and_axis() {
        let travel = travel_of(&Machine::generic());
        let ok = moves("G0 X0 Y0 Z5\nG1 X100 Y-50 F500\n");
        assert!(check_travel(&ok, travel).is_ok());
        let far = moves("G0 X0 Y0 Z5\nG1 X1000000000000 F500\n");
        let e = check_travel(&far, travel).unwrap_err();
        assert_eq!((e.line, e.axis, e.max), (2, 'X', DEFAULT_TRAVEL_MM));
        let mut machine = Machine::generic();
        machine.travel = Some([[0.0, 500.0], [0.0, 400.0], [-300.0, 10.0]]);
        let low = moves("G0 X10 Y10 Z5\nG1 Z-301 F100\n");
        let e = check_travel(&low, travel_of(&machine)).unwrap_err();
        assert_eq!((e.line, e.axis, e.min), (2, 'Z', -300.0));
        assert!(e.to_string().contains("line 2: Z"), "{e}");
    }

    #[test]
    fn an_arc_that_bulges_past_the_travel_is_refused_though_its_ends_are_inside() {
        let travel = [[0.0, 100.0], [0.0, 100.0], [-50.0, 50.0]];
        // A half circle from (90, 50) to (10, 50) over the top: it reaches y = 90.
        let inside = moves("G0 X90 Y50 Z0\nG3 X10 Y50 I-40 J0 F500\n");
        assert!(check_travel(&inside, travel).is_ok());
        let arc = moves("G0 X80 Y50 Z0\nG3 X20 Y50 I-30 J0 F500\nG3 X80 Y50 I30 J0\n");
        assert!(check_travel(&arc, travel).is_ok());
        // Centre (50, 60), radius 45: the half circle over the top reaches y = 105.
        let wide = moves("G0 X95 Y60 Z0\nG3 X5 Y60 I-45 J0 F500\n");
        let e = check_travel(&wide, travel).unwrap_err();
        assert_eq!((e.line, e.axis), (2, 'Y'), "{e}");
    }

    #[test]
    fn reading_an_stl_stock_can_be_the_peak() {
        let m = moves("G0 X0 Y0 Z5\nG1 Z-1 F500\nG1 X40\n");
        let size = |mesh_triangles| SimulationSize {
            stock_min: [0.0, 0.0, -10.0],
            stock_max: [40.0, 30.0, 0.0],
            cell: 0.5,
            moves: &m,
            tool_radius: 5.0,
            optimize: false,
            mesh_triangles,
        };
        let plain = estimate_simulation(&size(0)).unwrap();
        let stl = estimate_simulation(&size(6_000_000)).unwrap();
        assert_eq!(plain.mesh_bytes, 0);
        assert_eq!(stl.mesh_bytes, 6_000_000 * MESH_BUILD_BYTES_PER_TRIANGLE);
        // The 6 M-triangle box measured 2337 MB: the estimate is not below it.
        assert!(stl.peak_bytes >= 2337 << 20, "{stl:?}");
        assert_eq!(
            stl.peak_bytes,
            stl.grid_bytes + stl.mesh_bytes + FIXED_BYTES
        );
    }

    /// The removal pass's ray summaries, counted against a real grid's: left out, the
    /// corpus impeller at 0.1 mm was estimated at 277 MB and peaked at 381 MB RSS, 65 MB
    /// of the difference its 2.0 million rays' summaries.
    #[test]
    fn the_removal_counts_the_ray_summaries_of_a_real_grid() {
        use crate::geometry::dexel::RaySummaries;
        use crate::geometry::stock::Stock;
        let (min, max, cell) = ([0.0, 0.0, -10.0], [40.0, 30.0, 0.0], 0.25);
        let stock = Stock::block(min, max, cell).unwrap();
        let held: usize = (0..3)
            .map(|fam| {
                let s = RaySummaries::new(&stock.grid, fam);
                s.rays.capacity() * std::mem::size_of_val(&s.rays[0])
            })
            .sum();
        let path = moves("G0 X0 Y0 Z5\nG1 Z-1 F500\nG1 X40\n");
        let e = estimate_simulation(&SimulationSize {
            stock_min: min,
            stock_max: max,
            cell,
            moves: &path,
            tool_radius: 5.0,
            optimize: false,
            mesh_triangles: 0,
        })
        .unwrap();
        assert!(
            (held as u64..=held as u64 * 21 / 20).contains(&e.summaries_bytes),
            "{held} {e:?}"
        );
        assert!(
            e.peak_bytes >= e.grid_bytes + e.summaries_bytes + FIXED_BYTES,
            "{e:?}"
        );
    }

    #[test]
    fn the_estimate_grows_with_path_length_and_fine_cells() {
        fn size(moves: &[Move], cell: f64) -> SimulationSize<'_> {
            SimulationSize {
                stock_min: [0.0, 0.0, -10.0],
                stock_max: [40.0, 30.0, 0.0],
                cell,
                moves,
                tool_radius: 5.0,
                optimize: false,
                mesh_triangles: 0,
            }
        }
        let short = moves("G0 X0 Y0 Z5\nG1 Z-1 F500\nG1 X40\n");
        // The path outside the stock (and the tool's reach) records no steps.
        let through = moves("G0 X-1900 Y15 Z5\nG1 Z-1 F500\nG1 X1900\n");
        let a = estimate_simulation(&size(&short, 0.25)).unwrap();
        let b = estimate_simulation(&size(&through, 0.25)).unwrap();
        let step = STEP_BYTES;
        // 5 mm down from the origin, 6 mm down, 40 mm across: 204 quarter-millimetre steps.
        assert_eq!(a.steps_bytes, 204 * step);
        // Of the 3.8 km move, the 50 mm across the stock and the tool's reach each side.
        assert!((200 * step..230 * step).contains(&b.steps_bytes), "{b:?}");
        // 10,000 turns of radius 5 in the stock: 314 m, 1.26 million steps (and the plunge
        // and line before them), swept in parts of a batch; each keeps its sample.
        let turns = moves("G0 X20 Y15 Z5\nG1 Z-2 F500\nG1 X25\nG2 X25 Y15 I-5 J0 P10000\n");
        let c = estimate_simulation(&size(&turns, 0.25)).unwrap();
        assert_eq!(c.steps_bytes, (BATCH_CELLS + 1) * ARC_STEP_BYTES, "{c:?}");
        let steps = 1_256_637;
        assert!(
            (steps..steps + 200).contains(&(c.kept_bytes / KEPT_STEP_BYTES)),
            "{c:?}"
        );
        assert!(c.peak_bytes > c.steps_bytes + c.kept_bytes);
        let fine = estimate_simulation(&size(&short, 0.005)).unwrap();
        // The boundary of 8000 × 6000 × 2000 cells: about 2.6 GB of triangles, written to
        // the file a band of 64 rows at a time; four bands' worth (256 of 6001 rows)
        // counted twice, 222 MB, and a band's 64 MB of voxels.
        let stl = export::stl_bytes(2 * 2 * (8000 * 6000 + 6000 * 2000 + 2000 * 8000) / 4);
        assert!(
            (stl / 6001 * 512..stl / 6001 * 512 + (80 << 20)).contains(&fine.export_bytes),
            "{fine:?}"
        );
        assert!(fine.peak_bytes > fine.export_bytes);
    }

    #[test]
    fn many_short_moves_hold_one_batch_of_steps_and_keep_a_little_per_step() {
        // 2000 passes across the stock at 0.25 mm, far more steps than a batch.
        let mut program = String::from("G0 X-10 Y15 Z5\nG1 Z-1 F500\n");
        for _ in 0..1000 {
            program += "G1 X50\nG1 X-10\n";
        }
        let passes = moves(&program);
        let size = |optimize| SimulationSize {
            stock_min: [0.0, 0.0, -10.0],
            stock_max: [40.0, 30.0, 0.0],
            cell: 0.25,
            moves: &passes,
            tool_radius: 5.0,
            optimize,
            mesh_triangles: 0,
        };
        let e = estimate_simulation(&size(false)).unwrap();
        let step = STEP_BYTES;
        // 2000 passes of 50 mm inside the reach box (the stock and 5 mm), 200 cells each.
        let steps = e.kept_bytes / KEPT_STEP_BYTES;
        assert!((400_000..400_100).contains(&steps), "{e:?}");
        // One batch's worth, not the 2000 passes' 800 MB.
        assert_eq!(e.steps_bytes, BATCH_CELLS * STEP_BYTES);
        assert!(e.steps_bytes < steps * step / 5, "{e:?}");
        let o = estimate_simulation(&size(true)).unwrap();
        assert_eq!(
            o.kept_bytes,
            steps * (KEPT_STEP_BYTES + OPTIMIZER_STEP_BYTES)
        );
        assert!(o.peak_bytes > e.peak_bytes);
    }
}
