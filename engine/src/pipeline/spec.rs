//! What a simulation is asked to do, and what can go wrong.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::geometry::{self, StockShape};
use crate::machine::cycle_time::CycleTimeError;
use crate::machine::Machine;
use crate::nc;
use crate::optimize::{self, FeedLimits};
use crate::physics::Material;
use crate::tool::Tool;

/// Where the stock comes from.
#[derive(Clone)]
pub enum StockSource {
    Shape(StockShape),
    Stl(StlSource),
}

/// An STL mesh as given: the file's bytes (read when the simulation starts), or the
/// mesh already read (from a stream, so that the file was never whole in memory).
#[derive(Clone)]
pub enum StlSource {
    Bytes(Vec<u8>),
    /// Read already, with what reading it repaired.
    Mesh(std::sync::Arc<geometry::Mesh>, geometry::StlRepairs),
}

impl StlSource {
    /// The mesh, read and checked (borrowed when it was given read).
    pub fn mesh(&self) -> Result<std::borrow::Cow<'_, geometry::Mesh>, geometry::StlError> {
        self.repaired().map(|(mesh, _)| mesh)
    }

    /// `mesh`, with what reading it repaired.
    pub fn repaired(
        &self,
    ) -> Result<(std::borrow::Cow<'_, geometry::Mesh>, geometry::StlRepairs), geometry::StlError>
    {
        Ok(match self {
            StlSource::Bytes(bytes) => {
                let (mesh, repairs) =
                    geometry::Mesh::from_stl_reader_repaired(&bytes[..], bytes.len() as u64)?;
                (std::borrow::Cow::Owned(mesh), repairs)
            }
            StlSource::Mesh(mesh, repairs) => (std::borrow::Cow::Borrowed(mesh), *repairs),
        })
    }
}

impl From<Vec<u8>> for StlSource {
    fn from(bytes: Vec<u8>) -> Self {
        StlSource::Bytes(bytes)
    }
}

/// How a program's X Y Z A B C words relate to the part on a multi-axis machine.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisReading {
    /// Machine axes: the machine's kinematics give the tool tip and axis in the part frame
    /// (a plain 4/5-axis program without tool-centre-point control).
    #[default]
    Machine,
    /// X Y Z are the tool tip in the part frame and A B C set the tool axis: a control
    /// running tool-centre-point control (Fanuc G43.4, Heidenhain M128, LinuxCNC TCP
    /// kinematics such as the impeller sample's M428), which moves the tip on a straight line.
    ToolTip,
}

#[derive(Clone)]
pub struct SimulateSpec {
    pub program: String,
    pub interpret: nc::InterpretOptions,
    pub stock: StockSource,
    /// Tools by T number; the tool under key 0 (given alone) serves every tool number of
    /// a program that uses one. A program that selects one number without loading it (no
    /// M6) is cut with that number's tool. Numbers the program does not use are ignored.
    pub tools: BTreeMap<u32, Tool>,
    pub material: Material,
    /// For the cycle time (accelerations, junctions, rapid rate, tool change time).
    pub machine: Machine,
    /// Dexel spacing, mm; default from the smallest tool (radius / 20, within [0.02, 0.5]).
    pub cell: Option<f64>,
    pub memory_limit: u64,
    /// Angular positions per spindle revolution in the force model.
    pub force_positions: usize,
    /// Optimize the feeds to these limits and rewrite the program.
    pub optimize: Option<FeedLimits>,
    /// On a machine with rotary axes: how the program's axis words are read.
    pub axes: AxisReading,
    /// The tool's frequency response, for the chatter margin of every block.
    pub chatter: Option<ChatterSpec>,
    /// A thin wall's modes by remaining allowance: its static give adds to the form error
    /// (see `physics::deflection`).
    pub workpiece: Option<crate::physics::deflection::WorkpieceModes>,
    /// The design part (STL, in the stock's frame): gouges and the allowance left.
    pub part: Option<StlSource>,
    /// Clamps and vices in the part frame, checked against the whole tool on every move.
    pub fixture: Option<std::sync::Arc<geometry::Fixture>>,
}

impl SimulateSpec {
    /// The interpreter's options as the simulation will read the program, before the
    /// stock is known: for checks made ahead of it (travel, memory), which must see the
    /// moves the simulation will (a `G41 D1` takes the radius of the job's T1 here too).
    pub fn interpret_options_for_checks(&self) -> nc::InterpretOptions {
        self.interpret_options((None, None))
    }

