//! The HTTP edge: routes, per-route limits and timeouts, auth, request ids, metrics.

pub mod auth;
pub mod body;
pub mod chunked;
pub mod dashboard;
pub mod download;
pub mod guard;
pub mod jobs;
pub mod ops;
pub mod parsing;
pub mod problem;
pub mod resources;
pub mod rows_csv;
pub mod server;
pub mod webhooks;

use std::sync::Arc;
use std::time::Duration;

use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::http::{HeaderName, HeaderValue, Method, StatusCode};
use axum::middleware::{self, Next};
use axum::response::Response;
use axum::routing::{get, post};
use axum::Router;
use tokio::sync::Notify;
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::set_header::SetResponseHeaderLayer;
use tower_http::timeout::TimeoutLayer;
use tower_http::trace::{DefaultOnResponse, TraceLayer};

use crate::config::Limits;
use crate::metrics::Metrics;
use crate::store::{Db, ResourceKind};
use problem::ApiError;

#[derive(Clone)]
pub struct AppState {
    pub db: Db,
    pub limits: Arc<Limits>,
    pub metrics: Arc<Metrics>,
    pub auth: Arc<auth::Auth>,
    /// Wakes this process's idle workers when a job is submitted.
    pub job_submitted: Arc<Notify>,
    /// Turns true on SIGTERM/SIGINT: long responses (event streams) end so the server can stop.
    pub shutdown: tokio::sync::watch::Receiver<bool>,
    pub max_attempts: i64,
    /// What each job is held to: submissions estimated over it are refused.
    pub job_limits: crate::job_budget::JobLimits,
    /// Which webhook targets registration accepts.
    pub webhooks: crate::webhooks::WebhookConfig,
    /// The other sites whose pages may call the API (`--cors-origin`).
    pub cross_site: Arc<guard::CrossSite>,
}

/// Every route of the service, as (method, path) in the router's syntax. The router is
/// built from the same handlers below and a test checks this list against both the
/// live router and openapi.yaml, so the three cannot drift apart.
pub fn route_table() -> Vec<(Method, String)> {
    let mut routes: Vec<(Method, String)> = vec![
        (Method::GET, "/".into()),
        (Method::GET, "/openapi.yaml".into()),
        (Method::GET, "/healthz".into()),
        (Method::GET, "/readyz".into()),
        (Method::GET, "/metrics".into()),
    ];
    routes.extend(
        dashboard::ROUTES
            .iter()
            .map(|p| (Method::GET, p.to_string())),
    );
    for kind in ResourceKind::ALL {
        let c = kind.collection();
        routes.push((Method::POST, format!("/v1/{c}")));
        routes.push((Method::GET, format!("/v1/{c}")));
        routes.push((Method::GET, format!("/v1/{c}/{{id}}")));
        routes.push((Method::DELETE, format!("/v1/{c}/{{id}}")));
        routes.push((Method::GET, format!("/v1/{c}/{{id}}/content")));
    }
    for (m, p) in [
        (Method::POST, "/v1/jobs"),
        (Method::GET, "/v1/jobs"),
        (Method::GET, "/v1/jobs/{id}"),
        (Method::DELETE, "/v1/jobs/{id}"),
        (Method::POST, "/v1/jobs/{id}/cancel"),
        (Method::GET, "/v1/jobs/{id}/events"),
        (Method::GET, "/v1/jobs/{id}/attempts"),
        (Method::GET, "/v1/jobs/{id}/summary"),
        (Method::GET, "/v1/jobs/{id}/blocks"),
        (Method::GET, "/v1/jobs/{id}/blocks/{range}/samples"),
        (Method::GET, "/v1/jobs/{id}/program"),
        (Method::GET, "/v1/jobs/{id}/stock.stl"),
        (Method::GET, "/v1/jobs/{id}/free_region.svg"),
        (Method::POST, "/v1/webhooks"),
        (Method::GET, "/v1/webhooks"),
        (Method::GET, "/v1/webhooks/{id}"),
        (Method::DELETE, "/v1/webhooks/{id}"),
        (Method::GET, "/v1/webhooks/{id}/deliveries"),
        (
            Method::POST,
            "/v1/webhooks/{id}/deliveries/{delivery_id}/redeliver",
        ),
    ] {
        routes.push((m, p.into()));
    }
    routes
}

