//! Job kinds: one module per kind with its inputs, options and checks, and its run on a
//! blocking worker thread (the bridge from a stored job spec and its loaded inputs to the
//! engine, and from the engine's result to stored rows). [`JobKind`] is the one place
//! a kind's name is matched; the HTTP edge, the queue, the job process and the command
//! line all go through it.

mod accessibility;
mod csv_text;
mod energy;
mod identify;
mod identify_cuts;
mod identify_program;
mod inputs;
mod interpret;
mod process;
mod rotary_feed;
mod simulate;
pub(crate) mod stability;

use std::collections::BTreeMap;
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use millsim_engine::geometry::{Mesh, StlError, StlRepairs};
use millsim_engine::job::{CancelFlag, Progress};
use millsim_engine::pipeline::StlSource;

use crate::job_budget::{self, JobLimits, KindEstimate};
use crate::problem::{parse_options, Problem};
use crate::store::artifacts::ArtifactContent;
use crate::store::ResourceKind;

pub use accessibility::{analyze as accessibility_analyze, AccessibilityOptions};
pub use interpret::InterpretOptions;
pub use simulate::{check_tool_inputs, SimulateOptions};

/// A kind of job the API knows. Only the ones whose engine exists run; the others are
/// refused at submission with a clear "not supported yet".
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum JobKind {
    Interpret,
    Simulate,
    Optimize,
    Stability,
    Energy,
    RotaryFeed,
    Identify,
    Accessibility,
    Process,
}

