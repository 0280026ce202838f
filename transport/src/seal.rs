//! Message seals: HMAC-SHA256 over a message's key expression and payload, under the run's
//! message key ([`crate::credential::Credential::message_key`]), carried in the zenoh sample's
//! attachment (32 bytes). The payload itself is unchanged (`docs/protocol.md`).
//!
//! A seal binds the message to its key (a status cannot be replayed as an actuation) and to the
//! run (each run has its own key). It does not stop the replay of a run's own earlier messages on
//! the same key; receivers reject those by their step (stale, duplicate) or their content.

use hmac::{Hmac, Mac};
use sha2::Sha256;

/// Bytes of a seal.
pub const SEAL_LEN: usize = 32;

/// Domain separation: what a seal is over.
const LABEL: &[u8] = b"crawler seal 1\0";

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

    fn mac(&self, key_expr: &str, payload: &[u8]) -> Hmac<Sha256> {
        let mut mac = self.keyed.clone();
        mac.update(LABEL);
        mac.update(&(key_expr.len() as u64).to_le_bytes());
        mac.update(key_expr.as_bytes());
        mac.update(payload);
        mac
    }

    /// The seal of `payload` published on `key_expr`.
    pub fn seal(&self, key_expr: &str, payload: &[u8]) -> [u8; SEAL_LEN] {
        self.mac(key_expr, payload).finalize().into_bytes().into()
    }

    /// True if `seal` is the seal of `payload` on `key_expr` (compared in constant time).
    pub fn verify(&self, key_expr: &str, payload: &[u8], seal: &[u8]) -> bool {
        seal.len() == SEAL_LEN && self.mac(key_expr, payload).verify_slice(seal).is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_seal_verifies_only_its_key_payload_and_run_key() {
        let s = Seal::new(&[7; 32]);
        let t = s.seal("crawler/r/actuation", b"payload");
        assert!(s.verify("crawler/r/actuation", b"payload", &t));
        assert!(!s.verify("crawler/r/status/plant", b"payload", &t));
        assert!(!s.verify("crawler/r/actuation", b"payloaD", &t));
        assert!(!s.verify("crawler/r/actuation", b"payload", &t[..31]));
        assert!(!s.verify("crawler/r/actuation", b"payload", &[]));
        let mut flipped = t;
        flipped[31] ^= 1;
        assert!(!s.verify("crawler/r/actuation", b"payload", &flipped));
        assert!(!Seal::new(&[8; 32]).verify("crawler/r/actuation", b"payload", &t));
        // the key expression's length is bound: moving bytes between key and payload fails
        let t2 = s.seal("crawler/r/a", b"bc");
        assert!(!s.verify("crawler/r/ab", b"c", &t2));
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
