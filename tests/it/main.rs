//! The integration tests, compiled into one test binary (`it`) so that
//! `cargo test` links the crate once rather than once per file. Each module
//! was a separate `tests/*.rs` file; `common` and `export_common` are the
//! helpers they share. Run one module's tests with a filter, e.g.
//! `cargo test --release --test it search::`.
//!
//! The modules that run the `layout-opt` binary need the `cli` feature (on
//! by default); without it only the library's tests are compiled.

mod common;
mod export_common;

mod architecture;
mod bad_input;
mod conformance_generator;
mod dls_limits;
mod export;
mod identifiability;
mod images_calibration;
mod noise_free;
mod noisy;
mod plots;
mod render;
mod sets;
mod sphere_image;
mod sqpnp_crosscheck;
mod track;
mod unlabelled;
mod visibility;

#[cfg(feature = "cli")]
mod characterise;
#[cfg(feature = "cli")]
mod cli_consistency;
#[cfg(feature = "cli")]
mod cli_solve;
#[cfg(feature = "cli")]
mod export_cli;
#[cfg(feature = "cli")]
mod fabrication_cli;
#[cfg(feature = "cli")]
mod images_cli;
#[cfg(feature = "cli")]
mod reproduce;
#[cfg(feature = "cli")]
mod run_kernel;
#[cfg(feature = "cli")]
mod scenes;
#[cfg(feature = "cli")]
mod search;
#[cfg(feature = "cli")]
mod search_runs;
#[cfg(feature = "cli")]
mod sphere_cli;
#[cfg(feature = "cli")]
mod validate;
#[cfg(feature = "cli")]
mod volume;
