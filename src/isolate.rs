//! Containment: a job's engine work runs in a child process (`millsim job-exec`, this same
//! binary) under an address-space limit, so a job that runs out of memory, aborts or
//! crashes ends its own process and not the server or the other jobs; cancel, a lost
//! lease and the end of the shutdown grace kill it at once.
//!
//! The child reads the job from stdin and writes progress and the outcome to stdout, as
//! frames `[tag: u8][length: u64 LE][payload]`:
//! - parent → child: `J` the job (kind, options, limits, each input's name, file name and
//!   media type), then one `B` frame per input with its content, in the same order;
//! - child → parent: `P` progress (done, total as two u64) at most every 100 ms; then `S`
//!   the summary, `R` per row, `M` per sample (u64 row seq, then the JSON), `F` a file's
//!   name, media type and file name followed by a `B` with its content, `W` a file the
//!   job wrote in its directory (name, media type, file name, the file and its length:
//!   large files go to storage from there, never whole through the worker's memory), `N`
//!   a resource the job made (JSON), and `D` done; or
//!   `X` a problem document (the inputs are at fault), or `C` cancelled.
//!
//! A child that ends without an outcome frame died: killed by a signal (the kernel's OOM
//! killer, SIGSEGV) or aborted (an allocation over the address-space limit aborts with
//! `memory allocation of N bytes failed`). The job is then failed with a `resource-limit`
//! problem after that one attempt.

use std::io::{BufReader, BufWriter, Read, Write};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{ExitCode, Stdio};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use serde_json::Value;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt};

use millsim_engine::geometry::Mesh;
use millsim_engine::job::{CancelFlag, Progress};

use crate::job_budget::JobLimits;
use crate::jobs::{
    JobFailure, JobKind, JobOutput, LoadedInput, LoadedInputs, OutputFile, OutputResource,
};
use crate::problem::Problem;
use crate::queue::SharedProgress;
use crate::store::artifacts::{Artifact, ArtifactContent};
use crate::store::chunks::CHUNK_BYTES;
use crate::store::Db;

const JOB: u8 = b'J';
const BYTES: u8 = b'B';
const PROGRESS: u8 = b'P';
const SUMMARY: u8 = b'S';
const ROW: u8 = b'R';
const SAMPLE: u8 = b'M';
const FILE: u8 = b'F';
const DONE: u8 = b'D';
const PROBLEM: u8 = b'X';
const CANCELLED: u8 = b'C';
const RESOURCE: u8 = b'N';
const WRITTEN: u8 = b'W';

/// Largest frame either side accepts (an STL stock upload is at most a few hundred MiB).
const MAX_FRAME: u64 = 8 << 30;

/// Address space the child may reserve beyond the job's memory budget: code, thread
/// stacks and the allocator's per-thread arenas (reserved, mostly never touched).
pub fn address_space_limit(limits: &JobLimits) -> u64 {
    limits.memory_bytes + address_space_overhead()
}

/// What a job process's address space holds besides its budget: the executable, libraries
/// and a stack and arena per core.
fn address_space_overhead() -> u64 {
    let cores = std::thread::available_parallelism()
        .map(|n| n.get() as u64)
        .unwrap_or(1);
    (512 << 20) + cores * (128 << 20)
}

/// The hard address-space limit this process inherited (`ulimit -v`, a service manager's
/// `LimitAS=`, `prlimit`), bytes; None when unlimited. A job process cannot be given more.
pub fn inherited_address_space() -> Option<u64> {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes the struct it is given.
    if unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut r) } != 0 || r.rlim_max == libc::RLIM_INFINITY
    {
        return None;
    }
    Some(r.rlim_max as u64)
}

/// The largest job memory budget (MiB) whose address space fits under an inherited limit of
/// `bytes` (at least 64 MiB, the smallest budget).
pub fn budget_under_address_space(bytes: u64) -> u64 {
    (bytes.saturating_sub(address_space_overhead()) >> 20).max(64)
}

#[derive(Serialize, Deserialize)]
struct JobHeader {
    kind: JobKind,
    options: Value,
    limits: JobLimits,
    inputs: Vec<InputHeader>,
    /// The job's directory, made and removed by the worker: where the job writes its
    /// large files.
    #[serde(default)]
    work_dir: Option<PathBuf>,
}

#[derive(Serialize, Deserialize)]
struct InputHeader {
    name: String,
    file_name: Option<String>,
    media_type: String,
}

