//! 3-D lobes (critical depth over spindle speed × remaining allowance) and the depth-search
//! choice of the stability input.

use millsim_engine::physics::stability::{
    compute_lobes, compute_lobes_3d, AllowanceModes, DepthSearch, Method, Milling, Mode, RpmRange,
    SearchOptions, Stability3dInput, StabilityInput,
};

fn base(method: Method, rpm: RpmRange) -> Stability3dInput {
    Stability3dInput {
        method,
        teeth: 2,
        ktc_n_mm2: 600.0,
        krc_n_mm2: 200.0,
        radial_immersion: 0.5,
        milling: Milling::Down,
        modes_x: vec![Mode::with_stiffness(922.0, 0.011, 1.34005e6)],
        modes_y: vec![],
        rpm,
        steps_per_period: Some(12),
        search: DepthSearch::Bisection,
        scan_step_mm: None,
        allowance: vec![],
        allowances_mm: vec![],
    }
}

fn wp(allowance_mm: f64, f: f64, z: f64, k: f64) -> AllowanceModes {
    AllowanceModes {
        allowance_mm,
        modes_x: vec![Mode::with_stiffness(f, z, k)],
        modes_y: vec![Mode::with_stiffness(1.1 * f, z, 1.2 * k)],
    }
}

#[test]
fn at_a_given_allowance_the_surface_is_the_2d_lobes_with_those_modes() {
    for (method, rpm) in [
        (
            Method::Zoa,
            RpmRange {
                from: 5000.0,
                to: 25000.0,
                step: 500.0,
            },
        ),
        (
            Method::Sdm,
            RpmRange {
                from: 12000.0,
                to: 14000.0,
                step: 2000.0,
            },
        ),
    ] {
        let mut input = base(method, rpm);
        input.allowance = vec![
            wp(5.0, 1500.0, 0.02, 8e6),
            wp(1.0, 700.0, 0.03, 2e6),
            wp(3.0, 1100.0, 0.025, 5e6),
        ];
        input.allowances_mm = vec![3.0, 1.0];
        let surface = compute_lobes_3d(&input).unwrap();
        let n = input.rpm.speeds().len();
        assert_eq!(surface.rows.len(), 2 * n);
        for (i, (a, w)) in [
            (3.0, wp(3.0, 1100.0, 0.025, 5e6)),
            (1.0, wp(1.0, 700.0, 0.03, 2e6)),
        ]
        .into_iter()
        .enumerate()
        {
            let mut modes_x = input.modes_x.clone();
            modes_x.extend(w.modes_x.clone());
            let two_d = StabilityInput {
                method,
                teeth: 2,
                ktc_n_mm2: 600.0,
                krc_n_mm2: 200.0,
                radial_immersion: 0.5,
                milling: Milling::Down,
                modes_x,
                modes_y: w.modes_y.clone(),
                rpm: input.rpm,
                steps_per_period: Some(12),
                search: DepthSearch::Bisection,
                scan_step_mm: None,
            };
            let curve = compute_lobes(&two_d).unwrap();
            for (row, p) in surface.rows[i * n..(i + 1) * n].iter().zip(&curve.points) {
                assert_eq!(row.allowance_mm, a);
                assert_eq!(row.rpm, p.rpm);
                assert_eq!(
                    row.depth_mm, p.depth_mm,
                    "{method:?} at {a} mm, {} rpm",
                    p.rpm
                );
            }
        }
        assert!(surface
            .to_csv()
            .starts_with("allowance_mm,rpm,depth_mm\n3,"));
    }
}

#[test]
fn halfway_between_equal_modes_the_result_equals_them() {
    let mut input = base(
        Method::Zoa,
        RpmRange {
            from: 5000.0,
            to: 25000.0,
            step: 250.0,
        },
    );
    input.allowance = vec![wp(2.0, 900.0, 0.02, 3e6), wp(4.0, 900.0, 0.02, 3e6)];
    input.allowances_mm = vec![2.0, 3.0, 4.0];
    let s = compute_lobes_3d(&input).unwrap();
    let n = input.rpm.speeds().len();
    for i in 0..n {
        assert_eq!(s.rows[i].depth_mm, s.rows[n + i].depth_mm);
        assert_eq!(s.rows[i].depth_mm, s.rows[2 * n + i].depth_mm);
    }
    // Interpolation is linear in frequency, damping and stiffness.
    input.allowance[1] = wp(4.0, 1300.0, 0.04, 7e6);
    let (mx, my) = input.modes_at(3.0).unwrap();
    assert!((mx[0].freq_hz - 1100.0).abs() < 1e-9);
    assert!((mx[0].damping - 0.03).abs() < 1e-12);
    assert!((mx[0].stiffness() - 5e6).abs() < 1e-6);
    assert!((my[0].stiffness() - 6e6).abs() < 1e-6);
}

