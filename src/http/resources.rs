//! Inputs: stocks, tools, materials, machines, programs, tool libraries. Stored unchanged
//! after the engine's readers validated them.

use axum::extract::{FromRequest, Multipart, Path, Request, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::json;

use super::body::{
    collect_limited, content_length, media_type, read_limited, BodySink, SinkPlan, Spooled,
};
use super::chunked::chunk_body;
use super::problem::ApiError;
use super::{parse_query, AppState, Owner, PageQuery};
use crate::store::chunks::{ChunkKey, ResourceBody};
use crate::store::resources::{NewResource, ResourceRecord};
use crate::store::ResourceKind;
use crate::validate::{self, Validated};

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct UploadQuery {
    name: Option<String>,
}

/// The file name from `Content-Disposition: ...; filename="x.nc"`.
fn disposition_name(headers: &HeaderMap) -> Option<String> {
    let v = headers.get(header::CONTENT_DISPOSITION)?.to_str().ok()?;
    let at = v.find("filename=")?;
    Some(
        v[at + 9..]
            .split(';')
            .next()?
            .trim()
            .trim_matches('"')
            .to_string(),
    )
    .filter(|s| !s.is_empty())
}

/// The uploaded bytes into a sink as they arrive (memory, or a temporary file so that a
/// stock of hundreds of megabytes never sits in memory), at most `limit` bytes: the raw
/// body, or the `file` part (else the first part with a file name) of a multipart form.
/// Returns the sink and the file name the client gave, if any. A spooled upload leaves
/// `disk_reserve` bytes free in the temporary directory.
async fn upload_into<S: BodySink>(
    req: Request,
    limit: u64,
    disk_reserve: u64,
) -> Result<(S, Option<String>), ApiError> {
    let headers = req.headers().clone();
    let plan = SinkPlan {
        // A multipart form's length is a little over its file's: close enough to check.
        expected: content_length(&headers),
        disk_reserve,
    };

    if media_type(&headers) == "multipart/form-data" {
        let mut form = Multipart::from_request(req, &())
            .await
            .map_err(|e| ApiError::bad_request(format!("multipart form: {}", e.body_text())))?;
        while let Some(mut field) = form
            .next_field()
            .await
            .map_err(|e| multipart_error(e, limit))?
        {
            let is_file = field.name() == Some("file") || field.file_name().is_some();
            if !is_file {
                continue;
            }
            let name = field.file_name().map(str::to_string);
            let mut out = S::create(&plan)?;
            while let Some(chunk) = field.chunk().await.map_err(|e| multipart_error(e, limit))? {
                out.append(&chunk, limit).await?;
            }
            out.finish().await?;
            return Ok((out, name));
        }
        return Err(ApiError::invalid_field(
            "file",
            "the multipart form has no `file` part",
        ));
    }
    let name = disposition_name(&headers);
    let sink = collect_limited(&headers, req.into_body(), limit, disk_reserve).await?;
    Ok((sink, name))
}

fn multipart_error(e: axum::extract::multipart::MultipartError, limit: u64) -> ApiError {
    if super::body::is_body_timeout(&e) {
        ApiError::body_timeout()
    } else if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
        ApiError::too_large(limit)
    } else {
        ApiError::bad_request(format!("multipart form: {}", e.body_text()))
    }
}

/// The name an upload's checks call its file by: the one the query gives, else the
/// upload's own, else `default`.
fn file_label(query: &UploadQuery, upload_name: &Option<String>, default: &str) -> String {
    query
        .name
        .clone()
        .or(upload_name.clone())
        .unwrap_or_else(|| default.into())
}

