//! Memory estimates of the job kinds other than simulate/optimize, from what a submission
//! says (the options, the program's size), checked against the job's budget at
//! submission: an interpret or rotary-feed job holds its program parsed, its moves and
//! their rows; a stability or energy job the transition matrices of its lobes.

use serde::Serialize;

use millsim_engine::optimize::energy::DEFAULT_SEARCH_STEPS;
use millsim_engine::physics::stability::{Method, RpmRange, DEFAULT_STEPS_PER_PERIOD};

use crate::job_limits::JobLimits;
use crate::jobs::stability::StabilityRequest;
use crate::jobs::{JobKind, JobOptions};
use crate::problem::Problem;

/// What a job's process holds whatever the job (code, runtime, buffers): measured 11.7 to
/// 13.7 MB peak RSS for `millsim stability` on one mode and `millsim interpret` on a
/// one-line program.
pub const PROCESS_BYTES: u64 = 16 << 20;

/// Bytes an interpret job holds per byte of program text: the parsed program and its
/// moves (`millsim interpret` on 500,000 random G1 lines, 9.4 MB: 286 MB peak RSS, 29 B
/// per byte) and the rows kept as JSON until they are stored (143 B a move, 7.6 B per
/// byte of such a program).
pub const INTERPRET_BYTES_PER_PROGRAM_BYTE: u64 = 40;

/// A rotary-feed job also holds the corrected program and its report.
pub const ROTARY_FEED_BYTES_PER_PROGRAM_BYTE: u64 = INTERPRET_BYTES_PER_PROGRAM_BYTE + 2;

/// Square matrices of the transition's dimension each lobe worker holds (the product
/// being built, the step map applied, and the eigenvalue solver's copies). Measured with
/// `millsim stability` on 2 threads, over the one-mode run: dimension 420 (10 modes, 40
/// steps) 10.6 MB more, 7.5 matrices; dimension 992 (16 modes, 60 steps, sdm and fdm) 50
/// MB more, 6.4 matrices.
pub const LOBE_MATRICES_PER_WORKER: u64 = 4;

/// Bytes an accessibility job holds per byte of its part's STL (50 bytes a triangle in
/// binary): the mesh read (about 36 B a triangle), and the evaluations of
/// axes running at once (about 4 with two threads nesting), each with the triangles seen
/// along its axis and their clipped polygons (about 160 B a triangle). ASCII STL is larger
/// per triangle, so the same factor overestimates it. Measured (release, `/usr/bin/time -v
/// millsim accessibility` on the synthetic impeller, binary STL): 1.27 MB → 19.6 MB peak RSS,
/// 10.0 MB → 52.9 MB, 39.7 MB → 173 MB; this estimate gives 41, 181 and 656 MB.
pub const ACCESSIBILITY_BYTES_PER_PART_BYTE: u64 = 16;

/// The rasters of the evaluations at once (512² cells, about 20 B a cell, four of them).
pub const ACCESSIBILITY_RASTER_BYTES: u64 = 4 * 512 * 512 * 20;

/// Bytes of one row of lobes (rpm, depth, allowance) as stored JSON.
const LOBE_ROW_BYTES: u64 = 100;

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

/// The estimate of a job with these options and a program of `program_bytes` bytes, when
/// its kind is one this module knows (not simulate/optimize, process or identify);
/// `workers` lobe workers run at once (the job process's thread pool).
pub fn estimate(options: &JobOptions, program_bytes: u64, workers: u64) -> Option<KindEstimate> {
    let mut e = KindEstimate::default();
    match options {
        JobOptions::Interpret(_) => {
            e.program_bytes = program_bytes.saturating_mul(INTERPRET_BYTES_PER_PROGRAM_BYTE)
        }
        JobOptions::Accessibility(_) => {
            // `program_bytes` is the part's size for this kind.
            e.program_bytes = program_bytes
                .saturating_mul(ACCESSIBILITY_BYTES_PER_PART_BYTE)
                .saturating_add(ACCESSIBILITY_RASTER_BYTES)
        }
        JobOptions::RotaryFeed(_) => {
            e.program_bytes = program_bytes.saturating_mul(ROTARY_FEED_BYTES_PER_PROGRAM_BYTE)
        }
        JobOptions::Stability(request) => {
            let (method, mut modes, steps, mut rows) = match request.as_ref() {
                StabilityRequest::Lobes(i, _) => (
                    i.method,
                    i.modes_x.len() + i.modes_y.len(),
                    i.steps_per_period,
                    speeds(&i.rpm),
                ),
                StabilityRequest::Surface(i) => (
                    i.method,
                    i.modes_x.len() + i.modes_y.len(),
                    i.steps_per_period,
                    speeds(&i.rpm),
                ),
            };
            if let StabilityRequest::Surface(i) = request.as_ref() {
                // A 3-D surface: the workpiece's modes join the tool's, per allowance.
                modes += i
                    .allowance
                    .iter()
                    .map(|a| a.modes_x.len() + a.modes_y.len())
                    .max()
                    .unwrap_or(0);
                rows = rows.saturating_mul((i.allowances_mm.len() as u64).max(1));
            }
            let steps = steps.unwrap_or(DEFAULT_STEPS_PER_PERIOD).into();
            e.lobe_matrices_bytes =
                lobe_matrices_bytes(method_name(method), modes as u64, steps, workers);
            e.rows_bytes = rows.saturating_mul(LOBE_ROW_BYTES);
        }
        JobOptions::Energy(energy) => {
            let search = &energy.0;
            let modes = (search.modes_x.len() + search.modes_y.len()) as u64;
            if modes > 0 {
                let steps = search
                    .steps_per_period
                    .unwrap_or(DEFAULT_SEARCH_STEPS)
                    .into();
                e.lobe_matrices_bytes = lobe_matrices_bytes(
                    method_name(search.stability_method),
                    modes,
                    steps,
                    workers,
                );
            }
        }
        JobOptions::Simulate(_)
        | JobOptions::Optimize(_)
        | JobOptions::Process(_)
        | JobOptions::Identify(_) => return None,
    }
    e.peak_bytes = PROCESS_BYTES
        .saturating_add(e.program_bytes)
        .saturating_add(e.lobe_matrices_bytes)
        .saturating_add(e.rows_bytes);
    Some(e)
}

