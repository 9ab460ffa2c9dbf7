//! The `simulate` and `optimize` jobs: a program cut from a stock with its tools,
//! material and machine, block by block (forces, torque, power, chip); `optimize` also
//! rewrites the feeds to the options' limits.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use millsim_engine::job::{CancelFlag, Progress};
use millsim_engine::machine::Machine;
use millsim_engine::optimize::FeedLimits;
use millsim_engine::pipeline::{self, SimulateError, SimulateSpec, StlSource, StockSource};
use millsim_engine::tool::Tool;
use millsim_engine::{geometry, nc};

use super::inputs::{
    check_material, invalid, job_material, json_input, program_failure, program_text_encoded,
    required, stem_and_ext,
};
use super::interpret::default_dialect;
use super::{
    input, FieldError, InputSpec, JobFailure, JobKind, JobOutput, LoadedInputs, OutputFile,
    SubmittedInputs,
};
use crate::job_budget::{check_simulation, Checked, JobLimits, Refusal, SimulationCheck};
use crate::job_library::JobLibrary;
use crate::problem::Problem;
use crate::store::artifacts::ArtifactContent;
use crate::store::ResourceKind;

pub const INPUTS: [InputSpec; 7] = [
    input("program", ResourceKind::Program, true),
    input("stock", ResourceKind::Stock, true),
    // The tool for every T number; or one input per number, `T1`, `T2`, ...
    // (see `tool_number`); else the tool library's, else the program header's.
    input("tool", ResourceKind::Tool, false),
    // The tools of the T numbers no tool input names.
    input("tool_library", ResourceKind::ToolLibrary, false),
    // Else `options.material` names a built-in material.
    input("material", ResourceKind::Material, false),
    // Else a generic 3-axis machine.
    input("machine", ResourceKind::Machine, false),
    // The design part (an STL stock resource in the stock's frame): gouge and allowance.
    input("part", ResourceKind::Stock, false),
];

/// An input named `T<n>` (n in 1..=9999) is the tool for tool number n of the program.
pub fn tool_number(name: &str) -> Option<u32> {
    let digits = name.strip_prefix('T')?;
    if digits.is_empty() || digits.len() > 4 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok().filter(|n| (1..=9999).contains(n))
}

