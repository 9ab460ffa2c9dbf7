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

use std::io::Read;

use super::backend::{on_pool, on_tx};
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

impl Db {
    /// Stores a resource whose content is the file `content` (`len` bytes, read from its
    /// current position; `new.content` is not used), in chunks, in one transaction.
    /// Only one chunk is in memory at a time. The file is local (a spooled upload), so
    /// the transaction lasts as long as the disk takes, not as long as the client.
    pub async fn create_resource_chunked(
        &self,
        owner: &str,
        new: &NewResource<'_>,
        content: std::fs::File,
        len: u64,
    ) -> Result<ResourceRecord, StoreError> {
        let chunks = len.div_ceil(CHUNK_BYTES as u64) as i64;
        let id = super::new_id();
        let mut tx = self.begin().await?;
        insert_row(&mut tx, &id, owner, new, len as i64, chunks).await?;
        let mut file = Some(content);
        let mut written = 0u64;
        for seq in 0..chunks {
            // Read on a blocking thread: a cold file on a slow disk must not stall the
            // runtime.
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
                    "the upload's file ended after {written} of {len} bytes"
                ))));
            }
            written += buf.len() as u64;
            on_tx!(&mut tx, c => sqlx::query(
                "INSERT INTO resource_chunks (resource_id, seq, data) VALUES ($1, $2, $3)",
            )
            .bind(&id)
            .bind(seq)
            .bind(&buf)
            .execute(&mut *c)
            .await?
            .rows_affected());
        }
        let created = read_back(&mut tx, owner, new.kind, &id).await?;
        tx.commit().await?;
        Ok(created)
    }

    /// Chunk `seq` (from 0) of a chunked resource; None when it is not there (the
    /// resource was deleted).
    pub async fn resource_chunk(&self, id: &str, seq: i64) -> Result<Option<Vec<u8>>, StoreError> {
        Ok(on_pool!(&self.pool, p => sqlx::query_scalar(
            "SELECT data FROM resource_chunks WHERE resource_id = $1 AND seq = $2",
        )
        .bind(id)
        .bind(seq)
        .fetch_optional(p)
        .await?))
    }
}
