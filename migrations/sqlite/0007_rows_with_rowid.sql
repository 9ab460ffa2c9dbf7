-- Result rows and samples in rowid tables. As WITHOUT ROWID tables their ~1 KB rows were
-- keys of an index b-tree, whose cells hold about 1000 bytes before spilling to overflow
-- pages: a 100k-row result wrote 310 MB of WAL for 97 MB of JSON (4.5 s); in a rowid
-- table with the (job_id, seq) key in an index of its own, 119 MB (2.0 s), measured with
-- Python's sqlite3 on the same 100k rows.
CREATE TABLE job_rows_new (
    job_id TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    seq    INTEGER NOT NULL,
    data   TEXT    NOT NULL,                   -- JSON object, one block
    PRIMARY KEY (job_id, seq)
);
INSERT INTO job_rows_new (job_id, seq, data) SELECT job_id, seq, data FROM job_rows;
DROP TABLE job_rows;
ALTER TABLE job_rows_new RENAME TO job_rows;

CREATE TABLE job_samples_new (
    job_id TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    seq    INTEGER NOT NULL,                   -- the row's seq in job_rows
    data   TEXT    NOT NULL,
    PRIMARY KEY (job_id, seq)
);
INSERT INTO job_samples_new (job_id, seq, data) SELECT job_id, seq, data FROM job_samples;
DROP TABLE job_samples;
ALTER TABLE job_samples_new RENAME TO job_samples;
