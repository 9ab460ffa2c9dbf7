//! Webhook subscriptions and their durable outbox: deliveries are written in the same
//! transaction as the job's state change ([`enqueue_job_event`]), claimed by a dispatcher
//! with a lease, and every attempt is recorded. Plain SQL that PostgreSQL also reads.

use serde::Serialize;
use serde_json::{json, Value};

use super::backend::{on_pool, on_tx, RowGet, Tx};
use super::{new_id, now_ms, rfc3339, Db, StoreError};

/// The events a webhook may subscribe to.
pub const EVENTS: [&str; 4] = [
    "job.succeeded",
    "job.failed",
    "job.cancelled",
    "job.progress",
];

/// What a webhook registered without `events` gets: the end of every job.
pub const DEFAULT_EVENTS: [&str; 3] = ["job.succeeded", "job.failed", "job.cancelled"];

/// `job.progress` deliveries of one job are at least this far apart, ms (the worker's
/// heartbeat records progress four times a second).
pub const PROGRESS_INTERVAL_MS: i64 = 1000;

/// Deliveries one API key may have pending: a key whose receivers do not keep up gets
/// further events recorded as failed (listed, redeliverable) instead of an outbox that
/// grows without bound.
pub const MAX_QUEUED_PER_KEY: i64 = 1000;

/// Attempts a delivery gets before it is given up (see `webhooks::retry_delay` for the
/// schedule: over a day from the first to the last).
pub const ATTEMPT_LIMIT: i64 = 20;

#[derive(Clone, Debug, Serialize)]
pub struct WebhookRecord {
    pub id: String,
    pub url: String,
    pub events: Vec<String>,
    pub created_at: String,
}

fn webhook_record(row: &impl RowGet) -> Result<WebhookRecord, StoreError> {
    Ok(WebhookRecord {
        id: row.col("id")?,
        url: row.col("url")?,
        events: serde_json::from_str(&row.col::<String>("events")?)?,
        created_at: rfc3339(row.col("created_at")?),
    })
}

#[derive(Clone, Debug, Serialize)]
pub struct AttemptRecord {
    pub attempt: i64,
    pub started_at: String,
    pub duration_ms: i64,
    pub status_code: Option<i64>,
    pub error: Option<String>,
}

#[derive(Clone, Debug, Serialize)]
pub struct DeliveryRecord {
    pub id: String,
    pub webhook_id: String,
    pub event: String,
    pub job_id: String,
    /// pending | delivered | failed
    pub status: String,
    pub attempt_count: i64,
    pub created_at: String,
    pub delivered_at: Option<String>,
    pub next_attempt_at: Option<String>,
    pub last_error: Option<String>,
    pub attempts: Vec<AttemptRecord>,
}

/// An attempt as stored: (attempt, started_at, duration_ms, status_code, error).
type AttemptRow = (i64, i64, i64, Option<i64>, Option<String>);

/// A delivery a dispatcher claimed: where to post what, signed with which secret.
#[derive(Clone, Debug)]
pub struct DueDelivery {
    pub id: String,
    pub url: String,
    pub secret: String,
    pub event: String,
    pub body: String,
    /// The number of this attempt (1 for the first).
    pub attempt: i64,
    pub attempt_limit: i64,
}

/// How an attempt ended.
pub struct AttemptOutcome {
    pub started_at: i64,
    pub duration_ms: i64,
    pub status_code: Option<u16>,
    pub error: Option<String>,
    /// The receiver took it (a 2xx answer).
    pub delivered: bool,
    /// When to try again if it did not; None: give up.
    pub retry_at: Option<i64>,
}

