//! Storage on SQLite (the embedded default) or PostgreSQL (many hosts, one database):
//! opening and migrating the database, resources, jobs and results. One store for both:
//! see [`backend`] for how, and for the few statements that differ.

pub mod artifacts;
pub mod backend;
pub mod bulk;
pub mod chunks;
pub mod jobs;
pub mod notify;
pub mod resources;
pub mod row_groups;
#[cfg(test)]
mod scratch;
pub mod webhooks;
pub mod workers;

use std::str::FromStr;
use std::sync::atomic::AtomicI64;
use std::sync::Arc;
use std::time::Duration;

use sqlx::postgres::{PgConnectOptions, PgPoolOptions};
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};

use backend::{on_pool, Backend, Pool, Tx};
pub use jobs::{JobRecord, JobStatus};
pub use notify::JobWatch;
pub use resources::ResourceKind;

static SQLITE_MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("./migrations/sqlite");
static POSTGRES_MIGRATOR: sqlx::migrate::Migrator = sqlx::migrate!("./migrations/postgres");

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("database: {0}")]
    Sql(#[from] sqlx::Error),
    #[error("database migration: {0}")]
    Migrate(#[from] sqlx::migrate::MigrateError),
    #[error("stored JSON is corrupt: {0}")]
    Json(#[from] serde_json::Error),
    #[error("reading stored content: {0}")]
    Io(#[from] std::io::Error),
    /// A row this request had just found or written was deleted by another one.
    #[error("{0} was deleted while this request ran")]
    Vanished(String),
    #[error(
        "unsupported database URL `{0}`: use sqlite://FILE or postgres://USER:PASSWORD@HOST/DB"
    )]
    UnsupportedUrl(String),
}

/// A page of a list read with one row more than `limit` (`LIMIT limit + 1`): at most
/// `limit` items, and the cursor of the next page (the last item's id) when there is one.
fn page<T>(mut items: Vec<T>, limit: u32, id: impl Fn(&T) -> &String) -> (Vec<T>, Option<String>) {
    let next = if items.len() > limit as usize {
        items.truncate(limit as usize);
        items.last().map(|i| id(i).clone())
    } else {
        None
    };
    (items, next)
}

#[derive(Clone)]
pub struct Db {
    pool: Pool,
    /// PostgreSQL only: connections whose commits do not wait for the disk
    /// (`synchronous_commit = off`), for the queue's writes whose loss in a database
    /// crash is harmless: claims and heartbeats (see `Db::try_claim` for why).
    lossy: Option<sqlx::PgPool>,
    /// PostgreSQL's notifications, fanned out in this process (None on SQLite).
    changes: Option<Arc<notify::Changes>>,
    /// When this process last settled dead workers' jobs (unix ms).
    last_settled: Arc<AtomicI64>,
}

impl Db {
    /// Opens and migrates the database at `url`: `sqlite://FILE` (created if missing) or
    /// `postgres://USER:PASSWORD@HOST/DB` (the database must exist).
    pub async fn open(url: &str) -> Result<Db, StoreError> {
        if url.starts_with("sqlite:") {
            Self::open_sqlite(url).await
        } else if url.starts_with("postgres://") || url.starts_with("postgresql://") {
            Self::open_postgres(url).await
        } else {
            Err(StoreError::UnsupportedUrl(redact_url(url)))
        }
    }

    async fn open_sqlite(url: &str) -> Result<Db, StoreError> {
        let options = SqliteConnectOptions::from_str(url)?
            .create_if_missing(true)
            // WAL lets readers (the API) work while a worker commits results.
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Normal)
            // Several processes (serve + worker) share the file: wait for the lock.
            .busy_timeout(Duration::from_secs(15))
            .foreign_keys(true);
        let pool = SqlitePoolOptions::new()
            .max_connections(8)
            .acquire_timeout(Duration::from_secs(30))
            .connect_with(options)
            .await?;
        SQLITE_MIGRATOR.run(&pool).await?;
        Ok(Db {
            pool: Pool::Sqlite(pool),
            lossy: None,
            changes: None,
            last_settled: Arc::default(),
        })
    }

    async fn open_postgres(url: &str) -> Result<Db, StoreError> {
        let options = PgConnectOptions::from_str(url)?.application_name("millsim");
        let pool = PgPoolOptions::new()
            .max_connections(16)
            .acquire_timeout(Duration::from_secs(30))
            .connect_with(options.clone())
            .await?;
        // Opened on first use: an API process that runs no workers opens none.
        let lossy = PgPoolOptions::new()
            .max_connections(4)
            .acquire_timeout(Duration::from_secs(30))
            .connect_lazy_with(options.options([("synchronous_commit", "off")]));
        // Whichever process starts first migrates; sqlx's migrator holds a PostgreSQL
        // advisory lock (pg_advisory_lock, keyed by the database name) from before it
        // reads the applied versions until it is done, so processes starting together
        // wait for each other instead of applying a migration twice.
        POSTGRES_MIGRATOR.run(&pool).await?;
        let changes = notify::listen(&pool).await?;
        Ok(Db {
            pool: Pool::Postgres(pool),
            lossy: Some(lossy),
            changes: Some(changes),
            last_settled: Arc::default(),
        })
    }

    pub fn backend(&self) -> Backend {
        self.pool.backend()
    }

    pub(crate) async fn begin(&self) -> Result<Tx, StoreError> {
        self.pool.begin().await
    }

    /// Where claims and heartbeats write: the lossy pool on PostgreSQL, the one pool
    /// on SQLite.
    fn queue_pool(&self) -> Pool {
        match &self.lossy {
            Some(p) => Pool::Postgres(p.clone()),
            None => self.pool.clone(),
        }
    }

    fn migrator(&self) -> &'static sqlx::migrate::Migrator {
        match self.backend() {
            Backend::Sqlite => &SQLITE_MIGRATOR,
            Backend::Postgres => &POSTGRES_MIGRATOR,
        }
    }

    /// True when the database answers and every embedded migration is applied.
    pub async fn ready(&self) -> Result<(), String> {
        let applied: Vec<i64> = on_pool!(&self.pool, p => sqlx::query_scalar(
            "SELECT version FROM _sqlx_migrations WHERE success"
        )
        .fetch_all(p)
        .await)
        .map_err(|e| format!("database unreachable: {e}"))?;
        for m in self.migrator().iter() {
            if !applied.contains(&m.version) {
                return Err(format!(
                    "migration {} ({}) not applied",
                    m.version, m.description
                ));
            }
        }
        Ok(())
    }

    /// Resolves when a job may have been queued by any process (PostgreSQL); never on
    /// SQLite, where idle workers poll.
    pub async fn job_queued(&self) {
        match &self.changes {
            Some(c) => c.queued.notified().await,
            None => std::future::pending().await,
        }
    }

    /// Follows one job's changes (for an event stream). Take it before reading the job,
    /// so no change between the read and the wait is missed.
    pub async fn watch_job(&self, id: &str) -> Result<JobWatch, StoreError> {
        let bus = match (&self.changes, &self.pool) {
            (Some(c), Pool::Postgres(p)) => Some((c.as_ref(), p)),
            _ => None,
        };
        JobWatch::new(id, bus).await
    }
}

