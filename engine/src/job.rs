//! What a long computation needs from its caller: a cancellation flag it checks
//! between blocks, and a sink it reports progress to.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Set by the caller (a cancelled job, a shutting-down worker); checked by the engine
/// between blocks. Cloning shares the flag.
#[derive(Clone, Debug, Default)]
pub struct CancelFlag(Arc<AtomicBool>);

impl CancelFlag {
    pub fn new() -> Self {
        Self::default()
    }
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// Receives progress as (done, total) units of work, usually blocks.
pub trait Progress: Send + Sync {
    fn report(&self, done: u64, total: u64);
}

/// A progress sink that drops everything, for tests and one-shot CLI use.
pub struct NoProgress;

impl Progress for NoProgress {
    fn report(&self, _done: u64, _total: u64) {}
}
