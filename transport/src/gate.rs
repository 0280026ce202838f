//! What every subscriber checks at arrival, in the zenoh callback, before a payload is copied or
//! queued, in this order: its size against the key's largest legal message; its envelope and
//! (in an authenticated run) its seal; its run instance; its sender (role, and id where the
//! receiver knows whom it expects); and that it is newer than the last message taken from that
//! sender on that key (exactly once). Whatever fails is dropped there and counted by cause;
//! nothing else reaches an inbox.
//!
//! Pure: no zenoh here (the [`crate::participant`] feeds it what arrives), so every rule is
//! tested on bytes.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, RwLock};

use crawler_protocol::envelope::{role_byte, HEADER_LEN, ID_LEN};
use crawler_protocol::{Header, ProcessId, Role, RunNonce};

use crate::seal::{Seal, SEAL_LEN};

/// Payloads refused at arrival, by cause.
#[derive(Debug, Default)]
pub struct Refused {
    /// Larger than the key's largest legal message.
    pub oversize: AtomicU64,
    /// Without a valid envelope, or (authenticated runs) without a valid seal: not from a
    /// process holding the credential.
    pub unsealed: AtomicU64,
    /// Of another run instance (an earlier run with the same credential).
    pub other_run: AtomicU64,
    /// Arrived before this process knew the run's instance (a process that joins learns it
    /// from the plant; what the plant sent before is not for it).
    pub early: AtomicU64,
    /// From a sender that may not send on the key (another role, or not the expected process).
    pub foreign: AtomicU64,
    /// Not newer than the last message taken from its sender on the key: a replay.
    pub replayed: AtomicU64,
    /// Admitted but beyond the inbox's budget, or from one sender too many to keep track of.
    pub overflow: AtomicU64,
}

impl Refused {
    fn load(c: &AtomicU64) -> u64 {
        c.load(Ordering::Relaxed)
    }

    /// Oversized payloads so far.
    pub fn oversize(&self) -> u64 {
        Self::load(&self.oversize)
    }

    /// Payloads without a valid envelope or seal so far.
    pub fn unsealed(&self) -> u64 {
        Self::load(&self.unsealed)
    }

    /// Payloads of another run instance so far.
    pub fn other_run(&self) -> u64 {
        Self::load(&self.other_run)
    }

    /// Payloads that arrived before the run's instance was known, so far.
    pub fn early(&self) -> u64 {
        Self::load(&self.early)
    }

    /// Payloads from senders that may not send on their key so far.
    pub fn foreign(&self) -> u64 {
        Self::load(&self.foreign)
    }

    /// Replays so far.
    pub fn replayed(&self) -> u64 {
        Self::load(&self.replayed)
    }

    /// Payloads beyond an inbox's budget so far.
    pub fn overflow(&self) -> u64 {
        Self::load(&self.overflow)
    }

    /// Everything refused so far.
    pub fn total(&self) -> u64 {
        self.oversize()
            + self.unsealed()
            + self.other_run()
            + self.early()
            + self.foreign()
            + self.replayed()
            + self.overflow()
    }

    /// Counts one refusal.
    pub fn count(&self, r: Refusal) {
        let c = match r {
            Refusal::Oversize => &self.oversize,
            Refusal::Unsealed => &self.unsealed,
            Refusal::OtherRun => &self.other_run,
            Refusal::Early => &self.early,
            Refusal::Foreign => &self.foreign,
            Refusal::Replayed => &self.replayed,
            Refusal::Overflow => &self.overflow,
        };
        c.fetch_add(1, Ordering::Relaxed);
    }

    /// What was refused, in words; `None` if nothing was.
    pub fn describe(&self) -> Option<String> {
        (self.total() > 0).then(|| {
            format!(
                "{} oversized, {} without a valid envelope or seal, {} of another run instance, {} before the run's instance was known, {} from senders that may not send there, {} replayed, {} beyond an inbox's budget",
                self.oversize(),
                self.unsealed(),
                self.other_run(),
                self.early(),
                self.foreign(),
                self.replayed(),
                self.overflow()
            )
        })
    }
}

/// Why a payload was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// Larger than allowed.
    Oversize,
    /// No valid envelope or seal.
    Unsealed,
    /// Another run instance.
    OtherRun,
    /// Before the run's instance was known.
    Early,
    /// A sender that may not send on the key.
    Foreign,
    /// Not newer than what was taken from its sender.
    Replayed,
    /// No room.
    Overflow,
}

/// The run instance a process belongs to: drawn by the plant, learnt by the others from the
/// plant's sealed reply to a challenge. Shared by every gate of a process.
#[derive(Debug, Clone, Default)]
pub struct RunInstance(Arc<RwLock<Option<RunNonce>>>);

