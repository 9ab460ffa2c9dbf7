//! Rows of moves that cut nothing (issue 36): an air re-trace along a wall the first pass cut
//! shows no depth, width or angles.

mod common;

use std::collections::BTreeMap;

use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::pipeline::simulate;
use millsim_engine::tool::Tool;

#[test]
fn an_air_retrace_has_no_depth_width_or_angles_and_rows_name_the_tool() {
    // A slot, then the same slot again: the second pass removes nothing.
    let program =
        "G21 G90\nT1\nS8000 M3\nG0 X-10 Y0 Z5\nG0 Z-3\nG1 X60 F500\nG1 X-10\nG0 Z5\nM30\n";
    let mut spec = common::simulate::block_spec(program, Tool::flat(12.0, 4), 0.25);
    spec.tools = BTreeMap::from([(1, Tool::flat(12.0, 4))]);
    let out = simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    let row = |line: u32| out.rows.iter().find(|r| r.line == line).unwrap();
    let first = row(6);
    assert!(
        first.removed_volume > 100.0 && first.max_axial_depth > 2.9,
        "{first:?}"
    );
    let again = row(7);
    assert_eq!(again.removed_volume, 0.0, "{again:?}");
    assert!(again.flags.split('|').any(|f| f == "air"), "{again:?}");
    assert_eq!(
        (again.max_axial_depth, again.max_radial_width),
        (0.0, 0.0),
        "{again:?}"
    );
    assert_eq!(
        (again.entry_angle_deg, again.exit_angle_deg),
        (None, None),
        "{again:?}"
    );
}

#[test]
fn a_tool_selected_without_m6_names_its_rows() {
    // Fusion's one-tool posts select T1 and never load it: the rows say tool 1 whether the
    // job gives the tool as its one tool or as T1.
    let program = "G21 G90\nT1\nS10000 M3\nG0 X-10 Y0 Z5\nG0 Z-1\nG1 X60 F600\nG0 Z5\nM30\n";
    let one = common::simulate::block_spec(program, Tool::flat(6.0, 2), 0.2);
    let mut numbered = common::simulate::block_spec(program, Tool::flat(6.0, 2), 0.2);
    numbered.tools = BTreeMap::from([(1, Tool::flat(6.0, 2))]);
    for spec in [one, numbered] {
        let out = simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap();
        let tools: Vec<u32> = out.rows.iter().map(|r| r.tool).collect();
        assert!(tools.iter().all(|&t| t == 1), "{tools:?}");
        assert_eq!(out.summary.deflection[0].tool, 1);
    }
}
