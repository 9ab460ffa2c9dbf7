//! The `process` job: operations run in order on one stock, each cutting what the last
//! left (`millsim_engine::pipeline::run_process`).
//!
//! A request names its operations under `inputs.operations`, each with its own resources
//! (program, tool or `T<n>`, tool_library, part, library programs) and its `name` and
//! `options`. The HTTP edge stores them flat: operation n's inputs as `op<n>.<input>`
//! (so the queue loads them as any job's inputs) and its name and options under
//! `options.operations[n-1]`. Errors name the request's fields
//! (`inputs.operations[1].program`). Each operation is an optimize when its options give
//! `limits`, a simulate otherwise.

use serde::Deserialize;
use serde_json::{json, Map, Value};

use millsim_engine::geometry;
use millsim_engine::job::{CancelFlag, Progress};
use millsim_engine::pipeline::{self, Operation, ProcessError, ProcessSpec, SimulateError};

use super::inputs::{invalid, program_failure, stem_and_ext};
use super::simulate::{
    check_spec, spec_from_inputs, stream_stl, BuiltSpec, ExportError, SimulateOptions,
    SimulateSummary,
};
use super::{
    input, FieldError, InputSpec, JobFailure, JobOutput, LoadedInput, LoadedInputs, OutputFile,
    SubmittedInputs,
};
use crate::job_budget::problems::{mib, over_memory_budget};
use crate::job_budget::JobLimits;
use crate::problem::Problem;
use crate::store::artifacts::ArtifactContent;
use crate::store::ResourceKind;

pub use pipeline::MAX_OPERATIONS;

/// The process's own inputs; the operations' are `op<n>.<input>` (see [`operation_input`]).
pub const INPUTS: [InputSpec; 3] = [
    input("stock", ResourceKind::Stock, true),
    input("material", ResourceKind::Material, false),
    input("machine", ResourceKind::Machine, false),
];

/// What an operation takes by resource id under `inputs.operations[i]`.
const OPERATION_INPUTS: [(&str, ResourceKind); 4] = [
    ("program", ResourceKind::Program),
    ("tool", ResourceKind::Tool),
    ("tool_library", ResourceKind::ToolLibrary),
    ("part", ResourceKind::Stock),
];

/// Options of the whole process, not of one operation: one stock, one grid, one setup.
const PROCESS_ONLY: [&str; 5] = [
    "material",
    "cell_mm",
    "max_grid_mib",
    "fixture",
    "force_positions",
];

/// `op<n>.<name>` → (n from 1, name).
pub fn operation_input(name: &str) -> Option<(usize, &str)> {
    let rest = name.strip_prefix("op")?;
    let (n, input) = rest.split_once('.')?;
    if n.is_empty() || n.len() > 2 || !n.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let n: usize = n.parse().ok()?;
    (1..=MAX_OPERATIONS).contains(&n).then_some((n, input))
}

/// The resource kind of an operation's input `name` (without its `op<n>.`).
fn operation_input_kind(name: &str) -> Option<ResourceKind> {
    if let Some((_, k)) = OPERATION_INPUTS.iter().find(|(n, _)| *n == name) {
        Some(*k)
    } else if super::simulate::tool_number(name).is_some() {
        Some(ResourceKind::Tool)
    } else if super::inputs::library_file_name(name).is_some() {
        Some(ResourceKind::Program)
    } else {
        None
    }
}

/// An input a process names beyond its fixed ones: an operation's, or a fixture body's STL.
pub fn named_input(name: &str) -> Option<ResourceKind> {
    match operation_input(name) {
        Some((_, input)) => operation_input_kind(input),
        None if super::simulate::fixture_input(name) => Some(ResourceKind::Stock),
        None => None,
    }
}

/// The request's field for a stored input name (`op2.program` →
/// `inputs.operations[1].program`).
pub fn input_field(name: &str) -> String {
    match operation_input(name) {
        Some((n, input)) => format!("inputs.operations[{}].{input}", n - 1),
        None => format!("inputs.{name}"),
    }
}

