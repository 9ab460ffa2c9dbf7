//! Workers: claim a job, run its engine work (in a child process per job by default, under
//! the job's memory budget; on a blocking thread with `--job-isolation thread`), heartbeat
//! the lease while it runs, then commit the outcome with the results (only while holding the
//! lease). N workers run at most N jobs: the pool is bounded by construction.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::http::StatusCode;
use tokio::sync::{watch, Notify};

use millsim_engine::job::{CancelFlag, Progress};

use crate::config::{Isolation, QueueConfig};
use crate::isolate::{self, Ended};
use crate::jobs::{JobFailure, JobKind, LoadedInput, LoadedInputs, StoredChunks};
use crate::metrics::Metrics;
use crate::problem::Problem;
use crate::store::backend::Backend;
use crate::store::chunks::ResourceBody;
use crate::store::jobs::{ClaimedJob, CreatedResource, Finish, LeaseState, IN_PROCESS_MARK};
use crate::store::workers::WorkerReport;
use crate::store::{Db, ResourceKind, StoreError};

mod job_dir;

/// Why a job's inputs could not be loaded.
enum InputsError {
    /// The database did not answer: the job is not at fault and is tried again.
    Storage(StoreError),
    /// The inputs themselves are unusable (deleted): the job fails with this problem.
    Invalid(Problem),
}

/// Progress of a running job, read by the heartbeat.
#[derive(Default)]
pub struct SharedProgress {
    pub done: AtomicU64,
    pub total: AtomicU64,
}

impl Progress for SharedProgress {
    fn report(&self, done: u64, total: u64) {
        self.total.store(total, Ordering::Relaxed);
        self.done.store(done, Ordering::Relaxed);
    }
}

/// One worker's counts since it started, reported to the database for /metrics.
#[derive(Default)]
pub struct WorkerCounts {
    running: AtomicU64,
    claimed: AtomicU64,
    succeeded: AtomicU64,
    failed: AtomicU64,
    cancelled: AtomicU64,
    abandoned: AtomicU64,
}

impl WorkerCounts {
    /// Counts a job this worker ended as `outcome` (None: not ended by it).
    fn record(&self, outcome: Option<&'static str>) {
        let ended = match outcome {
            Some("succeeded") => &self.succeeded,
            Some("failed") => &self.failed,
            Some(_) => &self.cancelled,
            None => &self.abandoned,
        };
        ended.fetch_add(1, Ordering::Relaxed);
    }

    fn report(&self, id: &str, host: &str, started_at: i64) -> WorkerReport {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed) as i64;
        WorkerReport {
            id: id.to_string(),
            host: host.to_string(),
            pid: i64::from(std::process::id()),
            started_at,
            running: get(&self.running),
            claimed: get(&self.claimed),
            succeeded: get(&self.succeeded),
            failed: get(&self.failed),
            cancelled: get(&self.cancelled),
            abandoned: get(&self.abandoned),
        }
    }
}

/// How often a process reports its workers' counts.
const REPORT_EVERY: Duration = Duration::from_secs(1);

/// Reports `workers` every second until `done` (they have stopped, after any shutdown
/// grace), then removes their rows.
async fn report_workers(db: Db, workers: Vec<(String, Arc<WorkerCounts>)>, done: Arc<Notify>) {
    let host = host_name();
    let started_at = crate::store::now_ms();
    let reports = || {
        workers
            .iter()
            .map(|(id, c)| c.report(id, &host, started_at))
            .collect::<Vec<_>>()
    };
    let mut tick = tokio::time::interval(REPORT_EVERY);
    loop {
        tokio::select! {
            _ = tick.tick() => {
                if let Err(e) = db.report_workers(&reports()).await {
                    tracing::warn!(error = %e, "could not report the workers' counts");
                }
            }
            _ = done.notified() => break,
        }
    }
    let ids: Vec<String> = workers.iter().map(|(id, _)| id.clone()).collect();
    if let Err(e) = db.remove_workers(&ids).await {
        tracing::warn!(error = %e, "could not remove the workers' rows; they expire");
    }
}

/// This host's name: $HOSTNAME, else the kernel's (a shell does not always export it).
fn host_name() -> String {
    std::env::var("HOSTNAME")
        .ok()
        .or_else(|| std::fs::read_to_string("/proc/sys/kernel/hostname").ok())
        .map(|h| h.trim().to_string())
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "host".into())
}

