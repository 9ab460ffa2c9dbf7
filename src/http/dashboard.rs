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
macro_rules! embed {
    ($($name:literal => $path:literal),* $(,)?) => {
        [$(($name, content_type($name), include_bytes!(concat!("../../web/", $path)) as &[u8])),*]
    };
}

const fn content_type(name: &str) -> &'static str {
    let b = name.as_bytes();
    match b[b.len() - 1] {
        b's' if b[b.len() - 2] == b'j' => "text/javascript; charset=utf-8",
        b's' => "text/css; charset=utf-8",
        _ => "text/plain; charset=utf-8",
    }
}

// The dashboard's own modules, one view or concern each, then the vendored libraries.
const FILES: [(&str, &str, &[u8]); 33] = embed![
    "app.js" => "app.js",
    "util.js" => "util.js",
    "api.js" => "api.js",
    "list.js" => "list.js",
    "job.js" => "job.js",
    "newjob.js" => "newjob.js",
    "processform.js" => "processform.js",
    "cutting.js" => "cutting.js",
    "rows.js" => "rows.js",
    "blockplots.js" => "blockplots.js",
    "panzoom.js" => "panzoom.js",
    "samples.js" => "samples.js",
    "programdiff.js" => "programdiff.js",
    "xyplot.js" => "xyplot.js",
    "stability.js" => "stability.js",
    "lobes3d.js" => "lobes3d.js",
    "energy.js" => "energy.js",
    "interpret.js" => "interpret.js",
    "toolpath3d.js" => "toolpath3d.js",
    "rotaryfeed.js" => "rotaryfeed.js",
    "identify.js" => "identify.js",
    "accessibility.js" => "accessibility.js",
    "process.js" => "process.js",
    "stock3d.js" => "stock3d.js",
    "dashboard.css" => "dashboard.css",
    "uPlot.iife.min.js" => "vendor/uplot/uPlot.iife.min.js",
    "uPlot.min.css" => "vendor/uplot/uPlot.min.css",
    "uPlot.LICENSE.txt" => "vendor/uplot/LICENSE",
    "three.module.js" => "vendor/three/three.module.js",
    "three.core.js" => "vendor/three/three.core.js",
    "STLLoader.js" => "vendor/three/STLLoader.js",
    "OrbitControls.js" => "vendor/three/OrbitControls.js",
    "three.LICENSE.txt" => "vendor/three/LICENSE",
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

    #[test]
    fn every_module_of_web_is_embedded() {
        // A module added to web/ but not to FILES would 404 in the browser only.
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("web");
        for entry in std::fs::read_dir(dir).unwrap() {
            let name = entry.unwrap().file_name().into_string().unwrap();
            if name.ends_with(".js") || name.ends_with(".css") {
                assert!(
                    super::FILES.iter().any(|f| f.0 == name),
                    "web/{name} is not embedded"
                );
            }
        }
        assert_eq!(
            super::content_type("a.js"),
            "text/javascript; charset=utf-8"
        );
        assert_eq!(super::content_type("a.css"), "text/css; charset=utf-8");
        assert_eq!(
            super::content_type("LICENSE.txt"),
            "text/plain; charset=utf-8"
        );
    }
}
