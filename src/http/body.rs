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

/// Where a request body's bytes go as they arrive: memory, or a temporary file for the
/// uploads too large to hold.
pub trait BodySink: Sized {
    fn create() -> Result<Self, ApiError>;
    /// Appends a chunk, refusing the upload as soon as it crosses `limit` bytes.
    fn append(&mut self, chunk: &[u8], limit: u64) -> Result<(), ApiError>;
}

impl BodySink for Vec<u8> {
    fn create() -> Result<Self, ApiError> {
        Ok(Vec::new())
    }

    fn append(&mut self, chunk: &[u8], limit: u64) -> Result<(), ApiError> {
        if self.len() as u64 + chunk.len() as u64 > limit {
            return Err(ApiError::too_large(limit));
        }
        self.extend_from_slice(chunk);
        Ok(())
    }
}

/// The body into a sink, at most `limit` bytes: a Content-Length over it is refused before
/// any of the body is read, a body without one as soon as it crosses it.
pub async fn collect_limited<S: BodySink>(
    headers: &HeaderMap,
    body: Body,
    limit: u64,
) -> Result<S, ApiError> {
    if let Some(len) = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok())
    {
        if len > limit {
            return Err(ApiError::too_large(limit));
        }
    }
    let mut out = S::create()?;
    let mut stream = body.into_data_stream();
    while let Some(chunk) = stream.next().await {
        let chunk = chunk.map_err(body_error)?;
        out.append(&chunk, limit)?;
    }
    Ok(out)
}

/// [`collect_limited`] into memory.
pub async fn read_limited(
    headers: &HeaderMap,
    body: Body,
    limit: u64,
) -> Result<Vec<u8>, ApiError> {
    collect_limited(headers, body, limit).await
}

/// A request body written to an unnamed temporary file as it arrives (the file is gone
/// when the handle closes, whatever happens to the request).
pub struct Spooled {
    pub file: std::fs::File,
    pub len: u64,
}

impl BodySink for Spooled {
    fn create() -> Result<Spooled, ApiError> {
        let file = tempfile::tempfile()
            .map_err(|e| ApiError::internal(format!("temporary file for the upload: {e}")))?;
        Ok(Spooled { file, len: 0 })
    }

    fn append(&mut self, chunk: &[u8], limit: u64) -> Result<(), ApiError> {
        use std::io::Write;
        if self.len + chunk.len() as u64 > limit {
            return Err(ApiError::too_large(limit));
        }
        // A write to a local file: short, and the page cache takes it; not worth a
        // blocking thread per chunk.
        self.file
            .write_all(chunk)
            .map_err(|e| ApiError::internal(format!("writing the upload's temporary file: {e}")))?;
        self.len += chunk.len() as u64;
        Ok(())
    }
}

impl Spooled {
    /// A reader from the start of the file (sharing its handle).
    pub fn reader(&self) -> Result<std::fs::File, ApiError> {
        use std::io::{Seek, SeekFrom};
        let mut f = self
            .file
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
