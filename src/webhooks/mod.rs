//! Webhook deliveries: a dispatcher, separate from the job workers, posts the outbox's due
//! deliveries (written with each job state change, see `store::webhooks`), signs each
//! attempt, records it, and schedules a retry with exponential backoff. A receiver that
//! answers slowly holds one of the dispatcher's bounded delivery slots for at most the
//! request timeout, never a job worker, and one API key holds at most
//! `MAX_IN_FLIGHT_PER_KEY` of them: the keys take turns at the free ones, and within a
//! key its webhooks take turns, each at most `MAX_IN_FLIGHT_PER_WEBHOOK`.

pub mod signature;
pub mod target;

use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::sync::{watch, Semaphore};

use crate::store::webhooks::{AttemptOutcome, DueDelivery};
use crate::store::{now_ms, Db};

/// What the server allows webhooks (`--webhook-allow-private`).
#[derive(Clone, Copy, Debug, Default)]
pub struct WebhookConfig {
    /// Targets on private, loopback and link-local addresses are allowed.
    pub allow_private: bool,
}

/// How long a receiver has to answer one attempt.
const REQUEST_TIMEOUT: Duration = Duration::from_secs(10);
/// How long connecting may take, within the request timeout: a live receiver accepts in
/// milliseconds, and an address that drops the connection attempt would otherwise hold a
/// slot for the whole request timeout.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(2);

/// A claimed delivery is this dispatcher's for this long: resolving, connecting and the
/// request fit in it, so a live dispatcher never loses one it is still sending.
const LEASE_MS: i64 = 30_000;

/// Deliveries in flight at once, per dispatcher.
const MAX_IN_FLIGHT: usize = 16;

/// Deliveries of one API key in flight at once, over all dispatchers: a key whose
/// receivers never answer holds this many slots, the others stay free for other keys.
const MAX_IN_FLIGHT_PER_KEY: i64 = 4;

/// Deliveries of one webhook in flight at once: a key's dead receiver holds two of its
/// key's slots, and the key's other webhooks take turns at the rest.
const MAX_IN_FLIGHT_PER_WEBHOOK: i64 = 2;

/// How often an idle dispatcher looks for due deliveries: the first attempt follows a
/// job's state change within about this.
const POLL: Duration = Duration::from_millis(100);

/// The longest wait between two attempts.
const MAX_DELAY: Duration = Duration::from_secs(6 * 3600);

/// The wait after failed attempt `attempt` (1-based): 1 s, 2 s, 4 s, ... doubling up to
/// 6 h. With `store::webhooks::ATTEMPT_LIMIT` (20) attempts, the last comes about 33 h
/// after the first: a receiver down for a day still gets its deliveries.
pub fn retry_delay(attempt: i64) -> Duration {
    let exp = attempt.clamp(1, 32) - 1;
    Duration::from_secs(1u64 << exp).min(MAX_DELAY)
}

/// Runs until `shutdown` turns true: claims due deliveries and posts each on its own task.
pub async fn run_dispatcher(db: Db, config: WebhookConfig, mut shutdown: watch::Receiver<bool>) {
    let id = format!("{}-webhooks", crate::queue::process_worker_prefix());
    let slots = Arc::new(Semaphore::new(MAX_IN_FLIGHT));
    tracing::info!(dispatcher = %id, "webhook dispatcher started");
    loop {
        if *shutdown.borrow() {
            break;
        }
        let free = slots.available_permits();
        let claimed = if free == 0 {
            Vec::new()
        } else {
            match db.delivery_due().await {
                Ok(false) => Vec::new(),
                Ok(true) => match db
                    .claim_deliveries(
                        &id,
                        LEASE_MS,
                        free as i64,
                        MAX_IN_FLIGHT_PER_KEY,
                        MAX_IN_FLIGHT_PER_WEBHOOK,
                    )
                    .await
                {
                    Ok(due) => due,
                    Err(e) => {
                        tracing::warn!(error = %e, "claiming webhook deliveries failed");
                        Vec::new()
                    }
                },
                Err(e) => {
                    tracing::warn!(error = %e, "reading the webhook outbox failed");
                    Vec::new()
                }
            }
        };
        let idle = claimed.is_empty();
        for delivery in claimed {
            let Ok(permit) = slots.clone().acquire_owned().await else {
                break;
            };
            let (db, id) = (db.clone(), id.clone());
            tokio::spawn(async move {
                deliver(&db, &id, delivery, config).await;
                drop(permit);
            });
        }
        if idle {
            tokio::select! {
                _ = tokio::time::sleep(POLL) => {}
                _ = shutdown.changed() => {}
            }
        }
    }
    tracing::info!(dispatcher = %id, "webhook dispatcher stopped");
}