/// The request's `inputs.operations` flattened as the job stores them: the operations'
/// resource inputs into `inputs` (`op<n>.<input>`), their names and options into the
/// returned list (stored as `options.operations`). Names the field on error.
pub fn flatten_operations(inputs: &mut Map<String, Value>) -> Result<Vec<Value>, FieldError> {
    let field = "inputs.operations";
    let ops = match inputs.remove("operations") {
        Some(Value::Array(ops)) => ops,
        Some(_) => {
            return Err(FieldError::new(
                field,
                "a list of operations, each {\"name\": ..., \"program\": id, \"tool\" or \"T1\": id, \"options\": {...}}",
            ))
        }
        None => return Err(FieldError::new(field, "a `process` job needs `operations`")),
    };
    if ops.is_empty() || ops.len() > MAX_OPERATIONS {
        return Err(FieldError::new(
            field,
            format!("{} operations: give 1 to {MAX_OPERATIONS}", ops.len()),
        ));
    }
    if let Some(k) = inputs.keys().find(|k| operation_input(k).is_some()) {
        return Err(FieldError::new(
            format!("inputs.{k}"),
            "give an operation's inputs under inputs.operations",
        ));
    }
    let mut entries = Vec::with_capacity(ops.len());
    let mut names: Vec<String> = Vec::new();
    for (i, op) in ops.into_iter().enumerate() {
        let at = |k: &str| format!("{field}[{i}].{k}");
        let Value::Object(op) = op else {
            return Err(FieldError::new(
                format!("{field}[{i}]"),
                "an operation is an object: {\"name\": ..., \"program\": id, ...}",
            ));
        };
        let mut name = format!("op{}", i + 1);
        let mut options = Value::Object(Map::new());
        let mut has_program = false;
        for (k, v) in op {
            match k.as_str() {
                "name" => match v {
                    Value::String(s) if !s.trim().is_empty() && s.len() <= 100 => name = s,
                    _ => return Err(FieldError::new(at("name"), "a name of 1 to 100 characters")),
                },
                "options" if v.is_object() => options = v,
                "options" => return Err(FieldError::new(at("options"), "must be an object")),
                _ if operation_input_kind(&k).is_some() => {
                    has_program |= k == "program";
                    inputs.insert(format!("op{}.{k}", i + 1), v);
                }
                _ => {
                    return Err(FieldError::new(
                        at(&k),
                        format!("an operation takes no `{k}`; it takes name, options, program, tool or T<n>, tool_library, part and library/<file>"),
                    ))
                }
            }
        }
        if !has_program {
            return Err(FieldError::new(
                at("program"),
                "every operation needs a program",
            ));
        }
        if names.contains(&name) {
            return Err(FieldError::new(
                at("name"),
                format!("two operations are named `{name}`"),
            ));
        }
        names.push(name.clone());
        entries.push(json!({ "name": name, "options": options }));
    }
    Ok(entries)
}

#[derive(Debug, Deserialize)]
struct StoredOperation {
    name: String,
    #[serde(default)]
    options: Map<String, Value>,
}

/// The process's options as stored: the shared ones, `keep_stocks`, and the operations'
/// names and options (from `inputs.operations`).
#[derive(Debug, Deserialize)]
pub struct ProcessOptions {
    #[serde(default)]
    keep_stocks: bool,
    #[serde(default)]
    operations: Vec<StoredOperation>,
    /// The rest: options every operation shares (material, cell_mm, fixture, dialect, ...).
    #[serde(flatten)]
    shared: Map<String, Value>,
}

