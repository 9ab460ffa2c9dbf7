//! The two databases behind the one store. Statements are written once, with `$N`
//! placeholders (SQLite reads them as PostgreSQL does), and `on_pool!` / `on_tx!` compile
//! each for both drivers. What differs is here, in one place: row locking for claims, the
//! JSON constructor and serializing one owner's submissions.

use sqlx::postgres::{PgRow, Postgres};
use sqlx::sqlite::{Sqlite, SqliteRow};

use super::StoreError;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    Sqlite,
    Postgres,
}

#[derive(Clone)]
pub enum Pool {
    Sqlite(sqlx::SqlitePool),
    Postgres(sqlx::PgPool),
}

/// An open transaction on either backend.
pub enum Tx {
    Sqlite(sqlx::Transaction<'static, Sqlite>),
    Postgres(sqlx::Transaction<'static, Postgres>),
}

/// `on_pool!(&pool, p => body)`: `body` runs with `p` the backend's pool (`&SqlitePool`
/// or `&PgPool`); the same source is compiled once per driver.
macro_rules! on_pool {
    ($pool:expr, $p:ident => $body:expr) => {
        match $pool {
            $crate::store::backend::Pool::Sqlite($p) => $body,
            $crate::store::backend::Pool::Postgres($p) => $body,
        }
    };
}

/// `on_tx!(&mut tx, c => body)`: `body` runs with `c` the transaction's connection
/// (use it as `&mut *c`).
macro_rules! on_tx {
    ($tx:expr, $c:ident => $body:expr) => {
        match &mut *$tx {
            $crate::store::backend::Tx::Sqlite(t) => {
                let $c = &mut **t;
                $body
            }
            $crate::store::backend::Tx::Postgres(t) => {
                let $c = &mut **t;
                $body
            }
        }
    };
}

pub(crate) use {on_pool, on_tx};

impl Pool {
    pub async fn begin(&self) -> Result<Tx, StoreError> {
        Ok(match self {
            Pool::Sqlite(p) => Tx::Sqlite(p.begin().await?),
            Pool::Postgres(p) => Tx::Postgres(p.begin().await?),
        })
    }

    pub fn backend(&self) -> Backend {
        match self {
            Pool::Sqlite(_) => Backend::Sqlite,
            Pool::Postgres(_) => Backend::Postgres,
        }
    }
}

impl Tx {
    /// Makes the transaction read one snapshot (PostgreSQL reads a new one per statement
    /// otherwise; a SQLite read transaction already does). Call before the first read.
    pub async fn read_one_snapshot(&mut self) -> Result<(), StoreError> {
        if let Tx::Postgres(t) = self {
            sqlx::query("SET TRANSACTION ISOLATION LEVEL REPEATABLE READ")
                .execute(&mut **t)
                .await?;
        }
        Ok(())
    }

    pub async fn commit(self) -> Result<(), StoreError> {
        match self {
            Tx::Sqlite(t) => t.commit().await?,
            Tx::Postgres(t) => t.commit().await?,
        }
        Ok(())
    }

    pub async fn rollback(self) -> Result<(), StoreError> {
        match self {
            Tx::Sqlite(t) => t.rollback().await?,
            Tx::Postgres(t) => t.rollback().await?,
        }
        Ok(())
    }

    pub fn backend(&self) -> Backend {
        match self {
            Tx::Sqlite(_) => Backend::Sqlite,
            Tx::Postgres(_) => Backend::Postgres,
        }
    }

    /// Serializes job submissions of one owner until this transaction ends, so the
    /// per-owner queue limit counted inside it cannot be raced. SQLite already runs one
    /// writer at a time; PostgreSQL takes a transaction-scoped advisory lock.
    pub async fn lock_owner_queue(&mut self, owner: &str) -> Result<(), StoreError> {
        if let Tx::Postgres(t) = self {
            sqlx::query(
                "SELECT pg_advisory_xact_lock(hashtextextended('millsim-queue:' || $1, 0))",
            )
            .bind(owner)
            .execute(&mut **t)
            .await?;
        }
        Ok(())
    }
}

impl Backend {
    /// Appended to the subquery that picks rows to claim: on PostgreSQL concurrent
    /// claimers skip each other's rows instead of waiting on them (or taking the same
    /// one); SQLite's single writer needs nothing.
    pub fn skip_locked(self) -> &'static str {
        match self {
            Backend::Sqlite => "",
            Backend::Postgres => " FOR UPDATE SKIP LOCKED",
        }
    }
}

/// Types a row column decodes to on both backends.
pub trait Column:
    Sized
    + for<'r> sqlx::Decode<'r, Sqlite>
    + sqlx::Type<Sqlite>
    + for<'r> sqlx::Decode<'r, Postgres>
    + sqlx::Type<Postgres>
{
}

impl<T> Column for T where
    T: Sized
        + for<'r> sqlx::Decode<'r, Sqlite>
        + sqlx::Type<Sqlite>
        + for<'r> sqlx::Decode<'r, Postgres>
        + sqlx::Type<Postgres>
{
}

/// A row of either backend, read by column name (for the record builders shared by both).
pub trait RowGet {
    fn col<T: Column>(&self, name: &str) -> Result<T, sqlx::Error>;
}

impl RowGet for SqliteRow {
    fn col<T: Column>(&self, name: &str) -> Result<T, sqlx::Error> {
        sqlx::Row::try_get(self, name)
    }
}

impl RowGet for PgRow {
    fn col<T: Column>(&self, name: &str) -> Result<T, sqlx::Error> {
        sqlx::Row::try_get(self, name)
    }
}
