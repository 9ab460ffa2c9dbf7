//! millsim: the virtual-machining service and its command line.

mod accessibility_cli;
mod config;
mod csv;
mod http;
mod isolate;
mod job_budget;
mod job_library;
mod jobs;
mod metrics;
mod move_rows;
mod problem;
mod process_cli;
mod program_args;
mod queue;
mod run_cli;
mod stability_cli;
mod store;
mod validate;
mod webhooks;

use std::io::Write;
use std::net::SocketAddr;
use std::process::ExitCode;
use std::sync::Arc;

use clap::{Parser, Subcommand, ValueEnum};
use tokio::sync::{watch, Notify};

use config::{Limits, QueueConfig};
use http::auth::{hash_key, hex, Auth};
use millsim_engine::nc;

#[derive(Parser)]
#[command(
    name = "millsim",
    version,
    about = "Virtual machining: material removal, cutting forces, feed optimization"
)]
struct Cli {
    /// Log format on stderr.
    #[arg(
        long,
        global = true,
        env = "MILLSIM_LOG_FORMAT",
        value_enum,
        default_value = "text"
    )]
    log_format: LogFormat,
    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, ValueEnum)]
enum LogFormat {
    Text,
    Json,
}

#[derive(Subcommand)]
enum Command {
    /// Run the HTTP API and the workers.
    Serve(ServeArgs),
    /// Run workers only, against the same database as a `serve`.
    Worker(WorkerArgs),
    /// Interpret an NC program (G-code or APT/CLS) and print one JSON object per move, as
    /// the moves are made: on an error while running, the moves before it have been printed.
    Interpret(InterpretArgs),
    /// Simulate a program offline: writes summary.json, blocks.csv and stock.stl.
    Run(run_cli::RunArgs),
    /// Run a process offline (operations in order on one stock) from PROCESS.json, the
    /// service's `process` job request with file paths: writes summary.json, blocks.csv,
    /// each operation's program and stock.stl.
    Process(process_cli::ProcessArgs),
    /// Stability lobes: prints CSV rpm,depth_mm for INPUT.json (the `stability` job's options:
    /// with `recommend` the recommended speed on stderr; with `allowance` and
    /// `allowances_mm` the 3-D lobes as allowance_mm,rpm,depth_mm).
    Stability {
        /// The lobe input: method (zoa|sdm|fdm), teeth, coefficients, immersion, modes, speeds.
        input: std::path::PathBuf,
    },
    /// Largest tool and fixed (3+2) tool axis into a closed impeller's passage: prints the
    /// result as JSON for INPUT.json (the `accessibility` job's options, `part`: an STL path,
    /// optionally `machine`: a machine file or definition for the roughing program).
    Accessibility(accessibility_cli::AccessibilityArgs),
    /// Post an APT/CLS file for a machine: one G-code file per operation, rotary feeds corrected.
    Post(PostArgs),
    /// Print every HTTP route as `METHOD PATH`, one per line (checked against openapi.yaml).
    #[command(hide = true)]
    Routes,
    /// Runs one job read from stdin (the service's child process per job).
    #[command(hide = true)]
    JobExec,
    /// Make a new API key: prints the key, and the line to add to the key file.
    ApiKey {
        /// Name of the key's owner (a CAM station, an MES, ...).
        name: String,
    },
}

