//! Energy model against the idle-power fit of ../shared/REFERENCE.md ("Machine energy
//! example"): P_idle(n) = 2e-6·n² + 0.0149·n + 823.3 W for n ≤ 3000 rpm,
//! 3e-6·n² − 0.0034·n + 881.5 W above; auxiliary power 804 W.

use millsim_engine::machine::Machine;
use millsim_engine::physics::energy::{program_energy, EnergyBlock, EnergyModel};

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}

fn block(time_s: f64, spindle_rpm: f64, cutting_energy_j: f64) -> EnergyBlock {
    EnergyBlock {
        time_s,
        spindle_rpm,
        cutting_energy_j,
    }
}

#[test]
fn fixed_program_reproduces_hand_computed_energy() {
    let model = EnergyModel::reference_example();
    // Idle power by hand:
    //   2000 rpm: 2e-6·4e6 + 0.0149·2000 + 823.3 = 8 + 29.8 + 823.3 = 861.1 W
    //   3000 rpm (base speed, lower fit): 2e-6·9e6 + 0.0149·3000 + 823.3 = 18 + 44.7 + 823.3 = 886.0 W
    //   6000 rpm: 3e-6·3.6e7 − 0.0034·6000 + 881.5 = 108 − 20.4 + 881.5 = 969.1 W
    assert!(rel(model.idle_power_w(2000.0), 861.1) < 1e-12);
    assert!(rel(model.idle_power_w(3000.0), 886.0) < 1e-12);
    assert!(rel(model.idle_power_w(6000.0), 969.1) < 1e-12);
    assert_eq!(model.idle_power_w(0.0), 0.0);
    let program = [
        block(2.0, 0.0, 0.0),        // rapid, spindle off: aux only
        block(10.0, 2000.0, 1500.0), // cut at 2000 rpm
        block(8.0, 3000.0, 2400.0),  // cut at 3000 rpm
        block(5.0, 6000.0, 3000.0),  // cut at 6000 rpm
        block(1.5, 6000.0, 0.0),     // dwell, spindle on
        block(3.0, 0.0, 0.0),        // spindle off (M5), program still running
    ];
    let e = program_energy(&model, &program).unwrap();
    // Per block (idle, aux = 804·t, cut, in):
    let expect = [
        (0.0, 1608.0, 0.0, 1608.0),
        (8611.0, 8040.0, 1500.0, 18151.0),
        (7088.0, 6432.0, 2400.0, 15920.0),
        (4845.5, 4020.0, 3000.0, 11865.5),
        (1453.65, 1206.0, 0.0, 2659.65),
        (0.0, 2412.0, 0.0, 2412.0),
    ];
    for (i, (b, x)) in e.blocks.iter().zip(expect).enumerate() {
        for (got, want) in [
            (b.idle_j, x.0),
            (b.aux_j, x.1),
            (b.cut_j, x.2),
            (b.input_j, x.3),
        ] {
            if want == 0.0 {
                assert_eq!(got, 0.0, "block {i}");
            } else {
                assert!(rel(got, want) < 1e-9, "block {i}: {got} vs {want}");
            }
        }
    }
    // Totals: time 29.5 s; idle 8611 + 7088 + 4845.5 + 1453.65 = 21998.15 J;
    // aux 804·29.5 = 23718 J; cut 6900 J; in 52616.15 J; U = 6900/52616.15.
    assert!(rel(e.time_s, 29.5) < 1e-12);
    assert!(rel(e.idle_j, 21998.15) < 1e-9);
    assert!(rel(e.aux_j, 23718.0) < 1e-9);
    assert!(rel(e.cut_j, 6900.0) < 1e-9);
    assert!(rel(e.input_j, 52616.15) < 1e-9);
    assert!(rel(e.utilization, 6900.0 / 52616.15) < 1e-9);
    assert!((e.utilization - 0.131138).abs() < 1e-6);
}

#[test]
fn mrr_fallback_and_errors() {
    let model = EnergyModel::reference_example();
    // K = 2.5 J/mm³, MRR = 100 mm³/s for 4 s at 2000 rpm: E_cut = 2.5·100·4 = 1000 J,
    // idle 861.1·4 = 3444.4 J, aux 804·4 = 3216 J.
    let b = EnergyBlock::from_mrr(4.0, 2000.0, 100.0, 2.5);
    let e = program_energy(&model, &[b]).unwrap();
    assert!(rel(e.cut_j, 1000.0) < 1e-12);
    assert!(rel(e.idle_j, 3444.4) < 1e-9);
    assert!(rel(e.input_j, 1000.0 + 3444.4 + 3216.0) < 1e-9);
    let err = program_energy(&model, &[block(1.0, 100.0, 0.0), block(-1.0, 0.0, 0.0)]).unwrap_err();
    assert_eq!(err.field(), "blocks[1].time_s");
    let err = program_energy(&model, &[block(1.0, 0.0, 5.0)]).unwrap_err();
    assert_eq!(err.field(), "blocks[0].cutting_energy_j");
    assert_eq!(program_energy(&model, &[]).unwrap().utilization, 0.0);
}

#[test]
fn machine_energy_field_json_and_validation() {
    let json = r#"{"name":"hsm","rapid_rate":30000,"max_feed":12000,"acceleration":[3000,3000,2000],
        "spindle_min_rpm":100,"spindle_max_rpm":12000,"rated_power":7500,
        "energy":{"idle":{"base_rpm":3000,"below":[823.3,0.0149,2e-6],"above":[881.5,-0.0034,3e-6]},"aux_power_w":804}}"#;
    let m: Machine = serde_json::from_str(json).unwrap();
    assert_eq!(m.energy, Some(EnergyModel::reference_example()));
    m.validate().unwrap();
    // Absent field: no energy model; serialization omits it.
    let g = Machine::generic();
    assert!(g.energy.is_none());
    assert!(!serde_json::to_string(&g).unwrap().contains("energy"));
    let back: Machine = serde_json::from_str(&serde_json::to_string(&m).unwrap()).unwrap();
    assert_eq!(back, m);
    let bad = json.replace("\"aux_power_w\":804", "\"aux_power_w\":804,\"x\":1");
    assert!(serde_json::from_str::<Machine>(&bad).is_err());
    let mut m2 = m.clone();
    m2.energy.as_mut().unwrap().idle.above[2] = f64::INFINITY;
    assert_eq!(m2.validate().unwrap_err().field, "energy.idle.above[2]");
    m2.energy.as_mut().unwrap().idle.above = [0.0, -1.0, 0.0];
    assert_eq!(m2.validate().unwrap_err().field, "energy.idle");
}
