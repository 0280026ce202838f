//! # crawler-protocol
//!
//! The wire contract of the soft-crawler co-simulation: key expressions, messages and their
//! encoding. Every process of the project, and any controller written by someone else, depends
//! on this and nothing else. The byte-level description is `docs/protocol.md`.
//!
//! - Keys live under `crawler/<run-id>/` ([`keys::RunKeys`]).
//! - Messages are MessagePack maps with named fields and a version field `v`
//!   ([`messages::encode`], [`messages::decode`]); any MessagePack library reads them.
//! - [`messages::decode`] bounds the size, checks the version and validates every field, so a
//!   decoded message never carries NaN, an infinite value or an inconsistent size.
//! - Closed sets of values are enums that travel as their lowercase names: a status's
//!   [`Role`] and [`ProcessState`], a task's [`Outcome`].

/// An enum that travels as its name (`as_str`, `parse`): `Display`, and serde as a lowercase
/// string, refused by field, value and what is `allowed` when unknown.
macro_rules! wire_name {
    ($ty:ty, $field:literal, $allowed:expr) => {
        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.as_str())
            }
        }

        impl serde::Serialize for $ty {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(self.as_str())
            }
        }

        impl<'de> serde::Deserialize<'de> for $ty {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                crate::messages::named(d, $field, <$ty>::parse, $allowed)
            }
        }
    };
}

pub mod environment;
pub mod error;
pub mod keys;
pub mod limits;
pub mod messages;

pub use environment::{Environment, MAX_ENVIRONMENT_PIECES};
pub use error::ProtocolError;
pub use keys::{validate_run_id, Role, RunKeys};
pub use limits::RunLimits;
pub use messages::{
    decode, encode, Actuation, Applied, EpisodeMsg, EpisodeStats, Events, FinalReport, Message,
    Metrics, ModelInfo, ModelPrediction, Outcome, Prediction, ProcessState, Rejections,
    ReportWindow, Series, State, Status, TaskResult, WaveMsg, MAX_CELLS, MAX_MESSAGE_BYTES,
    MAX_SCENARIO_NAME_LEN, PROTOCOL_VERSION,
};
