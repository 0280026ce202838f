//! # crawler-facts
//!
//! The facts every crate of the project shares, written once:
//!
//! - [`metric`]: the metric table (name, symbol, unit, meaning of every steady-state metric): reports,
//!   predictions, sweep records and their Parquet columns, recorder entity paths and the wire
//!   messages all take their metrics from it;
//! - [`outcome`]: how a run did against the paper's task;
//! - [`limits`]: the sizes every input is bounded by (cells, names).
//!
//! No logic beyond lookups; serde only.

pub mod limits;
pub mod metric;
pub mod outcome;

pub use limits::{MAX_CELLS, MAX_ID_LEN, MAX_SCENARIO_NAME_LEN};
pub use metric::{Metric, MetricInfo, MetricValues, OutOfRange};
pub use outcome::Outcome;
