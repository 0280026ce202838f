//! # crawler-plant
//!
//! A finite-difference solver of the soft peristaltic crawler of Gusty et al. (the nonlinear
//! wave equation `rho u_tt = A_c E u_xx + (A_m f)_x - F(u_t)` on a periodic body) with asymmetric
//! Coulomb + viscous friction and exact (set-valued) stick, wrapped as an FMI 3.0 style
//! co-simulation slave.
//!
//! - [`solver`]: the kernel (leapfrog + closed-form implicit friction per node).
//! - [`friction`]: the set-valued friction law and its exact one-step solution.
//! - [`plant`]: the plant advanced in communication steps, with actuation, metrics and events.
//! - [`slave`]: the FMI-style lifecycle, value references and state serialization.
//! - [`execution`]: the one loop that runs a plant (controller before each step, observers after);
//!   [`report`]: what a run reports, whichever route ran it.
//! - [`scenario`]: TOML scenarios; [`simulate`]: an in-process run under the scenario's wave.
//! - [`framing`]: the framed, checksummed binary format of serialised states.
//! - [`cpu`]: whether this CPU runs the instructions the build targets (an answer, never an exit).
//!
//! Units are SI throughout: m, s, N, Pa, W, J.
//!
//! The library knows no network, command line or terminal: it never prints, draws or exits, so
//! it can be linked into another program (an FMU, a controller). The co-simulation node and the
//! `crawler-plant` program are the crate `crawler-plant` (`plant/`).

pub mod convergence;
pub mod cpu;
pub mod error;
pub mod events;
pub mod execution;
pub mod framing;
pub mod friction;
pub mod metrics;
pub mod model_description;
pub mod node_array;
mod node_friction;
pub mod pair;
pub mod params;
pub mod pipe;
pub mod plant;
pub mod report;
pub mod scenario;
pub mod simd;
pub mod simulate;
pub mod slave;
pub mod solver;
pub mod sums;
pub mod task;
pub mod wave;

pub use error::ParamError;
pub use params::PlantParams;
pub use plant::Plant;
pub use scenario::Scenario;
pub use slave::Slave;
pub use wave::Wave;
