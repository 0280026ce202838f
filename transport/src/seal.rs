//! Message seals: HMAC-SHA256 over a message's key expression, its envelope (the run instance,
//! the sender, the sequence number: [`crawler_protocol::envelope`]) and its payload, under the
//! run's message key ([`crate::credential::Credential::message_key`]), carried in the zenoh
//! sample's attachment after the envelope (32 bytes). The payload itself is unchanged
//! (`docs/protocol.md`).
//!
//! A seal binds the message to its key (a status cannot be replayed as an actuation), to the run
//! (each run id has its own key), to the run instance (a credential kept for several runs does
//! not make them one) and to its sender's sequence number, so that receivers can refuse a
//! replay of a run's own messages ([`crate::gate`]).

use hmac::{Hmac, Mac};
use sha2::Sha256;

/// Bytes of a seal.
pub const SEAL_LEN: usize = 32;

/// Domain separation: what a seal is over.
const LABEL: &[u8] = b"crawler seal 3\0";

/// Seals and checks messages under one run's message key.
#[derive(Clone)]
pub struct Seal {
    keyed: Hmac<Sha256>,
}

impl std::fmt::Debug for Seal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Seal(..)")
    }
}

impl Seal {
    /// A sealer under `key`.
    pub fn new(key: &[u8; 32]) -> Self {
        Self {
            keyed: <Hmac<Sha256> as Mac>::new_from_slice(key)
                .expect("HMAC takes a key of any length"),
        }
    }

    fn mac(&self, key_expr: &str, meta: &[u8], payload: &[u8]) -> Hmac<Sha256> {
        let mut mac = self.keyed.clone();
        mac.update(LABEL);
        mac.update(&(key_expr.len() as u64).to_le_bytes());
        mac.update(key_expr.as_bytes());
        mac.update(&(meta.len() as u64).to_le_bytes());
        mac.update(meta);
        mac.update(payload);
        mac
    }

    /// The seal of `payload` with the envelope `meta` (the header, and a reply's challenge)
    /// published on `key_expr`.
    pub fn seal(&self, key_expr: &str, meta: &[u8], payload: &[u8]) -> [u8; SEAL_LEN] {
        self.mac(key_expr, meta, payload)
            .finalize()
            .into_bytes()
            .into()
    }

    /// True if `seal` is the seal of `payload` with `meta` on `key_expr` (compared in constant
    /// time).
    pub fn verify(&self, key_expr: &str, meta: &[u8], payload: &[u8], seal: &[u8]) -> bool {
        seal.len() == SEAL_LEN && self.mac(key_expr, meta, payload).verify_slice(seal).is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_seal_verifies_only_its_key_envelope_payload_and_run_key() {
        let s = Seal::new(&[7; 32]);
        let k = "crawler/r/actuation";
        let t = s.seal(k, b"header", b"payload");
        assert!(s.verify(k, b"header", b"payload", &t));
        assert!(!s.verify("crawler/r/status/plant", b"header", b"payload", &t));
        assert!(!s.verify(k, b"header", b"payloaD", &t));
        assert!(!s.verify(k, b"headeR", b"payload", &t));
        assert!(!s.verify(k, b"header", b"payload", &t[..31]));
        assert!(!s.verify(k, b"header", b"payload", &[]));
        let mut flipped = t;
        flipped[31] ^= 1;
        assert!(!s.verify(k, b"header", b"payload", &flipped));
        assert!(!Seal::new(&[8; 32]).verify(k, b"header", b"payload", &t));
        // lengths are bound: moving bytes between key, envelope and payload fails
        let t2 = s.seal("crawler/r/a", b"hb", b"c");
        assert!(!s.verify("crawler/r/ah", b"b", b"c", &t2));
        assert!(!s.verify("crawler/r/a", b"h", b"bc", &t2));
    }

    #[test]
    fn seals_match_an_independent_hmac_sha256() {
        // RFC 4231 test case 2 checks the primitive itself: key "Jefe".
        let mut mac = <Hmac<Sha256> as Mac>::new_from_slice(b"Jefe").unwrap();
        mac.update(b"what do ya want for nothing?");
        let out: [u8; 32] = mac.finalize().into_bytes().into();
        let expected = "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843";
        let hex: String = out.iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(hex, expected);
    }
}
