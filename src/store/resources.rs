//! Uploaded inputs: stocks, tools, materials, machines, programs, tool libraries.

use serde::{Deserialize, Serialize};

use super::backend::{on_pool, on_tx, RowGet, Tx};
use super::chunks::{chunk_count, write_slice_chunks, ChunkKey, ResourceBody, CHUNK_BYTES};
use super::{rfc3339, Db, StoreError};

/// Serialized as [`as_str`](Self::as_str) names it (a job's process sends the kind of a
/// resource it made to the server).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ResourceKind {
    Stock,
    Tool,
    Material,
    Machine,
    Program,
    ToolLibrary,
}

impl ResourceKind {
    pub const ALL: [ResourceKind; 6] = [
        ResourceKind::Stock,
        ResourceKind::Tool,
        ResourceKind::Material,
        ResourceKind::Machine,
        ResourceKind::Program,
        ResourceKind::ToolLibrary,
    ];

    pub fn as_str(self) -> &'static str {
        // The serde names (snake_case) are these: a test checks them.
        match self {
            ResourceKind::Stock => "stock",
            ResourceKind::Tool => "tool",
            ResourceKind::Material => "material",
            ResourceKind::Machine => "machine",
            ResourceKind::Program => "program",
            ResourceKind::ToolLibrary => "tool_library",
        }
    }

    /// The collection's path segment under /v1.
    pub fn collection(self) -> &'static str {
        match self {
            ResourceKind::Stock => "stocks",
            ResourceKind::Tool => "tools",
            ResourceKind::Material => "materials",
            ResourceKind::Machine => "machines",
            ResourceKind::Program => "programs",
            ResourceKind::ToolLibrary => "tool-libraries",
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct ResourceRecord {
    pub id: String,
    pub kind: &'static str,
    pub name: Option<String>,
    pub media_type: String,
    pub size: i64,
    pub created_at: String,
    /// What validation found: block count, triangle count, bounding box, ...
    pub summary: serde_json::Value,
    /// JSON resources (tool, material, machine, parametric stock) carry their definition.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub definition: Option<serde_json::Value>,
}

pub struct NewResource<'a> {
    pub kind: ResourceKind,
    pub name: Option<&'a str>,
    pub media_type: &'a str,
    pub summary: serde_json::Value,
    pub content: &'a [u8],
    /// The JSON object whose members the resource's GET adds to its record (a tool
    /// library's tools and report), stored beside it (`resource_views`).
    pub view: Option<&'a str>,
}

/// The columns of a resource's record: all but its content, which may be 64 MB.
const RECORD_COLUMNS: &str = "id, kind, name, media_type, size, summary, created_at";

/// A record from a row of [`RECORD_COLUMNS`], without its definition (see [`with_definition`]).
fn record(kind: ResourceKind, row: &impl RowGet) -> Result<ResourceRecord, StoreError> {
    Ok(ResourceRecord {
        id: row.col("id")?,
        kind: kind.as_str(),
        name: row.col("name")?,
        media_type: row.col("media_type")?,
        size: row.col("size")?,
        created_at: rfc3339(row.col("created_at")?),
        summary: serde_json::from_str(&row.col::<String>("summary")?)?,
        definition: None,
    })
}

/// Whether a record carries its content as its definition: the JSON resources (tool,
/// material, machine, parametric stock), whose bodies are at most `--max-json-bytes`. A
/// tool library's JSON is Fusion's file, not a definition in the API's terms: its tools
/// are served read, by T number, instead.
fn has_definition(r: &ResourceRecord) -> bool {
    r.media_type == "application/json" && !matches!(r.kind, "tool_library" | "program")
}

/// The content of a JSON resource as its definition, read in `c`'s transaction or pool.
macro_rules! with_definition {
    ($exec:expr, $record:expr) => {{
        let mut r: ResourceRecord = $record;
        if has_definition(&r) {
            let content: Vec<u8> =
                sqlx::query_scalar("SELECT content FROM resources WHERE id = $1")
                    .bind(&r.id)
                    .fetch_one($exec)
                    .await?;
            r.definition = Some(serde_json::from_slice(&content)?);
        }
        r
    }};
}

/// Inserts a resource inside an open transaction.
pub async fn insert(tx: &mut Tx, owner: &str, new: &NewResource<'_>) -> Result<String, StoreError> {
    let id = super::new_id();
    insert_with_id(tx, &id, owner, new).await?;
    Ok(id)
}