/// Writes one delivery per webhook of the job's owner that subscribes to `event`, inside
/// the transaction that changes the job's state: the event exists exactly when the change
/// does.
pub async fn enqueue_job_event(tx: &mut Tx, job_id: &str, event: &str) -> Result<(), StoreError> {
    // The owner's webhooks first: most owners have none, and then the job is not read.
    let hooks: Vec<(String, String)> = on_tx!(tx, c => sqlx::query_as(
        "SELECT id, events FROM webhooks WHERE owner = (SELECT owner FROM jobs WHERE id = $1) ORDER BY id",
    )
    .bind(job_id)
    .fetch_all(&mut *c)
    .await?);
    if hooks.is_empty() {
        return Ok(());
    }
    type JobRow = (
        String,
        String,
        String,
        i64,
        Option<String>,
        i64,
        Option<i64>,
        i64,
        i64,
    );
    let job: Option<JobRow> = on_tx!(tx, c => sqlx::query_as(
        "SELECT owner, kind, status, attempts, error, created_at, finished_at, progress_done, progress_total FROM jobs WHERE id = $1",
    )
    .bind(job_id)
    .fetch_optional(&mut *c)
    .await?);
    let Some((owner, kind, status, attempts, error, created_at, finished_at, done, total)) = job
    else {
        return Ok(());
    };
    let now = now_ms();
    let (mut queued,): (i64,) = on_tx!(tx, c => sqlx::query_as(
        "SELECT COUNT(*) FROM webhook_deliveries WHERE owner = $1 AND status = 'pending'",
    )
    .bind(&owner)
    .fetch_one(&mut *c)
    .await?);
    for (webhook_id, events) in hooks {
        let events: Vec<String> = serde_json::from_str(&events)?;
        if !events.iter().any(|e| e == event) {
            continue;
        }
        let body = |id: &str| -> Result<String, StoreError> {
            let mut job_doc = json!({
                "id": job_id,
                "kind": kind,
                "status": status,
                "attempts": attempts,
                "created_at": rfc3339(created_at),
                "finished_at": finished_at.map(rfc3339),
                "progress": {
                    "done": done,
                    "total": total,
                },
            });
            if let Some(error) = &error {
                job_doc["error"] = serde_json::from_str::<Value>(error)?;
            }
            let base = format!("/v1/jobs/{job_id}");
            let mut links = json!({ "job": base, "attempts": format!("{base}/attempts") });
            if status == "succeeded" {
                links["summary"] = json!(format!("{base}/summary"));
                links["blocks"] = json!(format!("{base}/blocks"));
            }
            Ok(json!({
                "id": id,
                "event": event,
                "webhook_id": webhook_id,
                "created_at": rfc3339(now),
                "job": job_doc,
                "links": links,
            })
            .to_string())
        };
        if event == "job.progress" {
            // Progress coalesces: a progress delivery of this webhook and job still queued
            // (not in flight) takes the latest progress in place, keeping its id, attempts
            // and backoff, so a slow receiver's backlog holds one per job, not one a second.
            let waiting: Option<(String,)> = on_tx!(tx, c => sqlx::query_as(
                "SELECT id FROM webhook_deliveries WHERE webhook_id = $1 AND job_id = $2 AND event = 'job.progress'
                   AND status = 'pending' AND (lease_expires_at IS NULL OR lease_expires_at < $3) LIMIT 1",
            )
            .bind(&webhook_id)
            .bind(job_id)
            .bind(now)
            .fetch_optional(&mut *c)
            .await?);
            if let Some((id,)) = waiting {
                let replaced = on_tx!(tx, c => sqlx::query(
                    "UPDATE webhook_deliveries SET body = $1, created_at = $2, updated_at = $2
                     WHERE id = $3 AND status = 'pending' AND (lease_expires_at IS NULL OR lease_expires_at < $2)",
                )
                .bind(body(&id)?)
                .bind(now)
                .bind(&id)
                .execute(&mut *c)
                .await?
                .rows_affected());
                // Claimed in between: a new one queues behind it.
                if replaced > 0 {
                    continue;
                }
            }
        }
        let id = new_id();
        let body = body(&id)?;
        if queued >= MAX_QUEUED_PER_KEY {
            let why = format!(
                "not sent: this API key had {MAX_QUEUED_PER_KEY} deliveries pending (its receivers do not keep up); ask for a redelivery once they do"
            );
            on_tx!(tx, c => sqlx::query(
                "INSERT INTO webhook_deliveries (id, webhook_id, owner, event, job_id, body, status, attempts, attempt_limit, last_error, created_at, updated_at)
                 VALUES ($1, $2, $3, $4, $5, $6, 'failed', 0, $7, $8, $9, $9)",
            )
            .bind(&id)
            .bind(&webhook_id)
            .bind(&owner)
            .bind(event)
            .bind(job_id)
            .bind(body)
            .bind(ATTEMPT_LIMIT)
            .bind(why)
            .bind(now)
            .execute(&mut *c)
            .await?
            .rows_affected());
            continue;
        }
        on_tx!(tx, c => sqlx::query(
            "INSERT INTO webhook_deliveries (id, webhook_id, owner, event, job_id, body, status, attempts, attempt_limit, next_attempt_at, created_at, updated_at)
             VALUES ($1, $2, $3, $4, $5, $6, 'pending', 0, $7, $8, $8, $8)",
        )
        .bind(&id)
        .bind(&webhook_id)
        .bind(&owner)
        .bind(event)
        .bind(job_id)
        .bind(body)
        .bind(ATTEMPT_LIMIT)
        .bind(now)
        .execute(&mut *c)
        .await?
        .rows_affected());
        queued += 1;
    }
    Ok(())
}

