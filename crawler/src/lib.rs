//! # crawler
//!
//! The `crawler` program: `crawler run` (the whole co-simulation in one command), `crawler
//! compare`, `crawler sweep`, and each program of the project under one name (`crawler plant`,
//! `crawler controller`). `main.rs` parses and dispatches; the rest lives here:
//!
//! - [`run`]: `crawler run`; [`children`]: the run's processes and their command lines, built in
//!   one place; [`supervise`]: starting, watching and stopping them;
//! - [`compare`]: `crawler compare`; [`sweep`]: `crawler sweep` (also the `crawler-sweep` binary);
//! - [`preflight`]: what is checked before anything starts.

pub mod children;
pub mod compare;
pub mod preflight;
pub mod run;
pub mod supervise;
pub mod sweep;
