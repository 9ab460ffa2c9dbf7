//! Per-block result rows written in bulk, inside the job's success transaction: SQLite
//! takes multi-row INSERTs, PostgreSQL a COPY (one stream instead of a statement per
//! chunk, so a 100k-row result commits in a fraction of a second).

use super::backend::{on_tx, Tx};
use super::StoreError;

/// How much COPY text is buffered before it is sent.
const COPY_CHUNK_BYTES: usize = 1 << 20;

/// Replaces a job's rows in `table` (job_id, seq, data) with `items`.
pub async fn replace_rows(
    tx: &mut Tx,
    table: &str,
    job_id: &str,
    items: &[(usize, String)],
) -> Result<(), StoreError> {
    on_tx!(tx, c => sqlx::query(&format!("DELETE FROM {table} WHERE job_id = $1"))
        .bind(job_id)
        .execute(&mut *c)
        .await?
        .rows_affected());
    match tx {
        Tx::Sqlite(t) => {
            // One statement per 400 rows instead of one per row.
            for chunk in items.chunks(400) {
                let mut q =
                    sqlx::QueryBuilder::new(format!("INSERT INTO {table} (job_id, seq, data) "));
                q.push_values(chunk, |mut b, (seq, data)| {
                    b.push_bind(job_id).push_bind(*seq as i64).push_bind(data);
                });
                q.build().execute(&mut **t).await?;
            }
        }
        Tx::Postgres(t) => {
            if items.is_empty() {
                return Ok(());
            }
            let mut copy = t
                .copy_in_raw(&format!("COPY {table} (job_id, seq, data) FROM STDIN"))
                .await?;
            let id = copy_text(job_id);
            let mut buf = Vec::with_capacity(COPY_CHUNK_BYTES + 4096);
            for (seq, data) in items {
                buf.extend_from_slice(id.as_bytes());
                buf.push(b'\t');
                buf.extend_from_slice(seq.to_string().as_bytes());
                buf.push(b'\t');
                buf.extend_from_slice(copy_text(data).as_bytes());
                buf.push(b'\n');
                if buf.len() >= COPY_CHUNK_BYTES {
                    copy.send(buf.as_slice()).await?;
                    buf.clear();
                }
            }
            if !buf.is_empty() {
                copy.send(buf.as_slice()).await?;
            }
            copy.finish().await?;
        }
    }
    Ok(())
}

/// A value in COPY's text format: backslash, tab, newline and carriage return escaped.
fn copy_text(s: &str) -> std::borrow::Cow<'_, str> {
    if !s.contains(['\\', '\t', '\n', '\r']) {
        return s.into();
    }
    let mut out = String::with_capacity(s.len() + 8);
    for ch in s.chars() {
        match ch {
            '\\' => out.push_str("\\\\"),
            '\t' => out.push_str("\\t"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            c => out.push(c),
        }
    }
    out.into()
}

#[cfg(test)]
mod tests {
    use super::copy_text;

    #[test]
    fn copy_text_escapes_what_copy_reads_as_syntax() {
        assert_eq!(copy_text(r#"{"a":"b"}"#), r#"{"a":"b"}"#);
        assert_eq!(copy_text("a\\\"b\tc\nd\re"), "a\\\\\"b\\tc\\nd\\re");
    }
}