pub fn router(state: AppState) -> Router {
    let timeout = |secs: u64| {
        TimeoutLayer::with_status_code(StatusCode::REQUEST_TIMEOUT, Duration::from_secs(secs))
    };
    let limits = state.limits.clone();

    let mut api = Router::new();
    for kind in ResourceKind::ALL {
        let c = kind.collection();
        // Uploads get their own (long) timeout; the body limit is enforced while streaming.
        api = api
            .route(
                &format!("/v1/{c}"),
                post(move |s, o, r| resources::create(kind, s, o, r))
                    .get(move |s, o, r| resources::list(kind, s, o, r)),
            )
            .route(
                &format!("/v1/{c}/{{id}}"),
                get(move |s, o, p| resources::get_one(kind, s, o, p))
                    .delete(move |s, o, p| resources::delete(kind, s, o, p)),
            )
            .route(
                &format!("/v1/{c}/{{id}}/content"),
                get(move |s, o, p| resources::content(kind, s, o, p)),
            );
    }
    let api = api
        .route("/v1/jobs", post(jobs::create).get(jobs::list))
        .route("/v1/jobs/{id}", get(jobs::get_one).delete(jobs::delete))
        .route("/v1/jobs/{id}/cancel", post(jobs::cancel))
        .route("/v1/jobs/{id}/attempts", get(jobs::attempts))
        .route("/v1/jobs/{id}/summary", get(jobs::summary))
        .route("/v1/jobs/{id}/blocks", get(jobs::blocks))
        .route("/v1/jobs/{id}/blocks/{range}/samples", get(jobs::samples))
        .route("/v1/jobs/{id}/program", get(jobs::program))
        .route("/v1/jobs/{id}/stock.stl", get(jobs::stock_stl))
        .route("/v1/jobs/{id}/free_region.svg", get(jobs::free_region_svg))
        .route("/v1/webhooks", post(webhooks::create).get(webhooks::list))
        .route(
            "/v1/webhooks/{id}",
            get(webhooks::get_one).delete(webhooks::delete),
        )
        .route("/v1/webhooks/{id}/deliveries", get(webhooks::deliveries))
        .route(
            "/v1/webhooks/{id}/deliveries/{delivery_id}/redeliver",
            post(webhooks::redeliver),
        )
        .layer(timeout(limits.upload_timeout_secs))
        // Multipart reads through axum's limit; raw bodies are limited by body::read_limited.
        .layer(DefaultBodyLimit::max(limits.max_stl_bytes as usize))
        // Server-sent events last as long as the job: no request timeout.
        .route("/v1/jobs/{id}/events", get(jobs::events))
        .route_layer(middleware::from_fn_with_state(
            state.clone(),
            auth::require_key,
        ))
        .route_layer(middleware::from_fn_with_state(
            state.clone(),
            body::body_timeout,
        ));

    let ops = Router::new()
        .route("/", get(ops::index))
        .route("/openapi.yaml", get(ops::openapi))
        .route("/healthz", get(ops::healthz))
        .route("/readyz", get(ops::readyz))
        .route("/metrics", get(ops::metrics))
        .merge(dashboard::routes())
        .layer(timeout(30));

    let request_id = HeaderName::from_static("x-request-id");
    let router = Router::new()
        .merge(api)
        .merge(ops)
        .fallback(fallback)
        .method_not_allowed_fallback(method_not_allowed)
        // Innermost of the outer layers, so metrics and the trace see the 500 it answers.
        .layer(CatchPanicLayer::custom(problem::panic_response))
        .layer(middleware::from_fn_with_state(state.clone(), record_metrics))
        .layer(
            TraceLayer::new_for_http()
                .make_span_with(|req: &Request| {
                    let id = req.headers().get("x-request-id").and_then(|v| v.to_str().ok()).unwrap_or("-");
                    tracing::info_span!("request", method = %req.method(), uri = %req.uri(), request_id = %id)
                })
                // One line per request at the default level, with its status and latency.
                .on_response(DefaultOnResponse::new().level(tracing::Level::INFO)),
        )
        .layer(PropagateRequestIdLayer::new(request_id.clone()))
        .layer(SetRequestIdLayer::new(request_id, MakeRequestUuid))
        .layer(cors(&state.cross_site))
        .layer(middleware::from_fn_with_state(
            state.clone(),
            guard::refuse_cross_site,
        ));
    let router = guard::security_headers()
        .into_iter()
        .fold(router, |r, (name, value)| {
            r.layer(SetResponseHeaderLayer::if_not_present(name, value))
        });
    router.with_state(state)
}