impl JobKind {
    /// Every kind, in the order error messages list them.
    pub const ALL: [JobKind; 9] = [
        JobKind::Interpret,
        JobKind::Simulate,
        JobKind::Optimize,
        JobKind::Stability,
        JobKind::Energy,
        JobKind::RotaryFeed,
        JobKind::Identify,
        JobKind::Accessibility,
        JobKind::Process,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            JobKind::Interpret => "interpret",
            JobKind::Simulate => "simulate",
            JobKind::Optimize => "optimize",
            JobKind::Stability => "stability",
            JobKind::Energy => "energy",
            JobKind::RotaryFeed => "rotary-feed",
            JobKind::Identify => "identify",
            JobKind::Accessibility => "accessibility",
            JobKind::Process => "process",
        }
    }

    pub fn parse(name: &str) -> Option<JobKind> {
        JobKind::ALL.into_iter().find(|k| k.as_str() == name)
    }

    /// A kind named by a client, or a problem naming `field` and listing the kinds.
    pub fn from_request(name: &str, field: &str) -> Result<JobKind, Problem> {
        JobKind::parse(name).ok_or_else(|| {
            let names: Vec<&str> = JobKind::ALL.iter().map(|k| k.as_str()).collect();
            Problem::invalid_field(
                field,
                format!("unknown job kind `{name}`; one of: {}", names.join(", ")),
            )
        })
    }

    /// The inputs this kind takes by name (besides per-number tools, see
    /// [`tool_number_input`](Self::tool_number_input)).
    pub fn inputs(self) -> &'static [InputSpec] {
        match self {
            JobKind::Energy => &energy::INPUTS,
            JobKind::Interpret => &interpret::INPUTS,
            JobKind::RotaryFeed => &rotary_feed::INPUTS,
            JobKind::Simulate | JobKind::Optimize => &simulate::INPUTS,
            JobKind::Identify => &identify::INPUTS,
            JobKind::Accessibility => &accessibility::INPUTS,
            JobKind::Process => &process::INPUTS,
            JobKind::Stability => &[],
        }
    }

    /// For `simulate`, `optimize` and `interpret`: an input named `T<n>` (n in 1..=9999) is
    /// the tool for tool number n of the program (for `interpret`, the radius cutter
    /// compensation takes for D or T number n when the program's tool table gives none).
    pub fn tool_number_input(self, name: &str) -> Option<u32> {
        match self {
            JobKind::Simulate | JobKind::Optimize | JobKind::Interpret => {
                simulate::tool_number(name)
            }
            _ => None,
        }
    }

    /// For `interpret`, `simulate` and `optimize`: an input named `library/<file name>` is a
    /// program of the program library, which calls to programs not in the job's program
    /// run (`M98 P1000` runs `library/O1000.nc`; see `nc::ProgramLibrary`).
    pub fn library_input(self, name: &str) -> bool {
        matches!(
            self,
            JobKind::Interpret | JobKind::Simulate | JobKind::Optimize
        ) && inputs::library_file_name(name).is_some()
    }

    /// An input a request names beyond the kind's fixed ones: a per-number tool, a
    /// library program, or a fixture body's STL (`fixture/<name>`, a stock resource), with
    /// its resource kind.
    pub fn named_input(self, name: &str) -> Option<ResourceKind> {
        if self == JobKind::Process {
            return process::named_input(name);
        }
        if self.tool_number_input(name).is_some() {
            Some(ResourceKind::Tool)
        } else if self.library_input(name) {
            Some(ResourceKind::Program)
        } else if matches!(self, JobKind::Simulate | JobKind::Optimize)
            && simulate::fixture_input(name)
        {
            Some(ResourceKind::Stock)
        } else {
            None
        }
    }

    /// The inputs a request names, each with its resource kind and whether it must be
    /// given: the kind's fixed inputs, then any per-number tools. An input the kind does
    /// not take is refused, naming it.
    pub fn wanted_inputs<'a>(
        self,
        given: impl Iterator<Item = &'a String> + Clone,
    ) -> Result<Vec<(&'a str, ResourceKind, bool)>, Problem> {
        let specs = self.inputs();
        for name in given.clone() {
            if !specs.iter().any(|s| s.name == name) && self.named_input(name).is_none() {
                return Err(Problem::invalid_field(
                    self.input_field(name),
                    format!("a `{}` job takes no input `{name}`", self.as_str()),
                ));
            }
        }
        let mut wanted: Vec<(&str, ResourceKind, bool)> =
            specs.iter().map(|s| (s.name, s.kind, s.required)).collect();
        wanted.extend(given.filter_map(|n| self.named_input(n).map(|k| (n.as_str(), k, true))));
        Ok(wanted)
    }

    /// The request's field of a stored input name (`inputs.T1`; a process operation's
    /// `op2.program` is `inputs.operations[1].program`).
    pub fn input_field(self, name: &str) -> String {
        match self {
            JobKind::Process => process::input_field(name),
            _ => format!("inputs.{name}"),
        }
    }

    /// For `process`: the request's `inputs.operations` flattened as the job stores them
    /// (see `jobs::process`), the operations' names and options returned for
    /// `options.operations`.
    pub fn flatten_operations(
        self,
        inputs: &mut serde_json::Map<String, Value>,
    ) -> Result<Option<Vec<Value>>, Problem> {
        match self {
            JobKind::Process => process::flatten_operations(inputs)
                .map(Some)
                .map_err(FieldError::into_problem),
            _ => Ok(None),
        }
    }

    /// What can be checked before the job runs, once its inputs are known to exist: how
    /// the tools are named and the options, read once into the job's [`JobOptions`].
    /// Names the field on error.
    pub fn check<'a>(
        self,
        input_names: impl Iterator<Item = &'a String> + Clone,
        options: &Value,
    ) -> Result<JobOptions, Problem> {
        // How a simulation names its tools is checked before its options are read.
        if matches!(self, JobKind::Simulate | JobKind::Optimize) {
            check_tool_inputs(self, input_names.clone()).map_err(FieldError::into_problem)?;
        }
        let spec = JobOptions::parse(self, options, input_names.clone())?;
        spec.check(input_names)?;
        Ok(spec)
    }

    /// Everything a submission checks once its inputs are resolved, in order: [`check`]
    /// (how the tools are named, the options), what the kind checks against its stored
    /// inputs (an accessibility job's part), and the job memory budget. Names the field
    /// (or the budget) on error.
    ///
    /// [`check`]: Self::check
    pub fn check_submission<'a>(
        self,
        input_names: impl Iterator<Item = &'a String> + Clone,
        options: &Value,
        inputs: &SubmittedInputs,
        limits: &JobLimits,
    ) -> Result<(), Problem> {
        let spec = self.check(input_names, options)?;
        if let JobOptions::Accessibility(o) = &spec {
            accessibility::check_part(o, inputs)?;
        }
        spec.check_memory_budget(inputs, limits)
    }

    /// Runs the job. With `stock_file`, the machined stock of a simulate or optimize job is
    /// streamed into that file (a file the size of the stock's surface is then never held
    /// in memory) instead of being returned among the output files.
    pub fn run(
        self,
        options: &Value,
        inputs: LoadedInputs,
        limits: &JobLimits,
        cancel: &CancelFlag,
        progress: &dyn Progress,
        stock_file: Option<&std::path::Path>,
    ) -> Result<JobOutput, JobFailure> {
        // The stored options, read as at submission.
        let spec = match JobOptions::parse(self, options, inputs.keys()) {
            Ok(spec) => spec,
            // An identify job's options are refused as at submission.
            Err(problem) if self == JobKind::Identify => return Err(JobFailure::Invalid(problem)),
            Err(problem) => {
                let field = problem.extensions.get("field").and_then(Value::as_str);
                let detail = match (self, field) {
                    // These kinds' readers name the field as `field: message`.
                    (JobKind::Energy | JobKind::Stability | JobKind::Process, Some(field)) => {
                        format!("{field}: {}", problem.detail)
                    }
                    _ => problem.detail,
                };
                return Err(inputs::invalid("Invalid options", detail));
            }
        };
        match spec {
            JobOptions::Interpret(o) => interpret::run(&o, inputs, cancel, progress),
            JobOptions::Simulate(o) | JobOptions::Optimize(o) => simulate::run(
                self == JobKind::Optimize,
                &o,
                inputs,
                limits,
                cancel,
                progress,
                stock_file,
            ),
            JobOptions::Stability(o) => stability::run(*o, cancel, progress),
            JobOptions::RotaryFeed(o) => rotary_feed::run(&o, inputs),
            JobOptions::Energy(o) => energy::run(*o, inputs, cancel),
            JobOptions::Identify(o) => identify::run(o, options, inputs, limits, cancel, progress),
            JobOptions::Accessibility(o) => accessibility::run(&o, inputs, cancel),
            JobOptions::Process(o) => process::run(o, inputs, limits, cancel, progress, stock_file),
        }
    }
}

