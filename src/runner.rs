//! What each job kind does, on a blocking worker thread: the bridge from a stored job
//! spec and its loaded inputs to the engine, and from the engine's result to stored rows.

use serde::Deserialize;
use serde_json::{json, Value};

use millsim_engine::job::{CancelFlag, Progress};
use millsim_engine::nc;

/// Job kinds the API knows. Only the ones whose engine exists run; the others are refused
/// at submission with a clear "not supported yet".
pub const KNOWN_KINDS: [&str; 7] = ["interpret", "simulate", "optimize", "stability", "energy", "rotary-feed", "identify"];

pub fn is_supported(kind: &str) -> bool {
    kind == "interpret"
}

/// The inputs each kind needs, as (input name, resource kind).
pub fn required_inputs(kind: &str) -> &'static [(&'static str, crate::store::ResourceKind)] {
    match kind {
        "interpret" => &[("program", crate::store::ResourceKind::Program)],
        _ => &[],
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
}

fn default_dialect() -> nc::Dialect {
    nc::Dialect::Auto
}

impl InterpretOptions {
    pub fn engine_options(&self) -> Result<nc::InterpretOptions, nc::Diagnostics> {
        let mut o = nc::InterpretOptions { dialect: self.dialect, fanuc_implied_decimal: self.fanuc_implied_decimal, ..Default::default() };
        if let Some(t) = &self.tool_table {
            o.tool_table = nc::parse_tool_table(t)?;
        }
        Ok(o)
    }
}

/// Inputs a worker loaded from the database for one job.
pub struct LoadedInputs {
    pub program: Option<(String, String)>, // (file name, text)
}

/// The result of a job attempt that ran to the end.
pub struct JobOutput {
    pub summary: Value,
    pub rows: Vec<String>,
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

pub fn run(kind: &str, options: &Value, inputs: LoadedInputs, cancel: &CancelFlag, progress: &dyn Progress) -> Result<JobOutput, JobFailure> {
    match kind {
        "interpret" => interpret(options, inputs, cancel, progress),
        other => Err(JobFailure::Invalid(json!({
            "type": "https://millsim.dev/problems/not-supported",
            "title": "Not supported yet",
            "status": 422,
            "detail": format!("job kind `{other}` is not supported yet"),
        }))),
    }
}

fn interpret(options: &Value, inputs: LoadedInputs, cancel: &CancelFlag, progress: &dyn Progress) -> Result<JobOutput, JobFailure> {
    let (file, text) = inputs.program.ok_or_else(|| JobFailure::Invalid(json!({"title": "missing input `program`", "status": 422})))?;
    let opts: InterpretOptions = serde_json::from_value(options.clone()).map_err(|e| {
        JobFailure::Invalid(json!({"title": "Invalid options", "status": 422, "detail": e.to_string()}))
    })?;
    let engine_opts = opts.engine_options().map_err(|d| JobFailure::Invalid(diagnostics_problem("tool_table", &d)))?;
    let result = if crate::validate::looks_like_cls(&text) {
        millsim_engine::cl::read_cls(&text)
    } else {
        nc::interpret(&text, &engine_opts)
    }
    .map_err(|d| JobFailure::Invalid(diagnostics_problem(&file, &d)))?;
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
    let warnings: Vec<Value> =
        result.warnings.iter().map(|w| json!({"line": w.line, "column": w.col, "message": w.message})).collect();
    Ok(JobOutput {
        summary: json!({ "file": file, "moves": result.moves.len(), "blocks": result.block_count, "warnings": warnings, "row_columns": columns }),
        rows,
    })
}
