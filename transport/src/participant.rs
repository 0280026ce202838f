//! A process of a run on its zenoh session: the one place where the plant, the controller and
//! the recorder send and receive, so that every message is enveloped, sealed and checked the
//! same way (`docs/security.md`).
//!
//! - [`Participant::outlet`]: a publisher that puts each message with its envelope (the run
//!   instance, this process's role and id, the next sequence number on the key) and, in an
//!   authenticated run, its seal;
//! - [`Participant::subscribe`]: a subscriber whose callback runs the arrival [`Gate`] (size,
//!   envelope and seal, run instance, sender, exactly once) and hands what passes to an
//!   [`Inlet`] (a byte-bounded queue: [`queue`]); refusals and overflow are counted by cause;
//! - [`Participant::query`] and [`Participant::answer`]: a question with a fresh random challenge
//!   and the sealed answers that echo it. A process learns the run instance this way: a replayed
//!   answer of an earlier run fails the challenge, a rival queryable without the message key
//!   fails the seal, and every answer is looked at (no zenoh reply consolidation), so no rival
//!   can make the plant's own answer be dropped;
//! - [`Participant::departures`]: the liveliness tokens of a role, which say only that a
//!   process went away, never who is who.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossbeam_channel::{unbounded, Receiver, Sender};
use zenoh::qos::CongestionControl;
use zenoh::query::{ConsolidationMode, QueryTarget};
use zenoh::sample::SampleKind;
use zenoh::Wait;

use crawler_protocol::envelope::CHALLENGE_LEN;
use crawler_protocol::{Header, ProcessId, Role, RunKeys, RunNonce};

use crate::budget::{ByteBudget, Charged};
use crate::gate::{envelope, open, Accept, Gate, Refusal, Refused, RunInstance};
use crate::seal::Seal;

fn z(e: zenoh::Error) -> anyhow::Error {
    anyhow::anyhow!("zenoh: {e}")
}

/// A fresh run instance: 128 random bits from the operating system (the plant draws one when it
/// starts).
pub fn fresh_nonce() -> anyhow::Result<RunNonce> {
    let mut n = [0u8; 16];
    getrandom::fill(&mut n)
        .map_err(|e| anyhow::anyhow!("no random numbers from the operating system: {e}"))?;
    Ok(RunNonce(n))
}

/// A message that passed the arrival gate: its envelope's header and its payload (undecoded).
#[derive(Debug, Clone, PartialEq)]
pub struct Admitted {
    /// Who sent it, in which run instance, with which sequence number.
    pub header: Header,
    /// The message.
    pub bytes: Vec<u8>,
}

/// Where a subscription hands what passed its gate: `offer` returns false if there is no room
/// (the message is then dropped and counted as overflow).
pub trait Inlet: Send + Sync + 'static {
    /// Takes `m`, or returns false.
    fn offer(&self, m: Admitted) -> bool;
}

impl<F: Fn(Admitted) -> bool + Send + Sync + 'static> Inlet for F {
    fn offer(&self, m: Admitted) -> bool {
        self(m)
    }
}

/// The producing side of a byte-bounded queue (see [`queue`]).
#[derive(Debug, Clone)]
pub struct Queue {
    tx: Sender<Charged<Admitted>>,
    budget: ByteBudget,
}

impl Inlet for Queue {
    fn offer(&self, m: Admitted) -> bool {
        let len = m.bytes.len();
        self.budget
            .charge(m, len)
            .is_some_and(|c| self.tx.send(c).is_ok())
    }
}

impl Queue {
    /// The queue's budget.
    pub fn budget(&self) -> &ByteBudget {
        &self.budget
    }
}

/// A queue of admitted messages bounded by `budget` bytes ([`ByteBudget`]): its inlet and its
/// receiver (each message holds its bytes of the budget until dropped).
pub fn queue(budget: usize) -> (Queue, Receiver<Charged<Admitted>>) {
    let (tx, rx) = unbounded();
    (
        Queue {
            tx,
            budget: ByteBudget::new(budget),
        },
        rx,
    )
}

/// How a publisher behaves when the link is congested.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Congestion {
    /// Wait for room (every message the run depends on).
    Block,
    /// Drop (nothing of the run's).
    Drop,
}

/// A publisher of this process on one key: every message gets its envelope and seal.
pub struct Outlet {
    publisher: zenoh::pubsub::Publisher<'static>,
    key: String,
    seq: AtomicU64,
    role: Role,
    id: ProcessId,
    run: RunInstance,
    seal: Option<Seal>,
}