/// A job's options, typed by kind: read once at submission from the kind and the
/// request's `options` (which the job stores as given, that JSON unchanged), with the
/// problems a submission is told (the field named).
pub enum JobOptions {
    Interpret(InterpretOptions),
    Simulate(SimulateOptions),
    Optimize(SimulateOptions),
    Stability(Box<stability::StabilityRequest>),
    Energy(Box<energy::EnergyOptions>),
    RotaryFeed(rotary_feed::RotaryFeedJobOptions),
    Identify(identify::IdentifyOptions),
    Accessibility(AccessibilityOptions),
    Process(process::ProcessOptions),
}

impl JobOptions {
    /// The options of a `kind` job read (an energy job's `material` option is read
    /// against whether a `material` input is given). Names the field on error.
    pub fn parse<'a>(
        kind: JobKind,
        options: &Value,
        mut input_names: impl Iterator<Item = &'a String>,
    ) -> Result<JobOptions, Problem> {
        Ok(match kind {
            JobKind::Interpret => JobOptions::Interpret(parse_options(options)?),
            JobKind::Simulate => JobOptions::Simulate(parse_options(options)?),
            JobKind::Optimize => JobOptions::Optimize(parse_options(options)?),
            JobKind::Stability => JobOptions::Stability(Box::new(
                stability::options(options).map_err(FieldError::into_problem)?,
            )),
            JobKind::Energy => {
                let has_material_input = input_names.any(|n| n == "material");
                JobOptions::Energy(Box::new(
                    energy::options(options, has_material_input)
                        .map_err(FieldError::into_problem)?,
                ))
            }
            JobKind::RotaryFeed => JobOptions::RotaryFeed(parse_options(options)?),
            JobKind::Identify => JobOptions::Identify(parse_options(options)?),
            JobKind::Accessibility => JobOptions::Accessibility(parse_options(options)?),
            JobKind::Process => JobOptions::Process(
                process::stored_options(options).map_err(FieldError::into_problem)?,
            ),
        })
    }

    /// The options' checks beyond reading them, and those against the inputs' names.
    /// Names the field on error.
    pub fn check<'a>(
        &self,
        input_names: impl Iterator<Item = &'a String> + Clone,
    ) -> Result<(), Problem> {
        let has_material_input = input_names.clone().any(|n| n == "material");
        match self {
            JobOptions::Interpret(o) => interpret::check(o),
            JobOptions::RotaryFeed(o) => rotary_feed::check(o),
            // Reading these checked them whole.
            JobOptions::Energy(_) | JobOptions::Stability(_) => Ok(()),
            JobOptions::Simulate(o) | JobOptions::Optimize(o) => {
                let optimize = matches!(self, JobOptions::Optimize(_));
                o.check(optimize, has_material_input)
                    .map_err(FieldError::into_problem)?;
                simulate::check_fixture_inputs(o, input_names).map_err(FieldError::into_problem)
            }
            JobOptions::Identify(o) => identify::check(o),
            JobOptions::Accessibility(o) => accessibility::check(o),
            JobOptions::Process(o) => {
                process::check(input_names, o).map_err(FieldError::into_problem)
            }
        }
    }

    /// The kind these options are of.
    pub fn kind(&self) -> JobKind {
        match self {
            JobOptions::Interpret(_) => JobKind::Interpret,
            JobOptions::Simulate(_) => JobKind::Simulate,
            JobOptions::Optimize(_) => JobKind::Optimize,
            JobOptions::Stability(_) => JobKind::Stability,
            JobOptions::Energy(_) => JobKind::Energy,
            JobOptions::RotaryFeed(_) => JobKind::RotaryFeed,
            JobOptions::Identify(_) => JobKind::Identify,
            JobOptions::Accessibility(_) => JobKind::Accessibility,
            JobOptions::Process(_) => JobKind::Process,
        }
    }

    /// The memory estimate of a job with these options and a program of `program_bytes`
    /// bytes (an accessibility job: a part), by its kind's own `estimate`, when its kind
    /// is estimated from its options and the program's size (not simulate/optimize or
    /// process, checked by their grid, nor identify); `workers` lobe workers run at once
    /// (the job process's thread pool).
    pub fn estimate(&self, program_bytes: u64, workers: u64) -> Option<KindEstimate> {
        match self {
            JobOptions::Interpret(o) => Some(interpret::estimate(o, program_bytes)),
            JobOptions::RotaryFeed(o) => Some(rotary_feed::estimate(o, program_bytes)),
            JobOptions::Accessibility(o) => Some(accessibility::estimate(o, program_bytes)),
            JobOptions::Stability(o) => Some(stability::estimate(o, workers)),
            JobOptions::Energy(o) => Some(energy::estimate(o, workers)),
            JobOptions::Simulate(_)
            | JobOptions::Optimize(_)
            | JobOptions::Process(_)
            | JobOptions::Identify(_) => None,
        }
    }

    /// A job that cannot fit the job memory budget is refused at submission (422 naming
    /// the budget and the estimate) rather than failed later. A simulation (and a
    /// process) by its grid and stock export alone, what needs the program (step records,
    /// rows) being checked when the job runs; the other kinds by their [`estimate`] from
    /// their options and the size of their program (an accessibility job: of its part).
    ///
    /// [`estimate`]: Self::estimate
    pub fn check_memory_budget(
        &self,
        inputs: &SubmittedInputs,
        limits: &JobLimits,
    ) -> Result<(), Problem> {
        match self {
            JobOptions::Simulate(o) | JobOptions::Optimize(o) => {
                simulate::check_memory_budget(o, inputs, limits)
            }
            JobOptions::Process(o) => process::check_memory_budget(o, inputs, limits),
            _ => {
                // An accessibility job scales with its part (an STL), the others with the
                // program.
                let kind = self.kind();
                let input = if kind == JobKind::Accessibility {
                    "part"
                } else {
                    "program"
                };
                let program = inputs
                    .inline_program
                    .or(inputs.stored(input).map(|r| r.size));
                match self.estimate(program.unwrap_or(0), job_budget::lobe_workers()) {
                    Some(e) => job_budget::kinds::check(kind, &e, limits),
                    None => Ok(()),
                }
            }
        }
    }
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

