//! Programs parsed in the API process (an upload's check, a job's inline program). A parse
//! holds several times its text, so the text parsed at once is bounded by one largest
//! program (`--max-program-bytes`): small programs parse side by side, large ones take
//! turns, and concurrent uploads of the largest size hold one parse's memory, not one each.

use std::sync::OnceLock;

use tokio::sync::Semaphore;

use super::problem::ApiError;
use crate::validate::{self, Validated};

/// Permits in MiB of program text, created with the server's limit at the first parse.
static PARSING: OnceLock<Semaphore> = OnceLock::new();

fn mib(bytes: u64) -> u64 {
    bytes.div_ceil(1 << 20)
}

/// Checks a program as `validate::program` does, on a blocking thread, once its text fits
/// in what is being parsed (see the module doc); gives the bytes back with the result.
pub async fn program(
    bytes: Vec<u8>,
    file: String,
    max_program_bytes: u64,
) -> Result<(Vec<u8>, String, Validated), ApiError> {
    // tokio's semaphore takes at most u32::MAX >> 3 permits at once.
    let budget = mib(max_program_bytes).clamp(1, (u32::MAX >> 3) as u64) as u32;
    let parsing = PARSING.get_or_init(|| Semaphore::new(budget as usize));
    let want = (mib(bytes.len() as u64) as u32).clamp(1, budget);
    let turn = parsing
        .acquire_many(want)
        .await
        .map_err(|_| ApiError::internal("the program reader is closed"))?;
    // The turn goes with the parse: a client that leaves mid-parse does not free it early.
    tokio::task::spawn_blocking(move || {
        let _turn = turn;
        validate::program(&bytes, &file).map(|checked| (bytes, file, checked))
    })
    .await
    .map_err(|e| ApiError::blocking_failed(e, "the program reader"))?
}