impl RunInstance {
    /// A run instance known from the start (the plant's own).
    pub fn known(nonce: RunNonce) -> Self {
        Self(Arc::new(RwLock::new(Some(nonce))))
    }

    /// The instance, once known.
    pub fn get(&self) -> Option<RunNonce> {
        *self.0.read().unwrap_or_else(|e| e.into_inner())
    }

    /// Learns the instance (from a reply whose seal and challenge were checked).
    pub fn learn(&self, nonce: RunNonce) {
        *self.0.write().unwrap_or_else(|e| e.into_inner()) = Some(nonce);
    }
}

/// A set of process ids shared between the gates that check it and the code that changes it
/// (the plant's joined controller, the recorder's plant once known).
#[derive(Debug, Clone, Default)]
pub struct Senders(Arc<RwLock<Vec<ProcessId>>>);

impl Senders {
    /// A set holding `ids`.
    pub fn of(ids: &[ProcessId]) -> Self {
        Self(Arc::new(RwLock::new(ids.to_vec())))
    }

    /// Replaces the set.
    pub fn set(&self, ids: &[ProcessId]) {
        *self.0.write().unwrap_or_else(|e| e.into_inner()) = ids.to_vec();
    }

    /// True if `id` is in the set.
    pub fn contains(&self, id: &ProcessId) -> bool {
        self.0
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .contains(id)
    }
}

/// Who may send on a key.
#[derive(Debug, Clone)]
pub enum Accept {
    /// Any process of this role.
    Role(Role),
    /// The processes of this role in the set.
    Ids(Role, Senders),
    /// Any process of the role that the key's last segment names (`status/<role>`).
    RoleOfKey,
}

impl Accept {
    fn admits(&self, key_expr: &str, h: &Header) -> bool {
        match self {
            Accept::Role(r) => h.role == *r,
            Accept::Ids(r, ids) => h.role == *r && ids.contains(&h.sender),
            Accept::RoleOfKey => key_expr
                .rsplit('/')
                .next()
                .and_then(Role::parse)
                .is_some_and(|r| r == h.role),
        }
    }
}

/// Most senders one gate keeps track of (a run has a plant, a controller or two and a
/// recorder): beyond, a new sender's messages are refused rather than the table grown.
pub const MAX_SENDERS: usize = 64;

/// The last sequence number taken from each sender: what makes a message count at most once.
#[derive(Debug, Default)]
pub struct Taken(HashMap<(u8, [u8; ID_LEN]), u64>);

impl Taken {
    /// Takes `h` if it is newer than the last message taken from its sender.
    pub fn take(&mut self, h: &Header) -> Result<(), Refusal> {
        let key = (role_byte(h.role), *h.sender.as_bytes());
        let senders = self.0.len();
        match self.0.get_mut(&key) {
            Some(last) if h.seq <= *last => Err(Refusal::Replayed),
            Some(last) => {
                *last = h.seq;
                Ok(())
            }
            None if senders >= MAX_SENDERS => Err(Refusal::Overflow),
            None => {
                self.0.insert(key, h.seq);
                Ok(())
            }
        }
    }
}

/// The arrival check of one subscription (clones share the limit, the table and the counters).
#[derive(Debug, Clone)]
pub struct Gate {
    limit: Arc<AtomicUsize>,
    seal: Option<Seal>,
    run: RunInstance,
    accept: Accept,
    taken: Arc<Mutex<Taken>>,
    refused: Arc<Refused>,
}

