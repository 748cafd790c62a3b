//! `gema2 run`: the supervisor. Starts the pipeline's stages (pinned to their cores), waits for
//! each to be connected before starting the sources, reaps and restarts stages that die (with
//! backoff, cleaning up their shared memory), performs hot swaps asked for on the control
//! service, and reports latency per stage and per hop, throughput and accuracy.

pub mod child;
mod control;
pub mod monitor;
pub mod pipeline;
mod run;
pub mod swap;

pub use run::{run, RunArgs};
