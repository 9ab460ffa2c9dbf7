-- Per-step force samples of a job's rows (engaged steps only), one JSON array per row,
-- written with the job's success; read by block range for plotting.
CREATE TABLE job_samples (
    job_id TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    seq    INTEGER NOT NULL,                   -- the row's seq in job_rows
    data   TEXT    NOT NULL,
    PRIMARY KEY (job_id, seq)
) WITHOUT ROWID;
