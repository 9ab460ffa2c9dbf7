//! Reading request bodies within a per-route limit, streamed: a body over the limit
//! is refused as soon as it crosses it, never buffered whole first.

use std::time::Duration;

use axum::body::Body;
use axum::extract::{Request, State};
use axum::http::{header, HeaderMap};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use futures_util::StreamExt;

use super::problem::ApiError;
use super::AppState;

/// The error a request body's stream ends with when no byte came for the body timeout.
#[derive(Debug, thiserror::Error)]
#[error("no part of the request body arrived for {0:?}")]
pub struct BodyTimeout(pub Duration);

/// Whether a body read failed for the body timeout (anywhere in the error's sources).
pub fn is_body_timeout(e: &(dyn std::error::Error + 'static)) -> bool {
    let mut cur: Option<&(dyn std::error::Error + 'static)> = Some(e);
    while let Some(err) = cur {
        if err.is::<BodyTimeout>() {
            return true;
        }
        cur = err.source();
    }
    false
}

/// Middleware: a request body that stalls (no byte for `limits.body_timeout`, such as a
/// body shorter than its Content-Length held open) ends in a `BodyTimeout` error, which
/// the readers answer 408; the connection is then closed with the unread rest.
pub async fn body_timeout(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let has_body = req.headers().contains_key(header::TRANSFER_ENCODING)
        || req
            .headers()
            .get(header::CONTENT_LENGTH)
            .is_some_and(|v| v.as_bytes() != b"0");
    if !has_body {
        return next.run(req).await;
    }
    let timeout = state.limits.body_timeout;
    let (parts, body) = req.into_parts();
    let timed = futures_util::stream::unfold(
        (body.into_data_stream(), false),
        move |(mut stream, ended)| async move {
            if ended {
                return None;
            }
            match tokio::time::timeout(timeout, stream.next()).await {
                Ok(Some(Ok(chunk))) => Some((Ok(chunk), (stream, false))),
                Ok(Some(Err(e))) => Some((Err(axum::BoxError::from(e)), (stream, true))),
                Ok(None) => None,
                Err(_) => Some((
                    Err(axum::BoxError::from(BodyTimeout(timeout))),
                    (stream, true),
                )),
            }
        },
    );
    let res = next
        .run(Request::from_parts(parts, Body::from_stream(timed)))
        .await;
    res.into_response()
}

/// What a body sink is told before the first byte: the size the request announced
/// (Content-Length), and the disk a spooled upload must leave free.
#[derive(Clone, Copy, Debug)]
pub struct SinkPlan {
    pub expected: Option<u64>,
    pub disk_reserve: u64,
}

/// Where a request body's bytes go as they arrive: memory, or a temporary file for the
/// uploads too large to hold.
pub trait BodySink: Sized + Send {
    fn create(plan: &SinkPlan) -> Result<Self, ApiError>;
    /// Appends a chunk, refusing the upload as soon as it crosses `limit` bytes.
    fn append(
        &mut self,
        chunk: &[u8],
        limit: u64,
    ) -> impl std::future::Future<Output = Result<(), ApiError>> + Send;
    /// After the last chunk: whatever is still buffered is written.
    fn finish(&mut self) -> impl std::future::Future<Output = Result<(), ApiError>> + Send;
}

impl BodySink for Vec<u8> {
    fn create(_: &SinkPlan) -> Result<Self, ApiError> {
        Ok(Vec::new())
    }

    async fn append(&mut self, chunk: &[u8], limit: u64) -> Result<(), ApiError> {
        if self.len() as u64 + chunk.len() as u64 > limit {
            return Err(ApiError::too_large(limit));
        }
        self.extend_from_slice(chunk);
        Ok(())
    }

    async fn finish(&mut self) -> Result<(), ApiError> {
        Ok(())
    }
}

/// The Content-Length a request announced.
pub fn content_length(headers: &HeaderMap) -> Option<u64> {
    headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok())
}

/// The body into a sink, at most `limit` bytes: a Content-Length over it is refused before
/// any of the body is read, a body without one as soon as it crosses it.
pub async fn collect_limited<S: BodySink>(
    headers: &HeaderMap,
    body: Body,
    limit: u64,
    disk_reserve: u64,
) -> Result<S, ApiError> {
    let expected = content_length(headers);
    if expected.is_some_and(|len| len > limit) {
        return Err(ApiError::too_large(limit));
    }
    let mut out = S::create(&SinkPlan {
        expected,
        disk_reserve,
    })?;
    let mut stream = body.into_data_stream();
    while let Some(chunk) = stream.next().await {
        let chunk = chunk.map_err(body_error)?;
        out.append(&chunk, limit).await?;
    }
    out.finish().await?;
    Ok(out)
}

/// [`collect_limited`] into memory.
pub async fn read_limited(
    headers: &HeaderMap,
    body: Body,
    limit: u64,
) -> Result<Vec<u8>, ApiError> {
    collect_limited(headers, body, limit, 0).await
}

/// A request body written to an unnamed temporary file as it arrives (the file is gone
/// when the handle closes, whatever happens to the request). Chunks are gathered in
/// memory and written a batch at a time on a blocking thread, never on the runtime's.
pub struct Spooled {
    file: Option<std::fs::File>,
    pub len: u64,
    batch: Vec<u8>,
    disk_reserve: u64,
}

/// Bytes gathered before a write.
const SPOOL_BATCH: usize = 1 << 20;

/// Free bytes for an unprivileged writer on the file system of `dir`.
fn free_bytes(dir: &std::path::Path) -> std::io::Result<u64> {
    let st = rustix::fs::statvfs(dir)?;
    Ok(st.f_bavail.saturating_mul(st.f_frsize))
}

/// Refuses a write of `more` bytes into the temporary directory when it would leave less
/// than `reserve` free there (the database, the job directories and the system share that
/// disk; a full disk fails them all). `upload` is the upload's size so far with them.
fn check_free(more: u64, upload: u64, reserve: u64) -> Result<(), ApiError> {
    let dir = std::env::temp_dir();
    let free = free_bytes(&dir).map_err(|e| {
        ApiError::internal(format!(
            "free space of the temporary directory {}: {e}",
            dir.display()
        ))
    })?;
    if free < more.saturating_add(reserve) {
        return Err(ApiError::insufficient_storage(free, upload, reserve));
    }
    Ok(())
}

impl BodySink for Spooled {
    fn create(plan: &SinkPlan) -> Result<Spooled, ApiError> {
        // Before any byte is spooled: the announced size (or nothing yet, when the body
        // comes without a length) must leave the reserve free.
        let expected = plan.expected.unwrap_or(0);
        check_free(expected, expected, plan.disk_reserve)?;
        let file = tempfile::tempfile()
            .map_err(|e| ApiError::internal(format!("temporary file for the upload: {e}")))?;
        Ok(Spooled {
            file: Some(file),
            len: 0,
            batch: Vec::with_capacity(SPOOL_BATCH),
            disk_reserve: plan.disk_reserve,
        })
    }

    async fn append(&mut self, chunk: &[u8], limit: u64) -> Result<(), ApiError> {
        if self.len + chunk.len() as u64 > limit {
            return Err(ApiError::too_large(limit));
        }
        self.batch.extend_from_slice(chunk);
        self.len += chunk.len() as u64;
        if self.batch.len() >= SPOOL_BATCH {
            self.write_batch().await?;
        }
        Ok(())
    }

    async fn finish(&mut self) -> Result<(), ApiError> {
        self.write_batch().await
    }
}

impl Spooled {
    /// Writes the gathered batch on a blocking thread, checking the free space first (a
    /// body without a Content-Length is checked as it grows).
    async fn write_batch(&mut self) -> Result<(), ApiError> {
        use std::io::Write;
        if self.batch.is_empty() {
            return Ok(());
        }
        let mut file = self
            .file
            .take()
            .ok_or_else(|| ApiError::internal("the upload's temporary file was lost"))?;
        let batch = std::mem::take(&mut self.batch);
        let reserve = self.disk_reserve;
        let upload = self.len;
        let (file, mut batch) = tokio::task::spawn_blocking(move || {
            check_free(batch.len() as u64, upload, reserve)?;
            file.write_all(&batch).map_err(|e| {
                if e.raw_os_error() == Some(libc::ENOSPC) || e.raw_os_error() == Some(libc::EDQUOT)
                {
                    ApiError::insufficient_storage(0, upload, reserve)
                } else {
                    ApiError::internal(format!("writing the upload's temporary file: {e}"))
                }
            })?;
            Ok::<_, ApiError>((file, batch))
        })
        .await
        .map_err(|e| ApiError::blocking_failed(e, "the upload's writer"))??;
        batch.clear();
        self.batch = batch;
        self.file = Some(file);
        Ok(())
    }

    /// A reader from the start of the file (sharing its handle).
    pub fn reader(&self) -> Result<std::fs::File, ApiError> {
        use std::io::{Seek, SeekFrom};
        let mut f = self
            .file
            .as_ref()
            .ok_or_else(|| ApiError::internal("the upload's temporary file was lost"))?
            .try_clone()
            .map_err(|e| ApiError::internal(format!("reading the upload's temporary file: {e}")))?;
        f.seek(SeekFrom::Start(0))
            .map_err(|e| ApiError::internal(format!("reading the upload's temporary file: {e}")))?;
        Ok(f)
    }
}

fn body_error(e: axum::Error) -> ApiError {
    let e = e.into_inner();
    if is_body_timeout(e.as_ref()) {
        ApiError::body_timeout()
    } else {
        ApiError::bad_request(format!("could not read the request body: {e}"))
    }
}

/// The media type of a request without parameters, lower case.
pub fn media_type(headers: &HeaderMap) -> String {
    headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .map(|v| {
            v.split(';')
                .next()
                .unwrap_or("")
                .trim()
                .to_ascii_lowercase()
        })
        .unwrap_or_default()
}
