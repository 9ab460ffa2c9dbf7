//! Databases for the store's unit tests that run on both backends: where
//! MILLSIM_TEST_DATABASE names a PostgreSQL server, a database of the test's own created
//! there and dropped after it.

use super::jobs::NewJob;

/// A database created on the test server for one test.
pub struct ScratchPostgres {
    admin: String,
    name: String,
    pub url: String,
}

impl ScratchPostgres {
    /// None, after saying so, when MILLSIM_TEST_DATABASE names no PostgreSQL server.
    pub async fn create() -> Option<ScratchPostgres> {
        let Some(admin) = std::env::var("MILLSIM_TEST_DATABASE")
            .ok()
            .filter(|u| u.starts_with("postgres"))
        else {
            println!("postgres part skipped: MILLSIM_TEST_DATABASE names no PostgreSQL server");
            return None;
        };
        let name = format!("millsim_unit_{}", uuid::Uuid::new_v4().simple());
        let (server, _) = admin.rsplit_once('/').expect("a database URL");
        let url = format!("{server}/{name}");
        execute(&admin, &format!("CREATE DATABASE {name}")).await;
        Some(ScratchPostgres { admin, name, url })
    }

    /// Drops the database, closing what is still connected to it.
    pub async fn remove(self) {
        execute(
            &self.admin,
            &format!("DROP DATABASE {} WITH (FORCE)", self.name),
        )
        .await;
    }
}

async fn execute(url: &str, statement: &str) {
    use sqlx::Connection;
    let mut c = sqlx::PgConnection::connect(url).await.unwrap();
    sqlx::query(statement).execute(&mut c).await.unwrap();
}

/// A simulate job with nothing in it, which the store takes as it is.
pub fn new_job() -> NewJob {
    NewJob {
        kind: "simulate".into(),
        inputs: serde_json::Map::new(),
        inline: Vec::new(),
        options: serde_json::json!({}),
        idempotency_key: None,
        request_hash: String::new(),
        max_attempts: 3,
        max_queued: 10,
    }
}

/// The migrations of `backend` (a folder under migrations/) up to version `last`, copied
/// to a folder of their own so that a database can be left at that version (to test what
/// a later migration does to what it holds).
pub fn migrations_up_to(backend: &str, last: i64) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("migrations")
        .join(backend);
    for e in std::fs::read_dir(src).unwrap() {
        let e = e.unwrap();
        let name = e.file_name().into_string().unwrap();
        let version: i64 = name[..4].parse().unwrap();
        if version <= last {
            std::fs::copy(e.path(), dir.path().join(name)).unwrap();
        }
    }
    dir
}

/// Leaves the database of connection `$c` (either driver) at `$backend`'s migrations up
/// to version `$last` (see [`migrations_up_to`]).
macro_rules! migrate_up_to {
    ($c:ident, $backend:literal, $last:literal) => {
        let old = $crate::store::scratch::migrations_up_to($backend, $last);
        sqlx::migrate::Migrator::new(old.path())
            .await
            .unwrap()
            .run(&mut $c)
            .await
            .unwrap();
    };
}
pub(crate) use migrate_up_to;

/// A connection to the SQLite database at `url`, created if missing (to leave it at an
/// older version with [`migrate_up_to`]).
pub async fn sqlite_connection(url: &str) -> sqlx::SqliteConnection {
    use sqlx::Connection;
    let opts: sqlx::sqlite::SqliteConnectOptions = url.parse().unwrap();
    sqlx::SqliteConnection::connect_with(&opts.create_if_missing(true))
        .await
        .unwrap()
}