/// Checks that a job names its tools one way: `tool`, or `T1`, `T2`, ...
pub fn check_tool_inputs<'a>(
    kind: JobKind,
    names: impl Iterator<Item = &'a String> + Clone,
) -> Result<(), FieldError> {
    let numbered = names
        .clone()
        .filter(|n| kind.tool_number_input(n).is_some())
        .count();
    let single = names.clone().any(|n| n == "tool");
    // No tool at all is allowed: the program's header comments may describe its tools (the
    // job then fails naming the first T number nothing describes).
    match (single, numbered) {
        (true, n) if n > 0 => Err(FieldError::new(
            "inputs.tool",
            "give `tool` (one tool for the whole program) or `T1`, `T2`, ... (one per tool number), not both",
        )),
        _ => Ok(()),
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulateOptions {
    #[serde(default = "default_dialect")]
    pub dialect: nc::Dialect,
    #[serde(default)]
    pub fanuc_implied_decimal: bool,
    /// A built-in material (TC6, Al7075-T6, Al6082-T6) when no `material` input is given.
    #[serde(default)]
    pub material: Option<String>,
    /// Dexel spacing, mm; default: smallest tool radius / 20 within [0.02, 0.5].
    #[serde(default)]
    pub cell_mm: Option<f64>,
    /// Angular positions per revolution in the force model.
    #[serde(default = "default_positions")]
    pub force_positions: usize,
    /// Refuse grids over this size, MiB.
    #[serde(default = "default_grid_mib")]
    pub max_grid_mib: u64,
    /// optimize jobs: the targets and bounds of the feed optimization.
    #[serde(default)]
    pub limits: Option<FeedLimits>,
    /// M codes that do not move the machine (e.g. a control's M428) and may be skipped.
    #[serde(default)]
    pub passthrough_m_codes: Vec<u32>,
    /// Refuse M codes the interpreter does not know instead of warning.
    #[serde(default)]
    pub strict_m_codes: bool,
    /// Fanuc parameter CCR: corner rounding R and chamfer C written without the comma.
    #[serde(default)]
    pub fanuc_corners_without_comma: bool,
    /// Skip blocks that start with `/` (the control's block-delete switch on).
    #[serde(default)]
    pub block_delete: bool,
    /// A LinuxCNC tool table (`T1 P1 D6 Z50`), for G43 tool lengths.
    #[serde(default)]
    pub tool_table: Option<String>,
    /// On a machine with rotary axes: `machine` (X..C are machine axes, the default) or
    /// `tool_tip` (tool-centre-point control: X Y Z are the tip in the part frame).
    #[serde(default)]
    pub axes: pipeline::AxisReading,
    /// The tool's modes for a chatter margin per block: {"modes_x":[..],"modes_y":[..],
    /// "method":"sdm","steps_per_period":40}.
    #[serde(default)]
    pub chatter: Option<pipeline::ChatterSpec>,
    /// A thin wall's modes by remaining allowance, {"allowance":[{"allowance_mm":..,
    /// "modes_y":[..]}]}: its static give adds to the form error.
    #[serde(default)]
    pub workpiece: Option<millsim_engine::physics::deflection::WorkpieceModes>,
    /// Clamps and vices in the part frame, checked against the whole tool on every move:
    /// {"bodies":[{"name":"clamp 1","kind":"block","min":[..],"max":[..]}, {"kind":
    /// "cylinder",..}, {"kind":"stl","input":"fixture/vice"}]} (an STL body names a job
    /// input `fixture/<name>`, an uploaded STL stock resource).
    #[serde(default)]
    pub fixture: Option<Value>,
    /// The spindle speed chosen out of chatter: {"choose":true,"rpm":{"from":..,"to":..},
    /// "modes_x":[..],"modes_y":[..],"objective":"min_time"} (see
    /// `millsim_engine::optimize::spindle`).
    #[serde(default)]
    pub spindle: Option<millsim_engine::optimize::spindle::SpindleOptions>,
    /// The setup's work offsets, machine frame, mm: {"G54": [x, y, z], "G55": [..], ...}
    /// (G54 ... G59, G59.1 ... G59.3), set before the program runs as the control's offset
    /// table holds them; unlisted ones are zero.
    #[serde(default)]
    pub work_offsets: Option<BTreeMap<String, [f64; 3]>>,
}

/// The field an STL fixture body names its job input with.
const FIXTURE_STL_KEY: &str = "input";

/// An input named `fixture/<name>` is the STL of a fixture body that names it.
pub fn fixture_input(name: &str) -> bool {
    name.strip_prefix("fixture/")
        .is_some_and(|n| !n.is_empty() && n.len() <= 255)
}

/// At submission: a simulation whose grid and stock export alone cannot fit the job
/// memory budget (422 naming the budget and the estimate).
pub fn check_memory_budget(
    o: &SimulateOptions,
    inputs: &SubmittedInputs,
    limits: &JobLimits,
) -> Result<(), Problem> {
    fn tool_name(name: &str) -> &str {
        name
    }
    grid_budget(o.cell_mm, inputs, tool_name, limits)
}

/// The grid and stock export of a job's `stock` input against the budget: the cell is
/// `cell_mm`, or set by the finest of the tools given (`tool_name` reads an input's name
/// as a single-job tool name, `tool` or `T<n>`).
pub(super) fn grid_budget(
    cell_mm: Option<f64>,
    inputs: &SubmittedInputs,
    tool_name: fn(&str) -> &str,
    limits: &JobLimits,
) -> Result<(), Problem> {
    let Some(stock) = inputs.stored("stock") else {
        return Ok(());
    };
    let Some(bounds) = crate::job_budget::summary_bounds(&stock.summary) else {
        return Ok(());
    };
    let mut diameters = Vec::new();
    for (name, tool) in &inputs.stored {
        let name = tool_name(name);
        if name != "tool" && tool_number(name).is_none() {
            continue;
        }
        diameters.extend(tool.summary["diameter"].as_f64());
    }
    match crate::job_budget::submission_estimate(
        bounds,
        stock.summary["triangles"].as_u64().unwrap_or(0),
        cell_mm,
        &diameters,
        limits,
    ) {
        None => Ok(()),
        Some(estimate) => Err(crate::job_budget::over_budget_problem(
            None, &estimate, limits,
        )),
    }
}

/// Checks that every STL body of `options.fixture` names a `fixture/<name>` input the job
/// gives, and that every such input is named by a body.
pub fn check_fixture_inputs<'a>(
    opts: &SimulateOptions,
    names: impl Iterator<Item = &'a String> + Clone,
) -> Result<(), FieldError> {
    let spec = opts.fixture_spec()?;
    let refs: Vec<(usize, &str)> = spec
        .as_ref()
        .map_or(Vec::new(), |s| s.stl_references().collect());
    for (i, r) in &refs {
        let field = format!("options.fixture.bodies[{i}].{FIXTURE_STL_KEY}");
        if !fixture_input(r) {
            return Err(FieldError::new(
                field,
                format!(
                    "`{r}`: an STL body names a job input `fixture/<name>` (an uploaded STL stock)"
                ),
            ));
        }
        if !names.clone().any(|n| n.as_str() == *r) {
            return Err(FieldError::new(
                field,
                format!("names input `{r}`, which the job does not give"),
            ));
        }
    }
    if let Some(n) = names
        .filter(|n| fixture_input(n))
        .find(|n| !refs.iter().any(|(_, r)| *r == n.as_str()))
    {
        return Err(FieldError::new(
            format!("inputs.{n}"),
            "no body of options.fixture names this input",
        ));
    }
    Ok(())
}

impl SimulateOptions {
    /// `options.work_offsets` as the interpreter takes them, each error naming its field.
    pub fn work_offsets(&self) -> Result<Vec<(usize, [f64; 3])>, FieldError> {
        let mut out = Vec::new();
        for (name, v) in self.work_offsets.iter().flatten() {
            let field = format!("options.work_offsets.{name}");
            let k = nc::work_offset_index(name).ok_or_else(|| {
                FieldError::new(
                    &field,
                    format!(
                        "`{name}` is not a work offset; one of {}",
                        nc::WORK_OFFSET_NAMES.join(", ")
                    ),
                )
            })?;
            if !v
                .iter()
                .all(|x| x.is_finite() && x.abs() <= geometry::stock::MAX_STOCK_SIZE)
            {
                return Err(FieldError::new(
                    field,
                    format!(
                        "[x, y, z] in mm within ±{} mm, got {v:?}",
                        geometry::stock::MAX_STOCK_SIZE
                    ),
                ));
            }
            out.push((k, *v));
        }
        Ok(out)
    }

    /// `options.fixture` read, each error naming its field under `options.fixture`.
    pub fn fixture_spec(&self) -> Result<Option<geometry::FixtureSpec>, FieldError> {
        self.fixture
            .as_ref()
            .map(|v| {
                geometry::FixtureSpec::from_json(v, FIXTURE_STL_KEY).map_err(|e| {
                    let e = e.prefixed("options.fixture");
                    FieldError::new(e.field, e.message)
                })
            })
            .transpose()
    }
}

fn default_positions() -> usize {
    180
}

fn default_grid_mib() -> u64 {
    4096
}

impl SimulateOptions {
    /// The program options among these, as every job and command that reads a program
    /// takes them (one conversion to the interpreter's options).
    pub fn program_options(&self) -> super::InterpretOptions {
        super::InterpretOptions {
            dialect: self.dialect,
            fanuc_implied_decimal: self.fanuc_implied_decimal,
            fanuc_corners_without_comma: self.fanuc_corners_without_comma,
            passthrough_m_codes: self.passthrough_m_codes.clone(),
            block_delete: self.block_delete,
            strict_m_codes: self.strict_m_codes,
            tool_table: self.tool_table.clone(),
        }
    }

    /// Checks what can be checked before the job runs; names the option.
    pub fn check(&self, optimize: bool, has_material_input: bool) -> Result<(), FieldError> {
        self.program_options().engine_options().map_err(|d| {
            let first = d.0.first().map(|e| e.to_string()).unwrap_or_default();
            FieldError::new("options.tool_table", format!("tool table: {first}"))
        })?;
        match (&self.limits, optimize) {
            (None, true) => {
                return Err(FieldError::new(
                    "options.limits",
                    "an optimize job needs limits, e.g. {\"max_force\": 800}",
                ))
            }
            (Some(_), false) => {
                return Err(FieldError::new(
                    "options.limits",
                    "limits are for optimize jobs; submit kind `optimize`",
                ))
            }
            (Some(l), true) => {
                l.validate()
                    .map_err(|e| FieldError::new("options.limits", e.to_string()))?;
                if l.max_force.is_none()
                    && l.max_power.is_none()
                    && l.max_torque.is_none()
                    && l.max_chip_thickness.is_none()
                    && !l.has_bending_limit()
                {
                    return Err(FieldError::new("options.limits", "give at least one target: max_force, max_power, max_torque, max_chip_thickness, max_deflection_um or max_form_error_um"));
                }
            }
            (None, false) => {}
        }
        check_material(self.material.as_deref(), has_material_input)?;
        if let Some(c) = self.cell_mm {
            if !(0.005..=5.0).contains(&c) {
                return Err(FieldError::new(
                    "options.cell_mm",
                    format!("must be in [0.005, 5] mm, got {c}"),
                ));
            }
        }
        if !(8..=3600).contains(&self.force_positions) {
            return Err(FieldError::new(
                "options.force_positions",
                format!("must be in [8, 3600], got {}", self.force_positions),
            ));
        }
        if let Some(c) = &self.chatter {
            // The modes and method as the per-block chatter model will check them.
            millsim_engine::physics::chatter::ChatterModel::new(
                c.modes_x.clone(),
                c.modes_y.clone(),
                2,
                600.0,
                200.0,
                c.method,
                c.steps_per_period,
            )
            .map_err(|e| {
                FieldError::new(format!("options.chatter.{}", e.field()), e.to_string())
            })?;
        }
        if let Some(sp) = &self.spindle {
            self.check_spindle(sp)?;
        }
        if let Some(w) = &self.workpiece {
            w.compliance().map_err(|e| {
                FieldError::new(format!("options.workpiece.{}", e.field()), e.to_string())
            })?;
        }
        self.fixture_spec()?;
        self.work_offsets()?;
        if !(1..=16384).contains(&self.max_grid_mib) {
            return Err(FieldError::new(
                "options.max_grid_mib",
                "must be in [1, 16384]",
            ));
        }
        Ok(())
    }
}

impl SimulateOptions {
    /// The spindle option's numbers, and its modes (its own or `chatter`'s, given once) as
    /// the chatter model will check them.
    fn check_spindle(
        &self,
        sp: &millsim_engine::optimize::spindle::SpindleOptions,
    ) -> Result<(), FieldError> {
        let field = |f: &str| format!("options.spindle.{f}");
        sp.validate()
            .map_err(|e| FieldError::new(field(e.field()), e.to_string()))?;
        let own = !(sp.modes_x.is_empty() && sp.modes_y.is_empty());
        let chatter = self
            .chatter
            .as_ref()
            .filter(|c| !(c.modes_x.is_empty() && c.modes_y.is_empty()));
        let (modes_x, modes_y) = match (own, chatter) {
            (true, Some(_)) => {
                return Err(FieldError::new(
                    field("modes_x"),
                    "the modes are given in options.chatter too: give them once",
                ))
            }
            (true, None) => (&sp.modes_x, &sp.modes_y),
            (false, Some(c)) => (&c.modes_x, &c.modes_y),
            (false, None) => {
                return Err(FieldError::new(
                    field("modes_x"),
                    "give the tool's modes (modes_x and/or modes_y, or options.chatter): the speed is chosen from the stability lobes",
                ))
            }
        };
        millsim_engine::physics::chatter::ChatterModel::new(
            modes_x.clone(),
            modes_y.clone(),
            2,
            600.0,
            200.0,
            sp.method
                .or(self.chatter.as_ref().map(|c| c.method))
                .unwrap_or(millsim_engine::physics::stability::Method::Sdm),
            sp.steps_per_period
                .or(self.chatter.as_ref().map(|c| c.steps_per_period))
                .unwrap_or(40),
        )
        .map_err(|e| {
            let at = if own {
                "options.spindle"
            } else {
                "options.chatter"
            };
            FieldError::new(format!("{at}.{}", e.field()), e.to_string())
        })?;
        Ok(())
    }
}

#[derive(Serialize)]
pub(super) struct SimulateSummary<'a> {
    pub(super) file: &'a str,
    #[serde(flatten)]
    pub(super) simulation: &'a pipeline::SimulationSummary,
    /// Wall time per stage on the worker, seconds.
    pub(super) timings: &'a pipeline::StageTimings,
    pub(super) stock_export_s: f64,
    pub(super) dexel_updates: u64,
    /// The optimized program's cycle time and peak |F| (optimize jobs), also inside
    /// `optimization` with the benchmarks they are judged against.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) cycle_time_opt_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) force_peak_opt_n: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) optimization: Option<&'a pipeline::OptimizationSummary>,
    /// The job's memory budget and the estimate it was held to (MiB; by buffer, bytes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) memory: Option<Value>,
    /// With a `tool_library` input: its file and format, the T numbers it gave that cut,
    /// and its import report's notes on them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) tool_library: Option<Value>,
    pub(super) row_columns: Vec<String>,
}