/// One attempt: post, record, schedule what comes next.
async fn deliver(db: &Db, dispatcher: &str, d: DueDelivery, config: WebhookConfig) {
    let started_at = now_ms();
    let clock = Instant::now();
    let answer = post(&d, config).await;
    let duration_ms = clock.elapsed().as_millis() as i64;
    let (status_code, error) = match answer {
        Ok(code) => (Some(code), None),
        Err(e) => (None, Some(e)),
    };
    let delivered = status_code.is_some_and(|c| (200..300).contains(&c));
    let retry_at = (!delivered && d.attempt < d.attempt_limit)
        .then(|| now_ms() + retry_delay(d.attempt).as_millis() as i64);
    let outcome = AttemptOutcome {
        started_at,
        duration_ms,
        status_code,
        error,
        delivered,
        retry_at,
    };
    match db.record_attempt(&d, dispatcher, &outcome).await {
        Ok(true) => tracing::info!(
            delivery = %d.id, event = %d.event, attempt = d.attempt, delivered,
            status = ?outcome.status_code, error = ?outcome.error, ms = duration_ms,
            "webhook delivery attempt"
        ),
        Ok(false) => {
            tracing::warn!(delivery = %d.id, "webhook delivery lease lost; attempt not recorded")
        }
        Err(e) => {
            tracing::error!(delivery = %d.id, error = %e, "could not record a webhook attempt")
        }
    }
}

/// Posts the delivery, signed now; the receiver's status code, or why there is none.
async fn post(d: &DueDelivery, config: WebhookConfig) -> Result<u16, String> {
    let url = target::check_url(&d.url, config.allow_private)?;
    let addrs = target::resolve(&url, config.allow_private).await?;
    let host = url.host_str().unwrap_or_default().to_string();
    // The client connects only to the addresses checked above, and follows no redirect
    // (a redirect could lead anywhere).
    let client = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .connect_timeout(CONNECT_TIMEOUT)
        .timeout(REQUEST_TIMEOUT)
        .resolve_to_addrs(&host, &addrs)
        .user_agent(concat!("millsim-webhooks/", env!("CARGO_PKG_VERSION")))
        .build()
        .map_err(|e| format!("HTTP client: {e}"))?;
    let signature = signature::header(&d.secret, now_ms() / 1000, &d.body);
    let res = client
        .post(url)
        .header("content-type", "application/json")
        .header("millsim-signature", signature)
        .header("millsim-event", &d.event)
        .header("millsim-delivery", &d.id)
        .body(d.body.clone())
        .send()
        .await
        .map_err(|e| {
            if e.is_connect() && e.is_timeout() {
                format!("cannot connect within {CONNECT_TIMEOUT:?}")
            } else if e.is_timeout() {
                format!("no answer within {REQUEST_TIMEOUT:?}")
            } else if e.is_connect() {
                format!("cannot connect: {}", root_cause(&e))
            } else {
                root_cause(&e)
            }
        })?;
    Ok(res.status().as_u16())
}

/// The innermost cause of an error (reqwest wraps the socket's).
fn root_cause(e: &(dyn std::error::Error + 'static)) -> String {
    let mut cause: &(dyn std::error::Error + 'static) = e;
    // Bounded: error chains are a few links long.
    for _ in 0..16 {
        match cause.source() {
            Some(next) => cause = next,
            None => break,
        }
    }
    cause.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retries_start_within_seconds_and_span_over_a_day() {
        assert_eq!(retry_delay(1), Duration::from_secs(1));
        assert_eq!(retry_delay(2), Duration::from_secs(2));
        assert_eq!(retry_delay(3), Duration::from_secs(4));
        assert_eq!(retry_delay(40), MAX_DELAY);
        let limit = crate::store::webhooks::ATTEMPT_LIMIT;
        let span: Duration = (1..limit).map(retry_delay).sum();
        assert!(span > Duration::from_secs(24 * 3600), "{span:?}");
        assert!(span < Duration::from_secs(48 * 3600), "{span:?}");
    }
}
