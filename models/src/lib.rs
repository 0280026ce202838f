//! # crawler-models
//!
//! Reduced models of the soft crawler of Gusty et al. and the constrained optimum they give:
//!
//! - [`paper_model`]: the paper's leading-order perturbation solution (eqs. 27-34), with its
//!   misprints corrected (`docs/physics.md`) and validity reported instead of NaN.
//! - [`travelling_wave`]: the improved reduced model, the exact travelling-wave steady state
//!   with exact stick, as accurate as a converged plant at a tiny fraction of the cost.
//! - [`prediction`]: what a model predicts (the metric table's values) and whether it applies.
//! - [`optimizer`]: the constrained optimal open-loop policy (paper Sec. V) with explicit limits.
//! - [`verify`]: checking and certifying an optimum on the in-process plant.
//! - [`bench`]: the models' and the optimiser's timings.
//!
//! No network, command line or terminal. Units are SI throughout.

pub mod bench;
pub mod operating_point;
pub mod optimizer;
pub mod paper_model;
pub mod prediction;
pub mod roots;
pub mod travelling_wave;
pub mod verify;

pub use operating_point::OperatingPoint;
pub use prediction::{Model, Prediction, Validity};
