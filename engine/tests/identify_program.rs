//! Identification from a program run on a dynamometer: the mean forces per line that a
//! simulation with known coefficients reports (the simulate rows' part-frame means) give
//! those coefficients back when the program is fitted line by line, for the linear and
//! the exponential law.

mod common;

use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::physics::{CuttingCoefficients, ForceLaw, Material};
use millsim_engine::pipeline::{simulate, simulate_for_identification, LineForce};
use millsim_engine::tool::Tool;

/// A D8R1 bull-nose: slots at 1 and 2 mm at four feeds, then a 3 mm wide side cut beside
/// the deeper slot (down milling on the −y side), each cutting move on its own line.
const PROGRAM: &str = "G21 G90 G17
S8000 M3
G0 Z5
G0 X-10 Y0
G0 Z-1
G1 X30 F800
G1 X60 F2400
G0 Z5
G0 X-10 Y-10
G0 Z-2
G1 X30 F1600
G1 X60 F3200
G0 Z5
G0 X-10 Y-15
G0 Z-2
G1 X60 F2000
G0 Z5
M30
";

/// The simulate rows' mean forces of every line that cuts, with `k`.
fn measured(k: CuttingCoefficients) -> Vec<LineForce> {
    let mut spec = common::simulate::block_spec(PROGRAM, Tool::bull_nose(8.0, 1.0, 4), 0.25);
    spec.material = Material {
        coefficients: k,
        ..Material::builtin("TC6").unwrap()
    };
    let out = simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    out.rows
        .iter()
        .filter(|r| r.mean_force > 0.0)
        .map(|r| LineForce {
            line: r.line,
            force: [r.fx_mean_n, r.fy_mean_n, r.fz_mean_n],
        })
        .collect()
}

fn worst(got: &CuttingCoefficients, want: &CuttingCoefficients) -> f64 {
    let g = [got.ktc, got.krc, got.kac, got.kte, got.kre, got.kae];
    let w = [want.ktc, want.krc, want.kac, want.kte, want.kre, want.kae];
    (0..6)
        .map(|i| (g[i] - w[i]).abs() / w[i].abs())
        .fold(0.0, f64::max)
}

#[test]
fn a_programs_line_forces_give_the_coefficients_back() {
    let truth = Material::builtin("TC6").unwrap().coefficients;
    let lines = measured(truth);
    assert_eq!(
        lines.iter().map(|l| l.line).collect::<Vec<_>>(),
        vec![6, 7, 11, 12, 16]
    );
    // The fit's simulation has another material: the line responses do not depend on it.
    let mut spec = common::simulate::block_spec(PROGRAM, Tool::bull_nose(8.0, 1.0, 4), 0.25);
    spec.material = Material::builtin("Al6082-T6").unwrap();
    let program = simulate_for_identification(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    assert_eq!(program.cutting_lines(), vec![6, 7, 11, 12, 16]);
    assert!((program.feed_per_tooth(6).unwrap() - 800.0 / (8000.0 * 4.0)).abs() < 1e-12);
    let id = program.identify(&lines, ForceLaw::Linear).unwrap();
    let err = worst(&id.coefficients, &truth);
    eprintln!("program, linear: worst relative error {err:.2e}");
    // The same model on the same engagements: the fit is exact to rounding.
    assert!(err < 1e-6, "{:?} vs {truth:?}", id.coefficients);
    for r in &id.residuals {
        assert!(r.iter().all(|v| v.abs() < 1e-6), "{r:?}");
    }
    // A line that does not cut is refused, naming it.
    let mut with_air = lines.clone();
    with_air[0].line = 3;
    let e = program.identify(&with_air, ForceLaw::Linear).unwrap_err();
    assert_eq!(e.field(), "lines[0].line");
    // Lines at one feed only cannot separate the terms.
    let e = program.identify(&lines[..1], ForceLaw::Linear).unwrap_err();
    assert!(e.to_string().contains("give at least 2"), "{e}");
}

#[test]
fn a_programs_line_forces_give_the_exponential_law_back() {
    let truth = CuttingCoefficients {
        mtc: 0.25,
        mrc: 0.35,
        mac: 0.2,
        ktc: 900.0,
        krc: 320.0,
        kac: 240.0,
        ..Material::builtin("TC6").unwrap().coefficients
    };
    let lines = measured(truth);
    let spec = common::simulate::block_spec(PROGRAM, Tool::bull_nose(8.0, 1.0, 4), 0.25);
    let program = simulate_for_identification(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    let id = program.identify(&lines, ForceLaw::Exponential).unwrap();
    let k = id.coefficients;
    let err = worst(&k, &truth);
    eprintln!(
        "program, exponential: worst relative error {err:.2e}, m = {:?}",
        [k.mtc, k.mrc, k.mac]
    );
    assert!(err < 1e-3, "{k:?} vs {truth:?}");
    for (got, want) in [(k.mtc, 0.25), (k.mrc, 0.35), (k.mac, 0.2)] {
        assert!((got - want).abs() < 1e-3, "m {got} vs {want}");
    }
    // Five lines, fifteen forces for nine parameters.
    assert_eq!(id.degrees_of_freedom, 6);
}