impl Outlet {
    /// Publishes `bytes` with the next sequence number (an error before the run instance is
    /// known, or if zenoh fails).
    pub fn put(&self, bytes: Vec<u8>) -> anyhow::Result<()> {
        let run = self.run.get().ok_or_else(|| {
            anyhow::anyhow!(
                "cannot publish on {} before the run's instance is known",
                self.key
            )
        })?;
        let header = Header {
            run,
            role: self.role,
            sender: self.id,
            seq: self.seq.fetch_add(1, Ordering::Relaxed) + 1,
        };
        let att = envelope(self.seal.as_ref(), &self.key, &header, &[], &bytes);
        self.publisher.put(bytes).attachment(att).wait().map_err(z)
    }

    /// The key it publishes on.
    pub fn key(&self) -> &str {
        &self.key
    }
}

/// An answer to a [`Participant::query`]: the sealed reply that echoed the challenge.
#[derive(Debug, Clone, PartialEq)]
pub struct Answer {
    /// Who answered, in which run instance.
    pub header: Header,
    /// The answer (undecoded).
    pub bytes: Vec<u8>,
}

/// A process of a run on its session.
pub struct Participant {
    session: zenoh::Session,
    role: Role,
    id: ProcessId,
    seal: Option<Seal>,
    run: RunInstance,
    refused: Arc<Refused>,
}

impl Participant {
    /// Process `id` of `role` on `session`, sealing with `seal` (`None`: an unauthenticated
    /// run), in run instance `run` (known for the plant, learnt by the others).
    pub fn new(
        session: zenoh::Session,
        role: Role,
        id: ProcessId,
        seal: Option<Seal>,
        run: RunInstance,
    ) -> Self {
        Self {
            session,
            role,
            id,
            seal,
            run,
            refused: Arc::default(),
        }
    }

    /// The same participant counting its refusals into `refused` (shared with an earlier
    /// session of the same process).
    pub fn counting_into(self, refused: Arc<Refused>) -> Self {
        Self { refused, ..self }
    }

    /// The session.
    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// This process's id.
    pub fn id(&self) -> ProcessId {
        self.id
    }

    /// The run instance (known, or to be learnt).
    pub fn run(&self) -> &RunInstance {
        &self.run
    }

    /// The seal of an authenticated run.
    pub fn seal(&self) -> Option<&Seal> {
        self.seal.as_ref()
    }

    /// Everything this process refused at arrival, by cause (every gate it made counts here).
    pub fn refused(&self) -> &Arc<Refused> {
        &self.refused
    }

    /// A gate for payloads of at most `limit` bytes from the senders `accept` admits, counting
    /// into this process's counters.
    pub fn gate(&self, limit: usize, accept: Accept) -> Gate {
        Gate::new(
            limit,
            self.seal.clone(),
            self.run.clone(),
            accept,
            self.refused.clone(),
        )
    }

    /// Subscribes to `key`: what passes `gate` goes to `inlet` (no room: counted as overflow).
    pub fn subscribe(
        &self,
        key: &str,
        gate: Gate,
        inlet: impl Inlet,
    ) -> anyhow::Result<zenoh::pubsub::Subscriber<()>> {
        let refused = self.refused.clone();
        self.session
            .declare_subscriber(key.to_string())
            .callback(move |sample| {
                let payload = sample.payload().to_bytes();
                let att = sample.attachment().map(|a| a.to_bytes());
                let Ok(header) = gate.check(sample.key_expr().as_str(), &payload, att.as_deref())
                else {
                    return;
                };
                let m = Admitted {
                    header,
                    bytes: payload.into_owned(),
                };
                if !inlet.offer(m) {
                    refused.count(Refusal::Overflow);
                }
            })
            .wait()
            .map_err(z)
    }

    /// A publisher on `key`.
    pub fn outlet(
        &self,
        key: &str,
        congestion: Congestion,
        express: bool,
    ) -> anyhow::Result<Outlet> {
        let publisher = self
            .session
            .declare_publisher(key.to_string())
            .congestion_control(match congestion {
                Congestion::Block => CongestionControl::Block,
                Congestion::Drop => CongestionControl::Drop,
            })
            .express(express)
            .wait()
            .map_err(z)?;
        Ok(Outlet {
            publisher,
            key: key.to_string(),
            seq: AtomicU64::new(0),
            role: self.role,
            id: self.id,
            run: self.run.clone(),
            seal: self.seal.clone(),
        })
    }

