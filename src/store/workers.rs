//! The workers of every process sharing the database, for /metrics: each process writes
//! its workers' counts every second (`queue::report_workers`), so an API process on any
//! host shows them all. A row is stamped with the database's clock, so hosts' clocks need
//! not agree on who is alive.

use super::backend::{on_pool, Backend};
use super::{Db, StoreError};

/// A row not renewed for this long is a worker that died (reports come every second).
pub const LIVE_MS: i64 = 5_000;
/// Rows of dead workers are deleted after this long.
const FORGET_MS: i64 = 600_000;

/// One worker's state and counts since it started.
#[derive(Clone, Debug, Default, PartialEq, Eq, sqlx::FromRow)]
pub struct WorkerReport {
    pub id: String,
    pub host: String,
    pub pid: i64,
    pub started_at: i64,
    /// 1 while it runs a job.
    pub running: i64,
    pub claimed: i64,
    pub succeeded: i64,
    pub failed: i64,
    pub cancelled: i64,
    /// Claimed but not finished by this worker: lease lost, given back, or not committed.
    pub abandoned: i64,
}

impl Backend {
    /// The database's clock, unix milliseconds, in SQL.
    fn now_ms_sql(self) -> &'static str {
        match self {
            Backend::Sqlite => "CAST((julianday('now') - 2440587.5) * 86400000 AS INTEGER)",
            Backend::Postgres => "(extract(epoch FROM clock_timestamp()) * 1000)::bigint",
        }
    }
}

impl Db {
    /// Writes this process's workers' rows (their counts, and that they are alive).
    /// On PostgreSQL on the lossy connections: a report lost in a database crash is
    /// replaced a second later.
    pub async fn report_workers(&self, workers: &[WorkerReport]) -> Result<(), StoreError> {
        let now = self.backend().now_ms_sql();
        let pool = self.queue_pool();
        for w in workers {
            on_pool!(&pool, p => sqlx::query(&format!(
                "INSERT INTO workers (id, host, pid, started_at, seen_at, running, claimed, succeeded, failed, cancelled, abandoned)
                 VALUES ($1, $2, $3, $4, {now}, $5, $6, $7, $8, $9, $10)
                 ON CONFLICT (id) DO UPDATE SET seen_at = excluded.seen_at, running = excluded.running,
                    claimed = excluded.claimed, succeeded = excluded.succeeded, failed = excluded.failed,
                    cancelled = excluded.cancelled, abandoned = excluded.abandoned",
            ))
            .bind(&w.id)
            .bind(&w.host)
            .bind(w.pid)
            .bind(w.started_at)
            .bind(w.running)
            .bind(w.claimed)
            .bind(w.succeeded)
            .bind(w.failed)
            .bind(w.cancelled)
            .bind(w.abandoned)
            .execute(p)
            .await?
            .rows_affected());
        }
        on_pool!(&pool, p => sqlx::query(&format!("DELETE FROM workers WHERE seen_at < {now} - $1"))
            .bind(FORGET_MS)
            .execute(p)
            .await?
            .rows_affected());
        Ok(())
    }

    /// Deletes workers' rows (their process stops).
    pub async fn remove_workers(&self, ids: &[String]) -> Result<(), StoreError> {
        for id in ids {
            on_pool!(&self.pool, p => sqlx::query("DELETE FROM workers WHERE id = $1")
                .bind(id)
                .execute(p)
                .await?
                .rows_affected());
        }
        Ok(())
    }

    /// The workers alive in any process, by id.
    pub async fn live_workers(&self) -> Result<Vec<WorkerReport>, StoreError> {
        let now = self.backend().now_ms_sql();
        Ok(on_pool!(&self.pool, p => sqlx::query_as(&format!(
            "SELECT id, host, pid, started_at, running, claimed, succeeded, failed, cancelled, abandoned
             FROM workers WHERE seen_at >= {now} - $1 ORDER BY id"
        ))
        .bind(LIVE_MS)
        .fetch_all(p)
        .await?))
    }
}