/// [`insert`] with an id chosen beforehand (a job names the resource it makes in its
/// summary before the resource is stored).
pub async fn insert_with_id(
    tx: &mut Tx,
    id: &str,
    owner: &str,
    new: &NewResource<'_>,
) -> Result<(), StoreError> {
    let len = new.content.len();
    if len <= CHUNK_BYTES {
        return insert_row(tx, id, owner, new, len as i64, 0).await;
    }
    // Over a chunk (a program or tool library of up to 64 MB): in chunk rows, as a
    // streamed upload is, so that its GET and the jobs read it a chunk at a time.
    insert_row(tx, id, owner, new, len as i64, chunk_count(len as u64)).await?;
    let key = ChunkKey::Resource { id: id.to_string() };
    write_slice_chunks(tx, &key, new.content).await?;
    Ok(())
}

/// The resource's row: with `new.content` when `chunks` is 0, else with no content in
/// the row and `size` bytes in `chunks` chunk rows written next (see `chunks`).
pub(super) async fn insert_row(
    tx: &mut Tx,
    id: &str,
    owner: &str,
    new: &NewResource<'_>,
    size: i64,
    chunks: i64,
) -> Result<(), StoreError> {
    let inline: &[u8] = if chunks == 0 { new.content } else { &[] };
    on_tx!(tx, c => sqlx::query(
        "INSERT INTO resources (id, owner, kind, name, media_type, size, summary, content, created_at, chunks)
         VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10)",
    )
    .bind(id)
    .bind(owner)
    .bind(new.kind.as_str())
    .bind(new.name)
    .bind(new.media_type)
    .bind(size)
    .bind(new.summary.to_string())
    .bind(inline)
    .bind(super::now_ms())
    .bind(chunks)
    .execute(&mut *c)
    .await?
    .rows_affected());
    if let Some(view) = new.view {
        insert_view(tx, id, view).await?;
    }
    Ok(())
}

/// Stores a resource's view (see [`NewResource::view`]); a view already there stays (two
/// first GETs of an old library may both write it: it is the same).
async fn insert_view(tx: &mut Tx, id: &str, view: &str) -> Result<(), StoreError> {
    on_tx!(tx, c => sqlx::query(
        "INSERT INTO resource_views (resource_id, members) VALUES ($1, $2) ON CONFLICT (resource_id) DO NOTHING",
    )
    .bind(id)
    .bind(view)
    .execute(&mut *c)
    .await?
    .rows_affected());
    Ok(())
}

/// The record of a resource just inserted, read in the insert's transaction: once
/// committed, a DELETE may come first.
pub(super) async fn read_back(
    tx: &mut Tx,
    owner: &str,
    kind: ResourceKind,
    id: &str,
) -> Result<ResourceRecord, StoreError> {
    Ok(on_tx!(tx, c => {
        let row = sqlx::query(&format!("SELECT {RECORD_COLUMNS} FROM resources WHERE owner = $1 AND kind = $2 AND id = $3"))
            .bind(owner)
            .bind(kind.as_str())
            .bind(id)
            .fetch_optional(&mut *c)
            .await?
            .ok_or_else(|| StoreError::Vanished(format!("{} {id}", kind.as_str())))?;
        with_definition!(&mut *c, record(kind, &row)?)
    }))
}

impl Db {
    pub async fn create_resource(
        &self,
        owner: &str,
        new: &NewResource<'_>,
    ) -> Result<ResourceRecord, StoreError> {
        let mut tx = self.begin().await?;
        let id = insert(&mut tx, owner, new).await?;
        let created = read_back(&mut tx, owner, new.kind, &id).await?;
        tx.commit().await?;
        Ok(created)
    }

    pub async fn get_resource(
        &self,
        owner: &str,
        kind: ResourceKind,
        id: &str,
    ) -> Result<Option<ResourceRecord>, StoreError> {
        Ok(on_pool!(&self.pool, p => {
            let row = sqlx::query(&format!("SELECT {RECORD_COLUMNS} FROM resources WHERE owner = $1 AND kind = $2 AND id = $3"))
                .bind(owner)
                .bind(kind.as_str())
                .bind(id)
                .fetch_optional(p)
                .await?;
            match row {
                Some(row) => Some(with_definition!(p, record(kind, &row)?)),
                None => None,
            }
        }))
    }

