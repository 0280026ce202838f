//! # crawler-controller
//!
//! Models and controllers for the soft crawler of Gusty et al.:
//!
//! - [`paper_model`]: the paper's leading-order perturbation solution (eqs. 27-34), with its
//!   misprints corrected (`docs/physics.md` §7) and validity reported instead of NaN.
//! - [`travelling_wave`]: the improved reduced model, the exact travelling-wave steady state
//!   with exact stick, as accurate as a converged plant at a tiny fraction of the cost.
//! - [`optimizer`]: the constrained optimal open-loop policy (paper Sec. V) with explicit limits.
//! - [`verify`]: checking and certifying an optimum on the in-process plant.
//! - [`controller`] and [`policies`]: the `Controller` trait and the built-in policies.
//!
//! Units are SI throughout.

pub mod bench;
pub mod client;
pub mod closed_loop;
pub mod controller;
pub mod estimator;
pub mod figures;
pub mod operating_point;
pub mod optimizer;
pub mod paper_model;
pub mod policies;
pub mod prediction;
pub mod roots;
pub mod travelling_wave;
pub mod verify;

pub use controller::{Actuation, Context, Controller, Insight, Observation};
pub use operating_point::OperatingPoint;
pub use prediction::{Model, Prediction, Validity};