#[derive(Serialize, Deserialize)]
struct FileHeader {
    name: String,
    media_type: String,
    file_name: String,
}

/// A file the job wrote in its directory.
#[derive(Serialize, Deserialize)]
struct WrittenHeader {
    name: String,
    media_type: String,
    file_name: String,
    /// The file's name in the job's directory (no path).
    file: String,
    len: u64,
}

/// Files the job made in memory larger than this are written to its directory and sent
/// as `W` frames, so the worker does not hold them.
const WRITE_FILES_OVER: usize = CHUNK_BYTES;

fn write_frame(w: &mut impl Write, tag: u8, payload: &[u8]) -> std::io::Result<()> {
    w.write_all(&[tag])?;
    w.write_all(&(payload.len() as u64).to_le_bytes())?;
    w.write_all(payload)
}

fn read_frame(r: &mut impl Read) -> std::io::Result<(u8, Vec<u8>)> {
    let mut head = [0u8; 9];
    r.read_exact(&mut head)?;
    let len = u64::from_le_bytes(head[1..9].try_into().expect("8 bytes"));
    if len > MAX_FRAME {
        return Err(std::io::Error::other(format!("frame of {len} bytes")));
    }
    let mut payload = vec![0u8; len as usize];
    r.read_exact(&mut payload)?;
    Ok((head[0], payload))
}

async fn read_frame_async(r: &mut (impl AsyncRead + Unpin)) -> std::io::Result<(u8, Vec<u8>)> {
    let mut head = [0u8; 9];
    r.read_exact(&mut head).await?;
    let len = u64::from_le_bytes(head[1..9].try_into().expect("8 bytes"));
    if len > MAX_FRAME {
        return Err(std::io::Error::other(format!("frame of {len} bytes")));
    }
    let mut payload = vec![0u8; len as usize];
    r.read_exact(&mut payload).await?;
    Ok((head[0], payload))
}

/// Progress to the parent, at most every 100 ms (and always the last report).
struct PipeProgress {
    out: Arc<Mutex<BufWriter<std::fs::File>>>,
    last: Mutex<Option<Instant>>,
}

impl Progress for PipeProgress {
    fn report(&self, done: u64, total: u64) {
        {
            let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
            if done < total && last.is_some_and(|t| t.elapsed() < Duration::from_millis(100)) {
                return;
            }
            *last = Some(Instant::now());
        }
        let mut payload = [0u8; 16];
        payload[..8].copy_from_slice(&done.to_le_bytes());
        payload[8..].copy_from_slice(&total.to_le_bytes());
        let mut out = self.out.lock().unwrap_or_else(|e| e.into_inner());
        // A parent that went away kills this process soon (PDEATHSIG): nothing to do here.
        let _ = write_frame(&mut *out, PROGRESS, &payload).and_then(|_| out.flush());
    }
}

