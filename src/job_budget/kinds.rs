//! What the memory estimates of the job kinds other than simulate/optimize and process
//! share: the process itself, the estimate's parts, the lobe workers' transition
//! matrices (stability, energy), and the check of an estimate against the job's budget at
//! submission. Each kind estimates itself from what a submission says (the options, the
//! program's size) in its own module (`jobs::interpret::estimate`, ...): an interpret or
//! rotary-feed job holds its program parsed, its moves and their rows; a stability or
//! energy job the transition matrices of its lobes.

use serde::Serialize;

use millsim_engine::physics::stability::Method;

use super::problems::kind_over_budget_problem;
use super::JobLimits;
use crate::jobs::JobKind;
use crate::problem::Problem;

/// What a job's process holds whatever the job (code, runtime, buffers): measured 11.7 to
/// 13.7 MB peak RSS for `millsim stability` on one mode and `millsim interpret` on a
/// one-line program.
pub const PROCESS_BYTES: u64 = 16 << 20;

/// Square matrices of the transition's dimension each lobe worker holds (the product
/// being built, the step map applied, and the eigenvalue solver's copies). Measured with
/// `millsim stability` on 2 threads, over the one-mode run: dimension 420 (10 modes, 40
/// steps) 10.6 MB more, 7.5 matrices; dimension 992 (16 modes, 60 steps, sdm and fdm) 50
/// MB more, 6.4 matrices.
pub const LOBE_MATRICES_PER_WORKER: u64 = 4;

/// A job kind's memory, by part, bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct KindEstimate {
    /// The program parsed, its moves and their rows (interpret, rotary-feed).
    pub program_bytes: u64,
    /// The lobe workers' transition matrices (stability, energy with modes).
    pub lobe_matrices_bytes: u64,
    /// Result rows.
    pub rows_bytes: u64,
    /// All of it and the process.
    pub peak_bytes: u64,
}

impl KindEstimate {
    /// An estimate of these parts, its peak their sum and the process's.
    pub fn new(program_bytes: u64, lobe_matrices_bytes: u64, rows_bytes: u64) -> KindEstimate {
        KindEstimate {
            program_bytes,
            lobe_matrices_bytes,
            rows_bytes,
            peak_bytes: PROCESS_BYTES
                .saturating_add(program_bytes)
                .saturating_add(lobe_matrices_bytes)
                .saturating_add(rows_bytes),
        }
    }
}

/// Transition matrices of the time-domain lobe methods: dimension 2n + steps·n for n
/// modes (the state and the delayed states of a tooth period), 8 bytes an entry. The
/// zero-order method solves n×n systems per frequency: nothing to count.
pub fn lobe_matrices_bytes(method: Method, modes: u64, steps: u64, workers: u64) -> u64 {
    if method == Method::Zoa {
        return 0;
    }
    let dim = modes.saturating_mul(steps.saturating_add(2));
    dim.saturating_mul(dim)
        .saturating_mul(8 * LOBE_MATRICES_PER_WORKER)
        .saturating_mul(workers.max(1))
}

/// The lobe workers a job process runs at once.
pub fn lobe_workers() -> u64 {
    std::thread::available_parallelism().map_or(1, |n| n.get() as u64)
}

