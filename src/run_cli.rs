//! `millsim run`: a simulate job offline, for a CAM workstation. Same job code as the
//! service's workers; writes summary.json, blocks.csv and stock.stl into --out.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use serde_json::{json, Map, Value};

use millsim_engine::job::{CancelFlag, Progress};

use crate::csv;
use crate::jobs::{JobFailure, JobKind, LoadedInput, LoadedInputs};
use crate::problem::Problem;
use crate::store::artifacts::ArtifactContent;
use crate::store::ResourceKind;

#[derive(clap::Args)]
pub struct RunArgs {
    /// Stock as an STL file, or a JSON parametric stock (`{"kind":"cylinder",...}`).
    #[arg(long, conflicts_with = "block", required_unless_present = "block")]
    stock: Option<PathBuf>,
    /// Stock as a block: X,Y,Z of the lowest corner and DX,DY,DZ sizes, mm (a corner
    /// below zero as written, `--block -10,-10,-20,80,80,20`).
    #[arg(long, value_name = "X,Y,Z,DX,DY,DZ", allow_hyphen_values = true)]
    block: Option<String>,
    /// The NC program.
    #[arg(long)]
    program: PathBuf,
    /// The design part (STL, in the stock's frame): the summary reports gouges and the
    /// allowance left.
    #[arg(long)]
    part: Option<PathBuf>,
    /// Clamps and vices in the part frame (JSON: {"bodies":[{"name":"clamp 1","kind":
    /// "block","min":[..],"max":[..]}, {"kind":"stl","path":"vice.stl"}, ...]}; STL paths
    /// relative to the file): every move is checked against them with the whole tool.
    #[arg(long, value_name = "FILE")]
    fixture: Option<PathBuf>,
    /// A tool, as `T1=tool.json` (the tool of T1) or `tool.json`; repeat for each tool
    /// number the program uses (JSON as POST /v1/tools takes it).
    #[arg(long)]
    tool: Vec<String>,
    /// A tool library (Fusion 360 JSON, LinuxCNC .tbl or CSV): the tool of each T number
    /// no --tool gives. Without --tool or a library, the program's header comments
    /// (`(T1 D=6 CR=0 - flat end mill)`) describe the tools, with a warning per assumption.
    #[arg(long, value_name = "FILE")]
    tool_library: Option<PathBuf>,
    /// A built-in material name (TC6, Al7075-T6, Al6082-T6) or a material JSON file.
    #[arg(long)]
    material: String,
    /// Dexel spacing (grid resolution), mm (default: smallest tool radius / 20 within
    /// [0.02, 0.5]).
    #[arg(long, alias = "cell")]
    resolution: Option<f64>,
    /// Machine definition (JSON, as POST /v1/machines takes it) for the cycle time;
    /// default: a generic 3-axis machine.
    #[arg(long)]
    machine: Option<PathBuf>,
    /// Optimize the feeds: comma-separated limits, e.g. max_force=800,air_feed=5000,feed_step=10
    /// (any field of the job's options.limits; split_max_parts=4, split_min_length=2 and
    /// split_min_saving=0.05 split long moves whose engagement varies; tool_guards=false
    /// switches off every tool's default chip and force guards). Writes the rewritten
    /// program too.
    #[arg(long)]
    optimize: Option<String>,
    /// A tool's own limits, winning over --optimize's for its moves, e.g.
    /// `T2:max_force=120,max_feed=2000` or `T2:tool_guards=false` (repeat per tool; the
    /// job's limits.tools).
    #[arg(long, value_name = "T<n>:NAME=VALUE,...", requires = "optimize")]
    optimize_tool: Vec<String>,
    /// On a machine with rotary axes: `machine` (X..C are machine axes) or `tool_tip`
    /// (tool-centre-point control: X Y Z are the tool tip in the part frame).
    #[arg(long, default_value = "machine")]
    axes: String,
    /// Choose the spindle speed out of chatter: the job's options.spindle as a JSON file or
    /// inline JSON, e.g. `{"rpm":{"from":5000,"to":25000},"modes_x":[{"freq_hz":922,
    /// "damping":0.011,"mass_kg":0.03993}],"objective":"min_time"}`. Writes the program at
    /// the chosen speed (its feeds optimized with --optimize).
    #[arg(long, value_name = "FILE|JSON")]
    spindle: Option<String>,
    /// The program's options, as `millsim interpret` and the jobs take them.
    #[command(flatten)]
    program_options: crate::program_args::ProgramArgs,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

fn read(path: &Path) -> Result<Vec<u8>, String> {
    std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))
}

