//! The shared folder beside the project (`../shared`: the corpus of real programs and parts
//! written by others, and reference curves computed outside the code). A clone of the
//! project does not have it: tests that read it skip, saying so, when it is absent.
#![allow(dead_code)]

pub mod nc;
pub mod simulate;

use std::path::PathBuf;

/// The corpus folder, or None (and a printed reason) when it is absent.
pub fn corpus_dir() -> Option<PathBuf> {
    shared_dir("corpus")
}

/// The reference curves' folder, or None (and a printed reason) when it is absent.
pub fn reference_dir() -> Option<PathBuf> {
    shared_dir("reference")
}

fn shared_dir(name: &str) -> Option<PathBuf> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared")).join(name);
    if dir.is_dir() {
        Some(dir)
    } else {
        println!(
            "skipped: {} is absent (the shared folder is not part of a clone)",
            dir.display()
        );
        None
    }
}