    /// The interpreter's options for this job's program and every rewrite of it: cutter
    /// compensation takes the radius of the job's own tool where the program's tool table
    /// gives none.
    /// `start`: where the machine stands at the start and after a tool change (see
    /// `setup::start_positions`), unless the caller's options already say.
    pub(super) fn interpret_options(
        &self,
        (start, change): (Option<[f64; 3]>, Option<nc::ToolChangeTo>),
    ) -> nc::InterpretOptions {
        let mut o = self.interpret.clone();
        o.start_position = o.start_position.or(start);
        // Without the setup's work offsets the machine frame is the program's, so machine Z
        // zero, where posts retract with `G53 G0 Z0.`, would be program zero: a mill's Z home
        // is the top of its travel, and the start height (retracted above the stock) stands
        // in for it, as it does for the G28 home.
        if o.work_offsets.is_empty() && o.machine_z_home.is_none() {
            o.machine_z_home = o.start_position.map(|p| p[2]);
        }
        o.tool_change = o.tool_change.or(change);
        // G53.1 turns this machine's rotary axes; G69 hands the position back in its reading.
        if o.kinematics.is_none() && self.machine.kinematics != crate::machine::Kinematics::Xyz {
            o.kinematics = Some(crate::machine::MachineKinematics::of(&self.machine));
        }
        o.tool_tip_reading |= self.axes == AxisReading::ToolTip;
        // The job's tools, the one tool (key 0) serving every number; then the tools the
        // program's header comments describe, which the simulation cuts with for numbers
        // the job does not give (see `ToolLookup`).
        for (&number, tool) in self.tools.iter() {
            o.tool_diameters.entry(number).or_insert(tool.diameter);
        }
        crate::tool_library::add_header_diameters(&mut o.tool_diameters, &self.program);
        o
    }
}

/// Modal parameters of the tool (as a stability job takes them) for the per-block chatter
/// margin: axial depth / critical depth at the block's speed, radial immersion and milling
/// direction. The same modes serve every tool of the program.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChatterSpec {
    #[serde(default)]
    pub modes_x: Vec<crate::physics::stability::Mode>,
    #[serde(default)]
    pub modes_y: Vec<crate::physics::stability::Mode>,
    /// `zoa`, `sdm` (default) or `fdm`.
    #[serde(default = "default_chatter_method")]
    pub method: crate::physics::stability::Method,
    /// Discretization steps per tooth period (sdm/fdm).
    #[serde(default = "default_chatter_steps")]
    pub steps_per_period: u32,
}

fn default_chatter_method() -> crate::physics::stability::Method {
    crate::physics::stability::Method::Sdm
}

fn default_chatter_steps() -> u32 {
    40
}

#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    #[error("{0}")]
    Program(nc::Diagnostics),
    #[error("line {line}: tool T{tool} is used but not defined; define it under `tools`, give a tool library, or describe it in a comment such as (T{tool} D=6 CR=0 - flat end mill)")]
    UnknownTool { tool: u32, line: u32 },
    #[error("line {line}: the program changes to T{tool} but one tool was given; give a tool for each T number used ({used})")]
    OneToolForSeveral { tool: u32, line: u32, used: String },
    #[error("a tool for every number (key 0) cannot be combined with tools for given numbers")]
    ToolZeroWithOthers,
    #[error("line {line}: rotary axes (A/B/C) move, but the machine has none (kinematics xyz); give a machine with kinematics xyz_a, xyz_b, xyz_ac, xyz_bc or head_table")]
    RotaryAxes { line: u32 },
    #[error("stock: {0}")]
    Geometry(#[from] geometry::GeometryError),
    #[error("force model: {0}")]
    Physics(#[from] crate::physics::PhysicsError),
    #[error("cycle time: {0}")]
    CycleTime(#[from] CycleTimeError),
    #[error("feed optimization: {0}")]
    Optimize(#[from] optimize::OptimizeError),
    #[error("rewriting the program: {0}")]
    Rewrite(String),
    #[error("{0}")]
    Spindle(crate::optimize::spindle::SpindleError),
    #[error("stock: {0}")]
    GivenGrid(String),
    #[error("cancelled")]
    Cancelled,
}
