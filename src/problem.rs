//! RFC 9457 problem documents: the one type every error of the service becomes, whether
//! it is answered to a request (the HTTP edge turns it into a response) or stored as a
//! failed job's `error` (the worker turns it into JSON when it commits the outcome).
//! It lives outside `http` so that validation and the job kinds can build one without
//! depending on the HTTP layer.

use std::borrow::Cow;

use axum::http::StatusCode;
use serde_json::{json, Map, Value};

use millsim_engine::nc;
use millsim_engine::tool_library::ToolLibraryError;

/// The URL prefix of every problem `type`; the slug follows it.
const TYPE_PREFIX: &str = "https://millsim.dev/problems/";

/// An error: status, a stable type slug, a title and what exactly is wrong (field, line,
/// column...) in `extensions`.
#[derive(Debug, Clone)]
pub struct Problem {
    pub status: StatusCode,
    pub slug: Cow<'static, str>,
    pub title: Cow<'static, str>,
    pub detail: String,
    /// Boxed: a problem is the error of most results, which stay small this way.
    pub extensions: Box<Map<String, Value>>,
}

impl Problem {
    pub fn new(
        status: StatusCode,
        slug: impl Into<Cow<'static, str>>,
        title: impl Into<Cow<'static, str>>,
        detail: impl Into<String>,
    ) -> Self {
        Problem {
            status,
            slug: slug.into(),
            title: title.into(),
            detail: detail.into(),
            extensions: Box::default(),
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

    /// A job's input or option that turned out unusable when the job ran.
    pub fn invalid_input(title: impl Into<Cow<'static, str>>, detail: impl Into<String>) -> Self {
        Self::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid-input",
            title,
            detail,
        )
    }

    /// A job's program that does not interpret: the first five errors in the detail, every
    /// one with its line and column in `errors`.
    pub fn program_failed(file: &str, d: &nc::Diagnostics) -> Self {
        let detail =
            d.0.iter()
                .take(5)
                .map(|e| format!("{file}:{e}"))
                .collect::<Vec<_>>()
                .join("; ");
        Self::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid-program",
            "Program does not interpret",
            detail,
        )
        .with("file", file.to_string())
        .with("errors", diagnostics_json(d))
    }

    /// An uploaded program that does not read: the count and the first error, with its
    /// line and column as members.
    pub fn program_unreadable(file: &str, title: &'static str, d: &nc::Diagnostics) -> Self {
        let first =
            d.0.first()
                .map(|e| format!("{file}:{}:{}: {}", e.line, e.col, e.message))
                .unwrap_or_default();
        let mut err = Self::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid-program",
            title,
            format!("{} error(s); first: {first}", d.0.len()),
        )
        .with("file", file.to_string())
        .with("errors", diagnostics_json(d));
        if let Some(e) = d.0.first() {
            err = err.with("line", e.line).with("column", e.col);
        }
        err
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

    /// A 413 for a limit the server's operator can raise: the detail names the option, its
    /// environment variable and its default (other problems are returned unchanged).
    pub fn raised_by(mut self, option: &str, env: &str, default: u64) -> Self {
        if self.status == StatusCode::PAYLOAD_TOO_LARGE {
            self.detail = format!(
                "{}; the server's {option} (or {env}; default {default} bytes) raises it",
                self.detail
            );
            self = self.with("setting", option);
        }
        self
    }

    /// An upload the server has no disk for: spooling it would leave less than the
    /// reserve free in its temporary directory (`free` known), or the disk filled while
    /// it was written (`free` 0). The client may try again later; nothing was stored.
    pub fn insufficient_storage(free: u64, needed: u64, reserve: u64) -> Self {
        let detail = if free > 0 {
            format!(
                "the server's temporary directory has {free} bytes free; spooling this upload ({needed} bytes so far, or as its Content-Length said) would leave less than the {reserve} bytes it keeps free (upload_disk_reserve_mb). Nothing was stored; try again later"
            )
        } else {
            "the server's temporary directory filled up while this upload was written. Nothing was stored; try again later".to_string()
        };
        Self::disk_full(detail)
            .with("field", "file")
            .with("limit_name", "upload_disk_reserve_mb")
            .with("free_bytes", free)
            .with("needed_bytes", needed)
            .with("reserve_bytes", reserve)
    }

    /// The server's disk is full (the detail says which and for what): not the client's
    /// fault; it may try again later.
    pub fn disk_full(detail: impl Into<String>) -> Self {
        Self::new(
            StatusCode::INSUFFICIENT_STORAGE,
            "insufficient-storage",
            "Insufficient storage",
            detail,
        )
    }

