-- The per-key queue limit counts an owner's queued jobs at every submission.
CREATE INDEX jobs_by_owner_status ON jobs (owner, status);