impl Gate {
    /// Admits payloads of at most `limit` bytes of run instance `run` from senders that
    /// `accept` admits, each newer than the last taken from its sender, sealed under `seal`
    /// (`None`: an unauthenticated run, whose envelopes carry no seal); refusals are counted in
    /// `refused`.
    pub fn new(
        limit: usize,
        seal: Option<Seal>,
        run: RunInstance,
        accept: Accept,
        refused: Arc<Refused>,
    ) -> Self {
        Self {
            limit: Arc::new(AtomicUsize::new(limit)),
            seal,
            run,
            accept,
            taken: Arc::default(),
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

    /// Checks a payload that arrived on `key_expr` with `attachment`; returns its envelope's
    /// header, or why it was refused (counted).
    pub fn check(
        &self,
        key_expr: &str,
        payload: &[u8],
        attachment: Option<&[u8]>,
    ) -> Result<Header, Refusal> {
        self.classify(key_expr, payload, attachment)
            .inspect_err(|r| self.refused.count(*r))
    }

    fn classify(
        &self,
        key_expr: &str,
        payload: &[u8],
        attachment: Option<&[u8]>,
    ) -> Result<Header, Refusal> {
        if payload.len() > self.limit.load(Ordering::Relaxed) {
            return Err(Refusal::Oversize);
        }
        let header = open(self.seal.as_ref(), key_expr, payload, attachment, 0)
            .ok_or(Refusal::Unsealed)?
            .0;
        match self.run.get() {
            None => return Err(Refusal::Early),
            Some(run) if run != header.run => return Err(Refusal::OtherRun),
            Some(_) => {}
        }
        if !self.accept.admits(key_expr, &header) {
            return Err(Refusal::Foreign);
        }
        self.taken
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take(&header)?;
        Ok(header)
    }
}

/// The envelope of `payload` on `key_expr` from `attachment`, if it is well formed and (with
/// `seal`) sealed: its header and the `extra` bytes after it (a reply's challenge).
pub fn open<'a>(
    seal: Option<&Seal>,
    key_expr: &str,
    payload: &[u8],
    attachment: Option<&'a [u8]>,
    extra: usize,
) -> Option<(Header, &'a [u8])> {
    let att = attachment?;
    let meta_len = HEADER_LEN + extra;
    let expected = meta_len + if seal.is_some() { SEAL_LEN } else { 0 };
    if att.len() != expected {
        return None;
    }
    let (meta, tag) = att.split_at(meta_len);
    if let Some(s) = seal {
        if !s.verify(key_expr, meta, payload, tag) {
            return None;
        }
    }
    let header = Header::decode(meta).ok()?;
    Some((header, &meta[HEADER_LEN..]))
}

/// The attachment of `payload` on `key_expr` sent with `header` (and `extra` bytes after it, a
/// reply's challenge): the envelope, sealed when `seal` is given.
pub fn envelope(
    seal: Option<&Seal>,
    key_expr: &str,
    header: &Header,
    extra: &[u8],
    payload: &[u8],
) -> Vec<u8> {
    let mut att = Vec::with_capacity(HEADER_LEN + extra.len() + SEAL_LEN);
    att.extend_from_slice(&header.encode());
    att.extend_from_slice(extra);
    if let Some(s) = seal {
        let tag = s.seal(key_expr, &att, payload);
        att.extend_from_slice(&tag);
    }
    att
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEY: &str = "crawler/r/state";

    fn id(s: &str) -> ProcessId {
        ProcessId::parse(s).unwrap()
    }

    fn header(run: u8, role: Role, sender: &str, seq: u64) -> Header {
        Header {
            run: RunNonce([run; 16]),
            role,
            sender: id(sender),
            seq,
        }
    }

    fn plant(seq: u64) -> Header {
        header(1, Role::Plant, "000000000000000a", seq)
    }

    fn gate(seal: Option<Seal>, accept: Accept) -> Gate {
        Gate::new(
            100,
            seal,
            RunInstance::known(RunNonce([1; 16])),
            accept,
            Arc::default(),
        )
    }

    fn check(g: &Gate, h: &Header, payload: &[u8], seal: Option<&Seal>) -> Result<Header, Refusal> {
        let att = envelope(seal, KEY, h, &[], payload);
        g.check(KEY, payload, Some(&att))
    }

    #[test]
    fn each_sender_is_taken_once_in_order_and_replays_are_refused() {
        let s = Seal::new(&[3; 32]);
        let g = gate(Some(s.clone()), Accept::Role(Role::Plant));
        assert_eq!(check(&g, &plant(1), b"a", Some(&s)), Ok(plant(1)));
        assert_eq!(check(&g, &plant(2), b"b", Some(&s)), Ok(plant(2)));
        // the same message again, an older one, and one that skips ahead (a lost message is
        // not a reason to refuse what follows)
        assert_eq!(check(&g, &plant(2), b"b", Some(&s)), Err(Refusal::Replayed));
        assert_eq!(check(&g, &plant(1), b"a", Some(&s)), Err(Refusal::Replayed));
        assert_eq!(check(&g, &plant(9), b"c", Some(&s)), Ok(plant(9)));
        assert_eq!(check(&g, &plant(5), b"d", Some(&s)), Err(Refusal::Replayed));
        // another sender has its own count
        let other = header(1, Role::Plant, "000000000000000b", 1);
        assert_eq!(check(&g, &other, b"e", Some(&s)), Ok(other));
        assert_eq!(g.refused().replayed(), 3);
        assert_eq!(g.refused().total(), 3);
    }

    #[test]
    fn another_run_instance_is_refused_whatever_its_seal_says() {
        let s = Seal::new(&[3; 32]);
        let g = gate(Some(s.clone()), Accept::Role(Role::Plant));
        // sealed with the run's key (a credential kept for two runs), of an earlier instance
        let earlier = header(2, Role::Plant, "000000000000000a", 1);
        assert_eq!(check(&g, &earlier, b"a", Some(&s)), Err(Refusal::OtherRun));
        // a process that does not know the instance yet refuses everything, counted apart
        let blind = Gate::new(
            100,
            Some(s.clone()),
            RunInstance::default(),
            Accept::Role(Role::Plant),
            Arc::default(),
        );
        assert_eq!(
            check(&blind, &plant(1), b"a", Some(&s)),
            Err(Refusal::Early)
        );
        assert_eq!(g.refused().other_run(), 1);
        assert_eq!(g.refused().early(), 0);
        assert_eq!(
            (blind.refused().early(), blind.refused().other_run()),
            (1, 0)
        );
        assert_eq!(blind.refused().total(), 1);
    }

    #[test]
    fn only_accepted_senders_pass_and_a_refusal_takes_nothing() {
        let s = Seal::new(&[3; 32]);
        let joined = Senders::of(&[id("00000000000000c1")]);
        let g = gate(
            Some(s.clone()),
            Accept::Ids(Role::Controller, joined.clone()),
        );
        let c1 = |seq| header(1, Role::Controller, "00000000000000c1", seq);
        let c2 = header(1, Role::Controller, "00000000000000c2", 1);
        assert_eq!(check(&g, &c1(1), b"a", Some(&s)), Ok(c1(1)));
        assert_eq!(check(&g, &c2, b"a", Some(&s)), Err(Refusal::Foreign));
        // the plant claiming to be c1
        let mut wrong_role = c1(2);
        wrong_role.role = Role::Plant;
        assert_eq!(
            check(&g, &wrong_role, b"a", Some(&s)),
            Err(Refusal::Foreign)
        );
        // c2 joins: its first message passes (the refused one was not taken)
        joined.set(&[id("00000000000000c2")]);
        assert_eq!(check(&g, &c2, b"a", Some(&s)), Ok(c2));
        assert_eq!(check(&g, &c1(2), b"a", Some(&s)), Err(Refusal::Foreign));
        // a status key names its sender's role
        let st = gate(Some(s.clone()), Accept::RoleOfKey);
        let att = envelope(Some(&s), "crawler/r/status/plant", &plant(1), &[], b"x");
        assert!(st.check("crawler/r/status/plant", b"x", Some(&att)).is_ok());
        let att = envelope(
            Some(&s),
            "crawler/r/status/controller",
            &plant(2),
            &[],
            b"x",
        );
        assert_eq!(
            st.check("crawler/r/status/controller", b"x", Some(&att)),
            Err(Refusal::Foreign)
        );
    }

    #[test]
    fn without_the_message_key_nothing_passes() {
        let s = Seal::new(&[3; 32]);
        let g = gate(Some(s.clone()), Accept::Role(Role::Plant));
        // no attachment, an envelope without a seal, a seal under another key, a seal over
        // another payload, a header changed after sealing
        assert_eq!(g.check(KEY, b"a", None), Err(Refusal::Unsealed));
        assert_eq!(check(&g, &plant(1), b"a", None), Err(Refusal::Unsealed));
        assert_eq!(
            check(&g, &plant(1), b"a", Some(&Seal::new(&[4; 32]))),
            Err(Refusal::Unsealed)
        );
        let att = envelope(Some(&s), KEY, &plant(1), &[], b"a");
        assert_eq!(g.check(KEY, b"b", Some(&att)), Err(Refusal::Unsealed));
        let mut forged = att.clone();
        forged[41] ^= 1; // the sequence number
        assert_eq!(g.check(KEY, b"a", Some(&forged)), Err(Refusal::Unsealed));
        assert_eq!(
            g.check("crawler/r/events", b"a", Some(&att)),
            Err(Refusal::Unsealed)
        );
        // oversize first, before anything else is looked at
        assert_eq!(g.check(KEY, &[0; 101], None), Err(Refusal::Oversize));
        assert_eq!((g.refused().unsealed(), g.refused().oversize()), (6, 1));
        // the genuine one still passes: nothing above was taken
        assert!(g.check(KEY, b"a", Some(&att)).is_ok());
        // an unauthenticated run checks the envelope only
        let open = gate(None, Accept::Role(Role::Plant));
        assert!(check(&open, &plant(1), b"a", None).is_ok());
        assert_eq!(check(&open, &plant(1), b"a", None), Err(Refusal::Replayed));
        assert_eq!(
            check(&open, &plant(2), b"a", Some(&s)),
            Err(Refusal::Unsealed)
        );
    }

    #[test]
    fn a_gate_tracks_a_bounded_number_of_senders() {
        let g = gate(None, Accept::Role(Role::Controller));
        for i in 0..MAX_SENDERS {
            let h = header(1, Role::Controller, &format!("{i:016x}"), 1);
            assert!(check(&g, &h, b"a", None).is_ok());
        }
        let h = header(1, Role::Controller, "ffffffffffffffff", 1);
        assert_eq!(check(&g, &h, b"a", None), Err(Refusal::Overflow));
        // known senders go on
        let h = header(1, Role::Controller, &format!("{:016x}", 3), 2);
        assert!(check(&g, &h, b"a", None).is_ok());
    }
}
