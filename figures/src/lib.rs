//! # crawler-figures
//!
//! Figures of the soft crawler as PNG (plotters) and CSV:
//!
//! - [`paper`]: the paper's Fig. 5 (speed, power and mileage against alpha) and Fig. 6 (the
//!   omega-k planes of the optimum), the paper's model beside the improved model;
//! - [`maps`]: a sweep plan's heat maps of the models' errors against the plant ([`contour`]
//!   draws their level lines).

pub mod contour;
pub mod maps;
pub mod paper;

pub use paper::{register_font, write_figures, FigureOptions};