#[derive(clap::Args)]
struct QueueArgs {
    /// Database URL: sqlite://FILE (created if missing) or postgres://USER:PASSWORD@HOST/DB
    /// (shared by every `serve` and `worker` on any host); migrated on start.
    #[arg(long, env = "MILLSIM_DATABASE", default_value = "sqlite://millsim.db")]
    database: String,
    /// Worker count (engine threads); default: the number of cores.
    #[arg(long, env = "MILLSIM_WORKERS")]
    workers: Option<usize>,
    /// Lease a worker holds on a job between heartbeats, seconds (`--lease-secs`, the old
    /// spelling, is still read).
    #[arg(
        long = "lease-s",
        alias = "lease-secs",
        env = "MILLSIM_LEASE_S",
        default_value_t = 30.0
    )]
    lease_s: f64,
    /// Attempts before a job whose worker keeps dying is failed.
    #[arg(long, env = "MILLSIM_MAX_ATTEMPTS", default_value_t = 3)]
    max_attempts: i64,
    /// On SIGTERM/SIGINT, how long running jobs may finish before their leases are given back,
    /// seconds (`--shutdown-grace-secs`, the old spelling, is still read).
    #[arg(
        long = "shutdown-grace-s",
        alias = "shutdown-grace-secs",
        env = "MILLSIM_SHUTDOWN_GRACE_S",
        default_value_t = 30.0
    )]
    shutdown_grace_s: f64,
    /// Memory budget of one job, MiB; default: the smaller of the machine's memory and the
    /// cgroup's memory.max, / workers (512 MiB to 16 GiB), never above what an inherited
    /// address-space limit (ulimit -v) leaves a job. Jobs estimated over it are refused; a
    /// job's process is limited to it. A value above either limit is refused at start.
    #[arg(long, env = "MILLSIM_JOB_MEMORY_MB")]
    job_memory_mb: Option<u64>,
    /// Where jobs run: `process` (a child process each, under the memory limit) or
    /// `thread` (inside the server, no containment).
    #[arg(
        long,
        env = "MILLSIM_JOB_ISOLATION",
        value_enum,
        default_value = "process"
    )]
    job_isolation: config::Isolation,
    /// Let webhooks post to private, loopback and link-local addresses (a plant network,
    /// tests); by default only public hosts are targets.
    #[arg(long, env = "MILLSIM_WEBHOOK_ALLOW_PRIVATE")]
    webhook_allow_private: bool,
}

impl QueueArgs {
    fn webhooks(&self) -> webhooks::WebhookConfig {
        webhooks::WebhookConfig {
            allow_private: self.webhook_allow_private,
        }
    }

    fn config(&self, default_workers: usize) -> Result<QueueConfig, String> {
        if !(self.lease_s >= 0.2 && self.lease_s <= 3600.0) {
            return Err(format!(
                "--lease-s must be in [0.2, 3600], got {}",
                self.lease_s
            ));
        }
        if !(1..=100).contains(&self.max_attempts) {
            return Err(format!(
                "--max-attempts must be in [1, 100], got {}",
                self.max_attempts
            ));
        }
        if !(self.shutdown_grace_s >= 0.0 && self.shutdown_grace_s <= 86_400.0) {
            return Err(format!(
                "--shutdown-grace-s must be in [0, 86400], got {}",
                self.shutdown_grace_s
            ));
        }
        let workers = self.workers.unwrap_or(default_workers);
        // The default fits what the process may use; a budget asked for that no job process
        // could be given is refused here rather than failing every job later.
        let memory_mb = match self.job_memory_mb {
            None => job_budget::default_job_memory_mb(workers),
            Some(mb) => {
                let address_space = crate::isolate::inherited_address_space()
                    .map(|b| (b, crate::isolate::budget_under_address_space(b)));
                job_budget::check_requested_budget(
                    mb,
                    address_space,
                    job_budget::cgroup_memory_max(),
                )?;
                mb
            }
        };
        if !(64..=1 << 22).contains(&memory_mb) {
            return Err(format!(
                "--job-memory-mb must be in [64, 4194304], got {memory_mb}"
            ));
        }
        Ok(QueueConfig {
            workers,
            lease_ms: (self.lease_s * 1000.0) as i64,
            max_attempts: self.max_attempts,
            poll_ms: 250,
            shutdown_grace_ms: (self.shutdown_grace_s * 1000.0) as u64,
            isolation: self.job_isolation,
            limits: job_budget::JobLimits {
                memory_bytes: memory_mb << 20,
            },
        })
    }
}

