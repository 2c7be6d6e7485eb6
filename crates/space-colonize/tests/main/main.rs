#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used, clippy::panic)]

mod bad_input;
mod geometry;
mod real_data;
mod reconstruct;
mod skeleton;
mod wood;
