#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used, clippy::panic)]

mod ambient;
mod bad_input;
mod cramer_rao;
mod monte_carlo;
mod multimode;
mod paper;
mod real_wind;
