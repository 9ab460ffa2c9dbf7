//! What a job is held to on the service's side, in one place: the job's limits
//! ([`JobLimits`], its memory budget), their defaults from what the machine and its cgroup
//! allow ([`defaults`]), the checks before a job's engine work starts — a simulation's
//! moves against the machine's travel and its memory estimate against the budget
//! ([`simulation`]), the other kinds' estimates against it ([`kinds`]) — and the problems
//! a job over a limit is refused or failed with ([`problems`]).
//!
//! The engine's `millsim_engine::budget` (engine/src/budget.rs) stays pure and in the
//! engine: it checks moves against a travel and computes a simulation's memory model,
//! buffer by buffer, from its size (stock, cell, moves, tools). This module is what the
//! service does with it: it reads the job's inputs into that size, compares the
//! engine's estimate with the job's budget and says so with a problem naming the limit;
//! the kinds other than simulate/optimize and process are estimated by their own modules
//! (`jobs::interpret::estimate`, ...) with the pieces in [`kinds`].

pub mod defaults;
pub mod kinds;
pub mod problems;
pub mod simulation;

use serde::{Deserialize, Serialize};

pub use defaults::{cgroup_memory_max, check_requested_budget, default_job_memory_mb};
pub use kinds::{lobe_matrices_bytes, lobe_workers, KindEstimate};
pub use problems::over_budget_problem;
pub use simulation::{
    check_simulation, submission_estimate, summary_bounds, Checked, Refusal, SimulationCheck,
};

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
