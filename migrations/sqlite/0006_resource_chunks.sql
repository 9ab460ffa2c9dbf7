-- Large uploads (STL stocks and parts) are stored in chunks of at most 1 MiB, written
-- and read one at a time, so no process holds a whole file. `chunks` counts a
-- resource's chunk rows; 0 means the content is in resources.content.
ALTER TABLE resources ADD COLUMN chunks INTEGER NOT NULL DEFAULT 0;

CREATE TABLE resource_chunks (
    resource_id TEXT    NOT NULL REFERENCES resources (id) ON DELETE CASCADE,
    seq         INTEGER NOT NULL,
    data        BLOB    NOT NULL,
    PRIMARY KEY (resource_id, seq)
);
