//! What each job kind does, on a blocking worker thread: the bridge from a stored job
//! spec and its loaded inputs to the engine, and from the engine's result to stored rows.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use millsim_engine::job::{CancelFlag, Progress};
use millsim_engine::machine::rotary_feed::{
    correct_program, FeedOutput, RotaryFeedError, RotaryFeedOptions,
};
use millsim_engine::machine::Machine;
use millsim_engine::optimize::energy_search::{run_energy_job_with, EnergySearchOptions};
use millsim_engine::optimize::FeedLimits;
use millsim_engine::physics::stability::{
    compute_lobes_3d_with, compute_lobes_with, recommend_spindle_speed, Stability3dInput,
    StabilityInput,
};
use millsim_engine::physics::Material;
use millsim_engine::pipeline::{self, SimulateError, SimulateSpec, StockSource};
use millsim_engine::tool::Tool;
use millsim_engine::{geometry, nc};

use crate::job_library::JobLibrary;
use crate::job_limits::{check_simulation, JobLimits, Refusal, SimulationCheck};
use crate::store::ResourceKind;

/// Job kinds the API knows. Only the ones whose engine exists run; the others are refused
/// at submission with a clear "not supported yet".
pub const KNOWN_KINDS: [&str; 7] = [
    "interpret",
    "simulate",
    "optimize",
    "stability",
    "energy",
    "rotary-feed",
    "identify",
];

pub fn is_supported(kind: &str) -> bool {
    matches!(
        kind,
        "interpret" | "simulate" | "optimize" | "stability" | "rotary-feed" | "energy"
    )
}

/// One input a job kind takes: its name under `inputs`, the resource kind, and whether
/// it must be given.
pub struct InputSpec {
    pub name: &'static str,
    pub kind: ResourceKind,
    pub required: bool,
}

const fn input(name: &'static str, kind: ResourceKind, required: bool) -> InputSpec {
    InputSpec {
        name,
        kind,
        required,
    }
}

/// The inputs each kind takes.
pub fn inputs_of(kind: &str) -> &'static [InputSpec] {
    const INTERPRET: [InputSpec; 1] = [input("program", ResourceKind::Program, true)];
    const SIMULATE: [InputSpec; 7] = [
        input("program", ResourceKind::Program, true),
        input("stock", ResourceKind::Stock, true),
        // The tool for every T number; or one input per number, `T1`, `T2`, ...
        // (see `tool_number_input`); else the tool library's, else the program header's.
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
    const ROTARY_FEED: [InputSpec; 2] = [
        input("program", ResourceKind::Program, true),
        input("machine", ResourceKind::Machine, true),
    ];
    const ENERGY: [InputSpec; 3] = [
        input("tool", ResourceKind::Tool, true),
        // Else `options.material` names a built-in material.
        input("material", ResourceKind::Material, false),
        // Its `energy` field (idle spindle power, auxiliary power) is required.
        input("machine", ResourceKind::Machine, true),
    ];
    match kind {
        "energy" => &ENERGY,
        "interpret" => &INTERPRET,
        "rotary-feed" => &ROTARY_FEED,
        "simulate" | "optimize" => &SIMULATE,
        _ => &[],
    }
}

/// For `simulate` and `optimize`: an input named `T<n>` (n in 1..=9999) is the tool for
/// tool number n of the program.
pub fn tool_number_input(kind: &str, name: &str) -> Option<u32> {
    if !matches!(kind, "simulate" | "optimize") {
        return None;
    }
    let digits = name.strip_prefix('T')?;
    if digits.is_empty() || digits.len() > 4 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok().filter(|n| (1..=9999).contains(n))
}

/// Checks that a simulate/optimize job names its tools one way: `tool`, or `T1`, `T2`, ...
pub fn check_tool_inputs<'a>(
    kind: &str,
    names: impl Iterator<Item = &'a String> + Clone,
) -> Result<(), (String, String)> {
    if !matches!(kind, "simulate" | "optimize") {
        return Ok(());
    }
    let numbered = names
        .clone()
        .filter(|n| tool_number_input(kind, n).is_some())
        .count();
    let single = names.clone().any(|n| n == "tool");
    // No tool at all is allowed: the program's header comments may describe its tools (the
    // job then fails naming the first T number nothing describes).
    match (single, numbered) {
        (true, n) if n > 0 => Err((
            "inputs.tool".into(),
            "give `tool` (one tool for the whole program) or `T1`, `T2`, ... (one per tool number), not both".into(),
        )),
        _ => Ok(()),
    }
}

