-- Content over 1 MiB still in its row (programs and tool libraries uploaded, and programs
-- given inline in a job, before those were stored in chunks) moved into 1 MiB chunks, as
-- they are stored now: every reader then takes a chunk at a time.
INSERT INTO resource_chunks (resource_id, seq, data)
SELECT r.id, s.seq, substr(r.content, s.seq * 1048576 + 1, 1048576)
  FROM resources r, generate_series(0, (length(r.content) - 1) / 1048576) AS s(seq)
 WHERE r.chunks = 0 AND length(r.content) > 1048576;

UPDATE resources SET chunks = (length(content) + 1048575) / 1048576, content = ''::bytea
 WHERE chunks = 0 AND length(content) > 1048576;