    /// Asks `key` with a fresh random challenge and returns the first answer of at most `limit`
    /// bytes from a process of role `from` that echoes the challenge, is sealed (authenticated
    /// runs) and, if this process knows the run instance already, is of that instance; `None` if
    /// none came within `timeout`. Every reply is looked at (no consolidation, every
    /// queryable); the others are counted as refused.
    pub fn query(
        &self,
        key: &str,
        from: Role,
        limit: usize,
        timeout: Duration,
    ) -> anyhow::Result<Option<Answer>> {
        let mut challenge = [0u8; CHALLENGE_LEN];
        getrandom::fill(&mut challenge)
            .map_err(|e| anyhow::anyhow!("no random numbers from the operating system: {e}"))?;
        let replies = self
            .session
            .get(key.to_string())
            .payload(challenge.to_vec())
            .consolidation(ConsolidationMode::None)
            .target(QueryTarget::All)
            .timeout(timeout)
            .wait()
            .map_err(z)?;
        while let Ok(reply) = replies.recv() {
            let Ok(sample) = reply.result() else { continue };
            let payload = sample.payload().to_bytes();
            if payload.len() > limit {
                self.refused.count(Refusal::Oversize);
                continue;
            }
            let att = sample.attachment().map(|a| a.to_bytes());
            let opened = open(
                self.seal.as_ref(),
                sample.key_expr().as_str(),
                &payload,
                att.as_deref(),
                CHALLENGE_LEN,
            );
            let Some((header, echoed)) = opened else {
                self.refused.count(Refusal::Unsealed);
                continue;
            };
            let refusal = if echoed != challenge {
                // an answer to another question: a replay
                Some(Refusal::Replayed)
            } else if header.role != from {
                Some(Refusal::Foreign)
            } else if self.run.get().is_some_and(|r| r != header.run) {
                Some(Refusal::OtherRun)
            } else {
                None
            };
            match refusal {
                Some(r) => self.refused.count(r),
                None => {
                    return Ok(Some(Answer {
                        header,
                        bytes: payload.into_owned(),
                    }))
                }
            }
        }
        Ok(None)
    }

    /// Answers every query on `key` that carries a challenge with `bytes`, enveloped with the
    /// challenge and sealed.
    pub fn answer(&self, key: &str, bytes: Vec<u8>) -> anyhow::Result<zenoh::query::Queryable<()>> {
        let (run, seal, role, id) = (self.run.clone(), self.seal.clone(), self.role, self.id);
        let seq = AtomicU64::new(0);
        let key = key.to_string();
        self.session
            .declare_queryable(key.clone())
            .callback(move |query| {
                let Some(challenge) = query.payload().map(|p| p.to_bytes()) else {
                    return;
                };
                let Some(run) = run.get() else { return };
                if challenge.len() != CHALLENGE_LEN {
                    return;
                }
                let header = Header {
                    run,
                    role,
                    sender: id,
                    seq: seq.fetch_add(1, Ordering::Relaxed) + 1,
                };
                let att = envelope(seal.as_ref(), &key, &header, &challenge, &bytes);
                let _ = query
                    .reply(key.as_str(), bytes.clone())
                    .attachment(att)
                    .wait();
            })
            .wait()
            .map_err(z)
    }

    /// Declares this process's liveliness token in the run of `keys`.
    pub fn token(&self, keys: &RunKeys) -> anyhow::Result<zenoh::liveliness::LivelinessToken> {
        self.session
            .liveliness()
            .declare_token(keys.alive(self.role, self.id.as_str()))
            .wait()
            .map_err(z)
    }

    /// Calls `gone` with the id of every process of `role` whose liveliness token disappears (a
    /// token says that a process went away; who is who is decided by sealed messages).
    pub fn departures(
        &self,
        keys: &RunKeys,
        role: Role,
        gone: impl Fn(ProcessId) + Send + Sync + 'static,
    ) -> anyhow::Result<zenoh::pubsub::Subscriber<()>> {
        let k = keys.clone();
        self.session
            .liveliness()
            .declare_subscriber(keys.alive_all(role))
            .callback(move |sample| {
                if sample.kind() != SampleKind::Delete {
                    return;
                }
                if let Some(id) = k
                    .id_of_alive_key(role, sample.key_expr().as_str())
                    .and_then(|id| ProcessId::parse(id).ok())
                {
                    gone(id);
                }
            })
            .wait()
            .map_err(z)
    }

    /// Closes the session.
    pub fn close(self) {
        let _ = self.session.close().wait();
    }
}