/// A name for this process's workers, unique across processes and restarts.
pub fn process_worker_prefix() -> String {
    let host = host_name();
    format!(
        "{host}-{}-{}",
        std::process::id(),
        &uuid::Uuid::now_v7().simple().to_string()[20..]
    )
}

/// Runs `config.workers` workers until `shutdown` turns true, then lets running jobs
/// finish within the grace period or gives their leases back.
pub async fn run_workers(
    db: Db,
    config: QueueConfig,
    metrics: Arc<Metrics>,
    wake: Arc<Notify>,
    shutdown: watch::Receiver<bool>,
) {
    let prefix = process_worker_prefix();
    // Job directories of worker processes that were killed (any that shared this
    // temporary directory): their files were never stored.
    let tmp = std::env::temp_dir();
    let removed = tokio::task::spawn_blocking(move || job_dir::remove_stale(&tmp))
        .await
        .unwrap_or(0);
    if removed > 0 {
        tracing::info!(
            removed,
            "removed job directories of worker processes that are gone"
        );
    }
    let mut handles = Vec::new();
    let mut reported = Vec::new();
    for i in 0..config.workers {
        let counts = Arc::new(WorkerCounts::default());
        let id = match config.isolation {
            Isolation::Process => format!("{prefix}-w{i}"),
            Isolation::Thread => format!("{prefix}{IN_PROCESS_MARK}w{i}"),
        };
        reported.push((id.clone(), counts.clone()));
        let worker = Worker {
            id,
            counts,
            db: db.clone(),
            config: config.clone(),
            metrics: metrics.clone(),
            wake: wake.clone(),
            shutdown: shutdown.clone(),
        };
        handles.push(tokio::spawn(worker.run()));
    }
    let stopped = Arc::new(Notify::new());
    let reporter = tokio::spawn(report_workers(db.clone(), reported, stopped.clone()));
    tracing::info!(workers = config.workers, prefix = %prefix, "workers started");
    for h in handles {
        let _ = h.await;
    }
    stopped.notify_one();
    let _ = reporter.await;
    tracing::info!("workers stopped");
}

/// Results up to this size (rows, samples, files) are committed while the worker goes on
/// to the next job; larger ones before it does.
const PIPELINED_COMMIT_BYTES: usize = 1 << 20;
/// Commits a worker may have in flight.
const MAX_COMMITS_IN_FLIGHT: usize = 4;

/// A job this worker ran to its end, with the outcome to commit.
struct JobEnded {
    job: ClaimedJob,
    finish: Finish,
    started: Instant,
    /// When the run ended (unix ms): the end of the attempt in its log.
    ran_until: i64,
    /// The job's directory, holding the files it wrote until they are committed (removed
    /// when this is dropped, committed or not).
    _work_dir: Option<job_dir::JobDir>,
}

impl JobEnded {
    /// Bytes of the result to commit: held in memory, or in files the job wrote.
    fn bytes(&self) -> usize {
        match &self.finish {
            Finish::Succeeded {
                rows,
                samples,
                artifacts,
                resources,
                summary: _,
                progress: _,
            } => {
                rows.iter().map(String::len).sum::<usize>()
                    + samples.iter().map(|(_, s)| s.len()).sum::<usize>()
                    + artifacts
                        .iter()
                        .map(|a| a.content.size() as usize)
                        .sum::<usize>()
                    + resources.iter().map(|r| r.content.len()).sum::<usize>()
            }
            Finish::Failed { .. } | Finish::Cancelled => 0,
        }
    }

    /// Commits the outcome; the outcome committed, or None when it was not (lease lost,
    /// commit failed: the job is then claimed again when its lease expires).
    async fn commit(self, db: &Db, metrics: &Metrics, worker: &str) -> Option<&'static str> {
        let JobEnded {
            job,
            finish,
            started,
            ran_until,
            _work_dir,
        } = self;
        let label = match &finish {
            Finish::Succeeded { .. } => "succeeded",
            Finish::Failed { .. } => "failed",
            Finish::Cancelled => "cancelled",
        };
        match db.finish_job(&job, worker, finish, ran_until).await {
            Ok(true) => {
                metrics.observe_job(&job.kind, label, started.elapsed());
                tracing::info!(worker = %worker, job = %job.id, outcome = label, seconds = started.elapsed().as_secs_f64(), "job finished");
                Some(label)
            }
            Ok(false) => {
                tracing::warn!(worker = %worker, job = %job.id, "lease lost before commit; result dropped");
                None
            }
            Err(e) => {
                tracing::error!(worker = %worker, job = %job.id, error = %e, "could not commit the job's outcome");
                None
            }
        }
    }
}