#[derive(clap::Args)]
struct ServeArgs {
    /// Address to listen on. Non-loopback addresses need --api-key-file or --insecure-no-auth.
    #[arg(long, env = "MILLSIM_BIND", default_value = "127.0.0.1:8080")]
    bind: SocketAddr,
    #[command(flatten)]
    queue: QueueArgs,
    /// File of API keys, one `NAME SHA256HEX` per line (see `millsim api-key`).
    #[arg(long, env = "MILLSIM_API_KEY_FILE")]
    api_key_file: Option<std::path::PathBuf>,
    /// Serve a non-loopback address without API keys (trusted networks only).
    #[arg(long)]
    insecure_no_auth: bool,
    /// Another site whose pages may call the API (`https://mes.example:8443`), repeatable or
    /// comma-separated; requests from any other site's page are refused (403).
    #[arg(
        long = "cors-origin",
        env = "MILLSIM_CORS_ORIGIN",
        value_delimiter = ','
    )]
    cors_origin: Vec<String>,
    /// Largest STL upload, bytes.
    #[arg(long, env = "MILLSIM_MAX_UPLOAD_BYTES", default_value_t = config::DEFAULT_MAX_STL_BYTES)]
    max_upload_bytes: u64,
    /// Largest NC program (upload or inline in a job), bytes.
    #[arg(long, env = "MILLSIM_MAX_PROGRAM_BYTES", default_value_t = config::DEFAULT_MAX_PROGRAM_BYTES)]
    max_program_bytes: u64,
    /// Seconds a client has to send a request's headers before its connection is closed.
    #[arg(long, env = "MILLSIM_HEADER_TIMEOUT_S", default_value_t = 10.0)]
    header_timeout_s: f64,
    /// Seconds a request body may stall (no byte arrives) before it is answered 408.
    #[arg(long, env = "MILLSIM_BODY_TIMEOUT_S", default_value_t = 30.0)]
    body_timeout_s: f64,
    /// Open connections at most; over it, new connections are closed at once.
    #[arg(long, env = "MILLSIM_MAX_CONNECTIONS", default_value_t = 8192)]
    max_connections: usize,
    /// Queued jobs one API key may have; over it, submissions are answered 429.
    #[arg(long, env = "MILLSIM_MAX_QUEUED_PER_KEY", default_value_t = 1000)]
    max_queued_per_key: i64,
    /// MiB an STL upload must leave free in the temporary directory ($TMPDIR) it is
    /// spooled to; an upload that would not is answered 507 Insufficient Storage.
    #[arg(long, env = "MILLSIM_UPLOAD_DISK_RESERVE_MB", default_value_t = 512)]
    upload_disk_reserve_mb: u64,
}

#[derive(clap::Args)]
struct WorkerArgs {
    #[command(flatten)]
    queue: QueueArgs,
}

#[derive(clap::Args)]
struct PostArgs {
    /// The APT/CLS file.
    file: std::path::PathBuf,
    /// Machine definition (JSON, as POST /v1/machines takes it), with its kinematics.
    #[arg(long)]
    machine: std::path::PathBuf,
    /// Write inverse-time feeds (G93, F = 1/t) instead of corrected mm/min (G94).
    #[arg(long)]
    inverse_time: bool,
    /// Number the blocks N10, N20, ...
    #[arg(long)]
    n_numbers: bool,
    /// Decimals of X Y Z and of A B C.
    #[arg(long, default_value_t = 4)]
    decimals: usize,
    /// Output folder: FILE-STEM.op1.nc, .op2.nc, ...
    #[arg(long)]
    out: std::path::PathBuf,
}

#[derive(clap::Args)]
struct InterpretArgs {
    /// The NC program (G-code, or APT/CLS).
    file: std::path::PathBuf,
    #[command(flatten)]
    program: program_args::ProgramArgs,
    /// The tool of a tool number, as `T1=tool.json` (JSON as POST /v1/tools takes it);
    /// repeat per number. Cutter compensation (G41 D1) takes its radius where the program's
    /// tool table and G10 give none, as `millsim run` does.
    #[arg(long, value_name = "Tn=FILE")]
    tool: Vec<String>,
}

fn init_logs(format: LogFormat) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| "info,sqlx=warn,tower_http=info".into());
    // Colour codes only on a terminal: a log file or a journal gets plain text.
    use std::io::IsTerminal as _;
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr);
    match format {
        LogFormat::Json => builder.json().init(),
        LogFormat::Text => builder.init(),
    }
}

/// Environment names of settings renamed to the `_S` (seconds) spelling the other
/// settings use: an old name still set is read when the new one is not.
const RENAMED_ENV: [(&str, &str); 2] = [
    ("MILLSIM_LEASE_SECS", "MILLSIM_LEASE_S"),
    ("MILLSIM_SHUTDOWN_GRACE_SECS", "MILLSIM_SHUTDOWN_GRACE_S"),
];

