//! What the controller hears from its run: the plant's states and statuses and the liveliness
//! of the plant's role, each checked on arrival (size, seal) and queued within a byte budget of
//! its own, so that a backlog of states never crowds out the plant's final status and a flood
//! of statuses never crowds out states.

use std::sync::Arc;

use crossbeam_channel::{unbounded, Receiver};
use zenoh::pubsub::Subscriber;
use zenoh::sample::SampleKind;
use zenoh::Wait;

use crawler_protocol::{decode, Role, RunKeys, RunLimits, Status};
use crawler_transport::budget::{ByteBudget, Charged};
use crawler_transport::gate::{Gate, Refused};
use crawler_transport::Seal;

/// The smallest byte budget of the state inbox: a plant has
/// one state in flight; this holds eight of a 28 000-cell run's.
pub const STATE_INBOX_BYTES: usize = 8 << 20;

/// Byte budget of the plant's statuses waiting to be read: their own, so that a backlog of
/// states never crowds out the plant's final status (about one status a second arrives).
pub const STATUS_INBOX_BYTES: usize = 4 << 20;

/// A liveliness token of the plant's role came or went (never dropped).
pub enum Event {
    /// The process with this id declared its token.
    Up(String),
    /// The process with this id is gone.
    Down(String),
}

/// The controller's subscriptions and their queues.
pub struct Inbox {
    /// The plant's states, admitted and undecoded.
    pub states: Receiver<Charged<Vec<u8>>>,
    /// The plant's statuses, admitted and decoded.
    pub statuses: Receiver<Charged<Status>>,
    /// Liveliness of the plant's role.
    pub events: Receiver<Event>,
    refused: Arc<Refused>,
    state_budget: ByteBudget,
    _subscribers: [Subscriber<()>; 3],
}

impl Inbox {
    /// Subscribes to the run of `keys` on `session`, checking seals with `seal` and sizes with
    /// the run's `limits`.
    pub fn open(
        session: &zenoh::Session,
        keys: &RunKeys,
        limits: &RunLimits,
        seal: Option<&Seal>,
    ) -> anyhow::Result<Self> {
        let z = |e: zenoh::Error| anyhow::anyhow!("zenoh: {e}");
        let refused = Arc::new(Refused::default());
        let state_budget = ByteBudget::new(STATE_INBOX_BYTES.max(8 * limits.state()));
        let (state_tx, states) = unbounded();
        let gate = Gate::new(limits.state(), seal.cloned(), refused.clone());
        let budget = state_budget.clone();
        let state_sub = session
            .declare_subscriber(keys.state())
            .callback(move |s| {
                if let Ok(bytes) = gate.admit(&s) {
                    let len = bytes.len();
                    if let Some(charged) = budget.charge(bytes, len) {
                        let _ = state_tx.send(charged);
                    }
                }
            })
            .wait()
            .map_err(z)?;
        let (status_tx, statuses) = unbounded();
        let gate = Gate::new(RunLimits::text_message(), seal.cloned(), refused.clone());
        let budget = ByteBudget::new(STATUS_INBOX_BYTES.max(2 * RunLimits::text_message()));
        let status_sub = session
            .declare_subscriber(keys.status(Role::Plant))
            .callback(move |s| {
                let Ok(bytes) = gate.admit(&s) else { return };
                let len = bytes.len();
                if let Ok(st) = decode::<Status>(&bytes) {
                    if let Some(charged) = budget.charge(st, len) {
                        let _ = status_tx.send(charged);
                    }
                }
            })
            .wait()
            .map_err(z)?;
        let (event_tx, events) = unbounded();
        let plant_keys = keys.clone();
        let alive_sub = session
            .liveliness()
            .declare_subscriber(keys.alive_all(Role::Plant))
            .history(true)
            .callback(move |s| {
                if let Some(pid) = plant_keys.id_of_alive_key(Role::Plant, s.key_expr().as_str()) {
                    let _ = event_tx.send(match s.kind() {
                        SampleKind::Put => Event::Up(pid.to_string()),
                        SampleKind::Delete => Event::Down(pid.to_string()),
                    });
                }
            })
            .wait()
            .map_err(z)?;
        Ok(Self {
            states,
            statuses,
            events,
            refused,
            state_budget,
            _subscribers: [state_sub, status_sub, alive_sub],
        })
    }

    /// What was refused on arrival, in words; `None` if nothing was.
    pub fn refusals(&self) -> Option<String> {
        let (oversize, unsealed, overflow) = (
            self.refused.oversize(),
            self.refused.unsealed(),
            self.state_budget.overflow(),
        );
        (oversize + unsealed + overflow > 0).then(|| {
            format!(
                "{oversize} oversized, {unsealed} without a valid seal, {overflow} beyond the inbox's {} bytes",
                self.state_budget.cap()
            )
        })
    }
}
