//! Zero-order (Altintas–Budak) lobes against the absolute limits in shared/REFERENCE.md
//! (Insperger & Stépán's 1-DOF benchmark: flexibility in the feed direction x).

use millsim_engine::physics::stability::{
    compute_lobes, Method, Milling, Mode, StabilityInput, StabilitySystem,
};

const MASS_KG: f64 = 0.03993;
const FN_HZ: f64 = 922.0;

fn benchmark(immersion: f64, modes_x: Vec<Mode>, modes_y: Vec<Mode>) -> StabilitySystem {
    StabilitySystem::new(2, 600.0, 200.0, immersion, Milling::Down, modes_x, modes_y).unwrap()
}

fn mode() -> Mode {
    Mode::with_mass(FN_HZ, 0.011, MASS_KG)
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b
}

#[test]
fn absolute_limits_match_reference() {
    let slot = benchmark(1.0, vec![mode()], vec![]).zoa_absolute_limit_mm();
    let low = benchmark(0.05, vec![mode()], vec![]).zoa_absolute_limit_mm();
    eprintln!("zoa absolute limit: slot {slot:.5} mm (ref 0.298), aD=0.05 {low:.5} mm (ref 1.792)");
    assert!(rel(slot, 0.298) < 0.01, "slot {slot}");
    assert!(rel(low, 1.792) < 0.01, "aD=0.05 {low}");
}

#[test]
fn lobe_minimum_equals_absolute_limit_and_stiffness_equals_mass() {
    // The same mode given by its stiffness k = m·(2π·fn)².
    let k = MASS_KG * (2.0 * std::f64::consts::PI * FN_HZ).powi(2);
    let by_k = benchmark(1.0, vec![Mode::with_stiffness(FN_HZ, 0.011, k)], vec![]);
    let by_m = benchmark(1.0, vec![mode()], vec![]);
    let rpms: Vec<f64> = (0..=800).map(|i| 5000.0 + 25.0 * i as f64).collect();
    let a = by_k.zoa_lobes(&rpms, 10.0);
    let b = by_m.zoa_lobes(&rpms, 10.0);
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() < 1e-9);
    }
    let min = a.iter().copied().fold(f64::INFINITY, f64::min);
    let abs = by_m.zoa_absolute_limit_mm();
    assert!(
        min >= abs * 0.999 && min < abs * 1.01,
        "min {min} abs {abs}"
    );
    // Lobes: depth rises well above the limit between lobes (the pocket near 2 teeth · fn = 27,660 rpm
    // k = 0 lobe; here the k = 1 pocket around 18–23 krpm).
    let max = a.iter().copied().fold(0.0, f64::max);
    assert!(max > 3.0 * abs, "max {max}");
}

#[test]
fn symmetric_two_dof_is_not_less_stable_in_x_only_and_up_milling_mirrors() {
    // A mode in y as well can only lower (or keep) the absolute limit.
    let x_only = benchmark(1.0, vec![mode()], vec![]).zoa_absolute_limit_mm();
    let xy = benchmark(1.0, vec![mode()], vec![mode()]).zoa_absolute_limit_mm();
    eprintln!("slot: x only {x_only:.4} mm, x and y {xy:.4} mm");
    assert!(xy <= x_only * 1.0001);
    // Slotting is the same in up and down milling.
    let up = StabilitySystem::new(
        2,
        600.0,
        200.0,
        1.0,
        Milling::Up,
        vec![mode()],
        vec![mode()],
    )
    .unwrap()
    .zoa_absolute_limit_mm();
    assert!(rel(up, xy) < 1e-9);
}

#[test]
fn json_input_runs_and_validation_names_fields() {
    let json = r#"{"method":"zoa","teeth":2,"ktc_n_mm2":600,"krc_n_mm2":200,"radial_immersion":0.05,"milling":"down",
        "modes_x":[{"freq_hz":922,"damping":0.011,"stiffness_n_m":1.34005e6}],"modes_y":[],
        "rpm":{"from":5000,"to":25000,"step":250},"steps_per_period":40}"#;
    let input: StabilityInput = serde_json::from_str(json).unwrap();
    assert_eq!(input.method, Method::Zoa);
    let curve = compute_lobes(&input).unwrap();
    assert_eq!(curve.points.len(), 81);
    let min = curve.minimum().unwrap();
    assert!(rel(min.depth_mm, 1.792) < 0.01, "{min:?}");
    let csv = curve.to_csv();
    assert!(csv.starts_with("rpm,depth_mm\n5000,"));
    assert_eq!(csv.lines().count(), 82);

    let unknown = json.replace("\"teeth\"", "\"flutes\":2,\"teeth\"");
    let err = serde_json::from_str::<StabilityInput>(&unknown)
        .unwrap_err()
        .to_string();
    assert!(err.contains("flutes"), "{err}");

    let bad = |from: &str, to: &str, field: &str| {
        let input: StabilityInput = serde_json::from_str(&json.replace(from, to)).unwrap();
        let e = compute_lobes(&input).unwrap_err();
        assert_eq!(e.field(), field, "{e}");
    };
    bad("\"damping\":0.011", "\"damping\":1.5", "modes_x[0].damping");
    bad(
        "\"radial_immersion\":0.05",
        "\"radial_immersion\":1.2",
        "radial_immersion",
    );
    bad("\"step\":250", "\"step\":0", "rpm.step");
    bad("\"teeth\":2", "\"teeth\":0", "teeth");
    bad(
        "\"steps_per_period\":40",
        "\"steps_per_period\":1",
        "steps_per_period",
    );
    bad(
        "\"stiffness_n_m\":1.34005e6",
        "\"stiffness_n_m\":1.34005e6,\"mass_kg\":0.04",
        "modes_x[0].stiffness_n_m",
    );
    bad(
        "\"modes_x\":[{\"freq_hz\":922,\"damping\":0.011,\"stiffness_n_m\":1.34005e6}]",
        "\"modes_x\":[]",
        "modes_x",
    );
}
