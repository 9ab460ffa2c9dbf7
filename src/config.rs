//! Limits and timing the service runs with.

/// The default largest STL upload and NC program, bytes (`--max-upload-bytes`,
/// `--max-program-bytes`).
pub const DEFAULT_MAX_STL_BYTES: u64 = 256 << 20;
pub const DEFAULT_MAX_PROGRAM_BYTES: u64 = 64 << 20;

/// Per-route body limits and timeouts.
#[derive(Clone, Debug)]
pub struct Limits {
    pub max_stl_bytes: u64,
    pub max_program_bytes: u64,
    pub max_json_bytes: u64,
    pub upload_timeout_secs: u64,
    /// A request body that stalls this long (no byte arrives) is answered 408.
    pub body_timeout: std::time::Duration,
    /// Queued jobs one API key may have; a submission over it is answered 429.
    pub max_queued_per_key: i64,
    /// Bytes a spooled upload must leave free in the temporary directory; an upload that
    /// would not is answered 507.
    pub upload_disk_reserve_bytes: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_stl_bytes: DEFAULT_MAX_STL_BYTES,
            max_program_bytes: DEFAULT_MAX_PROGRAM_BYTES,
            max_json_bytes: 1 << 20,
            upload_timeout_secs: 600,
            body_timeout: std::time::Duration::from_secs(30),
            max_queued_per_key: 1000,
            upload_disk_reserve_bytes: 512 << 20,
        }
    }
}

/// Where a job's engine work runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Isolation {
    /// In a child process per job under an address-space limit: a job that dies takes
    /// only itself down.
    Process,
    /// On a blocking thread of the server (no containment; a job whose attempt was lost
    /// is then not retried, since it may have brought the server down).
    Thread,
}

/// How workers hold and renew jobs.
#[derive(Clone, Debug)]
pub struct QueueConfig {
    pub workers: usize,
    pub lease_ms: i64,
    pub max_attempts: i64,
    /// How often an idle worker looks for work another process submitted.
    pub poll_ms: u64,
    /// On shutdown, how long running jobs may take to finish before their leases are given back.
    pub shutdown_grace_ms: u64,
    pub isolation: Isolation,
    /// What each job is held to (memory budget).
    pub limits: crate::job_budget::JobLimits,
}
