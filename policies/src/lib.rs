//! # crawler-policies
//!
//! Controllers of the soft crawler behind one trait, [`Policy`]: an [`Observation`] of the plant
//! in, the [`Actuation`] over the next communication step out. Each policy owns its parameters
//! (`key=value`, [`Params`]) and validates them itself; [`REGISTRY`] names them all.
//!
//! - [`wave`]: a fixed travelling wave (or the resonant one); [`sweep`]: a schedule of waves;
//!   [`pulse`]: a wave switched on and off;
//! - [`optimal`]: the constrained optimum of the improved model, certified on the plant;
//! - [`adaptive`]: the optimum re-solved in flight from the friction it estimates;
//! - [`reflex`]: a distributed law of coupled oscillators with local stick, energy and stress
//!   reflexes.
//!
//! [`in_process::run`] runs a policy against the in-process plant through the plant's execution
//! loop, bit-identical to the co-simulation.

pub mod adaptive;
pub mod estimator;
pub mod in_process;
pub mod optimal;
pub mod params;
pub mod policy;
pub mod pulse;
pub mod reflex;
mod registry;
pub mod sweep;
pub mod wave;

pub use crawler_physics::execution::{Actuation, Observation};
pub use crawler_physics::wave::Wave;
pub use params::Params;
pub use policy::{Context, Insight, Policy};
pub use registry::{build, check, lookup, Entry, Factory, REGISTRY};
