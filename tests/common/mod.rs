//! Test harness: runs the real `millsim` binary on 127.0.0.1:0 with a temporary SQLite
//! file (or, with MILLSIM_TEST_DATABASE=postgres://..., a fresh PostgreSQL database) and
//! talks to it over HTTP.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

pub const BIN: &str = env!("CARGO_BIN_EXE_millsim");

pub fn corpus(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/corpus")
        .join(rel)
}

/// Whether the shared corpus beside the project is there; a clone does not have it, and a
/// test that reads it then skips, saying so.
pub fn corpus_present() -> bool {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    let present = dir.is_dir();
    if !present {
        skip(&format!(
            "{} (the shared corpus is not part of a clone)",
            dir.display()
        ));
    }
    present
}

/// Says on the run's output that the running test checks nothing (or less) for want of
/// `what`: `SKIPPED: <test> needs <what>`. Written to the stderr handle itself, because the
/// harness captures `println!` and `eprintln!` and shows them only for a failing test; the
/// test's name is its thread's, which the harness gives it.
pub fn skip(what: &str) {
    use std::io::Write;
    let thread = std::thread::current();
    let test = thread.name().unwrap_or("a test");
    // One write, so that the line stays whole among the harness's own output.
    let line = format!("SKIPPED: {test} needs {what}\n");
    let _ = std::io::stderr().write_all(line.as_bytes());
}

/// A stability job that runs for about a minute and counts its speeds as progress:
/// semi-discretization over 20,000 speeds, two modes a direction.
pub fn long_stability_job() -> Value {
    let mode = |f: f64| serde_json::json!({"freq_hz": f, "damping": 0.02, "stiffness_n_m": 2e6});
    serde_json::json!({"kind": "stability", "options": {"method": "sdm", "teeth": 2, "ktc_n_mm2": 600, "krc_n_mm2": 200,
        "radial_immersion": 0.5, "milling": "down",
        "modes_x": [mode(900.0), mode(1400.0)], "modes_y": [mode(950.0), mode(1500.0)],
        "rpm": {"from": 5000, "to": 25000, "step": 1}, "steps_per_period": 40}})
}

/// The Fusion 360 adaptive program the project holds (examples/adaptive), for tests that
/// need a real program whatever the checkout.
pub fn adaptive_program() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/adaptive/1055_utab_265bit.nc")
}

/// The PostgreSQL server the suite runs against (MILLSIM_TEST_DATABASE, a URL whose
/// database the tests may create others from); None: SQLite files.
pub fn test_postgres() -> Option<String> {
    std::env::var("MILLSIM_TEST_DATABASE")
        .ok()
        .filter(|u| u.starts_with("postgres://") || u.starts_with("postgresql://"))
}

/// The PostgreSQL server for a test that needs one; None (after saying why) without it.
pub fn require_postgres() -> Option<String> {
    let url = test_postgres();
    if url.is_none() {
        skip("MILLSIM_TEST_DATABASE naming a PostgreSQL server (.ci/run sets it)");
    }
    url
}

/// The database URL of a test server whose database is `path`: that SQLite file, or on
/// PostgreSQL a database of its own named after the path (so a server restarted on the
/// same path finds its jobs again), created on first use.
pub fn db_url(path: &Path) -> String {
    match test_postgres() {
        Some(base) => postgres::database_for(&base, &path.display().to_string()),
        None => format!("sqlite://{}", path.display()),
    }
}

mod postgres {
    use sqlx::Connection;

    pub fn database_for(base: &str, key: &str) -> String {
        // FNV-1a: a stable, short name for the path.
        let hash = key.bytes().fold(0xcbf29ce484222325u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x100000001b3)
        });
        let name = format!("millsim_t_{hash:016x}");
        let (base, query) = base.split_once('?').map_or((base, ""), |(b, q)| (b, q));
        let server = base.rsplit_once('/').map_or(base, |(s, _)| s);
        let url = if query.is_empty() {
            format!("{server}/{name}")
        } else {
            format!("{server}/{name}?{query}")
        };
        let admin = base.to_string();
        let created = name.clone();
        // Tests call this from inside their own runtime: connect from a thread of its own.
        std::thread::spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap();
            rt.block_on(async {
                let mut c = sqlx::PgConnection::connect(&admin)
                    .await
                    .unwrap_or_else(|e| panic!("MILLSIM_TEST_DATABASE: {e}"));
                let exists: Option<i32> =
                    sqlx::query_scalar("SELECT 1 FROM pg_database WHERE datname = $1")
                        .bind(&created)
                        .fetch_optional(&mut c)
                        .await
                        .unwrap();
                if exists.is_none() {
                    sqlx::query(&format!("CREATE DATABASE {created}"))
                        .execute(&mut c)
                        .await
                        .unwrap();
                }
            })
        })
        .join()
        .unwrap();
        url
    }
}

