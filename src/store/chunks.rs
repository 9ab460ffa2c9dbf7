//! Resource content in chunks: a large upload (an STL stock or part of hundreds of
//! megabytes) is written and read back 1 MiB at a time, so neither the API nor a worker
//! holds the whole file to store or serve it.
//!
//! Why rows in the database rather than a blob store (files on a disk, an object
//! store): the database is the one thing every host already shares (workers on other
//! hosts have no common file system), a resource and its chunks commit or roll back
//! together (a failed upload leaves nothing behind, a DELETE cascades to its chunks),
//! and the same statements run on SQLite and PostgreSQL. A 1 MiB chunk is far below
//! either's limits (SQLite's 1 GB blob, PostgreSQL's TOASTed bytea) and large enough that
//! a 300 MB file is 300 statements.
//!
//! Files a job produces (the exported stock, the optimized program) are stored the same
//! way, in `job_artifact_chunks`, by the same code.

use std::io::Read;

use super::backend::{on_pool, on_tx, Tx};
use super::resources::{insert_row, read_back, NewResource, ResourceRecord};
use super::{Db, StoreError};

/// The largest chunk stored.
pub const CHUNK_BYTES: usize = 1 << 20;

/// What a resource's content is read from.
pub enum ResourceBody {
    /// Small content, stored in the resource's row.
    Inline(Vec<u8>),
    /// Large content, in `chunks` rows of `resource_chunks` (see [`Db::resource_chunk`]).
    Chunked { id: String, chunks: i64 },
}

/// Reads up to `buf.len()` bytes (fewer only at the end of the file).
fn fill(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// Whose chunks: a resource's (an upload) or a job's artifact (a file it produced).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ChunkKey {
    Resource { id: String },
    Artifact { job_id: String, name: String },
}

/// Writes `len` bytes of `content` (from its current position) as chunk rows of `key`,
/// inside the caller's transaction: they commit or roll back with the row that counts
/// them. Only one chunk is in memory at a time, and it is read on a blocking thread (a
/// cold file on a slow disk must not stall the runtime). Returns the number of chunks.
pub async fn write_chunks<R: Read + Send + 'static>(
    tx: &mut Tx,
    key: &ChunkKey,
    content: R,
    len: u64,
) -> Result<i64, StoreError> {
    let chunks = chunk_count(len);
    let mut file = Some(content);
    let mut written = 0u64;
    for seq in 0..chunks {
        let f = file
            .take()
            .expect("the file is handed back after each read");
        let (f, buf) = tokio::task::spawn_blocking(move || {
            let mut f = f;
            let mut buf = vec![0u8; CHUNK_BYTES];
            let n = fill(&mut f, &mut buf)?;
            buf.truncate(n);
            Ok::<_, std::io::Error>((f, buf))
        })
        .await
        .map_err(|e| StoreError::Io(std::io::Error::other(e)))??;
        file = Some(f);
        if buf.is_empty() {
            return Err(StoreError::Io(std::io::Error::other(format!(
                "the file ended after {written} of {len} bytes"
            ))));
        }
        written += buf.len() as u64;
        insert_chunk(tx, key, seq, &buf).await?;
    }
    Ok(chunks)
}

/// Writes `content` as chunk rows of `key` inside the caller's transaction (content
/// already in memory: a program or tool library upload, a job's inline program).
pub async fn write_slice_chunks(
    tx: &mut Tx,
    key: &ChunkKey,
    content: &[u8],
) -> Result<i64, StoreError> {
    let mut chunks = 0;
    for (seq, buf) in content.chunks(CHUNK_BYTES).enumerate() {
        insert_chunk(tx, key, seq as i64, buf).await?;
        chunks += 1;
    }
    Ok(chunks)
}

/// One chunk row.
async fn insert_chunk(tx: &mut Tx, key: &ChunkKey, seq: i64, buf: &[u8]) -> Result<(), StoreError> {
    match key {
        ChunkKey::Resource { id } => on_tx!(tx, c => sqlx::query(
            "INSERT INTO resource_chunks (resource_id, seq, data) VALUES ($1, $2, $3)",
        )
        .bind(id)
        .bind(seq)
        .bind(buf)
        .execute(&mut *c)
        .await?
        .rows_affected()),
        ChunkKey::Artifact { job_id, name } => on_tx!(tx, c => sqlx::query(
            "INSERT INTO job_artifact_chunks (job_id, name, seq, data) VALUES ($1, $2, $3, $4)",
        )
        .bind(job_id)
        .bind(name)
        .bind(seq)
        .bind(buf)
        .execute(&mut *c)
        .await?
        .rows_affected()),
    };
    Ok(())
}