/// The stock as a binary STL into the file at `path`; its length.
pub(super) fn stream_stl(
    stock: &geometry::Stock,
    path: &std::path::Path,
) -> Result<u64, ExportError> {
    use std::io::Seek;
    let at = |e: std::io::Error| ExportError::Io(path.to_path_buf(), e);
    let file = std::fs::File::create(path).map_err(at)?;
    let mut out = std::io::BufWriter::with_capacity(1 << 20, file);
    geometry::export_stl(stock, &mut out).map_err(|e| match e {
        geometry::GeometryError::Io(e) => at(e),
        other => ExportError::Other(other.to_string()),
    })?;
    std::io::Write::flush(&mut out).map_err(at)?;
    out.seek(std::io::SeekFrom::End(0)).map_err(at)
}

/// Why the machined stock could not be exported.
#[derive(Debug)]
pub(super) enum ExportError {
    /// Writing the job's file failed.
    Io(std::path::PathBuf, std::io::Error),
    Other(String),
}

impl ExportError {
    /// The job's failure: a full disk is the server's (507, try again later), anything
    /// else the export's own.
    pub(super) fn into_failure(self) -> JobFailure {
        match self {
            ExportError::Io(path, e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded
                ) =>
            {
                JobFailure::Invalid(Problem::disk_full(format!(
                        "the worker's disk filled up while it wrote the machined stock ({}: {e}); this is not a fault of the job's inputs: submit it again once the server has space",
                        path.display()
                )))
            }
            ExportError::Io(path, e) => invalid("Stock export failed", format!("{}: {e}", path.display())),
            ExportError::Other(e) => invalid("Stock export failed", e),
        }
    }
}

