//! The plant's zenoh link: its publishers, the subscribers that fill the runner's inboxes, the
//! `model` queryable and the liveliness token and subscriber.
//!
//! The runner sees only an [`Inbox`] (actuation bytes and control events, as channels) and an
//! [`Outbox`] (encoded messages by [`Topic`]); this module is the one place that touches zenoh.

use std::sync::Arc;

use crossbeam_channel::{unbounded, Receiver, Sender};
use zenoh::qos::CongestionControl;
use zenoh::sample::SampleKind;
use zenoh::Wait;

use crawler_protocol::{encode, Environment, ModelInfo, Role, RunKeys, RunLimits};
use crawler_transport::budget::{ByteBudget, Charged};
use crawler_transport::gate::{self, Gate, Refused};
use crawler_transport::{Access, Network, Seal};

/// The smallest byte budget of the actuation inbox; beyond its budget messages are dropped and
/// counted (flooding), before and after a controller joined. A controller has one answer in
/// flight; this holds over a hundred of a 128-cell run's largest.
pub const INBOX_BYTES: usize = 256 << 10;

/// The actuation inbox's budget for a run of `limits`: at least [`INBOX_BYTES`], and room for
/// eight of the run's largest actuation messages.
pub fn inbox_bytes(limits: &RunLimits) -> usize {
    INBOX_BYTES.max(8 * limits.actuation())
}

/// Control events: never dropped.
#[derive(Debug, Clone, PartialEq)]
pub enum Control {
    /// A controller declared its liveliness token.
    ControllerUp(String),
    /// A controller's token disappeared.
    ControllerDown(String),
    /// SIGINT or SIGTERM.
    Interrupt,
}

/// What reaches the runner: actuation messages (bounded in bytes, overflow counted) and control
/// events.
#[derive(Debug)]
pub struct Inbox {
    /// Actuation messages as received (their size and seal checked), undecoded; each holds its
    /// bytes of the inbox's budget until dropped.
    pub data: Receiver<Charged<Vec<u8>>>,
    /// Controllers joining and leaving, and interrupts.
    pub control: Receiver<Control>,
    /// The byte budget of `data`.
    pub budget: ByteBudget,
    /// Payloads refused at arrival (oversized, unsealed).
    pub refused: Arc<Refused>,
}

/// The producing side of an [`Inbox`]'s data.
#[derive(Debug, Clone)]
pub struct Feeder {
    tx: Sender<Charged<Vec<u8>>>,
    budget: ByteBudget,
}

impl Feeder {
    /// Queues `bytes` if the budget allows (else drops and counts it); true if queued.
    pub fn offer(&self, bytes: Vec<u8>) -> bool {
        let len = bytes.len();
        match self.budget.charge(bytes, len) {
            Some(charged) => self.tx.send(charged).is_ok(),
            None => false,
        }
    }
}

impl Inbox {
    /// An inbox of `budget` bytes with the control channel `control`, and its feeder.
    pub fn channel(control: Receiver<Control>, budget: usize) -> (Feeder, Self) {
        let (tx, data) = unbounded();
        let budget = ByteBudget::new(budget);
        (
            Feeder {
                tx,
                budget: budget.clone(),
            },
            Self {
                data,
                control,
                budget,
                refused: Arc::default(),
            },
        )
    }

    /// Actuation messages dropped so far because the inbox's budget was spent.
    pub fn overflow(&self) -> u64 {
        self.budget.overflow()
    }
}

/// The plant's outgoing keys.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Topic {
    /// `State(n)`, every step (reliable: the controller waits for it).
    State,
    /// Stick-slip episodes of a step (reliable: the recorder records every one).
    Events,
    /// Metrics of a closed averaging block (reliable).
    Metrics,
    /// The plant's status (reliable).
    Status,
}

/// Where the runner's messages go.
pub trait Outbox {
    /// Publishes the encoded message `bytes` on the run's key of `topic`; never fails (a lost
    /// subscriber is not the plant's error).
    fn put(&self, topic: Topic, bytes: Vec<u8>);
}

/// The zenoh side of the plant.
pub struct Link {
    session: zenoh::Session,
    seal: Option<Seal>,
    state: zenoh::pubsub::Publisher<'static>,
    events: zenoh::pubsub::Publisher<'static>,
    metrics: zenoh::pubsub::Publisher<'static>,
    status: zenoh::pubsub::Publisher<'static>,
    _token: zenoh::liveliness::LivelinessToken,
    _actuation: zenoh::pubsub::Subscriber<()>,
    _controllers: zenoh::pubsub::Subscriber<()>,
    _model: zenoh::query::Queryable<()>,
    _environment: zenoh::query::Queryable<()>,
}

