//! A job's rows as one streamed CSV (`/v1/jobs/{id}/blocks?format=csv`): read from the
//! table page by page (memory stays flat whatever the number of blocks), each page turned
//! into CSV on a blocking thread straight from the rows' JSON text (see `crate::csv`), the
//! next page read and converted while the one before is sent.

use std::sync::Arc;

use axum::body::Body;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use futures_util::stream;

use super::problem::ApiError;
use crate::csv;
use crate::store::Db;

/// Rows per database read (about 3.5 MB of JSON for a simulate job's rows).
const PAGE: i64 = 5000;

/// The CSV of job `id`'s rows with the `declared` keys as columns (else the first row's),
/// or only the `wanted` ones, numbers written as `numbers` says. The first page is read before answering, so an unknown
/// column is a 400 naming it, not a broken stream.
pub async fn csv_response(
    db: Db,
    id: String,
    declared: Option<Vec<String>>,
    wanted: Option<Vec<String>>,
    numbers: csv::Numbers,
) -> Result<Response, ApiError> {
    let first = db.job_rows(&id, 0, PAGE).await?;
    let cols = {
        let mut parsed = Vec::new();
        for (_, d) in &first {
            let mut p = Vec::new();
            if csv::read_pairs(d, &mut p) {
                parsed.push(p);
            }
        }
        let keys = declared.unwrap_or_else(|| {
            parsed
                .first()
                .map(|p| p.iter().map(|(k, _)| k.to_string()).collect())
                .unwrap_or_default()
        });
        csv::columns(&keys, &parsed)
    };
    let cols = match wanted {
        None => cols,
        Some(w) => {
            let all: Vec<String> = cols.iter().map(|c| c.header.clone()).collect();
            let w: Vec<&str> = w.iter().map(String::as_str).collect();
            csv::select(cols, &w).map_err(|bad| {
                ApiError::invalid_field(
                    "columns",
                    format!(
                        "no column `{bad}` in this job's rows; they are: {}",
                        all.join(",")
                    ),
                )
            })?
        }
    };
    // A producer reads and converts the pages while the one before is on the wire (the
    // next page's read and conversion overlap the client's reading); the channel holds
    // two pages, so memory stays at a few pages whatever the number of rows. A client
    // that goes away closes the channel and stops the producer.
    let (tx, mut rx) = tokio::sync::mpsc::channel::<std::io::Result<bytes::Bytes>>(2);
    let cols = Arc::new(cols);
    tokio::spawn(async move {
        let mut page = first;
        let mut header = true;
        while let Some(&(last, _)) = page.last() {
            let full = page.len() as i64 == PAGE;
            let c = cols.clone();
            let text = tokio::task::spawn_blocking(move || convert(&page, &c, header, numbers));
            let next = if full {
                Some(db.job_rows(&id, last + 1, PAGE).await)
            } else {
                None
            };
            header = false;
            let text = text.await.map_err(std::io::Error::other);
            let sent = tx.send(text.map(bytes::Bytes::from)).await;
            match (sent, next) {
                (Ok(()), Some(Ok(p))) => page = p,
                (Ok(()), Some(Err(e))) => {
                    // The rows so far have gone out; the broken stream tells the client.
                    let _ = tx.send(Err(std::io::Error::other(e.to_string()))).await;
                    break;
                }
                _ => break,
            }
        }
    });
    let stream = stream::poll_fn(move |cx| rx.poll_recv(cx));
    Ok((
        [
            (header::CONTENT_TYPE, "text/csv; charset=utf-8"),
            (
                header::CONTENT_DISPOSITION,
                "attachment; filename=\"blocks.csv\"",
            ),
        ],
        Body::from_stream(stream),
    )
        .into_response())
}

/// One page of rows as CSV text (the header first where asked).
fn convert(
    rows: &[(i64, String)],
    cols: &[csv::Column],
    header: bool,
    numbers: csv::Numbers,
) -> String {
    let mut out = String::with_capacity(rows.len() * 16 * cols.len());
    if header {
        csv::write_header(&mut out, cols);
    }
    let mut pairs = Vec::new();
    for (_, d) in rows {
        if csv::read_pairs(d, &mut pairs) {
            csv::write_row(&mut out, cols, &pairs, numbers);
        }
    }
    out
}