/// Options of an `interpret` job.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InterpretOptions {
    #[serde(default = "default_dialect")]
    pub dialect: nc::Dialect,
    /// Fanuc: a length word without a decimal point counts in thousandths of a mm.
    #[serde(default)]
    pub fanuc_implied_decimal: bool,
    /// A LinuxCNC tool table (`T1 P1 D6 Z50`), for G43 tool lengths.
    #[serde(default)]
    pub tool_table: Option<String>,
    /// Fanuc parameter CCR: corner rounding R and chamfer C written without the comma.
    #[serde(default)]
    pub fanuc_corners_without_comma: bool,
    /// M codes that do not move the machine (e.g. a control's M428) and may be skipped.
    #[serde(default)]
    pub passthrough_m_codes: Vec<u32>,
    /// Skip blocks that start with `/` (the control's block-delete switch on).
    #[serde(default)]
    pub block_delete: bool,
    /// Refuse M codes the interpreter does not know (and `passthrough_m_codes` does not
    /// list) instead of running them as no-ops with a warning.
    #[serde(default)]
    pub strict_m_codes: bool,
}

fn default_dialect() -> nc::Dialect {
    nc::Dialect::Auto
}

impl InterpretOptions {
    pub fn engine_options(&self) -> Result<nc::InterpretOptions, nc::Diagnostics> {
        let mut o = nc::InterpretOptions {
            dialect: self.dialect,
            fanuc_implied_decimal: self.fanuc_implied_decimal,
            fanuc_corners_without_comma: self.fanuc_corners_without_comma,
            passthrough_m_codes: self.passthrough_m_codes.clone(),
            block_delete: self.block_delete,
            strict_m_codes: self.strict_m_codes,
            ..Default::default()
        };
        if let Some(t) = &self.tool_table {
            o.tool_table = nc::parse_tool_table(t)?;
        }
        Ok(o)
    }
}

/// A stored input as a worker loaded it.
pub struct LoadedInput {
    pub file_name: Option<String>,
    pub media_type: String,
    pub content: Vec<u8>,
}

/// Inputs a worker loaded from the database for one job, by input name.
pub type LoadedInputs = BTreeMap<String, LoadedInput>;

/// A result file.
pub struct OutputFile {
    /// Result name: `program` (operation 1 of a posted CLS too), `program.op2`, ...,
    /// `stock.stl`.
    pub name: String,
    pub media_type: &'static str,
    pub file_name: String,
    pub content: Vec<u8>,
}

/// The result of a job attempt that ran to the end.
pub struct JobOutput {
    pub summary: Value,
    pub rows: Vec<String>,
    /// Per-step samples as (row seq, JSON array), for rows that have any.
    pub samples: Vec<(usize, String)>,
    pub files: Vec<OutputFile>,
}

/// Why a job attempt ended without output.
pub enum JobFailure {
    /// The inputs are wrong; running again will not help. The problem document says why.
    Invalid(Value),
    Cancelled,
}

fn diagnostics_problem(file: &str, d: &nc::Diagnostics) -> Value {
    json!({
        "type": "https://millsim.dev/problems/invalid-program",
        "title": "Program does not interpret",
        "status": 422,
        "detail": d.0.iter().take(5).map(|e| format!("{file}:{e}")).collect::<Vec<_>>().join("; "),
        "file": file,
        "errors": d.0.iter().map(|e| json!({"line": e.line, "column": e.col, "message": e.message})).collect::<Vec<_>>(),
    })
}

