//! # crawler-recorder
//!
//! Records a soft-crawler co-simulation run into a Rerun `.rrd` file. It depends only on the wire
//! protocol: zenoh callbacks push raw payloads into an inbox bounded in bytes ([`session`]; when
//! it is full they hold the link, so the run waits rather than losing states), and a writer decodes
//! them and records them in step order, columnar ([`recorder`]): every state's scalars and the
//! fields of every `--every`-th state, one chunk per entity per block of states. Payloads are
//! checked at arrival (size, and in an authenticated run their seal); the writer records only what
//! the run can have produced ([`checks`]) and notes everything it rejects. At close the file's
//! chunks are merged ([`compact`]) and it ends with Rerun's footer.

pub mod checks;
pub mod cli;
pub mod compact;
pub mod layout;
pub mod output;
pub mod paths;
pub mod recorder;
pub mod session;
pub mod viewer;

pub use recorder::{Counts, Incoming, Recorder, RecorderOptions};