pub async fn create(
    kind: ResourceKind,
    State(state): State<AppState>,
    Owner(owner): Owner,
    req: Request,
) -> Result<Response, ApiError> {
    let query: UploadQuery = parse_query(req.uri().query())?;
    let limits = state.limits.clone();
    let mt = media_type(req.headers());
    let (bytes, file_name, checked): (Vec<u8>, Option<String>, Validated) = match kind {
        ResourceKind::Stock if mt == "application/json" => {
            let bytes = read_limited(
                &req.headers().clone(),
                req.into_body(),
                limits.max_json_bytes,
            )
            .await?;
            let v = validate::stock_json(&bytes)?;
            (bytes, None, v)
        }
        ResourceKind::Stock => {
            let (spooled, name) =
                upload_into::<Spooled>(req, limits.max_stl_bytes, limits.upload_disk_reserve_bytes)
                    .await
                    .map_err(|e| {
                        e.raised_by(
                            "--max-upload-bytes",
                            "MILLSIM_MAX_UPLOAD_BYTES",
                            crate::config::DEFAULT_MAX_STL_BYTES,
                        )
                    })?;
            let file = file_label(&query, &name, "stock.stl");
            // Read back from the file a block at a time (twice if it has duplicate
            // triangles); the check is CPU work: keep it off the runtime.
            let spool = spooled.reader()?;
            let len = spooled.len;
            let checked = tokio::task::spawn_blocking(move || {
                let open = || {
                    use std::io::{Seek, SeekFrom};
                    let mut f = spool.try_clone()?;
                    f.seek(SeekFrom::Start(0))?;
                    Ok(f)
                };
                validate::stl_stream(open, len, &file)
            })
            .await
            .map_err(|e| ApiError::blocking_failed(e, "the STL reader"))??;
            let name = query.name.or(name);
            let record = state
                .db
                .create_resource_chunked(
                    &owner,
                    &NewResource {
                        kind,
                        name: name.as_deref(),
                        media_type: checked.media_type,
                        summary: checked.summary,
                        content: &[],
                        view: None,
                    },
                    spooled.reader()?,
                    len,
                )
                .await?;
            return Ok(created(kind, record));
        }
        ResourceKind::Program => {
            let (bytes, name) = upload_into::<Vec<u8>>(req, limits.max_program_bytes, 0)
                .await
                .map_err(program_too_large)?;
            let file = file_label(&query, &name, "program.nc");
            let (bytes, _, checked) =
                super::parsing::program(bytes, file, limits.max_program_bytes).await?;
            let name = query.name.or(name);
            return store(&state, &owner, kind, name.as_deref(), checked, bytes, None).await;
        }
        ResourceKind::ToolLibrary => {
            // Any media type: the engine tells the format from the content, as offline.
            let (bytes, name) = upload_into::<Vec<u8>>(req, limits.max_program_bytes, 0)
                .await
                .map_err(program_too_large)?;
            let file = file_label(&query, &name, "tools");
            // Read once, here: the GET answers from the view stored beside the file.
            let (bytes, (checked, view)) =
                read_library_serially("the tool library reader", move || {
                    validate::tool_library(&bytes, &file).map(|v| (bytes, v))
                })
                .await?;
            let name = query.name.or(name);
            return store(
                &state,
                &owner,
                kind,
                name.as_deref(),
                checked,
                bytes,
                Some(&view),
            )
            .await;
        }
        ResourceKind::Tool | ResourceKind::Material | ResourceKind::Machine => {
            if !(mt == "application/json" || mt.is_empty()) {
                return Err(ApiError::new(
                    StatusCode::UNSUPPORTED_MEDIA_TYPE,
                    "unsupported-media-type",
                    "Unsupported media type",
                    format!(
                        "a {} is JSON: send Content-Type: application/json, not `{mt}`",
                        kind.as_str()
                    ),
                ));
            }
            let bytes = read_limited(
                &req.headers().clone(),
                req.into_body(),
                limits.max_json_bytes,
            )
            .await?;
            let v = match kind {
                ResourceKind::Tool => validate::tool(&bytes)?,
                ResourceKind::Material => validate::material(&bytes)?,
                _ => validate::machine(&bytes)?,
            };
            (bytes, None, v)
        }
    };
    let name = query.name.or(file_name);
    store(&state, &owner, kind, name.as_deref(), checked, bytes, None).await
}

/// Stores a checked upload held in memory (over a chunk, in chunks: see
/// `store::resources::insert_with_id`); answers 201 with its record.
async fn store(
    state: &AppState,
    owner: &str,
    kind: ResourceKind,
    name: Option<&str>,
    checked: Validated,
    bytes: Vec<u8>,
    view: Option<&str>,
) -> Result<Response, ApiError> {
    let new = NewResource {
        kind,
        name,
        media_type: checked.media_type,
        summary: checked.summary,
        content: &bytes,
        view,
    };
    let record = state.db.create_resource(owner, &new).await?;
    Ok(created(kind, record))
}

/// 201 with the new resource's record and location.
fn created(kind: ResourceKind, record: ResourceRecord) -> Response {
    let location = format!("/v1/{}/{}", kind.collection(), record.id);
    (
        StatusCode::CREATED,
        [(header::LOCATION, location)],
        Json(record),
    )
        .into_response()
}

pub async fn list(
    kind: ResourceKind,
    State(state): State<AppState>,
    Owner(owner): Owner,
    req: Request,
) -> Result<Response, ApiError> {
    let q: PageQuery = parse_query(req.uri().query())?;
    if q.status.is_some() || q.kind.is_some() {
        return Err(ApiError::invalid_field(
            "status",
            "`status` and `kind` filter jobs, not resources",
        ));
    }
    let (items, next) = state
        .db
        .list_resources(&owner, kind, q.cursor.as_deref(), q.limit()?)
        .await?;
    Ok(Json(json!({ "items": items, "next_cursor": next })).into_response())
}

pub async fn get_one(
    kind: ResourceKind,
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let r = state
        .db
        .get_resource(&owner, kind, &id)
        .await?
        .ok_or_else(|| ApiError::not_found(kind.as_str(), &id))?;
    if kind == ResourceKind::ToolLibrary {
        return library_view(&state, &owner, r).await;
    }
    Ok(Json(r).into_response())
}