/// Operation `i`'s options: the shared ones under its own (which may not set the
/// process's one-per-stock options), and whether it is optimized.
fn operation_options(
    shared: &Map<String, Value>,
    op: &StoredOperation,
    i: usize,
) -> Result<(SimulateOptions, bool), FieldError> {
    let at = |k: &str| format!("inputs.operations[{i}].options.{k}");
    let mut merged = shared.clone();
    // The fixture is built once, with the first operation (one setup for all).
    if i > 0 {
        merged.remove("fixture");
    }
    let mut optimize = None;
    for (k, v) in &op.options {
        if PROCESS_ONLY.contains(&k.as_str()) {
            return Err(FieldError::new(
                at(k),
                format!("one {k} for the whole process: give it in options.{k}"),
            ));
        }
        if k == "optimize" {
            optimize = Some(
                v.as_bool()
                    .ok_or_else(|| FieldError::new(at(k), "true or false"))?,
            );
            continue;
        }
        merged.insert(k.clone(), v.clone());
    }
    let opts: SimulateOptions =
        crate::problem::parse_json(Value::Object(merged).to_string().as_bytes()).map_err(|p| {
            let field = p
                .extensions
                .get("field")
                .and_then(Value::as_str)
                .unwrap_or("")
                .to_string();
            let top = field.split(['.', '[']).next().unwrap_or("");
            let field = if op.options.contains_key(top) || shared.get(top).is_none() {
                at(&field)
            } else {
                format!("options.{field}")
            };
            FieldError::new(field, p.detail)
        })?;
    let optimize = match (optimize, &opts.limits) {
        (Some(true), None) => {
            return Err(FieldError::new(
                at("limits"),
                "an optimized operation needs limits, e.g. {\"max_force\": 800}",
            ))
        }
        (Some(false), Some(_)) => {
            return Err(FieldError::new(
                at("limits"),
                "limits are for optimized operations: drop them or `optimize: false`",
            ))
        }
        (_, limits) => limits.is_some(),
    };
    Ok((opts, optimize))
}

/// A check's field under the operation's options when it is one of its own.
fn operation_field(e: FieldError, op: &StoredOperation, i: usize) -> FieldError {
    match e.field.strip_prefix("options.") {
        Some(rest)
            if op
                .options
                .contains_key(rest.split(['.', '[']).next().unwrap_or("")) =>
        {
            FieldError::new(format!("inputs.operations[{i}].options.{rest}"), e.message)
        }
        _ => e,
    }
}

/// The options read as a submission and the job read them (errors name the field).
pub fn stored_options(options: &Value) -> Result<ProcessOptions, FieldError> {
    let o: ProcessOptions = serde_json::from_value(options.clone())
        .map_err(|e| FieldError::new("options", e.to_string()))?;
    if o.operations.is_empty() {
        return Err(FieldError::new(
            "inputs.operations",
            "a `process` job needs `operations`",
        ));
    }
    Ok(o)
}

/// At submission: the grid and stock export against the job memory budget, with the
/// cell of `options.cell_mm` (shared by the operations) or of the finest tool of all the
/// operations (`op2.T1`).
pub fn check_memory_budget(
    o: &ProcessOptions,
    inputs: &SubmittedInputs,
    limits: &JobLimits,
) -> Result<(), Problem> {
    let cell_mm = o.shared.get("cell_mm").and_then(Value::as_f64);
    fn tool_name(name: &str) -> &str {
        match name.split_once('.') {
            Some((op, tool)) if op.starts_with("op") => tool,
            _ => name,
        }
    }
    super::simulate::grid_budget(cell_mm, inputs, tool_name, limits)
}

/// At submission: every operation's options, and how each names its tools; the fixture's
/// STL inputs against `options.fixture`.
pub fn check<'a>(
    input_names: impl Iterator<Item = &'a String> + Clone,
    o: &ProcessOptions,
) -> Result<(), FieldError> {
    let has_material_input = input_names.clone().any(|n| n == "material");
    for (i, op) in o.operations.iter().enumerate() {
        let (opts, optimize) = operation_options(&o.shared, op, i)?;
        opts.check(optimize, has_material_input)
            .map_err(|e| operation_field(e, op, i))?;
        let prefix = format!("op{}.", i + 1);
        let own: Vec<String> = input_names
            .clone()
            .filter_map(|n| n.strip_prefix(&prefix).map(str::to_string))
            .collect();
        super::check_tool_inputs(super::JobKind::Simulate, own.iter()).map_err(|e| {
            FieldError::new(
                e.field
                    .replacen("inputs.", &format!("inputs.operations[{i}]."), 1),
                e.message,
            )
        })?;
        if i == 0 {
            let shared: Vec<String> = input_names
                .clone()
                .filter(|n| operation_input(n).is_none())
                .cloned()
                .collect();
            super::simulate::check_fixture_inputs(&opts, shared.iter())?;
        }
    }
    Ok(())
}

