//! Problem documents at the HTTP edge: the one place where errors become responses
//! (`application/problem+json`), and where storage errors become problems.

use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};

pub use crate::problem::{parse_json, Problem as ApiError};
use crate::store::StoreError;

pub const PROBLEM_JSON: &str = "application/problem+json";

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

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

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
