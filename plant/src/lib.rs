//! # crawler-plant
//!
//! The plant of [`crawler_physics`] as a node of a co-simulation over zenoh (`crawler-plant run`),
//! and the pieces of the `crawler-plant` program around the physics library. The roles follow
//! libcosim's split of a co-simulation:
//!
//! - [`access`]: the run's credential and zenoh user file, created by the plant and removed at
//!   its exit;
//! - [`admission`]: one actuation message decoded and checked for the step the plant waits for,
//!   rejections counted by cause (pure; no clock, no network);
//! - [`link`]: the zenoh publishers, subscribers, queryable and liveliness, and the inboxes they
//!   fill;
//! - [`runner`]: the lockstep on the plant's fixed-step clock: the plant library's execution loop
//!   with the joined controller (over an inbox) as its controller and the publisher (to an outbox)
//!   as its observer (the link, or channels in tests);
//! - [`wire`]: the plant's report as the protocol's `FinalReport`;
//! - [`checkpoint`]: a stopped run (plant state, scenario, bookkeeping), resumed bit-identically;
//! - [`environment`]: the pipe's friction as the plant resolved it, answered to the recorder;
//! - [`bench`]: cell updates per second of the stepping loop (`crawler-plant bench`);
//! - [`preflight`]: what a run costs and where it really ends, said before it starts;
//! - [`cli`]: the `crawler-plant` program (parsing and dispatch).

pub mod access;
pub mod admission;
pub mod bench;
pub mod checkpoint;
pub mod cli;
pub mod environment;
pub mod link;
pub mod preflight;
pub mod runner;
pub mod wire;