/// A `job.progress` delivery for each webhook of the job's owner that wants one, unless
/// the job's last one is younger than `PROGRESS_INTERVAL_MS` or the job has not counted its
/// work yet (called with each heartbeat).
pub async fn enqueue_progress(db: &Db, job_id: &str) -> Result<(), StoreError> {
    let (wanted,): (i64,) = on_pool!(&db.pool, p => sqlx::query_as(
        "SELECT COUNT(*) FROM webhooks w JOIN jobs j ON w.owner = j.owner
         WHERE j.id = $1 AND j.progress_total > 0 AND w.events LIKE '%\"job.progress\"%'",
    )
    .bind(job_id)
    .fetch_one(p)
    .await?);
    if wanted == 0 {
        return Ok(());
    }
    let mut tx = db.begin().await?;
    let (last,): (Option<i64>,) = on_tx!(&mut tx, c => sqlx::query_as(
        "SELECT MAX(created_at) FROM webhook_deliveries WHERE job_id = $1 AND event = 'job.progress'",
    )
    .bind(job_id)
    .fetch_one(&mut *c)
    .await?);
    if last.is_some_and(|t| now_ms() - t < PROGRESS_INTERVAL_MS) {
        return Ok(());
    }
    enqueue_job_event(&mut tx, job_id, "job.progress").await?;
    tx.commit().await?;
    Ok(())
}

/// A delivery row as read, before its attempts are added.
fn delivery_record(row: &impl RowGet) -> Result<DeliveryRecord, StoreError> {
    let status: String = row.col("status")?;
    Ok(DeliveryRecord {
        id: row.col("id")?,
        webhook_id: row.col("webhook_id")?,
        event: row.col("event")?,
        job_id: row.col("job_id")?,
        attempt_count: row.col("attempts")?,
        created_at: rfc3339(row.col("created_at")?),
        delivered_at: row.col::<Option<i64>>("delivered_at")?.map(rfc3339),
        next_attempt_at: if status == "pending" {
            row.col::<Option<i64>>("next_attempt_at")?.map(rfc3339)
        } else {
            None
        },
        last_error: row.col("last_error")?,
        status,
        attempts: Vec::new(),
    })
}

/// A delivery with its attempts, read in the same transaction.
async fn with_attempts(tx: &mut Tx, mut d: DeliveryRecord) -> Result<DeliveryRecord, StoreError> {
    let attempts: Vec<AttemptRow> = on_tx!(tx, c => sqlx::query_as(
        "SELECT attempt, started_at, duration_ms, status_code, error FROM webhook_attempts WHERE delivery_id = $1 ORDER BY attempt",
    )
    .bind(&d.id)
    .fetch_all(&mut *c)
    .await?);
    d.attempts = attempts
        .into_iter()
        .map(
            |(attempt, started, duration_ms, status_code, error)| AttemptRecord {
                attempt,
                started_at: rfc3339(started),
                duration_ms,
                status_code,
                error,
            },
        )
        .collect();
    Ok(d)
}

impl Db {
    /// Webhooks an owner has (each one fans every job event out once more).
    pub async fn count_webhooks(&self, owner: &str) -> Result<i64, StoreError> {
        Ok(on_pool!(&self.pool, p =>
            sqlx::query_scalar("SELECT COUNT(*) FROM webhooks WHERE owner = $1")
                .bind(owner)
                .fetch_one(p)
                .await?))
    }

