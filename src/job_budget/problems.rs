//! The problems a job over one of its limits is refused (at submission) or failed (when it
//! runs) with: over the memory budget by its estimate (a `resource-limit` problem naming
//! `job_memory_mb`, the budget and the estimate), its results over it or its process dead
//! (the job process's, see `isolate`), and a move outside the machine's travel.

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
            "{}the simulation needs about {} MiB (grid {} MiB, its removal summaries {} MiB, step records held at once {} MiB, what the steps keep {} MiB, rows {} MiB, stock export {} MiB, STL mesh read {} MiB), over the job memory budget of {} MiB (job_memory_mb); use a coarser cell_mm, a smaller stock or shorter moves",
            file.map(|f| format!("{f}: ")).unwrap_or_default(),
            mib(estimate.peak_bytes),
            mib(estimate.grid_bytes),
            mib(estimate.summaries_bytes),
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

/// A job whose results (rows, samples, files) sent by its process exceed its budget of
/// `budget_bytes`: the job fails.
pub fn results_over_budget(budget_bytes: u64) -> Problem {
    Problem::resource_limit(
        "Results over the job's memory budget",
        format!("the job's results (rows, samples, files) exceed its memory budget of {} MiB (job_memory_mb)", budget_bytes >> 20),
        "job_memory_mb",
    )
    .with("limit", budget_bytes >> 20)
}

/// A job whose process died without a result (`how`: killed by which signal, or its exit
/// status; `said`: what it wrote on stderr), with a budget of `memory_mb`: out of memory
/// when it says so. The job is not retried.
pub fn process_died(how: &str, said: &str, memory_mb: u64) -> Problem {
    let out_of_memory = said.contains("memory allocation of") || said.contains("out of memory");
    // What the process said that tells why: the failed allocation, a panic, else its last words.
    let last_line = said
        .lines()
        .find(|l| l.contains("memory allocation of"))
        .or_else(|| said.lines().find(|l| l.starts_with("thread '")))
        .or_else(|| said.lines().last())
        .unwrap_or("")
        .trim()
        .to_string();
    Problem::resource_limit(
        if out_of_memory { "Job ran out of memory" } else { "Job's process died" },
        format!(
            "the process running this job {how}{}; its memory budget is {memory_mb} MiB (job_memory_mb). The job is not retried: it would die again",
            if last_line.is_empty() { String::new() } else { format!(" after: {last_line}") },
        ),
        "job_memory_mb",
    )
    .with("limit", memory_mb)
}