fn main() -> ExitCode {
    for (old, new) in RENAMED_ENV {
        if let (Some(v), None) = (std::env::var_os(old), std::env::var_os(new)) {
            // Before any thread starts: nothing else reads the environment yet.
            std::env::set_var(new, v);
        }
    }
    let cli = Cli::parse();
    match cli.command {
        Command::Interpret(args) => interpret(args),
        Command::Stability { input } => match stability_cli::run(&input) {
            Ok(out) => {
                print!("{}", out.csv);
                if let Some(note) = out.note {
                    eprintln!("{note}");
                }
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("{e}");
                ExitCode::FAILURE
            }
        },
        Command::Accessibility(args) => match accessibility_cli::run(&args) {
            Ok(json) => {
                println!("{json}");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("millsim accessibility: {e}");
                ExitCode::FAILURE
            }
        },
        Command::Post(args) => match post(args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("millsim post: {e}");
                ExitCode::FAILURE
            }
        },
        Command::Run(args) => match run_cli::run(args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("millsim run: {e}");
                ExitCode::FAILURE
            }
        },
        Command::Process(args) => match process_cli::run(args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("millsim process: {e}");
                ExitCode::FAILURE
            }
        },
        Command::JobExec => isolate::job_exec_main(),
        Command::Routes => {
            for (method, path) in http::route_table() {
                println!("{method} {path}");
            }
            ExitCode::SUCCESS
        }
        Command::ApiKey { name } => {
            if name.is_empty() || name.contains(char::is_whitespace) {
                eprintln!("millsim api-key: the name must be one word");
                return ExitCode::from(2);
            }
            let key = format!(
                "ms_{}{}",
                uuid::Uuid::new_v4().simple(),
                uuid::Uuid::new_v4().simple()
            );
            println!("key: {key}");
            println!("key file line: {name} {}", hex(&hash_key(&key)));
            ExitCode::SUCCESS
        }
        Command::Serve(args) => {
            init_logs(cli.log_format);
            run_async(serve(args))
        }
        Command::Worker(args) => {
            init_logs(cli.log_format);
            run_async(worker(args))
        }
    }
}