#[test]
fn absolute_limit_is_proportional_to_a_single_modes_stiffness() {
    // One workpiece mode, rigid tool: the zero-order limit a_lim = −1/(2·Kt·α·min Re G) with
    // G = 1/k·g(ω/ωn, ζ), so at fixed frequency and damping a_lim ∝ k.
    let mut input = base(
        Method::Zoa,
        RpmRange {
            from: 4000.0,
            to: 30000.0,
            step: 500.0,
        },
    );
    input.modes_x.clear();
    input.allowance = vec![
        AllowanceModes {
            allowance_mm: 0.0,
            modes_x: vec![Mode::with_stiffness(800.0, 0.02, 1e6)],
            modes_y: vec![],
        },
        AllowanceModes {
            allowance_mm: 4.0,
            modes_x: vec![Mode::with_stiffness(800.0, 0.02, 5e6)],
            modes_y: vec![],
        },
    ];
    input.allowances_mm = vec![0.0, 1.0, 2.0, 3.0, 4.0];
    let stiffness = |a: f64| 1e6 + 1e6 * a;
    let mut ratio0 = None;
    let mut prev = 0.0;
    for &a in &input.allowances_mm {
        let lim = input
            .input_at(a)
            .unwrap()
            .system()
            .unwrap()
            .zoa_absolute_limit_mm();
        assert!(lim > prev, "not increasing at {a} mm");
        prev = lim;
        let r = lim / stiffness(a);
        let r0 = *ratio0.get_or_insert(r);
        assert!((r / r0 - 1.0).abs() < 1e-6, "{a} mm: {r} vs {r0}");
    }
    // The whole zero-order surface scales the same way (below the 16 mm search cap).
    let s = compute_lobes_3d(&input).unwrap();
    let n = input.rpm.speeds().len();
    for i in 0..n {
        let d0 = s.rows[i].depth_mm;
        for j in 1..5 {
            let d = s.rows[j * n + i].depth_mm;
            if d < 16.0 {
                assert!(
                    (d / d0 - stiffness(j as f64) / 1e6).abs() < 1e-6 * d / d0,
                    "{d} {d0}"
                );
            }
        }
    }
}

#[test]
fn errors_name_the_field_and_json_is_strict() {
    let mut input = base(
        Method::Zoa,
        RpmRange {
            from: 5000.0,
            to: 6000.0,
            step: 500.0,
        },
    );
    input.allowance = vec![wp(1.0, 900.0, 0.02, 3e6), wp(3.0, 900.0, 0.02, 3e6)];
    input.allowances_mm = vec![2.0, 3.5];
    assert_eq!(
        compute_lobes_3d(&input).unwrap_err().field(),
        "allowances_mm[1]"
    );
    input.allowances_mm = vec![2.0];
    input.allowance[1].modes_y.clear();
    assert_eq!(
        compute_lobes_3d(&input).unwrap_err().field(),
        "allowance[1]"
    );
    input.allowance[1] = wp(3.0, 900.0, 1.5, 3e6);
    assert_eq!(
        compute_lobes_3d(&input).unwrap_err().field(),
        "allowance[1].modes_x[0].damping"
    );
    let json = r#"{"method":"zoa","teeth":2,"ktc_n_mm2":600,"krc_n_mm2":200,"radial_immersion":0.5,
        "milling":"down","rpm":{"from":5000,"to":6000,"step":500},"search":"first_loss",
        "allowance":[{"allowance_mm":1,"modes_x":[{"freq_hz":900,"damping":0.02,"stiffness_n_m":3e6}]},
                     {"allowance_mm":3,"modes_x":[{"freq_hz":800,"damping":0.02,"stiffness_n_m":2e6}]}],
        "allowances_mm":[1,2,3]}"#;
    let parsed: Stability3dInput = serde_json::from_str(json).unwrap();
    assert_eq!(parsed.search, DepthSearch::FirstLoss);
    assert_eq!(compute_lobes_3d(&parsed).unwrap().rows.len(), 9);
    assert!(
        serde_json::from_str::<Stability3dInput>(&json.replace("\"teeth\"", "\"teth\"")).is_err()
    );
}

#[test]
fn stability_input_chooses_the_depth_search() {
    let json = r#"{"method":"sdm","teeth":2,"ktc_n_mm2":600,"krc_n_mm2":200,"radial_immersion":1.0,"milling":"down",
        "modes_x":[{"freq_hz":922,"damping":0.011,"mass_kg":0.03993}],
        "rpm":{"from":18750,"to":18750,"step":250},"steps_per_period":20}"#;
    let plain: StabilityInput = serde_json::from_str(json).unwrap();
    assert_eq!(plain.search, DepthSearch::Bisection);
    // Default: unchanged serialization (no `search` key) and the bisection result.
    assert!(!serde_json::to_string(&plain).unwrap().contains("search"));
    let sys = plain.system().unwrap();
    let bis = sys
        .sd_lobes(&[18750.0], 20, &SearchOptions::default())
        .unwrap()[0];
    assert_eq!(compute_lobes(&plain).unwrap().points[0].depth_mm, bis);
    let scan: StabilityInput = serde_json::from_str(&json.replace(
        "\"steps_per_period\":20",
        "\"steps_per_period\":20,\"search\":\"first_loss\",\"scan_step_mm\":0.05",
    ))
    .unwrap();
    assert_eq!(scan.search, DepthSearch::FirstLoss);
    let fl = sys
        .sd_lobes(&[18750.0], 20, &SearchOptions::first_loss(0.05))
        .unwrap()[0];
    let got = compute_lobes(&scan).unwrap().points[0].depth_mm;
    assert_eq!(got, fl);
    assert!(got <= bis + 1e-4, "first loss {got} above bisection {bis}");
    let bad = json.replace(
        "\"steps_per_period\":20",
        "\"steps_per_period\":20,\"search\":\"newton\"",
    );
    assert!(serde_json::from_str::<StabilityInput>(&bad).is_err());
    let mut neg = scan.clone();
    neg.scan_step_mm = Some(-1.0);
    assert_eq!(compute_lobes(&neg).unwrap_err().field(), "scan_step_mm");
}
