//! A job's rows as one streamed CSV (`/v1/jobs/{id}/blocks?format=csv`): read from the
//! table page by page (memory stays flat whatever the number of blocks), each page turned
//! into CSV on a blocking thread straight from the rows' JSON text (see `crate::csv`).

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
    struct S {
        db: Db,
        id: String,
        cols: Arc<Vec<csv::Column>>,
        page: Option<Vec<(i64, String)>>,
        header: bool,
        /// A failed read, told after the rows before it have gone out.
        failed: Option<String>,
    }
    let stream = stream::unfold(
        S {
            db,
            id,
            cols: Arc::new(cols),
            page: Some(first),
            header: true,
            failed: None,
        },
        move |mut s| async move {
            if let Some(e) = s.failed.take() {
                return Some((Err(std::io::Error::other(e)), s));
            }
            let rows = s.page.take()?;
            let Some(&(last, _)) = rows.last() else {
                return None;
            };
            let full = rows.len() as i64 == PAGE;
            let (cols, header) = (s.cols.clone(), s.header);
            s.header = false;
            let text = tokio::task::spawn_blocking(move || {
                let mut out = String::with_capacity(rows.len() * 64 * cols.len() / 4);
                if header {
                    csv::write_header(&mut out, &cols);
                }
                let mut pairs = Vec::new();
                for (_, d) in &rows {
                    if csv::read_pairs(d, &mut pairs) {
                        csv::write_row(&mut out, &cols, &pairs, numbers);
                    }
                }
                out
            })
            .await
            .map_err(std::io::Error::other);
            let text = match text {
                Ok(t) => t,
                Err(e) => return Some((Err(e), s)),
            };
            if full {
                match s.db.job_rows(&s.id, last + 1, PAGE).await {
                    Ok(next) => s.page = Some(next),
                    Err(e) => s.failed = Some(e.to_string()),
                }
            }
            Some((Ok::<_, std::io::Error>(bytes::Bytes::from(text)), s))
        },
    );
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
