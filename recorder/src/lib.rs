//! # crawler-recorder
//!
//! Records a soft-crawler co-simulation run into a Rerun `.rrd` file. It depends only on the wire
//! protocol: zenoh callbacks push raw payloads into a bounded channel (never blocking the
//! publishers) and a writer decodes them and logs them in step order, decimating the fields when
//! it falls behind (and saying so in the recording). Payloads are checked at arrival (size, and
//! in an authenticated run their seal) and queued within a byte budget; the writer records only
//! what the run can have produced ([`checks`]) and notes everything it rejects.

pub mod checks;
pub mod layout;
pub mod output;
pub mod paths;
pub mod recorder;
pub mod viewer;

pub use recorder::{Counts, Incoming, Recorder, RecorderOptions};