pub fn run(
    kind: &str,
    options: &Value,
    inputs: LoadedInputs,
    limits: &JobLimits,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<JobOutput, JobFailure> {
    run_with_stock_file(kind, options, inputs, limits, cancel, progress, None)
}

/// [`run`], with the machined stock of a simulate or optimize job streamed into
/// `stock_file` (a file the size of the stock's surface is then never held in memory)
/// instead of being returned among the output files.
pub fn run_with_stock_file(
    kind: &str,
    options: &Value,
    inputs: LoadedInputs,
    limits: &JobLimits,
    cancel: &CancelFlag,
    progress: &dyn Progress,
    stock_file: Option<&std::path::Path>,
) -> Result<JobOutput, JobFailure> {
    match kind {
        "interpret" => interpret(options, inputs, cancel, progress),
        "simulate" | "optimize" => simulate_job(
            kind == "optimize",
            options,
            inputs,
            limits,
            cancel,
            progress,
            stock_file,
        ),
        "stability" => stability_job(options, cancel, progress),
        "rotary-feed" => rotary_feed_job(options, inputs),
        "energy" => energy_job(options, inputs, cancel),
        other => Err(JobFailure::Invalid(json!({
            "type": "https://millsim.dev/problems/not-supported",
            "title": "Not supported yet",
            "status": 422,
            "detail": format!("job kind `{other}` is not supported yet"),
        }))),
    }
}

fn invalid(title: &str, detail: impl Into<String>) -> JobFailure {
    JobFailure::Invalid(json!({
        "type": "https://millsim.dev/problems/invalid-input", "title": title, "status": 422, "detail": detail.into(),
    }))
}

/// Input `name` parsed from JSON as a `what` (tool, machine, material), if the job has it.
fn json_input<T: serde::de::DeserializeOwned>(
    inputs: &mut LoadedInputs,
    name: &str,
    what: &str,
) -> Result<Option<T>, JobFailure> {
    inputs
        .remove(name)
        .map(|i| {
            serde_json::from_slice(&i.content)
                .map_err(|e| invalid(&format!("Invalid {what}"), format!("input `{name}`: {e}")))
        })
        .transpose()
}

fn required<T>(input: Option<T>, name: &str) -> Result<T, JobFailure> {
    input.ok_or_else(|| invalid("Missing input", format!("the job has no `{name}` input")))
}

/// The job's material: the built-in one `options.material` names, else the `material` input.
fn job_material(name: Option<&str>, inputs: &mut LoadedInputs) -> Result<Material, JobFailure> {
    match name {
        Some(name) => Material::builtin(name).ok_or_else(|| invalid("Unknown material", name)),
        None => required(json_input(inputs, "material", "material")?, "material"),
    }
}

/// The program input as (file name, text).
fn program_text(inputs: &mut LoadedInputs) -> Result<(String, String), JobFailure> {
    let p = inputs
        .remove("program")
        .ok_or_else(|| invalid("Missing input", "the job has no `program` input"))?;
    let file = p.file_name.unwrap_or_else(|| "program.nc".into());
    let text = String::from_utf8(p.content)
        .map_err(|_| invalid("Program is not text", format!("{file} is not UTF-8")))?;
    Ok((file, text))
}

/// An interpretation that stopped: on a cancel (the interpreter stops with an error when
/// its flag is set) the job is cancelled, otherwise the program is at fault.
fn program_failure(cancel: &CancelFlag, file: &str, d: &nc::Diagnostics) -> JobFailure {
    if cancel.is_cancelled() {
        JobFailure::Cancelled
    } else {
        JobFailure::Invalid(diagnostics_problem(file, d))
    }
}

fn interpret(
    options: &Value,
    mut inputs: LoadedInputs,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<JobOutput, JobFailure> {
    let (file, text) = program_text(&mut inputs)?;
    let opts: InterpretOptions = serde_json::from_value(options.clone()).map_err(|e| {
        JobFailure::Invalid(
            json!({"title": "Invalid options", "status": 422, "detail": e.to_string()}),
        )
    })?;
    let mut engine_opts = opts
        .engine_options()
        .map_err(|d| JobFailure::Invalid(diagnostics_problem("tool_table", &d)))?;
    engine_opts.cancel = Some(cancel.clone());
    let result = if crate::validate::looks_like_cls(&text) {
        millsim_engine::cl::read_cls(&text)
    } else {
        nc::interpret(&text, &engine_opts)
    }
    .map_err(|d| program_failure(cancel, &file, &d))?;
    if cancel.is_cancelled() {
        return Err(JobFailure::Cancelled);
    }
    let total = result.moves.len() as u64;
    let mut rows = Vec::with_capacity(result.moves.len());
    // Rows differ (arcs carry a centre, dwells seconds): the CSV needs every column.
    let mut columns: Vec<String> = Vec::new();
    for (i, m) in result.moves.iter().enumerate() {
        let row = serde_json::to_value(m).expect("moves serialize");
        if let Value::Object(o) = &row {
            for k in o.keys() {
                if !columns.iter().any(|c| c == k) {
                    columns.push(k.clone());
                }
            }
        }
        rows.push(row.to_string());
        if i % 4096 == 0 {
            progress.report(i as u64, total);
            if cancel.is_cancelled() {
                return Err(JobFailure::Cancelled);
            }
        }
    }
    progress.report(total, total);
    let warnings: Vec<Value> = result
        .warnings
        .iter()
        .map(|w| json!({"line": w.line, "column": w.col, "message": w.message}))
        .collect();
    Ok(JobOutput {
        summary: json!({ "file": file, "moves": result.moves.len(), "blocks": result.block_count, "warnings": warnings, "row_columns": columns }),
        rows,
        samples: Vec::new(),
        files: Vec::new(),
    })
}

/// Options of a `simulate` job.
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
    /// On a machine with rotary axes: `machine` (X..C are machine axes, the default) or
    /// `tool_tip` (tool-centre-point control: X Y Z are the tip in the part frame).
    #[serde(default)]
    pub axes: pipeline::AxisReading,
    /// The tool's modes for a chatter margin per block: {"modes_x":[..],"modes_y":[..],
    /// "method":"sdm","steps_per_period":40}.
    #[serde(default)]
    pub chatter: Option<pipeline::ChatterSpec>,
}

fn default_positions() -> usize {
    180
}

fn default_grid_mib() -> u64 {
    4096
}

impl SimulateOptions {
    /// Checks what can be checked before the job runs; names the option.
    pub fn check(&self, optimize: bool, has_material_input: bool) -> Result<(), (String, String)> {
        match (&self.limits, optimize) {
            (None, true) => {
                return Err((
                    "options.limits".into(),
                    "an optimize job needs limits, e.g. {\"max_force\": 800}".into(),
                ))
            }
            (Some(_), false) => {
                return Err((
                    "options.limits".into(),
                    "limits are for optimize jobs; submit kind `optimize`".into(),
                ))
            }
            (Some(l), true) => {
                l.validate()
                    .map_err(|e| ("options.limits".to_string(), e.to_string()))?;
                if l.max_force.is_none()
                    && l.max_power.is_none()
                    && l.max_torque.is_none()
                    && l.max_chip_thickness.is_none()
                {
                    return Err(("options.limits".into(), "give at least one target: max_force, max_power, max_torque or max_chip_thickness".into()));
                }
            }
            (None, false) => {}
        }
        check_material(self.material.as_deref(), has_material_input)?;
        if let Some(c) = self.cell_mm {
            if !(0.005..=5.0).contains(&c) {
                return Err((
                    "options.cell_mm".into(),
                    format!("must be in [0.005, 5] mm, got {c}"),
                ));
            }
        }
        if !(8..=3600).contains(&self.force_positions) {
            return Err((
                "options.force_positions".into(),
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
            .map_err(|e| (format!("options.chatter.{}", e.field()), e.to_string()))?;
        }
        if !(1..=16384).contains(&self.max_grid_mib) {
            return Err((
                "options.max_grid_mib".into(),
                "must be in [1, 16384]".into(),
            ));
        }
        Ok(())
    }
}

#[derive(Serialize)]
struct SimulateSummary<'a> {
    file: &'a str,
    #[serde(flatten)]
    simulation: &'a pipeline::SimulationSummary,
    /// Wall time per stage on the worker, seconds.
    timings: &'a pipeline::StageTimings,
    stock_export_s: f64,
    dexel_updates: u64,
    /// The optimized program's cycle time and peak |F| (optimize jobs), also inside
    /// `optimization` with the benchmarks they are judged against.
    #[serde(skip_serializing_if = "Option::is_none")]
    cycle_time_opt_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    force_peak_opt_n: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    optimization: Option<&'a pipeline::OptimizationSummary>,
    /// The job's memory budget and the estimate it was held to (MiB; by buffer, bytes).
    #[serde(skip_serializing_if = "Option::is_none")]
    memory: Option<Value>,
    /// With a `tool_library` input: its file and format, the T numbers it gave that cut,
    /// and its import report's notes on them.
    #[serde(skip_serializing_if = "Option::is_none")]
    tool_library: Option<Value>,
    row_columns: Vec<String>,
}

/// The stock as a binary STL into the file at `path`.
fn stream_stl(stock: &geometry::Stock, path: &std::path::Path) -> Result<(), String> {
    let name = path.display();
    let file = std::fs::File::create(path).map_err(|e| format!("{name}: {e}"))?;
    let mut out = std::io::BufWriter::with_capacity(1 << 20, file);
    geometry::export_stl(stock, &mut out).map_err(|e| format!("{name}: {e}"))?;
    std::io::Write::flush(&mut out).map_err(|e| format!("{name}: {e}"))
}

fn simulate_job(
    optimize: bool,
    options: &Value,
    mut inputs: LoadedInputs,
    limits: &JobLimits,
    cancel: &CancelFlag,
    progress: &dyn Progress,
    stock_file: Option<&std::path::Path>,
) -> Result<JobOutput, JobFailure> {
    let opts: SimulateOptions = serde_json::from_value(options.clone())
        .map_err(|e| invalid("Invalid options", e.to_string()))?;
    opts.check(optimize, inputs.contains_key("material"))
        .map_err(|(f, m)| invalid("Invalid options", format!("{f}: {m}")))?;
    let (file, text) = program_text(&mut inputs)?;
    // Key 0: one tool serves every tool number; else the tool of each number.
    let mut tools = BTreeMap::new();
    let names: Vec<String> = inputs.keys().cloned().collect();
    for name in names {
        let number = if name == "tool" {
            0
        } else if let Some(n) =
            tool_number_input(if optimize { "optimize" } else { "simulate" }, &name)
        {
            n
        } else {
            continue;
        };
        let tool: Tool = required(json_input(&mut inputs, &name, "tool")?, &name)?;
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
    let material = job_material(opts.material.as_deref(), &mut inputs)?;
    let machine = json_input(&mut inputs, "machine", "machine")?.unwrap_or_else(Machine::generic);
    let stock = inputs
        .remove("stock")
        .ok_or_else(|| invalid("Missing input", "the job has no `stock` input"))?;
    let stock = if stock.media_type == "application/json" {
        StockSource::Shape(
            serde_json::from_slice::<geometry::StockShape>(&stock.content)
                .map_err(|e| invalid("Invalid stock", e.to_string()))?,
        )
    } else {
        StockSource::Stl(stock.content)
    };
    let interpret = nc::InterpretOptions {
        dialect: opts.dialect,
        fanuc_implied_decimal: opts.fanuc_implied_decimal,
        passthrough_m_codes: opts.passthrough_m_codes.clone(),
        strict_m_codes: opts.strict_m_codes,
        cancel: Some(cancel.clone()),
        ..Default::default()
    };
    // Travel and memory budget, before the pipeline allocates anything.
    let check = SimulationCheck {
        file: &file,
        program: &text,
        interpret: &interpret,
        machine: &machine,
        axes: opts.axes,
        stock: &stock,
        tools: &tools,
        cell: opts.cell_mm,
        optimize,
    };
    let estimate = check_simulation(&check, limits).map_err(|r| match r {
        Refusal::Program(d) => program_failure(cancel, &file, &d),
        Refusal::Problem(p) => JobFailure::Invalid(p),
    })?;
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
        part: match inputs.remove("part") {
            Some(p) if p.media_type == "application/json" => {
                return Err(invalid(
                    "Invalid part",
                    "the design part must be an STL mesh, not a parametric stock",
                ))
            }
            Some(p) => Some(p.content),
            None => None,
        },
    };
    let mut out = pipeline::simulate(&spec, cancel, progress).map_err(|e| match e {
        SimulateError::Cancelled => JobFailure::Cancelled,
        SimulateError::Program(d) => program_failure(cancel, &file, &d),
        other => invalid("Simulation refused", format!("{file}: {other}")),
    })?;
    // The stock mesh and the rows' JSON are independent: both at once.
    let ((rows, samples), (stl, export_s)) = std::thread::scope(|scope| {
        let serialized = scope.spawn(|| {
            let rows: Vec<String> = out
                .rows
                .iter()
                .map(|r| serde_json::to_string(r).expect("rows serialize"))
                .collect();
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
            Some(path) => stream_stl(&out.stock, path).map(|()| None),
            None => geometry::export_stl_vec(&out.stock)
                .map(|(stl, _)| Some(stl))
                .map_err(|e| e.to_string()),
        };
        let exported = (written, clock.elapsed().as_secs_f64());
        match serialized.join() {
            Ok(v) => (v, exported),
            Err(panic) => std::panic::resume_unwind(panic),
        }
    });
    let stl = stl.map_err(|e| invalid("Stock export failed", e.to_string()))?;
    let tool_library = library.map(|library| {
        let (section, warnings) = library.report(&out.tool_numbers);
        out.summary.tool_warnings.extend(warnings);
        section
    });
    let row_columns = match serde_json::to_value(out.rows.first().cloned().unwrap_or_default()) {
        Ok(Value::Object(o)) => o.keys().cloned().collect(),
        _ => Vec::new(),
    };
    let (stem, ext) = file
        .rsplit_once('.')
        .map(|(s, e)| (s, format!(".{e}")))
        .unwrap_or((&file, String::new()));
    let mut files: Vec<OutputFile> = stl
        .map(|content| OutputFile {
            name: "stock.stl".into(),
            media_type: "model/stl",
            file_name: format!("{stem}.stock.stl"),
            content,
        })
        .into_iter()
        .collect();
    if let Some(text) = out.optimized_program {
        files.push(OutputFile {
            name: "program".into(),
            media_type: "text/plain; charset=utf-8",
            file_name: format!("{stem}.opt{ext}"),
            content: text.into_bytes(),
        });
    }
    Ok(JobOutput {
        summary: serde_json::to_value(SimulateSummary {
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
        .expect("summary serializes"),
        rows,
        samples,
        files,
    })
}

/// Where to look for a spindle speed: the widest stable pocket within `near_rpm ± window_rpm`
/// at `depth_mm`.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecommendOptions {
    pub near_rpm: f64,
    pub depth_mm: f64,
    #[serde(default = "default_window_rpm")]
    pub window_rpm: f64,
}

fn default_window_rpm() -> f64 {
    3000.0
}

/// A stability job: a lobe diagram (optionally with a recommended speed), or a 3-D surface
/// over the remaining allowance when `allowance` is given.
pub enum StabilityRequest {
    Lobes(StabilityInput, Option<RecommendOptions>),
    Surface(Stability3dInput),
}

/// Options of a `stability` job: the object `millsim stability INPUT.json` reads, plus
/// `recommend` ({near_rpm, depth_mm, window_rpm}), or `allowance` and `allowances_mm` for
/// 3-D lobes. Names the field on error.
pub fn stability_options(options: &Value) -> Result<StabilityRequest, (String, String)> {
    let path_err = |e: serde_path_to_error::Error<serde_json::Error>| {
        (format!("options.{}", e.path()), e.inner().to_string())
    };
    let mut rest = options.as_object().cloned().unwrap_or_default();
    let recommend = rest.remove("recommend");
    if rest.contains_key("allowance") || rest.contains_key("allowances_mm") {
        if recommend.is_some() {
            return Err((
                "options.recommend".into(),
                "a speed recommendation needs a 2-D lobe diagram (no `allowance`)".into(),
            ));
        }
        let input: Stability3dInput =
            serde_path_to_error::deserialize(Value::Object(rest)).map_err(path_err)?;
        input
            .validate()
            .map_err(|e| (format!("options.{}", e.field()), e.to_string()))?;
        return Ok(StabilityRequest::Surface(input));
    }
    let input: StabilityInput =
        serde_path_to_error::deserialize(Value::Object(rest)).map_err(path_err)?;
    input
        .validate()
        .map_err(|e| (format!("options.{}", e.field()), e.to_string()))?;
    let recommend: Option<RecommendOptions> = recommend
        .map(|r| serde_path_to_error::deserialize(r))
        .transpose()
        .map_err(|e: serde_path_to_error::Error<serde_json::Error>| {
            (
                format!("options.recommend.{}", e.path()),
                e.inner().to_string(),
            )
        })?;
    if let Some(r) = &recommend {
        for (field, v) in [
            ("near_rpm", r.near_rpm),
            ("depth_mm", r.depth_mm),
            ("window_rpm", r.window_rpm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err((
                    format!("options.recommend.{field}"),
                    format!("must be a positive number, got {v}"),
                ));
            }
        }
    }
    Ok(StabilityRequest::Lobes(input, recommend))
}

/// Lobes as rows (rpm, critical depth) — or (allowance_mm, rpm, depth_mm) for a 3-D surface:
/// /blocks serves them as JSON pages and CSV.
fn stability_job(
    options: &Value,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<JobOutput, JobFailure> {
    let request = stability_options(options)
        .map_err(|(f, m)| invalid("Invalid options", format!("{f}: {m}")))?;
    let refused = |e: millsim_engine::physics::PhysicsError| match e {
        millsim_engine::physics::PhysicsError::Cancelled => JobFailure::Cancelled,
        e => invalid("Stability refused", e.to_string()),
    };
    let (summary, rows): (Value, Vec<String>) = match request {
        StabilityRequest::Lobes(input, recommend) => {
            let curve = compute_lobes_with(&input, cancel, progress).map_err(refused)?;
            let recommendation = recommend.map(|r| {
                recommend_spindle_speed(&curve.points, r.near_rpm, r.depth_mm, r.window_rpm)
            });
            let rows = curve
                .points
                .iter()
                .map(|p| json!({"rpm": p.rpm, "depth_mm": p.depth_mm}).to_string())
                .collect();
            let mut summary = json!({
                "method": curve.method,
                "speeds": curve.points.len(),
                "minimum": curve.minimum(),
                "row_columns": ["rpm", "depth_mm"],
            });
            if let Some(r) = recommendation {
                // null: no speed in the window is stable at that depth.
                summary["recommendation"] = json!(r);
            }
            (summary, rows)
        }
        StabilityRequest::Surface(input) => {
            let surface = compute_lobes_3d_with(&input, cancel, progress).map_err(refused)?;
            let rows = surface
                .rows
                .iter()
                .map(|p| {
                    json!({"allowance_mm": p.allowance_mm, "rpm": p.rpm, "depth_mm": p.depth_mm})
                        .to_string()
                })
                .collect();
            let summary = json!({
                "method": surface.method,
                "allowances": input.allowances_mm.len(),
                "points": surface.rows.len(),
                "row_columns": ["allowance_mm", "rpm", "depth_mm"],
            });
            (summary, rows)
        }
    };
    let n = rows.len() as u64;
    progress.report(n, n);
    Ok(JobOutput {
        summary,
        rows,
        samples: Vec::new(),
        files: Vec::new(),
    })
}

/// A job's material: a `material` input or a built-in name in `options.material`, one of them.
fn check_material(name: Option<&str>, has_material_input: bool) -> Result<(), (String, String)> {
    let field = || "options.material".to_string();
    match (name, has_material_input) {
        (Some(_), true) => Err((
            field(),
            "give a `material` input or `options.material`, not both".into(),
        )),
        (None, false) => Err((
            field(),
            "name a built-in material (TC6, Al7075-T6, Al6082-T6) or give a `material` input"
                .into(),
        )),
        (Some(name), false) if Material::builtin(name).is_none() => {
            let names: Vec<String> = millsim_engine::physics::builtin_materials()
                .into_iter()
                .map(|m| m.name)
                .collect();
            Err((
                field(),
                format!(
                    "no built-in material `{name}`; one of: {}",
                    names.join(", ")
                ),
            ))
        }
        _ => Ok(()),
    }
}

/// Options of an `energy` job: the search options (`EnergySearchOptions`) plus `material`,
/// a built-in material name when no `material` input is given. Names the field on error.
pub fn energy_options(
    options: &Value,
    has_material_input: bool,
) -> Result<(EnergySearchOptions, Option<String>), (String, String)> {
    let mut rest = options.as_object().cloned().unwrap_or_default();
    let material = match rest.remove("material") {
        None => None,
        Some(Value::String(name)) => Some(name),
        Some(_) => {
            return Err((
                "options.material".into(),
                "must be a built-in material name".into(),
            ))
        }
    };
    check_material(material.as_deref(), has_material_input)?;
    let search: EnergySearchOptions = serde_path_to_error::deserialize(Value::Object(rest))
        .map_err(|e| (format!("options.{}", e.path()), e.inner().to_string()))?;
    search
        .validate()
        .map_err(|e| (format!("options.{}", e.field()), e.to_string()))?;
    Ok((search, material))
}

/// Spindle speed, depths and feed of a face or side milling task that maximize the energy
/// utilization or minimize energy or time under the machine's and the stability limits;
/// the Pareto front of time against energy when asked. Rows: the front (or the best point).
fn energy_job(
    options: &Value,
    mut inputs: LoadedInputs,
    cancel: &CancelFlag,
) -> Result<JobOutput, JobFailure> {
    let (search, material_name) = energy_options(options, inputs.contains_key("material"))
        .map_err(|(f, m)| invalid("Invalid options", format!("{f}: {m}")))?;
    let tool: Tool = required(json_input(&mut inputs, "tool", "tool")?, "tool")?;
    let machine: Machine = required(json_input(&mut inputs, "machine", "machine")?, "machine")?;
    let material = job_material(material_name.as_deref(), &mut inputs)?;
    let result = run_energy_job_with(&search, &tool, &material.coefficients, &machine, cancel)
        .map_err(|e| match e {
            millsim_engine::physics::PhysicsError::Cancelled => JobFailure::Cancelled,
            e => JobFailure::Invalid(json!({
                "type": "https://millsim.dev/problems/energy-search",
                "title": "Energy search refused",
                "status": 422,
                "detail": e.to_string(),
                "field": e.field(),
            })),
        })?;
    let points = result
        .pareto
        .clone()
        .unwrap_or_else(|| vec![result.best.clone()]);
    let rows: Vec<String> = points
        .iter()
        .map(|p| serde_json::to_string(p).expect("rows serialize"))
        .collect();
    let row_columns = match serde_json::to_value(&result.best) {
        Ok(Value::Object(o)) => o.keys().cloned().collect::<Vec<_>>(),
        _ => Vec::new(),
    };
    let mut summary = serde_json::to_value(&result).expect("summary serializes");
    summary["material"] = json!(material.name);
    summary["row_columns"] = json!(row_columns);
    Ok(JobOutput {
        summary,
        rows,
        samples: Vec::new(),
        files: Vec::new(),
    })
}

/// Options of a `rotary-feed` job.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotaryFeedJobOptions {
    /// `per_min` (G94, F = I/t) or `inverse_time` (G93, F = 1/t; a G94 program is converted:
    /// G93 before its first feed block, G94 after its last).
    #[serde(default)]
    pub output: FeedOutput,
    #[serde(default = "default_dialect")]
    pub dialect: nc::Dialect,
    /// M codes that do not move the machine (e.g. LinuxCNC's M428/M429).
    #[serde(default)]
    pub passthrough_m_codes: Vec<u32>,
    /// CLS input: decimals of the posted coordinates (1 to 9, default 4).
    #[serde(default = "default_post_decimals")]
    pub decimals: usize,
    /// CLS input: number the posted blocks N10, N20, ...
    #[serde(default)]
    pub n_numbers: bool,
}

fn default_post_decimals() -> usize {
    4
}

/// An APT/CLS file posted to G-code for the machine with corrected feeds: one program per
/// operation (`program` is the first, `program.op2`, ... the others); rows are every posted
/// feed move with its tool-tip distance and corrected F.
fn post_cls_job(
    file: &str,
    text: &str,
    machine: &Machine,
    opts: &RotaryFeedJobOptions,
) -> Result<JobOutput, JobFailure> {
    use millsim_engine::machine::post::{post_cls, PostOptions};
    if !(1..=9).contains(&opts.decimals) {
        return Err(invalid(
            "Invalid options",
            format!("decimals: must be 1 to 9, got {}", opts.decimals),
        ));
    }
    let options = PostOptions {
        n_numbers: opts.n_numbers.then_some((10, 10)),
        linear_decimals: opts.decimals,
        angle_decimals: opts.decimals,
        feed: RotaryFeedOptions {
            output: opts.output,
            ..RotaryFeedOptions::default()
        },
        ..PostOptions::default()
    };
    let posted = post_cls(text, machine, &options)
        .map_err(|e| invalid("Posting refused", format!("{file}: {e}")))?;
    let stem = file.rsplit_once('.').map(|(s, _)| s).unwrap_or(file);
    let mut rows = Vec::new();
    let mut files = Vec::new();
    let mut operations = Vec::new();
    for p in &posted {
        for b in &p.feeds.blocks {
            let mut row = serde_json::to_value(b).expect("rows serialize");
            row["operation"] = json!(p.operation);
            rows.push(row.to_string());
        }
        let name = if p.operation == 1 {
            "program".to_string()
        } else {
            format!("program.op{}", p.operation)
        };
        let file_name = format!("{stem}.op{}.nc", p.operation);
        operations.push(json!({
            "operation": p.operation,
            "tool": p.tool,
            "moves": p.axes.len(),
            "file_name": file_name,
            "limited_blocks": p.feeds.blocks.iter().filter(|b| b.limited).count(),
            "issues": p.issues,
        }));
        files.push(OutputFile {
            name,
            media_type: "text/plain; charset=utf-8",
            file_name,
            content: p.text.clone().into_bytes(),
        });
    }
    Ok(JobOutput {
        summary: json!({
            "file": file,
            "format": "cls",
            "operations": operations,
            "blocks": rows.len(),
            "row_columns": ["operation", "block", "line", "feed", "output", "limited"],
        }),
        rows,
        samples: Vec::new(),
        files,
    })
}

/// Rotary-axis feed correction of a G-code program: F words rewritten so the tool tip moves
/// at the programmed feed; rows are the corrected feed per block.
fn rotary_feed_job(options: &Value, mut inputs: LoadedInputs) -> Result<JobOutput, JobFailure> {
    let opts: RotaryFeedJobOptions = serde_json::from_value(options.clone())
        .map_err(|e| invalid("Invalid options", e.to_string()))?;
    let (file, text) = program_text(&mut inputs)?;
    let machine: Machine = required(json_input(&mut inputs, "machine", "machine")?, "machine")?;
    if crate::validate::looks_like_cls(&text) {
        return post_cls_job(&file, &text, &machine, &opts);
    }
    let interpret = nc::InterpretOptions {
        dialect: opts.dialect,
        passthrough_m_codes: opts.passthrough_m_codes.clone(),
        ..Default::default()
    };
    let feed = RotaryFeedOptions {
        output: opts.output,
        ..RotaryFeedOptions::default()
    };
    let (corrected, report) =
        correct_program(&text, &interpret, &machine, &feed).map_err(|e| match e {
            RotaryFeedError::Program(d) => JobFailure::Invalid(diagnostics_problem(&file, &d)),
            other => invalid("Rotary feed correction refused", format!("{file}: {other}")),
        })?;
    let rows: Vec<String> = report
        .blocks
        .iter()
        .map(|b| serde_json::to_string(b).expect("rows serialize"))
        .collect();
    let (stem, ext) = file
        .rsplit_once('.')
        .map(|(s, e)| (s, format!(".{e}")))
        .unwrap_or((&file, String::new()));
    Ok(JobOutput {
        summary: json!({
            "file": file,
            "blocks": report.blocks.len(),
            "limited_blocks": report.blocks.iter().filter(|b| b.limited).count(),
            "skipped_moves": report.skipped.len(),
            "row_columns": ["block", "line", "feed", "output", "limited"],
        }),
        rows,
        samples: Vec::new(),
        files: vec![OutputFile {
            name: "program".into(),
            media_type: "text/plain; charset=utf-8",
            file_name: format!("{stem}.rotary{ext}"),
            content: corrected.into_bytes(),
        }],
    })
}