/// The simulation the job's inputs and options describe (the program's file name with it),
/// refused before anything is allocated when it would exceed the job limits. `keeps_steps`:
/// the job keeps a record of every step (optimize, identification), which the memory
/// estimate counts.
pub(super) fn spec_from_inputs(
    opts: &SimulateOptions,
    keeps_steps: bool,
    inputs: &mut LoadedInputs,
    limits: &JobLimits,
    cancel: &CancelFlag,
) -> Result<BuiltSpec, JobFailure> {
    let (file, text, encoding) = program_text_encoded(inputs)?;
    // Key 0: one tool serves every tool number; else the tool of each number.
    let mut tools = BTreeMap::new();
    let names: Vec<String> = inputs.keys().cloned().collect();
    for name in names {
        let number = if name == "tool" {
            0
        } else if let Some(n) = tool_number(&name) {
            n
        } else {
            continue;
        };
        let tool: Tool = required(json_input(inputs, &name, "Invalid tool")?, &name)?;
        tools.insert(number, tool);
    }
    let library = inputs
        .remove("tool_library")
        .map(JobLibrary::load)
        .transpose()
        .map_err(JobFailure::Invalid)?
        .map(|mut library| {
            library.fill(&mut tools);
            library
        });
    let material = job_material(opts.material.as_deref(), inputs)?;
    let machine =
        json_input(inputs, "machine", "Invalid machine")?.unwrap_or_else(Machine::generic);
    let stock = inputs
        .remove("stock")
        .ok_or_else(|| invalid("Missing input", "the job has no `stock` input"))?;
    let stock = if stock.media_type == "application/json" {
        StockSource::Shape(
            serde_json::from_slice::<geometry::StockShape>(crate::problem::without_bom(
                &stock.content,
            ))
            .map_err(|e| invalid("Invalid stock", e.to_string()))?,
        )
    } else {
        let file = stock
            .file_name
            .clone()
            .unwrap_or_else(|| "stock.stl".into());
        StockSource::Stl(
            stock
                .stl()
                .map_err(|e| invalid("Invalid stock", format!("{file}: {e}")))?,
        )
    };
    let interpret = nc::InterpretOptions {
        cancel: Some(cancel.clone()),
        library: super::inputs::program_library(inputs)?,
        // G53.1 turns the machine's rotary axes (the job's checks interpret before the engine).
        kinematics: (machine.kinematics != millsim_engine::machine::Kinematics::Xyz)
            .then(|| millsim_engine::machine::MachineKinematics::of(&machine)),
        tool_tip_reading: opts.axes == pipeline::AxisReading::ToolTip,
        work_offsets: opts
            .work_offsets()
            .map_err(|e| invalid("Invalid options", e.to_string()))?,
        ..opts.program_options().engine_options().map_err(|d| {
            let first = d.0.first().map(|e| e.to_string()).unwrap_or_default();
            invalid("Invalid options", format!("options.tool_table: {first}"))
        })?
    };
    let part = match inputs.remove("part") {
        Some(p) if p.media_type == "application/json" => {
            return Err(invalid(
                "Invalid part",
                "the design part must be an STL mesh, not a parametric stock",
            ))
        }
        Some(p) => {
            let file = p.file_name.clone().unwrap_or_else(|| "part.stl".into());
            Some(
                p.stl()
                    .map_err(|e| invalid("Invalid part", format!("{file}: {e}")))?,
            )
        }
        None => None,
    };
    // The fixture's STL bodies from their `fixture/<name>` inputs (checked at submission).
    let fixture = match opts
        .fixture_spec()
        .map_err(|e| invalid("Invalid fixture", e.to_string()))?
    {
        Some(spec) => Some(std::sync::Arc::new(
            spec.build(FIXTURE_STL_KEY, |name| {
                let input = inputs
                    .remove(name)
                    .ok_or_else(|| format!("the job has no input `{name}`"))?;
                if input.media_type == "application/json" {
                    return Err(
                        "a fixture body's mesh must be an STL, not a parametric stock".into(),
                    );
                }
                let stl = input.stl().map_err(|e| e.to_string())?;
                stl.mesh()
                    .map(|m| m.into_owned())
                    .map_err(|e| e.to_string())
            })
            .map_err(|e| invalid("Invalid fixture", e.prefixed("options.fixture").to_string()))?,
        )),
        None => None,
    };
    let spec = SimulateSpec {
        program: text,
        interpret,
        stock,
        tools,
        material,
        machine,
        cell: opts.cell_mm,
        memory_limit: opts.max_grid_mib << 20,
        force_positions: opts.force_positions,
        optimize: opts.limits.clone(),
        axes: opts.axes,
        chatter: opts.chatter.clone(),
        workpiece: opts.workpiece.clone(),
        part,
        fixture,
    };
    // Travel and memory budget, before the pipeline allocates anything.
    let checked = check_spec(&file, &spec, keeps_steps, opts.cell_mm, limits, cancel)?;
    Ok(BuiltSpec {
        file,
        encoding,
        spec,
        estimate: checked.estimate,
        tool_radii: checked.tool_radii,
        estimate_cell: checked.cell,
        library,
    })
}

