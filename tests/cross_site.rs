//! Cross-site protection and security headers (issue 34): a page of another site cannot
//! submit, upload or register webhooks on a server without keys; JSON routes take JSON only;
//! every answer carries a CSP, no-framing, nosniff and no-referrer.

mod common;

use serde_json::{json, Value};

use common::*;

async fn post(
    c: &reqwest::Client,
    s: &Server,
    path: &str,
    origin: Option<&str>,
    ct: &str,
    body: String,
) -> (u16, Value, reqwest::header::HeaderMap) {
    let mut r = c.post(s.url(path)).header("content-type", ct).body(body);
    if let Some(o) = origin {
        r = r.header("origin", o);
    }
    let res = r.send().await.unwrap();
    let headers = res.headers().clone();
    let status = res.status().as_u16();
    let v: Value = res.json().await.unwrap_or(Value::Null);
    (status, v, headers)
}

#[tokio::test]
async fn another_sites_page_is_refused_and_json_is_json() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(
        &dir.path().join("t.db"),
        &[
            "--workers",
            "1",
            "--cors-origin",
            "https://mes.example:8443",
        ],
    );
    let c = client();
    let hook = json!({"url": "http://127.0.0.1:9/hook"}).to_string();
    // A page of another site: refused before anything is read, naming the origin.
    for (path, body) in [
        ("/v1/webhooks", hook.clone()),
        ("/v1/jobs", json!({"kind": "interpret"}).to_string()),
    ] {
        let (st, v, _) = post(
            &c,
            &s,
            path,
            Some("http://evil.example"),
            "text/plain",
            body,
        )
        .await;
        assert_eq!(st, 403, "{path}: {v}");
        assert_eq!(
            v["type"], "https://millsim.dev/problems/cross-origin-refused",
            "{v}"
        );
        assert_eq!(v["origin"], "http://evil.example", "{v}");
    }
    let list = get_json(&c, &s, "/v1/webhooks").await;
    assert_eq!(
        list["items"].as_array().map(|a| a.len()).unwrap_or(0),
        0,
        "{list}"
    );
    // The server's own page (its Origin is the server) and an API client (no Origin) pass;
    // an allowed site too, with its CORS header.
    let own = s.base.clone();
    let (st, v, _) = post(
        &c,
        &s,
        "/v1/webhooks",
        Some(&own),
        "application/json",
        hook.clone(),
    )
    .await;
    assert!(st == 201 || st == 422, "own origin: {st} {v}");
    let (st, v, h) = post(
        &c,
        &s,
        "/v1/webhooks",
        Some("https://mes.example:8443"),
        "application/json",
        hook.clone(),
    )
    .await;
    assert!(st == 201 || st == 422, "allowed origin: {st} {v}");
    assert_eq!(
        h.get("access-control-allow-origin")
            .and_then(|v| v.to_str().ok()),
        Some("https://mes.example:8443")
    );
    // JSON routes take JSON: a text/plain or form body is 415, whoever sends it.
    for ct in ["text/plain", "application/x-www-form-urlencoded"] {
        let (st, v, _) = post(&c, &s, "/v1/webhooks", None, ct, hook.clone()).await;
        assert_eq!(st, 415, "{ct}: {v}");
        let (st, v, _) = post(
            &c,
            &s,
            "/v1/jobs",
            None,
            ct,
            json!({"kind": "interpret"}).to_string(),
        )
        .await;
        assert_eq!(st, 415, "{ct}: {v}");
    }
}

#[tokio::test]
async fn every_answer_carries_the_security_headers() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(&dir.path().join("t.db"), &["--workers", "1"]);
    let c = client();
    for path in [
        "/",
        "/jobs/x",
        "/v1/jobs",
        "/healthz",
        "/openapi.yaml",
        "/v1/nothing",
    ] {
        let res = c.get(s.url(path)).send().await.unwrap();
        let h = res.headers();
        let csp = h
            .get("content-security-policy")
            .and_then(|v| v.to_str().ok())
            .unwrap_or("");
        assert!(
            csp.contains("script-src 'self' 'sha256-") && csp.contains("frame-ancestors 'none'"),
            "{path}: {csp}"
        );
        assert_eq!(h.get("x-frame-options").unwrap(), "DENY", "{path}");
        assert_eq!(
            h.get("x-content-type-options").unwrap(),
            "nosniff",
            "{path}"
        );
        assert_eq!(h.get("referrer-policy").unwrap(), "no-referrer", "{path}");
        assert!(
            h.get("access-control-allow-origin").is_none(),
            "{path}: no CORS without --cors-origin"
        );
    }
}
