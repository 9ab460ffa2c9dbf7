//! Files a job produced (the exported stock, the optimized program, a picture): stored
//! with the job's success, small ones in their row of `job_artifacts`, larger ones in 1 MiB
//! rows of `job_artifact_chunks` written by the uploads' chunk code, and read back for the
//! downloads.

use super::backend::{on_pool, on_tx, Tx};
use super::chunks::{chunk_count, write_chunks, ChunkKey, CHUNK_BYTES};
use super::{Db, StoreError};

/// A file a job produced, to store with its success.
pub struct Artifact {
    pub name: String,
    pub media_type: String,
    pub file_name: String,
    pub content: ArtifactContent,
}

/// Where a produced file's bytes are until they are stored.
pub enum ArtifactContent {
    /// In memory (small files, and jobs run on a thread of the worker).
    Bytes(Vec<u8>),
    /// A file the job wrote in its directory, `len` bytes: streamed into chunk rows at
    /// the commit, never whole in the worker's memory.
    File { path: std::path::PathBuf, len: u64 },
}

impl ArtifactContent {
    /// Bytes it stores.
    pub fn size(&self) -> u64 {
        match self {
            ArtifactContent::Bytes(b) => b.len() as u64,
            ArtifactContent::File { len, .. } => *len,
        }
    }
}

/// A stored artifact as the download reads it.
pub struct StoredArtifact {
    pub media_type: String,
    pub file_name: String,
    pub size: i64,
    pub body: ArtifactBody,
}

pub enum ArtifactBody {
    /// Small content, stored in the artifact's row.
    Inline(Vec<u8>),
    /// Large content, in `chunks` rows of `job_artifact_chunks` (see [`Db::chunk`]).
    Chunked { key: ChunkKey, chunks: i64 },
}

/// Stores one artifact of a job inside its success transaction: a small one in its row,
/// a larger one (in memory above a chunk, or written to a file) in chunk rows.
pub(super) async fn insert_artifact(
    tx: &mut Tx,
    job_id: &str,
    a: Artifact,
) -> Result<(), StoreError> {
    let len = a.content.size();
    let chunks = if len > CHUNK_BYTES as u64 {
        chunk_count(len)
    } else {
        0
    };
    let inline: &[u8] = match (&a.content, chunks) {
        (ArtifactContent::Bytes(b), 0) => b,
        _ => &[],
    };
    // A small file the job wrote is read whole: it is at most a chunk.
    let small_file = match (&a.content, chunks) {
        (ArtifactContent::File { path, .. }, 0) => Some(tokio::fs::read(path).await?),
        _ => None,
    };
    let inline = small_file.as_deref().unwrap_or(inline);
    if inline.len() as u64 != len && chunks == 0 {
        return Err(StoreError::Io(std::io::Error::other(format!(
            "the job's file {} has {} bytes, not the {len} it reported",
            a.name,
            inline.len()
        ))));
    }
    on_tx!(tx, c => sqlx::query("INSERT INTO job_artifacts (job_id, name, media_type, file_name, content, chunks, size) VALUES ($1, $2, $3, $4, $5, $6, $7)")
        .bind(job_id)
        .bind(&a.name)
        .bind(&a.media_type)
        .bind(&a.file_name)
        .bind(inline)
        .bind(chunks)
        .bind(len as i64)
        .execute(&mut *c)
        .await?
        .rows_affected());
    if chunks > 0 {
        let key = ChunkKey::Artifact {
            job_id: job_id.to_string(),
            name: a.name,
        };
        match a.content {
            ArtifactContent::Bytes(b) => {
                write_chunks(tx, &key, std::io::Cursor::new(b), len).await?;
            }
            ArtifactContent::File { path, .. } => {
                let file = std::fs::File::open(&path)?;
                write_chunks(tx, &key, file, len).await?;
            }
        }
    }
    Ok(())
}

impl Db {
    pub async fn job_artifact(
        &self,
        job_id: &str,
        name: &str,
    ) -> Result<Option<StoredArtifact>, StoreError> {
        type Row = (String, String, Vec<u8>, i64, i64);
        let row: Option<Row> = on_pool!(&self.pool, p => sqlx::query_as("SELECT media_type, file_name, content, chunks, size FROM job_artifacts WHERE job_id = $1 AND name = $2")
            .bind(job_id)
            .bind(name)
            .fetch_optional(p)
            .await?);
        Ok(row.map(
            |(media_type, file_name, content, chunks, size)| StoredArtifact {
                media_type,
                file_name,
                size,
                body: if chunks > 0 {
                    ArtifactBody::Chunked {
                        key: ChunkKey::Artifact {
                            job_id: job_id.to_string(),
                            name: name.to_string(),
                        },
                        chunks,
                    }
                } else {
                    ArtifactBody::Inline(content)
                },
            },
        ))
    }
}
