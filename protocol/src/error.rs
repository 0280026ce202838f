//! Why a message was rejected.

/// A rejected message or value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProtocolError {
    /// The payload is larger than [`crate::MAX_MESSAGE_BYTES`].
    #[error("payload of {size} bytes exceeds the limit of {limit} bytes")]
    TooLarge {
        /// Bytes received.
        size: usize,
        /// The limit.
        limit: usize,
    },
    /// Not a MessagePack encoding of the expected message.
    #[error("malformed {message} message: {reason}")]
    Malformed {
        /// The message type expected.
        message: &'static str,
        /// The decoder's reason.
        reason: String,
    },
    /// A protocol version this build does not speak.
    #[error("{message} message has protocol version {got}, this build speaks {expected}")]
    Version {
        /// The message type.
        message: &'static str,
        /// The version received.
        got: u16,
        /// The version expected.
        expected: u16,
    },
    /// A field out of range.
    #[error("invalid {field} = {value}: allowed {allowed}")]
    Invalid {
        /// The field.
        field: String,
        /// Its value.
        value: String,
        /// What is allowed.
        allowed: String,
    },
}

impl ProtocolError {
    /// An invalid field.
    pub fn invalid(
        field: impl Into<String>,
        value: impl std::fmt::Display,
        allowed: impl Into<String>,
    ) -> Self {
        Self::Invalid {
            field: field.into(),
            value: value.to_string(),
            allowed: allowed.into(),
        }
    }
}
