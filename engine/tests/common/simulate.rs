//! The simulation the cutting tests share: one tool in the block they cut.

use std::collections::BTreeMap;

use millsim_engine::geometry::StockShape;
use millsim_engine::machine::Machine;
use millsim_engine::nc::InterpretOptions;
use millsim_engine::physics::Material;
use millsim_engine::pipeline::{SimulateSpec, StockSource};
use millsim_engine::tool::Tool;

/// `program` cut by `tool` (as T1) in a 100 × 40 × 10 mm block of Al7075-T6 (x 0..100,
/// y −20..20, top at z = 0) on cells of `cell` mm, on the generic machine, with forces
/// sampled at 360 positions per revolution; the caller changes what its test needs.
pub fn block_spec(program: &str, tool: Tool, cell: f64) -> SimulateSpec {
    SimulateSpec {
        program: program.into(),
        interpret: InterpretOptions::default(),
        stock: StockSource::Shape(StockShape::Block {
            min: [0.0, -20.0, -10.0],
            max: [100.0, 20.0, 0.0],
        }),
        tools: BTreeMap::from([(0, tool)]),
        material: Material::builtin("Al7075-T6").unwrap(),
        machine: Machine::generic(),
        cell: Some(cell),
        memory_limit: 1 << 30,
        force_positions: 360,
        optimize: None,
        axes: Default::default(),
        workpiece: None,
        chatter: None,
        part: None,
        fixture: None,
    }
}