/// `millsim job-exec`: runs one job read from stdin, writes its progress and outcome to
/// stdout (see the module's doc). Exit 0 whenever an outcome was written.
pub fn job_exec_main() -> ExitCode {
    let mut stdin = BufReader::new(std::io::stdin().lock());
    let mut read = || -> std::io::Result<(JobHeader, LoadedInputs)> {
        let (tag, payload) = read_frame(&mut stdin)?;
        if tag != JOB {
            return Err(std::io::Error::other("the first frame is not a job"));
        }
        let header: JobHeader = serde_json::from_slice(&payload)?;
        let mut inputs = LoadedInputs::new();
        for i in &header.inputs {
            if i.media_type == "model/stl" {
                // Read into a mesh as it streams in: the file is never whole in memory.
                let mut head = [0u8; 9];
                stdin.read_exact(&mut head)?;
                if head[0] != BYTES {
                    return Err(std::io::Error::other("an input frame is not bytes"));
                }
                let len = u64::from_le_bytes(head[1..9].try_into().expect("8 bytes"));
                let mut frame = (&mut stdin).take(len);
                let mesh = Mesh::from_stl_reader_repaired(&mut frame, len)
                    .map(|(mesh, repairs)| (Arc::new(mesh), repairs));
                // What a refused file left unread belongs to this frame.
                std::io::copy(&mut frame, &mut std::io::sink())?;
                inputs.insert(
                    i.name.clone(),
                    LoadedInput {
                        file_name: i.file_name.clone(),
                        media_type: i.media_type.clone(),
                        mesh: Some(mesh),
                        ..Default::default()
                    },
                );
                continue;
            }
            let (tag, content) = read_frame(&mut stdin)?;
            if tag != BYTES {
                return Err(std::io::Error::other("an input frame is not bytes"));
            }
            inputs.insert(
                i.name.clone(),
                LoadedInput {
                    file_name: i.file_name.clone(),
                    media_type: i.media_type.clone(),
                    content,
                    ..Default::default()
                },
            );
        }
        Ok((header, inputs))
    };
    let (header, inputs) = match read() {
        Ok(v) => v,
        Err(e) => {
            eprintln!("millsim job-exec: reading the job: {e}");
            return ExitCode::from(2);
        }
    };
    // The frames get stdout to themselves: anything else printed goes to stderr.
    let frames = match private_stdout() {
        Ok(f) => f,
        Err(e) => {
            eprintln!("millsim job-exec: taking stdout: {e}");
            return ExitCode::from(2);
        }
    };
    let out = Arc::new(Mutex::new(BufWriter::with_capacity(1 << 16, frames)));
    let progress = PipeProgress {
        out: out.clone(),
        last: Mutex::new(None),
    };
    // The stock, the largest file a job makes, goes straight to the job's directory.
    let stock_file = header.work_dir.as_ref().map(|d| d.join("stock.stl"));
    let result = header.kind.run(
        &header.options,
        inputs,
        &header.limits,
        &CancelFlag::new(),
        &progress,
        stock_file.as_deref(),
    );
    let mut out = out.lock().unwrap_or_else(|e| e.into_inner());
    let written = match result {
        Ok(output) => write_output(&mut *out, output, header.work_dir.as_deref()),
        Err(JobFailure::Invalid(problem)) => {
            write_frame(&mut *out, PROBLEM, problem.to_json().to_string().as_bytes())
        }
        Err(JobFailure::Cancelled) => write_frame(&mut *out, CANCELLED, &[]),
    };
    match written.and_then(|_| out.flush()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("millsim job-exec: writing the outcome: {e}");
            ExitCode::from(3)
        }
    }
}

/// A private handle on stdout for the frames; file descriptor 1 then points at stderr.
fn private_stdout() -> std::io::Result<std::fs::File> {
    use std::os::fd::FromRawFd;
    // SAFETY: plain descriptor calls; the duplicate is owned by the File alone.
    unsafe {
        let fd = libc::dup(1);
        if fd < 0 {
            return Err(std::io::Error::last_os_error());
        }
        if libc::dup2(2, 1) < 0 {
            return Err(std::io::Error::last_os_error());
        }
        Ok(std::fs::File::from_raw_fd(fd))
    }
}

fn write_output(
    w: &mut impl Write,
    output: JobOutput,
    work_dir: Option<&Path>,
) -> std::io::Result<()> {
    write_frame(w, SUMMARY, output.summary.to_string().as_bytes())?;
    for row in &output.rows {
        write_frame(w, ROW, row.as_bytes())?;
    }
    for (seq, json) in &output.samples {
        let mut payload = Vec::with_capacity(8 + json.len());
        payload.extend_from_slice(&(*seq as u64).to_le_bytes());
        payload.extend_from_slice(json.as_bytes());
        write_frame(w, SAMPLE, &payload)?;
    }
    for (i, f) in output.files.into_iter().enumerate() {
        let (path, len) = match (f.content, work_dir) {
            (ArtifactContent::File { path, len }, _) => (path, len),
            (ArtifactContent::Bytes(content), Some(dir)) if content.len() > WRITE_FILES_OVER => {
                let path = dir.join(format!("file-{i}"));
                std::fs::write(&path, &content)?;
                (path, content.len() as u64)
            }
            (ArtifactContent::Bytes(content), _) => {
                let header = FileHeader {
                    name: f.name,
                    media_type: f.media_type.to_string(),
                    file_name: f.file_name,
                };
                write_frame(w, FILE, &serde_json::to_vec(&header)?)?;
                write_frame(w, BYTES, &content)?;
                continue;
            }
        };
        let file = path
            .file_name()
            .and_then(|n| n.to_str())
            .filter(|_| work_dir.is_some_and(|d| path.parent() == Some(d)))
            .ok_or_else(|| {
                std::io::Error::other(format!("{} is not in the job's directory", path.display()))
            })?
            .to_string();
        let header = WrittenHeader {
            name: f.name,
            media_type: f.media_type.to_string(),
            file_name: f.file_name,
            file,
            len,
        };
        write_frame(w, WRITTEN, &serde_json::to_vec(&header)?)?;
    }
    for r in &output.resources {
        write_frame(w, RESOURCE, &serde_json::to_vec(r)?)?;
    }
    write_frame(w, DONE, &[])
}

