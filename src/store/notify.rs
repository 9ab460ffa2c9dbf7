//! The event bus on PostgreSQL: one LISTEN connection per process turns the `jobs`
//! trigger's notifications (migrations/postgres) into wake-ups for this process's idle
//! workers and its event streams. SQLite has no such bus: there, workers and streams poll.

use std::sync::Arc;
use std::time::Duration;

use sqlx::postgres::PgListener;
use tokio::sync::{broadcast, Notify};

use super::StoreError;

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

/// Waits for a change to one job: pushed on PostgreSQL, a short poll interval on SQLite.
pub struct JobWatch {
    id: String,
    rx: Option<broadcast::Receiver<Arc<str>>>,
}

impl JobWatch {
    pub(super) fn new(id: &str, changes: Option<&Changes>) -> JobWatch {
        JobWatch {
            id: id.to_string(),
            rx: changes.map(|c| c.jobs.subscribe()),
        }
    }

    /// Returns when the job may have changed (read it again).
    pub async fn changed(&mut self) {
        let Some(rx) = &mut self.rx else {
            tokio::time::sleep(STREAM_POLL).await;
            return;
        };
        let wait = async {
            loop {
                match rx.recv().await {
                    Ok(id) if &*id == self.id || &*id == ANY_JOB => return,
                    Ok(_) => {}
                    // Fell behind the bus: this job's change may be among the dropped ones.
                    Err(broadcast::error::RecvError::Lagged(_)) => return,
                    Err(broadcast::error::RecvError::Closed) => std::future::pending::<()>().await,
                }
            }
        };
        let _ = tokio::time::timeout(STREAM_FALLBACK, wait).await;
    }
}
