//! What the controller hears from its run: the plant's states and statuses, each admitted by the
//! participant's arrival gate (size, seal, this run instance, the plant that answered the
//! controller's challenge, each message once) and queued within a byte budget of its own, so
//! that a backlog of states never crowds out the plant's final status and a flood of statuses
//! never crowds out states; and the plant's departure (its liveliness token).

use std::sync::Arc;

use crossbeam_channel::{unbounded, Receiver};
use zenoh::pubsub::Subscriber;

use crawler_protocol::{decode, ProcessId, Role, RunKeys, RunLimits, Status};
use crawler_transport::budget::{ByteBudget, Charged};
use crawler_transport::gate::{Accept, Senders};
use crawler_transport::participant::{queue, Admitted, Queue};
use crawler_transport::Participant;

/// The smallest byte budget of the state inbox: a plant has one state in flight (two when it
/// resends); this holds eight of a 28 000-cell run's, 8 MiB.
pub const STATE_INBOX_BYTES: usize = 8 << 20;

/// Byte budget of the plant's statuses waiting to be read: their own, so that a backlog of
/// states never crowds out the plant's final status (about one status a second arrives).
pub const STATUS_INBOX_BYTES: usize = 4 << 20;

/// The state inbox's budget for a run of `limits`: at least [`STATE_INBOX_BYTES`], and room for
/// eight of the run's largest states.
pub fn state_inbox_bytes(limits: &RunLimits) -> usize {
    STATE_INBOX_BYTES.max(8 * limits.state())
}

/// The status inbox's budget: at least [`STATUS_INBOX_BYTES`], and room for two statuses of
/// the largest legal size.
pub fn status_inbox_bytes() -> usize {
    STATUS_INBOX_BYTES.max(2 * RunLimits::text_message())
}

/// The controller's subscriptions and their queues.
pub struct Inbox {
    /// The plant's states, admitted and undecoded.
    pub states: Receiver<Charged<Admitted>>,
    /// The plant's statuses, admitted and decoded.
    pub statuses: Receiver<Charged<Status>>,
    /// The plant went away (its liveliness token disappeared).
    pub gone: Receiver<ProcessId>,
    _subscribers: [Subscriber<()>; 3],
}

impl Inbox {
    /// Subscribes `participant` to the run of `keys` whose plant is `plant` (the process that
    /// answered its challenge), checking sizes with the run's `limits`.
    pub fn open(
        participant: &Participant,
        keys: &RunKeys,
        limits: &RunLimits,
        plant: ProcessId,
    ) -> anyhow::Result<Self> {
        let from_plant = Accept::Ids(Role::Plant, Senders::of(&[plant]));
        let (state_q, states): (Queue, _) = queue(state_inbox_bytes(limits));
        let gate = participant.gate(limits.state(), from_plant.clone());
        let state_sub = participant.subscribe(&keys.state(), gate, state_q)?;
        let (status_tx, statuses) = unbounded();
        let budget = ByteBudget::new(status_inbox_bytes());
        let gate = participant.gate(RunLimits::text_message(), from_plant);
        let status_sub =
            participant.subscribe(&keys.status(Role::Plant), gate, move |m: Admitted| {
                let len = m.bytes.len();
                // a status that does not decode is dropped here (nothing to act on)
                let Ok(st) = decode::<Status>(&m.bytes) else {
                    return true;
                };
                budget
                    .charge(st, len)
                    .is_some_and(|c| status_tx.send(c).is_ok())
            })?;
        let (gone_tx, gone) = unbounded();
        let gone_sub = participant.departures(keys, Role::Plant, move |id| {
            if id == plant {
                let _ = gone_tx.send(id);
            }
        })?;
        Ok(Self {
            states,
            statuses,
            gone,
            _subscribers: [state_sub, status_sub, gone_sub],
        })
    }
}

/// What `participant` refused at arrival, in words; `None` if nothing was.
pub fn refusals(participant: &Participant) -> Option<String> {
    let r: &Arc<_> = participant.refused();
    r.describe()
}
