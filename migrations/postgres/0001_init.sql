-- The PostgreSQL schema: the same tables as migrations/sqlite/0001..0004, in PostgreSQL's
-- types. Integers are BIGINT (the store reads every integer as i64); ids sort in byte
-- order (COLLATE "C") because they are the cursors, as in SQLite.

CREATE TABLE resources (
    id          TEXT COLLATE "C" PRIMARY KEY,
    owner       TEXT    NOT NULL,
    kind        TEXT    NOT NULL,
    name        TEXT,
    media_type  TEXT    NOT NULL,
    size        BIGINT  NOT NULL,
    summary     TEXT    NOT NULL,
    content     BYTEA   NOT NULL,
    created_at  BIGINT  NOT NULL
);
CREATE INDEX resources_by_owner_kind ON resources (owner, kind, id);

CREATE TABLE jobs (
    id               TEXT COLLATE "C" PRIMARY KEY,
    owner            TEXT    NOT NULL,
    kind             TEXT    NOT NULL,
    status           TEXT    NOT NULL CHECK (status IN ('queued','running','succeeded','failed','cancelled')),
    spec             TEXT    NOT NULL,
    idempotency_key  TEXT,
    request_hash     TEXT,
    progress_done    BIGINT  NOT NULL DEFAULT 0,
    progress_total   BIGINT  NOT NULL DEFAULT 0,
    attempts         BIGINT  NOT NULL DEFAULT 0,
    max_attempts     BIGINT  NOT NULL,
    lease_owner      TEXT,
    lease_expires_at BIGINT,
    cancel_requested BIGINT  NOT NULL DEFAULT 0,
    error            TEXT,
    summary          TEXT,
    created_at       BIGINT  NOT NULL,
    started_at       BIGINT,
    finished_at      BIGINT,
    updated_at       BIGINT  NOT NULL
);
CREATE UNIQUE INDEX jobs_idempotency ON jobs (owner, idempotency_key) WHERE idempotency_key IS NOT NULL;
CREATE INDEX jobs_by_owner ON jobs (owner, id);
CREATE INDEX jobs_by_owner_status ON jobs (owner, status);
-- What a claim reads: the queued jobs oldest first, and running ones by lease expiry.
-- Partial, so finished jobs (most of the table) cost a claim nothing.
CREATE INDEX jobs_queued ON jobs (id) WHERE status = 'queued';
CREATE INDEX jobs_running_lease ON jobs (lease_expires_at) WHERE status = 'running';

CREATE TABLE job_rows (
    job_id TEXT   NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    seq    BIGINT NOT NULL,
    data   TEXT   NOT NULL,
    PRIMARY KEY (job_id, seq)
);

CREATE TABLE job_artifacts (
    job_id     TEXT  NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    name       TEXT  NOT NULL,
    media_type TEXT  NOT NULL,
    file_name  TEXT  NOT NULL,
    content    BYTEA NOT NULL,
    PRIMARY KEY (job_id, name)
);

CREATE TABLE job_attempts (
    job_id      TEXT   NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    attempt     BIGINT NOT NULL,
    worker      TEXT   NOT NULL,
    started_at  BIGINT NOT NULL,
    finished_at BIGINT,
    outcome     TEXT,
    PRIMARY KEY (job_id, attempt)
);

CREATE TABLE job_samples (
    job_id TEXT   NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    seq    BIGINT NOT NULL,
    data   TEXT   NOT NULL,
    PRIMARY KEY (job_id, seq)
);

CREATE TABLE webhooks (
    id         TEXT COLLATE "C" PRIMARY KEY,
    owner      TEXT   NOT NULL,
    url        TEXT   NOT NULL,
    events     TEXT   NOT NULL,
    secret     TEXT   NOT NULL,
    created_at BIGINT NOT NULL
);
CREATE INDEX webhooks_by_owner ON webhooks (owner, id);

CREATE TABLE webhook_deliveries (
    id               TEXT COLLATE "C" PRIMARY KEY,
    webhook_id       TEXT   NOT NULL REFERENCES webhooks (id) ON DELETE CASCADE,
    owner            TEXT   NOT NULL,
    event            TEXT   NOT NULL,
    job_id           TEXT   NOT NULL,
    body             TEXT   NOT NULL,
    status           TEXT   NOT NULL CHECK (status IN ('pending', 'delivered', 'failed')),
    attempts         BIGINT NOT NULL DEFAULT 0,
    attempt_limit    BIGINT NOT NULL,
    next_attempt_at  BIGINT,
    lease_owner      TEXT,
    lease_expires_at BIGINT,
    redeliver        BIGINT NOT NULL DEFAULT 0,
    last_error       TEXT,
    created_at       BIGINT NOT NULL,
    delivered_at     BIGINT,
    updated_at       BIGINT NOT NULL
);
CREATE INDEX webhook_deliveries_due ON webhook_deliveries (status, next_attempt_at);
CREATE INDEX webhook_deliveries_by_webhook ON webhook_deliveries (webhook_id, id);
CREATE INDEX webhook_deliveries_by_job ON webhook_deliveries (job_id, event);

CREATE TABLE webhook_attempts (
    delivery_id TEXT   NOT NULL REFERENCES webhook_deliveries (id) ON DELETE CASCADE,
    attempt     BIGINT NOT NULL,
    started_at  BIGINT NOT NULL,
    duration_ms BIGINT NOT NULL,
    status_code BIGINT,
    error       TEXT,
    PRIMARY KEY (delivery_id, attempt)
);

-- The event bus: every change to a job is announced (delivered at commit, so a listener
-- never reads a change that may still roll back). Workers on any host wake on
-- `millsim_job_queued`; event streams follow `millsim_job_changed` (payload: the job id).
CREATE FUNCTION millsim_job_notify() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    IF TG_OP = 'DELETE' THEN
        PERFORM pg_notify('millsim_job_changed', OLD.id);
        RETURN NULL;
    END IF;
    PERFORM pg_notify('millsim_job_changed', NEW.id);
    IF NEW.status = 'queued' THEN
        PERFORM pg_notify('millsim_job_queued', '');
    END IF;
    RETURN NULL;
END
$$;
CREATE TRIGGER jobs_notify AFTER INSERT OR UPDATE OR DELETE ON jobs
    FOR EACH ROW EXECUTE FUNCTION millsim_job_notify();
