//! RFC 9457 problem documents: the one place where errors become HTTP responses.

use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use serde_json::{json, Map, Value};

use millsim_engine::tool_library::ToolLibraryError;

use crate::store::StoreError;

pub const PROBLEM_JSON: &str = "application/problem+json";

/// An error answered to a client: status, a stable type slug, a title and what exactly
/// is wrong (field, line, column...) in `extensions`.
#[derive(Debug)]
pub struct ApiError {
    pub status: StatusCode,
    pub slug: &'static str,
    pub title: &'static str,
    pub detail: String,
    pub extensions: Map<String, Value>,
}

impl ApiError {
    pub fn new(
        status: StatusCode,
        slug: &'static str,
        title: &'static str,
        detail: impl Into<String>,
    ) -> Self {
        ApiError {
            status,
            slug,
            title,
            detail: detail.into(),
            extensions: Map::new(),
        }
    }

    pub fn with(mut self, key: &str, value: impl Into<Value>) -> Self {
        // The RFC 9457 members are set from the error itself, never by an extension.
        debug_assert!(
            !matches!(key, "type" | "title" | "status" | "detail"),
            "extension `{key}` would replace a problem member"
        );
        self.extensions.insert(key.to_string(), value.into());
        self
    }

    pub fn bad_request(detail: impl Into<String>) -> Self {
        Self::new(
            StatusCode::BAD_REQUEST,
            "bad-request",
            "Bad request",
            detail,
        )
    }

    /// The body parsed but a value is not acceptable; `field` is a JSON path.
    pub fn invalid_field(field: impl Into<String>, detail: impl Into<String>) -> Self {
        let field = field.into();
        Self::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid-field",
            "Invalid field",
            detail,
        )
        .with("field", field)
    }

    pub fn not_found(what: &str, id: &str) -> Self {
        Self::new(
            StatusCode::NOT_FOUND,
            "not-found",
            "Not found",
            format!("no {what} with id `{id}`"),
        )
        .with("id", id.to_string())
    }

    pub fn too_large(limit: u64) -> Self {
        Self::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            "too-large",
            "Request body too large",
            format!("the body exceeds this route's limit of {limit} bytes"),
        )
        .with("limit_bytes", limit)
    }

    /// A job over the server's job memory budget, from the same problem document a job
    /// refused at run time carries (its detail and extensions: limit, estimate).
    pub fn over_budget(problem: Value) -> Self {
        let mut err = Self::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "resource-limit",
            "Over the job's memory budget",
            problem["detail"].as_str().unwrap_or_default(),
        );
        if let Value::Object(members) = problem {
            for (k, v) in members {
                if !matches!(k.as_str(), "type" | "title" | "status" | "detail") {
                    err.extensions.insert(k, v);
                }
            }
        }
        err
    }

    /// A request body that stalled (see `body::body_timeout`).
    pub fn body_timeout() -> Self {
        Self::new(
            StatusCode::REQUEST_TIMEOUT,
            "body-timeout",
            "Request body timeout",
            "the request body stopped arriving before its end (body_timeout_s); send the whole body at once",
        )
        .with("limit_name", "body_timeout_s")
    }

    pub fn conflict(detail: impl Into<String>) -> Self {
        Self::new(StatusCode::CONFLICT, "conflict", "Conflict", detail)
    }

    pub fn not_supported(detail: impl Into<String>) -> Self {
        Self::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "not-supported",
            "Not supported yet",
            detail,
        )
    }

    pub fn unauthorized(detail: impl Into<String>) -> Self {
        Self::new(
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            "Unauthorized",
            detail,
        )
    }

    /// A fault of the server's: the client's request may well have been fine.
    pub fn internal(detail: impl Into<String>) -> Self {
        Self::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            "internal",
            "Internal error",
            detail,
        )
    }

    /// A blocking task (a reader, a parser) that did not return: it panicked or was
    /// cancelled. That is a bug of ours, never the client's input being wrong.
    pub fn blocking_failed(e: tokio::task::JoinError, what: &str) -> Self {
        tracing::error!(error = %e, "{what} stopped on an internal error");
        Self::internal(format!(
            "{what} stopped on an internal error; this is a bug in millsim, please report it with the request id"
        ))
    }

    pub fn to_json(&self) -> Value {
        let mut doc = json!({
            "type": format!("https://millsim.dev/problems/{}", self.slug),
            "title": self.title,
            "status": self.status.as_u16(),
            "detail": self.detail,
        });
        if let Value::Object(m) = &mut doc {
            m.extend(self.extensions.clone());
        }
        doc
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (
            self.status,
            [(header::CONTENT_TYPE, PROBLEM_JSON)],
            self.to_json().to_string(),
        )
            .into_response()
    }
}

