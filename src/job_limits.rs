//! What every job is held to before its engine work starts: the machine's travel and the
//! job's memory budget. The checks read the interpreted moves and the engine's estimate
//! (`millsim_engine::budget`); a job that cannot fit fails with a problem naming the
//! limit, the file and line, or the budget and the estimate.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use millsim_engine::budget::{self, MemoryEstimate, SimulationSize};
use millsim_engine::geometry;
use millsim_engine::machine::Machine;
use millsim_engine::nc::{self, Move};
use millsim_engine::pipeline::{AxisReading, StockSource};
use millsim_engine::tool::Tool;
use millsim_engine::tool_library::tools_from_header;

use crate::problem::Problem;

/// What the server holds each job to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct JobLimits {
    /// Memory a job may use, bytes (`--job-memory-mb`).
    pub memory_bytes: u64,
}

impl JobLimits {
    pub fn memory_mb(&self) -> u64 {
        self.memory_bytes >> 20
    }
}

/// The default memory budget per job: what the process may really use (the machine's
/// memory, its cgroup's `memory.max`, its inherited address-space limit), see
/// `default_budget_mb`.
pub fn default_job_memory_mb(workers: usize) -> u64 {
    default_budget_mb(
        total_memory_bytes(),
        cgroup_memory_max(),
        crate::isolate::inherited_address_space().map(crate::isolate::budget_under_address_space),
        workers,
    )
}

/// The default budget, MiB: the smaller of the machine's memory and the cgroup's limit
/// (both shared by every job at once) divided by the workers, at most 16 GiB and at least
/// 512 MiB; then never above `address_space_fit_mb`, the budget a job process can be given
/// under an inherited RLIMIT_AS (per process, so not divided: each job gets its own).
pub fn default_budget_mb(
    total_bytes: Option<u64>,
    cgroup_bytes: Option<u64>,
    address_space_fit_mb: Option<u64>,
    workers: usize,
) -> u64 {
    let total_mb = total_bytes.map(|b| b >> 20).unwrap_or(4096);
    let shared_mb = cgroup_bytes.map_or(total_mb, |c| total_mb.min(c >> 20));
    let budget = (shared_mb / workers.max(1) as u64).clamp(512, 16 << 10);
    match address_space_fit_mb {
        // Above it every job process would fail to start (setrlimit EPERM).
        Some(fit) => budget.min(fit),
        None => budget,
    }
}

/// Refuses an explicit `--job-memory-mb` no job process could be given: above what the
/// inherited address-space limit leaves a job (`address_space_fit_mb`, with the limit
/// `address_space_bytes`), or above the cgroup's `memory.max` (one job alone would be
/// killed by the kernel before reaching it).
pub fn check_requested_budget(
    requested_mb: u64,
    address_space: Option<(u64, u64)>,
    cgroup_bytes: Option<u64>,
) -> Result<(), String> {
    if let Some((limit_bytes, fit_mb)) = address_space {
        if requested_mb > fit_mb {
            return Err(format!(
                "--job-memory-mb {requested_mb} is above the {fit_mb} MiB the inherited address-space limit (ulimit -v, LimitAS=: {} MiB, less what a job process needs besides its budget) allows; lower --job-memory-mb or raise the limit",
                limit_bytes >> 20
            ));
        }
    }
    if let Some(c) = cgroup_bytes {
        if requested_mb > c >> 20 {
            return Err(format!(
                "--job-memory-mb {requested_mb} is above the {} MiB the cgroup's memory.max (the container's memory limit) allows; lower --job-memory-mb or raise the limit",
                c >> 20
            ));
        }
    }
    Ok(())
}

/// The memory limit of this process's cgroup (v2) and its ancestors, the smallest, bytes;
/// None when there is none (or no cgroup v2).
pub fn cgroup_memory_max() -> Option<u64> {
    let own = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let path = cgroup_v2_path(&own)?;
    let root = std::path::Path::new("/sys/fs/cgroup");
    // A parent's limit holds for its children too: walk up to the root.
    let mut dir = root.join(path.trim_start_matches('/'));
    let mut smallest: Option<u64> = None;
    loop {
        if let Ok(text) = std::fs::read_to_string(dir.join("memory.max")) {
            if let Some(b) = parse_memory_max(&text) {
                smallest = Some(smallest.map_or(b, |s| s.min(b)));
            }
        }
        if dir == root || !dir.pop() || !dir.starts_with(root) {
            break;
        }
    }
    smallest
}

/// The cgroup v2 path in `/proc/self/cgroup` contents (the `0::/path` line).
pub fn cgroup_v2_path(proc_self_cgroup: &str) -> Option<&str> {
    proc_self_cgroup
        .lines()
        .find_map(|l| l.strip_prefix("0::"))
        .map(str::trim)
        .filter(|p| p.starts_with('/'))
}

/// A `memory.max` file's contents: bytes, or None for `max` (no limit) or unreadable text.
pub fn parse_memory_max(text: &str) -> Option<u64> {
    match text.trim() {
        "max" => None,
        n => n.parse().ok(),
    }
}

