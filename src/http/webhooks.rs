//! Webhooks: registration (the secret is shown once), listing, deletion, and each
//! webhook's deliveries with their attempts, redelivered on request. Per API key: another
//! key's webhooks are not found.

use axum::extract::{Path, Request, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Deserialize;
use serde_json::{json, Value};

use super::body::read_limited;
use super::problem::{parse_json, ApiError};
use super::{parse_query, AppState, Owner, PageQuery};
use crate::store::webhooks::{DEFAULT_EVENTS, EVENTS};
use crate::webhooks::{signature, target};

/// Webhooks one API key may have: each one multiplies every job event.
const MAX_WEBHOOKS_PER_KEY: i64 = 100;

/// Largest registration body.
const MAX_BODY: u64 = 16 << 10;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WebhookRequest {
    url: String,
    /// Default: every event.
    #[serde(default)]
    events: Option<Vec<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ListQuery {
    cursor: Option<String>,
    limit: Option<String>,
}

impl ListQuery {
    fn limit(&self) -> Result<u32, ApiError> {
        PageQuery {
            cursor: None,
            limit: self.limit.clone(),
            status: None,
            kind: None,
        }
        .limit()
    }
}

pub async fn create(
    State(state): State<AppState>,
    Owner(owner): Owner,
    req: Request,
) -> Result<Response, ApiError> {
    let headers = req.headers().clone();
    super::guard::require_json(&headers)?;
    let bytes = read_limited(&headers, req.into_body(), MAX_BODY).await?;
    let request: WebhookRequest = parse_json(&bytes)?;
    let url = target::check_url(&request.url, state.webhooks.allow_private)
        .map_err(|m| ApiError::invalid_field("url", format!("`{}`: {m}", request.url)))?;
    let events = match request.events {
        None => DEFAULT_EVENTS.iter().map(|e| e.to_string()).collect(),
        Some(list) if list.is_empty() => {
            return Err(ApiError::invalid_field(
                "events",
                format!("name at least one event: {}", EVENTS.join(", ")),
            ))
        }
        Some(list) => {
            let mut events: Vec<String> = Vec::new();
            for (i, e) in list.into_iter().enumerate() {
                if !EVENTS.contains(&e.as_str()) {
                    return Err(ApiError::invalid_field(
                        format!("events[{i}]"),
                        format!("unknown event `{e}`; one of: {}", EVENTS.join(", ")),
                    ));
                }
                if !events.contains(&e) {
                    events.push(e);
                }
            }
            events
        }
    };
    if state.db.count_webhooks(&owner).await? >= MAX_WEBHOOKS_PER_KEY {
        return Err(ApiError::conflict(format!(
            "this API key already has {MAX_WEBHOOKS_PER_KEY} webhooks; delete one first"
        ))
        .with("limit", MAX_WEBHOOKS_PER_KEY));
    }
    let secret = signature::new_secret();
    let hook = state
        .db
        .create_webhook(&owner, url.as_str(), &events, &secret)
        .await?;
    let mut doc = serde_json::to_value(&hook).expect("webhooks serialize");
    // Shown this once: the server keeps it only to sign deliveries.
    doc["secret"] = Value::String(secret);
    Ok((
        StatusCode::CREATED,
        [(header::LOCATION, format!("/v1/webhooks/{}", hook.id))],
        Json(doc),
    )
        .into_response())
}

pub async fn list(
    State(state): State<AppState>,
    Owner(owner): Owner,
    req: Request,
) -> Result<Response, ApiError> {
    let q: ListQuery = parse_query(req.uri().query())?;
    let (items, next) = state
        .db
        .list_webhooks(&owner, q.cursor.as_deref(), q.limit()?)
        .await?;
    Ok(Json(json!({ "items": items, "next_cursor": next })).into_response())
}

pub async fn get_one(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let hook = state
        .db
        .get_webhook(&owner, &id)
        .await?
        .ok_or_else(|| ApiError::not_found("webhook", &id))?;
    Ok(Json(hook).into_response())
}

pub async fn delete(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    if !state.db.delete_webhook(&owner, &id).await? {
        return Err(ApiError::not_found("webhook", &id));
    }
    Ok(StatusCode::NO_CONTENT.into_response())
}

pub async fn deliveries(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path(id): Path<String>,
    req: Request,
) -> Result<Response, ApiError> {
    let q: ListQuery = parse_query(req.uri().query())?;
    state
        .db
        .get_webhook(&owner, &id)
        .await?
        .ok_or_else(|| ApiError::not_found("webhook", &id))?;
    let (items, next) = state
        .db
        .list_deliveries(&owner, &id, q.cursor.as_deref(), q.limit()?)
        .await?;
    Ok(Json(json!({ "items": items, "next_cursor": next })).into_response())
}

/// Sends a delivery again now (with a fresh allowance of attempts), whatever its state.
pub async fn redeliver(
    State(state): State<AppState>,
    Owner(owner): Owner,
    Path((id, delivery)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    if !state.db.redeliver(&owner, &id, &delivery).await? {
        return Err(ApiError::not_found("delivery", &delivery).with("webhook_id", id));
    }
    let record = state
        .db
        .get_delivery(&owner, &id, &delivery)
        .await?
        .ok_or_else(|| ApiError::not_found("delivery", &delivery))?;
    Ok((StatusCode::ACCEPTED, Json(record)).into_response())
}