/// Chunks of `len` bytes.
pub fn chunk_count(len: u64) -> i64 {
    len.div_ceil(CHUNK_BYTES as u64) as i64
}

impl Db {
    /// Stores a resource whose content is the file `content` (`len` bytes, read from its
    /// current position; `new.content` is not used), in chunks, in one transaction.
    /// The file is local (a spooled upload), so the transaction lasts as long as the disk
    /// takes, not as long as the client.
    pub async fn create_resource_chunked(
        &self,
        owner: &str,
        new: &NewResource<'_>,
        content: std::fs::File,
        len: u64,
    ) -> Result<ResourceRecord, StoreError> {
        let id = super::new_id();
        let mut tx = self.begin().await?;
        insert_row(&mut tx, &id, owner, new, len as i64, chunk_count(len)).await?;
        let key = ChunkKey::Resource { id: id.clone() };
        write_chunks(&mut tx, &key, content, len).await?;
        let created = read_back(&mut tx, owner, new.kind, &id).await?;
        tx.commit().await?;
        Ok(created)
    }

    /// Chunk `seq` (from 0) of a chunked resource; None when it is not there (the
    /// resource was deleted).
    pub async fn resource_chunk(&self, id: &str, seq: i64) -> Result<Option<Vec<u8>>, StoreError> {
        self.chunk(&ChunkKey::Resource { id: id.to_string() }, seq)
            .await
    }

    /// Chunk `seq` (from 0) of `key`; None when it is not there (its owner was deleted).
    pub async fn chunk(&self, key: &ChunkKey, seq: i64) -> Result<Option<Vec<u8>>, StoreError> {
        Ok(match key {
            ChunkKey::Resource { id } => on_pool!(&self.pool, p => sqlx::query_scalar(
                "SELECT data FROM resource_chunks WHERE resource_id = $1 AND seq = $2",
            )
            .bind(id)
            .bind(seq)
            .fetch_optional(p)
            .await?),
            ChunkKey::Artifact { job_id, name } => on_pool!(&self.pool, p => sqlx::query_scalar(
                "SELECT data FROM job_artifact_chunks WHERE job_id = $1 AND name = $2 AND seq = $3",
            )
            .bind(job_id)
            .bind(name)
            .bind(seq)
            .fetch_optional(p)
            .await?),
        })
    }
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use crate::store::scratch::{migrate_up_to, sqlite_connection};
    use crate::store::ResourceKind;

    use super::ResourceBody;

    /// A program stored whole in its row, as before programs were chunked.
    macro_rules! seed_row_content {
        ($c:ident, $backend:literal, $last:literal, $id:expr, $content:expr) => {
            migrate_up_to!($c, $backend, $last);
            let content: &[u8] = $content;
            sqlx::query(
                "INSERT INTO resources (id, owner, kind, name, media_type, size, summary, content, created_at)
                 VALUES ($1, 'o', 'program', 'a.nc', 'text/plain', $2, '{}', $3, 0)",
            )
            .bind($id)
            .bind(content.len() as i64)
            .bind(content)
            .execute(&mut $c)
            .await
            .unwrap();
        };
    }

    async fn moved_into_chunks(db: &Db, big: &[u8], small: &[u8]) {
        let body = db
            .resource_body("o", ResourceKind::Program, "big")
            .await
            .unwrap();
        assert!(matches!(
            body.unwrap().3,
            ResourceBody::Chunked { chunks: 4, .. }
        ));
        let (_, _, read) = db
            .resource_content("o", ResourceKind::Program, "big")
            .await
            .unwrap()
            .unwrap();
        assert!(read == big, "the content changed");
        let body = db
            .resource_body("o", ResourceKind::Program, "small")
            .await
            .unwrap();
        assert!(matches!(body.unwrap().3, ResourceBody::Inline(b) if b == small));
    }

