//! The integration tests, compiled into one test binary (`it`) so that
//! `cargo test` links the crate once rather than once per file. Each module
//! was a separate `tests/*.rs` file; `common` and `export_common` are the
//! helpers they share. Run one module's tests with a filter, e.g.
//! `cargo test --release --test it search::`.

mod common;
mod export_common;

mod bad_input;
mod conformance_generator;
mod export;
mod noise_free;
mod noisy;
mod sqpnp_crosscheck;

mod cli_solve;
mod export_cli;
mod reproduce;
mod search;
mod validate;