/// Checks a `kind` job's estimate against the budget: Err(problem) when it is over it (a
/// 422 resource-limit problem naming the budget and the estimate).
pub fn check(kind: JobKind, e: &KindEstimate, limits: &JobLimits) -> Result<(), Problem> {
    if e.peak_bytes <= limits.memory_bytes {
        return Ok(());
    }
    Err(kind_over_budget_problem(kind, e, limits))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jobs::{JobOptions, SubmittedInputs};
    use serde_json::{json, Value};

    fn mode() -> Value {
        json!({"freq_hz": 900, "damping": 0.02, "stiffness_n_m": 2e7})
    }

    #[test]
    fn lobe_matrices_cover_the_measured_runs() {
        // `millsim stability` on 2 threads, peak RSS over the one-mode run's 11.7 MB.
        for (modes, steps, measured) in [(10, 40, 10.6e6), (16, 60, 50.0e6)] {
            for method in [Method::Sdm, Method::Fdm] {
                let b = lobe_matrices_bytes(method, modes, steps, 2) as f64;
                assert!(b >= measured && b < 2.0 * measured, "{modes} {steps}: {b}");
            }
        }
        assert_eq!(lobe_matrices_bytes(Method::Zoa, 16, 60, 2), 0);
    }

    /// The options of a `kind` job read as a submission reads them (no inputs given).
    fn spec(kind: JobKind, options: Value) -> JobOptions {
        JobOptions::parse(kind, &options, std::iter::empty()).unwrap()
    }

    /// A job with these options and a program (an accessibility job: a part) of
    /// `program_bytes` bytes, checked against the budget as at submission.
    fn check(options: &JobOptions, program_bytes: u64, limits: &JobLimits) -> Result<(), Problem> {
        let inputs = SubmittedInputs {
            stored: Vec::new(),
            inline_program: Some(program_bytes),
        };
        options.check_memory_budget(&inputs, limits)
    }

    /// A stability job's options with these modes a direction, speeds and steps.
    fn stability(modes: &[Value], rpm: Value) -> Value {
        json!({"method": "sdm", "teeth": 2, "ktc_n_mm2": 600, "krc_n_mm2": 200,
            "radial_immersion": 0.5, "milling": "down", "modes_x": modes, "modes_y": modes,
            "rpm": rpm, "steps_per_period": 40})
    }

    /// An energy job's options with these modes in x and steps a period.
    fn energy(modes_x: &[Value], steps: Option<u32>) -> Value {
        let mut o = json!({"material": "Al7075-T6", "length_mm": 200, "width_mm": 8,
            "depth_mm": 12, "cutting_speed_m_min": {"min": 100, "max": 300},
            "feed_per_tooth_mm": {"min": 0.02, "max": 0.2}, "objective": "min_energy",
            "modes_x": modes_x, "modes_y": []});
        if let Some(steps) = steps {
            o["steps_per_period"] = json!(steps);
        }
        o
    }

    #[test]
    fn each_kind_is_refused_over_a_small_budget_and_runs_under_it() {
        let limits = JobLimits {
            memory_bytes: 256 << 20,
        };
        // The stability job: 100 modes a direction, 40 steps a period.
        let many: Vec<Value> = (0..100).map(|_| mode()).collect();
        let heavy = stability(&many, json!({"from": 5000, "to": 6000, "step": 100}));
        let p = check(&spec(JobKind::Stability, heavy), 0, &limits)
            .unwrap_err()
            .to_json();
        assert_eq!(
            (p["status"].as_u64(), p["limit"].as_u64()),
            (Some(422), Some(256))
        );
        assert!(p["estimate_mb"].as_u64().unwrap() > 2_000, "{p}");
        let light = stability(&[mode()], json!({"from": 5000, "to": 25000, "step": 1}));
        assert!(check(&spec(JobKind::Stability, light), 0, &limits).is_ok());
        let heavy_energy = spec(JobKind::Energy, energy(&many, Some(100)));
        assert!(check(&heavy_energy, 0, &limits).is_err());
        assert!(check(&spec(JobKind::Energy, energy(&[], None)), 0, &limits).is_ok());
        // 10 MB of G-code: about 400 MB parsed with its moves and rows.
        let interpret = spec(JobKind::Interpret, json!({}));
        assert!(check(&interpret, 10 << 20, &limits).is_err());
        let rotary_feed = spec(JobKind::RotaryFeed, json!({}));
        assert!(check(&rotary_feed, 10 << 20, &limits).is_err());
        assert!(check(&interpret, 1 << 20, &limits).is_ok());
        assert!(check(&spec(JobKind::Simulate, json!({})), 1 << 30, &limits).is_ok());
        // A 200k-triangle binary part (10 MB) fits; a 5M-triangle one (250 MB) does not.
        let accessibility = spec(
            JobKind::Accessibility,
            json!({"entry": [0, 0, 10], "target": [0, 0, 0]}),
        );
        assert!(check(&accessibility, 10 << 20, &limits).is_ok());
        assert!(check(&accessibility, 250 << 20, &limits).is_err());
    }
}