/// How long a worker waits after giving a job back for a storage error.
const STORAGE_BACKOFF_MS: u64 = 500;

/// Tries at starting a job's process (by any server) before the job is failed:
/// a passing shortage (descriptors, processes) gets a second chance, a lasting one (the
/// executable gone, a limit it cannot be given) does not loop for ever.
const START_TRIES: i64 = 3;

struct Worker {
    id: String,
    counts: Arc<WorkerCounts>,
    db: Db,
    config: QueueConfig,
    metrics: Arc<Metrics>,
    wake: Arc<Notify>,
    shutdown: watch::Receiver<bool>,
}

impl Worker {
    async fn run(mut self) {
        let mut commits = tokio::task::JoinSet::new();
        loop {
            while commits.try_join_next().is_some() {}
            if *self.shutdown.borrow() {
                // Results already computed are committed before the worker stops.
                while commits.join_next().await.is_some() {}
                return;
            }
            match self.db.claim_job(&self.id, self.config.lease_ms).await {
                Ok(Some(job)) => {
                    self.counts.claimed.fetch_add(1, Ordering::Relaxed);
                    self.counts.running.store(1, Ordering::Relaxed);
                    let ended = self.run_job(job).await;
                    self.counts.running.store(0, Ordering::Relaxed);
                    let Some(ended) = ended else {
                        self.counts.record(None);
                        continue;
                    };
                    // SQLite runs one writer at a time: a commit in flight would only
                    // make the next claim wait for it (pipelining it measured slower; see the
                    // README's queue throughput table).
                    if self.db.backend() == Backend::Sqlite
                        || ended.bytes() > PIPELINED_COMMIT_BYTES
                    {
                        let done = ended.commit(&self.db, &self.metrics, &self.id).await;
                        self.counts.record(done);
                        continue;
                    }
                    // On PostgreSQL a small result commits while this worker claims and
                    // runs the next job: its commit's wait for the disk (one fsync, ~3 ms here) no longer
                    // paces the worker, and commits in flight share fsyncs. Bounded in
                    // count and size, so what waits in memory stays small.
                    while commits.len() >= MAX_COMMITS_IN_FLIGHT {
                        commits.join_next().await;
                    }
                    let (db, metrics, id, counts) = (
                        self.db.clone(),
                        self.metrics.clone(),
                        self.id.clone(),
                        self.counts.clone(),
                    );
                    commits.spawn(async move {
                        counts.record(ended.commit(&db, &metrics, &id).await);
                    });
                }
                Ok(None) => {
                    // Woken by a submission in this process, by the database's
                    // notification of one from any process (PostgreSQL), or by the poll
                    // that finds jobs whose lease expired (nothing announces those).
                    tokio::select! {
                        _ = self.wake.notified() => {}
                        _ = self.db.job_queued() => {}
                        _ = tokio::time::sleep(Duration::from_millis(self.config.poll_ms)) => {}
                        _ = self.shutdown.changed() => {}
                    }
                }
                Err(e) => {
                    tracing::warn!(worker = %self.id, error = %e, "claim failed; retrying");
                    tokio::time::sleep(Duration::from_millis(500)).await;
                }
            }
        }
    }