/// A stored resource a submission names, as the submission checks see it.
#[derive(Clone, Debug)]
pub struct StoredInput {
    /// Bytes of its content.
    pub size: u64,
    /// What validation found (bounds, triangles, diameter, format, ...).
    pub summary: Value,
}

/// The inputs of a submission once resolved: the stored resources it names, by input
/// name in the request's order, and the size of an inline program.
#[derive(Clone, Debug, Default)]
pub struct SubmittedInputs {
    pub stored: Vec<(String, StoredInput)>,
    pub inline_program: Option<u64>,
}

impl SubmittedInputs {
    /// The stored resource given as input `name`.
    pub fn stored(&self, name: &str) -> Option<&StoredInput> {
        self.stored.iter().find(|(n, _)| n == name).map(|(_, r)| r)
    }
}

/// A value a check refused: the field (a JSON path under the request) and why.
#[derive(Debug)]
pub struct FieldError {
    pub field: String,
    pub message: String,
}

impl FieldError {
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        FieldError {
            field: field.into(),
            message: message.into(),
        }
    }

    /// At submission: a 422 naming the field.
    pub fn into_problem(self) -> Problem {
        Problem::invalid_field(self.field, self.message)
    }
}

impl std::fmt::Display for FieldError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.message)
    }
}

/// A stored input as a worker loaded it.
#[derive(Default)]
pub struct LoadedInput {
    pub file_name: Option<String>,
    pub media_type: String,
    /// The bytes, unless one of the two below says where they are instead (then empty).
    pub content: Vec<u8>,
    /// In the worker: a large input left in the database, sent to the job's process a
    /// chunk at a time.
    pub stored_chunks: Option<StoredChunks>,
    /// In the job's process: an STL input read into a mesh as it streamed in (or why it
    /// could not be), so its bytes were never whole in memory.
    pub mesh: Option<Result<(Arc<Mesh>, StlRepairs), StlError>>,
}