/// Total memory of the machine (MemTotal of /proc/meminfo), if known.
fn total_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The problem of a job whose estimate is over its budget (422 at submission, a failed
/// job at run time).
pub fn over_budget_problem(
    file: Option<&str>,
    estimate: &MemoryEstimate,
    limits: &JobLimits,
) -> Problem {
    let mib = |b: u64| b.div_ceil(1 << 20);
    let problem = Problem::resource_limit(
        "Over the job's memory budget",
        format!(
            "{}the simulation needs about {} MiB (grid {} MiB, step records held at once {} MiB, what the steps keep {} MiB, rows {} MiB, stock export {} MiB, STL mesh read {} MiB), over the job memory budget of {} MiB (job_memory_mb); use a coarser cell_mm, a smaller stock or shorter moves",
            file.map(|f| format!("{f}: ")).unwrap_or_default(),
            mib(estimate.peak_bytes),
            mib(estimate.grid_bytes),
            mib(estimate.steps_bytes),
            mib(estimate.kept_bytes),
            mib(estimate.rows_bytes),
            mib(estimate.export_bytes),
            mib(estimate.mesh_bytes),
            limits.memory_mb(),
        ),
        "job_memory_mb",
    )
    .with("limit", limits.memory_mb())
    .with("estimate_mb", mib(estimate.peak_bytes))
    .with("estimate", serde_json::to_value(estimate).unwrap_or_default());
    match file {
        Some(f) => problem.with("file", f),
        None => problem,
    }
}

fn travel_problem(file: &str, e: &budget::TravelError, travel: [[f64; 2]; 3]) -> Problem {
    Problem::new(
        axum::http::StatusCode::UNPROCESSABLE_ENTITY,
        "out-of-travel",
        "Move outside the machine's travel",
        format!("{file}:{e}"),
    )
    .with("file", file)
    .with("line", e.line)
    .with("axis", e.axis.to_string())
    .with("value", e.value)
    .with("travel_mm", json!(travel))
}

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
    fn the_default_budget_shares_the_memory_within_bounds() {
        let one = default_job_memory_mb(1);
        assert!((512..=16 << 10).contains(&one));
        assert!(default_job_memory_mb(10_000) == 512);
    }

    #[test]
    fn the_cgroup_limit_is_read_from_its_files() {
        let v1_and_v2 = "4:memory:/process_api/8a27\n1:cpu:/\n0::/system.slice/millsim.service\n";
        assert_eq!(
            cgroup_v2_path(v1_and_v2),
            Some("/system.slice/millsim.service")
        );
        assert_eq!(cgroup_v2_path("0::/\n"), Some("/"));
        // cgroup v1 only: no v2 path, so no limit read.
        assert_eq!(cgroup_v2_path("4:memory:/docker/abc\n1:cpu:/\n"), None);
        assert_eq!(parse_memory_max("max\n"), None);
        assert_eq!(parse_memory_max("4294967296\n"), Some(4 << 30));
        assert_eq!(parse_memory_max(""), None);
    }

    #[test]
    fn the_default_budget_is_the_smallest_limit_shared_by_the_workers() {
        let gib = 1u64 << 30;
        // Machine 64 GiB, 4 workers: 16 GiB each.
        assert_eq!(default_budget_mb(Some(64 * gib), None, None, 4), 16 << 10);
        // A container limited to 8 GiB on that machine: 2 GiB each.
        assert_eq!(
            default_budget_mb(Some(64 * gib), Some(8 * gib), None, 4),
            2048
        );
        // A cgroup limit above the machine's memory changes nothing.
        assert_eq!(
            default_budget_mb(Some(8 * gib), Some(64 * gib), None, 2),
            4096
        );
        // An inherited address-space limit caps each job, not divided (each process has its own).
        assert_eq!(default_budget_mb(Some(64 * gib), None, Some(5000), 2), 5000);
        assert_eq!(
            default_budget_mb(Some(64 * gib), Some(8 * gib), Some(5000), 2),
            4096
        );
        // Under a tiny address-space limit, below the usual 512 MiB floor.
        assert_eq!(default_budget_mb(Some(64 * gib), None, Some(100), 1), 100);
    }

    #[test]
    fn a_requested_budget_above_a_limit_is_refused_naming_both() {
        let as_limit = Some((6u64 << 30, 4864));
        let e = check_requested_budget(12000, as_limit, None).unwrap_err();
        assert!(
            e.contains("--job-memory-mb 12000")
                && e.contains("4864 MiB")
                && e.contains("address-space"),
            "{e}"
        );
        assert!(check_requested_budget(4864, as_limit, None).is_ok());
        let e = check_requested_budget(3000, None, Some(2 << 30)).unwrap_err();
        assert!(
            e.contains("--job-memory-mb 3000")
                && e.contains("2048 MiB")
                && e.contains("memory.max"),
            "{e}"
        );
        assert!(check_requested_budget(2048, None, Some(2 << 30)).is_ok());
        assert!(check_requested_budget(1 << 20, None, None).is_ok());
    }

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
