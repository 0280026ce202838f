//! The envelope of every message: which run instance it belongs to, who sent it and in which
//! order, carried in the zenoh sample's attachment beside the message (the payload is the
//! message alone), and covered by its seal (`docs/protocol.md`, [Envelope]).
//!
//! ```text
//! offset  bytes  field
//!      0      1  envelope version, 3 (the protocol version)
//!      1      1  sender's role: 'p' plant, 'c' controller, 'b' bridge (the recorder)
//!      2     16  run instance: 128 random bits the plant draws when it starts
//!     18     16  sender's process id: 16 lowercase hex digits (ASCII)
//!     34      8  sequence number, little-endian: 1, 2, ... per sender and key
//! ```
//!
//! A reply to a query carries the query's 16-byte challenge after the header; in an
//! authenticated run the 32-byte seal follows (`attachment = header [challenge] [seal]`).
//!
//! Receivers keep, per key and sender, the last sequence number they took, and refuse anything
//! not newer; a message of another run instance is refused whatever its seal says. So a message
//! is acted on at most once, and a run's messages never count in another run, even one that
//! shares its credential.

use crate::error::ProtocolError;
use crate::keys::Role;

/// Bytes of a run instance's nonce.
pub const NONCE_LEN: usize = 16;
/// Bytes of a process id (16 lowercase hex digits).
pub const ID_LEN: usize = 16;
/// Bytes of the envelope's header.
pub const HEADER_LEN: usize = 2 + NONCE_LEN + ID_LEN + 8;
/// Bytes of a query's challenge (the payload of a `get`, echoed in the reply's envelope).
pub const CHALLENGE_LEN: usize = 16;
/// The envelope's version byte: the protocol version it belongs to.
pub const ENVELOPE_VERSION: u8 = 3;

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A run instance: 128 random bits drawn by the plant when it starts (a resumed run is another
/// instance). Every message of the run carries it.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct RunNonce(pub [u8; NONCE_LEN]);

impl std::fmt::Debug for RunNonce {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RunNonce({})", hex(&self.0))
    }
}

impl std::fmt::Display for RunNonce {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&hex(&self.0))
    }
}

/// A process id: exactly 16 lowercase hex digits, as in liveliness keys and messages.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ProcessId([u8; ID_LEN]);

impl ProcessId {
    /// The id `s`, if it is 16 lowercase hex digits.
    pub fn parse(s: &str) -> Result<Self, ProtocolError> {
        Self::from_bytes(s.as_bytes()).ok_or_else(|| {
            ProtocolError::invalid(
                "process id",
                format!("{:?}", s.chars().take(32).collect::<String>()),
                "16 lowercase hex digits",
            )
        })
    }

    fn from_bytes(b: &[u8]) -> Option<Self> {
        let ok = b.len() == ID_LEN && b.iter().all(|c| matches!(c, b'0'..=b'9' | b'a'..=b'f'));
        ok.then(|| {
            let mut id = [0u8; ID_LEN];
            id.copy_from_slice(b);
            Self(id)
        })
    }

    /// The id as text.
    pub fn as_str(&self) -> &str {
        // only lowercase hex digits are ever stored
        std::str::from_utf8(&self.0).unwrap_or("")
    }

    /// The id's 16 ASCII bytes.
    pub fn as_bytes(&self) -> &[u8; ID_LEN] {
        &self.0
    }
}

impl std::fmt::Debug for ProcessId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ProcessId({})", self.as_str())
    }
}

impl std::fmt::Display for ProcessId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The role's byte in an envelope.
pub fn role_byte(role: Role) -> u8 {
    match role {
        Role::Plant => b'p',
        Role::Controller => b'c',
        Role::Bridge => b'b',
    }
}

fn role_of_byte(b: u8) -> Option<Role> {
    Role::ALL.into_iter().find(|r| role_byte(*r) == b)
}

/// The header of an envelope: run instance, sender and sequence number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// The run instance.
    pub run: RunNonce,
    /// The sender's role.
    pub role: Role,
    /// The sender's process id.
    pub sender: ProcessId,
    /// The sender's sequence number on this key (from 1).
    pub seq: u64,
}