pub(crate) fn file_input(path: &Path, media_type: &str) -> Result<LoadedInput, String> {
    Ok(LoadedInput {
        file_name: path.file_name().map(|n| n.to_string_lossy().to_string()),
        media_type: media_type.into(),
        content: read(path)?,
        ..Default::default()
    })
}

/// A file read as a job input that is a resource of `kind`, checked as the service checks
/// an upload of that kind: a stock is an STL, or a parametric stock when the file is JSON;
/// a tool, a machine or a material JSON. Errors name the file (a check's: as `label`).
pub(crate) fn resource_input(
    path: &Path,
    label: &str,
    kind: ResourceKind,
) -> Result<LoadedInput, String> {
    let media = match kind {
        ResourceKind::Program | ResourceKind::ToolLibrary => "text/plain",
        ResourceKind::Stock => "model/stl",
        _ => "application/json",
    };
    let mut input = file_input(path, media)?;
    let check = match kind {
        ResourceKind::Stock if input.content.trim_ascii_start().starts_with(b"{") => {
            input.media_type = "application/json".into();
            crate::validate::stock_json(&input.content).map(|_| ())
        }
        ResourceKind::Stock => crate::validate::stl(&input.content, label).map(|_| ()),
        ResourceKind::Tool => crate::validate::tool(&input.content).map(|_| ()),
        ResourceKind::Machine => crate::validate::machine(&input.content).map(|_| ()),
        ResourceKind::Material => crate::validate::material(&input.content).map(|_| ()),
        _ => Ok(()),
    };
    check.map_err(|e| format!("{label}: {}", e.detail))?;
    Ok(input)
}

/// A problem of a job's checks as the commands print it: `field: detail`.
pub(crate) fn field_message(p: &Problem) -> String {
    let field = p
        .extensions
        .get("field")
        .and_then(Value::as_str)
        .unwrap_or("");
    format!("{field}: {}", p.detail)
}

/// The options' fields `millsim run` fills in from a flag, most specific first.
const FIELD_FLAGS: [(&str, &str); 9] = [
    ("options.limits.tools", "--optimize-tool"),
    ("options.limits", "--optimize"),
    ("options.spindle", "--spindle"),
    ("options.axes", "--axes"),
    ("options.cell_mm", "--resolution"),
    ("options.material", "--material"),
    ("options.fixture", "--fixture"),
    ("inputs.tool", "--tool"),
    ("inputs.T", "--tool"),
];

/// A check's problem as `millsim run` says it: the flag that gave the field, then the field
/// and what is wrong. The options are JSON this command wrote, so a position in them
/// (serde's "at line 1 column 62") would point at nothing the user wrote: it is left out.
fn run_message(p: &Problem) -> String {
    let field = p
        .extensions
        .get("field")
        .and_then(Value::as_str)
        .unwrap_or("");
    let detail = match p.detail.rfind(" at line ") {
        Some(i) if p.detail[i..].contains(" column ") => &p.detail[..i],
        _ => p.detail.as_str(),
    };
    let flag = FIELD_FLAGS.iter().find_map(|(prefix, flag)| {
        let rest = field.strip_prefix(prefix)?;
        (rest.is_empty() || rest.starts_with(['.', '[']) || prefix.ends_with(".T")).then_some(*flag)
    });
    match flag {
        Some(flag) => format!("{flag} ({field}): {detail}"),
        None => format!("{field}: {detail}"),
    }
}