    pub async fn create_webhook(
        &self,
        owner: &str,
        url: &str,
        events: &[String],
        secret: &str,
    ) -> Result<WebhookRecord, StoreError> {
        let id = new_id();
        let events = serde_json::to_string(events)?;
        on_pool!(&self.pool, p => {
            let row = sqlx::query(
                "INSERT INTO webhooks (id, owner, url, events, secret, created_at) VALUES ($1, $2, $3, $4, $5, $6)
                 RETURNING id, url, events, created_at",
            )
            .bind(&id)
            .bind(owner)
            .bind(url)
            .bind(&events)
            .bind(secret)
            .bind(now_ms())
            .fetch_one(p)
            .await?;
            webhook_record(&row)
        })
    }

    pub async fn get_webhook(
        &self,
        owner: &str,
        id: &str,
    ) -> Result<Option<WebhookRecord>, StoreError> {
        on_pool!(&self.pool, p => {
            let row = sqlx::query(
                "SELECT id, url, events, created_at FROM webhooks WHERE owner = $1 AND id = $2",
            )
            .bind(owner)
            .bind(id)
            .fetch_optional(p)
            .await?;
            row.as_ref().map(webhook_record).transpose()
        })
    }

    pub async fn list_webhooks(
        &self,
        owner: &str,
        cursor: Option<&str>,
        limit: u32,
    ) -> Result<(Vec<WebhookRecord>, Option<String>), StoreError> {
        let items = on_pool!(&self.pool, p => {
            let rows = sqlx::query(
                "SELECT id, url, events, created_at FROM webhooks WHERE owner = $1 AND id > $2 ORDER BY id LIMIT $3",
            )
            .bind(owner)
            .bind(cursor.unwrap_or(""))
            .bind(i64::from(limit) + 1)
            .fetch_all(p)
            .await?;
            rows.iter()
                .map(webhook_record)
                .collect::<Result<Vec<_>, _>>()?
        });
        Ok(super::page(items, limit, |w| &w.id))
    }

    /// Deletes a webhook and its deliveries (pending ones are not sent).
    pub async fn delete_webhook(&self, owner: &str, id: &str) -> Result<bool, StoreError> {
        let done = on_pool!(&self.pool, p => sqlx::query("DELETE FROM webhooks WHERE owner = $1 AND id = $2")
            .bind(owner)
            .bind(id)
            .execute(p)
            .await?
            .rows_affected());
        Ok(done > 0)
    }

    /// One page of a webhook's deliveries, newest last, each with its attempts.
    pub async fn list_deliveries(
        &self,
        owner: &str,
        webhook_id: &str,
        cursor: Option<&str>,
        limit: u32,
    ) -> Result<(Vec<DeliveryRecord>, Option<String>), StoreError> {
        // One snapshot for the deliveries and their attempts: an attempt recorded between
        // two reads would otherwise show beside a delivery still pending.
        let mut tx = self.begin().await?;
        tx.read_one_snapshot().await?;
        let rows = on_tx!(&mut tx, c => {
            let rows = sqlx::query(
                "SELECT * FROM webhook_deliveries WHERE owner = $1 AND webhook_id = $2 AND id > $3 ORDER BY id LIMIT $4",
            )
            .bind(owner)
            .bind(webhook_id)
            .bind(cursor.unwrap_or(""))
            .bind(i64::from(limit) + 1)
            .fetch_all(&mut *c)
            .await?;
            rows.iter()
                .map(delivery_record)
                .collect::<Result<Vec<_>, _>>()?
        });
        let mut items = Vec::with_capacity(rows.len());
        for d in rows.iter().take(limit as usize) {
            items.push(with_attempts(&mut tx, d.clone()).await?);
        }
        tx.commit().await?;
        let next = if rows.len() > limit as usize {
            items.last().map(|d| d.id.clone())
        } else {
            None
        };
        Ok((items, next))
    }

    pub async fn get_delivery(
        &self,
        owner: &str,
        webhook_id: &str,
        id: &str,
    ) -> Result<Option<DeliveryRecord>, StoreError> {
        let mut tx = self.begin().await?;
        tx.read_one_snapshot().await?;
        let found = on_tx!(&mut tx, c => {
            let row = sqlx::query(
                "SELECT * FROM webhook_deliveries WHERE owner = $1 AND webhook_id = $2 AND id = $3",
            )
            .bind(owner)
            .bind(webhook_id)
            .bind(id)
            .fetch_optional(&mut *c)
            .await?;
            row.as_ref().map(delivery_record).transpose()?
        });
        let found = match found {
            Some(d) => Some(with_attempts(&mut tx, d).await?),
            None => None,
        };
        tx.commit().await?;
        Ok(found)
    }

