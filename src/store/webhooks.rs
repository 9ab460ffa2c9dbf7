//! Webhook subscriptions and their durable outbox: deliveries are written in the same
//! transaction as the job's state change ([`enqueue_job_event`]), claimed by a dispatcher
//! with a lease, and every attempt is recorded. Plain SQL that PostgreSQL also reads.

use serde::Serialize;
use serde_json::{json, Value};
use sqlx::Row;

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

fn webhook_record(row: &sqlx::sqlite::SqliteRow) -> Result<WebhookRecord, StoreError> {
    Ok(WebhookRecord {
        id: row.try_get("id")?,
        url: row.try_get("url")?,
        events: serde_json::from_str(&row.try_get::<String, _>("events")?)?,
        created_at: rfc3339(row.try_get("created_at")?),
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
pub async fn enqueue_job_event(
    tx: &mut sqlx::Transaction<'_, sqlx::Sqlite>,
    job_id: &str,
    event: &str,
) -> Result<(), StoreError> {
    let Some(job) = sqlx::query(
        "SELECT id, owner, kind, status, attempts, error, created_at, finished_at, progress_done, progress_total FROM jobs WHERE id = ?",
    )
    .bind(job_id)
    .fetch_optional(&mut **tx)
    .await?
    else {
        return Ok(());
    };
    let owner: String = job.try_get("owner")?;
    let hooks: Vec<(String, String)> =
        sqlx::query_as("SELECT id, events FROM webhooks WHERE owner = ? ORDER BY id")
            .bind(&owner)
            .fetch_all(&mut **tx)
            .await?;
    let now = now_ms();
    for (webhook_id, events) in hooks {
        let events: Vec<String> = serde_json::from_str(&events)?;
        if !events.iter().any(|e| e == event) {
            continue;
        }
        let id = new_id();
        let status: String = job.try_get("status")?;
        let mut job_doc = json!({
            "id": job_id,
            "kind": job.try_get::<String, _>("kind")?,
            "status": status,
            "attempts": job.try_get::<i64, _>("attempts")?,
            "created_at": rfc3339(job.try_get("created_at")?),
            "finished_at": job.try_get::<Option<i64>, _>("finished_at")?.map(rfc3339),
            "progress": {
                "done": job.try_get::<i64, _>("progress_done")?,
                "total": job.try_get::<i64, _>("progress_total")?,
            },
        });
        if let Some(error) = job.try_get::<Option<String>, _>("error")? {
            job_doc["error"] = serde_json::from_str::<Value>(&error)?;
        }
        let base = format!("/v1/jobs/{job_id}");
        let mut links = json!({ "job": base, "attempts": format!("{base}/attempts") });
        if status == "succeeded" {
            links["summary"] = json!(format!("{base}/summary"));
            links["blocks"] = json!(format!("{base}/blocks"));
        }
        let body = json!({
            "id": id,
            "event": event,
            "webhook_id": webhook_id,
            "created_at": rfc3339(now),
            "job": job_doc,
            "links": links,
        });
        sqlx::query(
            "INSERT INTO webhook_deliveries (id, webhook_id, owner, event, job_id, body, status, attempts, attempt_limit, next_attempt_at, created_at, updated_at)
             VALUES (?, ?, ?, ?, ?, ?, 'pending', 0, ?, ?, ?, ?)",
        )
        .bind(&id)
        .bind(&webhook_id)
        .bind(&owner)
        .bind(event)
        .bind(job_id)
        .bind(body.to_string())
        .bind(ATTEMPT_LIMIT)
        .bind(now)
        .bind(now)
        .bind(now)
        .execute(&mut **tx)
        .await?;
    }
    Ok(())
}

/// A `job.progress` delivery for each webhook of the job's owner that wants one, unless
/// the job's last one is younger than `PROGRESS_INTERVAL_MS` or the job has not counted its
/// work yet (called with each heartbeat).
pub async fn enqueue_progress(db: &Db, job_id: &str) -> Result<(), StoreError> {
    let (wanted,): (i64,) = sqlx::query_as(
        "SELECT COUNT(*) FROM webhooks w JOIN jobs j ON w.owner = j.owner
         WHERE j.id = ? AND j.progress_total > 0 AND w.events LIKE '%\"job.progress\"%'",
    )
    .bind(job_id)
    .fetch_one(&db.pool)
    .await?;
    if wanted == 0 {
        return Ok(());
    }
    let mut tx = db.pool.begin().await?;
    let (last,): (Option<i64>,) = sqlx::query_as(
        "SELECT MAX(created_at) FROM webhook_deliveries WHERE job_id = ? AND event = 'job.progress'",
    )
    .bind(job_id)
    .fetch_one(&mut *tx)
    .await?;
    if last.is_some_and(|t| now_ms() - t < PROGRESS_INTERVAL_MS) {
        return Ok(());
    }
    enqueue_job_event(&mut tx, job_id, "job.progress").await?;
    tx.commit().await?;
    Ok(())
}

impl Db {
    /// Webhooks an owner has (each one fans every job event out once more).
    pub async fn count_webhooks(&self, owner: &str) -> Result<i64, StoreError> {
        Ok(
            sqlx::query_scalar("SELECT COUNT(*) FROM webhooks WHERE owner = ?")
                .bind(owner)
                .fetch_one(&self.pool)
                .await?,
        )
    }

    pub async fn create_webhook(
        &self,
        owner: &str,
        url: &str,
        events: &[String],
        secret: &str,
    ) -> Result<WebhookRecord, StoreError> {
        let id = new_id();
        let row = sqlx::query(
            "INSERT INTO webhooks (id, owner, url, events, secret, created_at) VALUES (?, ?, ?, ?, ?, ?)
             RETURNING id, url, events, created_at",
        )
        .bind(&id)
        .bind(owner)
        .bind(url)
        .bind(serde_json::to_string(events)?)
        .bind(secret)
        .bind(now_ms())
        .fetch_one(&self.pool)
        .await?;
        webhook_record(&row)
    }

    pub async fn get_webhook(
        &self,
        owner: &str,
        id: &str,
    ) -> Result<Option<WebhookRecord>, StoreError> {
        let row = sqlx::query(
            "SELECT id, url, events, created_at FROM webhooks WHERE owner = ? AND id = ?",
        )
        .bind(owner)
        .bind(id)
        .fetch_optional(&self.pool)
        .await?;
        row.as_ref().map(webhook_record).transpose()
    }

    pub async fn list_webhooks(
        &self,
        owner: &str,
        cursor: Option<&str>,
        limit: u32,
    ) -> Result<(Vec<WebhookRecord>, Option<String>), StoreError> {
        let rows = sqlx::query(
            "SELECT id, url, events, created_at FROM webhooks WHERE owner = ? AND id > ? ORDER BY id LIMIT ?",
        )
        .bind(owner)
        .bind(cursor.unwrap_or(""))
        .bind(i64::from(limit) + 1)
        .fetch_all(&self.pool)
        .await?;
        let mut items = rows
            .iter()
            .map(webhook_record)
            .collect::<Result<Vec<_>, _>>()?;
        let next = if items.len() > limit as usize {
            items.truncate(limit as usize);
            items.last().map(|w| w.id.clone())
        } else {
            None
        };
        Ok((items, next))
    }

    /// Deletes a webhook and its deliveries (pending ones are not sent).
    pub async fn delete_webhook(&self, owner: &str, id: &str) -> Result<bool, StoreError> {
        let done = sqlx::query("DELETE FROM webhooks WHERE owner = ? AND id = ?")
            .bind(owner)
            .bind(id)
            .execute(&self.pool)
            .await?;
        Ok(done.rows_affected() > 0)
    }

    /// One page of a webhook's deliveries, newest last, each with its attempts.
    pub async fn list_deliveries(
        &self,
        owner: &str,
        webhook_id: &str,
        cursor: Option<&str>,
        limit: u32,
    ) -> Result<(Vec<DeliveryRecord>, Option<String>), StoreError> {
        let rows = sqlx::query(
            "SELECT * FROM webhook_deliveries WHERE owner = ? AND webhook_id = ? AND id > ? ORDER BY id LIMIT ?",
        )
        .bind(owner)
        .bind(webhook_id)
        .bind(cursor.unwrap_or(""))
        .bind(i64::from(limit) + 1)
        .fetch_all(&self.pool)
        .await?;
        let mut items = Vec::with_capacity(rows.len());
        for row in rows.iter().take(limit as usize) {
            items.push(self.delivery_record(row).await?);
        }
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
        let row = sqlx::query(
            "SELECT * FROM webhook_deliveries WHERE owner = ? AND webhook_id = ? AND id = ?",
        )
        .bind(owner)
        .bind(webhook_id)
        .bind(id)
        .fetch_optional(&self.pool)
        .await?;
        match row {
            Some(r) => Ok(Some(self.delivery_record(&r).await?)),
            None => Ok(None),
        }
    }

    async fn delivery_record(
        &self,
        row: &sqlx::sqlite::SqliteRow,
    ) -> Result<DeliveryRecord, StoreError> {
        let id: String = row.try_get("id")?;
        let attempts: Vec<AttemptRow> = sqlx::query_as(
            "SELECT attempt, started_at, duration_ms, status_code, error FROM webhook_attempts WHERE delivery_id = ? ORDER BY attempt",
        )
        .bind(&id)
        .fetch_all(&self.pool)
        .await?;
        let status: String = row.try_get("status")?;
        Ok(DeliveryRecord {
            webhook_id: row.try_get("webhook_id")?,
            event: row.try_get("event")?,
            job_id: row.try_get("job_id")?,
            attempt_count: row.try_get("attempts")?,
            created_at: rfc3339(row.try_get("created_at")?),
            delivered_at: row.try_get::<Option<i64>, _>("delivered_at")?.map(rfc3339),
            next_attempt_at: if status == "pending" {
                row.try_get::<Option<i64>, _>("next_attempt_at")?
                    .map(rfc3339)
            } else {
                None
            },
            last_error: row.try_get("last_error")?,
            status,
            attempts: attempts
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
                .collect(),
            id,
        })
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
        let done = sqlx::query(
            "UPDATE webhook_deliveries SET status = 'pending', next_attempt_at = ?1, attempt_limit = attempts + ?2,
                redeliver = CASE WHEN lease_expires_at >= ?1 THEN 1 ELSE 0 END, updated_at = ?1
             WHERE owner = ?3 AND webhook_id = ?4 AND id = ?5",
        )
        .bind(now)
        .bind(ATTEMPT_LIMIT)
        .bind(owner)
        .bind(webhook_id)
        .bind(id)
        .execute(&self.pool)
        .await?;
        Ok(done.rows_affected() > 0)
    }

    /// Whether a delivery is due (a read, so idle dispatchers do not take the write lock).
    pub async fn delivery_due(&self) -> Result<bool, StoreError> {
        let now = now_ms();
        let row: Option<(String,)> = sqlx::query_as(
            "SELECT id FROM webhook_deliveries WHERE status = 'pending' AND next_attempt_at <= ?
               AND (lease_expires_at IS NULL OR lease_expires_at < ?) LIMIT 1",
        )
        .bind(now)
        .bind(now)
        .fetch_optional(&self.pool)
        .await?;
        Ok(row.is_some())
    }

    /// Claims up to `limit` due deliveries for `dispatcher` with a lease of `lease_ms`
    /// (a dispatcher that dies mid-delivery leaves them to another once it expires). The
    /// attempt counter moves here, so an attempt cut short by a crash still counts.
    pub async fn claim_deliveries(
        &self,
        dispatcher: &str,
        lease_ms: i64,
        limit: i64,
    ) -> Result<Vec<DueDelivery>, StoreError> {
        let now = now_ms();
        let rows = sqlx::query(
            "UPDATE webhook_deliveries SET lease_owner = ?, lease_expires_at = ?, attempts = attempts + 1, updated_at = ?
             WHERE id IN (SELECT id FROM webhook_deliveries
                          WHERE status = 'pending' AND next_attempt_at <= ?
                            AND (lease_expires_at IS NULL OR lease_expires_at < ?)
                          ORDER BY next_attempt_at LIMIT ?)
             RETURNING id, webhook_id, event, body, attempts, attempt_limit",
        )
        .bind(dispatcher)
        .bind(now + lease_ms)
        .bind(now)
        .bind(now)
        .bind(now)
        .bind(limit)
        .fetch_all(&self.pool)
        .await?;
        let mut due = Vec::with_capacity(rows.len());
        for r in rows {
            let webhook_id: String = r.try_get("webhook_id")?;
            let hook: Option<(String, String)> =
                sqlx::query_as("SELECT url, secret FROM webhooks WHERE id = ?")
                    .bind(&webhook_id)
                    .fetch_optional(&self.pool)
                    .await?;
            // Deleted since (its deliveries go with it): nothing to send.
            let Some((url, secret)) = hook else { continue };
            due.push(DueDelivery {
                id: r.try_get("id")?,
                url,
                secret,
                event: r.try_get("event")?,
                body: r.try_get("body")?,
                attempt: r.try_get("attempts")?,
                attempt_limit: r.try_get("attempt_limit")?,
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
        let mut tx = self.pool.begin().await?;
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
        let done = sqlx::query(
            "UPDATE webhook_deliveries SET
                status = CASE WHEN redeliver = 1 THEN 'pending' ELSE ?1 END,
                next_attempt_at = CASE WHEN redeliver = 1 THEN ?5 ELSE ?2 END,
                delivered_at = COALESCE(?3, delivered_at), last_error = ?4,
                lease_owner = NULL, lease_expires_at = NULL, redeliver = 0, updated_at = ?5
             WHERE id = ?6 AND lease_owner = ?7 AND attempts = ?8",
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
        .execute(&mut *tx)
        .await?;
        if done.rows_affected() == 0 {
            tx.rollback().await?;
            return Ok(false);
        }
        sqlx::query(
            "INSERT INTO webhook_attempts (delivery_id, attempt, started_at, duration_ms, status_code, error)
             VALUES (?, ?, ?, ?, ?, ?)",
        )
        .bind(&delivery.id)
        .bind(delivery.attempt)
        .bind(outcome.started_at)
        .bind(outcome.duration_ms)
        .bind(outcome.status_code.map(i64::from))
        .bind(error)
        .execute(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(true)
    }
}
