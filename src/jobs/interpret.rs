//! The `interpret` job: a program (G-code or APT/CLS) read into moves, one row per move.

use serde::Deserialize;
use serde_json::{json, Value};

use millsim_engine::job::{CancelFlag, Progress};
use millsim_engine::nc;

use super::inputs::{json_input, program_failure, program_text};
use super::{input, InputSpec, JobFailure, JobOutput, LoadedInputs};
use crate::job_budget::KindEstimate;
use crate::problem::Problem;
use crate::store::ResourceKind;

pub const INPUTS: [InputSpec; 1] = [input("program", ResourceKind::Program, true)];

/// The program options: of an `interpret` job, and (the same fields) of every job and
/// command that reads an NC program (`simulate`, `optimize`, `millsim interpret`, `run`).
#[derive(Debug, Default, Clone, Deserialize, serde::Serialize)]
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

pub fn default_dialect() -> nc::Dialect {
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

/// The options at submission: the tool table reads.
pub fn check(o: &InterpretOptions) -> Result<(), Problem> {
    o.engine_options().map_err(|d| {
        let first = d.0.first().map(|e| e.to_string()).unwrap_or_default();
        Problem::invalid_field("options.tool_table", format!("tool table: {first}"))
    })?;
    Ok(())
}

/// Bytes an interpret job holds per byte of program text: the parsed program and its
/// moves (`millsim interpret` on 500,000 random G1 lines, 9.4 MB: 286 MB peak RSS, 29 B
/// per byte) and the rows kept as JSON until they are stored (143 B a move, 7.6 B per
/// byte of such a program).
pub const INTERPRET_BYTES_PER_PROGRAM_BYTE: u64 = 40;

/// The memory of an interpret job of a program of `program_bytes` bytes: the program
/// parsed, its moves and their rows.
pub fn estimate(_: &InterpretOptions, program_bytes: u64) -> KindEstimate {
    KindEstimate::new(
        program_bytes.saturating_mul(INTERPRET_BYTES_PER_PROGRAM_BYTE),
        0,
        0,
    )
}

pub fn run(
    opts: &InterpretOptions,
    mut inputs: LoadedInputs,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<JobOutput, JobFailure> {
    let (file, text) = program_text(&mut inputs)?;
    let mut engine_opts = opts
        .engine_options()
        .map_err(|d| JobFailure::Invalid(Problem::program_failed("tool_table", &d)))?;
    engine_opts.cancel = Some(cancel.clone());
    // The job's tools by number, else its header comments' tools: the radius cutter
    // compensation takes where the program's tool table and G10 give none, as a simulate
    // job's.
    let numbered: Vec<(String, u32)> = inputs
        .keys()
        .filter_map(|k| Some((k.clone(), super::JobKind::Interpret.tool_number_input(k)?)))
        .collect();
    for (name, number) in numbered {
        let tool: millsim_engine::tool::Tool =
            super::inputs::required(json_input(&mut inputs, &name, "Invalid tool")?, &name)?;
        engine_opts.tool_diameters.insert(number, tool.diameter);
    }
    millsim_engine::tool_library::add_header_diameters(&mut engine_opts.tool_diameters, &text);
    engine_opts.library = super::inputs::program_library(&mut inputs)?;
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
    // Rows differ (arcs carry a centre, dwells seconds): every row carries every column
    // of the job's rows, null where its move has none, so that a page and the CSV header
    // do not depend on which move came first. One pass for the columns, one for the rows.
    let mut columns: Vec<String> = Vec::new();
    for m in &result.moves {
        if let Value::Object(o) = serde_json::to_value(m).expect("moves serialize") {
            for k in o.keys() {
                if !columns.iter().any(|c| c == k) {
                    columns.push(k.clone());
                }
            }
        }
    }
    for (i, m) in result.moves.iter().enumerate() {
        let mut row = serde_json::to_value(m).expect("moves serialize");
        if let Value::Object(o) = &mut row {
            for c in &columns {
                if !o.contains_key(c) {
                    o.insert(c.clone(), Value::Null);
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
    // Rows of library moves carry `source_file`, an index into `library_files`.
    let warnings: Vec<Value> = result
        .warnings
        .iter()
        .map(|w| json!({"line": w.line, "column": w.col, "message": w.message}))
        .collect();
    Ok(JobOutput::rows(
        json!({ "file": file, "moves": result.moves.len(), "blocks": result.block_count, "warnings": warnings, "row_columns": columns, "library_files": result.library_files }),
        rows,
    ))
}