/// A shared input handed to each operation (a JSON resource, or the stock mesh, shared).
fn share(input: &LoadedInput) -> LoadedInput {
    LoadedInput {
        file_name: input.file_name.clone(),
        media_type: input.media_type.clone(),
        content: input.content.clone(),
        stored_chunks: input.stored_chunks.clone(),
        // The stock's mesh was read once (`run`); a mesh that failed is not shared.
        mesh: match &input.mesh {
            Some(Ok((mesh, repairs))) => Some(Ok((mesh.clone(), *repairs))),
            _ => None,
        },
    }
}

/// The memory a process holds beyond its largest operation: the rows and what the steps
/// keep of every operation before the last, and the stocks kept (each an export).
fn process_estimate(
    estimates: &[Option<millsim_engine::budget::MemoryEstimate>],
    keep_stocks: bool,
) -> Option<(u64, Value)> {
    let all: Vec<_> = estimates.iter().flatten().collect();
    if all.len() != estimates.len() {
        return None;
    }
    let peak = all.iter().map(|e| e.peak_bytes).max().unwrap_or(0);
    let held: u64 = all[..all.len() - 1]
        .iter()
        .map(|e| e.rows_bytes + e.kept_bytes)
        .sum();
    let stocks: u64 = if keep_stocks {
        all[..all.len() - 1].iter().map(|e| e.export_bytes).sum()
    } else {
        0
    };
    let total = peak + held + stocks;
    Some((
        total,
        json!({
            "peak_bytes": total,
            "largest_operation_bytes": peak,
            "earlier_rows_bytes": held,
            "kept_stocks_bytes": stocks,
            "operations": all,
        }),
    ))
}

