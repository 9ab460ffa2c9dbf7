-- Failed tries at starting a job's process, counted with the job so that every server and
-- worker sharing the database counts the same tries (a job is failed after 3).
ALTER TABLE jobs ADD COLUMN start_failures INTEGER NOT NULL DEFAULT 0;
