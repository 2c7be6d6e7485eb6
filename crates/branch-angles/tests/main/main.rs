//! Integration tests of branch-angles.
#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used, clippy::panic)]

mod angles;
mod csv;