    async fn load_inputs(
        &self,
        job: &ClaimedJob,
        kind: JobKind,
    ) -> Result<LoadedInputs, InputsError> {
        let mut loaded = LoadedInputs::new();
        let mut wanted: Vec<(String, ResourceKind)> = kind
            .inputs()
            .iter()
            .map(|s| (s.name.to_string(), s.kind))
            .collect();
        if let Some(given) = job.spec["inputs"].as_object() {
            wanted.extend(
                given
                    .keys()
                    .filter_map(|n| kind.named_input(n).map(|k| (n.clone(), k))),
            );
        }
        for (name, kind) in wanted {
            let Some(id) = job.spec["inputs"][&name].as_str() else {
                continue;
            };
            let found = self
                .db
                .resource_body(&job.owner, kind, id)
                .await
                .map_err(InputsError::Storage)?;
            let Some((file_name, media_type, size, body)) = found else {
                return Err(InputsError::Invalid(Problem::new(
                    StatusCode::UNPROCESSABLE_ENTITY,
                    "input-gone",
                    "Input deleted",
                    format!(
                        "input `{name}` ({} {id}) was deleted before the job ran",
                        kind.as_str()
                    ),
                )));
            };
            let input = match body {
                ResourceBody::Inline(content) => LoadedInput {
                    file_name,
                    media_type,
                    content,
                    ..Default::default()
                },
                // A job's process is sent the chunks as it reads them; a job on a thread
                // of this process takes the content whole.
                ResourceBody::Chunked { id, chunks }
                    if self.config.isolation == Isolation::Process =>
                {
                    LoadedInput {
                        file_name,
                        media_type,
                        stored_chunks: Some(StoredChunks {
                            resource_id: id,
                            chunks,
                            size: size as u64,
                        }),
                        ..Default::default()
                    }
                }
                ResourceBody::Chunked { .. } => {
                    let (file_name, media_type, content) = self
                        .db
                        .resource_content(&job.owner, kind, id)
                        .await
                        .map_err(InputsError::Storage)?
                        .ok_or_else(|| {
                            InputsError::Storage(StoreError::Vanished(format!(
                                "{} {id}",
                                kind.as_str()
                            )))
                        })?;
                    LoadedInput {
                        file_name,
                        media_type,
                        content,
                        ..Default::default()
                    }
                }
            };
            loaded.insert(name, input);
        }
        Ok(loaded)
    }

    /// Runs a claimed job; its outcome to commit, or None when this worker does not end
    /// it (given back, lease lost).
    async fn run_job(&mut self, job: ClaimedJob) -> Option<JobEnded> {
        let started = Instant::now();
        tracing::info!(worker = %self.id, job = %job.id, kind = %job.kind, attempt = job.attempt, "job claimed");
        // A kind this build does not know (stored by a newer server sharing the database):
        // the job fails, saying so, rather than being claimed again and again.
        let loaded = match JobKind::parse(&job.kind) {
            Some(kind) => self
                .load_inputs(&job, kind)
                .await
                .map(|inputs| (kind, inputs)),
            None => Err(InputsError::Invalid(Problem::not_supported(format!(
                "job kind `{}` is not known to this worker",
                job.kind
            )))),
        };
        let mut work_dir = None;
        let outcome = match loaded {
            Err(InputsError::Invalid(problem)) => Finish::Failed {
                error: problem.to_json(),
            },
            Err(InputsError::Storage(e)) => {
                tracing::warn!(worker = %self.id, job = %job.id, error = %e, "could not load the job's inputs; giving the job back");
                if let Err(e) = self.db.release_job(&job, &self.id).await {
                    tracing::error!(worker = %self.id, job = %job.id, error = %e, "could not give the job back; its lease will expire");
                }
                // The database is struggling: do not claim the job straight back.
                tokio::time::sleep(Duration::from_millis(STORAGE_BACKOFF_MS)).await;
                return None;
            }
            Ok((kind, inputs)) => {
                // Where the job writes its large files, until they are committed.
                let dir = match job_dir::create() {
                    Ok(d) => d,
                    Err(e) => {
                        tracing::error!(worker = %self.id, job = %job.id, error = %e, "could not make the job's directory; giving the job back");
                        self.give_back(&job).await;
                        return None;
                    }
                };
                let finish = self.execute(&job, kind, inputs, dir.path()).await;
                work_dir = Some(dir);
                match finish {
                    Some(finish) => finish,
                    // Lease lost or given back: whoever holds the job now writes its outcome.
                    None => return None,
                }
            }
        };
        Some(JobEnded {
            job,
            finish: outcome,
            started,
            ran_until: crate::store::now_ms(),
            _work_dir: work_dir,
        })
    }

