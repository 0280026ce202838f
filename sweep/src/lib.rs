//! # crawler-sweep
//!
//! Parameter sweeps of the soft crawler: a plan ([`plan`]) names axes of scenario keys and their
//! values and what to evaluate at each point (the plant with a convergence estimate, the paper's
//! and the improved model, a policy in closed loop). Each point ([`point`]) is resolved by the
//! scenario's own parser and identified by a hash of everything that determines its results, so
//! interrupted sweeps resume and overlapping plans share results through the [`store`]. Points
//! run on all local cores ([`local`]) or as a Slurm job array ([`slurm`]); the results are one
//! Parquet file per sweep ([`table`]); for plans with `[figures]` the library computes the maps
//! ([`maps`]) and a program draws them ([`run::MapOutputs`]: the heat maps of `crawler-figures`,
//! the recording of `crawler sweep`).
//!
//! No command line, network or drawing: `crawler sweep` is the program.
//!
//! Units are SI throughout.

pub mod evaluate;
pub mod local;
pub mod maps;
pub mod plan;
pub mod point;
pub mod record;
pub mod run;
pub mod slurm;
pub mod store;
pub mod table;
