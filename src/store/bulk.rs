//! Per-block result rows written in bulk, inside the job's success transaction: SQLite
//! takes multi-row INSERTs, PostgreSQL a binary COPY above a few hundred rows (one stream
//! instead of a statement per chunk).

use super::backend::{on_tx, Tx};
use super::StoreError;

/// Up to this many rows, PostgreSQL gets an INSERT too.
const COPY_FROM_ROWS: usize = 400;
/// How much COPY text is buffered before it is sent.
const COPY_CHUNK_BYTES: usize = 1 << 20;

/// Writes a job's rows in `table` (job_id, seq, data). Rows are written once, with the
/// job's success (only the lease holder commits it), so there are none to replace.
pub async fn insert_rows(
    tx: &mut Tx,
    table: &str,
    job_id: &str,
    items: &[(usize, String)],
) -> Result<(), StoreError> {
    match tx {
        Tx::Postgres(t) if items.len() > COPY_FROM_ROWS => {
            // Binary COPY: the JSON goes as it is, with no escaping on our side and no
            // text parsing on the server's (the text format escaped every backslash of
            // the JSON's own escapes, a character at a time).
            let mut copy = t
                .copy_in_raw(&format!(
                    "COPY {table} (job_id, seq, data) FROM STDIN (FORMAT binary)"
                ))
                .await?;
            let mut buf = Vec::with_capacity(COPY_CHUNK_BYTES + 4096);
            buf.extend_from_slice(b"PGCOPY\n\xff\r\n\0");
            buf.extend_from_slice(&0i32.to_be_bytes()); // flags
            buf.extend_from_slice(&0i32.to_be_bytes()); // header extension length
            for (seq, data) in items {
                buf.extend_from_slice(&3i16.to_be_bytes());
                push_field(&mut buf, job_id.as_bytes());
                push_field(&mut buf, &(*seq as i64).to_be_bytes());
                push_field(&mut buf, data.as_bytes());
                if buf.len() >= COPY_CHUNK_BYTES {
                    copy.send(buf.as_slice()).await?;
                    buf.clear();
                }
            }
            buf.extend_from_slice(&(-1i16).to_be_bytes()); // trailer
            copy.send(buf.as_slice()).await?;
            copy.finish().await?;
        }
        // SQLite, and a few rows on PostgreSQL (most jobs: one round trip, where a COPY
        // takes three): one multi-row INSERT per 400 rows instead of one per row.
        _ => {
            for chunk in items.chunks(400) {
                on_tx!(tx, c => {
                    let mut q =
                        sqlx::QueryBuilder::new(format!("INSERT INTO {table} (job_id, seq, data) "));
                    q.push_values(chunk, |mut b, (seq, data)| {
                        b.push_bind(job_id).push_bind(*seq as i64).push_bind(data);
                    });
                    q.build().execute(&mut *c).await?;
                });
            }
        }
    }
    Ok(())
}

/// One field of a binary COPY tuple: its length, then its bytes (a text column's are
/// its UTF-8, a bigint's its 8 bytes big-endian).
fn push_field(buf: &mut Vec<u8>, bytes: &[u8]) {
    buf.extend_from_slice(&(bytes.len() as i32).to_be_bytes());
    buf.extend_from_slice(bytes);
}

#[cfg(test)]
mod tests {
    use std::time::{Duration, Instant};

    use crate::store::jobs::{Finish, NewJob};
    use crate::store::Db;

    /// A result row the size of a simulate job's (about 700 bytes of JSON).
    fn row(i: usize) -> String {
        let mut o = serde_json::Map::new();
        o.insert("block".into(), i.into());
        o.insert("line".into(), (i + 15).into());
        o.insert(
            "flags".into(),
            serde_json::json!(["air", "a \"quoted\"\tnote"]),
        );
        for k in 0..30 {
            o.insert(
                format!("field_{k:02}_mm"),
                (i as f64 * 1.000_123 + f64::from(k)).into(),
            );
        }
        serde_json::Value::Object(o).to_string()
    }

    async fn admin(url: &str, statement: &str) {
        use sqlx::Connection;
        let mut c = sqlx::PgConnection::connect(url).await.unwrap();
        sqlx::query(statement).execute(&mut c).await.unwrap();
    }

    /// Commits a claimed job's 100k-row result; returns how long the commit took.
    async fn commit_100k_rows(db: &Db) -> Duration {
        let new = NewJob {
            kind: "simulate".into(),
            inputs: serde_json::Map::new(),
            inline: Vec::new(),
            options: serde_json::json!({}),
            idempotency_key: None,
            request_hash: String::new(),
            max_attempts: 3,
            max_queued: 10,
        };
        db.create_job("bench", new).await.unwrap();
        let job = db.claim_job("w", 600_000).await.unwrap().unwrap();
        let rows: Vec<String> = (0..100_000).map(row).collect();
        let last = rows[99_999].clone();
        let started = Instant::now();
        let finish = Finish::Succeeded {
            summary: serde_json::json!({"rows": 100_000}),
            rows,
            samples: Vec::new(),
            artifacts: Vec::new(),
            resources: Vec::new(),
            progress: (100_000, 100_000),
        };
        assert!(db
            .finish_job(&job, "w", finish, crate::store::now_ms())
            .await
            .unwrap());
        let took = started.elapsed();
        let page = db.job_rows(&job.id, 99_998, 10).await.unwrap();
        assert_eq!(page.len(), 2);
        assert_eq!(page[1], (99_999, last), "the row reads back as written");
        took
    }

    /// What the test holds the commit to (the figures are printed): room for a busy
    /// 2-core CI machine, yet a row-at-a-time write (tens of seconds) fails it.
    const COMMIT_BOUND: Duration = Duration::from_secs(10);

    #[tokio::test]
    async fn a_100k_row_result_commits_in_bulk() {
        let dir = tempfile::tempdir().unwrap();
        let sqlite = Db::open(&format!("sqlite://{}", dir.path().join("b.db").display()))
            .await
            .unwrap();
        let took = commit_100k_rows(&sqlite).await;
        println!("sqlite: 100k rows committed in {took:?}");
        let sqlite_took = took;
        let Some(base) = std::env::var("MILLSIM_TEST_DATABASE")
            .ok()
            .filter(|u| u.starts_with("postgres"))
        else {
            println!("postgres part skipped: MILLSIM_TEST_DATABASE names no PostgreSQL server");
            assert!(sqlite_took < COMMIT_BOUND, "sqlite: {sqlite_took:?}");
            return;
        };
        let name = format!("millsim_unit_{}", uuid::Uuid::new_v4().simple());
        let (server, _) = base.rsplit_once('/').unwrap();
        admin(&base, &format!("CREATE DATABASE {name}")).await;
        let pg = Db::open(&format!("{server}/{name}")).await.unwrap();
        let took = commit_100k_rows(&pg).await;
        println!("postgres: 100k rows committed in {took:?}");
        drop(pg);
        admin(&base, &format!("DROP DATABASE {name} WITH (FORCE)")).await;
        assert!(took < COMMIT_BOUND, "postgres: {took:?}");
        assert!(sqlite_took < COMMIT_BOUND, "sqlite: {sqlite_took:?}");
    }
}