pub fn run(
    o: ProcessOptions,
    mut inputs: LoadedInputs,
    limits: &JobLimits,
    cancel: &CancelFlag,
    progress: &dyn Progress,
    stock_file: Option<&std::path::Path>,
) -> Result<JobOutput, JobFailure> {
    let bad = |e: FieldError| invalid("Invalid options", e.to_string());
    let has_material_input = inputs.contains_key("material");
    // The shared inputs every operation reads; the stock, read once, is shared too.
    let mut shared: Vec<(String, LoadedInput)> = Vec::new();
    for name in ["stock", "material", "machine"] {
        let Some(mut i) = inputs.remove(name) else {
            continue;
        };
        if name == "stock" && i.media_type != "application/json" && i.mesh.is_none() {
            let file = i.file_name.clone().unwrap_or_else(|| "stock.stl".into());
            let content = std::mem::take(&mut i.content);
            let (mesh, repairs) =
                geometry::Mesh::from_stl_reader_repaired(&content[..], content.len() as u64)
                    .map_err(|e| invalid("Invalid stock", format!("{file}: {e}")))?;
            i.mesh = Some(Ok((std::sync::Arc::new(mesh), repairs)));
        }
        shared.push((name.to_string(), i));
    }
    let fixture_inputs: Vec<String> = inputs
        .keys()
        .filter(|n| super::simulate::fixture_input(n))
        .cloned()
        .collect();
    // Every operation cuts at the process's one cell (the engine takes the finest default
    // of every operation's tools). A first guess from the tools given by id; an operation
    // whose check finds a finer tool (from a tool library or its program's header
    // comments) sets the cell, and the operations checked at a coarser one are estimated
    // again at it (below).
    let shared_cell = o.shared.get("cell_mm").and_then(Value::as_f64);
    let radii: Vec<f64> = inputs
        .iter()
        .filter(|(n, _)| {
            operation_input(n)
                .is_some_and(|(_, i)| i == "tool" || super::simulate::tool_number(i).is_some())
        })
        .filter_map(|(_, x)| {
            serde_json::from_slice::<millsim_engine::tool::Tool>(crate::problem::without_bom(
                &x.content,
            ))
            .ok()
        })
        .map(|t| t.radius())
        .collect();
    let estimate_cell = shared_cell.or((!radii.is_empty()).then(|| geometry::default_cell(&radii)));
    let mut operations = Vec::with_capacity(o.operations.len());
    let mut files = Vec::with_capacity(o.operations.len());
    let mut encodings = Vec::with_capacity(o.operations.len());
    let mut estimates = Vec::new();
    let mut estimate_cells = Vec::new();
    let mut all_radii = Vec::new();
    let mut libraries = Vec::new();
    for (i, op) in o.operations.iter().enumerate() {
        let (mut opts, optimize) = operation_options(&o.shared, op, i).map_err(bad)?;
        opts.check(optimize, has_material_input)
            .map_err(|e| bad(operation_field(e, op, i)))?;
        opts.cell_mm = opts.cell_mm.or(estimate_cell);
        let prefix = format!("op{}.", i + 1);
        let mut own: LoadedInputs = shared.iter().map(|(n, x)| (n.clone(), share(x))).collect();
        let names: Vec<String> = inputs
            .keys()
            .filter(|n| n.starts_with(&prefix))
            .cloned()
            .collect();
        for n in names {
            let x = inputs.remove(&n).expect("listed");
            own.insert(n[prefix.len()..].to_string(), x);
        }
        if i == 0 {
            for n in &fixture_inputs {
                own.extend(inputs.remove(n).map(|x| (n.clone(), x)));
            }
        }
        let BuiltSpec {
            file,
            encoding,
            spec,
            estimate,
            tool_radii,
            estimate_cell,
            library,
        } = spec_from_inputs(&opts, optimize, &mut own, limits, cancel)
            .map_err(|f| in_operation(f, i, &op.name))?;
        files.push(file);
        encodings.push(encoding);
        estimates.push((estimate, optimize));
        estimate_cells.push(estimate_cell);
        all_radii.extend(tool_radii);
        libraries.push(library);
        operations.push(Operation {
            name: op.name.clone(),
            spec,
            spindle: opts.spindle.clone(),
        });
    }
    // The cell the engine will take: the process's, else the finest default of all the
    // tools the operations cut with, however each was given.
    let cell = shared_cell.unwrap_or_else(|| geometry::default_cell(&all_radii));
    let mut checked = Vec::with_capacity(estimates.len());
    for (i, ((estimate, optimize), at)) in estimates.into_iter().zip(estimate_cells).enumerate() {
        checked.push(if at == cell {
            estimate
        } else {
            let op = &operations[i];
            check_spec(&files[i], &op.spec, optimize, Some(cell), limits, cancel)
                .map_err(|f| in_operation(f, i, &op.name))?
                .estimate
        });
    }
    let estimates = checked;
    let memory = process_estimate(&estimates, o.keep_stocks);
    if let Some((bytes, estimate)) = &memory {
        if *bytes > limits.memory_bytes {
            return Err(JobFailure::Invalid(over_memory_budget(
                format!(
                    "the process needs about {} MiB (its largest operation, the rows of the others{}), over the job memory budget of {} MiB (job_memory_mb); use a coarser cell_mm, fewer operations{}",
                    mib(*bytes),
                    if o.keep_stocks { " and the stocks kept" } else { "" },
                    limits.memory_mb(),
                    if o.keep_stocks { " or keep_stocks false" } else { "" },
                ),
                limits,
                *bytes,
                estimate.clone(),
            )));
        }
    }
    let process = ProcessSpec {
        stock: operations[0].spec.stock.clone(),
        cell: o.shared.get("cell_mm").and_then(Value::as_f64),
        fixture: operations[0].spec.fixture.clone(),
        operations,
    };
    // The stocks asked for are exported as each operation leaves them (one grid held).
    let mut kept: Vec<Result<Vec<u8>, String>> = Vec::new();
    let last = process.operations.len() - 1;
    let result = pipeline::run_process(&process, cancel, progress, &mut |i, stock| {
        if o.keep_stocks && i < last {
            kept.push(
                geometry::export_stl_vec(stock)
                    .map(|(stl, _)| stl)
                    .map_err(|e| e.to_string()),
            );
        }
    });
    let out = result.map_err(|e| match e {
        ProcessError::Cancelled => JobFailure::Cancelled,
        ProcessError::Operation {
            index,
            name,
            source,
        } => {
            let file = &files[index];
            let failure = match source {
                SimulateError::Cancelled => JobFailure::Cancelled,
                SimulateError::Program(d) => program_failure(cancel, file, &d),
                SimulateError::Spindle(e) => invalid("Invalid options", e.to_string()),
                other => invalid("Simulation refused", format!("{file}: {other}")),
            };
            in_operation(failure, index, &name)
        }
        other => invalid("Invalid process", other.to_string()),
    })?;
    output(
        &process,
        out,
        (&files, &encodings, libraries, memory.map(|(_, v)| v)),
        (o.keep_stocks, kept),
        limits,
        stock_file,
    )
}