/// A lobe method as the options name it.
fn method_name(method: Method) -> &'static str {
    match method {
        Method::Zoa => "zoa",
        Method::Sdm => "sdm",
        Method::Fdm => "fdm",
    }
}

/// Transition matrices of the time-domain lobe methods: dimension 2n + steps·n for n
/// modes (the state and the delayed states of a tooth period), 8 bytes an entry. The
/// zero-order method solves n×n systems per frequency: nothing to count.
pub fn lobe_matrices_bytes(method: &str, modes: u64, steps: u64, workers: u64) -> u64 {
    if method == "zoa" {
        return 0;
    }
    let dim = modes.saturating_mul(steps.saturating_add(2));
    dim.saturating_mul(dim)
        .saturating_mul(8 * LOBE_MATRICES_PER_WORKER)
        .saturating_mul(workers.max(1))
}

/// Speeds of an rpm range (its own check bounds them).
fn speeds(rpm: &RpmRange) -> u64 {
    let n = ((rpm.to - rpm.from) / rpm.step).floor() + 1.0;
    if n.is_finite() && n > 0.0 {
        n.min(1e12) as u64
    } else {
        0
    }
}

/// The lobe workers a job process runs at once.
pub fn lobe_workers() -> u64 {
    std::thread::available_parallelism().map_or(1, |n| n.get() as u64)
}

/// Checks a job with these options against the budget: Err(problem) when its estimate is
/// over it (a 422 resource-limit problem naming the budget and the estimate).
pub fn check(options: &JobOptions, program_bytes: u64, limits: &JobLimits) -> Result<(), Problem> {
    let Some(e) = estimate(options, program_bytes, lobe_workers()) else {
        return Ok(());
    };
    let kind = options.kind();
    if e.peak_bytes <= limits.memory_bytes {
        return Ok(());
    }
    let mib = |b: u64| b.div_ceil(1 << 20);
    Err(Problem::resource_limit(
        "Over the job's memory budget",
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
        "job_memory_mb",
    )
    .with("limit", limits.memory_mb())
    .with("estimate_mb", mib(e.peak_bytes))
    .with("estimate", serde_json::to_value(&e).unwrap_or_default()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::{json, Value};

    fn mode() -> Value {
        json!({"freq_hz": 900, "damping": 0.02, "stiffness_n_m": 2e7})
    }

    #[test]
    fn lobe_matrices_cover_the_measured_runs() {
        // `millsim stability` on 2 threads, peak RSS over the one-mode run's 11.7 MB.
        for (modes, steps, measured) in [(10, 40, 10.6e6), (16, 60, 50.0e6)] {
            for method in ["sdm", "fdm"] {
                let b = lobe_matrices_bytes(method, modes, steps, 2) as f64;
                assert!(b >= measured && b < 2.0 * measured, "{modes} {steps}: {b}");
            }
        }
        assert_eq!(lobe_matrices_bytes("zoa", 16, 60, 2), 0);
    }

    /// The options of a `kind` job read as a submission reads them (no inputs given).
    fn spec(kind: JobKind, options: Value) -> JobOptions {
        JobOptions::parse(kind, &options, std::iter::empty()).unwrap()
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
