-- Large uploads (STL stocks and parts) are stored in chunks of at most 1 MiB, written
-- and read one at a time, so no process holds a whole file. `chunks` counts a
-- resource's chunk rows; 0 means the content is in resources.content.
ALTER TABLE resources ADD COLUMN chunks BIGINT NOT NULL DEFAULT 0;

CREATE TABLE resource_chunks (
    resource_id TEXT COLLATE "C" NOT NULL REFERENCES resources (id) ON DELETE CASCADE,
    seq         BIGINT NOT NULL,
    data        BYTEA  NOT NULL,
    PRIMARY KEY (resource_id, seq)
);
-- Chunks are compressed STL floats at best a little: skip the TOAST compression attempt.
ALTER TABLE resource_chunks ALTER COLUMN data SET STORAGE EXTERNAL;