/// The answer to a handler that panicked (tower-http's CatchPanicLayer): a problem
/// document rather than a dropped connection.
pub fn panic_response(panic: Box<dyn std::any::Any + Send + 'static>) -> Response {
    let message = panic
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| panic.downcast_ref::<&str>().copied())
        .unwrap_or("(no message)");
    tracing::error!(panic = %message, "request handler panicked");
    ApiError::internal(
        "the server stopped on an internal error while answering; this is a bug in millsim, please report it with the request id",
    )
    .into_response()
}

impl From<StoreError> for ApiError {
    fn from(e: StoreError) -> Self {
        if let StoreError::Vanished(what) = &e {
            // A race with a DELETE, not a fault: the same request again gets a clean answer.
            return ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "concurrent-change",
                "Changed while answering",
                format!("{what} was deleted while this request ran; retry the request"),
            );
        }
        // Storage failures are ours, not the client's; the log has the cause.
        tracing::error!(error = %e, "storage error");
        ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "storage",
            "Storage unavailable",
            "the database could not complete the request; retry later",
        )
    }
}

impl From<ToolLibraryError> for ApiError {
    fn from(e: ToolLibraryError) -> Self {
        // The engine names the tool by its T number and place ("T3 (line 4)", "data[2]"):
        // a line there is the file's line.
        let line = e
            .tool
            .split_once("line ")
            .and_then(|(_, rest)| rest.trim_end_matches(')').parse::<u64>().ok());
        let mut err = ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid-tool-library",
            "Tool library does not read",
            e.to_string(),
        )
        .with("field", e.field)
        .with("tool", e.tool);
        if let Some(line) = line {
            err = err.with("line", line);
        }
        err
    }
}

/// Parses JSON and, on failure, says where: the JSON path of a bad value, or the line
/// and column of a syntax error.
pub fn parse_json<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    let de = &mut serde_json::Deserializer::from_slice(bytes);
    serde_path_to_error::deserialize(de).map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner();
        if inner.is_syntax() || inner.is_eof() {
            ApiError::bad_request(format!("malformed JSON: {inner}"))
                .with("line", inner.line())
                .with("column", inner.column())
        } else {
            // serde reports a missing or unknown field at its parent: name the field itself.
            let msg = inner.to_string();
            let named = ["missing field `", "unknown field `"]
                .iter()
                .find_map(|p| msg.strip_prefix(p))
                .and_then(|rest| rest.split('`').next())
                .map(|f| {
                    if path == "." {
                        f.to_string()
                    } else {
                        format!("{path}.{f}")
                    }
                });
            let field = named.unwrap_or(path);
            ApiError::invalid_field(field.clone(), format!("`{field}`: {msg}"))
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    async fn body_json(res: Response) -> Value {
        let bytes = axum::body::to_bytes(res.into_body(), 1 << 20)
            .await
            .unwrap();
        serde_json::from_slice(&bytes).unwrap()
    }

    #[tokio::test]
    async fn a_panic_in_a_blocking_reader_is_a_500_problem_not_a_400() {
        let join = tokio::task::spawn_blocking(|| -> Result<(), ApiError> { panic!("reader bug") })
            .await
            .unwrap_err();
        let res = ApiError::blocking_failed(join, "the STL reader").into_response();
        assert_eq!(res.status(), StatusCode::INTERNAL_SERVER_ERROR);
        assert_eq!(res.headers()[header::CONTENT_TYPE], PROBLEM_JSON);
        let doc = body_json(res).await;
        assert_eq!(doc["status"], 500);
        assert!(doc["detail"].as_str().unwrap().contains("STL reader"));
    }

    #[tokio::test]
    async fn a_panicking_handler_is_answered_500_with_a_problem() {
        use tower::ServiceExt;
        let app = axum::Router::new()
            .route(
                "/boom",
                axum::routing::get(|| async {
                    panic!("handler bug");
                    #[allow(unreachable_code)]
                    StatusCode::OK
                }),
            )
            .layer(tower_http::catch_panic::CatchPanicLayer::custom(
                panic_response,
            ));
        let req = axum::http::Request::get("/boom")
            .body(axum::body::Body::empty())
            .unwrap();
        let res = app.oneshot(req).await.unwrap();
        assert_eq!(res.status(), StatusCode::INTERNAL_SERVER_ERROR);
        assert_eq!(res.headers()[header::CONTENT_TYPE], PROBLEM_JSON);
        assert_eq!(
            body_json(res).await["type"],
            "https://millsim.dev/problems/internal"
        );
    }
}
