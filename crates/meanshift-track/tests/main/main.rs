//! Integration tests of meanshift-track: OpenCV parity against committed fixtures, the
//! tracker on generated sequences, bad input.
#![allow(clippy::expect_used, clippy::unwrap_used, clippy::panic)] // tests fail by panicking

mod parity;
mod real_frames;
mod tracker;
