-- Content over 1 MiB still in its row (programs and tool libraries uploaded, and programs
-- given inline in a job, before those were stored in chunks) moved into 1 MiB chunks, as
-- they are stored now: every reader then takes a chunk at a time (SQLite reads a whole blob
-- even to take part of it, so a row's 64 MB program cost 64 MB a read).
WITH RECURSIVE parts(id, seq, n) AS (
    SELECT id, 0, (length(content) + 1048575) / 1048576
      FROM resources WHERE chunks = 0 AND length(content) > 1048576
    UNION ALL
    SELECT id, seq + 1, n FROM parts WHERE seq + 1 < n
)
INSERT INTO resource_chunks (resource_id, seq, data)
SELECT p.id, p.seq, substr(r.content, p.seq * 1048576 + 1, 1048576)
  FROM parts p JOIN resources r ON r.id = p.id;

UPDATE resources SET chunks = (length(content) + 1048575) / 1048576, content = X''
 WHERE chunks = 0 AND length(content) > 1048576;
