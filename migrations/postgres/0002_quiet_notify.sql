-- Notifications only where someone waits for them. A NOTIFY takes a database-wide lock
-- at commit and holds it until the commit is on disk, so every transaction that notifies
-- commits one after the other: with a notification on every claim and every result, the
-- workers' commits could not share a WAL flush and the queue topped out near one commit
-- per fsync. Now:
-- * `millsim_job_queued` is sent when a job becomes queued (submitted, or given back):
--   idle workers on any host wait for it;
-- * `millsim_job_changed` (payload: the job id) is sent only for jobs an event stream
--   follows: each stream registers its job in `job_watchers`, then waits for the
--   transactions already writing the job (a row lock) before its first read, so a change
--   either is in that read or commits after the registration and notifies (store/notify.rs).

CREATE TABLE job_watchers (
    job_id     TEXT COLLATE "C" NOT NULL,
    -- One row per stream (a process may follow one job from several streams).
    watcher    TEXT   NOT NULL,
    -- A stream renews it while it lives; rows of processes that died are deleted once
    -- expired (until then they cost a notification nobody reads, nothing more).
    expires_at BIGINT NOT NULL,
    PRIMARY KEY (job_id, watcher)
);
CREATE INDEX job_watchers_expiry ON job_watchers (expires_at);

DROP TRIGGER jobs_notify ON jobs;

CREATE OR REPLACE FUNCTION millsim_job_notify() RETURNS trigger LANGUAGE plpgsql AS $$
DECLARE
    job TEXT;
BEGIN
    IF TG_OP = 'DELETE' THEN
        job := OLD.id;
    ELSE
        job := NEW.id;
        IF NEW.status = 'queued' AND (TG_OP = 'INSERT' OR OLD.status <> 'queued') THEN
            PERFORM pg_notify('millsim_job_queued', '');
        END IF;
    END IF;
    IF EXISTS (SELECT 1 FROM job_watchers WHERE job_id = job) THEN
        PERFORM pg_notify('millsim_job_changed', job);
    END IF;
    RETURN NULL;
END
$$;

CREATE TRIGGER jobs_notify AFTER INSERT OR UPDATE OR DELETE ON jobs
    FOR EACH ROW EXECUTE FUNCTION millsim_job_notify();
