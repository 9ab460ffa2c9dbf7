-- Files a job produces (the exported stock STL runs to hundreds of MB at fine cells) are
-- stored as uploads are: in chunks of at most 1 MiB, written and read one at a time, so
-- neither a worker nor the API holds a whole file. `chunks` counts an artifact's chunk
-- rows and `size` its bytes; 0 chunks means the content is in job_artifacts.content.
ALTER TABLE job_artifacts ADD COLUMN chunks INTEGER NOT NULL DEFAULT 0;
ALTER TABLE job_artifacts ADD COLUMN size INTEGER NOT NULL DEFAULT 0;
UPDATE job_artifacts SET size = length(content);

CREATE TABLE job_artifact_chunks (
    job_id TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    name   TEXT    NOT NULL,
    seq    INTEGER NOT NULL,
    data   BLOB    NOT NULL,
    PRIMARY KEY (job_id, name, seq)
);
