-- Result rows and samples stored as groups: consecutive rows framed together and
-- compressed with zstd (src/store/row_groups.rs), one table row per ~512 KiB of JSON, so a
-- 100k-block result writes ~190 rows and a seventh of the bytes. Groups never overlap, so
-- (job_id, last_seq) orders them and finds the group holding a seq with one range scan.
CREATE TABLE job_row_groups (
    job_id    TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    last_seq  INTEGER NOT NULL,
    first_seq INTEGER NOT NULL,
    codec     TEXT    NOT NULL,   -- 'zstd': framed rows, compressed; 'row': one row's JSON as is
    raw_bytes INTEGER NOT NULL,   -- length of the decompressed bytes
    data      BLOB    NOT NULL,
    PRIMARY KEY (job_id, last_seq)
);

CREATE TABLE job_sample_groups (
    job_id    TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    last_seq  INTEGER NOT NULL,   -- seqs are those of the rows the samples belong to
    first_seq INTEGER NOT NULL,
    codec     TEXT    NOT NULL,
    raw_bytes INTEGER NOT NULL,
    data      BLOB    NOT NULL,
    PRIMARY KEY (job_id, last_seq)
);

-- Rows written one by one before become groups of one, their JSON as it was.
INSERT INTO job_row_groups (job_id, last_seq, first_seq, codec, raw_bytes, data)
    SELECT job_id, seq, seq, 'row', length(CAST(data AS BLOB)), CAST(data AS BLOB) FROM job_rows;
DROP TABLE job_rows;
INSERT INTO job_sample_groups (job_id, last_seq, first_seq, codec, raw_bytes, data)
    SELECT job_id, seq, seq, 'row', length(CAST(data AS BLOB)), CAST(data AS BLOB) FROM job_samples;
DROP TABLE job_samples;