    /// The stored view of a resource (see [`NewResource::view`]); None when it has none
    /// (a tool library uploaded before views were stored).
    pub async fn resource_view(&self, id: &str) -> Result<Option<String>, StoreError> {
        Ok(on_pool!(&self.pool, p => sqlx::query_scalar(
            "SELECT members FROM resource_views WHERE resource_id = $1",
        )
        .bind(id)
        .fetch_optional(p)
        .await?))
    }

    /// Stores the view of a resource that had none (computed at its first GET).
    pub async fn store_resource_view(&self, id: &str, view: &str) -> Result<(), StoreError> {
        let mut tx = self.begin().await?;
        insert_view(&mut tx, id, view).await?;
        tx.commit().await
    }

    /// The stored bytes and media type of a resource, unchanged, whole in memory (a
    /// chunked one is put together: see [`Db::resource_body`] to read it a chunk at a
    /// time).
    pub async fn resource_content(
        &self,
        owner: &str,
        kind: ResourceKind,
        id: &str,
    ) -> Result<Option<(Option<String>, String, Vec<u8>)>, StoreError> {
        let Some((name, media_type, size, body)) = self.resource_body(owner, kind, id).await?
        else {
            return Ok(None);
        };
        let bytes = match body {
            ResourceBody::Inline(bytes) => bytes,
            ResourceBody::Chunked { id, chunks } => {
                let mut out = Vec::with_capacity(size as usize);
                for seq in 0..chunks {
                    let chunk = self
                        .resource_chunk(&id, seq)
                        .await?
                        .ok_or_else(|| StoreError::Vanished(format!("{} {id}", kind.as_str())))?;
                    out.extend_from_slice(&chunk);
                }
                out
            }
        };
        Ok(Some((name, media_type, bytes)))
    }

    /// A resource's file name, media type, size and content (inline, or where its
    /// chunks are).
    pub async fn resource_body(
        &self,
        owner: &str,
        kind: ResourceKind,
        id: &str,
    ) -> Result<Option<(Option<String>, String, i64, ResourceBody)>, StoreError> {
        type Row = (Option<String>, String, i64, Vec<u8>, i64);
        // Content in the row is at most a chunk: larger content is in chunk rows (see
        // `insert_with_id`, and the migration that moved older content there).
        let row: Option<Row> = on_pool!(&self.pool, p => sqlx::query_as(
            "SELECT name, media_type, size, content, chunks FROM resources WHERE owner = $1 AND kind = $2 AND id = $3",
        )
        .bind(owner)
        .bind(kind.as_str())
        .bind(id)
        .fetch_optional(p)
        .await?);
        Ok(row.map(|(name, media_type, size, content, chunks)| {
            let body = if chunks > 0 {
                ResourceBody::Chunked {
                    id: id.to_string(),
                    chunks,
                }
            } else {
                ResourceBody::Inline(content)
            };
            (name, media_type, size, body)
        }))
    }

    /// One page of resources of a kind, oldest first, after `cursor` (an id).
    pub async fn list_resources(
        &self,
        owner: &str,
        kind: ResourceKind,
        cursor: Option<&str>,
        limit: u32,
    ) -> Result<(Vec<ResourceRecord>, Option<String>), StoreError> {
        let items = on_pool!(&self.pool, p => {
            let rows = sqlx::query(&format!(
                "SELECT {RECORD_COLUMNS} FROM resources
                 WHERE owner = $1 AND kind = $2 AND id > $3 ORDER BY id LIMIT $4",
            ))
            .bind(owner)
            .bind(kind.as_str())
            .bind(cursor.unwrap_or(""))
            .bind(i64::from(limit) + 1)
            .fetch_all(p)
            .await?;
            rows.iter()
                .map(|r| record(kind, r))
                .collect::<Result<Vec<_>, _>>()?
        });
        Ok(super::page(items, limit, |r| &r.id))
    }

    /// Deletes a resource; false when there was none.
    pub async fn delete_resource(
        &self,
        owner: &str,
        kind: ResourceKind,
        id: &str,
    ) -> Result<bool, StoreError> {
        let done = on_pool!(&self.pool, p => sqlx::query("DELETE FROM resources WHERE owner = $1 AND kind = $2 AND id = $3")
            .bind(owner)
            .bind(kind.as_str())
            .bind(id)
            .execute(p)
            .await?
            .rows_affected());
        Ok(done > 0)
    }
}