    /// Content over a chunk that an older version stored in its row (a 64 MB program was
    /// read whole by every GET) is moved into chunk rows by the migration and reads back
    /// byte for byte; content of a chunk or less stays in its row.
    #[tokio::test]
    async fn large_content_in_a_row_is_moved_into_chunks() {
        use sqlx::Connection;
        let big: Vec<u8> = (0..(3 << 20) + 12_345u32)
            .map(|i| (i * 7 % 251) as u8)
            .collect();
        let small = b"G0 X1\n".to_vec();
        let dir = tempfile::tempdir().unwrap();
        let url = format!("sqlite://{}", dir.path().join("old.db").display());
        {
            let mut c = sqlite_connection(&url).await;
            seed_row_content!(c, "sqlite", 11, "big", &big);
            seed_row_content!(c, "sqlite", 11, "small", &small);
            c.close().await.unwrap();
        }
        moved_into_chunks(&Db::open(&url).await.unwrap(), &big, &small).await;

        let Some(scratch) = ScratchPostgres::create().await else {
            return;
        };
        {
            let mut c = sqlx::PgConnection::connect(&scratch.url).await.unwrap();
            seed_row_content!(c, "postgres", 8, "big", &big);
            seed_row_content!(c, "postgres", 8, "small", &small);
            c.close().await.unwrap();
        }
        let pg = Db::open(&scratch.url).await.unwrap();
        moved_into_chunks(&pg, &big, &small).await;
        drop(pg);
        scratch.remove().await;
    }

    use crate::store::artifacts::{Artifact, ArtifactBody, ArtifactContent};
    use crate::store::jobs::Finish;
    use crate::store::scratch::{new_job, ScratchPostgres};
    use crate::store::Db;

    use super::ChunkKey;

    async fn artifact_chunk_rows(db: &Db) -> i64 {
        crate::store::backend::on_pool!(&db.pool, p => sqlx::query_scalar::<_, i64>(
            "SELECT COUNT(*) FROM job_artifact_chunks",
        )
        .fetch_one(p)
        .await
        .unwrap())
    }

    fn success(file: &std::path::Path, len: u64) -> Finish {
        Finish::Succeeded {
            summary: serde_json::json!({}),
            rows: vec!["{}".into()],
            samples: Vec::new(),
            artifacts: vec![Artifact {
                name: "stock.stl".into(),
                media_type: "model/stl".into(),
                file_name: "a.stock.stl".into(),
                content: ArtifactContent::File {
                    path: file.to_path_buf(),
                    len,
                },
            }],
            resources: Vec::new(),
            progress: (1, 1),
        }
    }

    /// A worker whose lease expired and was taken over commits nothing, not even the
    /// chunks of its file (they are written after the lease check, in its transaction);
    /// the worker holding the job stores them once, and they read back byte for byte.
    async fn lost_lease_leaves_no_chunks(db: &Db) {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("stock.stl");
        let content: Vec<u8> = (0..(3 << 20) + 12_345u32)
            .map(|i| (i * 7 % 251) as u8)
            .collect();
        std::fs::File::create(&file)
            .unwrap()
            .write_all(&content)
            .unwrap();
        let len = content.len() as u64;
        db.create_job("o", new_job()).await.unwrap();
        let first = db.claim_job("w1", 50).await.unwrap().unwrap();
        tokio::time::sleep(std::time::Duration::from_millis(120)).await;
        let second = db.claim_job("w2", 60_000).await.unwrap().unwrap();
        assert_eq!((second.id.as_str(), second.attempt), (first.id.as_str(), 2));

        let now = crate::store::now_ms();
        let late = db
            .finish_job(&first, "w1", success(&file, len), now)
            .await
            .unwrap();
        assert!(!late, "the first worker lost its lease");
        assert_eq!(
            artifact_chunk_rows(db).await,
            0,
            "no chunk of a lost attempt"
        );

        assert!(db
            .finish_job(&second, "w2", success(&file, len), now)
            .await
            .unwrap());
        assert_eq!(artifact_chunk_rows(db).await, 4);
        let stored = db
            .job_artifact(&first.id, "stock.stl")
            .await
            .unwrap()
            .unwrap();
        assert_eq!(stored.size as u64, len);
        let ArtifactBody::Chunked { key, chunks } = stored.body else {
            panic!("a file over a chunk is stored in chunks");
        };
        assert_eq!(
            key,
            ChunkKey::Artifact {
                job_id: first.id.clone(),
                name: "stock.stl".into()
            }
        );
        let mut back = Vec::new();
        for seq in 0..chunks {
            back.extend(db.chunk(&key, seq).await.unwrap().unwrap());
        }
        assert!(back == content, "the chunks read back as the file");
    }

    #[tokio::test]
    async fn an_attempt_whose_lease_was_lost_leaves_no_chunks() {
        let dir = tempfile::tempdir().unwrap();
        let sqlite = Db::open(&format!("sqlite://{}", dir.path().join("c.db").display()))
            .await
            .unwrap();
        lost_lease_leaves_no_chunks(&sqlite).await;
        let Some(scratch) = ScratchPostgres::create().await else {
            return;
        };
        let pg = Db::open(&scratch.url).await.unwrap();
        lost_lease_leaves_no_chunks(&pg).await;
        drop(pg);
        scratch.remove().await;
    }
}
