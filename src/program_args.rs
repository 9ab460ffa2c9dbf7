//! The program options every command that reads an NC program takes (`interpret`, `run`,
//! `process`; `post` reads APT/CLS, which they do not concern),
//! defined once: the same set the jobs take ([`jobs::InterpretOptions`]), so a program that
//! runs offline runs the same way through the service.

use std::path::PathBuf;

use clap::ValueEnum;
use millsim_engine::nc;
use serde_json::{json, Map, Value};

use crate::jobs;

#[derive(Clone, Copy, ValueEnum)]
pub enum DialectArg {
    Auto,
    Fanuc,
    Linuxcnc,
}

impl DialectArg {
    fn dialect(self) -> nc::Dialect {
        match self {
            DialectArg::Auto => nc::Dialect::Auto,
            DialectArg::Fanuc => nc::Dialect::Fanuc,
            DialectArg::Linuxcnc => nc::Dialect::LinuxCnc,
        }
    }
}

#[derive(clap::Args)]
pub struct ProgramArgs {
    #[arg(long, value_enum, default_value = "auto")]
    pub dialect: DialectArg,
    /// LinuxCNC tool table for G43 tool lengths.
    #[arg(long)]
    pub tool_table: Option<PathBuf>,
    /// Fanuc: length words without a decimal point count in thousandths of a mm.
    #[arg(long)]
    pub fanuc_implied_decimal: bool,
    /// Fanuc parameter CCR: corner rounding R and chamfer C written without the comma.
    #[arg(long)]
    pub fanuc_corners_without_comma: bool,
    /// M codes that do not move the machine and may be skipped, e.g. --passthrough-m 428,429.
    #[arg(long, value_delimiter = ',')]
    pub passthrough_m: Vec<u32>,
    /// Skip blocks that start with `/` (block-delete switch on).
    #[arg(long)]
    pub block_delete: bool,
    /// Refuse M codes the interpreter does not know instead of running them as no-ops
    /// with a warning.
    #[arg(long)]
    pub strict_m_codes: bool,
    /// Folder of the programs that calls to programs not in the file run (`M98 P1000`:
    /// `O1000.nc`; `o<name> call`: `name.ngc`).
    #[arg(long, value_name = "DIR")]
    pub library: Option<PathBuf>,
}

impl ProgramArgs {
    /// The options as a job takes them (the tool table read from its file).
    pub fn job_options(&self) -> Result<jobs::InterpretOptions, String> {
        let tool_table = match &self.tool_table {
            Some(path) => Some(
                std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?,
            ),
            None => None,
        };
        Ok(jobs::InterpretOptions {
            dialect: self.dialect.dialect(),
            fanuc_implied_decimal: self.fanuc_implied_decimal,
            fanuc_corners_without_comma: self.fanuc_corners_without_comma,
            passthrough_m_codes: self.passthrough_m.clone(),
            block_delete: self.block_delete,
            strict_m_codes: self.strict_m_codes,
            tool_table,
        })
    }

    /// The same options as fields of a job's options object (what `run` submits).
    pub fn insert_into(&self, options: &mut Map<String, Value>) -> Result<(), String> {
        let o = self.job_options()?;
        let fields = serde_json::to_value(&o).map_err(|e| e.to_string())?;
        if let Value::Object(m) = fields {
            for (k, v) in m {
                // Defaults stay out: the document reads as the user wrote the command.
                if !matches!(&v, Value::Bool(false) | Value::Null)
                    && v != json!([])
                    && !(k == "dialect" && v == json!("auto"))
                {
                    options.insert(k, v);
                }
            }
        }
        Ok(())
    }
}