/// How a job's engine work ended, in either way of running it.
pub enum Ended {
    /// The engine returned (output, a problem with the inputs, or cancelled).
    Returned(Result<ParentOutput, JobFailure>),
    /// The child died without an outcome: a `resource-limit` problem.
    Died(Problem),
    /// The engine panicked (a bug): what it said.
    Panicked(String),
}

/// A job's output as the parent stores it (file media types as strings).
pub struct ParentOutput {
    pub summary: Value,
    pub rows: Vec<String>,
    pub samples: Vec<(usize, String)>,
    pub files: Vec<Artifact>,
    pub resources: Vec<OutputResource>,
}

impl From<JobOutput> for ParentOutput {
    fn from(o: JobOutput) -> Self {
        ParentOutput {
            summary: o.summary,
            rows: o.rows,
            samples: o.samples,
            files: o
                .files
                .into_iter()
                .map(|f: OutputFile| Artifact {
                    name: f.name,
                    media_type: f.media_type.to_string(),
                    file_name: f.file_name,
                    content: f.content,
                })
                .collect(),
            resources: o.resources,
        }
    }
}

/// A job running in a child process.
pub struct ChildJob {
    pid: i32,
    /// Set when this side killed the child (cancel, lost lease, shutdown).
    killed: Arc<std::sync::atomic::AtomicBool>,
    /// Set once the child is reaped: its pid may then be another process's.
    reaped: Arc<std::sync::atomic::AtomicBool>,
    pub ended: std::pin::Pin<Box<dyn std::future::Future<Output = Ended> + Send>>,
}

impl ChildJob {
    /// Kills the child at once (SIGKILL); `ended` then resolves to cancelled.
    pub fn kill(&self) {
        if self.pid <= 0 || self.reaped.load(Ordering::SeqCst) {
            return;
        }
        if !self.killed.swap(true, Ordering::SeqCst) {
            // SAFETY: a plain signal to our own unreaped child (kill and `ended` run on the
            // same task, never at once).
            unsafe {
                libc::kill(self.pid, libc::SIGKILL);
            }
        }
    }
}

