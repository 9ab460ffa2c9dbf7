//! The event bus on PostgreSQL: one LISTEN connection per process turns the `jobs`
//! trigger's notifications (migrations/postgres) into wake-ups for this process's idle
//! workers and its event streams. Job changes are announced only for jobs a stream
//! follows (`job_watchers`): a NOTIFY serializes commits, so the queue's claims and
//! results send none unless someone waits for them. SQLite has no such bus: there,
//! workers and streams poll.

use std::sync::Arc;
use std::time::Duration;

use sqlx::postgres::PgListener;
use tokio::sync::{broadcast, Notify};

use super::{new_id, now_ms, StoreError};

const QUEUED: &str = "millsim_job_queued";
const CHANGED: &str = "millsim_job_changed";
/// Sent to event streams when notifications may have been missed (the LISTEN connection
/// was re-established): every stream reads its job again.
pub const ANY_JOB: &str = "*";

/// How long an event stream waits for a notification before it reads its job anyway: a
/// safety net only, changes arrive pushed.
const STREAM_FALLBACK: Duration = Duration::from_secs(5);
/// What SQLite's event streams poll at.
const STREAM_POLL: Duration = Duration::from_millis(200);

pub struct Changes {
    /// A job was queued (submitted, or given back): wakes one idle worker of this process.
    pub queued: Notify,
    /// A job changed: its id (or [`ANY_JOB`]).
    pub jobs: broadcast::Sender<Arc<str>>,
}

/// Starts listening; the returned bus lives as long as the process.
pub async fn listen(pool: &sqlx::PgPool) -> Result<Arc<Changes>, StoreError> {
    let mut listener = PgListener::connect_with(pool).await?;
    listener.listen_all([QUEUED, CHANGED]).await?;
    let changes = Arc::new(Changes {
        queued: Notify::new(),
        jobs: broadcast::channel(1024).0,
    });
    let bus = changes.clone();
    tokio::spawn(async move {
        loop {
            match listener.try_recv().await {
                Ok(Some(n)) if n.channel() == QUEUED => bus.queued.notify_one(),
                Ok(Some(n)) => {
                    let _ = bus.jobs.send(n.payload().into());
                }
                // The connection was lost and is being re-established: whatever was sent
                // meanwhile is gone, so everyone looks again.
                Ok(None) => wake_everyone(&bus),
                Err(e) => {
                    tracing::warn!(error = %e, "database notifications interrupted; retrying");
                    wake_everyone(&bus);
                    tokio::time::sleep(Duration::from_secs(1)).await;
                }
            }
        }
    });
    Ok(changes)
}

fn wake_everyone(bus: &Changes) {
    bus.queued.notify_waiters();
    bus.queued.notify_one();
    let _ = bus.jobs.send(ANY_JOB.into());
}

/// How long a stream's registration lives without renewal: a process that dies leaves
/// its rows behind for at most this long (then any new stream deletes them).
const WATCH_TTL_MS: i64 = 300_000;
/// How often a live stream renews its registration.
const WATCH_RENEW_MS: i64 = 60_000;

/// A stream's row in `job_watchers` (PostgreSQL): it makes the database announce its
/// job's changes. Deleted when the stream ends.
struct Registration {
    pool: sqlx::PgPool,
    watcher: String,
    renewed_at: i64,
}

/// Waits for a change to one job: pushed on PostgreSQL, a short poll interval on SQLite.
pub struct JobWatch {
    id: String,
    rx: Option<broadcast::Receiver<Arc<str>>>,
    registration: Option<Registration>,
}

impl JobWatch {
    /// Starts following job `id`. On PostgreSQL: subscribes to this process's bus,
    /// registers the job in `job_watchers`, then waits for the transactions already
    /// writing the job (`FOR SHARE` waits on their row lock). The trigger looks for
    /// watchers when it writes the job: a writer that looked before the registration
    /// has committed by the time this returns, so the caller's next read shows its
    /// change; any later writer finds the registration and notifies.
    pub(super) async fn new(
        id: &str,
        changes: Option<(&Changes, &sqlx::PgPool)>,
    ) -> Result<JobWatch, StoreError> {
        let Some((changes, pool)) = changes else {
            return Ok(JobWatch {
                id: id.to_string(),
                rx: None,
                registration: None,
            });
        };
        let rx = changes.jobs.subscribe();
        let now = now_ms();
        let watcher = new_id();
        // Expired rows are those of processes that died while streaming.
        sqlx::query("DELETE FROM job_watchers WHERE expires_at < $1")
            .bind(now)
            .execute(pool)
            .await?;
        sqlx::query("INSERT INTO job_watchers (job_id, watcher, expires_at) VALUES ($1, $2, $3)")
            .bind(id)
            .bind(&watcher)
            .bind(now + WATCH_TTL_MS)
            .execute(pool)
            .await?;
        sqlx::query("SELECT 1 FROM jobs WHERE id = $1 FOR SHARE")
            .bind(id)
            .fetch_optional(pool)
            .await?;
        Ok(JobWatch {
            id: id.to_string(),
            rx: Some(rx),
            registration: Some(Registration {
                pool: pool.clone(),
                watcher,
                renewed_at: now,
            }),
        })
    }

    /// Returns when the job may have changed (read it again).
    pub async fn changed(&mut self) {
        self.renew().await;
        let Some(rx) = &mut self.rx else {
            tokio::time::sleep(STREAM_POLL).await;
            return;
        };
        let wait = async {
            loop {
                match rx.recv().await {
                    Ok(id) if *id == *self.id || &*id == ANY_JOB => return,
                    Ok(_) => {}
                    // Fell behind the bus: this job's change may be among the dropped ones.
                    Err(broadcast::error::RecvError::Lagged(_)) => return,
                    Err(broadcast::error::RecvError::Closed) => std::future::pending::<()>().await,
                }
            }
        };
        let _ = tokio::time::timeout(STREAM_FALLBACK, wait).await;
    }

    /// Keeps a long stream's registration from expiring. A failure is only logged: the
    /// stream still reads its job every few seconds.
    async fn renew(&mut self) {
        let Some(r) = &mut self.registration else {
            return;
        };
        let now = now_ms();
        if now - r.renewed_at < WATCH_RENEW_MS {
            return;
        }
        r.renewed_at = now;
        if let Err(e) = sqlx::query(
            "UPDATE job_watchers SET expires_at = $1 WHERE job_id = $2 AND watcher = $3",
        )
        .bind(now + WATCH_TTL_MS)
        .bind(&self.id)
        .bind(&r.watcher)
        .execute(&r.pool)
        .await
        {
            tracing::warn!(job = %self.id, error = %e, "could not renew an event stream's registration");
        }
    }
}

impl Drop for JobWatch {
    fn drop(&mut self) {
        let Some(r) = self.registration.take() else {
            return;
        };
        let id = std::mem::take(&mut self.id);
        // Dropped in async code (the stream's end); if the runtime is gone, the row
        // simply expires.
        if let Ok(rt) = tokio::runtime::Handle::try_current() {
            rt.spawn(async move {
                let _ = sqlx::query("DELETE FROM job_watchers WHERE job_id = $1 AND watcher = $2")
                    .bind(&id)
                    .bind(&r.watcher)
                    .execute(&r.pool)
                    .await;
            });
        }
    }
}
