-- Webhook subscriptions, per API key. The secret signs deliveries (HMAC-SHA256), so it is
-- kept as given, not hashed; it is shown to the client once, when the webhook is created.
CREATE TABLE webhooks (
    id         TEXT    PRIMARY KEY,            -- UUIDv7, also the list cursor
    owner      TEXT    NOT NULL,               -- API key name ('' when auth is off)
    url        TEXT    NOT NULL,
    events     TEXT    NOT NULL,               -- JSON array: job.succeeded | job.failed | job.cancelled
    secret     TEXT    NOT NULL,
    created_at INTEGER NOT NULL                -- unix ms
);
CREATE INDEX webhooks_by_owner ON webhooks (owner, id);

-- The outbox: one row per (webhook, event), written in the same transaction as the job's
-- state change, so a crash or restart loses none. A dispatcher claims due rows with a
-- lease, posts them, and records every attempt.
CREATE TABLE webhook_deliveries (
    id               TEXT    PRIMARY KEY,      -- UUIDv7
    webhook_id       TEXT    NOT NULL REFERENCES webhooks (id) ON DELETE CASCADE,
    owner            TEXT    NOT NULL,
    event            TEXT    NOT NULL,
    job_id           TEXT    NOT NULL,         -- no foreign key: a delivery outlives a deleted job
    body             TEXT    NOT NULL,         -- the JSON body, the same bytes at every attempt
    status           TEXT    NOT NULL CHECK (status IN ('pending', 'delivered', 'failed')),
    attempts         INTEGER NOT NULL DEFAULT 0,
    attempt_limit    INTEGER NOT NULL,         -- raised by a redelivery request
    next_attempt_at  INTEGER,                  -- unix ms, while pending
    lease_owner      TEXT,
    lease_expires_at INTEGER,
    redeliver        INTEGER NOT NULL DEFAULT 0, -- asked again while an attempt was in flight
    last_error       TEXT,
    created_at       INTEGER NOT NULL,
    delivered_at     INTEGER,
    updated_at       INTEGER NOT NULL
);
CREATE INDEX webhook_deliveries_due ON webhook_deliveries (status, next_attempt_at);
CREATE INDEX webhook_deliveries_by_webhook ON webhook_deliveries (webhook_id, id);

-- Every attempt at a delivery: when, how long, the receiver's status or the error.
CREATE TABLE webhook_attempts (
    delivery_id TEXT    NOT NULL REFERENCES webhook_deliveries (id) ON DELETE CASCADE,
    attempt     INTEGER NOT NULL,
    started_at  INTEGER NOT NULL,
    duration_ms INTEGER NOT NULL,
    status_code INTEGER,                       -- HTTP status; NULL when there was no answer
    error       TEXT,
    PRIMARY KEY (delivery_id, attempt)
);