/// Progress on stderr: a bar redrawn in place on a terminal (each whole percent), a line
/// every 10% otherwise (logs, CI).
pub(crate) struct StderrProgress {
    /// Last step shown, plus one (0: nothing shown yet).
    shown: AtomicU64,
    terminal: bool,
    /// The command, and what the progress counts.
    command: &'static str,
    unit: &'static str,
}

impl StderrProgress {
    pub(crate) fn new(command: &'static str, unit: &'static str) -> Self {
        use std::io::IsTerminal;
        StderrProgress {
            shown: AtomicU64::new(0),
            terminal: std::io::stderr().is_terminal(),
            command,
            unit,
        }
    }

    /// Ends the bar's line.
    pub(crate) fn finish(&self) {
        if self.terminal && self.shown.load(Ordering::Relaxed) > 0 {
            eprintln!();
        }
    }
}

impl Progress for StderrProgress {
    fn report(&self, done: u64, total: u64) {
        if total == 0 {
            return;
        }
        let done = done.min(total);
        let (step, steps) = if self.terminal {
            (done * 100 / total, 100)
        } else {
            (done * 10 / total, 10)
        };
        if self.shown.fetch_max(step + 1, Ordering::Relaxed) > step {
            return;
        }
        let percent = step * 100 / steps;
        if self.terminal {
            let filled = (percent / 4) as usize;
            eprint!(
                "\r{}: [{}{}] {percent:3}% ({done}/{total} {})",
                self.command,
                "#".repeat(filled),
                " ".repeat(25 - filled),
                self.unit
            );
        } else {
            eprintln!(
                "{}: {percent}% ({done}/{total} {})",
                self.command, self.unit
            );
        }
    }
}

pub fn run(args: RunArgs) -> Result<(), String> {
    let mut inputs = LoadedInputs::new();
    inputs.insert("program".into(), file_input(&args.program, "text/plain")?);
    inputs.insert("stock".into(), stock_input(&args)?);
    if let Some(dir) = &args.program_options.library {
        let library = millsim_engine::nc::ProgramLibrary::from_dir(dir)
            .map_err(|e| format!("--library {e}"))?;
        for f in library.files() {
            inputs.insert(
                format!("library/{}", f.name),
                LoadedInput {
                    file_name: Some(f.name.clone()),
                    media_type: "text/plain".into(),
                    content: f.text.clone().into_bytes(),
                    ..Default::default()
                },
            );
        }
    }
    tool_inputs(&args, &mut inputs)?;
    let mut options = Map::new();
    if let Some(path) = &args.part {
        let part = file_input(path, "model/stl")?;
        crate::validate::stl(&part.content, &path.display().to_string())
            .map_err(|e| format!("{}: {}", path.display(), e.detail))?;
        inputs.insert("part".into(), part);
    }
    if let Some(path) = &args.fixture {
        options.insert("fixture".into(), fixture_document(path, &mut inputs)?);
    }
    if let Some(path) = &args.machine {
        let label = path.display().to_string();
        let machine = resource_input(path, &label, ResourceKind::Machine)?;
        inputs.insert("machine".into(), machine);
    }
    if Path::new(&args.material).is_file() {
        let material = resource_input(
            Path::new(&args.material),
            &args.material,
            ResourceKind::Material,
        )?;
        inputs.insert("material".into(), material);
    } else {
        options.insert("material".into(), Value::String(args.material.clone()));
    }
    options.insert("axes".into(), Value::String(args.axes.clone()));
    args.program_options.insert_into(&mut options)?;
    if let Some(c) = args.resolution {
        options.insert("cell_mm".into(), json!(c));
    }
    if let Some(spec) = &args.optimize {
        options.insert("limits".into(), optimize_limits(spec, &args.optimize_tool)?);
    }
    if let Some(spindle) = &args.spindle {
        options.insert("spindle".into(), spindle_option(spindle)?);
    }
    let kind = if args.optimize.is_some() {
        JobKind::Optimize
    } else {
        JobKind::Simulate
    };
    let options = Value::Object(options);
    // As a submission checks the job: how the tools are named, the options read and
    // checked (by the kind's own reader).
    kind.check(inputs.keys(), &options)
        .map_err(|p| run_message(&p))?;

    run_offline(
        kind,
        &options,
        inputs,
        &args.out,
        ("millsim run", "moves"),
        run_report,
    )
}