    /// Asks for a delivery to be sent again now, whatever its state; it gets a fresh
    /// allowance of attempts. False when there is no such delivery.
    pub async fn redeliver(
        &self,
        owner: &str,
        webhook_id: &str,
        id: &str,
    ) -> Result<bool, StoreError> {
        let now = now_ms();
        // An attempt in flight (leased) will record its outcome after this: `redeliver`
        // tells it to leave the delivery pending for one more attempt.
        let done = on_pool!(&self.pool, p => sqlx::query(
            "UPDATE webhook_deliveries SET status = 'pending', next_attempt_at = $1, attempt_limit = attempts + $2,
                redeliver = CASE WHEN lease_expires_at >= $1 THEN 1 ELSE 0 END, updated_at = $1
             WHERE owner = $3 AND webhook_id = $4 AND id = $5",
        )
        .bind(now)
        .bind(ATTEMPT_LIMIT)
        .bind(owner)
        .bind(webhook_id)
        .bind(id)
        .execute(p)
        .await?
        .rows_affected());
        Ok(done > 0)
    }

    /// Whether a delivery is due (a read, so idle dispatchers do not take the write lock).
    pub async fn delivery_due(&self) -> Result<bool, StoreError> {
        let now = now_ms();
        let row: Option<(String,)> = on_pool!(&self.pool, p => sqlx::query_as(
            "SELECT id FROM webhook_deliveries WHERE status = 'pending' AND next_attempt_at <= $1
               AND (lease_expires_at IS NULL OR lease_expires_at < $1) LIMIT 1",
        )
        .bind(now)
        .fetch_optional(p)
        .await?);
        Ok(row.is_some())
    }

    /// Claims up to `limit` due deliveries for `dispatcher` with a lease of `lease_ms`
    /// (a dispatcher that dies mid-delivery leaves them to another once it expires). The
    /// attempt counter moves here, so an attempt cut short by a crash still counts. On
    /// PostgreSQL the due rows are locked `FOR UPDATE SKIP LOCKED`: dispatchers on other
    /// hosts take other deliveries.
    ///
    /// Fair between API keys: the keys take turns (each key's oldest due delivery, then
    /// each key's second, ...), and a key has at most `per_key` deliveries in flight over
    /// all dispatchers (its unexpired leases), so receivers that hold every attempt for
    /// the whole timeout stall only their own key's deliveries. Fair between one key's
    /// webhooks too: a webhook has at most `per_webhook` in flight, and within a key the
    /// webhooks take turns, so one dead receiver cannot hold all of its key's slots.
    pub async fn claim_deliveries(
        &self,
        dispatcher: &str,
        lease_ms: i64,
        limit: i64,
        per_key: i64,
        per_webhook: i64,
    ) -> Result<Vec<DueDelivery>, StoreError> {
        let now = now_ms();
        let skip_locked = self.backend().skip_locked();
        type Claimed = (String, String, String, String, i64, i64);
        // The window ranks in a subquery of its own: PostgreSQL locks no rows of a query
        // with window functions, so the lock is taken by the plain select around it.
        let rows: Vec<Claimed> = on_pool!(&self.pool, p => sqlx::query_as(&format!(
            "UPDATE webhook_deliveries SET lease_owner = $1, lease_expires_at = $2, attempts = attempts + 1, updated_at = $3
             WHERE id IN (SELECT id FROM webhook_deliveries WHERE id IN (
                 SELECT id FROM (
                     SELECT id, next_attempt_at, in_flight,
                            ROW_NUMBER() OVER (PARTITION BY owner ORDER BY hook_turn, next_attempt_at, id) AS turn
                     FROM (
                         SELECT d.id, d.owner, d.next_attempt_at, COALESCE(f.n, 0) AS in_flight,
                                ROW_NUMBER() OVER (PARTITION BY d.webhook_id ORDER BY d.next_attempt_at, d.id)
                                  + COALESCE(w.n, 0) AS hook_turn
                         FROM webhook_deliveries d
                         LEFT JOIN (SELECT owner, COUNT(*) AS n FROM webhook_deliveries
                                    WHERE status = 'pending' AND lease_expires_at >= $3 GROUP BY owner) f
                           ON f.owner = d.owner
                         LEFT JOIN (SELECT webhook_id, COUNT(*) AS n FROM webhook_deliveries
                                    WHERE status = 'pending' AND lease_expires_at >= $3 GROUP BY webhook_id) w
                           ON w.webhook_id = d.webhook_id
                         WHERE d.status = 'pending' AND d.next_attempt_at <= $3
                           AND (d.lease_expires_at IS NULL OR d.lease_expires_at < $3)
                     ) by_hook
                     WHERE hook_turn <= $6
                 ) ranked
                 WHERE turn + in_flight <= $5
                 ORDER BY turn, next_attempt_at LIMIT $4
             ){skip_locked})
             RETURNING id, webhook_id, event, body, attempts, attempt_limit",
        ))
        .bind(dispatcher)
        .bind(now + lease_ms)
        .bind(now)
        .bind(limit)
        .bind(per_key)
        .bind(per_webhook)
        .fetch_all(p)
        .await?);
        let mut due = Vec::with_capacity(rows.len());
        for (id, webhook_id, event, body, attempt, attempt_limit) in rows {
            let hook: Option<(String, String)> = on_pool!(&self.pool, p =>
                sqlx::query_as("SELECT url, secret FROM webhooks WHERE id = $1")
                    .bind(&webhook_id)
                    .fetch_optional(p)
                    .await?);
            // Deleted since (its deliveries go with it): nothing to send.
            let Some((url, secret)) = hook else { continue };
            due.push(DueDelivery {
                id,
                url,
                secret,
                event,
                body,
                attempt,
                attempt_limit,
            });
        }
        Ok(due)
    }