impl Header {
    /// The header's bytes.
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        b[0] = ENVELOPE_VERSION;
        b[1] = role_byte(self.role);
        b[2..2 + NONCE_LEN].copy_from_slice(&self.run.0);
        b[2 + NONCE_LEN..2 + NONCE_LEN + ID_LEN].copy_from_slice(&self.sender.0);
        b[HEADER_LEN - 8..].copy_from_slice(&self.seq.to_le_bytes());
        b
    }

    /// The header at the start of `bytes` (which may go on: a challenge, a seal).
    pub fn decode(bytes: &[u8]) -> Result<Self, ProtocolError> {
        let bad = |field: &str, value: String, allowed: &str| {
            Err(ProtocolError::invalid(
                format!("envelope.{field}"),
                value,
                allowed,
            ))
        };
        if bytes.len() < HEADER_LEN {
            return bad(
                "header",
                format!("{} bytes", bytes.len()),
                &format!("at least {HEADER_LEN} bytes"),
            );
        }
        if bytes[0] != ENVELOPE_VERSION {
            return bad(
                "version",
                bytes[0].to_string(),
                &ENVELOPE_VERSION.to_string(),
            );
        }
        let Some(role) = role_of_byte(bytes[1]) else {
            return bad(
                "role",
                format!("0x{:02x}", bytes[1]),
                "'p', 'c' or 'b' (0x70, 0x63, 0x62)",
            );
        };
        let mut run = [0u8; NONCE_LEN];
        run.copy_from_slice(&bytes[2..2 + NONCE_LEN]);
        let id = &bytes[2 + NONCE_LEN..2 + NONCE_LEN + ID_LEN];
        let Some(sender) = ProcessId::from_bytes(id) else {
            return bad("sender", hex(id), "16 lowercase hex digits (ASCII)");
        };
        let mut seq = [0u8; 8];
        seq.copy_from_slice(&bytes[HEADER_LEN - 8..HEADER_LEN]);
        let seq = u64::from_le_bytes(seq);
        if seq == 0 {
            return bad("seq", "0".into(), "1 or more");
        }
        Ok(Self {
            run: RunNonce(run),
            role,
            sender,
            seq,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> Header {
        Header {
            run: RunNonce([0xab; NONCE_LEN]),
            role: Role::Controller,
            sender: ProcessId::parse("00c0ffee00c0ffee").unwrap(),
            seq: 0x0102,
        }
    }

    #[test]
    fn a_header_round_trips_and_reads_as_documented() {
        let h = header();
        let b = h.encode();
        assert_eq!(b.len(), 42);
        assert_eq!((b[0], b[1]), (3, b'c'));
        assert_eq!(&b[18..34], b"00c0ffee00c0ffee");
        assert_eq!(&b[34..], &[2, 1, 0, 0, 0, 0, 0, 0]);
        assert_eq!(Header::decode(&b).unwrap(), h);
        // what follows the header (a challenge, a seal) is not its business
        let mut longer = b.to_vec();
        longer.extend([9; 48]);
        assert_eq!(Header::decode(&longer).unwrap(), h);
    }

    #[test]
    fn malformed_headers_are_refused_naming_the_field() {
        let b = header().encode();
        let refused = |edit: &dyn Fn(&mut Vec<u8>)| {
            let mut x = b.to_vec();
            edit(&mut x);
            Header::decode(&x).unwrap_err().to_string()
        };
        assert!(refused(&|x| x.truncate(41)).contains("envelope.header = 41 bytes"));
        assert!(refused(&|x| x[0] = 2).contains("envelope.version = 2: allowed 3"));
        assert!(refused(&|x| x[1] = b'x').contains("envelope.role = 0x78"));
        assert!(refused(&|x| x[20] = b'G').contains("envelope.sender"));
        assert!(refused(&|x| x[34..].fill(0)).contains("envelope.seq = 0"));
    }

    #[test]
    fn process_ids_are_sixteen_lowercase_hex_digits() {
        assert_eq!(
            ProcessId::parse("0123456789abcdef").unwrap().as_str(),
            "0123456789abcdef"
        );
        for bad in [
            "",
            "0123456789ABCDEF",
            "0123456789abcde",
            "0123456789abcdef0",
            "c0ffee",
        ] {
            let e = ProcessId::parse(bad).unwrap_err().to_string();
            assert!(e.contains("16 lowercase hex digits"), "{bad}: {e}");
        }
    }
}
