//! The plant's zenoh link: its participant in the run (publishers, the subscribers that fill the
//! runner's inboxes, the `model` and `environment` queryables) and its liveliness.
//!
//! The runner sees only an [`Inbox`] (actuation and join requests that passed the arrival gate,
//! and control events, as channels) and an [`Outbox`] (encoded messages by [`Topic`]); this module
//! is the one place that touches zenoh.

use std::sync::Arc;

use crossbeam_channel::{Receiver, Sender};

use crawler_protocol::{
    encode, Environment, ModelInfo, ProcessId, Role, RunKeys, RunLimits, RunNonce,
};
use crawler_transport::budget::{ByteBudget, Charged};
use crawler_transport::gate::{Accept, Refused, RunInstance, Senders};
use crawler_transport::participant::{queue, Admitted, Congestion, Inlet, Outlet, Queue};
use crawler_transport::{Access, Network, Participant, Seal};

/// The smallest byte budget of the actuation inbox; beyond its budget messages are dropped and
/// counted (flooding), before and after a controller joined. A controller has one answer in
/// flight; this holds over a hundred of a 128-cell run's largest.
pub const INBOX_BYTES: usize = 256 << 10;

/// The byte budget of the join requests waiting to be read (a controller sends one every 500 ms
/// until it is admitted; this holds over a hundred of the largest).
pub const JOIN_INBOX_BYTES: usize = 64 << 10;

/// The actuation inbox's budget for a run of `limits`: at least [`INBOX_BYTES`], and room for
/// eight of the run's largest actuation messages.
pub fn inbox_bytes(limits: &RunLimits) -> usize {
    INBOX_BYTES.max(8 * limits.actuation())
}

/// Control events: never dropped.
#[derive(Debug, Clone, PartialEq)]
pub enum Control {
    /// A controller's liveliness token disappeared: the process went away.
    ControllerDown(ProcessId),
    /// SIGINT or SIGTERM.
    Interrupt,
}

/// What reaches the runner: actuation messages and join requests (each admitted by the arrival
/// gate, bounded in bytes, overflow counted) and control events.
#[derive(Debug)]
pub struct Inbox {
    /// Actuation messages as received, with their envelope, undecoded; each holds its bytes of
    /// the inbox's budget until dropped.
    pub data: Receiver<Charged<Admitted>>,
    /// Join requests as received, with their envelope, undecoded.
    pub joins: Receiver<Charged<Admitted>>,
    /// Controllers leaving, and interrupts.
    pub control: Receiver<Control>,
    /// The byte budget of `data`.
    pub budget: ByteBudget,
    /// Payloads refused at arrival, by cause.
    pub refused: Arc<Refused>,
    /// Whose actuation the arrival gate admits: the controller of the step the plant waits for.
    pub controllers: Senders,
}

/// The producing sides of an [`Inbox`] (the link's subscribers, or a test).
#[derive(Debug, Clone)]
pub struct Feeders {
    /// Actuation.
    pub actuation: Queue,
    /// Join requests.
    pub joins: Queue,
}

impl Feeders {
    /// Queues an actuation message if the budget allows (else drops it); true if queued.
    pub fn offer(&self, m: Admitted) -> bool {
        self.actuation.offer(m)
    }

    /// Queues a join request if the budget allows (else drops it); true if queued.
    pub fn join(&self, m: Admitted) -> bool {
        self.joins.offer(m)
    }
}

impl Inbox {
    /// An inbox of `budget` bytes of actuation with the control channel `control`, and its
    /// feeders.
    pub fn channel(control: Receiver<Control>, budget: usize) -> (Feeders, Self) {
        let (actuation, data) = queue(budget);
        let (joins, join_rx) = queue(JOIN_INBOX_BYTES);
        let budget = actuation.budget().clone();
        (
            Feeders { actuation, joins },
            Self {
                data,
                joins: join_rx,
                control,
                budget,
                refused: Arc::default(),
                controllers: Senders::default(),
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
    participant: Participant,
    state: Outlet,
    events: Outlet,
    metrics: Outlet,
    status: Outlet,
    _token: zenoh::liveliness::LivelinessToken,
    _actuation: zenoh::pubsub::Subscriber<()>,
    _joins: zenoh::pubsub::Subscriber<()>,
    _controllers: zenoh::pubsub::Subscriber<()>,
    _model: zenoh::query::Queryable<()>,
    _environment: zenoh::query::Queryable<()>,
}

impl Link {
    /// Opens the plant's session in `network` as process `id` of run instance `nonce`, checking
    /// connecting sessions with `access` and sealing with `seal`: answers `model` and
    /// `environment` queries with `info` and `environment`, forwards actuation (of legal size for
    /// `info`'s run, of this instance, from the controller the runner admits, each once) and
    /// join requests into the returned inbox, and controllers' departures to `control_tx`
    /// (whose receiver `control_rx` becomes the inbox's control channel).
    pub fn open(
        network: &Network,
        (id, nonce): (ProcessId, RunNonce),
        (info, environment): (ModelInfo, Environment),
        (access, seal): (&Access, Option<Seal>),
        control_tx: Sender<Control>,
        control_rx: Receiver<Control>,
    ) -> anyhow::Result<(Self, Inbox)> {
        let keys = RunKeys::new(&network.run_id)?;
        let limits = RunLimits::new(info.cells as usize);
        let session = crawler_transport::open(Role::Plant, network, access, limits.largest())?;
        let participant =
            Participant::new(session, Role::Plant, id, seal, RunInstance::known(nonce));
        // Blocking publishers: with one priority per link (QoS off, which bounds what a link
        // reassembles) a dropping publisher lost most events and metrics behind the states'
        // batches whenever the recorder was a little behind.
        let outlet = |key: String| participant.outlet(&key, Congestion::Block, true);
        let state = outlet(keys.state())?;
        let events = outlet(keys.events())?;
        let metrics = outlet(keys.metrics())?;
        let status = outlet(keys.status(Role::Plant))?;
        let (feeders, mut inbox) = Inbox::channel(control_rx, inbox_bytes(&limits));
        inbox.refused = participant.refused().clone();
        let gate = participant.gate(
            limits.actuation(),
            Accept::Ids(Role::Controller, inbox.controllers.clone()),
        );
        let actuation = participant.subscribe(&keys.actuation(), gate, feeders.actuation)?;
        let gate = participant.gate(RunLimits::join(), Accept::Role(Role::Controller));
        let joins = participant.subscribe(&keys.join(), gate, feeders.joins)?;
        let controllers = participant.departures(&keys, Role::Controller, move |cid| {
            let _ = control_tx.send(Control::ControllerDown(cid));
        })?;
        let model = participant.answer(&keys.model(), encode(&info))?;
        let environment = participant.answer(&keys.environment(), encode(&environment))?;
        let token = participant.token(&keys)?;
        let link = Self {
            participant,
            state,
            events,
            metrics,
            status,
            _token: token,
            _actuation: actuation,
            _joins: joins,
            _controllers: controllers,
            _model: model,
            _environment: environment,
        };
        Ok((link, inbox))
    }

    /// Closes the session (the liveliness token disappears with it).
    pub fn close(self) {
        let Self { participant, .. } = self;
        participant.close();
    }
}

impl Outbox for Link {
    fn put(&self, topic: Topic, bytes: Vec<u8>) {
        let outlet = match topic {
            Topic::State => &self.state,
            Topic::Events => &self.events,
            Topic::Metrics => &self.metrics,
            Topic::Status => &self.status,
        };
        let _ = outlet.put(bytes);
    }
}
