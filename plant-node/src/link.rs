//! The plant's zenoh link: its publishers, the subscribers that fill the runner's inboxes, the
//! `model` queryable and the liveliness token and subscriber.
//!
//! The runner sees only an [`Inbox`] (actuation bytes and control events, as channels) and an
//! [`Outbox`] (encoded messages by [`Topic`]); this module is the one place that touches zenoh.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use crossbeam_channel::{bounded, Receiver, Sender};
use zenoh::qos::CongestionControl;
use zenoh::sample::SampleKind;
use zenoh::Wait;

use crawler_protocol::{encode, ModelInfo, Role, RunKeys};
use crawler_transport::Network;

/// Capacity of the actuation inbox; beyond it messages are dropped and counted (flooding).
pub const INBOX: usize = 1024;

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

/// What reaches the runner: actuation messages (bounded, overflow counted) and control events.
#[derive(Debug)]
pub struct Inbox {
    /// Actuation messages as received, undecoded.
    pub data: Receiver<Vec<u8>>,
    /// Controllers joining and leaving, and interrupts.
    pub control: Receiver<Control>,
    /// Actuation messages dropped because `data` was full.
    pub overflow: Arc<AtomicU64>,
}

impl Inbox {
    /// Actuation messages dropped so far because the inbox was full.
    pub fn overflow(&self) -> u64 {
        self.overflow.load(Ordering::Relaxed)
    }
}

/// The plant's outgoing keys.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Topic {
    /// `State(n)`, every step (reliable: the controller waits for it).
    State,
    /// Stick-slip episodes of a step (dropped under congestion).
    Events,
    /// Metrics of a closed averaging block (dropped under congestion).
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
    state: zenoh::pubsub::Publisher<'static>,
    events: zenoh::pubsub::Publisher<'static>,
    metrics: zenoh::pubsub::Publisher<'static>,
    status: zenoh::pubsub::Publisher<'static>,
    _token: zenoh::liveliness::LivelinessToken,
    _actuation: zenoh::pubsub::Subscriber<()>,
    _controllers: zenoh::pubsub::Subscriber<()>,
    _model: zenoh::query::Queryable<()>,
}

impl Link {
    /// Opens the plant's session in `network` as process `id`: answers `model` queries with
    /// `info`, forwards actuation into the returned inbox and controllers' liveliness to
    /// `control_tx` (whose receiver `control_rx` becomes the inbox's control channel).
    pub fn open(
        network: &Network,
        id: &str,
        info: ModelInfo,
        control_tx: Sender<Control>,
        control_rx: Receiver<Control>,
    ) -> anyhow::Result<(Self, Inbox)> {
        let keys = RunKeys::new(&network.run_id)?;
        let session = crawler_transport::open(Role::Plant, network)?;
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
        let events = publisher(keys.events(), false)?;
        let metrics = publisher(keys.metrics(), false)?;
        let status = publisher(keys.status(Role::Plant), true)?;
        let (data_tx, data) = bounded::<Vec<u8>>(INBOX);
        let overflow = Arc::new(AtomicU64::new(0));
        let dropped = overflow.clone();
        let actuation = session
            .declare_subscriber(keys.actuation())
            .callback(move |sample| {
                let bytes = sample.payload().to_bytes().into_owned();
                if data_tx.try_send(bytes).is_err() {
                    dropped.fetch_add(1, Ordering::Relaxed);
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
        let info_bytes = encode(&info);
        let model = session
            .declare_queryable(keys.model())
            .callback(move |query| {
                let _ = query
                    .reply(query.key_expr().clone(), info_bytes.clone())
                    .wait();
            })
            .wait()
            .map_err(z)?;
        let token = session
            .liveliness()
            .declare_token(keys.alive(Role::Plant, id))
            .wait()
            .map_err(z)?;
        let link = Self {
            session,
            state,
            events,
            metrics,
            status,
            _token: token,
            _actuation: actuation,
            _controllers: controllers,
            _model: model,
        };
        let inbox = Inbox {
            data,
            control: control_rx,
            overflow,
        };
        Ok((link, inbox))
    }

    /// Closes the session (the liveliness token disappears with it).
    pub fn close(self) {
        let _ = self.session.close().wait();
    }
}

impl Outbox for Link {
    fn put(&self, topic: Topic, bytes: Vec<u8>) {
        let publisher = match topic {
            Topic::State => &self.state,
            Topic::Events => &self.events,
            Topic::Metrics => &self.metrics,
            Topic::Status => &self.status,
        };
        let _ = publisher.put(bytes).wait();
    }
}
