//! # crawler-fmu
//!
//! The soft-crawler plant ([`crawler_physics::slave::Slave`]) as a Functional Mock-up Unit for
//! co-simulation, with the C API of both FMI 2.0 ([`fmi2`]) and FMI 3.0 ([`fmi3`]) written by
//! hand (`#[no_mangle] extern "C"`, types from the standard headers). One shared library holds
//! both APIs; `scripts/build-fmu.sh` packages it twice, with the FMI 2.0 and the FMI 3.0
//! `modelDescription.xml` ([`defaults::model_description`]).
//!
//! Rules every entry point keeps:
//! - its body runs inside `catch_unwind`: a panic is reported as `Error` (and the instance
//!   accepts nothing but `FreeInstance` and `Reset` afterwards), never unwound into the host;
//! - every pointer is checked for NULL, every instance for its tag, every array size against the
//!   number of values it must hold (an importer may pass `nValues = 1` for an array);
//! - there is no global state: each instance owns its plant, its logger and its buffers, so
//!   several instances live in one process and may be called from any thread (one call at a time
//!   per instance, as FMI requires);
//! - errors are reported through the importer's logger with a category, the FMI 2.0 logger
//!   always with the format `"%s"` (a message is never a format string).
//!
//! The FMU's defaults (parameters, the wave it is driven by, the default experiment) are the
//! paper scenario's, the same as the `crawler-plant` program's ([`defaults`]).

pub mod defaults;
pub mod documentation;
pub mod fmi2;
pub mod fmi3;
mod instance;
