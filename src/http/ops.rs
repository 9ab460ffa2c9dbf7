//! Operational routes: health, readiness, metrics, the contract, the landing page.

use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::{Html, IntoResponse, Response};

use super::problem::ApiError;
use super::AppState;

pub const OPENAPI_YAML: &str = include_str!("../../openapi.yaml");

pub async fn index() -> Html<&'static str> {
    Html(include_str!("../../web/index.html"))
}

pub async fn openapi() -> Response {
    ([(header::CONTENT_TYPE, "application/yaml")], OPENAPI_YAML).into_response()
}

pub async fn healthz() -> Response {
    (
        StatusCode::OK,
        [(header::CONTENT_TYPE, "application/json")],
        r#"{"status":"ok"}"#,
    )
        .into_response()
}

pub async fn readyz(State(state): State<AppState>) -> Response {
    match state.db.ready().await {
        Ok(()) => (
            StatusCode::OK,
            [(header::CONTENT_TYPE, "application/json")],
            r#"{"status":"ready"}"#,
        )
            .into_response(),
        Err(why) => ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "not-ready",
            "Not ready",
            why,
        )
        .into_response(),
    }
}

pub async fn metrics(State(state): State<AppState>) -> Response {
    let counts = state.db.job_counts().await.unwrap_or_default();
    let workers = state.db.live_workers().await.unwrap_or_default();
    let text = state.metrics.render(&counts, &workers);
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response()
}