    /// A job held to one of the server's limits (its memory budget, its isolation): the one
    /// `resource-limit` problem, naming the limit's setting.
    pub fn resource_limit(
        title: impl Into<Cow<'static, str>>,
        detail: impl Into<String>,
        limit_name: &str,
    ) -> Self {
        Self::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "resource-limit",
            title,
            detail,
        )
        .with("limit_name", limit_name)
    }

    /// A job whose worker stopped without finishing it on each of its allowed attempts.
    pub fn worker_lost(attempts: i64, max_attempts: i64) -> Self {
        Self::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            "worker-lost",
            "Job failed",
            format!(
                "the worker running this job stopped without finishing it {attempts} times (max attempts {max_attempts})"
            ),
        )
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
            "type": format!("{TYPE_PREFIX}{}", self.slug),
            "title": self.title,
            "status": self.status.as_u16(),
            "detail": self.detail,
        });
        if let Value::Object(m) = &mut doc {
            m.extend(self.extensions.iter().map(|(k, v)| (k.clone(), v.clone())));
        }
        doc
    }

    /// A problem document read back (from a job's process): the inverse of `to_json`.
    pub fn from_json(doc: Value) -> Self {
        let Value::Object(mut m) = doc else {
            return Self::internal(format!("not a problem document: {doc}"));
        };
        let mut take = |k: &str| match m.remove(k) {
            Some(Value::String(s)) => s,
            _ => String::new(),
        };
        let slug = take("type")
            .strip_prefix(TYPE_PREFIX)
            .unwrap_or("internal")
            .to_string();
        let (title, detail) = (take("title"), take("detail"));
        let status = m
            .remove("status")
            .and_then(|s| s.as_u64())
            .and_then(|s| StatusCode::from_u16(s as u16).ok())
            .unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
        Problem {
            status,
            slug: slug.into(),
            title: title.into(),
            detail,
            extensions: Box::new(m),
        }
    }
}

fn diagnostics_json(d: &nc::Diagnostics) -> Value {
    Value::Array(
        d.0.iter()
            .map(|e| json!({ "line": e.line, "column": e.col, "message": e.message }))
            .collect(),
    )
}

impl From<ToolLibraryError> for Problem {
    fn from(e: ToolLibraryError) -> Self {
        // The engine names the tool by its T number and place ("T3 (line 4)", "data[2]"):
        // a line there is the file's line.
        let line = e
            .tool
            .split_once("line ")
            .and_then(|(_, rest)| rest.trim_end_matches(')').parse::<u64>().ok());
        let mut err = Problem::new(
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

/// The bytes without a leading UTF-8 byte-order mark (Windows editors write one; JSON
/// parsers refuse it).
pub fn without_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes)
}

/// Parses JSON and, on failure, says where: the JSON path of a bad value, or the line
/// and column of a syntax error.
pub fn parse_json<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, Problem> {
    let de = &mut serde_json::Deserializer::from_slice(without_bom(bytes));
    serde_path_to_error::deserialize(de).map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner();
        if inner.is_syntax() || inner.is_eof() {
            Problem::bad_request(format!("malformed JSON: {inner}"))
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
                    // An unknown field is already the last step of the path; a missing
                    // one is not (the path stops at its parent).
                    if path == "." {
                        f.to_string()
                    } else if path == f || path.ends_with(&format!(".{f}")) {
                        path.clone()
                    } else {
                        format!("{path}.{f}")
                    }
                });
            let field = named.unwrap_or(path);
            Problem::invalid_field(field.clone(), format!("`{field}`: {msg}"))
        }
    })
}

/// Parses a job's `options` object: as [`parse_json`], with the field named under
/// `options.`.
pub fn parse_options<T: serde::de::DeserializeOwned>(options: &Value) -> Result<T, Problem> {
    parse_json(options.to_string().as_bytes()).map_err(|mut e| {
        let field = e
            .extensions
            .get("field")
            .and_then(Value::as_str)
            .unwrap_or("")
            .to_string();
        e.extensions
            .insert("field".into(), Value::String(format!("options.{field}")));
        e
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Outer {
        url: String,
        inner: Option<Inner>,
    }

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Inner {
        depth: f64,
    }

    #[test]
    fn parse_json_names_unknown_and_missing_fields_once() {
        let field = |body: &str| {
            let e = parse_json::<Outer>(body.as_bytes()).unwrap_err();
            e.extensions["field"].as_str().unwrap().to_string()
        };
        assert_eq!(field(r#"{"url":"x","secret":1}"#), "secret");
        assert_eq!(field(r#"{"inner":{"depth":1}}"#), "url");
        assert_eq!(
            field(r#"{"url":"x","inner":{"depth":1,"width":2}}"#),
            "inner.width"
        );
        assert_eq!(field(r#"{"url":"x","inner":{}}"#), "inner.depth");
        assert_eq!(
            field(r#"{"url":"x","inner":{"depth":"deep"}}"#),
            "inner.depth"
        );
    }

    #[test]
    fn a_problem_read_back_from_its_json_is_the_same_document() {
        let p = Problem::invalid_field("options.decimals", "must be 1 to 9").with("limit", 9);
        let back = Problem::from_json(p.to_json());
        assert_eq!(back.to_json(), p.to_json());
        assert_eq!(back.status, StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(back.slug, "invalid-field");
    }
}
