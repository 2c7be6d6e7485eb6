#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used, clippy::panic)]

mod assign;
mod bad_input;
mod export;
mod pose;
mod release;
mod wind;