fn run_async(f: impl std::future::Future<Output = Result<(), String>>) -> ExitCode {
    let rt = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("millsim: cannot start the runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    match rt.block_on(f) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("millsim: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Turns true on SIGTERM or SIGINT.
fn shutdown_signal() -> watch::Receiver<bool> {
    let (tx, rx) = watch::channel(false);
    tokio::spawn(async move {
        let ctrl_c = tokio::signal::ctrl_c();
        let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
            .expect("SIGTERM handler");
        tokio::select! {
            _ = ctrl_c => {}
            _ = term.recv() => {}
        }
        tracing::info!(
            "shutdown requested: no new jobs are claimed; running jobs finish or are given back"
        );
        let _ = tx.send(true);
    });
    rx
}

fn cores() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}

async fn serve(args: ServeArgs) -> Result<(), String> {
    let queue = args.queue.config(cores())?;
    if !(args.header_timeout_s.is_finite() && args.header_timeout_s > 0.0) {
        return Err(format!(
            "--header-timeout-s must be a positive number of seconds, got {}",
            args.header_timeout_s
        ));
    }
    if !(args.body_timeout_s.is_finite() && args.body_timeout_s > 0.0) {
        return Err(format!(
            "--body-timeout-s must be a positive number of seconds, got {}",
            args.body_timeout_s
        ));
    }
    if args.max_connections == 0 {
        return Err("--max-connections must be at least 1".into());
    }
    if args.max_queued_per_key < 1 {
        return Err(format!(
            "--max-queued-per-key must be at least 1, got {}",
            args.max_queued_per_key
        ));
    }
    let auth = match &args.api_key_file {
        Some(path) => {
            let text =
                std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
            Auth::from_key_file(&path.display().to_string(), &text).map_err(|e| e.to_string())?
        }
        None => Auth::disabled(),
    };
    if !args.bind.ip().is_loopback() && !auth.enabled() && !args.insecure_no_auth {
        return Err(format!(
            "refusing to serve {} without API keys: pass --api-key-file FILE (see `millsim api-key`), or --insecure-no-auth on a trusted network",
            args.bind
        ));
    }
    let db = store::Db::open(&args.queue.database)
        .await
        .map_err(|e| format!("{}: {e}", store::redact_url(&args.queue.database)))?;
    let metrics = Arc::new(metrics::Metrics::default());
    let wake = Arc::new(Notify::new());
    let limits = Limits {
        max_stl_bytes: args.max_upload_bytes,
        max_program_bytes: args.max_program_bytes,
        max_queued_per_key: args.max_queued_per_key,
        upload_disk_reserve_bytes: args.upload_disk_reserve_mb.saturating_mul(1 << 20),
        body_timeout: std::time::Duration::from_secs_f64(args.body_timeout_s),
        ..Limits::default()
    };
    let shutdown = shutdown_signal();
    let state = http::AppState {
        db: db.clone(),
        limits: Arc::new(limits),
        metrics: metrics.clone(),
        auth: Arc::new(auth),
        job_submitted: wake.clone(),
        max_attempts: queue.max_attempts,
        job_limits: queue.limits,
        webhooks: args.queue.webhooks(),
        shutdown: shutdown.clone(),
        cross_site: Arc::new(http::guard::CrossSite {
            allowed: args.cors_origin.clone(),
        }),
    };
    let listener = tokio::net::TcpListener::bind(args.bind)
        .await
        .map_err(|e| format!("cannot bind {}: {e}", args.bind))?;
    let addr = listener.local_addr().map_err(|e| e.to_string())?;
    let shutdown_grace_ms = queue.shutdown_grace_ms;
    // Webhook deliveries run beside the workers, never on them.
    let dispatcher = tokio::spawn(webhooks::run_dispatcher(
        db.clone(),
        args.queue.webhooks(),
        shutdown.clone(),
    ));
    let workers = tokio::spawn(queue::run_workers(
        db,
        queue,
        metrics,
        wake,
        shutdown.clone(),
    ));
    tracing::info!(%addr, "listening");
    // Tests and scripts read the bound address (the port may have been 0) from stdout.
    println!("millsim listening on http://{addr}");
    let _ = std::io::stdout().flush();
    let limits = http::server::ConnectionLimits {
        header_timeout: std::time::Duration::from_secs_f64(args.header_timeout_s),
        max_connections: args.max_connections,
        // Open requests get the same grace as running jobs: SIGTERM ends the process
        // within it (plus the time to give jobs back), whatever the clients do.
        grace: std::time::Duration::from_millis(shutdown_grace_ms),
    };
    http::server::serve(listener, http::router(state), limits, shutdown.clone()).await;
    let _ = workers.await;
    let _ = dispatcher.await;
    Ok(())
}

async fn worker(args: WorkerArgs) -> Result<(), String> {
    let queue = args.queue.config(cores())?;
    if queue.workers == 0 {
        return Err("--workers must be at least 1 for `millsim worker`".into());
    }
    let db = store::Db::open(&args.queue.database)
        .await
        .map_err(|e| format!("{}: {e}", store::redact_url(&args.queue.database)))?;
    let shutdown = shutdown_signal();
    let dispatcher = tokio::spawn(webhooks::run_dispatcher(
        db.clone(),
        args.queue.webhooks(),
        shutdown.clone(),
    ));
    queue::run_workers(
        db,
        queue,
        Arc::new(metrics::Metrics::default()),
        Arc::new(Notify::new()),
        shutdown,
    )
    .await;
    let _ = dispatcher.await;
    Ok(())
}

/// `T3=tool.json`: tool number 3 and the diameter of the tool the file describes.
fn tool_diameter(spec: &str) -> Result<(u32, f64), String> {
    let (name, path) = spec
        .split_once('=')
        .ok_or_else(|| format!("{spec}: give the tool number, as T1=tool.json"))?;
    let number = jobs::JobKind::Interpret
        .tool_number_input(name.trim())
        .ok_or_else(|| format!("{spec}: `{name}` is not a tool number like T1"))?;
    let bytes = std::fs::read(path).map_err(|e| format!("{spec}: {path}: {e}"))?;
    validate::tool(&bytes).map_err(|e| format!("{spec}: {path}: {}", e.detail))?;
    let tool: millsim_engine::tool::Tool =
        serde_json::from_slice(crate::problem::without_bom(&bytes))
            .map_err(|e| format!("{spec}: {path}: {e}"))?;
    Ok((number, tool.diameter))
}

fn interpret(args: InterpretArgs) -> ExitCode {
    let file = args.file.display().to_string();
    let text = match std::fs::read(&args.file) {
        Ok(bytes) => match validate::program_string(bytes) {
            Some((t, _)) => t,
            None => {
                eprintln!("{file}: not text (neither UTF-8 nor ISO 8859-1)");
                return ExitCode::from(2);
            }
        },
        Err(e) => {
            eprintln!("{file}: {e}");
            return ExitCode::from(2);
        }
    };
    let job_options = match args.program.job_options() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };
    // The same options a job gets; only the tool table's errors name its own file.
    let mut options = match job_options.engine_options() {
        Ok(o) => o,
        Err(diags) => {
            let table = args
                .program
                .tool_table
                .as_ref()
                .map(|p| p.display().to_string())
                .unwrap_or_default();
            for d in &diags.0 {
                eprintln!("{table}:{d}");
            }
            return ExitCode::FAILURE;
        }
    };
    for spec in &args.tool {
        match tool_diameter(spec) {
            Ok((number, diameter)) => {
                if options.tool_diameters.insert(number, diameter).is_some() {
                    eprintln!("--tool {spec}: T{number} is given twice");
                    return ExitCode::from(2);
                }
            }
            Err(e) => {
                eprintln!("--tool {e}");
                return ExitCode::from(2);
            }
        }
    }
    // Where no --tool gives a number, the tool the program's header describes (as `run`).
    millsim_engine::tool_library::add_header_diameters(&mut options.tool_diameters, &text);
    if let Some(dir) = &args.program.library {
        match nc::ProgramLibrary::from_dir(dir) {
            Ok(l) => options.library = Some(std::sync::Arc::new(l)),
            Err(e) => {
                eprintln!("--library {e}");
                return ExitCode::from(2);
            }
        }
    }
    let stdout = std::io::stdout();
    let mut w = stdout.lock();
    // Moves are printed as they are made, so that memory stays bounded whatever the
    // program's length, in blocks of about 64 KiB; the first write error stops the printing.
    let mut rows = Vec::with_capacity(1 << 17);
    let mut write_failed = false;
    let mut print = |m: nc::Move| {
        if write_failed {
            return;
        }
        move_rows::write_row(&mut rows, &m);
        if rows.len() >= 1 << 16 {
            write_failed = w.write_all(&rows).is_err();
            rows.clear();
        }
    };
    let result = if validate::looks_like_cls(&text) {
        millsim_engine::cl::read_cls(&text).map(|mut out| {
            out.moves.drain(..).for_each(&mut print);
            out
        })
    } else {
        nc::interpret_each(&text, &options, &mut print)
    };
    if write_failed || w.write_all(&rows).is_err() || w.flush().is_err() {
        return ExitCode::FAILURE;
    }
    match result {
        Ok(out) => {
            for (i, f) in out.library_files.iter().enumerate() {
                eprintln!("{file}: library file {i}: {f}");
            }
            for w in &out.warnings {
                eprintln!("{file}:{w} (warning)");
            }
            ExitCode::SUCCESS
        }
        Err(diags) => {
            for d in &diags.0 {
                eprintln!("{file}:{d}");
            }
            ExitCode::FAILURE
        }
    }
}

