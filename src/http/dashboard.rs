//! The web dashboard: static files under web/, embedded in the binary and served on the
//! API's own origin (nothing is fetched from another host). `/` is the job list (served by
//! ops::index from the same web/index.html), `/jobs/{id}` one job; the page reads
//! everything through the public API under /v1, with the user's API key where the server
//! requires one.

use axum::extract::Path;
use axum::http::{header, HeaderValue};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use axum::Router;

use super::problem::ApiError;
use super::AppState;

/// The routes this module serves, for the route table (and openapi.yaml).
pub const ROUTES: [&str; 2] = ["/jobs/{id}", "/ui/{file}"];

/// Every embedded file as (name under /ui/, content type, bytes).
const FILES: [(&str, &str, &[u8]); 11] = [
    (
        "dashboard.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../../web/dashboard.js"),
    ),
    (
        "dashboard.css",
        "text/css; charset=utf-8",
        include_bytes!("../../web/dashboard.css"),
    ),
    (
        "uPlot.iife.min.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../../web/vendor/uplot/uPlot.iife.min.js"),
    ),
    (
        "uPlot.min.css",
        "text/css; charset=utf-8",
        include_bytes!("../../web/vendor/uplot/uPlot.min.css"),
    ),
    (
        "uPlot.LICENSE.txt",
        "text/plain; charset=utf-8",
        include_bytes!("../../web/vendor/uplot/LICENSE"),
    ),
    (
        "stock3d.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../../web/stock3d.js"),
    ),
    (
        "three.module.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../../web/vendor/three/three.module.js"),
    ),
    (
        "three.core.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../../web/vendor/three/three.core.js"),
    ),
    (
        "STLLoader.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../../web/vendor/three/STLLoader.js"),
    ),
    (
        "OrbitControls.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../../web/vendor/three/OrbitControls.js"),
    ),
    (
        "three.LICENSE.txt",
        "text/plain; charset=utf-8",
        include_bytes!("../../web/vendor/three/LICENSE"),
    ),
];

pub fn routes() -> Router<AppState> {
    Router::new()
        .route(ROUTES[0], get(job_page))
        .route(ROUTES[1], get(file))
}

/// One job's page: the same document as `/`, which shows the job named by the path.
async fn job_page(Path(_id): Path<String>) -> Html<&'static str> {
    Html(include_str!("../../web/index.html"))
}

async fn file(Path(name): Path<String>) -> Response {
    match FILES.iter().find(|(n, _, _)| *n == name) {
        Some((_, content_type, bytes)) => (
            [
                (header::CONTENT_TYPE, HeaderValue::from_static(content_type)),
                // Embedded in this binary: revalidated on each load, so a new build is seen at once.
                (header::CACHE_CONTROL, HeaderValue::from_static("no-cache")),
            ],
            *bytes,
        )
            .into_response(),
        None => ApiError::not_found("dashboard file", &name).into_response(),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_embedded_file_is_named_once_and_not_empty() {
        let mut names: Vec<_> = super::FILES.iter().map(|f| f.0).collect();
        assert!(super::FILES.iter().all(|f| !f.2.is_empty()));
        names.sort();
        names.dedup();
        assert_eq!(names.len(), super::FILES.len());
    }
}
