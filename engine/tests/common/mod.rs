//! The shared folder beside the project (`../shared`: the corpus of real programs and parts
//! written by others, and reference curves computed outside the code). A clone of the
//! project does not have it: tests that read it skip, saying so, when it is absent.
#![allow(dead_code)]

pub mod mesh;
pub mod nc;
pub mod simulate;

use std::path::PathBuf;

/// The corpus folder, or None (and a [`skip`] line) when it is absent.
pub fn corpus_dir() -> Option<PathBuf> {
    shared_dir("corpus")
}

/// The reference curves' folder, or None (and a [`skip`] line) when it is absent.
pub fn reference_dir() -> Option<PathBuf> {
    shared_dir("reference")
}

fn shared_dir(name: &str) -> Option<PathBuf> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared")).join(name);
    if dir.is_dir() {
        Some(dir)
    } else {
        skip(&format!(
            "{} (the shared folder is not part of a clone)",
            dir.display()
        ));
        None
    }
}

/// Says on the run's output that the running test checks nothing (or less) for want of
/// `what`: `SKIPPED: <test> needs <what>`. Written to the stderr handle itself, because the
/// harness captures `println!` and `eprintln!` and shows them only for a failing test; the
/// test's name is its thread's, which the harness gives it.
pub fn skip(what: &str) {
    use std::io::Write;
    let thread = std::thread::current();
    let test = thread.name().unwrap_or("a test");
    // One write, so that the line stays whole among the harness's own output.
    let line = format!("SKIPPED: {test} needs {what}\n");
    let _ = std::io::stderr().write_all(line.as_bytes());
}
