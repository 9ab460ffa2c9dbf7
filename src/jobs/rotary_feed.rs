//! The `rotary-feed` job: rotary-axis feed correction of a G-code program (F words
//! rewritten so the tool tip moves at the programmed feed), or an APT/CLS file posted to
//! G-code for the machine with corrected feeds.

use serde::Deserialize;
use serde_json::json;

use millsim_engine::machine::rotary_feed::{
    correct_program, FeedOutput, RotaryFeedError, RotaryFeedOptions,
};
use millsim_engine::machine::Machine;
use millsim_engine::nc;

use super::inputs::{invalid, json_input, program_text_encoded, required, stem_and_ext};
use super::interpret::{default_dialect, INTERPRET_BYTES_PER_PROGRAM_BYTE};
use super::{input, InputSpec, JobFailure, JobOutput, LoadedInputs, OutputFile};
use crate::job_budget::KindEstimate;
use crate::problem::Problem;
use crate::store::artifacts::ArtifactContent;
use crate::store::ResourceKind;

pub const INPUTS: [InputSpec; 2] = [
    input("program", ResourceKind::Program, true),
    input("machine", ResourceKind::Machine, true),
];

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
            content: ArtifactContent::Bytes(p.text.clone().into_bytes()),
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
        resources: Vec::new(),
    })
}

/// Rotary-axis feed correction of a G-code program: F words rewritten so the tool tip moves
/// at the programmed feed; rows are the corrected feed per block.
pub fn run(opts: &RotaryFeedJobOptions, mut inputs: LoadedInputs) -> Result<JobOutput, JobFailure> {
    let (file, text, encoding) = program_text_encoded(&mut inputs)?;
    let machine: Machine = required(
        json_input(&mut inputs, "machine", "Invalid machine")?,
        "machine",
    )?;
    if crate::validate::looks_like_cls(&text) {
        return post_cls_job(&file, &text, &machine, opts);
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
            RotaryFeedError::Program(d) => JobFailure::Invalid(Problem::program_failed(&file, &d)),
            other => invalid("Rotary feed correction refused", format!("{file}: {other}")),
        })?;
    let rows: Vec<String> = report
        .blocks
        .iter()
        .map(|b| serde_json::to_string(b).expect("rows serialize"))
        .collect();
    let (stem, ext) = stem_and_ext(&file);
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
            media_type: encoding.media_type(),
            file_name: format!("{stem}.rotary{ext}"),
            content: ArtifactContent::Bytes(encoding.encode(corrected)),
        }],
        resources: Vec::new(),
    })
}

/// The options at submission: the decimals are in range.
pub fn check(o: &RotaryFeedJobOptions) -> Result<(), Problem> {
    if !(1..=9).contains(&o.decimals) {
        return Err(Problem::invalid_field(
            "options.decimals",
            format!("must be 1 to 9, got {}", o.decimals),
        ));
    }
    Ok(())
}

/// A rotary-feed job also holds the corrected program and its report.
pub const ROTARY_FEED_BYTES_PER_PROGRAM_BYTE: u64 = INTERPRET_BYTES_PER_PROGRAM_BYTE + 2;

/// The memory of a rotary-feed job of a program of `program_bytes` bytes: as an
/// interpret job's, and the corrected program and its report.
pub fn estimate(_: &RotaryFeedJobOptions, program_bytes: u64) -> KindEstimate {
    KindEstimate::new(
        program_bytes.saturating_mul(ROTARY_FEED_BYTES_PER_PROGRAM_BYTE),
        0,
        0,
    )
}
