//! The recorder's zenoh side: its session, its subscriptions to every key of the run, and the
//! inbox between the callbacks and the writer.
//!
//! The callbacks check each payload at arrival (size; in an authenticated run its seal) and queue
//! it within a byte budget. When the writer is behind and the budget is spent, a callback waits
//! for room (at most [`HOLD`]): zenoh then stops reading the link, the plant's blocking publisher
//! waits, and the run goes at the writer's pace instead of losing states. A writer behind for
//! longer than that (stalled, starved) makes the callbacks drop and count instead, until the
//! inbox has room again, so that it can never hold the run for long.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, Sender};
use zenoh::Wait;

use crawler_protocol::{decode, Environment, Message, ModelInfo, Role, RunKeys, RunLimits};
use crawler_transport::budget::{ByteBudget, Charged, OVERHEAD};
use crawler_transport::gate::{Gate, Refused};
use crawler_transport::{Credential, Network, Seal};

use crate::Incoming;

/// Byte budget of the states in the inbox between the zenoh callbacks and the writer (about 600
/// states of 512 cells, 0.2 s of the main job's lockstep: what `kill -9` of a writer that is
/// behind can lose on top of its last flush). The three budgets below (28 MiB together) are what
/// the inbox holds at most, so together with zenoh's buffers they stay well under the 64 MiB a
/// process may grow by (`docs/security.md`). A message larger than its budget (a state of more
/// than 200 000 cells) still passes when nothing else is queued.
pub const STATE_BYTES: usize = 8 << 20;
/// Byte budget of everything else in it (events, metrics, predictions): its own, so a backlog of
/// states never crowds them out.
pub const OTHER_BYTES: usize = 16 << 20;
/// Statuses have an inbox and a budget of their own: a flood of episodes must never drop the
/// plant's final status.
pub const STATUS_BYTES: usize = 4 << 20;
/// Messages the status inbox holds (a process sends about one status a second).
pub const STATUS_SLOTS: usize = 1024;
/// Longest a callback waits for room in the inbox before it drops (and counts) a message: well
/// under zenoh's lease (10 s), during which a link that is not read is still alive.
pub const HOLD: Duration = Duration::from_secs(2);

/// A message of the inbox with the moment it arrived.
pub type Arrival = (Instant, Charged<Incoming>);

/// The inbox: what the callbacks put in, and what the writer takes out.
pub struct Inbox {
    /// The callbacks' side.
    pub sink: Sink,
    /// States, events, metrics and predictions.
    pub rx: Receiver<Arrival>,
    /// Statuses.
    pub status_rx: Receiver<Arrival>,
    /// Plant liveliness (unbounded: never dropped).
    pub plant_rx: Receiver<Incoming>,
    /// Its sender, for each connection's liveliness subscriber.
    pub plant_tx: Sender<Incoming>,
    /// Payloads refused at arrival.
    pub refused: Arc<Refused>,
}

impl Inbox {
    /// An inbox of at most `slots` messages (and the byte budgets above).
    pub fn new(slots: usize) -> Self {
        let (tx, rx) = crossbeam_channel::bounded::<Arrival>(slots);
        let (status_tx, status_rx) = crossbeam_channel::bounded::<Arrival>(STATUS_SLOTS);
        let (plant_tx, plant_rx) = crossbeam_channel::unbounded::<Incoming>();
        Self {
            sink: Sink {
                tx,
                status_tx,
                statuses: ByteBudget::new(STATUS_BYTES),
                states: ByteBudget::new(STATE_BYTES),
                others: ByteBudget::new(OTHER_BYTES),
                dropped: Arc::default(),
                shedding: Arc::default(),
            },
            rx,
            status_rx,
            plant_rx,
            plant_tx,
            refused: Arc::new(Refused::default()),
        }
    }

    /// True if nothing waits in the inbox.
    pub fn is_empty(&self) -> bool {
        self.rx.is_empty() && self.status_rx.is_empty()
    }
}