/// Tool libraries are parsed in the API process at upload (and at the first GET of one
/// stored before views were), and a large one takes a few hundred MB while it is read:
/// one read at a time, so that concurrent reads wait for each other instead of adding up
/// past the server's memory.
static LIBRARY_READS: tokio::sync::Semaphore = tokio::sync::Semaphore::const_new(1);

/// This request's turn at reading a tool library (see [`LIBRARY_READS`]).
async fn library_turn() -> Result<tokio::sync::SemaphorePermit<'static>, ApiError> {
    LIBRARY_READS
        .acquire()
        .await
        .map_err(|_| ApiError::internal("the tool library reader is closed"))
}

/// One tool library read at a time (see [`LIBRARY_READS`]).
async fn read_library_serially<T: Send + 'static>(
    what: &'static str,
    read: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    let _turn = library_turn().await?;
    read_library(what, read).await
}

/// Reads a library on a blocking thread (the caller holds its turn).
async fn read_library<T: Send + 'static>(
    what: &'static str,
    read: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    Ok(tokio::task::spawn_blocking(read)
        .await
        .map_err(|e| ApiError::blocking_failed(e, what))??)
}

/// The view of a library stored before views were: read from its file (the file is taken
/// from the database only once this request's turn has come, so that GETs waiting for
/// theirs do not each hold one) and stored for the next GET.
async fn legacy_view(state: &AppState, owner: &str, id: &str) -> Result<String, ApiError> {
    let _turn = library_turn().await?;
    // Made by a GET that had the turn before this one.
    if let Some(view) = state.db.resource_view(id).await? {
        return Ok(view);
    }
    let (name, _, bytes) = state
        .db
        .resource_content(owner, ResourceKind::ToolLibrary, id)
        .await?
        .ok_or_else(|| ApiError::not_found(ResourceKind::ToolLibrary.as_str(), id))?;
    let file = name.unwrap_or_else(|| "tools".into());
    let view = read_library("the tool library reader", move || {
        let lib = validate::read_tool_library(&bytes, &file)?;
        Ok(validate::library_view(lib)?)
    })
    .await?;
    // The answer does not depend on it: a failure (the library deleted meanwhile) only
    // means the next GET makes it again.
    if let Err(e) = state.db.store_resource_view(id, &view).await {
        tracing::warn!(library = %id, error = %e, "could not store a tool library's view");
    }
    Ok(view)
}

/// A tool library's record with what it holds (its format, tools by T number and import
/// report: the view stored at upload, see `validate::library_view`), sent as the record's
/// JSON with the view's members after its own, never parsing the file again. A library
/// stored before views has its view made now, once, and stored.
async fn library_view(
    state: &AppState,
    owner: &str,
    record: ResourceRecord,
) -> Result<Response, ApiError> {
    let view = match state.db.resource_view(&record.id).await? {
        Some(view) => view,
        None => legacy_view(state, owner, &record.id).await?,
    };
    let mut head = serde_json::to_vec(&record)
        .map_err(|e| ApiError::internal(format!("the library's record: {e}")))?;
    // `{..record..}` + `{..view..}` → `{..record.., ..view..}`: both are JSON objects,
    // the record never empty.
    head.pop();
    head.push(b',');
    let tail = bytes::Bytes::from(view).slice(1..);
    let body =
        futures_util::stream::iter([Ok::<_, std::io::Error>(bytes::Bytes::from(head)), Ok(tail)]);
    Ok((
        [(header::CONTENT_TYPE, "application/json")],
        axum::body::Body::from_stream(body),
    )
        .into_response())
}

pub async fn content(
    kind: ResourceKind,
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let (name, mt, size, body) = state
        .db
        .resource_body(&owner, kind, &id)
        .await?
        .ok_or_else(|| ApiError::not_found(kind.as_str(), &id))?;
    let mut res = match body {
        ResourceBody::Inline(bytes) => ([(header::CONTENT_TYPE, mt)], bytes).into_response(),
        ResourceBody::Chunked { id, chunks } => (
            [
                (header::CONTENT_TYPE, mt),
                (header::CONTENT_LENGTH, size.to_string()),
            ],
            chunk_body(state.db.clone(), ChunkKey::Resource { id }, chunks),
        )
            .into_response(),
    };
    if let Some(name) = name {
        res.headers_mut().insert(
            header::CONTENT_DISPOSITION,
            super::download::attachment(&name),
        );
    }
    Ok(res)
}

pub async fn delete(
    kind: ResourceKind,
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    if state.db.delete_resource(&owner, kind, &id).await? {
        Ok(StatusCode::NO_CONTENT.into_response())
    } else {
        Err(ApiError::not_found(kind.as_str(), &id))
    }
}

/// A program over the limit: the 413 names the server option that raises it.
pub(super) fn program_too_large(e: ApiError) -> ApiError {
    e.raised_by(
        "--max-program-bytes",
        "MILLSIM_MAX_PROGRAM_BYTES",
        crate::config::DEFAULT_MAX_PROGRAM_BYTES,
    )
}