fn post(args: PostArgs) -> Result<(), String> {
    use millsim_engine::machine::post::{post_cls, PostOptions};
    use millsim_engine::machine::rotary_feed::{FeedOutput, RotaryFeedOptions};
    let file = args.file.display().to_string();
    let cls = std::fs::read_to_string(&args.file).map_err(|e| format!("{file}: {e}"))?;
    let machine_bytes =
        std::fs::read(&args.machine).map_err(|e| format!("{}: {e}", args.machine.display()))?;
    validate::machine(&machine_bytes)
        .map_err(|e| format!("{}: {}", args.machine.display(), e.detail))?;
    let machine: millsim_engine::machine::Machine =
        serde_json::from_slice(crate::problem::without_bom(&machine_bytes))
            .map_err(|e| e.to_string())?;
    if !(1..=9).contains(&args.decimals) {
        return Err(format!("--decimals must be 1 to 9, got {}", args.decimals));
    }
    let options = PostOptions {
        n_numbers: args.n_numbers.then_some((10, 10)),
        linear_decimals: args.decimals,
        angle_decimals: args.decimals,
        feed: RotaryFeedOptions {
            output: if args.inverse_time {
                FeedOutput::InverseTime
            } else {
                FeedOutput::PerMin
            },
            ..Default::default()
        },
        ..Default::default()
    };
    let posted = post_cls(&cls, &machine, &options).map_err(|e| format!("{file}: {e}"))?;
    std::fs::create_dir_all(&args.out).map_err(|e| format!("{}: {e}", args.out.display()))?;
    let stem = args
        .file
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "program".into());
    for p in &posted {
        let path = args.out.join(format!("{stem}.op{}.nc", p.operation));
        std::fs::write(&path, &p.text).map_err(|e| format!("{}: {e}", path.display()))?;
        for issue in &p.issues {
            eprintln!("{file}:{}: {:?}", issue.index, issue.kind);
        }
        eprintln!(
            "millsim post: operation {} (T{}): {} moves -> {}",
            p.operation,
            p.tool,
            p.axes.len(),
            path.display()
        );
    }
    Ok(())
}