/// Where the callbacks put what passed the gates.
#[derive(Clone)]
pub struct Sink {
    tx: Sender<Arrival>,
    status_tx: Sender<Arrival>,
    statuses: ByteBudget,
    states: ByteBudget,
    others: ByteBudget,
    dropped: Arc<AtomicU64>,
    /// Set while the callbacks drop instead of waiting (the writer was behind longer than
    /// [`HOLD`]); cleared by the writer once the inbox is less than half full.
    shedding: Arc<AtomicBool>,
}

impl Sink {
    /// Messages dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Lets the callbacks wait for room again once the inbox is less than half full (the
    /// writer calls it).
    pub fn relieve(&self) {
        let half = |b: &ByteBudget| b.used() <= b.cap() / 2;
        if self.shedding.load(Ordering::Relaxed)
            && half(&self.states)
            && half(&self.others)
            && self.tx.len() <= self.tx.capacity().unwrap_or(0) / 2
        {
            self.shedding.store(false, Ordering::Relaxed);
        }
    }

    /// Queues `msg` (`len` payload bytes), waiting at most [`HOLD`] for room; drops and counts
    /// it if there is none (or while shedding).
    pub fn offer(&self, msg: Incoming, len: usize) {
        let (budget, tx) = match msg {
            Incoming::State(_) => (&self.states, &self.tx),
            Incoming::Status(_) => (&self.statuses, &self.status_tx),
            _ => (&self.others, &self.tx),
        };
        let deadline = Instant::now() + HOLD;
        // wait for the budget to take it (as `charge` would: room, or nothing queued)
        let fits = || {
            let used = budget.used();
            used == 0 || used + len + OVERHEAD <= budget.cap()
        };
        let mut waited = false;
        while !fits() && !self.shedding.load(Ordering::Relaxed) && Instant::now() < deadline {
            waited = true;
            std::thread::sleep(Duration::from_micros(200));
        }
        let queued = budget
            .charge(msg, len)
            .is_some_and(|m| tx.send_deadline((Instant::now(), m), deadline).is_ok());
        if !queued {
            if waited || Instant::now() >= deadline {
                self.shedding.store(true, Ordering::Relaxed);
            }
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

fn subscribe(
    session: &zenoh::Session,
    key: String,
    gate: Gate,
    sink: Sink,
    wrap: fn(Vec<u8>) -> Incoming,
) -> anyhow::Result<zenoh::pubsub::Subscriber<()>> {
    session
        .declare_subscriber(key)
        .callback(move |sample| {
            // oversized and unsealed payloads are counted by the gate
            let Ok(bytes) = gate.admit(&sample) else {
                return;
            };
            let len = bytes.len();
            sink.offer(wrap(bytes), len);
        })
        .wait()
        .map_err(|e| anyhow::anyhow!("zenoh: {e}"))
}

/// The recorder's session and its subscriptions.
pub struct Connection {
    session: zenoh::Session,
    _subs: Vec<zenoh::pubsub::Subscriber<()>>,
    _plants: zenoh::pubsub::Subscriber<()>,
    _token: zenoh::liveliness::LivelinessToken,
    /// The gate of the state key (its limit is tightened once the run's size is known).
    pub state_gate: Gate,
    seal: Option<Seal>,
    /// Largest message reassembled, bytes.
    pub limit: usize,
}

impl Connection {
    /// Connects to the plant (waiting for it until `give_up`), reassembling at most `limit`
    /// bytes, subscribed to every key of the run; `id` is this process's.
    pub fn open(
        network: &Network,
        credential: &mut Option<Credential>,
        limit: usize,
        (inbox, id): (&Inbox, &str),
        give_up: &mut dyn FnMut() -> bool,
    ) -> anyhow::Result<Option<Self>> {
        let keys = RunKeys::new(&network.run_id)?;
        let Some((session, used)) = crawler_transport::connect_client(
            Role::Bridge,
            network,
            credential.clone(),
            limit,
            give_up,
        )?
        else {
            return Ok(None);
        };
        *credential = used;
        let seal = credential.as_ref().map(|c| Seal::new(&c.message_key()));
        let refused = &inbox.refused;
        let gate = |limit: usize| Gate::new(limit, seal.clone(), refused.clone());
        let state_gate = gate(limit);
        let sink = &inbox.sink;
        let subs = vec![
            subscribe(
                &session,
                keys.state(),
                state_gate.clone(),
                sink.clone(),
                Incoming::State,
            )?,
            subscribe(
                &session,
                keys.events(),
                gate(limit),
                sink.clone(),
                Incoming::Events,
            )?,
            subscribe(
                &session,
                keys.metrics(),
                gate(RunLimits::metrics()),
                sink.clone(),
                Incoming::Metrics,
            )?,
            subscribe(
                &session,
                keys.prediction(),
                gate(RunLimits::text_message()),
                sink.clone(),
                Incoming::Prediction,
            )?,
            subscribe(
                &session,
                keys.status_all(),
                gate(RunLimits::text_message()),
                sink.clone(),
                Incoming::Status,
            )?,
        ];
        let plants = watch_plants(&session, &keys, inbox.plant_tx.clone())?;
        let token = session
            .liveliness()
            .declare_token(keys.alive(Role::Bridge, id))
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh: {e}"))?;
        Ok(Some(Self {
            session,
            _subs: subs,
            _plants: plants,
            _token: token,
            state_gate,
            seal,
            limit,
        }))
    }

    /// The plant's model description, if it answers (sealed) within 200 ms.
    pub fn query_model(&self, keys: &RunKeys, refused: &Arc<Refused>) -> Option<ModelInfo> {
        self.query(keys.model(), refused, |info: &ModelInfo| {
            info.run == keys.run()
        })
    }

    /// The pipe as the plant resolved it, if it answers (sealed) within 200 ms.
    pub fn query_environment(&self, keys: &RunKeys, refused: &Arc<Refused>) -> Option<Environment> {
        self.query(keys.environment(), refused, |e: &Environment| {
            e.run == keys.run()
        })
    }

    /// The plant's answer on the queryable `key`, decoded, validated and of this run (`ours`).
    fn query<M: Message>(
        &self,
        key: String,
        refused: &Arc<Refused>,
        ours: impl Fn(&M) -> bool,
    ) -> Option<M> {
        let replies = self
            .session
            .get(key)
            .timeout(Duration::from_millis(200))
            .wait()
            .ok()?;
        let gate = Gate::new(
            RunLimits::before_model(),
            self.seal.clone(),
            refused.clone(),
        );
        let mut found = None;
        while let Ok(reply) = replies.recv() {
            let Ok(sample) = reply.result() else {
                continue;
            };
            let Ok(bytes) = gate.admit(sample) else {
                continue;
            };
            if let Ok(m) = decode::<M>(&bytes) {
                if ours(&m) {
                    found = Some(m);
                }
            }
        }
        found
    }

    /// Ends the subscriptions and the session.
    pub fn close(self) {
        let Self { session, _subs, .. } = self;
        drop(_subs);
        let _ = session.close().wait();
    }
}

/// Plant liveliness, through its own unbounded channel: it must never be dropped.
fn watch_plants(
    session: &zenoh::Session,
    keys: &RunKeys,
    plant_tx: Sender<Incoming>,
) -> anyhow::Result<zenoh::pubsub::Subscriber<()>> {
    let plant_keys = keys.clone();
    session
        .liveliness()
        .declare_subscriber(keys.alive_all(Role::Plant))
        .history(true)
        .callback(move |sample| {
            if let Some(pid) = plant_keys.id_of_alive_key(Role::Plant, sample.key_expr().as_str()) {
                let _ = plant_tx.send(match sample.kind() {
                    zenoh::sample::SampleKind::Put => Incoming::PlantUp(pid.to_string()),
                    zenoh::sample::SampleKind::Delete => Incoming::PlantDown(pid.to_string()),
                });
            }
        })
        .wait()
        .map_err(|e| anyhow::anyhow!("zenoh: {e}"))
}
