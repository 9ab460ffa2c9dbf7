//! Jobs and the durable queue: every state change is one SQL statement or one
//! transaction, so a worker that dies at any point leaves a job that is either
//! finished or claimable again once its lease expires.

use std::sync::atomic::Ordering;

use serde::Serialize;

use super::artifacts::{insert_artifact, Artifact};
use super::backend::{on_pool, on_tx, RowGet, Tx};
use super::bulk::{insert_groups, read_rows};
use super::resources::{insert as insert_resource, insert_with_id, NewResource};
use super::row_groups::{pack, Group};
use super::webhooks::enqueue_job_event;
use super::{new_id, now_ms, rfc3339, Db, StoreError};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum JobStatus {
    Queued,
    Running,
    Succeeded,
    Failed,
    Cancelled,
}

impl JobStatus {
    pub const ALL: [JobStatus; 5] = [
        JobStatus::Queued,
        JobStatus::Running,
        JobStatus::Succeeded,
        JobStatus::Failed,
        JobStatus::Cancelled,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            JobStatus::Queued => "queued",
            JobStatus::Running => "running",
            JobStatus::Succeeded => "succeeded",
            JobStatus::Failed => "failed",
            JobStatus::Cancelled => "cancelled",
        }
    }

    pub fn parse(s: &str) -> Option<JobStatus> {
        JobStatus::ALL.into_iter().find(|v| v.as_str() == s)
    }

    pub fn is_terminal(self) -> bool {
        matches!(
            self,
            JobStatus::Succeeded | JobStatus::Failed | JobStatus::Cancelled
        )
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct Progress {
    pub done: i64,
    pub total: i64,
}

#[derive(Clone, Debug, Serialize)]
pub struct JobRecord {
    pub id: String,
    pub kind: String,
    pub status: JobStatus,
    pub inputs: serde_json::Value,
    pub options: serde_json::Value,
    pub progress: Progress,
    pub attempts: i64,
    pub max_attempts: i64,
    pub cancel_requested: bool,
    pub created_at: String,
    pub started_at: Option<String>,
    pub finished_at: Option<String>,
    /// Seconds from start to finish of the attempt that finished it.
    pub duration_seconds: Option<f64>,
    pub error: Option<serde_json::Value>,
    pub summary: Option<serde_json::Value>,
}

fn job_record(row: &impl RowGet) -> Result<JobRecord, StoreError> {
    let spec: serde_json::Value = serde_json::from_str(&row.col::<String>("spec")?)?;
    let status: String = row.col("status")?;
    let started: Option<i64> = row.col("started_at")?;
    let finished: Option<i64> = row.col("finished_at")?;
    let json_col = |name: &str| -> Result<Option<serde_json::Value>, StoreError> {
        Ok(match row.col::<Option<String>>(name)? {
            Some(s) => Some(serde_json::from_str(&s)?),
            None => None,
        })
    };
    Ok(JobRecord {
        id: row.col("id")?,
        kind: row.col("kind")?,
        status: JobStatus::parse(&status).unwrap_or(JobStatus::Failed),
        inputs: spec
            .get("inputs")
            .cloned()
            .unwrap_or(serde_json::Value::Null),
        options: spec
            .get("options")
            .cloned()
            .unwrap_or(serde_json::Value::Null),
        progress: Progress {
            done: row.col("progress_done")?,
            total: row.col("progress_total")?,
        },
        attempts: row.col("attempts")?,
        max_attempts: row.col("max_attempts")?,
        cancel_requested: row.col::<i64>("cancel_requested")? != 0,
        created_at: rfc3339(row.col("created_at")?),
        started_at: started.map(rfc3339),
        finished_at: finished.map(rfc3339),
        duration_seconds: match (started, finished) {
            (Some(s), Some(f)) => Some((f - s) as f64 / 1000.0),
            _ => None,
        },
        error: json_col("error")?,
        summary: json_col("summary")?,
    })
}

/// An inline input carried by a job submission, stored as a resource with the job.
pub struct InlineInput {
    /// Key under `inputs` that will name the new resource's id.
    pub input: String,
    pub kind: super::ResourceKind,
    pub name: Option<String>,
    pub media_type: &'static str,
    pub summary: serde_json::Value,
    pub content: Vec<u8>,
}

pub struct NewJob {
    pub kind: String,
    /// Inputs by id; inline inputs are added under their key once stored.
    pub inputs: serde_json::Map<String, serde_json::Value>,
    pub inline: Vec<InlineInput>,
    pub options: serde_json::Value,
    pub idempotency_key: Option<String>,
    pub request_hash: String,
    pub max_attempts: i64,
    /// Queued jobs this owner may have; a submission over it is refused.
    pub max_queued: i64,
}

pub enum CreateOutcome {
    Created(JobRecord),
    /// Same idempotency key and same body: the job created the first time.
    Replayed(JobRecord),
    /// Same idempotency key, another body.
    KeyConflict(JobRecord),
    /// The owner already has `max_queued` queued jobs; nothing was stored.
    QueueFull,
}

/// A job as a worker sees it after claiming it.
#[derive(Clone, Debug)]
pub struct ClaimedJob {
    pub id: String,
    pub owner: String,
    pub kind: String,
    pub spec: serde_json::Value,
    pub attempt: i64,
}

/// How a worker's attempt ended, written with the state change.
pub enum Finish {
    Succeeded {
        summary: serde_json::Value,
        rows: Vec<String>,
        samples: Vec<(usize, String)>,
        artifacts: Vec<Artifact>,
        /// Resources the job made, owned by the job's owner.
        resources: Vec<CreatedResource>,
        progress: (u64, u64),
    },
    Failed {
        error: serde_json::Value,
    },
    Cancelled,
}

/// A resource a job made, stored with its success under the id the job chose.
pub struct CreatedResource {
    pub id: String,
    pub kind: super::ResourceKind,
    pub name: String,
    pub media_type: String,
    pub summary: serde_json::Value,
    pub content: Vec<u8>,
}

/// What the heartbeat learned.
pub enum LeaseState {
    Held { cancel_requested: bool },
    Lost,
}

/// In a worker's id: it runs jobs inside the server process (job isolation `thread`).
pub const IN_PROCESS_MARK: &str = "-inproc-";

/// How often, at least, a claiming process settles dead workers' jobs, ms.
const SETTLE_EVERY_MS: i64 = 1000;

/// Ends a dead worker's attempt (still open) as lost.
async fn close_lost_attempt(
    tx: &mut Tx,
    job_id: &str,
    attempt: i64,
    now: i64,
) -> Result<(), StoreError> {
    on_tx!(tx, c => sqlx::query("UPDATE job_attempts SET outcome = 'lost', finished_at = $1 WHERE job_id = $2 AND attempt = $3 AND outcome IS NULL")
        .bind(now)
        .bind(job_id)
        .bind(attempt)
        .execute(&mut *c)
        .await?
        .rows_affected());
    Ok(())
}

fn is_unique_violation(e: &sqlx::Error) -> bool {
    matches!(e, sqlx::Error::Database(d) if d.is_unique_violation())
}

impl Db {
    pub async fn create_job(
        &self,
        owner: &str,
        mut new: NewJob,
    ) -> Result<CreateOutcome, StoreError> {
        if let Some(key) = &new.idempotency_key {
            if let Some(existing) = self.job_by_idempotency_key(owner, key).await? {
                match self
                    .replay_or_conflict(owner, &new.request_hash, existing)
                    .await
                {
                    // Deleted since it was found: the key is free, this is a new job.
                    Err(StoreError::Vanished(_)) => {}
                    other => return other,
                }
            }
        }
        let now = now_ms();
        let id = new_id();
        let mut tx = self.begin().await?;
        for inline in &new.inline {
            let resource = NewResource {
                kind: inline.kind,
                name: inline.name.as_deref(),
                media_type: inline.media_type,
                summary: inline.summary.clone(),
                content: &inline.content,
                view: None,
            };
            let rid = insert_resource(&mut tx, owner, &resource).await?;
            new.inputs
                .insert(inline.input.clone(), serde_json::Value::String(rid));
        }
        let spec = serde_json::json!({ "inputs": new.inputs, "options": new.options });
        tx.lock_owner_queue(owner).await?;
        // The queue limit is checked in the INSERT itself, so concurrent submissions
        // cannot both pass a count taken before either was stored. A key used by a
        // concurrent first submission inserts nothing (ON CONFLICT, which on PostgreSQL
        // waits for that submission to commit or roll back) and is answered below.
        let inserted = on_tx!(&mut tx, c => sqlx::query(
            "INSERT INTO jobs (id, owner, kind, status, spec, idempotency_key, request_hash, max_attempts, created_at, updated_at)
             SELECT $1, $2, $3, 'queued', $4, $5, $6, $7, $8, $8
             WHERE (SELECT COUNT(*) FROM jobs WHERE owner = $2 AND status = 'queued') < $9
             ON CONFLICT (owner, idempotency_key) WHERE idempotency_key IS NOT NULL DO NOTHING",
        )
        .bind(&id)
        .bind(owner)
        .bind(&new.kind)
        .bind(spec.to_string())
        .bind(&new.idempotency_key)
        .bind(&new.request_hash)
        .bind(new.max_attempts)
        .bind(now)
        .bind(new.max_queued)
        .execute(&mut *c)
        .await
        .map(|done| done.rows_affected()));
        match inserted {
            Ok(0) => {
                tx.rollback().await?;
                // A replay that raced its first submission is answered as a replay.
                if let Some(key) = &new.idempotency_key {
                    if let Some(existing) = self.job_by_idempotency_key(owner, key).await? {
                        return self
                            .replay_or_conflict(owner, &new.request_hash, existing)
                            .await;
                    }
                }
                Ok(CreateOutcome::QueueFull)
            }
            Ok(_) => {
                // Read back inside the transaction: after the commit a worker may already
                // have claimed it, and the answer to the submission is the job as created.
                let job = on_tx!(&mut tx, c => {
                    let row = sqlx::query("SELECT * FROM jobs WHERE owner = $1 AND id = $2")
                        .bind(owner)
                        .bind(&id)
                        .fetch_one(&mut *c)
                        .await?;
                    job_record(&row)?
                });
                tx.commit().await?;
                Ok(CreateOutcome::Created(job))
            }
            // Two requests with one key raced; the other one won.
            Err(e) if is_unique_violation(&e) && new.idempotency_key.is_some() => {
                tx.rollback().await?;
                let key = new.idempotency_key.as_deref().unwrap_or_default();
                let existing = self
                    .job_by_idempotency_key(owner, key)
                    .await?
                    .ok_or(StoreError::Sql(e))?;
                self.replay_or_conflict(owner, &new.request_hash, existing)
                    .await
            }
            Err(e) => Err(e.into()),
        }
    }

    async fn job_by_idempotency_key(
        &self,
        owner: &str,
        key: &str,
    ) -> Result<Option<(String, String)>, StoreError> {
        let row: Option<(String, Option<String>)> = on_pool!(&self.pool, p => sqlx::query_as(
            "SELECT id, request_hash FROM jobs WHERE owner = $1 AND idempotency_key = $2",
        )
        .bind(owner)
        .bind(key)
        .fetch_optional(p)
        .await?);
        Ok(row.map(|(id, hash)| (id, hash.unwrap_or_default())))
    }

    async fn replay_or_conflict(
        &self,
        owner: &str,
        hash: &str,
        (id, stored_hash): (String, String),
    ) -> Result<CreateOutcome, StoreError> {
        // A DELETE may have come between the lookup by key and this read.
        let job = self
            .get_job(owner, &id)
            .await?
            .ok_or_else(|| StoreError::Vanished(format!("job {id}")))?;
        Ok(if stored_hash == hash {
            CreateOutcome::Replayed(job)
        } else {
            CreateOutcome::KeyConflict(job)
        })
    }

    pub async fn get_job(&self, owner: &str, id: &str) -> Result<Option<JobRecord>, StoreError> {
        on_pool!(&self.pool, p => {
            let row = sqlx::query("SELECT * FROM jobs WHERE owner = $1 AND id = $2")
                .bind(owner)
                .bind(id)
                .fetch_optional(p)
                .await?;
            row.as_ref().map(job_record).transpose()
        })
    }

    pub async fn list_jobs(
        &self,
        owner: &str,
        status: Option<JobStatus>,
        kind: Option<&str>,
        cursor: Option<&str>,
        limit: u32,
    ) -> Result<(Vec<JobRecord>, Option<String>), StoreError> {
        let items = on_pool!(&self.pool, p => {
            let rows = sqlx::query(
                "SELECT * FROM jobs WHERE owner = $1 AND id > $2
                   AND ($3 IS NULL OR status = $3) AND ($4 IS NULL OR kind = $4)
                 ORDER BY id LIMIT $5",
            )
            .bind(owner)
            .bind(cursor.unwrap_or(""))
            .bind(status.map(JobStatus::as_str))
            .bind(kind)
            .bind(i64::from(limit) + 1)
            .fetch_all(p)
            .await?;
            rows.iter().map(job_record).collect::<Result<Vec<_>, _>>()?
        });
        Ok(super::page(items, limit, |j| &j.id))
    }

    /// Cancels a queued job at once; asks a running one to stop (its worker sees the
    /// flag at the next heartbeat). Returns the job as it now is.
    /// A running job whose lease has expired (its worker died) is cancelled at once too,
    /// and its open attempt closed as lost.
    pub async fn cancel_job(&self, owner: &str, id: &str) -> Result<Option<JobRecord>, StoreError> {
        let now = now_ms();
        let mut tx = self.begin().await?;
        let settled: Option<(String, i64)> = on_tx!(&mut tx, c => sqlx::query_as(
            "UPDATE jobs SET
                status = CASE WHEN status = 'queued' OR lease_expires_at < $1 THEN 'cancelled' ELSE status END,
                finished_at = CASE WHEN status = 'queued' OR lease_expires_at < $1 THEN $1 ELSE finished_at END,
                lease_owner = CASE WHEN status = 'queued' OR lease_expires_at < $1 THEN NULL ELSE lease_owner END,
                cancel_requested = 1, updated_at = $1
             WHERE owner = $2 AND id = $3 AND status IN ('queued', 'running')
             RETURNING status, attempts",
        )
        .bind(now)
        .bind(owner)
        .bind(id)
        .fetch_optional(&mut *c)
        .await?);
        if let Some((status, attempt)) = settled {
            if status == "cancelled" {
                close_lost_attempt(&mut tx, id, attempt, now).await?;
                enqueue_job_event(&mut tx, id, "job.cancelled").await?;
            }
        }
        tx.commit().await?;
        self.get_job(owner, id).await
    }

    /// Fails jobs whose lease expired on their last allowed attempt: a job that keeps
    /// killing its worker must stop being retried.
    pub async fn fail_exhausted(&self) -> Result<u64, StoreError> {
        let now = now_ms();
        let mut tx = self.begin().await?;
        let skip_locked = tx.backend().skip_locked();
        let lost: Vec<(String, i64, i64)> = on_tx!(&mut tx, c => sqlx::query_as(&format!(
            "UPDATE jobs SET status = 'failed', finished_at = $1, updated_at = $1, lease_owner = NULL
             WHERE id IN (SELECT id FROM jobs
                          WHERE status = 'running' AND lease_expires_at < $1 AND attempts >= max_attempts{skip_locked})
             RETURNING id, attempts, max_attempts",
        ))
        .bind(now)
        .fetch_all(&mut *c)
        .await?);
        // The problem is built here like every other, not as JSON inside the SQL.
        for (id, attempts, max_attempts) in &lost {
            let error = crate::problem::Problem::worker_lost(*attempts, *max_attempts)
                .to_json()
                .to_string();
            on_tx!(&mut tx, c => sqlx::query("UPDATE jobs SET error = $1 WHERE id = $2")
                .bind(error)
                .bind(id)
                .execute(&mut *c)
                .await?
                .rows_affected());
            close_lost_attempt(&mut tx, id, *attempts, now).await?;
            enqueue_job_event(&mut tx, id, "job.failed").await?;
        }
        tx.commit().await?;
        Ok(lost.len() as u64)
    }

    /// Settles the jobs of dead workers (leases expired): failed when their attempts are
    /// used up or they ran inside a server that died with them, cancelled when a cancel
    /// was asked for. Claims skip such jobs, so this need not run before every claim.
    pub async fn settle_lost_jobs(&self) -> Result<(), StoreError> {
        let now = now_ms();
        self.fail_exhausted().await?;
        let mut tx = self.begin().await?;
        let skip_locked = tx.backend().skip_locked();
        let cancelled: Vec<(String, i64)> = on_tx!(&mut tx, c => sqlx::query_as(&format!(
            "UPDATE jobs SET status = 'cancelled', finished_at = $1, updated_at = $1, lease_owner = NULL
             WHERE id IN (SELECT id FROM jobs
                          WHERE status = 'running' AND lease_expires_at < $1 AND cancel_requested = 1{skip_locked})
             RETURNING id, attempts",
        ))
        .bind(now)
        .fetch_all(&mut *c)
        .await?);
        // Their workers died: the attempts end here, or they would stay open for ever.
        for (id, attempt) in &cancelled {
            close_lost_attempt(&mut tx, id, *attempt, now).await?;
            enqueue_job_event(&mut tx, id, "job.cancelled").await?;
        }
        // A job whose worker ran it inside the server process (thread isolation) and was
        // lost with it may have brought the server down: failed, not run again.
        let error = crate::problem::Problem::resource_limit(
            "Job lost with its server",
            "the server running this job inside its own process (job isolation `thread`) stopped while the job ran; the job may have brought it down (out of memory, a crash), so it is not retried",
            "job_isolation",
        )
        .to_json()
        .to_string();
        let crashed: Vec<(String, i64)> = on_tx!(&mut tx, c => sqlx::query_as(&format!(
            "UPDATE jobs SET status = 'failed', finished_at = $1, updated_at = $1, lease_owner = NULL,
                error = $3
             WHERE id IN (SELECT id FROM jobs
                          WHERE status = 'running' AND lease_expires_at < $1 AND lease_owner LIKE $2{skip_locked})
             RETURNING id, attempts",
        ))
        .bind(now)
        .bind(format!("%{IN_PROCESS_MARK}%"))
        .bind(error)
        .fetch_all(&mut *c)
        .await?);
        for (id, attempt) in &crashed {
            close_lost_attempt(&mut tx, id, *attempt, now).await?;
            enqueue_job_event(&mut tx, id, "job.failed").await?;
        }
        tx.commit().await?;
        self.last_settled.store(now, Ordering::Relaxed);
        Ok(())
    }

    /// Claims a job: the oldest running job whose lease expired (its worker died) and
    /// that may run again, else the oldest queued job. Retries go first so a long queue
    /// does not hold back a job that was already running. One UPDATE … RETURNING whose
    /// subqueries pick the job, each from its own partial index; on PostgreSQL they lock
    /// it `FOR UPDATE SKIP LOCKED`, so concurrent claimers on any host take different
    /// jobs without waiting on each other.
    /// Dead workers' jobs are settled first: at least every `SETTLE_EVERY_MS` in this
    /// process, and whenever nothing is claimable.
    pub async fn claim_job(
        &self,
        worker: &str,
        lease_ms: i64,
    ) -> Result<Option<ClaimedJob>, StoreError> {
        if now_ms() - self.last_settled.load(Ordering::Relaxed) >= SETTLE_EVERY_MS {
            self.settle_lost_jobs().await?;
        } else if let Some(job) = self.try_claim(worker, lease_ms).await? {
            return Ok(Some(job));
        } else {
            self.settle_lost_jobs().await?;
        }
        self.try_claim(worker, lease_ms).await
    }

    async fn try_claim(
        &self,
        worker: &str,
        lease_ms: i64,
    ) -> Result<Option<ClaimedJob>, StoreError> {
        let now = now_ms();
        // An expired job that settling would end (attempts used up, cancel asked, lost
        // with its server) is not claimed: settle_lost_jobs ends it.
        let claim = |skip_locked: &str| {
            format!(
                "UPDATE jobs SET status = 'running', lease_owner = $1, lease_expires_at = $2,
                    attempts = attempts + 1, started_at = $3, finished_at = NULL, updated_at = $3
                 WHERE id = COALESCE(
                    (SELECT id FROM jobs
                     WHERE status = 'running' AND lease_expires_at < $3 AND attempts < max_attempts
                       AND cancel_requested = 0 AND lease_owner NOT LIKE $4
                     ORDER BY id LIMIT 1{skip_locked}),
                    (SELECT id FROM jobs WHERE status = 'queued' ORDER BY id LIMIT 1{skip_locked}))
                 RETURNING id, owner, kind, spec, attempts"
            )
        };
        let in_process = format!("%{IN_PROCESS_MARK}%");
        type Claimed = (String, String, String, String, i64);
        let row: Option<Claimed> = match &self.lossy {
            // PostgreSQL: the claim and its attempt row in one statement, on a connection
            // whose commit does not wait for the disk. If the database crashes before the
            // commit is flushed, the claim is lost: the job is as it was (queued, or
            // running with an expired lease) and is claimed again, with the same attempt
            // number, by another worker or this one. The worker that believed it held it
            // learns otherwise at its next heartbeat (the lease is not its own: it stops),
            // and its result cannot commit: finish_job writes only while `lease_owner` is
            // this worker and `attempts` this attempt, in a durable commit. A durable
            // commit also flushes every earlier one (the WAL is written in order), so a
            // result is never on disk without the claim it depends on. What a lost claim
            // can cost is a job run twice for at most one heartbeat period after a
            // database crash, never a result written twice or lost.
            Some(pg) => {
                sqlx::query_as(&format!(
                    "WITH claimed AS ({}),
                 closed AS (
                    -- The previous attempt, if its worker died, ends here as lost.
                    UPDATE job_attempts SET outcome = 'lost', finished_at = $3
                    WHERE job_id = (SELECT id FROM claimed) AND outcome IS NULL),
                 opened AS (
                    INSERT INTO job_attempts (job_id, attempt, worker, started_at)
                    SELECT id, attempts, $1, $3 FROM claimed)
                 SELECT id, owner, kind, spec, attempts FROM claimed",
                    claim(" FOR UPDATE SKIP LOCKED")
                ))
                .bind(worker)
                .bind(now + lease_ms)
                .bind(now)
                .bind(&in_process)
                .fetch_optional(pg)
                .await?
            }
            // SQLite (no writes in WITH): one transaction; its single writer needs no
            // row locks.
            None => {
                let mut tx = self.begin().await?;
                let row: Option<Claimed> = on_tx!(&mut tx, c => sqlx::query_as(&claim(""))
                    .bind(worker)
                    .bind(now + lease_ms)
                    .bind(now)
                    .bind(&in_process)
                    .fetch_optional(&mut *c)
                    .await?);
                if let Some((id, _, _, _, attempt)) = &row {
                    on_tx!(&mut tx, c => {
                        if *attempt > 1 {
                            sqlx::query("UPDATE job_attempts SET outcome = 'lost', finished_at = $1 WHERE job_id = $2 AND outcome IS NULL")
                                .bind(now)
                                .bind(id)
                                .execute(&mut *c)
                                .await?;
                        }
                        sqlx::query(
                            "INSERT INTO job_attempts (job_id, attempt, worker, started_at) VALUES ($1, $2, $3, $4)",
                        )
                        .bind(id)
                        .bind(*attempt)
                        .bind(worker)
                        .bind(now)
                        .execute(&mut *c)
                        .await?;
                    });
                    tx.commit().await?;
                } else {
                    tx.rollback().await?;
                }
                row
            }
        };
        let Some((id, owner, kind, spec, attempt)) = row else {
            return Ok(None);
        };
        Ok(Some(ClaimedJob {
            id,
            owner,
            kind,
            spec: serde_json::from_str(&spec)?,
            attempt,
        }))
    }

    /// Extends the lease and records progress; tells the worker whether it still holds
    /// the job and whether someone asked to cancel it.
    pub async fn heartbeat(
        &self,
        job: &ClaimedJob,
        worker: &str,
        lease_ms: i64,
        done: u64,
        total: u64,
    ) -> Result<LeaseState, StoreError> {
        let now = now_ms();
        // On PostgreSQL not waited for on disk either (see try_claim): a renewal lost in
        // a database crash shortens the lease, which at worst lets another worker take
        // the job, and then this worker's result cannot commit. Lost progress is
        // rewritten at the next beat.
        let row: Option<(i64,)> = on_pool!(&self.queue_pool(), p => sqlx::query_as(
            "UPDATE jobs SET lease_expires_at = $1, progress_done = $2, progress_total = $3, updated_at = $4
             WHERE id = $5 AND lease_owner = $6 AND status = 'running' AND attempts = $7
             RETURNING cancel_requested",
        )
        .bind(now + lease_ms)
        .bind(done as i64)
        .bind(total as i64)
        .bind(now)
        .bind(&job.id)
        .bind(worker)
        .bind(job.attempt)
        .fetch_optional(p)
        .await?);
        Ok(match row {
            Some((c,)) => {
                super::webhooks::enqueue_progress(self, &job.id).await?;
                LeaseState::Held {
                    cancel_requested: c != 0,
                }
            }
            None => LeaseState::Lost,
        })
    }

    /// Writes the outcome and the results in one transaction, only if this worker still
    /// holds this attempt's lease. Returns false (and writes nothing) when it does not.
    /// `ran_until` (unix ms) is when the attempt's run ended: the attempt spans its claim
    /// to then (a worker on PostgreSQL may claim its next job while this commits); the
    /// job's finished_at is the commit's time, when its outcome became visible.
    pub async fn finish_job(
        &self,
        job: &ClaimedJob,
        worker: &str,
        mut finish: Finish,
        ran_until: i64,
    ) -> Result<bool, StoreError> {
        let now = now_ms();
        let (status, summary, error, outcome) = match &finish {
            Finish::Succeeded { summary, .. } => {
                ("succeeded", Some(summary.to_string()), None, "succeeded")
            }
            Finish::Failed { error } => ("failed", None, Some(error.to_string()), "failed"),
            Finish::Cancelled => ("cancelled", None, None, "cancelled"),
        };
        let progress = match &finish {
            Finish::Succeeded { progress, .. } => Some((progress.0 as i64, progress.1 as i64)),
            _ => None,
        };
        // Rows and samples are grouped and compressed before the transaction begins, so
        // it writes (and holds its locks for) a seventh of their bytes.
        let (row_groups, sample_groups) = match &mut finish {
            Finish::Succeeded { rows, samples, .. } => {
                let rows: Vec<(i64, String)> = std::mem::take(rows)
                    .into_iter()
                    .enumerate()
                    .map(|(seq, r)| (seq as i64, r))
                    .collect();
                let samples: Vec<(i64, String)> = std::mem::take(samples)
                    .into_iter()
                    .map(|(seq, s)| (seq as i64, s))
                    .collect();
                tokio::task::spawn_blocking(move || {
                    Ok::<_, std::io::Error>((pack(&rows)?, pack(&samples)?))
                })
                .await
                .map_err(std::io::Error::other)??
            }
            _ => (Vec::<Group>::new(), Vec::new()),
        };
        let mut tx = self.begin().await?;
        // The state change comes first so the transaction takes the write lock before it
        // reads anything (no lock upgrade, no SQLITE_BUSY deadlock between processes).
        let done = on_tx!(&mut tx, c => sqlx::query(
            "UPDATE jobs SET status = $1, summary = $2, error = $3, finished_at = $4, updated_at = $4,
                lease_owner = NULL, lease_expires_at = NULL,
                progress_done = COALESCE($5, progress_done), progress_total = COALESCE($6, progress_total)
             WHERE id = $7 AND lease_owner = $8 AND status = 'running' AND attempts = $9",
        )
        .bind(status)
        .bind(summary)
        .bind(error)
        .bind(now)
        .bind(progress.map(|p| p.0))
        .bind(progress.map(|p| p.1))
        .bind(&job.id)
        .bind(worker)
        .bind(job.attempt)
        .execute(&mut *c)
        .await?
        .rows_affected());
        if done == 0 {
            tx.rollback().await?;
            return Ok(false);
        }
        if let Finish::Succeeded {
            artifacts,
            resources,
            ..
        } = finish
        {
            let owner: String = if resources.is_empty() {
                String::new()
            } else {
                on_tx!(&mut tx, c => sqlx::query_scalar("SELECT owner FROM jobs WHERE id = $1")
                    .bind(&job.id)
                    .fetch_one(&mut *c)
                    .await?)
            };
            for r in &resources {
                let new = NewResource {
                    kind: r.kind,
                    name: Some(&r.name),
                    media_type: &r.media_type,
                    summary: r.summary.clone(),
                    content: &r.content,
                    view: None,
                };
                insert_with_id(&mut tx, &r.id, &owner, &new).await?;
            }
            insert_groups(&mut tx, "job_row_groups", &job.id, &row_groups).await?;
            insert_groups(&mut tx, "job_sample_groups", &job.id, &sample_groups).await?;
            // Written after the lease check above, in this transaction: an attempt that
            // lost its lease leaves no chunk behind.
            for a in artifacts {
                insert_artifact(&mut tx, &job.id, a).await?;
            }
        }
        on_tx!(&mut tx, c => sqlx::query(
            "UPDATE job_attempts SET outcome = $1, finished_at = $2 WHERE job_id = $3 AND attempt = $4",
        )
        .bind(outcome)
        .bind(ran_until.min(now))
        .bind(&job.id)
        .bind(job.attempt)
        .execute(&mut *c)
        .await?
        .rows_affected());
        // The webhooks' outbox, with the state change: both commit or neither.
        enqueue_job_event(&mut tx, &job.id, &format!("job.{outcome}")).await?;
        tx.commit().await?;
        Ok(true)
    }

    /// Gives a job back to the queue on graceful shutdown; the attempt does not count.
    pub async fn release_job(&self, job: &ClaimedJob, worker: &str) -> Result<bool, StoreError> {
        let now = now_ms();
        let mut tx = self.begin().await?;
        let done = on_tx!(&mut tx, c => sqlx::query(
            "UPDATE jobs SET status = 'queued', lease_owner = NULL, lease_expires_at = NULL,
                attempts = attempts - 1, updated_at = $1
             WHERE id = $2 AND lease_owner = $3 AND status = 'running' AND attempts = $4",
        )
        .bind(now)
        .bind(&job.id)
        .bind(worker)
        .bind(job.attempt)
        .execute(&mut *c)
        .await?
        .rows_affected());
        if done == 0 {
            tx.rollback().await?;
            return Ok(false);
        }
        // The attempt does not count: its number is reused by the next claim.
        on_tx!(&mut tx, c => sqlx::query("DELETE FROM job_attempts WHERE job_id = $1 AND attempt = $2")
            .bind(&job.id)
            .bind(job.attempt)
            .execute(&mut *c)
            .await?
            .rows_affected());
        tx.commit().await?;
        Ok(true)
    }

    /// Counts a failed start of the job's process, stored with the job (every server
    /// and worker sharing the database counts the same tries), while `worker` holds its
    /// lease: the tries so far, None when it no longer holds it.
    pub async fn count_start_failure(
        &self,
        job: &ClaimedJob,
        worker: &str,
    ) -> Result<Option<i64>, StoreError> {
        Ok(on_pool!(&self.pool, p => sqlx::query_scalar(
            "UPDATE jobs SET start_failures = start_failures + 1, updated_at = $1
             WHERE id = $2 AND lease_owner = $3 AND status = 'running' AND attempts = $4
             RETURNING start_failures",
        )
        .bind(now_ms())
        .bind(&job.id)
        .bind(worker)
        .bind(job.attempt)
        .fetch_optional(p)
        .await?))
    }

    /// One page of a finished job's per-block rows, raw JSON text, from `from` on.
    pub async fn job_rows(
        &self,
        job_id: &str,
        from: i64,
        limit: i64,
    ) -> Result<Vec<(i64, String)>, StoreError> {
        let want = usize::try_from(limit).unwrap_or(0);
        read_rows(&self.pool, "job_row_groups", job_id, from, i64::MAX, want).await
    }

    /// Per-step samples of the rows with seq in [from, to], in seq order.
    pub async fn job_samples(
        &self,
        job_id: &str,
        from: i64,
        to: i64,
    ) -> Result<Vec<(i64, String)>, StoreError> {
        read_rows(
            &self.pool,
            "job_sample_groups",
            job_id,
            from,
            to,
            usize::MAX,
        )
        .await
    }

    pub async fn delete_job(&self, owner: &str, id: &str) -> Result<bool, StoreError> {
        let done = on_pool!(&self.pool, p => sqlx::query(
            "DELETE FROM jobs WHERE owner = $1 AND id = $2 AND status NOT IN ('queued', 'running')",
        )
        .bind(owner)
        .bind(id)
        .execute(p)
        .await?
        .rows_affected());
        Ok(done > 0)
    }

    /// Job counts by status, over all owners, for /metrics.
    pub async fn job_counts(&self) -> Result<Vec<(String, i64)>, StoreError> {
        Ok(on_pool!(&self.pool, p =>
            sqlx::query_as("SELECT status, COUNT(*) FROM jobs GROUP BY status")
                .fetch_all(p)
                .await?))
    }

    /// The attempts log of a job: (attempt, worker, started, finished, outcome).
    pub async fn job_attempts(
        &self,
        job_id: &str,
    ) -> Result<Vec<(i64, String, i64, Option<i64>, Option<String>)>, StoreError> {
        Ok(
            on_pool!(&self.pool, p => sqlx::query_as("SELECT attempt, worker, started_at, finished_at, outcome FROM job_attempts WHERE job_id = $1 ORDER BY attempt")
            .bind(job_id)
            .fetch_all(p)
            .await?),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn a_replay_whose_job_was_deleted_is_an_error_not_a_panic() {
        let dir = tempfile::tempdir().unwrap();
        let url = format!("sqlite://{}", dir.path().join("t.db").display());
        let db = Db::open(&url).await.unwrap();
        let gone = ("nosuchjob".to_string(), "hash".to_string());
        let out = db.replay_or_conflict("mes", "hash", gone).await;
        assert!(matches!(out, Err(StoreError::Vanished(_))));
    }
}