    /// Runs the engine and heartbeats until it ends. None when the job must not be
    /// finished by this worker (lease lost, or given back on shutdown).
    async fn execute(
        &mut self,
        job: &ClaimedJob,
        kind: JobKind,
        inputs: LoadedInputs,
        work_dir: &std::path::Path,
    ) -> Option<Finish> {
        let progress = Arc::new(SharedProgress::default());
        let mut engine = match self.start_engine(job, kind, inputs, progress.clone(), work_dir) {
            Ok(e) => e,
            Err(e) => {
                // Cannot start a process (descriptors, fork, the executable gone): not the
                // job's fault, and perhaps passing. Counted with the job, so that every
                // server sharing the database counts the same tries: given back up to
                // START_TRIES times, then failed.
                let tries = match self.db.count_start_failure(job, &self.id).await {
                    Ok(Some(tries)) => tries,
                    Ok(None) => return None,
                    Err(se) => {
                        tracing::error!(worker = %self.id, job = %job.id, error = %e, storage_error = %se, "could not start the job's process nor count it; giving the job back");
                        self.give_back(job).await;
                        return None;
                    }
                };
                if tries >= START_TRIES {
                    tracing::error!(worker = %self.id, job = %job.id, error = %e, tries, "could not start the job's process; the job fails");
                    return Some(Finish::Failed {
                        error: start_failed_problem(&e, tries).to_json(),
                    });
                }
                tracing::error!(worker = %self.id, job = %job.id, error = %e, tries, "could not start the job's process; giving the job back");
                self.give_back(job).await;
                return None;
            }
        };
        // The heartbeat is also how a cancel reaches the engine (from any process): often
        // enough that a cancelled job stops within a second.
        let beat = Duration::from_millis((self.config.lease_ms as u64 / 3).clamp(100, 250));
        // The claim set the lease: the first beat is due one period later, not at once.
        let mut ticker = tokio::time::interval_at(tokio::time::Instant::now() + beat, beat);
        let mut grace_deadline: Option<tokio::time::Instant> = None;
        let mut give_back = false;
        let mut lost = false;
        let result = loop {
            let grace = async {
                match grace_deadline {
                    Some(d) => tokio::time::sleep_until(d).await,
                    None => std::future::pending().await,
                }
            };
            tokio::select! {
                r = engine.ended() => break r,
                _ = ticker.tick() => {
                    let (done, total) = (progress.done.load(Ordering::Relaxed), progress.total.load(Ordering::Relaxed));
                    match self.db.heartbeat(job, &self.id, self.config.lease_ms, done, total).await {
                        Ok(LeaseState::Held { cancel_requested }) => if cancel_requested { engine.stop() },
                        Ok(LeaseState::Lost) => {
                            tracing::warn!(worker = %self.id, job = %job.id, "lease lost; stopping");
                            lost = true;
                            engine.stop();
                        }
                        Err(e) => tracing::warn!(worker = %self.id, job = %job.id, error = %e, "heartbeat failed"),
                    }
                }
                _ = self.shutdown.changed(), if grace_deadline.is_none() => {
                    grace_deadline = Some(tokio::time::Instant::now() + Duration::from_millis(self.config.shutdown_grace_ms));
                }
                _ = grace => {
                    tracing::info!(worker = %self.id, job = %job.id, "shutdown grace over; giving the job back");
                    give_back = true;
                    engine.stop();
                    grace_deadline = Some(tokio::time::Instant::now() + Duration::from_secs(3600));
                }
            }
        };
        if lost {
            return None;
        }
        match result {
            Ended::Returned(Ok(out)) => Some(Finish::Succeeded {
                resources: out
                    .resources
                    .into_iter()
                    .map(|r| CreatedResource {
                        id: r.id,
                        kind: r.kind,
                        name: r.name,
                        media_type: r.media_type,
                        summary: r.summary,
                        content: r.content,
                    })
                    .collect(),
                summary: out.summary,
                rows: out.rows,
                samples: out.samples,
                artifacts: out.files,
                progress: (
                    progress.done.load(Ordering::Relaxed),
                    progress.total.load(Ordering::Relaxed),
                ),
            }),
            Ended::Returned(Err(JobFailure::Invalid(problem))) => Some(Finish::Failed {
                error: problem.to_json(),
            }),
            Ended::Returned(Err(JobFailure::Cancelled)) if give_back => {
                match self.db.release_job(job, &self.id).await {
                    Ok(_) => {
                        tracing::info!(worker = %self.id, job = %job.id, "job given back to the queue")
                    }
                    Err(e) => {
                        tracing::error!(worker = %self.id, job = %job.id, error = %e, "could not give the job back; its lease will expire")
                    }
                }
                None
            }
            Ended::Returned(Err(JobFailure::Cancelled)) => Some(Finish::Cancelled),
            Ended::Died(problem) => {
                tracing::error!(worker = %self.id, job = %job.id, error = %problem.detail, "the job's process died");
                Some(Finish::Failed {
                    error: problem.to_json(),
                })
            }
            Ended::Panicked(said) => {
                tracing::error!(worker = %self.id, job = %job.id, error = %said, "engine panicked");
                Some(Finish::Failed {
                    error: Problem::internal("the engine stopped on an internal error while running this job; this is a bug in millsim, please report it with the job id").to_json(),
                })
            }
        }
    }