/// The travel and memory check of a built simulation, its estimate at `cell` (else at the
/// default cell of the tools its program cuts with).
pub(super) fn check_spec(
    file: &str,
    spec: &SimulateSpec,
    keeps_steps: bool,
    cell: Option<f64>,
    limits: &JobLimits,
    cancel: &CancelFlag,
) -> Result<Checked, JobFailure> {
    let interpret = spec.interpret_options_for_checks();
    let check = SimulationCheck {
        file,
        program: &spec.program,
        interpret: &interpret,
        machine: &spec.machine,
        axes: spec.axes,
        stock: &spec.stock,
        tools: &spec.tools,
        cell,
        optimize: keeps_steps,
        // The fixture's meshes are held as a part's is (a mesh and its BVH each).
        part_triangles: match &spec.part {
            Some(StlSource::Mesh(mesh, _)) => mesh.triangles.len() as u64,
            // Not read yet: the binary size's count (an ASCII file's is lower).
            Some(StlSource::Bytes(bytes)) => bytes.len() as u64 / 50,
            None => 0,
        } + spec.fixture.as_ref().map_or(0, |f| f.triangles()),
    };
    check_simulation(&check, limits).map_err(|r| match r {
        Refusal::Program(d) => program_failure(cancel, file, &d),
        Refusal::Problem(p) => JobFailure::Invalid(p),
    })
}

