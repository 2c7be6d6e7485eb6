#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used, clippy::panic)]

mod bad_input;
mod pose;
mod release;
mod wind;