impl Link {
    /// Opens the plant's session in `network` as process `id`, checking connecting sessions
    /// with `access` and sealing with `seal`: answers `model` queries with `info`, forwards
    /// actuation (of legal size for `info`'s run, sealed) into the returned inbox and
    /// controllers' liveliness to `control_tx` (whose receiver `control_rx` becomes the inbox's
    /// control channel).
    pub fn open(
        network: &Network,
        id: &str,
        (info, environment): (ModelInfo, Environment),
        (access, seal): (&Access, Option<Seal>),
        control_tx: Sender<Control>,
        control_rx: Receiver<Control>,
    ) -> anyhow::Result<(Self, Inbox)> {
        let keys = RunKeys::new(&network.run_id)?;
        let limits = RunLimits::new(info.cells as usize);
        let session = crawler_transport::open(Role::Plant, network, access, limits.largest())?;
        let z = |e: zenoh::Error| anyhow::anyhow!("zenoh: {e}");
        let publisher = |key: String, block: bool| {
            session
                .declare_publisher(key)
                .congestion_control(if block {
                    CongestionControl::Block
                } else {
                    CongestionControl::Drop
                })
                .express(true)
                .wait()
                .map_err(z)
        };
        let state = publisher(keys.state(), true)?;
        // Blocking like the states: with one priority per link (QoS off, which bounds what a
        // link reassembles) a dropping publisher lost most events and metrics behind the
        // states' batches whenever the recorder was a little behind.
        let events = publisher(keys.events(), true)?;
        let metrics = publisher(keys.metrics(), true)?;
        let status = publisher(keys.status(Role::Plant), true)?;
        let (feeder, inbox) = Inbox::channel(control_rx, inbox_bytes(&limits));
        let gate = Gate::new(limits.actuation(), seal.clone(), inbox.refused.clone());
        let actuation = session
            .declare_subscriber(keys.actuation())
            .callback(move |sample| {
                // refused payloads are counted by the gate, overflow by the budget
                if let Ok(bytes) = gate.admit(&sample) {
                    feeder.offer(bytes);
                }
            })
            .wait()
            .map_err(z)?;
        let keys2 = keys.clone();
        let controllers = session
            .liveliness()
            .declare_subscriber(keys.alive_all(Role::Controller))
            .history(true)
            .callback(move |sample| {
                if let Some(cid) =
                    keys2.id_of_alive_key(Role::Controller, sample.key_expr().as_str())
                {
                    let ev = match sample.kind() {
                        SampleKind::Put => Control::ControllerUp(cid.to_string()),
                        SampleKind::Delete => Control::ControllerDown(cid.to_string()),
                    };
                    let _ = control_tx.send(ev);
                }
            })
            .wait()
            .map_err(z)?;
        let model = answer(&session, keys.model(), encode(&info), seal.as_ref())?;
        let environment = answer(
            &session,
            keys.environment(),
            encode(&environment),
            seal.as_ref(),
        )?;
        let token = session
            .liveliness()
            .declare_token(keys.alive(Role::Plant, id))
            .wait()
            .map_err(z)?;
        let link = Self {
            session,
            seal,
            state,
            events,
            metrics,
            status,
            _token: token,
            _actuation: actuation,
            _controllers: controllers,
            _model: model,
            _environment: environment,
        };
        Ok((link, inbox))
    }

    /// Closes the session (the liveliness token disappears with it).
    pub fn close(self) {
        let _ = self.session.close().wait();
    }
}

/// A queryable on `key` answering `bytes` (sealed when the run is authenticated).
fn answer(
    session: &zenoh::Session,
    key: String,
    bytes: Vec<u8>,
    seal: Option<&Seal>,
) -> anyhow::Result<zenoh::query::Queryable<()>> {
    let attachment = gate::attachment(seal, &key, &bytes);
    session
        .declare_queryable(key.clone())
        .callback(move |query| {
            let reply = query.reply(key.as_str(), bytes.clone());
            let _ = match &attachment {
                Some(a) => reply.attachment(a.clone()).wait(),
                None => reply.wait(),
            };
        })
        .wait()
        .map_err(|e| anyhow::anyhow!("zenoh: {e}"))
}

impl Outbox for Link {
    fn put(&self, topic: Topic, bytes: Vec<u8>) {
        let publisher = match topic {
            Topic::State => &self.state,
            Topic::Events => &self.events,
            Topic::Metrics => &self.metrics,
            Topic::Status => &self.status,
        };
        let _ = gate::put(publisher, self.seal.as_ref(), bytes);
    }
}