/// The stock `--stock` (an STL, or a parametric stock when the file is JSON) or `--block`
/// gives, as the job's `stock` input.
fn stock_input(args: &RunArgs) -> Result<LoadedInput, String> {
    Ok(match (&args.stock, &args.block) {
        (Some(path), _) => {
            // A JSON file is a parametric stock ({"kind":"block"|"cylinder",...}).
            let mut stock = file_input(path, "model/stl")?;
            if stock.content.trim_ascii_start().starts_with(b"{") {
                crate::validate::stock_json(&stock.content)
                    .map_err(|e| format!("{}: {}", path.display(), e.detail))?;
                stock.media_type = "application/json".into();
            } else {
                // Checked first, so a refusal names this file (and where the mesh is
                // open) rather than the program the simulation was reading it for.
                crate::validate::stl(&stock.content, &path.display().to_string())
                    .map_err(|e| e.detail)?;
            }
            stock
        }
        (None, Some(spec)) => {
            let v: Vec<f64> = spec
                .split(',')
                .map(|s| {
                    s.trim()
                        .parse::<f64>()
                        .map_err(|_| format!("--block: `{s}` is not a number"))
                })
                .collect::<Result<_, _>>()?;
            let [x, y, z, dx, dy, dz] = v[..] else {
                return Err(format!(
                    "--block takes six numbers X,Y,Z,DX,DY,DZ, got {}",
                    v.len()
                ));
            };
            if !(dx > 0.0 && dy > 0.0 && dz > 0.0) {
                return Err("--block: DX, DY and DZ must be positive".into());
            }
            let shape = json!({"kind": "block", "min": [x, y, z], "max": [x + dx, y + dy, z + dz]});
            LoadedInput {
                file_name: None,
                media_type: "application/json".into(),
                content: shape.to_string().into_bytes(),
                ..Default::default()
            }
        }
        (None, None) => return Err("give --stock FILE.stl or --block X,Y,Z,DX,DY,DZ".into()),
    })
}

/// The tools `--tool` gives (`T3=file.json`, or one file for every tool number) and the
/// `--tool-library`, as the job's inputs; the library's notes on stderr.
fn tool_inputs(args: &RunArgs, inputs: &mut LoadedInputs) -> Result<(), String> {
    for spec in &args.tool {
        // `T3=file.json` is the tool of T3; a bare file serves every tool number.
        let (name, path) = match spec.split_once('=') {
            Some((t, p)) => {
                let name = t.trim().to_ascii_uppercase();
                if JobKind::Simulate.tool_number_input(&name).is_none() {
                    return Err(format!("--tool {spec}: `{t}` is not a tool number like T1"));
                }
                (name, p)
            }
            None => ("tool".to_string(), spec.as_str()),
        };
        if inputs.contains_key(&name) {
            return Err(format!("--tool: {name} is given twice"));
        }
        inputs.insert(
            name,
            resource_input(Path::new(path), path, ResourceKind::Tool)?,
        );
    }
    if let Some(path) = &args.tool_library {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let library = millsim_engine::tool_library::ToolLibrary::read(&text)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        for n in &library.report.unmodelled {
            eprintln!(
                "{}: {} {}: not modelled: {}",
                path.display(),
                n.tool,
                n.field,
                n.note
            );
        }
        for n in &library.report.assumed {
            eprintln!("{}: {} {}: {}", path.display(), n.tool, n.field, n.note);
        }
        // The runner gives each T number no --tool names its tool, as for a service job.
        inputs.insert(
            "tool_library".into(),
            LoadedInput {
                file_name: path.file_name().map(|n| n.to_string_lossy().to_string()),
                media_type: "text/plain".into(),
                content: text.into_bytes(),
                ..Default::default()
            },
        );
    }
    Ok(())
}

