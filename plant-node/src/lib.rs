//! # crawler-plant-node
//!
//! The plant of [`crawler_plant`] as a node of a co-simulation over zenoh (`crawler-plant run`),
//! and the pieces of the `crawler-plant` program around the physics library.
//!
//! - [`cosim`]: the co-simulation run: the plant owns the clock and steps in lockstep with the
//!   controller that joined.
//! - [`checkpoint`]: a stopped run (plant state, scenario, bookkeeping), resumed bit-identically.
//! - [`bench`]: cell updates per second of the stepping loop (`crawler-plant bench`).

pub mod bench;
pub mod checkpoint;
pub mod cosim;