    /// Records how an attempt ended and what happens next (delivered, retried at a time,
    /// or given up), only while `dispatcher` holds the delivery's lease.
    pub async fn record_attempt(
        &self,
        delivery: &DueDelivery,
        dispatcher: &str,
        outcome: &AttemptOutcome,
    ) -> Result<bool, StoreError> {
        let now = now_ms();
        let mut tx = self.begin().await?;
        let (status, next, delivered_at) = match (outcome.delivered, outcome.retry_at) {
            (true, _) => ("delivered", None, Some(now)),
            (false, Some(at)) => ("pending", Some(at), None),
            (false, None) => ("failed", None, None),
        };
        let error = outcome.error.clone().or_else(|| {
            outcome
                .status_code
                .filter(|_| !outcome.delivered)
                .map(|c| format!("the receiver answered {c}"))
        });
        // A redelivery asked for during this attempt keeps the delivery pending, due now.
        let done = on_tx!(&mut tx, c => sqlx::query(
            "UPDATE webhook_deliveries SET
                status = CASE WHEN redeliver = 1 THEN 'pending' ELSE $1 END,
                next_attempt_at = CASE WHEN redeliver = 1 THEN $5 ELSE $2 END,
                delivered_at = COALESCE($3, delivered_at), last_error = $4,
                lease_owner = NULL, lease_expires_at = NULL, redeliver = 0, updated_at = $5
             WHERE id = $6 AND lease_owner = $7 AND attempts = $8",
        )
        .bind(status)
        .bind(next)
        .bind(delivered_at)
        .bind(if outcome.delivered {
            None
        } else {
            error.clone()
        })
        .bind(now)
        .bind(&delivery.id)
        .bind(dispatcher)
        .bind(delivery.attempt)
        .execute(&mut *c)
        .await?
        .rows_affected());
        if done == 0 {
            tx.rollback().await?;
            return Ok(false);
        }
        on_tx!(&mut tx, c => sqlx::query(
            "INSERT INTO webhook_attempts (delivery_id, attempt, started_at, duration_ms, status_code, error)
             VALUES ($1, $2, $3, $4, $5, $6)",
        )
        .bind(&delivery.id)
        .bind(delivery.attempt)
        .bind(outcome.started_at)
        .bind(outcome.duration_ms)
        .bind(outcome.status_code.map(i64::from))
        .bind(error)
        .execute(&mut *c)
        .await?
        .rows_affected());
        tx.commit().await?;
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::store::scratch::ScratchPostgres;

    /// Runs `check` on a fresh SQLite database, then on PostgreSQL where the suite has one.
    macro_rules! on_both {
        ($check:ident) => {{
            let dir = tempfile::tempdir().unwrap();
            let sqlite = Db::open(&format!("sqlite://{}", dir.path().join("w.db").display()))
                .await
                .unwrap();
            $check(&sqlite).await;
            if let Some(scratch) = ScratchPostgres::create().await {
                let pg = Db::open(&scratch.url).await.unwrap();
                $check(&pg).await;
                drop(pg);
                scratch.remove().await;
            }
        }};
    }

    /// A running job of `owner` that has counted its work: its id.
    async fn job(db: &Db, owner: &str, done: i64) -> String {
        let id = new_id();
        on_pool!(&db.pool, p => sqlx::query(
            "INSERT INTO jobs (id, owner, kind, status, spec, max_attempts, progress_done, progress_total, created_at, updated_at)
             VALUES ($1, $2, 'interpret', 'running', '{}', 1, $3, 100, 0, 0)",
        )
        .bind(&id)
        .bind(owner)
        .bind(done)
        .execute(p)
        .await
        .unwrap()
        .rows_affected());
        id
    }

    async fn set_done(db: &Db, job: &str, done: i64) {
        on_pool!(&db.pool, p => sqlx::query("UPDATE jobs SET progress_done = $1 WHERE id = $2")
            .bind(done)
            .bind(job)
            .execute(p)
            .await
            .unwrap()
            .rows_affected());
    }

    async fn event(db: &Db, job: &str, event: &str) {
        let mut tx = db.begin().await.unwrap();
        enqueue_job_event(&mut tx, job, event).await.unwrap();
        tx.commit().await.unwrap();
    }

    /// (status, body) of every delivery of `owner`, oldest first.
    async fn rows(db: &Db, owner: &str) -> Vec<(String, Value)> {
        let rows: Vec<(String, String)> = on_pool!(&db.pool, p => sqlx::query_as(
            "SELECT status, body FROM webhook_deliveries WHERE owner = $1 ORDER BY id",
        )
        .bind(owner)
        .fetch_all(p)
        .await
        .unwrap());
        rows.into_iter()
            .map(|(s, b)| (s, serde_json::from_str(&b).unwrap()))
            .collect()
    }

    #[tokio::test]
    async fn keys_take_turns_and_each_has_a_few_deliveries_in_flight_at_most() {
        on_both!(fairness);
    }

    async fn fairness(db: &Db) {
        let events = vec!["job.succeeded".to_string()];
        for _ in 0..50 {
            db.create_webhook("a", "http://a.example/", &events, "s")
                .await
                .unwrap();
        }
        db.create_webhook("b", "http://b.example/", &events, "s")
            .await
            .unwrap();
        event(db, &job(db, "a", 0).await, "job.succeeded").await;
        event(db, &job(db, "b", 0).await, "job.succeeded").await;
        let first = db.claim_deliveries("d1", 30_000, 16, 4, 2).await.unwrap();
        let to = |d: &[DueDelivery], host: &str| d.iter().filter(|d| d.url.contains(host)).count();
        // b's one delivery, queued after a's fifty, is claimed at once; a gets 4.
        assert_eq!((to(&first, "a.example"), to(&first, "b.example")), (4, 1));
        // a's four are in flight (leased, another dispatcher too): no more of a's.
        let second = db.claim_deliveries("d2", 30_000, 16, 4, 2).await.unwrap();
        assert!(second.is_empty(), "{second:?}");
        // One of a's ends: a gets one slot back.
        let outcome = AttemptOutcome {
            started_at: now_ms(),
            duration_ms: 1,
            status_code: Some(200),
            error: None,
            delivered: true,
            retry_at: None,
        };
        let a_one = first.iter().find(|d| d.url.contains("a.example")).unwrap();
        assert!(db.record_attempt(a_one, "d1", &outcome).await.unwrap());
        let third = db.claim_deliveries("d2", 30_000, 16, 4, 2).await.unwrap();
        assert_eq!(to(&third, "a.example"), 1);
    }

    #[tokio::test]
    async fn a_keys_webhooks_take_turns_and_each_has_two_in_flight_at_most() {
        on_both!(fairness_within_a_key);
    }

    async fn fairness_within_a_key(db: &Db) {
        let events = vec!["job.succeeded".to_string()];
        db.create_webhook("a", "http://dead.example/", &events, "s")
            .await
            .unwrap();
        for _ in 0..10 {
            event(db, &job(db, "a", 0).await, "job.succeeded").await;
        }
        db.create_webhook("a", "http://live.example/", &events, "s")
            .await
            .unwrap();
        event(db, &job(db, "a", 0).await, "job.succeeded").await;
        let to = |d: &[DueDelivery], host: &str| d.iter().filter(|d| d.url.contains(host)).count();
        // The dead webhook's eleven are older than the live one's, yet it gets two slots
        // and the live one its delivery at once.
        let first = db.claim_deliveries("d1", 30_000, 16, 4, 2).await.unwrap();
        assert_eq!(
            (to(&first, "dead"), to(&first, "live")),
            (2, 1),
            "{first:?}"
        );
        // The dead webhook's two are in flight (leased): none more of its own.
        let second = db.claim_deliveries("d2", 30_000, 16, 4, 2).await.unwrap();
        assert!(second.is_empty(), "{second:?}");
    }

    #[tokio::test]
    async fn queued_progress_keeps_only_the_latest_per_webhook_and_job() {
        on_both!(coalescing);
    }

    async fn coalescing(db: &Db) {
        let events = vec!["job.progress".to_string()];
        db.create_webhook("a", "http://a.example/", &events, "s")
            .await
            .unwrap();
        let j = job(db, "a", 10).await;
        let other = job(db, "a", 5).await;
        for done in [10, 20, 30] {
            set_done(db, &j, done).await;
            event(db, &j, "job.progress").await;
        }
        event(db, &other, "job.progress").await;
        let got = rows(db, "a").await;
        assert_eq!(got.len(), 2, "{got:?}");
        assert_eq!(got[0].1["job"]["progress"]["done"], 30);
        assert_eq!(got[1].1["job"]["id"], json!(other));
        // In flight, a delivery keeps what it sends; the next progress queues behind it.
        let claimed = db.claim_deliveries("d", 30_000, 16, 4, 2).await.unwrap();
        assert_eq!(claimed.len(), 2);
        set_done(db, &j, 40).await;
        event(db, &j, "job.progress").await;
        set_done(db, &j, 50).await;
        event(db, &j, "job.progress").await;
        let got = rows(db, "a").await;
        assert_eq!(got.len(), 3, "{got:?}");
        assert_eq!(got[0].1["job"]["progress"]["done"], 30);
        assert_eq!(got[2].1["job"]["progress"]["done"], 50);
        // The body names the row it is sent as.
        let ids: Vec<String> = on_pool!(&db.pool, p => sqlx::query_scalar(
            "SELECT id FROM webhook_deliveries ORDER BY id"
        )
        .fetch_all(p)
        .await
        .unwrap());
        assert_eq!(got[2].1["id"], json!(ids[2]));
    }

    #[tokio::test]
    async fn a_key_past_its_queue_cap_gets_further_deliveries_recorded_as_failed() {
        on_both!(queue_cap);
    }

    async fn queue_cap(db: &Db) {
        let events = vec!["job.succeeded".to_string()];
        for _ in 0..100 {
            db.create_webhook("a", "http://a.example/", &events, "s")
                .await
                .unwrap();
        }
        db.create_webhook("b", "http://b.example/", &events, "s")
            .await
            .unwrap();
        let jobs = (MAX_QUEUED_PER_KEY / 100 + 1) as usize;
        for _ in 0..jobs {
            event(db, &job(db, "a", 0).await, "job.succeeded").await;
        }
        event(db, &job(db, "b", 0).await, "job.succeeded").await;
        let count = |rows: &[(String, Value)], status: &str| {
            rows.iter().filter(|(s, _)| s == status).count() as i64
        };
        let a = rows(db, "a").await;
        assert_eq!(count(&a, "pending"), MAX_QUEUED_PER_KEY);
        assert_eq!(count(&a, "failed"), jobs as i64 * 100 - MAX_QUEUED_PER_KEY);
        let (why,): (String,) = on_pool!(&db.pool, p => sqlx::query_as(
            "SELECT last_error FROM webhook_deliveries WHERE status = 'failed' LIMIT 1"
        )
        .fetch_one(p)
        .await
        .unwrap());
        assert!(why.contains("pending"), "{why}");
        // Another key's queue is its own.
        assert_eq!(count(&rows(db, "b").await, "pending"), 1);
    }
}
