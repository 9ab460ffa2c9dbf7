//! The parameter search of the `energy` job: spindle speed, axial depth, radial width and
//! feed per tooth of a face or side milling task that maximize the energy utilization (or
//! minimize energy or time) under the stability, force, power and feed limits, with its
//! Pareto front of machining time against energy. The energy model itself is physics:
//! [`crate::physics::energy`].
//!
//! - [`EnergyProblem`]: the search ([`EnergyProblem::search`]), the exhaustive grid
//!   ([`EnergyProblem::grid`]) and the Pareto front ([`EnergyProblem::pareto_front`]);
//!   [`run_energy_job`] runs an [`EnergySearchOptions`] (the `energy` job's options).
//!
//! Units: W, J, s, rpm, mm, mm/min, N, N·m.
//!
//! Files: `options` (the job's JSON), `point` (a point of the space and the results),
//! `problem` (the validated problem and its bounds), `lobes` (the stability constraint),
//! `forces` (the straight-cut engagement and its cached forces), `evaluate` (one point),
//! `speed` (the best spindle speed at one feed), `search` (the search and the grid),
//! `pareto`, `diagnose` (why nothing is feasible).

mod diagnose;
mod evaluate;
mod forces;
mod lobes;
mod options;
mod pareto;
mod point;
mod problem;
mod search;
mod speed;

pub use options::{EnergySearchOptions, Objective, Range};
pub use pareto::non_dominated;
pub use point::{EnergyPoint, EnergySearchResult, SearchSpace, StabilityCheck, Violation};
pub use problem::EnergyProblem;

use crate::job::CancelFlag;
use crate::machine::Machine;
use crate::physics::material::CuttingCoefficients;
use crate::physics::PhysicsError;
use crate::tool::Tool;

/// Default semi-/full-discretization steps per tooth period of the search's lobes.
pub const DEFAULT_SEARCH_STEPS: u32 = 20;
/// Default number of speeds of the search's lobe table (per radial width).
pub const DEFAULT_STABILITY_RPM_POINTS: u32 = 31;
/// Default largest number of axial passes.
pub const DEFAULT_MAX_AXIAL_PASSES: u32 = 8;
/// Bisection tolerance of the search's lobe tables, mm (the linear interpolation between
/// table speeds is the coarser approximation).
pub const DEPTH_TOLERANCE_MM: f64 = 1e-3;
/// Height of the engagement slices of the force model, at most, mm.
const SLICE_MM: f64 = 0.1;

fn lin(lo: f64, hi: f64, i: u32, n: u32) -> f64 {
    if n == 0 || i == 0 {
        lo
    } else if i == n {
        hi
    } else {
        lo + (hi - lo) * i as f64 / n as f64
    }
}

/// Runs the `energy` job: builds the problem, searches the objective and, when
/// `options.pareto`, the front.
pub fn run_energy_job(
    options: &EnergySearchOptions,
    tool: &Tool,
    coefficients: &CuttingCoefficients,
    machine: &Machine,
) -> Result<EnergySearchResult, PhysicsError> {
    run_energy_job_with(options, tool, coefficients, machine, &CancelFlag::new())
}

/// [`run_energy_job`] for a job: ends with [`PhysicsError::Cancelled`] soon after `cancel`
/// is set (looked at before every lobe depth and every feed tried).
pub fn run_energy_job_with(
    options: &EnergySearchOptions,
    tool: &Tool,
    coefficients: &CuttingCoefficients,
    machine: &Machine,
    cancel: &CancelFlag,
) -> Result<EnergySearchResult, PhysicsError> {
    let mut p = EnergyProblem::new_with(options, tool, coefficients, machine, cancel)?;
    let best = p.search(options.objective)?;
    let stability_check = match p.direct_critical_depth_mm(best.radial_passes, best.spindle_rpm)? {
        Some(direct) => Some(StabilityCheck {
            spindle_rpm: best.spindle_rpm,
            axial_depth_mm: best.axial_depth_mm,
            table_critical_depth_mm: best.critical_depth_mm.unwrap_or(f64::NAN),
            direct_critical_depth_mm: direct,
            margin: best.axial_depth_mm / direct,
            within_limit: best.axial_depth_mm <= options.stability_factor * direct,
        }),
        None => None,
    };
    let pareto = if options.pareto {
        Some(p.pareto_front()?)
    } else {
        None
    };
    Ok(EnergySearchResult {
        objective: options.objective,
        best,
        stability_constrained: p.stability_constrained(),
        stability_note: p.stability_note().to_string(),
        stability_check,
        space: p.space(),
        pareto,
        evaluations: p.evaluations(),
    })
}
