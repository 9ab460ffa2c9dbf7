//! The shared corpus beside the project (`../shared/corpus`: real programs and parts
//! written by others). A clone of the project does not have it: tests that read it skip,
//! saying so, when it is absent.
#![allow(dead_code)]

use std::path::PathBuf;

/// The corpus folder, or None (and a printed reason) when it is absent.
pub fn corpus_dir() -> Option<PathBuf> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/corpus"));
    if dir.is_dir() {
        Some(dir)
    } else {
        println!(
            "skipped: {} is absent (the shared corpus is not part of a clone)",
            dir.display()
        );
        None
    }
}
