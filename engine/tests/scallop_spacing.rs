//! The scallop beside a neighbouring pass from the path's step-over (issue 30): a D10 ball
//! raster 1 mm apart leaves r − √(r² − (s/2)²) = 25.06 µm, where the engaged width on the grid
//! read 32.4 µm.

mod common;

use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::pipeline::simulate;
use millsim_engine::tool::Tool;

#[test]
fn a_ball_raster_reports_the_scallop_of_its_step_over() {
    let step = 1.0;
    let mut program = String::from("G21 G90\nS8000 M3\nG0 X10 Y-5 Z5\nG1 Z-0.5 F300\n");
    for k in 0..11 {
        let y = -5.0 + step * k as f64;
        let (from, to) = if k % 2 == 0 {
            (10.0, 90.0)
        } else {
            (90.0, 10.0)
        };
        if k > 0 {
            program.push_str(&format!("G1 X{from} Y{y} F1000\n"));
        }
        program.push_str(&format!("G1 X{to} Y{y} F1000\n"));
    }
    program.push_str("G0 Z5\nM30\n");
    let tool = Tool {
        flute_length: 20.0,
        ..Tool::ball(10.0, 2)
    };
    let out = simulate(
        &common::simulate::block_spec(&program, tool, 0.1),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let exact = (5.0 - (25.0f64 - 0.25).sqrt()) * 1000.0;
    // The passes along X (80 mm long); the first has no neighbour before it.
    let passes: Vec<_> = out
        .rows
        .iter()
        .filter(|r| r.kind == "linear" && r.length > 50.0)
        .collect();
    assert_eq!(passes.len(), 11);
    eprintln!(
        "scallops (µm): {:?}; exact {exact:.2}",
        passes
            .iter()
            .map(|r| (r.scallop_um * 100.0).round() / 100.0)
            .collect::<Vec<_>>()
    );
    for r in &passes[1..] {
        assert!(
            (r.scallop_um - exact).abs() < 1e-6,
            "line {}: {} vs {exact}",
            r.line,
            r.scallop_um
        );
    }
    // The 1 mm link moves between passes run across them: not beside a parallel pass.
    let links: Vec<_> = out
        .rows
        .iter()
        .filter(|r| r.kind == "linear" && (r.length - 1.0).abs() < 1e-9)
        .collect();
    assert!(!links.is_empty());
    for r in links {
        assert!(
            (r.scallop_um - exact).abs() > 1.0,
            "link line {}: {}",
            r.line,
            r.scallop_um
        );
    }
}