/// Starts `millsim job-exec` for a job, with its address space limited, dying with the
/// server (PR_SET_PDEATHSIG), and feeds it the job.
/// `db` is where inputs left in the database in chunks are read from as they are sent;
/// `work_dir` the job's directory (the worker's to remove), where it writes large files.
pub fn spawn(
    kind: JobKind,
    options: &Value,
    inputs: LoadedInputs,
    limits: JobLimits,
    progress: Arc<SharedProgress>,
    db: Option<Db>,
    work_dir: &Path,
) -> std::io::Result<ChildJob> {
    let exe = std::env::current_exe()?;
    let parent = std::process::id() as libc::pid_t;
    let address_space = address_space_limit(&limits);
    let mut cmd = std::process::Command::new(exe);
    cmd.arg("job-exec")
        // glibc keeps a heap arena per thread and returns little of it: with two the
        // adaptive example peaked at 146-159 MB instead of 170 MB, as fast.
        .env(
            "MALLOC_ARENA_MAX",
            std::env::var_os("MALLOC_ARENA_MAX").unwrap_or_else(|| "2".into()),
        )
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    // SAFETY: only async-signal-safe calls (setrlimit, prctl, getppid, _exit, open, write,
    // close) between fork and exec.
    unsafe {
        cmd.pre_exec(move || {
            // Never above an inherited hard limit: raising it fails (EPERM) and the job
            // would not start. The budget fits at start-up (the default lowered to it, an
            // explicit one over it refused); this guards against a limit lowered since.
            // (inherited_address_space only calls getrlimit: async-signal-safe.)
            let cap = match inherited_address_space() {
                Some(max) => address_space.min(max),
                None => address_space,
            } as libc::rlim_t;
            let limit = libc::rlimit {
                rlim_cur: cap,
                rlim_max: cap,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // The server died between fork and prctl: do not outlive it.
            if libc::getppid() != parent {
                libc::_exit(1);
            }
            // If the machine runs out of memory anyway, the kernel kills a job process
            // before the server (best effort: raising one's own score needs no privilege).
            let fd = libc::open(c"/proc/self/oom_score_adj".as_ptr(), libc::O_WRONLY);
            if fd >= 0 {
                libc::write(fd, b"1000".as_ptr().cast(), 4);
                libc::close(fd);
            }
            Ok(())
        });
    }
    let mut child = tokio::process::Command::from(cmd)
        .kill_on_drop(true)
        .spawn()?;
    let pid = child.id().map(|p| p as i32).unwrap_or(0);
    let mut stdin = child.stdin.take().expect("piped stdin");
    let mut stdout =
        tokio::io::BufReader::with_capacity(1 << 16, child.stdout.take().expect("piped stdout"));
    let mut stderr = child.stderr.take().expect("piped stderr");
    let header = JobHeader {
        kind,
        options: options.clone(),
        limits,
        inputs: inputs
            .iter()
            .map(|(name, i)| InputHeader {
                name: name.clone(),
                file_name: i.file_name.clone(),
                media_type: i.media_type.clone(),
            })
            .collect(),
        work_dir: Some(work_dir.to_path_buf()),
    };
    let header = serde_json::to_vec(&header)?;
    let work_dir = work_dir.to_path_buf();
    // The inputs go in on their own task: a child that dies early must not block them.
    tokio::spawn(async move {
        // A child that died early closed its end: its exit status says why.
        let _ = send_job(&mut stdin, &header, &inputs, db.as_ref()).await;
    });
    // The last few KiB of the child's stderr: what a dying process said.
    let stderr_tail = tokio::spawn(async move {
        let mut tail: Vec<u8> = Vec::new();
        let mut buf = [0u8; 4096];
        while let Ok(n) = stderr.read(&mut buf).await {
            if n == 0 {
                break;
            }
            tail.extend_from_slice(&buf[..n]);
            if tail.len() > 8192 {
                tail.drain(..tail.len() - 4096);
            }
        }
        String::from_utf8_lossy(&tail).trim().to_string()
    });
    let killed = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let reaped = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let (was_killed, now_reaped) = (killed.clone(), reaped.clone());
    let memory_mb = limits.memory_mb();
    let ended = Box::pin(async move {
        let outcome = read_outcome(&mut stdout, &progress, limits.memory_bytes, &work_dir).await;
        if outcome.is_some() {
            // Done, or results over the budget: either way nothing more is read.
            let _ = child.start_kill();
        }
        let status = child.wait().await;
        now_reaped.store(true, Ordering::SeqCst);
        let said = stderr_tail.await.unwrap_or_default();
        match outcome {
            Some(result) => Ended::Returned(result),
            None if was_killed.load(Ordering::SeqCst) => {
                Ended::Returned(Err(JobFailure::Cancelled))
            }
            None => match status {
                Ok(s) if s.code() == Some(101) => Ended::Panicked(said),
                Ok(s) => Ended::Died(died_problem(s, &said, memory_mb)),
                Err(e) => Ended::Died(crate::job_budget::problems::process_died(
                    &format!("could not be waited for: {e}"),
                    &said,
                    memory_mb,
                )),
            },
        }
    });
    Ok(ChildJob {
        pid,
        killed,
        reaped,
        ended,
    })
}

async fn send_job(
    stdin: &mut tokio::process::ChildStdin,
    header: &[u8],
    inputs: &LoadedInputs,
    db: Option<&Db>,
) -> std::io::Result<()> {
    let frame = |tag: u8, len: usize| {
        let mut h = vec![tag];
        h.extend_from_slice(&(len as u64).to_le_bytes());
        h
    };
    stdin.write_all(&frame(JOB, header.len())).await?;
    stdin.write_all(header).await?;
    for i in inputs.values() {
        let Some(stored) = &i.stored_chunks else {
            stdin.write_all(&frame(BYTES, i.content.len())).await?;
            stdin.write_all(&i.content).await?;
            continue;
        };
        // A large input goes from the database to the child a chunk at a time.
        let db = db.ok_or_else(|| std::io::Error::other("a chunked input without its database"))?;
        stdin.write_all(&frame(BYTES, stored.size as usize)).await?;
        let mut sent = 0u64;
        for seq in 0..stored.chunks {
            let chunk = db
                .resource_chunk(&stored.resource_id, seq)
                .await
                .map_err(std::io::Error::other)?
                .ok_or_else(|| {
                    std::io::Error::other(format!(
                        "{} was deleted while it was sent",
                        stored.resource_id
                    ))
                })?;
            sent += chunk.len() as u64;
            if sent > stored.size {
                return Err(std::io::Error::other(
                    "stored chunks longer than the resource",
                ));
            }
            stdin.write_all(&chunk).await?;
        }
        if sent != stored.size {
            return Err(std::io::Error::other(
                "stored chunks shorter than the resource",
            ));
        }
    }
    stdin.flush().await
}

/// Reads frames until an outcome; None when the stream ends (or breaks) before one.
/// Results over `budget` bytes are refused (the server holds them until they are stored:
/// a job's budget bounds them too).
/// Files the job wrote (`W`) are taken from `work_dir` and not counted: they are not in
/// memory.
async fn read_outcome(
    r: &mut (impl AsyncRead + Unpin),
    progress: &SharedProgress,
    budget: u64,
    work_dir: &Path,
) -> Option<Result<ParentOutput, JobFailure>> {
    let mut out = ParentOutput {
        summary: Value::Null,
        rows: Vec::new(),
        samples: Vec::new(),
        files: Vec::new(),
        resources: Vec::new(),
    };
    let mut file: Option<FileHeader> = None;
    let mut received = 0u64;
    loop {
        let (tag, payload) = read_frame_async(r).await.ok()?;
        received += payload.len() as u64;
        if received > budget {
            return Some(Err(JobFailure::Invalid(
                crate::job_budget::problems::results_over_budget(budget),
            )));
        }
        match tag {
            PROGRESS if payload.len() == 16 => {
                let done = u64::from_le_bytes(payload[..8].try_into().ok()?);
                let total = u64::from_le_bytes(payload[8..].try_into().ok()?);
                progress.total.store(total, Ordering::Relaxed);
                progress.done.store(done, Ordering::Relaxed);
            }
            SUMMARY => out.summary = serde_json::from_slice(&payload).ok()?,
            ROW => out.rows.push(String::from_utf8(payload).ok()?),
            SAMPLE if payload.len() >= 8 => {
                let seq = u64::from_le_bytes(payload[..8].try_into().ok()?) as usize;
                out.samples
                    .push((seq, String::from_utf8(payload[8..].to_vec()).ok()?));
            }
            FILE => file = Some(serde_json::from_slice(&payload).ok()?),
            BYTES => {
                let h = file.take()?;
                out.files.push(Artifact {
                    name: h.name,
                    media_type: h.media_type,
                    file_name: h.file_name,
                    content: ArtifactContent::Bytes(payload),
                });
            }
            WRITTEN => {
                let h: WrittenHeader = serde_json::from_slice(&payload).ok()?;
                // A plain name in the job's directory, as long as the job said: anything
                // else is a broken child, as a malformed frame is.
                if h.file.is_empty() || h.file.contains('/') || h.file.starts_with('.') {
                    return None;
                }
                let path = work_dir.join(&h.file);
                let meta = tokio::fs::symlink_metadata(&path).await.ok()?;
                if !meta.is_file() || meta.len() != h.len {
                    return None;
                }
                out.files.push(Artifact {
                    name: h.name,
                    media_type: h.media_type,
                    file_name: h.file_name,
                    content: ArtifactContent::File { path, len: h.len },
                });
            }
            RESOURCE => out.resources.push(serde_json::from_slice(&payload).ok()?),
            DONE => return Some(Ok(out)),
            PROBLEM => {
                return Some(Err(JobFailure::Invalid(Problem::from_json(
                    serde_json::from_slice(&payload).ok()?,
                ))))
            }
            CANCELLED => return Some(Err(JobFailure::Cancelled)),
            _ => return None,
        }
    }
}

fn died_problem(status: std::process::ExitStatus, said: &str, memory_mb: u64) -> Problem {
    let how = match status.signal() {
        Some(sig) => format!("was killed by signal {sig} ({})", signal_name(sig)),
        None => format!(
            "exited with status {} without a result",
            status.code().unwrap_or(-1)
        ),
    };
    crate::job_budget::problems::process_died(&how, said, memory_mb)
}

fn signal_name(sig: i32) -> &'static str {
    match sig {
        libc::SIGKILL => "SIGKILL: the kernel's out-of-memory killer, or an operator",
        libc::SIGABRT => "SIGABRT: the process aborted, as on a failed allocation",
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGBUS => "SIGBUS",
        libc::SIGTERM => "SIGTERM",
        _ => "a signal",
    }
}
