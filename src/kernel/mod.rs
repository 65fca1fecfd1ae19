//! The run kernel: what every command's workflow shares, so that no command
//! rebuilds it and none can grow outside it.
//!
//! * [`outputs`]: one output set per run. It takes the lock of every
//!   output, refuses before any work an output that is one of the run's
//!   inputs or another of its outputs, stages every file beside its target
//!   and commits them together, or none.
//! * [`stop`]: the process's one stop request (Ctrl-C sets it), and the
//!   [`Interrupted`](stop::Interrupted) error a run that honoured it ends
//!   with; the binary turns that error, and only that error, into exit
//!   status 130.

pub mod outputs;
pub mod stop;

pub use outputs::{OutputError, OutputPlan, Outputs, Scratch};
pub use stop::{Interrupted, StopRequest};