/// A failure of operation `i`, its problem saying which.
fn in_operation(f: JobFailure, i: usize, name: &str) -> JobFailure {
    match f {
        JobFailure::Invalid(mut p) => {
            p.detail = format!("operation {} ({name}): {}", i + 1, p.detail);
            p.extensions.insert("operation".into(), json!(i + 1));
            JobFailure::Invalid(p)
        }
        other => other,
    }
}

type Reports<'a> = (
    &'a [String],
    &'a [crate::validate::TextEncoding],
    Vec<Option<crate::job_library::JobLibrary>>,
    Option<Value>,
);

/// The job's results: the summary with every operation's, the rows of all with their
/// `operation`, each operation's program, the final stock and the kept ones.
fn output(
    process: &ProcessSpec,
    mut out: pipeline::ProcessOutput,
    (files, encodings, libraries, memory): Reports,
    (keep_stocks, kept): (bool, Vec<Result<Vec<u8>, String>>),
    limits: &JobLimits,
    stock_file: Option<&std::path::Path>,
) -> Result<JobOutput, JobFailure> {
    let mut results = Vec::new();
    let mut summaries = Vec::new();
    for (i, (op, library)) in out.operations.iter_mut().zip(libraries).enumerate() {
        let file = &files[i];
        let tool_library = library.map(|library| {
            let (section, warnings) = library.report(&op.tool_numbers);
            op.summary.tool_warnings.extend(warnings);
            section
        });
        let mut s = serde_json::to_value(SimulateSummary {
            file,
            simulation: &op.summary,
            timings: &op.timings,
            stock_export_s: 0.0,
            dexel_updates: op.rays_tested,
            cycle_time_opt_s: op.optimization.as_ref().map(|o| o.cycle_time_after_s),
            force_peak_opt_n: op.optimization.as_ref().map(|o| o.peak_force_after),
            optimization: op.optimization.as_ref(),
            memory: None,
            tool_library,
            row_columns: Vec::new(),
        })
        .expect("summary serializes");
        super::simulate::place_collisions(&process.operations[i].spec, &mut s);
        let obj = s.as_object_mut().expect("an object");
        obj.remove("row_columns");
        obj.remove("stock_export_s");
        obj.insert("operation".into(), json!(i + 1));
        obj.insert("name".into(), json!(op.name));
        obj.insert("optimized".into(), json!(op.optimization.is_some()));
        obj.insert("stock_kept".into(), json!(keep_stocks));
        summaries.push(s);
        // Each operation's program: optimized (or at its chosen speed), else as given.
        let (stem, ext) = stem_and_ext(file);
        let text = op
            .optimized_program
            .take()
            .unwrap_or_else(|| process.operations[i].spec.program.clone());
        results.push(OutputFile {
            name: if i == 0 {
                "program".into()
            } else {
                format!("program.op{}", i + 1)
            },
            media_type: encodings[i].media_type(),
            file_name: format!(
                "{stem}.op{}{}{ext}",
                i + 1,
                if op.optimization.is_some() {
                    ".opt"
                } else {
                    ""
                }
            ),
            content: ArtifactContent::Bytes(encodings[i].encode(text)),
        });
    }
    for (i, stl) in kept.into_iter().enumerate() {
        let stl = stl.map_err(|e| {
            invalid(
                "Stock export failed",
                format!("after operation {}: {e}", i + 1),
            )
        })?;
        results.push(OutputFile {
            name: format!("stock.op{}.stl", i + 1),
            media_type: "model/stl",
            file_name: format!("stock.op{}.stl", i + 1),
            content: ArtifactContent::Bytes(stl),
        });
    }
    let clock = std::time::Instant::now();
    let final_stock = match stock_file {
        Some(path) => stream_stl(&out.stock, path).map(|len| ArtifactContent::File {
            path: path.to_path_buf(),
            len,
        }),
        None => geometry::export_stl_vec(&out.stock)
            .map(|(stl, _)| ArtifactContent::Bytes(stl))
            .map_err(|e| ExportError::Other(e.to_string())),
    }
    .map_err(ExportError::into_failure)?;
    let export_s = clock.elapsed().as_secs_f64();
    let (stem, _) = stem_and_ext(&files[files.len() - 1]);
    results.push(OutputFile {
        name: "stock.stl".into(),
        media_type: "model/stl",
        file_name: format!("{stem}.stock.stl"),
        content: final_stock,
    });

    // Rows of every operation; a column any operation's rows have is in every row.
    let counts: Vec<usize> = out.operations.iter().map(|op| op.rows.len()).collect();
    let all: Vec<pipeline::MoveRow> = out
        .operations
        .iter_mut()
        .flat_map(|op| std::mem::take(&mut op.rows))
        .collect();
    let row_json = pipeline::RowJson::new(&all);
    let mut rows = Vec::with_capacity(all.len());
    let mut samples = Vec::new();
    let mut seq = 0usize;
    for (i, op) in out.operations.iter().enumerate() {
        let name = serde_json::to_string(&op.name).expect("a name serializes");
        for k in 0..counts[i] {
            let json = row_json.to_json(&all[seq]);
            // The operation first, as the CSV's first columns.
            rows.push(format!(
                "{{\"operation\":{},\"operation_name\":{name},{}",
                i + 1,
                &json[1..]
            ));
            if let Some(s) = op.samples.get(k).filter(|s| !s.is_empty()) {
                samples.push((seq, serde_json::to_string(s).expect("samples serialize")));
            }
            seq += 1;
        }
    }
    let mut row_columns = vec!["operation".to_string(), "operation_name".to_string()];
    row_columns.extend(pipeline::row_columns(&all));

    let ops = &out.operations;
    let sum = |f: &dyn Fn(&pipeline::OperationOutput) -> f64| ops.iter().map(f).sum::<f64>();
    let cycle_before = sum(&|o| o.summary.cycle_time_s);
    let cycle_after = sum(&|o| {
        o.optimization
            .as_ref()
            .map_or(o.summary.cycle_time_s, |x| x.cycle_time_after_s)
    });
    let summary = json!({
        "operations": summaries,
        "operation_count": ops.len(),
        "cell_mm": out.cell,
        "stock_volume_before": ops[0].summary.stock_volume_before,
        "stock_volume_after": ops[ops.len() - 1].summary.stock_volume_after,
        "removed_volume_mm3": sum(&|o| o.summary.removed_volume),
        "cycle_time_s": cycle_before,
        "cycle_time_opt_s": cycle_after,
        "force_peak_n": ops.iter().map(|o| o.summary.peak_force).fold(0.0, f64::max),
        "moves": all.len(),
        "keep_stocks": keep_stocks,
        "grid_s": out.grid_s,
        "stock_export_s": export_s,
        "memory": memory.map(|m| json!({
            "budget_mb": limits.memory_mb(),
            "estimate_mb": m["peak_bytes"].as_u64().unwrap_or(0).div_ceil(1 << 20),
            "estimate": m,
        })),
        "row_columns": row_columns,
    });
    Ok(JobOutput {
        summary,
        rows,
        samples,
        files: results,
        resources: Vec::new(),
    })
}
