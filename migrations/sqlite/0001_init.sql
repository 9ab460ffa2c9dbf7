-- Inputs, stored unchanged. One table for the five resource kinds: they share
-- everything but their validation, which happens before the insert.
CREATE TABLE resources (
    id          TEXT    PRIMARY KEY,           -- UUIDv7: time-ordered, so it is also the cursor
    owner       TEXT    NOT NULL,              -- API key name ('' when auth is off)
    kind        TEXT    NOT NULL,              -- stock | tool | material | machine | program
    name        TEXT,                          -- original file name or given name
    media_type  TEXT    NOT NULL,
    size        INTEGER NOT NULL,
    summary     TEXT    NOT NULL,              -- JSON: what validation found (blocks, triangles, ...)
    content     BLOB    NOT NULL,
    created_at  INTEGER NOT NULL               -- unix ms
);
CREATE INDEX resources_by_owner_kind ON resources (owner, kind, id);

CREATE TABLE jobs (
    id               TEXT    PRIMARY KEY,
    owner            TEXT    NOT NULL,
    kind             TEXT    NOT NULL,
    status           TEXT    NOT NULL CHECK (status IN ('queued','running','succeeded','failed','cancelled')),
    spec             TEXT    NOT NULL,         -- JSON: inputs (ids) and options
    idempotency_key  TEXT,
    request_hash     TEXT,
    progress_done    INTEGER NOT NULL DEFAULT 0,
    progress_total   INTEGER NOT NULL DEFAULT 0,
    attempts         INTEGER NOT NULL DEFAULT 0,
    max_attempts     INTEGER NOT NULL,
    lease_owner      TEXT,
    lease_expires_at INTEGER,
    cancel_requested INTEGER NOT NULL DEFAULT 0,
    error            TEXT,                     -- JSON problem document when failed
    summary          TEXT,                     -- JSON result summary when succeeded
    created_at       INTEGER NOT NULL,
    started_at       INTEGER,
    finished_at      INTEGER,
    updated_at       INTEGER NOT NULL
);
CREATE UNIQUE INDEX jobs_idempotency ON jobs (owner, idempotency_key) WHERE idempotency_key IS NOT NULL;
CREATE INDEX jobs_claimable ON jobs (status, lease_expires_at, id);
CREATE INDEX jobs_by_owner ON jobs (owner, id);

-- Per-block result rows, written in the same transaction as the job's success.
CREATE TABLE job_rows (
    job_id TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    seq    INTEGER NOT NULL,
    data   TEXT    NOT NULL,                   -- JSON object, one block
    PRIMARY KEY (job_id, seq)
) WITHOUT ROWID;

-- Result files (optimized program, final stock, lobes).
CREATE TABLE job_artifacts (
    job_id     TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    name       TEXT NOT NULL,
    media_type TEXT NOT NULL,
    file_name  TEXT NOT NULL,
    content    BLOB NOT NULL,
    PRIMARY KEY (job_id, name)
);

-- Every attempt at a job: who ran it, when, how it ended. Operators read it to see
-- re-runs after a crash; tests read it to prove a job never completed twice.
CREATE TABLE job_attempts (
    job_id      TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    attempt     INTEGER NOT NULL,
    worker      TEXT    NOT NULL,
    started_at  INTEGER NOT NULL,
    finished_at INTEGER,
    outcome     TEXT,                          -- succeeded | failed | cancelled | lost (NULL while running)
    PRIMARY KEY (job_id, attempt)
);
