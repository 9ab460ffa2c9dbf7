//! Jobs: submission (idempotent), status, cancellation, progress events, results.

use std::convert::Infallible;
use std::time::Duration;

use axum::extract::{Path, Request, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::Json;
use futures_util::stream;
use serde::Deserialize;
use serde_json::{json, Map, Value};
use sha2::{Digest, Sha256};

use super::auth::hex;
use super::body::read_limited;
use super::problem::{parse_json, ApiError};
use super::{parse_query, AppState, Owner, PageQuery};
use crate::jobs::{JobKind, StoredInput, SubmittedInputs};
use crate::store::artifacts::ArtifactBody;
use crate::store::jobs::{CreateOutcome, InlineInput, NewJob};
use crate::store::{Db, JobRecord, JobStatus, ResourceKind};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JobRequest {
    kind: String,
    #[serde(default)]
    inputs: Map<String, Value>,
    #[serde(default)]
    options: Option<Value>,
}

/// What a refused submission is told to wait: long enough for workers to start a few jobs.
const QUEUE_FULL_RETRY_AFTER_SECS: &str = "5";

fn job_response(status: StatusCode, job: &JobRecord, replayed: bool) -> Response {
    let mut res = (
        status,
        [(header::LOCATION, format!("/v1/jobs/{}", job.id))],
        Json(job),
    )
        .into_response();
    if replayed {
        res.headers_mut().insert(
            "idempotent-replayed",
            header::HeaderValue::from_static("true"),
        );
    }
    res
}

/// The `Idempotency-Key` header, if given: 1 to 255 visible ASCII characters.
fn idempotency_key(headers: &HeaderMap) -> Result<Option<String>, ApiError> {
    Ok(match headers.get("idempotency-key") {
        None => None,
        Some(v) => {
            let k = v
                .to_str()
                .map_err(|_| ApiError::bad_request("Idempotency-Key must be visible ASCII"))?
                .trim();
            if k.is_empty() || k.len() > 255 {
                return Err(ApiError::bad_request(
                    "Idempotency-Key must be 1 to 255 characters",
                ));
            }
            Some(k.to_string())
        }
    })
}

/// Each input the kind wants, as given: the id of a stored resource of the owner's
/// (checked to exist, and its size and summary kept for the submission's checks), or an
/// inline program (read and stored with the job).
async fn resolve_inputs(
    state: &AppState,
    owner: &str,
    job_kind: JobKind,
    given: &Map<String, Value>,
) -> Result<(Map<String, Value>, Vec<InlineInput>, SubmittedInputs), ApiError> {
    let mut inputs = Map::new();
    let mut inline = Vec::new();
    let mut submitted = SubmittedInputs::default();
    let wanted = job_kind.wanted_inputs(given.keys())?;
    for (name, kind, required) in wanted {
        let field = job_kind.input_field(name);
        match given.get(name) {
            None if required => {
                return Err(ApiError::invalid_field(
                    field,
                    format!("a `{}` job needs input `{name}`", job_kind.as_str()),
                ))
            }
            None => {}
            Some(Value::String(id)) => {
                let Some(record) = state.db.get_resource(owner, kind, id).await? else {
                    return Err(ApiError::invalid_field(
                        field,
                        format!("no {} with id `{id}`", kind.as_str()),
                    )
                    .with("id", id.clone()));
                };
                submitted.stored.push((
                    name.to_string(),
                    StoredInput {
                        size: record.size.max(0) as u64,
                        summary: record.summary,
                    },
                ));
                inputs.insert(name.to_string(), Value::String(id.clone()));
            }
            Some(Value::Object(o)) if kind == ResourceKind::Program => {
                let content = o.get("content").and_then(Value::as_str).ok_or_else(|| {
                    ApiError::invalid_field(
                        format!("{field}.content"),
                        "an inline program is {\"name\": ..., \"content\": \"G-code text\"}",
                    )
                })?;
                let file = o
                    .get("name")
                    .and_then(Value::as_str)
                    .unwrap_or("program.nc")
                    .to_string();
                // Up to the body limit of G-code: parsed off the async runtime, in turns
                // with the uploads (`parsing`).
                let (content, file, checked) = super::parsing::program(
                    content.as_bytes().to_vec(),
                    file,
                    state.limits.max_program_bytes,
                )
                .await?;
                inline.push(InlineInput {
                    input: name.to_string(),
                    kind,
                    name: Some(file),
                    media_type: checked.media_type,
                    summary: checked.summary,
                    content,
                });
            }
            Some(_) => {
                return Err(ApiError::invalid_field(
                    field,
                    format!(
                        "input `{name}` must be the id of a {} (a string)",
                        kind.as_str()
                    ),
                ))
            }
        }
    }
    submitted.inline_program = inline
        .iter()
        .find(|i| i.input == "program")
        .map(|i| i.content.len() as u64);
    Ok((inputs, inline, submitted))
}

pub async fn create(
    State(state): State<AppState>,
    Owner(owner): Owner,
    headers: HeaderMap,
    req: Request,
) -> Result<Response, ApiError> {
    super::guard::require_json(&headers)?;
    let bytes = read_limited(&headers, req.into_body(), state.limits.max_program_bytes)
        .await
        .map_err(super::resources::program_too_large)?;
    // Up to the body limit of JSON (an inline program): parsed and hashed off the async
    // runtime, as the program itself is read below.
    let (request, request_hash) = tokio::task::spawn_blocking(move || {
        let request: JobRequest = parse_json(&bytes)?;
        Ok::<_, ApiError>((request, hex(&Sha256::digest(&bytes))))
    })
    .await
    .map_err(|e| ApiError::blocking_failed(e, "the job request reader"))??;
    let key = idempotency_key(&headers)?;
    let job_kind = JobKind::from_request(&request.kind, "kind")?;
    let options = request.options.clone().unwrap_or_else(|| json!({}));
    if !options.is_object() {
        return Err(ApiError::invalid_field(
            "options",
            "`options` must be a JSON object",
        ));
    }

    // A process's operations are stored flat (see `jobs::process`).
    let mut given = request.inputs.clone();
    let mut options = options;
    if let Some(operations) = job_kind.flatten_operations(&mut given)? {
        if options.get("operations").is_some() {
            return Err(ApiError::invalid_field(
                "options.operations",
                "give the operations under inputs.operations, each with its own options",
            ));
        }
        options["operations"] = Value::Array(operations);
    }
    let (inputs, inline, submitted) = resolve_inputs(&state, &owner, job_kind, &given).await?;
    job_kind.check_submission(given.keys(), &options, &submitted, &state.job_limits)?;
    let outcome = state
        .db
        .create_job(
            &owner,
            NewJob {
                kind: request.kind,
                inputs,
                inline,
                options,
                idempotency_key: key.clone(),
                request_hash,
                max_attempts: state.max_attempts,
                max_queued: state.limits.max_queued_per_key,
            },
        )
        .await?;
    match outcome {
        CreateOutcome::Created(job) => {
            state.job_submitted.notify_one();
            Ok(job_response(StatusCode::ACCEPTED, &job, false))
        }
        CreateOutcome::Replayed(job) => Ok(job_response(StatusCode::ACCEPTED, &job, true)),
        CreateOutcome::KeyConflict(job) => Err(ApiError::conflict(format!(
            "Idempotency-Key `{}` was used for another request (job {}); use a new key for a new job",
            key.unwrap_or_default(),
            job.id
        ))
        .with("job_id", job.id)),
        CreateOutcome::QueueFull => {
            let limit = state.limits.max_queued_per_key;
            let mut res = ApiError::new(
                StatusCode::TOO_MANY_REQUESTS,
                "queue-full",
                "Too many queued jobs",
                format!(
                    "this API key already has {limit} queued jobs (max_queued_per_key); retry once some have started"
                ),
            )
            .with("limit", limit)
            .with("limit_name", "max_queued_per_key")
            .into_response();
            res.headers_mut().insert(
                header::RETRY_AFTER,
                header::HeaderValue::from_static(QUEUE_FULL_RETRY_AFTER_SECS),
            );
            Ok(res)
        }
    }
}

async fn find(db: &Db, owner: &str, id: &str) -> Result<JobRecord, ApiError> {
    db.get_job(owner, id)
        .await?
        .ok_or_else(|| ApiError::not_found("job", id))
}

pub async fn get_one(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Json<JobRecord>, ApiError> {
    Ok(Json(find(&state.db, &owner, &id).await?))
}

pub async fn list(
    State(state): State<AppState>,
    Owner(owner): Owner,
    req: Request,
) -> Result<Response, ApiError> {
    let q: PageQuery = parse_query(req.uri().query())?;
    let status = match &q.status {
        None => None,
        Some(s) => Some(JobStatus::parse(s).ok_or_else(|| {
            ApiError::invalid_field(
                "status",
                format!(
                    "unknown status `{s}`; one of: queued, running, succeeded, failed, cancelled"
                ),
            )
        })?),
    };
    if let Some(k) = &q.kind {
        JobKind::from_request(k, "kind")?;
    }
    let (items, next) = state
        .db
        .list_jobs(
            &owner,
            status,
            q.kind.as_deref(),
            q.cursor.as_deref(),
            q.limit()?,
        )
        .await?;
    Ok(Json(json!({ "items": items, "next_cursor": next })).into_response())
}

pub async fn delete(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let job = find(&state.db, &owner, &id).await?;
    if !job.status.is_terminal() {
        return Err(ApiError::conflict(format!(
            "job {id} is {}: cancel it first",
            job.status.as_str()
        ))
        .with("job_status", job.status.as_str()));
    }
    state.db.delete_job(&owner, &id).await?;
    Ok(StatusCode::NO_CONTENT.into_response())
}

pub async fn cancel(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let before = find(&state.db, &owner, &id).await?;
    if before.status.is_terminal() {
        return Err(
            ApiError::conflict(format!("job {id} already {}", before.status.as_str()))
                .with("job_status", before.status.as_str()),
        );
    }
    let job = state
        .db
        .cancel_job(&owner, &id)
        .await?
        .ok_or_else(|| ApiError::not_found("job", &id))?;
    Ok(job_response(StatusCode::ACCEPTED, &job, false))
}

pub async fn attempts(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    find(&state.db, &owner, &id).await?;
    let rows = state.db.job_attempts(&id).await?;
    let items: Vec<Value> = rows
        .into_iter()
        .map(|(attempt, worker, started, finished, outcome)| {
            json!({ "attempt": attempt, "worker": worker, "started_at": crate::store::rfc3339(started),
                    "finished_at": finished.map(crate::store::rfc3339), "outcome": outcome })
        })
        .collect();
    Ok(Json(json!({ "items": items })).into_response())
}

/// The job, which must have succeeded for its results to exist.
async fn succeeded(db: &Db, owner: &str, id: &str) -> Result<JobRecord, ApiError> {
    let job = find(db, owner, id).await?;
    if job.status != JobStatus::Succeeded {
        return Err(ApiError::conflict(format!(
            "job {id} is {}: results exist once it has succeeded",
            job.status.as_str()
        ))
        .with("job_status", job.status.as_str()));
    }
    Ok(job)
}

pub async fn summary(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let job = succeeded(&state.db, &owner, &id).await?;
    Ok(Json(job.summary.unwrap_or(Value::Null)).into_response())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BlocksQuery {
    format: Option<String>,
    /// CSV only: the columns to send (comma-separated), in the rows' order.
    columns: Option<String>,
    /// CSV only: fractional numbers to this many significant digits (as stored without).
    digits: Option<String>,
    cursor: Option<String>,
    limit: Option<String>,
}

pub async fn blocks(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
    req: Request,
) -> Result<Response, ApiError> {
    let q: BlocksQuery = parse_query(req.uri().query())?;
    let job = succeeded(&state.db, &owner, &id).await?;
    match q.format.as_deref().unwrap_or("json") {
        "json" => {
            if q.columns.is_some() || q.digits.is_some() {
                return Err(ApiError::invalid_field(
                    if q.columns.is_some() {
                        "columns"
                    } else {
                        "digits"
                    },
                    "columns and digits shape format=csv; JSON rows are whole",
                ));
            }
            let from = match &q.cursor {
                None => 0,
                Some(c) => c.parse::<i64>().ok().filter(|v| *v >= 0).ok_or_else(|| {
                    ApiError::invalid_field("cursor", format!("not a cursor of this route: `{c}`"))
                })?,
            };
            let limit = PageQuery {
                cursor: None,
                limit: q.limit.clone(),
                status: None,
                kind: None,
            }
            .limit()?;
            let rows = state.db.job_rows(&id, from, i64::from(limit) + 1).await?;
            let more = rows.len() > limit as usize;
            let items: Vec<Value> = rows
                .iter()
                .take(limit as usize)
                .map(|(_, d)| serde_json::from_str(d).unwrap_or(Value::Null))
                .collect();
            let next = if more {
                rows.get(limit as usize).map(|(seq, _)| seq.to_string())
            } else {
                None
            };
            Ok(Json(json!({ "items": items, "next_cursor": next })).into_response())
        }
        "csv" => {
            let declared: Option<Vec<String>> = job
                .summary
                .as_ref()
                .and_then(|s| s.get("row_columns"))
                .and_then(|c| serde_json::from_value(c.clone()).ok());
            let wanted = q.columns.as_deref().map(|c| {
                c.split(',')
                    .map(|w| w.trim().to_string())
                    .filter(|w| !w.is_empty())
                    .collect()
            });
            let digits = match q.digits.as_deref() {
                None => None,
                Some(d) => Some(
                    d.parse::<usize>()
                        .ok()
                        .filter(|d| (1..=17).contains(d))
                        .ok_or_else(|| {
                            ApiError::invalid_field(
                                "digits",
                                format!("`{d}` is not a number of significant digits from 1 to 17"),
                            )
                        })?,
                ),
            };
            super::rows_csv::csv_response(
                state.db.clone(),
                id,
                declared,
                wanted,
                crate::csv::Numbers { digits },
            )
            .await
        }
        other => Err(ApiError::invalid_field(
            "format",
            format!("unknown format `{other}`; one of: json, csv"),
        )),
    }
}

/// Largest block range one samples request may ask for.
const MAX_SAMPLE_RANGE: i64 = 10_000;

/// Per-step force samples of rows `from` to `to` (row seq numbers, inclusive), e.g.
/// `/blocks/100-250/samples`. Rows without engaged steps are left out.
pub async fn samples(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path((id, range)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    let bad = || {
        ApiError::invalid_field("range", format!("`{range}` is not a block range FROM-TO (row numbers, FROM <= TO, at most {MAX_SAMPLE_RANGE} rows)"))
    };
    let (from, to) = range.split_once('-').ok_or_else(bad)?;
    let (from, to) = (
        from.parse::<i64>().map_err(|_| bad())?,
        to.parse::<i64>().map_err(|_| bad())?,
    );
    if from < 0 || to < from || to - from >= MAX_SAMPLE_RANGE {
        return Err(bad());
    }
    succeeded(&state.db, &owner, &id).await?;
    let items: Vec<Value> = state
        .db
        .job_samples(&id, from, to)
        .await?
        .into_iter()
        .map(|(seq, data)| json!({ "row": seq, "samples": serde_json::from_str::<Value>(&data).unwrap_or(Value::Null) }))
        .collect();
    Ok(Json(json!({ "from": from, "to": to, "items": items })).into_response())
}

async fn artifact(
    state: &AppState,
    owner: &str,
    id: &str,
    name: &str,
    what: &str,
) -> Result<Response, ApiError> {
    let job = succeeded(&state.db, owner, id).await?;
    let a = state.db.job_artifact(id, name).await?.ok_or_else(|| {
        ApiError::new(
            StatusCode::NOT_FOUND,
            "no-result",
            "No such result",
            format!(
                "job {id} ({}) produced no {what}: only optimize/simulate jobs do",
                job.kind
            ),
        )
    })?;
    let mut res = match a.body {
        ArtifactBody::Inline(bytes) => {
            ([(header::CONTENT_TYPE, a.media_type)], bytes).into_response()
        }
        // A large file (the stock of a fine grid) is sent a chunk at a time.
        ArtifactBody::Chunked { key, chunks } => (
            [
                (header::CONTENT_TYPE, a.media_type),
                (header::CONTENT_LENGTH, a.size.to_string()),
            ],
            super::chunked::chunk_body(state.db.clone(), key, chunks),
        )
            .into_response(),
    };
    res.headers_mut().insert(
        header::CONTENT_DISPOSITION,
        super::download::attachment(&a.file_name),
    );
    Ok(res)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProgramQuery {
    /// A posted CLS file's operation (1-based); the first by default.
    operation: Option<u32>,
}

pub async fn program(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
    req: Request,
) -> Result<Response, ApiError> {
    let q: ProgramQuery = parse_query(req.uri().query())?;
    match q.operation {
        None | Some(1) => artifact(&state, &owner, &id, "program", "program").await,
        Some(0) => Err(ApiError::invalid_field(
            "operation",
            "operations count from 1",
        )),
        Some(n) => {
            let name = format!("program.op{n}");
            artifact(&state, &owner, &id, &name, &format!("operation {n}")).await
        }
    }
}

/// `/stock.stl`: the final stock; of a process job kept with `keep_stocks`,
/// `?operation=N` the stock after operation N (the last one's is the final stock).
pub async fn stock_stl(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
    req: Request,
) -> Result<Response, ApiError> {
    let q: ProgramQuery = parse_query(req.uri().query())?;
    let Some(n) = q.operation else {
        return artifact(&state, &owner, &id, "stock.stl", "final stock").await;
    };
    let job = succeeded(&state.db, &owner, &id).await?;
    let count = job
        .summary
        .as_ref()
        .and_then(|s| s["operation_count"].as_u64())
        .ok_or_else(|| {
            ApiError::invalid_field(
                "operation",
                format!(
                    "job {id} ({}) has no operations: only process jobs do",
                    job.kind
                ),
            )
        })?;
    if n == 0 || u64::from(n) > count {
        return Err(ApiError::new(
            StatusCode::NOT_FOUND,
            "no-result",
            "No such result",
            format!("job {id} has operations 1 to {count}, not {n}"),
        ));
    }
    if u64::from(n) == count {
        return artifact(&state, &owner, &id, "stock.stl", "final stock").await;
    }
    let kept = job
        .summary
        .as_ref()
        .is_some_and(|s| s["keep_stocks"] == Value::Bool(true));
    if !kept {
        return Err(ApiError::new(
            StatusCode::NOT_FOUND,
            "no-result",
            "No such result",
            format!("job {id} kept only its final stock (operation {count}); submit it with options.keep_stocks true for the stock after each operation"),
        ));
    }
    let name = format!("stock.op{n}.stl");
    artifact(
        &state,
        &owner,
        &id,
        &name,
        &format!("stock after operation {n}"),
    )
    .await
}

pub async fn free_region_svg(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    artifact(
        &state,
        &owner,
        &id,
        "free_region.svg",
        "free-region picture",
    )
    .await
}

/// The last event of a stream that cannot follow the job any more: a problem document.
fn error_event(e: &ApiError) -> Event {
    Event::default()
        .event("error")
        .json_data(e.to_json())
        .unwrap_or_default()
}

/// Server-sent events: `progress` whenever it changes, then one `status` event with the
/// final job (or an `error` event with a problem if the job cannot be read), then the
/// stream ends. Reads the database, so progress from workers in other
/// processes arrives too: pushed by the database's notifications on PostgreSQL, polled
/// on SQLite.
pub async fn events(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    // Watch before the first read, so a change between the two is not missed.
    let watch = state.db.watch_job(&id).await?;
    let job = find(&state.db, &owner, &id).await?;
    struct S {
        db: Db,
        watch: crate::store::JobWatch,
        owner: String,
        id: String,
        last: Option<(String, i64, i64)>,
        first: Option<JobRecord>,
        finished: bool,
        shutdown: tokio::sync::watch::Receiver<bool>,
    }
    let start = S {
        db: state.db.clone(),
        watch,
        owner,
        id,
        last: None,
        first: Some(job),
        finished: false,
        shutdown: state.shutdown.clone(),
    };
    let stream = stream::unfold(start, |mut s| async move {
        if s.finished {
            return None;
        }
        loop {
            let job = match s.first.take() {
                Some(j) => j,
                None => {
                    // The server is stopping: end the stream (the client reconnects to
                    // another instance or after the restart; the job itself is safe).
                    tokio::select! {
                        _ = s.watch.changed() => {}
                        _ = s.shutdown.wait_for(|v| *v) => return None,
                    }
                    match s.db.get_job(&s.owner, &s.id).await {
                        Ok(Some(j)) => j,
                        // Deleted or unreadable: say so in a last `error` event, so a
                        // client does not take the end of the stream for the job's end.
                        Ok(None) => {
                            s.finished = true;
                            return Some((Ok(error_event(&ApiError::not_found("job", &s.id))), s));
                        }
                        Err(e) => {
                            s.finished = true;
                            return Some((Ok(error_event(&ApiError::from(e))), s));
                        }
                    }
                }
            };
            if job.status.is_terminal() {
                s.finished = true;
                let ev = Event::default()
                    .event("status")
                    .json_data(&job)
                    .unwrap_or_default();
                return Some((Ok::<_, Infallible>(ev), s));
            }
            let now = (
                job.status.as_str().to_string(),
                job.progress.done,
                job.progress.total,
            );
            if s.last.as_ref() != Some(&now) {
                s.last = Some(now);
                let ev = Event::default()
                    .event("progress")
                    .json_data(json!({ "status": job.status, "done": job.progress.done, "total": job.progress.total, "attempts": job.attempts }))
                    .unwrap_or_default();
                return Some((Ok(ev), s));
            }
        }
    });
    Ok(Sse::new(stream)
        .keep_alive(KeepAlive::new().interval(Duration::from_secs(15)))
        .into_response())
}
