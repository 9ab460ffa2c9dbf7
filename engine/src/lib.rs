//! millsim-engine: the pure computation core of millsim.
//!
//! No async, HTTP or SQL here: everything takes in-memory inputs and returns
//! in-memory results, so it can be tested with plain `#[test]`s.
//! Units inside: mm, mm/min, rev/min, s, N, N·m, W, J.

pub mod accessibility;
pub mod budget;
pub mod cl;
pub mod engagement;
pub mod geometry;
pub mod job;
pub mod machine;
pub mod nc;
pub mod optimize;
pub mod physics;
pub mod pipeline;
mod prefetch;
pub mod tool;
pub mod tool_library;
mod vec3;