    /// Gives a job back after a failure that is not the job's (no process, no directory)
    /// and waits a little before the next claim.
    async fn give_back(&self, job: &ClaimedJob) {
        if let Err(e) = self.db.release_job(job, &self.id).await {
            tracing::error!(worker = %self.id, job = %job.id, error = %e, "could not give the job back; its lease will expire");
        }
        tokio::time::sleep(Duration::from_millis(STORAGE_BACKOFF_MS)).await;
    }

    /// Starts the job's engine work: in a child process, or on a blocking thread. Either
    /// writes the stock it exports into `work_dir`.
    fn start_engine(
        &self,
        job: &ClaimedJob,
        kind: JobKind,
        inputs: LoadedInputs,
        progress: Arc<SharedProgress>,
        work_dir: &std::path::Path,
    ) -> std::io::Result<Engine> {
        let options = job.spec["options"].clone();
        let limits = self.config.limits;
        match self.config.isolation {
            Isolation::Process => Ok(Engine::Process(isolate::spawn(
                kind,
                &options,
                inputs,
                limits,
                progress,
                Some(self.db.clone()),
                work_dir,
            )?)),
            Isolation::Thread => {
                let cancel = CancelFlag::new();
                let flag = cancel.clone();
                let stock_file = work_dir.join("stock.stl");
                let handle = tokio::task::spawn_blocking(move || {
                    kind.run(
                        &options,
                        inputs,
                        &limits,
                        &flag,
                        progress.as_ref(),
                        Some(&stock_file),
                    )
                    .map(isolate::ParentOutput::from)
                });
                Ok(Engine::Thread { handle, cancel })
            }
        }
    }
}

/// The problem of a job whose process could not be started `tries` times.
fn start_failed_problem(e: &std::io::Error, tries: i64) -> Problem {
    let exe = std::env::current_exe()
        .map(|p| p.display().to_string())
        .unwrap_or_else(|e| format!("(unknown: {e})"));
    Problem::new(
        StatusCode::INTERNAL_SERVER_ERROR,
        "job-not-started",
        "The job's process could not be started",
        format!(
            "the server could not start the process that runs this job (`{exe} job-exec`) {tries} times: {e}; the job is not tried again. Check the server's limits (ulimit -v, -n, -u) and that its executable is still in place"
        ),
    )
    .with("tries", tries)
    .with("error", e.to_string())
}

/// A job's engine work as it runs.
enum Engine {
    Process(isolate::ChildJob),
    Thread {
        handle: tokio::task::JoinHandle<Result<isolate::ParentOutput, JobFailure>>,
        cancel: CancelFlag,
    },
}

impl Engine {
    /// Asks the work to stop: the child is killed, the thread's flag set.
    fn stop(&self) {
        match self {
            Engine::Process(child) => child.kill(),
            Engine::Thread { cancel, .. } => cancel.cancel(),
        }
    }

    /// How it ended (cancel-safe: may be polled again after another branch won).
    async fn ended(&mut self) -> Ended {
        match self {
            Engine::Process(child) => (&mut child.ended).await,
            Engine::Thread { handle, .. } => match handle.await {
                Ok(r) => Ended::Returned(r),
                Err(join) => Ended::Panicked(join.to_string()),
            },
        }
    }
}