/// A simulation built from a job's inputs, with what its summary reports of them.
pub(super) struct BuiltSpec {
    pub file: String,
    /// How the program's bytes read: a rewritten program is written back the same way.
    pub encoding: crate::validate::TextEncoding,
    pub spec: SimulateSpec,
    pub estimate: Option<millsim_engine::budget::MemoryEstimate>,
    /// The radii of the tools the program cuts with (given, a library's, its header's).
    pub tool_radii: Vec<f64>,
    /// The cell `estimate` is at.
    pub estimate_cell: f64,
    pub library: Option<JobLibrary>,
}

pub fn run(
    optimize: bool,
    opts: &SimulateOptions,
    mut inputs: LoadedInputs,
    limits: &JobLimits,
    cancel: &CancelFlag,
    progress: &dyn Progress,
    stock_file: Option<&std::path::Path>,
) -> Result<JobOutput, JobFailure> {
    opts.check(optimize, inputs.contains_key("material"))
        .map_err(|e| invalid("Invalid options", e.to_string()))?;
    let BuiltSpec {
        file,
        encoding,
        spec,
        estimate,
        library,
        ..
    } = spec_from_inputs(opts, optimize, &mut inputs, limits, cancel)?;
    let result = match &opts.spindle {
        Some(sp) => pipeline::simulate_choosing_spindle(&spec, sp, cancel, progress),
        None => pipeline::simulate(&spec, cancel, progress),
    };
    let mut out = result.map_err(|e| match e {
        SimulateError::Cancelled => JobFailure::Cancelled,
        SimulateError::Program(d) => program_failure(cancel, &file, &d),
        SimulateError::Spindle(e) => invalid("Invalid options", e.to_string()),
        other => invalid("Simulation refused", format!("{file}: {other}")),
    })?;
    // The stock mesh and the rows' JSON are independent: both at once.
    let ((rows, samples), (stl, export_s)) = std::thread::scope(|scope| {
        let serialized = scope.spawn(|| {
            // Every row names every column of the job (null where it has no value), so a
            // page of rows reads the same whatever its first row is.
            let json = pipeline::RowJson::new(&out.rows);
            let rows: Vec<String> = out.rows.iter().map(|r| json.to_json(r)).collect();
            let samples: Vec<(usize, String)> = out
                .samples
                .iter()
                .enumerate()
                .filter(|(_, s)| !s.is_empty())
                .map(|(i, s)| (i, serde_json::to_string(s).expect("samples serialize")))
                .collect();
            (rows, samples)
        });
        let clock = std::time::Instant::now();
        let written = match stock_file {
            Some(path) => stream_stl(&out.stock, path).map(|len| ArtifactContent::File {
                path: path.to_path_buf(),
                len,
            }),
            None => geometry::export_stl_vec(&out.stock)
                .map(|(stl, _)| ArtifactContent::Bytes(stl))
                .map_err(|e| ExportError::Other(e.to_string())),
        };
        let exported = (written, clock.elapsed().as_secs_f64());
        match serialized.join() {
            Ok(v) => (v, exported),
            Err(panic) => std::panic::resume_unwind(panic),
        }
    });
    let stl = stl.map_err(ExportError::into_failure)?;
    let tool_library = library.map(|library| {
        let (section, warnings) = library.report(&out.tool_numbers);
        out.summary.tool_warnings.extend(warnings);
        section
    });
    let row_columns = millsim_engine::pipeline::row_columns(&out.rows);
    let (stem, ext) = stem_and_ext(&file);
    let mut files = vec![OutputFile {
        name: "stock.stl".into(),
        media_type: "model/stl",
        file_name: format!("{stem}.stock.stl"),
        content: stl,
    }];
    if let Some(text) = out.optimized_program {
        files.push(OutputFile {
            name: "program".into(),
            media_type: encoding.media_type(),
            file_name: format!("{stem}.opt{ext}"),
            content: ArtifactContent::Bytes(encoding.encode(text)),
        });
    }
    let mut summary = serde_json::to_value(SimulateSummary {
        file: &file,
        simulation: &out.summary,
        timings: &out.timings,
        stock_export_s: export_s,
        dexel_updates: out.rays_tested,
        cycle_time_opt_s: out.optimization.as_ref().map(|o| o.cycle_time_after_s),
        force_peak_opt_n: out.optimization.as_ref().map(|o| o.peak_force_after),
        optimization: out.optimization.as_ref(),
        memory: estimate.map(|e| {
            json!({
                "budget_mb": limits.memory_mb(),
                "estimate_mb": e.peak_bytes.div_ceil(1 << 20),
                "estimate": e,
            })
        }),
        tool_library,
        row_columns,
    })
    .expect("summary serializes");
    place_collisions(&spec, &mut summary);
    Ok(JobOutput {
        summary,
        rows,
        samples,
        files,
        resources: Vec::new(),
    })
}