/// CORS for the sites `--cors-origin` allows (none by default: no CORS headers at all).
fn cors(sites: &guard::CrossSite) -> CorsLayer {
    let origins: Vec<HeaderValue> = sites
        .allowed
        .iter()
        .filter_map(|o| HeaderValue::from_str(o).ok())
        .collect();
    if origins.is_empty() {
        return CorsLayer::new();
    }
    CorsLayer::new()
        .allow_origin(AllowOrigin::list(origins))
        .allow_methods(tower_http::cors::Any)
        .allow_headers(tower_http::cors::Any)
}

async fn fallback(req: Request) -> ApiError {
    ApiError::new(
        StatusCode::NOT_FOUND,
        "no-route",
        "No such route",
        format!("no route for {} {}", req.method(), req.uri().path()),
    )
}

async fn method_not_allowed(req: Request) -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        "method-not-allowed",
        "Method not allowed",
        format!("{} is not allowed on {}", req.method(), req.uri().path()),
    )
}

async fn record_metrics(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map(|p| p.as_str().to_string())
        .unwrap_or_else(|| "unmatched".into());
    let method = req.method().clone();
    let start = std::time::Instant::now();
    let res = next.run(req).await;
    state.metrics.observe_request(
        method.as_str(),
        &route,
        res.status().as_u16(),
        start.elapsed(),
    );
    res
}

/// The owner of the resources a request may see: the API key's name, or "" when auth is off.
#[derive(Clone, Debug)]
pub struct Owner(pub String);

impl<S: Send + Sync> axum::extract::FromRequestParts<S> for Owner {
    type Rejection = ApiError;
    async fn from_request_parts(
        parts: &mut axum::http::request::Parts,
        _: &S,
    ) -> Result<Self, Self::Rejection> {
        parts
            .extensions
            .get::<Owner>()
            .cloned()
            .ok_or_else(|| ApiError::unauthorized("no API key"))
    }
}

/// Query parameters of a list route.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PageQuery {
    pub cursor: Option<String>,
    pub limit: Option<String>,
    pub status: Option<String>,
    pub kind: Option<String>,
}

impl PageQuery {
    pub fn limit(&self) -> Result<u32, ApiError> {
        match &self.limit {
            None => Ok(50),
            Some(s) => match s.parse::<u32>() {
                Ok(n) if (1..=1000).contains(&n) => Ok(n),
                _ => Err(ApiError::invalid_field(
                    "limit",
                    format!("`limit` must be an integer from 1 to 1000, got `{s}`"),
                )),
            },
        }
    }
}

/// Parses a query string with a problem document (not axum's plain-text rejection).
pub fn parse_query<T: serde::de::DeserializeOwned>(query: Option<&str>) -> Result<T, ApiError> {
    let q = query.unwrap_or("");
    serde_urlencoded_parse(q)
}

fn serde_urlencoded_parse<T: serde::de::DeserializeOwned>(q: &str) -> Result<T, ApiError> {
    axum::extract::Query::<T>::try_from_uri(
        &format!("/?{q}")
            .parse()
            .map_err(|_| ApiError::bad_request("malformed query string"))?,
    )
    .map(|axum::extract::Query(v)| v)
    .map_err(|e| ApiError::bad_request(format!("query string: {}", e.body_text())))
}