/// Where a chunked resource's content is (`store::chunks`).
#[derive(Clone, Debug)]
pub struct StoredChunks {
    pub resource_id: String,
    pub chunks: i64,
    pub size: u64,
}

impl LoadedInput {
    /// An STL input as the pipeline takes it: the mesh read as it streamed in, or the
    /// bytes to read.
    pub fn stl(self) -> Result<StlSource, StlError> {
        match self.mesh {
            Some(mesh) => mesh.map(|(mesh, repairs)| StlSource::Mesh(mesh, repairs)),
            None => Ok(StlSource::Bytes(self.content)),
        }
    }
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
    /// In memory, or a file the job wrote in its directory (the stock STL of a job given
    /// one: see `JobKind::run`'s `stock_file`).
    pub content: ArtifactContent,
}

/// A resource a job makes (an identified material), stored with the job's success and
/// then listed with the owner's other resources. Its id is chosen by the job, so the
/// summary can name it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct OutputResource {
    pub id: String,
    pub kind: ResourceKind,
    pub name: String,
    pub media_type: String,
    pub summary: Value,
    pub content: Vec<u8>,
}

impl OutputResource {
    pub fn new(kind: ResourceKind, name: &str, content: Vec<u8>, summary: Value) -> Self {
        OutputResource {
            id: crate::store::new_id(),
            kind,
            name: name.to_string(),
            media_type: "application/json".into(),
            summary,
            content,
        }
    }
}

/// The result of a job attempt that ran to the end.
pub struct JobOutput {
    pub summary: Value,
    pub rows: Vec<String>,
    /// Per-step samples as (row seq, JSON array), for rows that have any.
    pub samples: Vec<(usize, String)>,
    pub files: Vec<OutputFile>,
    pub resources: Vec<OutputResource>,
}

impl JobOutput {
    /// A summary and rows, no samples or files.
    fn rows(summary: Value, rows: Vec<String>) -> JobOutput {
        JobOutput {
            summary,
            rows,
            samples: Vec::new(),
            files: Vec::new(),
            resources: Vec::new(),
        }
    }
}

/// Why a job attempt ended without output.
#[derive(Debug)]
pub enum JobFailure {
    /// The inputs are wrong; running again will not help. The problem says why.
    Invalid(Problem),
    Cancelled,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_reads_back_from_its_name_and_its_json() {
        for k in JobKind::ALL {
            assert_eq!(JobKind::parse(k.as_str()), Some(k));
            let json = serde_json::to_value(k).unwrap();
            assert_eq!(json, Value::String(k.as_str().into()));
        }
        assert_eq!(JobKind::parse("teleport"), None);
    }

    #[test]
    fn resource_kinds_serialize_as_their_names() {
        for k in ResourceKind::ALL {
            let json = serde_json::to_value(k).unwrap();
            assert_eq!(json, Value::String(k.as_str().into()));
            assert_eq!(serde_json::from_value::<ResourceKind>(json).unwrap(), k);
        }
    }
}
