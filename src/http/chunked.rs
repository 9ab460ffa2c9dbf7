//! Streaming stored chunks back (a large upload's content, a large file a job produced):
//! one chunk read from the database per chunk sent, so the API holds one chunk, not the
//! file.

use axum::body::Body;

use crate::store::chunks::ChunkKey;
use crate::store::Db;

/// The body of `chunks` chunks of `key`. If they vanish while they are sent (the
/// resource or job was deleted) the body ends early with an error: the client sees a
/// short body against its Content-Length.
pub fn chunk_body(db: Db, key: ChunkKey, chunks: i64) -> Body {
    let stream = futures_util::stream::unfold(0i64, move |seq| {
        let db = db.clone();
        let key = key.clone();
        async move {
            if seq >= chunks {
                return None;
            }
            let next = match db.chunk(&key, seq).await {
                Ok(Some(chunk)) => Ok(bytes::Bytes::from(chunk)),
                Ok(None) => Err(std::io::Error::other(format!(
                    "{key:?} was deleted while it was sent"
                ))),
                Err(e) => Err(std::io::Error::other(e.to_string())),
            };
            Some((next, seq + 1))
        }
    });
    Body::from_stream(stream)
}
