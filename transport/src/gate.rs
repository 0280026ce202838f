//! What every subscriber checks at arrival, in the zenoh callback, before a payload is copied or
//! queued: its size against the key's largest legal message, then (in an authenticated run) its
//! seal. Whatever fails is dropped there and counted; nothing else reaches an inbox.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;

use zenoh::bytes::ZBytes;
use zenoh::pubsub::Publisher;
use zenoh::sample::Sample;
use zenoh::Wait;

use crate::seal::Seal;

/// Payloads refused at arrival, by cause.
#[derive(Debug, Default)]
pub struct Refused {
    /// Larger than the key's largest legal message.
    pub oversize: AtomicU64,
    /// Without a valid seal (authenticated runs): not from a process holding the credential.
    pub unsealed: AtomicU64,
}

impl Refused {
    /// Oversized payloads so far.
    pub fn oversize(&self) -> u64 {
        self.oversize.load(Ordering::Relaxed)
    }

    /// Unsealed or wrongly sealed payloads so far.
    pub fn unsealed(&self) -> u64 {
        self.unsealed.load(Ordering::Relaxed)
    }
}

/// Why a payload was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// Larger than allowed.
    Oversize,
    /// No valid seal.
    Unsealed,
}

/// The arrival check of one key (clones share the limit and the counters).
#[derive(Debug, Clone)]
pub struct Gate {
    limit: Arc<AtomicUsize>,
    seal: Option<Seal>,
    refused: Arc<Refused>,
}

impl Gate {
    /// Admits payloads of at most `limit` bytes carrying a valid seal under `seal` (any payload
    /// of that size when `seal` is `None`, an unauthenticated run); refusals are counted in
    /// `refused`.
    pub fn new(limit: usize, seal: Option<Seal>, refused: Arc<Refused>) -> Self {
        Self {
            limit: Arc::new(AtomicUsize::new(limit)),
            seal,
            refused,
        }
    }

    /// Changes the size limit (once the run's size is known), for this gate and its clones.
    pub fn set_limit(&self, limit: usize) {
        self.limit.store(limit, Ordering::Relaxed);
    }

    /// The counters of this gate.
    pub fn refused(&self) -> &Arc<Refused> {
        &self.refused
    }

    /// Checks a payload that arrived on `key_expr` with `attachment`; returns its bytes.
    pub fn check(
        &self,
        key_expr: &str,
        payload: &ZBytes,
        attachment: Option<&ZBytes>,
    ) -> Result<Vec<u8>, Refusal> {
        if payload.len() > self.limit.load(Ordering::Relaxed) {
            self.refused.oversize.fetch_add(1, Ordering::Relaxed);
            return Err(Refusal::Oversize);
        }
        let bytes = payload.to_bytes();
        if let Some(seal) = &self.seal {
            let ok = attachment.is_some_and(|a| seal.verify(key_expr, &bytes, &a.to_bytes()));
            if !ok {
                self.refused.unsealed.fetch_add(1, Ordering::Relaxed);
                return Err(Refusal::Unsealed);
            }
        }
        Ok(bytes.into_owned())
    }

    /// Checks a sample (see [`Gate::check`]).
    pub fn admit(&self, sample: &Sample) -> Result<Vec<u8>, Refusal> {
        self.check(
            sample.key_expr().as_str(),
            sample.payload(),
            sample.attachment(),
        )
    }
}

/// Publishes `bytes` on `publisher`, sealed when `seal` is given.
pub fn put(publisher: &Publisher<'_>, seal: Option<&Seal>, bytes: Vec<u8>) -> zenoh::Result<()> {
    match seal {
        Some(s) => {
            let tag = s.seal(publisher.key_expr().as_str(), &bytes);
            publisher.put(bytes).attachment(tag.to_vec()).wait()
        }
        None => publisher.put(bytes).wait(),
    }
}

/// The attachment sealing `bytes` on `key_expr`, if the run is authenticated (for replies and
/// one-off puts).
pub fn attachment(seal: Option<&Seal>, key_expr: &str, bytes: &[u8]) -> Option<Vec<u8>> {
    seal.map(|s| s.seal(key_expr, bytes).to_vec())
}
