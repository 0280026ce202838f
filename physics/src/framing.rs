//! Framed binary files and blobs: magic bytes, format version, CRC-32, MessagePack payload.
//!
//! Layout: 8 magic bytes, format version (u32 little endian), CRC-32 of the payload (u32 little
//! endian), then the payload (MessagePack with named fields). Used for serialized plant states
//! and co-simulation checkpoints, so that a truncated or corrupted file is refused, not read.

use serde::de::DeserializeOwned;
use serde::Serialize;

/// Why a framed blob was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct FrameError(pub String);

/// Frames `value` with `magic` and `version`.
pub fn encode<T: Serialize>(magic: &[u8; 8], version: u32, value: &T) -> Vec<u8> {
    let payload = rmp_serde::to_vec_named(value).expect("framed values serialize");
    let mut out = Vec::with_capacity(payload.len() + 16);
    out.extend_from_slice(magic);
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    out.extend_from_slice(&payload);
    out
}

/// What changed with each format version (states and checkpoints share the numbering).
fn history(version: u32) -> &'static str {
    match version {
        1 => "format 1: internal step at Courant number 0.9 dividing the communication step, no free ends or pipe map",
        2 => "format 2: the filter's change of the displacement added apart from the node pass's, so the round-off differs",
        _ => "an unknown earlier format",
    }
}

/// Checks magic, version and checksum, then decodes. `what` names the content in errors.
pub fn decode<T: DeserializeOwned>(
    magic: &[u8; 8],
    version: u32,
    what: &str,
    bytes: &[u8],
) -> Result<T, FrameError> {
    if bytes.len() < 16 || &bytes[..8] != magic {
        return Err(FrameError(format!(
            "not a {what} (the magic bytes {} are missing)",
            String::from_utf8_lossy(magic)
        )));
    }
    let got = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    if got != version {
        let why = if got < version {
            format!(
                "; it was written by an earlier build of the plant ({}), which this build cannot \
                 continue bit-identically: rerun the scenario",
                history(got)
            )
        } else {
            "; it was written by a newer build".to_string()
        };
        return Err(FrameError(format!(
            "{what} has format version {got}, this build reads {version}{why}"
        )));
    }
    let crc = u32::from_le_bytes(bytes[12..16].try_into().expect("4 bytes"));
    let payload = &bytes[16..];
    if crc32fast::hash(payload) != crc {
        return Err(FrameError(format!(
            "{what} checksum mismatch (truncated or corrupted)"
        )));
    }
    let mut de = rmp_serde::Deserializer::new(std::io::Cursor::new(payload));
    let value = T::deserialize(&mut de).map_err(|e| FrameError(format!("{what} payload: {e}")))?;
    let read = de.position();
    if read != payload.len() as u64 {
        return Err(FrameError(format!(
            "{what} payload: {} bytes after its end (another file appended?)",
            payload.len() as u64 - read
        )));
    }
    Ok(value)
}

/// Reads the file at `path` if it holds at most `limit` bytes (a device or a file of unbounded
/// length is refused once `limit` bytes have been read, not read to the end).
pub fn read_at_most(path: &std::path::Path, limit: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let mut bytes = Vec::new();
    std::fs::File::open(path)?
        .take(limit + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("larger than {limit} bytes, the most this file may hold"),
        ));
    }
    Ok(bytes)
}

/// [`read_at_most`] for a text file: its bytes as UTF-8.
pub fn read_text_at_most(path: &std::path::Path, limit: u64) -> std::io::Result<String> {
    String::from_utf8(read_at_most(path, limit)?).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text ({e})"),
        )
    })
}