pub struct Server {
    pub child: Child,
    pub base: String,
    pub db_url: String,
}

impl Server {
    /// Starts `millsim serve` on a free port against `db` (a file path).
    pub fn start(db: &Path, extra: &[&str]) -> Server {
        Self::start_with_env(db, extra, &[])
    }

    /// `start` with extra environment variables for the server process.
    pub fn start_with_env(db: &Path, extra: &[&str], env: &[(&str, &str)]) -> Server {
        Self::start_command(Command::new(BIN), db, extra, env)
    }

    /// `start` under an address-space limit of `kb` KiB (`ulimit -v`), as a service
    /// manager's `LimitAS=` starts it.
    pub fn start_under_ulimit_v(db: &Path, kb: u64, extra: &[&str]) -> Server {
        let mut sh = Command::new("sh");
        sh.args(["-c", &format!("ulimit -v {kb} && exec \"$0\" \"$@\""), BIN]);
        Self::start_command(sh, db, extra, &[])
    }

    /// `start` of another executable (a copy of the binary the test may remove).
    pub fn start_exe(exe: &Path, db: &Path, extra: &[&str]) -> Server {
        // A copy just written may still be open for writing in a process another test
        // thread forked (ETXTBSY until that child execs): wait for it to be runnable.
        for _ in 0..100 {
            match Command::new(exe).arg("--version").output() {
                Err(e) if e.raw_os_error() == Some(26) => {
                    std::thread::sleep(Duration::from_millis(20))
                }
                _ => break,
            }
        }
        Self::start_command(Command::new(exe), db, extra, &[])
    }

