//! The problems a job over one of its limits is refused (at submission) or failed (when it
//! runs) with: over the memory budget (a `resource-limit` problem naming `job_memory_mb`,
//! the budget and the estimate), and a move outside the machine's travel.

use serde_json::{json, Value};

use millsim_engine::budget::{self, MemoryEstimate};

use super::kinds::KindEstimate;
use super::JobLimits;
use crate::jobs::JobKind;
use crate::problem::Problem;

/// Bytes in MiB, rounded up, as the problems give them.
pub fn mib(bytes: u64) -> u64 {
    bytes.div_ceil(1 << 20)
}

/// A job over its memory budget: the `resource-limit` problem naming `job_memory_mb`,
/// with the budget (`limit`, MiB), the estimate's peak (`estimate_mb`, MiB) and its parts
/// (`estimate`). `detail` says what needs the memory and what to change.
pub fn over_memory_budget(
    detail: String,
    limits: &JobLimits,
    peak_bytes: u64,
    estimate: Value,
) -> Problem {
    Problem::resource_limit("Over the job's memory budget", detail, "job_memory_mb")
        .with("limit", limits.memory_mb())
        .with("estimate_mb", mib(peak_bytes))
        .with("estimate", estimate)
}

/// The problem of a simulation whose estimate is over its budget (422 at submission, a
/// failed job at run time), naming the program's file when known.
pub fn over_budget_problem(
    file: Option<&str>,
    estimate: &MemoryEstimate,
    limits: &JobLimits,
) -> Problem {
    let problem = over_memory_budget(
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
        limits,
        estimate.peak_bytes,
        serde_json::to_value(estimate).unwrap_or_default(),
    );
    match file {
        Some(f) => problem.with("file", f),
        None => problem,
    }
}

/// The problem of a `kind` job (not a simulation or a process) whose estimate is over its
/// budget: 422 at submission.
pub fn kind_over_budget_problem(kind: JobKind, e: &KindEstimate, limits: &JobLimits) -> Problem {
    over_memory_budget(
        format!(
            "the {} job needs about {} MiB (program and moves {} MiB, lobe matrices {} MiB, rows {} MiB), over the job memory budget of {} MiB (job_memory_mb); {}",
            kind.as_str(),
            mib(e.peak_bytes),
            mib(e.program_bytes),
            mib(e.lobe_matrices_bytes),
            mib(e.rows_bytes),
            limits.memory_mb(),
            match kind {
                JobKind::Interpret | JobKind::RotaryFeed => "split the program",
                JobKind::Accessibility => "decimate the part's mesh",
                _ => "use fewer modes or steps_per_period, or the zoa method",
            },
        ),
        limits,
        e.peak_bytes,
        serde_json::to_value(e).unwrap_or_default(),
    )
}

/// The problem of a move outside the machine's travel: the file and line, the axis, the
/// value and the travel.
pub(super) fn travel_problem(
    file: &str,
    e: &budget::TravelError,
    travel: [[f64; 2]; 3],
) -> Problem {
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
