//! A job's result rows and samples in and out of their group tables (`job_row_groups`,
//! `job_sample_groups`; the layout is `row_groups`'): written inside the job's success
//! transaction as multi-row INSERTs of whole groups, read back a few groups at a time.

use super::backend::{on_pool, on_tx, Pool, Tx};
use super::row_groups::{unpack, Group};
use super::StoreError;

/// Groups per INSERT statement (a few MB of compressed bytes).
const GROUPS_PER_INSERT: usize = 16;
/// Groups per read: a page of a few thousand rows takes one or two reads.
const GROUPS_PER_READ: i64 = 4;

/// Writes a job's groups in `table`. They are written once, with the job's success (only
/// the lease holder commits it), so there are none to replace.
pub async fn insert_groups(
    tx: &mut Tx,
    table: &str,
    job_id: &str,
    groups: &[Group],
) -> Result<(), StoreError> {
    for chunk in groups.chunks(GROUPS_PER_INSERT) {
        on_tx!(tx, c => {
            let mut q = sqlx::QueryBuilder::new(format!(
                "INSERT INTO {table} (job_id, last_seq, first_seq, codec, raw_bytes, data) "
            ));
            q.push_values(chunk, |mut b, g| {
                b.push_bind(job_id)
                    .push_bind(g.last_seq)
                    .push_bind(g.first_seq)
                    .push_bind(g.codec)
                    .push_bind(g.raw_bytes)
                    .push_bind(g.data.as_slice());
            });
            q.build().execute(&mut *c).await?;
        });
    }
    Ok(())
}

