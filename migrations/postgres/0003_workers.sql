-- The live workers of every process on every host, for /metrics: each
-- process writes its workers' counts here every second and deletes its rows when it
-- stops; a row not renewed for a few seconds is a worker that died.
CREATE TABLE workers (
    id         TEXT COLLATE "C" PRIMARY KEY,
    host       TEXT    NOT NULL,
    pid        BIGINT  NOT NULL,
    started_at BIGINT  NOT NULL,
    -- The database's clock (unix ms), so hosts' clocks need not agree.
    seen_at    BIGINT  NOT NULL,
    running    BIGINT  NOT NULL,
    claimed    BIGINT  NOT NULL,
    succeeded  BIGINT  NOT NULL,
    failed     BIGINT  NOT NULL,
    cancelled  BIGINT  NOT NULL,
    -- Claimed but not finished by this worker: lease lost, given back, or not committed.
    abandoned  BIGINT  NOT NULL
);