/// Where each listed collision happened, for the dashboard's 3-D view: `from` and `to`, the
/// tool tip at its move's start and end, mm. Only on a 3-axis machine (the tip is then the
/// programmed X, Y, Z); the program is read again, which costs an interpretation, only when
/// there are collisions.
pub(super) fn place_collisions(spec: &SimulateSpec, summary: &mut Value) {
    let Some(list) = summary.get_mut("collisions").and_then(Value::as_array_mut) else {
        return;
    };
    if list.is_empty() || spec.machine.kinematics != millsim_engine::machine::Kinematics::Xyz {
        return;
    }
    let Ok(program) = nc::interpret(&spec.program, &spec.interpret_options_for_checks()) else {
        return;
    };
    for c in list.iter_mut() {
        let (Some(block), Some(line)) = (c["block"].as_u64(), c["line"].as_u64()) else {
            continue;
        };
        if let Some(m) = program
            .moves
            .iter()
            .find(|m| m.block as u64 == block && u64::from(m.line) == line)
        {
            c["from"] = json!([m.start[0], m.start[1], m.start[2]]);
            c["to"] = json!([m.end[0], m.end[1], m.end[2]]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn problem(e: ExportError) -> Problem {
        match e.into_failure() {
            JobFailure::Invalid(p) => p,
            JobFailure::Cancelled => panic!("an export failure is not a cancel"),
        }
    }

    #[test]
    fn a_full_disk_fails_the_export_as_the_servers_not_the_jobs() {
        let path = std::path::PathBuf::from("/tmp/millsim-job-x/stock.stl");
        // ENOSPC and EDQUOT, as the kernel reports them.
        for errno in [libc::ENOSPC, libc::EDQUOT] {
            let p = problem(ExportError::Io(
                path.clone(),
                std::io::Error::from_raw_os_error(errno),
            ));
            assert_eq!(p.status.as_u16(), 507, "errno {errno}");
            assert_eq!(p.slug, "insufficient-storage");
            assert!(
                p.detail.contains("/tmp/millsim-job-x/stock.stl"),
                "{}",
                p.detail
            );
            assert!(
                p.detail.contains("not a fault of the job's inputs"),
                "{}",
                p.detail
            );
        }
        // Other errors stay the export's own.
        let p = problem(ExportError::Io(
            path.clone(),
            std::io::Error::from_raw_os_error(libc::EACCES),
        ));
        assert_eq!(p.status.as_u16(), 422);
        assert_eq!(p.title, "Stock export failed");
        assert!(
            p.detail.starts_with("/tmp/millsim-job-x/stock.stl: "),
            "{}",
            p.detail
        );
        assert_eq!(problem(ExportError::Other("x".into())).status.as_u16(), 422);
    }
}