/// Up to `want` of job `job_id`'s rows in `table` with seq in `from..=to`, in seq order.
pub async fn read_rows(
    pool: &Pool,
    table: &str,
    job_id: &str,
    from: i64,
    to: i64,
    want: usize,
) -> Result<Vec<(i64, String)>, StoreError> {
    let mut out = Vec::new();
    let mut next = from;
    while out.len() < want && next <= to {
        // Groups never overlap, so in last_seq order they are in seq order, and the first
        // with last_seq >= next holds `next` or the first row after it (an index range scan).
        let groups: Vec<(i64, i64, String, i64, Vec<u8>)> = on_pool!(pool, p => sqlx::query_as(&format!(
            "SELECT last_seq, first_seq, codec, raw_bytes, data FROM {table}
             WHERE job_id = $1 AND last_seq >= $2 AND first_seq <= $3 ORDER BY last_seq LIMIT $4"
        ))
        .bind(job_id)
        .bind(next)
        .bind(to)
        .bind(GROUPS_PER_READ)
        .fetch_all(p)
        .await?);
        let Some(&(last, ..)) = groups.last() else {
            break;
        };
        let done = (groups.len() as i64) < GROUPS_PER_READ;
        // Decompression is CPU work: off the async threads.
        let rows = tokio::task::spawn_blocking(move || {
            let mut rows = Vec::new();
            for (_, first, codec, raw, data) in groups {
                rows.extend(unpack(&codec, first, raw, data)?);
            }
            Ok::<_, std::io::Error>(rows)
        })
        .await
        .map_err(std::io::Error::other)??;
        out.extend(
            rows.into_iter()
                .filter(|(seq, _)| (next..=to).contains(seq))
                .take(want - out.len()),
        );
        if done || last == i64::MAX {
            break;
        }
        next = last + 1;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use std::time::{Duration, Instant};

    use crate::store::jobs::Finish;
    use crate::store::scratch::{new_job, ScratchPostgres};
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

    /// Commits a claimed job's 100k-row result; returns how long the commit took.
    async fn commit_100k_rows(db: &Db) -> Duration {
        db.create_job("bench", new_job()).await.unwrap();
        let job = db.claim_job("w", 600_000).await.unwrap().unwrap();
        let rows: Vec<String> = (0..100_000).map(row).collect();
        let last = rows[99_999].clone();
        let started = Instant::now();
        let finish = Finish::Succeeded {
            summary: serde_json::json!({"rows": 100_000}),
            rows,
            // Every tenth row has its steps' samples, as force rows do.
            samples: (0..100_000)
                .step_by(10)
                .map(|s| (s, format!("[[{s}.5,1.25]]")))
                .collect(),
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
        // A page from the middle, across groups, in order and whole.
        let page = db.job_rows(&job.id, 41_234, 5000).await.unwrap();
        assert_eq!(page.len(), 5000);
        assert!(page
            .iter()
            .enumerate()
            .all(|(i, (seq, d))| *seq == 41_234 + i as i64 && *d == row(*seq as usize)));
        let samples = db.job_samples(&job.id, 49_990, 50_500).await.unwrap();
        let seqs: Vec<i64> = samples.iter().map(|s| s.0).collect();
        assert_eq!(
            seqs,
            (49_990..=50_500)
                .filter(|s| s % 10 == 0)
                .collect::<Vec<_>>()
        );
        assert!(samples
            .iter()
            .all(|(seq, d)| *d == format!("[[{seq}.5,1.25]]")));
        took
    }

    const OLD_ROWS: [&str; 3] = [r#"{"block":0,"é":"a"}"#, r#"{"block":1}"#, r#"{"block":2}"#];

    /// Rows and samples as one row each (before groups), for a database at that version.
    fn old_rows_statements() -> [String; 3] {
        [
            "INSERT INTO jobs (id, owner, kind, status, spec, max_attempts, created_at, updated_at, summary) VALUES ('old', '', 'interpret', 'succeeded', '{}', 3, 0, 0, '{}')".to_string(),
            format!("INSERT INTO job_rows (job_id, seq, data) VALUES ('old', 0, '{}'), ('old', 1, '{}'), ('old', 2, '{}')", OLD_ROWS[0], OLD_ROWS[1], OLD_ROWS[2]),
            "INSERT INTO job_samples (job_id, seq, data) VALUES ('old', 1, '[[1.5,2]]')".to_string(),
        ]
    }

    async fn old_rows_read_back(db: &Db) {
        let all = db.job_rows("old", 0, 10).await.unwrap();
        let want: Vec<(i64, String)> = OLD_ROWS
            .iter()
            .enumerate()
            .map(|(i, r)| (i as i64, r.to_string()))
            .collect();
        assert_eq!(all, want);
        assert_eq!(db.job_rows("old", 1, 1).await.unwrap(), want[1..2]);
        assert_eq!(
            db.job_samples("old", 0, 2).await.unwrap(),
            vec![(1, "[[1.5,2]]".to_string())]
        );
    }

    /// Leaves the database of connection `$c` (either driver) at `$backend`'s migrations up
    /// to `$last`, the last before groups, holding rows stored one by one; closes `$c`.
    macro_rules! migrate_before_groups_and_seed {
        ($c:ident, $backend:literal, $last:literal) => {
            crate::store::scratch::migrate_up_to!($c, $backend, $last);
            for q in old_rows_statements() {
                sqlx::query(&q).execute(&mut $c).await.unwrap();
            }
            $c.close().await.unwrap();
        };
    }

    /// A database whose rows were stored one by one keeps them when it is migrated to groups.
    #[tokio::test]
    async fn rows_stored_before_groups_read_back_after_the_migration() {
        let dir = tempfile::tempdir().unwrap();
        let url = format!("sqlite://{}", dir.path().join("old.db").display());
        {
            use sqlx::Connection;
            let mut c = crate::store::scratch::sqlite_connection(&url).await;
            migrate_before_groups_and_seed!(c, "sqlite", 7);
        }
        old_rows_read_back(&Db::open(&url).await.unwrap()).await;

        let Some(scratch) = ScratchPostgres::create().await else {
            return;
        };
        let url = scratch.url.clone();
        {
            use sqlx::Connection;
            let mut c = sqlx::PgConnection::connect(&url).await.unwrap();
            migrate_before_groups_and_seed!(c, "postgres", 4);
        }
        let pg = Db::open(&url).await.unwrap();
        old_rows_read_back(&pg).await;
        drop(pg);
        scratch.remove().await;
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
        assert!(sqlite_took < COMMIT_BOUND, "sqlite: {sqlite_took:?}");
        let Some(scratch) = ScratchPostgres::create().await else {
            return;
        };
        let pg = Db::open(&scratch.url).await.unwrap();
        let took = commit_100k_rows(&pg).await;
        println!("postgres: 100k rows committed in {took:?}");
        drop(pg);
        scratch.remove().await;
        assert!(took < COMMIT_BOUND, "postgres: {took:?}");
    }
}