/// The job's `options.limits` of `--optimize`'s `NAME=VALUE,...` (`split_*` into
/// `split`, counts as integers) and each `--optimize-tool T<n>:NAME=VALUE,...`.
fn optimize_limits(spec: &str, tool_specs: &[String]) -> Result<Value, String> {
    let mut limits = Map::new();
    for (k, value) in name_values("--optimize", spec)? {
        // Counts (max_iterations) are integers in the options.
        let value = match value.as_f64() {
            Some(v) if v.fract() == 0.0 && v.abs() < 1e15 => json!(v as i64),
            _ => value,
        };
        // split_max_parts=4, split_min_length=2, split_min_saving=0.05: limits.split.
        match k.strip_prefix("split_") {
            Some(field) => {
                let split = limits.entry("split").or_insert_with(|| json!({}));
                split[field] = value;
            }
            None => {
                limits.insert(k, value);
            }
        }
    }
    let mut tools = Map::new();
    for spec in tool_specs {
        let (tool, pairs) = spec
            .split_once(':')
            .ok_or_else(|| format!("--optimize-tool: `{spec}` is not T<n>:NAME=VALUE,..."))?;
        let own: Map<String, Value> = name_values(&format!("--optimize-tool {tool}"), pairs)?
            .into_iter()
            .collect();
        tools.insert(tool.trim().to_ascii_uppercase(), Value::Object(own));
    }
    if !tools.is_empty() {
        limits.insert("tools".into(), Value::Object(tools));
    }
    Ok(Value::Object(limits))
}

/// The job's `options.spindle` of `--spindle`: inline JSON, or the file it names.
fn spindle_option(spindle: &str) -> Result<Value, String> {
    let text = if spindle.trim_start().starts_with('{') {
        spindle.to_string()
    } else {
        String::from_utf8(read(Path::new(spindle))?).map_err(|e| format!("{spindle}: {e}"))?
    };
    serde_json::from_str(&text).map_err(|e| format!("--spindle: {e}"))
}

/// Runs a job offline, its stock streamed straight to `out/stock.stl` (at fine cells it is
/// the largest output) and its other results written there; `command` shows its progress
/// on stderr, counted in `unit` (see [`StderrProgress`]), then `report`'s lines of the
/// summary and how many moves in how long.
pub(crate) fn run_offline(
    kind: JobKind,
    options: &Value,
    inputs: LoadedInputs,
    out: &Path,
    (command, unit): (&'static str, &'static str),
    report: fn(&Value) -> String,
) -> Result<(), String> {
    let started = std::time::Instant::now();
    let progress = StderrProgress::new(command, unit);
    // Offline, the job may use the machine's memory (as one worker would).
    let limits = crate::job_budget::JobLimits {
        memory_bytes: crate::job_budget::default_job_memory_mb(1) << 20,
    };
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let result = kind.run(
        options,
        inputs,
        &limits,
        &CancelFlag::new(),
        &progress,
        Some(&out.join("stock.stl")),
    );
    progress.finish();
    let done = result.map_err(|f| match f {
        JobFailure::Invalid(problem) => problem.detail,
        JobFailure::Cancelled => "cancelled".into(),
    })?;
    let wall = started.elapsed().as_secs_f64();
    let (summary, rows) = write_outputs(out, done, wall)?;
    eprint!("{}", report(&summary));
    eprintln!(
        "{command}: {rows} moves in {wall:.2} s; wrote {}",
        out.display()
    );
    Ok(())
}

