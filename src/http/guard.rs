//! What a page on another site must not get from this server: a request that carries another
//! site's `Origin` is refused (403) unless `--cors-origin` names that site (a CAM station's
//! browser could otherwise submit, upload, cancel and register webhooks on a loopback server
//! without keys), JSON bodies are taken as JSON only, and every answer carries the security
//! headers (a CSP that runs only the server's own scripts, no framing, no sniffing, no
//! referrer).

use axum::extract::{Request, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::problem::ApiError;
use super::AppState;

/// The sites whose pages may call the API (`--cors-origin`), as `scheme://host[:port]`.
#[derive(Clone, Debug, Default)]
pub struct CrossSite {
    pub allowed: Vec<String>,
}

/// The dashboard's one inline script, its import map: allowed by its hash, so that no other
/// inline script runs.
const IMPORT_MAP: &str = r#"{"imports": {"three": "/ui/three.module.js"}}"#;

/// The Content-Security-Policy of every answer: scripts from this server and the import map
/// only; styles may be set inline (the dashboard sizes its elements); images and models from
/// this server, data: and blob: URLs; no framing by any site.
pub fn content_security_policy() -> String {
    use base64::Engine as _;
    use sha2::Digest as _;
    let hash = base64::engine::general_purpose::STANDARD.encode(sha2::Sha256::digest(IMPORT_MAP));
    format!(
        "default-src 'self'; script-src 'self' 'sha256-{hash}'; style-src 'self' 'unsafe-inline'; \
         img-src 'self' data: blob:; connect-src 'self'; object-src 'none'; base-uri 'none'; \
         form-action 'self'; frame-ancestors 'none'"
    )
}

/// Whether `origin` is the server the request was sent to (its Host), by any scheme.
fn same_origin(origin: &str, headers: &HeaderMap) -> bool {
    let Some(host) = headers.get(header::HOST).and_then(|h| h.to_str().ok()) else {
        return false;
    };
    origin
        .strip_prefix("http://")
        .or_else(|| origin.strip_prefix("https://"))
        .is_some_and(|authority| authority.eq_ignore_ascii_case(host))
}

/// Refuses a request from another site's page (403, `cross-origin-refused`) unless that site
/// is allowed; API clients (curl, an MES) send no Origin and are not concerned.
pub async fn refuse_cross_site(
    State(state): State<AppState>,
    req: Request,
    next: Next,
) -> Response {
    if let Some(origin) = req.headers().get(header::ORIGIN) {
        let text = origin.to_str().unwrap_or("");
        let allowed = state.cross_site.allowed.iter().any(|a| a == text);
        if !allowed && !same_origin(text, req.headers()) {
            return ApiError::new(
                StatusCode::FORBIDDEN,
                "cross-origin-refused",
                "Request from another site refused",
                format!(
                    "a request from a page of `{text}` is refused: this server answers its own \
                     pages and API clients; start it with --cors-origin {text} to let that site call it"
                ),
            )
            .with("origin", text.to_string())
            .into_response();
        }
    }
    next.run(req).await
}

/// A JSON body must say it is JSON (`application/json` or `…+json`), or say nothing: a form or
/// `text/plain` post is what a page on another site can send without asking.
pub fn require_json(headers: &HeaderMap) -> Result<(), ApiError> {
    let Some(ct) = headers.get(header::CONTENT_TYPE) else {
        return Ok(());
    };
    let essence = ct
        .to_str()
        .unwrap_or("")
        .split(';')
        .next()
        .unwrap_or("")
        .trim()
        .to_ascii_lowercase();
    if essence == "application/json" || essence.ends_with("+json") || essence.is_empty() {
        return Ok(());
    }
    Err(ApiError::new(
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
        "unsupported-media-type",
        "Unsupported media type",
        format!("this body is JSON: send Content-Type: application/json, not `{essence}`"),
    ))
}

/// The security headers every answer carries (set where a handler did not set its own).
pub fn security_headers() -> [(header::HeaderName, HeaderValue); 4] {
    [
        (
            header::CONTENT_SECURITY_POLICY,
            HeaderValue::from_str(&content_security_policy()).expect("an ASCII policy"),
        ),
        (header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY")),
        (
            header::X_CONTENT_TYPE_OPTIONS,
            HeaderValue::from_static("nosniff"),
        ),
        (
            header::REFERRER_POLICY,
            HeaderValue::from_static("no-referrer"),
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_policy_allows_the_import_map_in_the_dashboard_page() {
        // The page's import map must be exactly the text the hash is of, or the 3-D views
        // stop loading under the policy.
        let page = include_str!("../../web/index.html");
        assert!(
            page.contains(&format!("<script type=\"importmap\">{IMPORT_MAP}</script>")),
            "web/index.html's import map changed: update IMPORT_MAP"
        );
        assert!(content_security_policy().contains("'sha256-"));
    }

    #[test]
    fn same_origin_is_the_host_the_request_went_to() {
        let mut h = HeaderMap::new();
        h.insert(header::HOST, HeaderValue::from_static("127.0.0.1:8080"));
        assert!(same_origin("http://127.0.0.1:8080", &h));
        assert!(!same_origin("http://127.0.0.1:8081", &h));
        assert!(!same_origin("http://evil.example", &h));
        assert!(!same_origin("null", &h));
    }
}