/// A database URL without its password, for messages.
pub fn redact_url(url: &str) -> String {
    match (url.find("://"), url.rfind('@')) {
        (Some(scheme), Some(at)) if at > scheme => {
            let userinfo = &url[scheme + 3..at];
            let user = userinfo.split(':').next().unwrap_or("");
            format!("{}{user}:***{}", &url[..scheme + 3], &url[at..])
        }
        _ => url.to_string(),
    }
}

/// Milliseconds since the Unix epoch.
pub fn now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() as i64)
        .unwrap_or(0)
}

/// A new time-ordered id; its order is creation order, so ids double as cursors.
pub fn new_id() -> String {
    uuid::Uuid::now_v7().to_string()
}

/// Formats unix milliseconds as RFC 3339 UTC, e.g. 2026-11-21T10:33:00.123Z.
pub fn rfc3339(ms: i64) -> String {
    let secs = ms.div_euclid(1000);
    let millis = ms.rem_euclid(1000);
    let days = secs.div_euclid(86_400);
    let sod = secs.rem_euclid(86_400);
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{millis:03}Z",
        sod / 3600,
        (sod % 3600) / 60,
        sod % 60
    )
}

#[cfg(test)]
mod tests {
    use super::{redact_url as redact, rfc3339};

    #[test]
    fn redact_hides_the_password_only() {
        assert_eq!(
            redact("postgres://u:secret@h:5432/db"),
            "postgres://u:***@h:5432/db"
        );
        assert_eq!(redact("mysql://h/db"), "mysql://h/db");
    }

    #[test]
    fn rfc3339_matches_known_instants() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(rfc3339(951_782_400_000), "2000-02-29T00:00:00.000Z");
        // Epoch milliseconds from Python's datetime for 2026-11-21T10:13:00.123Z.
        assert_eq!(rfc3339(1_795_255_980_123), "2026-11-21T10:13:00.123Z");
    }
}