    fn start_command(mut cmd: Command, db: &Path, extra: &[&str], env: &[(&str, &str)]) -> Server {
        let db_url = db_url(db);
        let mut child = cmd
            .args(["serve", "--bind", "127.0.0.1:0", "--database", &db_url])
            .args(extra)
            .env("RUST_LOG", "warn")
            .envs(env.iter().copied())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start millsim serve");
        let stdout = child.stdout.take().unwrap();
        let mut line = String::new();
        BufReader::new(stdout)
            .read_line(&mut line)
            .expect("read the listening line");
        let base = line
            .trim()
            .strip_prefix("millsim listening on ")
            .unwrap_or_else(|| panic!("unexpected first line: {line:?}"))
            .to_string();
        Server {
            child,
            base,
            db_url,
        }
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// SIGTERM, then wait for the process to exit; returns its exit status success.
    pub fn terminate(mut self) -> bool {
        let pid = self.child.id() as i32;
        unsafe_kill(pid, 15);
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status.success();
            }
            if Instant::now() > deadline {
                let _ = self.child.kill();
                return false;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A child process (a worker, an API) killed when the test ends however it ends: a failed
/// assertion would otherwise leave it running against the test's database.
pub struct KilledOnDrop(pub Child);

impl std::ops::Deref for KilledOnDrop {
    type Target = Child;
    fn deref(&self) -> &Child {
        &self.0
    }
}

impl std::ops::DerefMut for KilledOnDrop {
    fn deref_mut(&mut self) -> &mut Child {
        &mut self.0
    }
}

impl Drop for KilledOnDrop {
    fn drop(&mut self) {
        if let Ok(None) = self.0.try_wait() {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
}

/// Sends a signal with the `kill` command (no libc dependency for one call).
pub fn unsafe_kill(pid: i32, signal: i32) {
    let _ = Command::new("kill")
        .args([format!("-{signal}"), pid.to_string()])
        .status();
}

pub fn client() -> reqwest::Client {
    reqwest::Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .unwrap()
}

pub async fn json(res: reqwest::Response) -> (u16, Value) {
    let status = res.status().as_u16();
    let text = res.text().await.unwrap();
    (
        status,
        serde_json::from_str(&text).unwrap_or(Value::String(text)),
    )
}

/// Creates a resource (POST `path` with `body`; it must be accepted) and returns its id.
pub async fn create(c: &reqwest::Client, s: &Server, path: &str, body: Value) -> String {
    let (st, v) = post_json(c, s, path, &body).await;
    assert_eq!(st, 201, "{path}: {v}");
    v["id"].as_str().unwrap().to_string()
}

/// A closed STL of the box `lo`..`hi`, as the engine's exporter writes a block stock
/// (outward normals).
pub fn exported_box_stl(lo: [f64; 3], hi: [f64; 3]) -> Vec<u8> {
    let stock = millsim_engine::geometry::Stock::block(lo, hi, 0.5).unwrap();
    millsim_engine::geometry::export_stl_vec(&stock).unwrap().0
}

/// The block stock the slot tests cut (with [`post_slot_tool`]'s tool): 100 × 40 × 10 mm,
/// x 0 to 100, y −20 to 20, its top at z 0.
pub fn slot_block() -> Value {
    serde_json::json!({"kind": "block", "min": [0, -20, -10], "max": [100, 20, 0]})
}

/// Uploads a program file and returns its id.
pub async fn upload_program(c: &reqwest::Client, s: &Server, path: &Path) -> String {
    let name = path.file_name().unwrap().to_string_lossy().to_string();
    post_program(c, s, &name, std::fs::read(path).unwrap()).await
}

/// Uploads a program's text as `name` (it must be accepted) and returns its id.
pub async fn post_program(
    c: &reqwest::Client,
    s: &Server,
    name: &str,
    text: impl Into<reqwest::Body>,
) -> String {
    let (status, v) = json(
        c.post(s.url(&format!("/v1/programs?name={name}")))
            .header("content-type", "text/plain")
            .body(text)
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(status, 201, "{v}");
    v["id"].as_str().unwrap().to_string()
}

/// Creates the tool the slot tests cut with (flat Ø10, 4 flutes, no helix, 20 mm flutes)
/// and returns its id.
pub async fn post_slot_tool(c: &reqwest::Client, s: &Server) -> String {
    let tool = serde_json::json!({"type": "flat", "diameter_mm": 10.0, "flutes": 4, "helix_deg": 0.0, "flute_length_mm": 20.0});
    let (status, v) = post_json(c, s, "/v1/tools", &tool).await;
    assert_eq!(status, 201, "{v}");
    v["id"].as_str().unwrap().to_string()
}

/// Submits a job (it must be accepted), waits up to `within` for it and returns it,
/// asserting that it succeeded.
pub async fn run_job(c: &reqwest::Client, s: &Server, body: &Value, within: Duration) -> Value {
    let (status, job) = post_json(c, s, "/v1/jobs", body).await;
    assert_eq!(status, 202, "{job}");
    let done = wait_job(c, s, job["id"].as_str().unwrap(), within).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    done
}

pub async fn submit_interpret(c: &reqwest::Client, s: &Server, program: &str) -> Value {
    let (status, v) = json(
        c.post(s.url("/v1/jobs"))
            .json(&serde_json::json!({"kind": "interpret", "inputs": {"program": program}}))
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert_eq!(status, 202, "{v}");
    v
}

/// Polls a job until it is in a terminal state.
pub async fn wait_job(c: &reqwest::Client, s: &Server, id: &str, within: Duration) -> Value {
    let deadline = Instant::now() + within;
    loop {
        let (_, v) = json(
            c.get(s.url(&format!("/v1/jobs/{id}")))
                .send()
                .await
                .unwrap(),
        )
        .await;
        if matches!(
            v["status"].as_str(),
            Some("succeeded" | "failed" | "cancelled")
        ) {
            return v;
        }
        assert!(
            Instant::now() < deadline,
            "job {id} did not finish in {within:?}: {v}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Runs `millsim interpret FILE ARGS...`, asserts it succeeded, and returns its moves.
pub fn interpret_moves(file: &Path, args: &[&str]) -> Vec<Value> {
    let out = std::process::Command::new(BIN)
        .arg("interpret")
        .arg(file)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}: {}",
        file.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// GET a JSON document from the server.
pub async fn get_json(c: &reqwest::Client, s: &Server, path: &str) -> Value {
    json(c.get(s.url(path)).send().await.unwrap()).await.1
}

/// POST a JSON body; the status and the response's JSON.
pub async fn post_json(c: &reqwest::Client, s: &Server, path: &str, body: &Value) -> (u16, Value) {
    json(c.post(s.url(path)).json(body).send().await.unwrap()).await
}

/// POST an STL file (a stock upload); the status and the response's JSON.
pub async fn post_stl(c: &reqwest::Client, s: &Server, path: &str, stl: Vec<u8>) -> (u16, Value) {
    json(
        c.post(s.url(path))
            .header("content-type", "model/stl")
            .body(stl)
            .send()
            .await
            .unwrap(),
    )
    .await
}

/// POSTs an STL to /v1/stocks in chunked transfer (no Content-Length), 64 KiB a chunk.
/// None when the server answered and closed before the whole body was sent (a refusal
/// of the request as a whole; its answer is then not read).
pub async fn post_stl_chunked(c: &reqwest::Client, s: &Server, stl: &[u8]) -> Option<(u16, Value)> {
    let chunks: Vec<Result<Vec<u8>, std::io::Error>> =
        stl.chunks(1 << 16).map(|c| Ok(c.to_vec())).collect();
    let res = c
        .post(s.url("/v1/stocks"))
        .header("content-type", "model/stl")
        .body(reqwest::Body::wrap_stream(futures_util::stream::iter(
            chunks,
        )))
        .send()
        .await
        .ok()?;
    Some(json(res).await)
}

/// POSTs an STL to /v1/stocks as a multipart form's `file` part named `file_name`.
pub async fn post_stl_multipart(
    c: &reqwest::Client,
    s: &Server,
    stl: Vec<u8>,
    file_name: &str,
) -> (u16, Value) {
    let form = reqwest::multipart::Form::new().part(
        "file",
        reqwest::multipart::Part::bytes(stl).file_name(file_name.to_string()),
    );
    json(
        c.post(s.url("/v1/stocks"))
            .multipart(form)
            .send()
            .await
            .unwrap(),
    )
    .await
}

/// GET a path's body as text (CSV results, programs).
pub async fn get_text(c: &reqwest::Client, s: &Server, path: &str) -> String {
    c.get(s.url(path))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap()
}

/// Runs one SQL statement on a test server's database (SQLite file or PostgreSQL), from a
/// connection of its own: for tests that change what is stored under a running server.
pub async fn sql(db_url: &str, statement: &str) {
    use sqlx::Connection;
    if db_url.starts_with("sqlite:") {
        let mut conn = sqlx::SqliteConnection::connect(db_url).await.unwrap();
        sqlx::query(statement).execute(&mut conn).await.unwrap();
        conn.close().await.unwrap();
    } else {
        let mut conn = sqlx::PgConnection::connect(db_url).await.unwrap();
        sqlx::query(statement).execute(&mut conn).await.unwrap();
        conn.close().await.unwrap();
    }
}

/// The one integer a query on a test server's database answers (`SELECT COUNT(*) ...`).
pub async fn sql_i64(db_url: &str, query: &str) -> i64 {
    use sqlx::Connection;
    if db_url.starts_with("sqlite:") {
        let mut conn = sqlx::SqliteConnection::connect(db_url).await.unwrap();
        let n = sqlx::query_scalar(query)
            .fetch_one(&mut conn)
            .await
            .unwrap();
        conn.close().await.unwrap();
        n
    } else {
        let mut conn = sqlx::PgConnection::connect(db_url).await.unwrap();
        let n = sqlx::query_scalar(query)
            .fetch_one(&mut conn)
            .await
            .unwrap();
        conn.close().await.unwrap();
        n
    }
}

/// A memory figure of a process from /proc/PID/status, kB (`VmRSS`, `VmHWM`: its peak).
pub fn proc_kb(pid: u32, field: &str) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    status
        .lines()
        .find(|l| l.starts_with(field) && l[field.len()..].starts_with(':'))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}

/// Resets a process's peak resident memory (VmHWM) to its current one (Linux
/// `clear_refs` 5), so that a test measures the peak of what it does next.
pub fn reset_peak_rss(pid: u32) {
    std::fs::write(format!("/proc/{pid}/clear_refs"), "5").unwrap();
}