/// A job's results into folder `dir`: summary.json (with `wall_s`), blocks.csv (the
/// summary's `row_columns`), and its files in memory (a program under its file name, the
/// others under their result names; a stock streamed to its file is there already).
/// Returns the summary and the row count.
pub(crate) fn write_outputs(
    dir: &Path,
    out: crate::jobs::JobOutput,
    wall: f64,
) -> Result<(Value, usize), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let write = |name: &str, bytes: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, bytes).map_err(|e| format!("{}: {e}", p.display()))
    };
    let mut summary = out.summary;
    summary["wall_s"] = json!(wall);
    write(
        "summary.json",
        serde_json::to_string_pretty(&summary)
            .expect("JSON")
            .as_bytes(),
    )?;
    let keys: Vec<String> =
        serde_json::from_value(summary["row_columns"].clone()).unwrap_or_default();
    let rows: Vec<csv::Pairs> = out
        .rows
        .iter()
        .filter_map(|r| {
            let mut p = Vec::new();
            csv::read_pairs(r, &mut p).then_some(p)
        })
        .collect();
    let cols = csv::columns(&keys, &rows);
    let mut text = String::new();
    csv::write_header(&mut text, &cols);
    for r in &rows {
        csv::write_row(&mut text, &cols, r, csv::Numbers::default());
    }
    write("blocks.csv", text.as_bytes())?;
    for f in &out.files {
        // The stock went straight to its file.
        let ArtifactContent::Bytes(content) = &f.content else {
            continue;
        };
        // A rewritten program keeps the input's name with .opt before the extension (a
        // process's: with its operation, `rough.op1.opt.nc`).
        let by_file_name = f.name == "program"
            || (summary["operation_count"].is_u64() && f.name.starts_with("program."));
        write(if by_file_name { &f.file_name } else { &f.name }, content)?;
    }
    Ok((summary, rows.len()))
}

/// The fixture file as the job's `options.fixture`: each STL body's `path` (relative to
/// the file) read into a job input `fixture/<body index>` that the body names instead.
/// Errors name the file and the field (`fixture.json: bodies[2].max: ...`).
fn fixture_document(path: &Path, inputs: &mut LoadedInputs) -> Result<Value, String> {
    let doc: Value = serde_json::from_slice(crate::problem::without_bom(&read(path)?))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    fixture_with_paths(doc, dir, &path.display().to_string(), inputs)
}

/// A fixture document whose STL bodies give a `path` (relative to `dir`) as the job's
/// `options.fixture`: each such body's file read into a job input `fixture/<body index>`
/// that the body names instead. Errors start with `label` and name the field.
pub(crate) fn fixture_with_paths(
    mut doc: Value,
    dir: &Path,
    label: &str,
    inputs: &mut LoadedInputs,
) -> Result<Value, String> {
    let at = |e: &dyn std::fmt::Display| format!("{label}: {e}");
    let spec =
        millsim_engine::geometry::FixtureSpec::from_json(&doc, "path").map_err(|e| at(&e))?;
    for (i, file) in spec.stl_references() {
        let name = format!("fixture/{i}");
        let stl = file_input(&dir.join(file), "model/stl")
            .map_err(|e| at(&format!("bodies[{i}].path: {e}")))?;
        crate::validate::stl(&stl.content, file)
            .map_err(|e| at(&format!("bodies[{i}].path: {file}: {}", e.detail)))?;
        inputs.insert(name.clone(), stl);
        let body = doc["bodies"][i]
            .as_object_mut()
            .expect("a body the reader took");
        body.remove("path");
        body.insert("input".into(), Value::String(name));
    }
    Ok(doc)
}

