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
    decode, encode, Actuation, EpisodeMsg, Events, Message, Metrics, ModelInfo, ModelPrediction,
    Prediction, Rejections, Series, State, Status, WaveMsg, MAX_CELLS, MAX_MESSAGE_BYTES,
    PROTOCOL_VERSION,
};
