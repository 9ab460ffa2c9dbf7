-- The live workers of every process (and, on PostgreSQL, every host), for /metrics: each
-- process writes its workers' counts here every second and deletes its rows when it
-- stops; a row not renewed for a few seconds is a worker that died.
CREATE TABLE workers (
    id         TEXT    PRIMARY KEY,
    host       TEXT    NOT NULL,
    pid        INTEGER NOT NULL,
    started_at INTEGER NOT NULL,
    -- The database's clock (unix ms), so hosts' clocks need not agree.
    seen_at    INTEGER NOT NULL,
    running    INTEGER NOT NULL,
    claimed    INTEGER NOT NULL,
    succeeded  INTEGER NOT NULL,
    failed     INTEGER NOT NULL,
    cancelled  INTEGER NOT NULL,
    -- Claimed but not finished by this worker: lease lost, given back, or not committed.
    abandoned  INTEGER NOT NULL
);