/// `NAME=VALUE,...` of option `flag` as (name, value) pairs, each value a number or
/// `true`/`false` (`tool_guards=false`); errors name the flag and pair.
fn name_values(flag: &str, list: &str) -> Result<Vec<(String, Value)>, String> {
    list.split(',')
        .filter(|p| !p.trim().is_empty())
        .map(|pair| {
            let (k, v) = pair
                .split_once('=')
                .ok_or_else(|| format!("{flag}: `{pair}` is not NAME=VALUE"))?;
            let value = match v.trim() {
                "true" => Value::Bool(true),
                "false" => Value::Bool(false),
                n => json!(n.parse::<f64>().map_err(|_| format!(
                    "{flag}: `{v}` is neither a number nor true/false (in `{pair}`)"
                ))?),
            };
            Ok((k.trim().to_string(), value))
        })
        .collect()
}

/// The few lines a machinist reads before running the output: the cycle time before and
/// after, the peak force and its line, every collision (the first 20 by line), limits the
/// optimizer could not hold, and the tool and program warnings. The rest is in summary.json.
pub fn run_report(summary: &Value) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let num = |v: &Value| v.as_f64().unwrap_or(0.0);
    let opt = &summary["optimization"];
    if opt.is_object() {
        let (before, after) = (
            num(&opt["cycle_time_before_s"]),
            num(&opt["cycle_time_after_s"]),
        );
        let change = if before > 0.0 {
            100.0 * (after - before) / before
        } else {
            0.0
        };
        // With a chosen spindle speed the feeds were scheduled from the program at that speed.
        let from = if summary["spindle"].is_object() {
            "at the chosen speed"
        } else {
            "programmed"
        };
        let _ = writeln!(
            out,
            "cycle time: {before:.1} s {from}, {after:.1} s optimized ({change:+.1} %); best constant feed {:.1} s",
            num(&opt["cycle_time_constant_feed_s"])
        );
    } else {
        let _ = writeln!(out, "cycle time: {:.1} s", num(&summary["cycle_time_s"]));
    }
    let sp = &summary["spindle"];
    if sp.is_object() {
        let _ = writeln!(
            out,
            "spindle: {:.0} rpm chosen ({:.0} programmed){}; chatter margin max {:.2} before, {:.2} after; cycle time {:.1} s at the programmed speed, {:.1} s at the chosen",
            num(&sp["chosen_rpm"]),
            num(&sp["programmed_rpm"]),
            if sp["stable"].as_bool() == Some(true) { ", stable" } else { ", NOT STABLE" },
            num(&sp["chatter_margin_max_before"]),
            num(&sp["chatter_margin_max_after"]),
            num(&sp["cycle_time_programmed_s"]),
            num(&sp["cycle_time_at_chosen_s"]),
        );
        let _ = writeln!(out, "spindle: {}", sp["reason"].as_str().unwrap_or(""));
    }
    match summary["force_peak_line"].as_u64() {
        Some(line) => {
            let _ = write!(
                out,
                "peak force: {:.0} N at line {line}",
                num(&summary["force_peak_n"])
            );
            if opt.is_object() {
                let _ = write!(out, "; {:.0} N after", num(&opt["peak_force_after"]));
            }
            out.push('\n');
        }
        None => out.push_str("peak force: no cut\n"),
    }
    // Each tool's worst bending: where it deflects most and the form error it leaves.
    for t in summary["deflection"].as_array().into_iter().flatten() {
        // A value no move reached (no finishing pass for a form error) names no line.
        let at = |k: &str| {
            t[k].as_u64()
                .map_or(String::new(), |l| format!(" at line {l}"))
        };
        let form = match t["form_error_line"].as_u64() {
            Some(_) => format!(
                "{:+.1} µm{} ({})",
                num(&t["form_error_um"]),
                at("form_error_line"),
                if num(&t["form_error_um"]) >= 0.0 {
                    "material left"
                } else {
                    "overcut"
                }
            ),
            None => "none".to_string(),
        };
        let _ = writeln!(
            out,
            "T{}: deflection {:.1} µm{}; form error {form}; bending stress {:.0} MPa",
            t["tool"],
            num(&t["deflection_peak_um"]),
            at("deflection_line"),
            num(&t["bending_stress_mpa"]),
        );
    }
    if let Some(list) = summary["collisions"].as_array().filter(|c| !c.is_empty()) {
        let _ = writeln!(out, "COLLISIONS: {}", list.len());
        for c in list.iter().take(20) {
            let _ = writeln!(
                out,
                "  line {}: {}",
                c["line"],
                c["kind"].as_str().unwrap_or("?")
            );
        }
        if list.len() > 20 {
            let _ = writeln!(out, "  ... {} more in summary.json", list.len() - 20);
        }
    }
    // Each move that meets the fixture: the body, the tool's part and where.
    let fixture = &summary["fixture"];
    if let Some(list) = fixture["collisions"].as_array().filter(|c| !c.is_empty()) {
        let xyz = |v: &Value| {
            let n = |k: usize| v[k].as_f64().unwrap_or(f64::NAN);
            format!("X{:.3} Y{:.3} Z{:.3}", n(0), n(1), n(2))
        };
        let _ = writeln!(
            out,
            "FIXTURE COLLISIONS: {}",
            fixture["collision_moves"]
                .as_u64()
                .unwrap_or(list.len() as u64)
        );
        for c in list.iter().take(20) {
            let _ = writeln!(
                out,
                "  line {}: {} of T{} meets `{}` ({} move), tip at {}, contact at {}",
                c["line"],
                c["part"].as_str().unwrap_or("?"),
                c["tool"],
                c["body"].as_str().unwrap_or("?"),
                c["kind"].as_str().unwrap_or("?"),
                xyz(&c["tip"]),
                xyz(&c["point"]),
            );
        }
        if list.len() > 20 {
            let _ = writeln!(out, "  ... {} more in summary.json", list.len() - 20);
        }
    }
    if opt.is_object() {
        let n = opt["force_limit_unreachable_moves"].as_u64().unwrap_or(0);
        if n > 0 {
            let lines: Vec<String> = opt["force_limit_unreachable_lines"]
                .as_array()
                .map(|l| l.iter().take(10).map(|v| v.to_string()).collect())
                .unwrap_or_default();
            let _ = writeln!(
                out,
                "limit not met on {n} moves (even at the minimum feed), lines {}",
                lines.join(", ")
            );
        }
        if let Some(tools) = opt["tools"].as_array() {
            for t in tools {
                let g = &t["guards"];
                if g.is_object() {
                    let _ = writeln!(
                        out,
                        "T{}: guards: chip {:.3} mm ({}), force {:.0} N ({})",
                        t["tool"],
                        num(&g["max_chip_thickness"]),
                        g["chip_source"].as_str().unwrap_or("?"),
                        num(&g["max_force"]),
                        g["force_source"].as_str().unwrap_or("?"),
                    );
                }
                for (key, what) in [
                    ("limited_by", "slowed by"),
                    ("limits_not_met", "limit not met at the new feed"),
                ] {
                    if let Some(notes) = t[key].as_array().filter(|n| !n.is_empty()) {
                        let notes: Vec<String> = notes
                            .iter()
                            .map(|n| {
                                format!(
                                    "{} ({} moves)",
                                    n["limit"].as_str().unwrap_or("?"),
                                    n["moves"]
                                )
                            })
                            .collect();
                        let _ = writeln!(out, "T{}: {what}: {}", t["tool"], notes.join(", "));
                    }
                }
            }
        }
    }
    for key in ["tool_warnings", "program_warnings", "warnings"] {
        for w in summary[key].as_array().into_iter().flatten() {
            let _ = writeln!(out, "warning: {}", w.as_str().unwrap_or_default());
        }
    }
    out
}
