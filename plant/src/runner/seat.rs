//! Who controls the run, step by step: the controller whose answer the plant waits for, the
//! requests to take the run over at a later step, and who controlled which steps.
//!
//! Pure: the runner tells it what it heard (sealed join requests, departures) and at which step,
//! and asks it, before it publishes each state, whom that state is for. A change of controller
//! therefore happens only at a step boundary, between the last state the old controller answered
//! and the first one the new controller answers: no step is lost or answered twice.

use crawler_protocol::ProcessId;
use crawler_transport::gate::Senders;

/// Most take-over requests waiting at once (the rest are refused until one is settled).
pub const MAX_REQUESTS: usize = 16;

/// A controller of the run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Controller {
    /// Its process id.
    pub id: ProcessId,
    /// Its policy's name (as its join request said).
    pub policy: String,
}

impl std::fmt::Display for Controller {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({})", self.id, self.policy)
    }
}

/// A controller's turn: it controls the steps from `first` until the next turn's.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Turn {
    /// Its first step.
    pub first: u64,
    /// The controller.
    pub controller: Controller,
}

/// A change of controller at a step boundary.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Change {
    /// The first step of the new controller.
    pub step: u64,
    /// The controller before (none at the run's start, or after the controller left).
    pub from: Option<Controller>,
    /// The new controller.
    pub to: Controller,
}

/// What the seat made of a join request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Heard {
    /// The requester controls the run from now on (from the state about to be published or
    /// published again).
    Admitted(Change),
    /// The requester already controls the run.
    AlreadyIn,
    /// The run keeps its controller (a plain join while it has one).
    Kept(Controller),
    /// The requester takes the run over at the first boundary at or after `at`.
    Requested {
        /// The step it asked for (at least the next one).
        at: u64,
        /// True if it had asked before (a repeated request).
        again: bool,
    },
    /// Too many requests wait already.
    Full,
}

#[derive(Debug, Clone)]
struct Request {
    controller: Controller,
    at: u64,
    /// Order of arrival (the latest request wins a tie).
    order: u64,
}

/// Who controls the run.
#[derive(Debug)]
pub struct Seat {
    joined: Option<Controller>,
    requests: Vec<Request>,
    received: u64,
    senders: Senders,
    history: Vec<Turn>,
}

impl Seat {
    /// An empty seat; `senders` is the arrival gate's view of whose actuation is admitted,
    /// kept equal to the controller.
    pub fn new(senders: Senders) -> Self {
        senders.set(&[]);
        Self {
            joined: None,
            requests: Vec::new(),
            received: 0,
            senders,
            history: Vec::new(),
        }
    }

    /// The controller of the step being answered.
    pub fn joined(&self) -> Option<&Controller> {
        self.joined.as_ref()
    }

    /// True once a controller joined (something was, or is being, simulated).
    pub fn ever_joined(&self) -> bool {
        !self.history.is_empty()
    }

    /// Who controlled which steps so far.
    pub fn history(&self) -> &[Turn] {
        &self.history
    }

    fn admit(&mut self, to: Controller, step: u64) -> Change {
        self.requests.retain(|r| r.controller.id != to.id);
        self.senders.set(&[to.id]);
        self.history.push(Turn {
            first: step,
            controller: to.clone(),
        });
        Change {
            step,
            from: self.joined.replace(to.clone()),
            to,
        }
    }

    /// A join request of `controller` while the plant is at step `n` (the state of step `n` is
    /// about to be published, or was published to the controller): `take_over` as the request
    /// says (`None`: a plain join).
    ///
    /// A run that never had a controller admits a plain join, or a take-over due by `n`, at once
    /// and keeps later take-overs for their step; a run that has a controller keeps it against a
    /// plain join and keeps a take-over for the first boundary at or after its step and after
    /// `n` (the state of `n` is the current controller's); a run whose controller left admits any
    /// request at once.
    pub fn hear(&mut self, controller: Controller, take_over: Option<u64>, n: u64) -> Heard {
        match (&self.joined, take_over) {
            (Some(j), _) if j.id == controller.id => Heard::AlreadyIn,
            (Some(j), None) => Heard::Kept(j.clone()),
            (None, Some(at)) if at > n && !self.ever_joined() => self.request(controller, at),
            (None, _) => Heard::Admitted(self.admit(controller, n)),
            (Some(_), Some(at)) => self.request(controller, at.max(n + 1)),
        }
    }

    fn request(&mut self, controller: Controller, at: u64) -> Heard {
        self.received += 1;
        let order = self.received;
        if let Some(r) = self
            .requests
            .iter_mut()
            .find(|r| r.controller.id == controller.id)
        {
            *r = Request {
                controller,
                at,
                order,
            };
            return Heard::Requested { at, again: true };
        }
        if self.requests.len() >= MAX_REQUESTS {
            return Heard::Full;
        }
        self.requests.push(Request {
            controller,
            at,
            order,
        });
        Heard::Requested { at, again: false }
    }

    /// Before the state of step `n` is published: the take-over due by then, if any (the
    /// request for the latest step wins, then the latest request), and the other requests due by
    /// then, which are dropped.
    pub fn due(&mut self, n: u64) -> Option<(Change, Vec<Controller>)> {
        self.joined.as_ref()?;
        let winner = self
            .requests
            .iter()
            .filter(|r| r.at <= n)
            .max_by_key(|r| (r.at, r.order))?
            .controller
            .clone();
        let change = self.admit(winner, n);
        let mut dropped = Vec::new();
        self.requests.retain(|r| {
            let keep = r.at > n;
            if !keep {
                dropped.push(r.controller.clone());
            }
            keep
        });
        Some((change, dropped))
    }

    /// Process `id` went away: true if it was the run's controller (the run has none now).
    /// A request of its is forgotten.
    pub fn left(&mut self, id: &ProcessId) -> bool {
        self.requests.retain(|r| r.controller.id != *id);
        if self.joined.as_ref().is_some_and(|j| j.id == *id) {
            self.joined = None;
            self.senders.set(&[]);
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(n: u8, policy: &str) -> Controller {
        Controller {
            id: ProcessId::parse(&format!("{n:016x}")).unwrap(),
            policy: policy.into(),
        }
    }

    fn admitted(h: Heard) -> Change {
        match h {
            Heard::Admitted(c) => c,
            other => panic!("not admitted: {other:?}"),
        }
    }

    #[test]
    fn the_first_plain_join_takes_the_run_and_others_are_kept_out() {
        let senders = Senders::default();
        let mut seat = Seat::new(senders.clone());
        let a = c(1, "wave");
        let change = admitted(seat.hear(a.clone(), None, 0));
        assert_eq!((change.step, change.from, &change.to), (0, None, &a));
        assert!(senders.contains(&a.id));
        assert_eq!(seat.hear(a.clone(), None, 5), Heard::AlreadyIn);
        assert_eq!(seat.hear(c(2, "wave"), None, 5), Heard::Kept(a.clone()));
        assert!(!senders.contains(&c(2, "").id));
        assert_eq!(seat.due(6), None);
        assert_eq!(seat.joined(), Some(&a));
    }

    #[test]
    fn a_take_over_happens_at_its_step_and_not_before() {
        let senders = Senders::default();
        let mut seat = Seat::new(senders.clone());
        let (a, b) = (c(1, "wave"), c(2, "reflex"));
        // B asks before A joined: it waits for its step, A takes the run from its start
        assert_eq!(
            seat.hear(b.clone(), Some(2000), 0),
            Heard::Requested {
                at: 2000,
                again: false
            }
        );
        assert_eq!(seat.joined(), None);
        admitted(seat.hear(a.clone(), None, 0));
        // its repeated requests change nothing
        assert_eq!(
            seat.hear(b.clone(), Some(2000), 700),
            Heard::Requested {
                at: 2000,
                again: true
            }
        );
        for n in 1..2000 {
            assert_eq!(seat.due(n), None, "step {n}");
        }
        let (change, dropped) = seat.due(2000).unwrap();
        assert_eq!(
            change,
            Change {
                step: 2000,
                from: Some(a.clone()),
                to: b.clone()
            }
        );
        assert!(dropped.is_empty());
        assert!(senders.contains(&b.id) && !senders.contains(&a.id));
        assert_eq!(
            seat.history(),
            [
                Turn {
                    first: 0,
                    controller: a
                },
                Turn {
                    first: 2000,
                    controller: b
                }
            ]
        );
    }

    #[test]
    fn a_take_over_asked_for_a_past_step_happens_at_the_next_boundary() {
        let mut seat = Seat::new(Senders::default());
        let (a, b) = (c(1, "wave"), c(2, "reflex"));
        admitted(seat.hear(a, None, 0));
        // the state of step 41 is A's: B gets 42
        assert_eq!(
            seat.hear(b.clone(), Some(0), 41),
            Heard::Requested {
                at: 42,
                again: false
            }
        );
        assert_eq!(seat.due(41), None);
        assert_eq!(seat.due(42).unwrap().0.to, b);
        // asked at the start for a step already due: admitted at once
        let mut seat = Seat::new(Senders::default());
        assert_eq!(admitted(seat.hear(b.clone(), Some(0), 0)).to, b);
    }

    #[test]
    fn of_several_requests_due_the_latest_step_wins_and_the_rest_are_dropped() {
        let mut seat = Seat::new(Senders::default());
        let (a, b, d, e) = (c(1, "a"), c(2, "b"), c(3, "d"), c(4, "e"));
        admitted(seat.hear(a, None, 0));
        seat.hear(b.clone(), Some(10), 1);
        seat.hear(d.clone(), Some(12), 2);
        seat.hear(e.clone(), Some(30), 3);
        let (change, dropped) = seat.due(20).unwrap();
        assert_eq!((change.step, change.to), (20, d));
        assert_eq!(dropped, [b]);
        assert_eq!(seat.due(30).unwrap().0.to, e);
    }

    #[test]
    fn a_controller_that_leaves_empties_the_seat_for_the_next_request() {
        let senders = Senders::default();
        let mut seat = Seat::new(senders.clone());
        let (a, b, d) = (c(1, "a"), c(2, "b"), c(3, "d"));
        admitted(seat.hear(a.clone(), None, 0));
        seat.hear(d.clone(), Some(9000), 5);
        assert!(!seat.left(&b.id), "not the controller");
        assert!(
            !seat.left(&d.id) && seat.due(9000).is_none(),
            "its request is gone"
        );
        assert!(seat.left(&a.id));
        assert_eq!(seat.joined(), None);
        assert!(!senders.contains(&a.id));
        // the run has none now: any request is admitted at once, a take-over too
        let change = admitted(seat.hear(b.clone(), Some(9000), 300));
        assert_eq!((change.step, change.from, change.to), (300, None, b));
    }

    #[test]
    fn requests_are_bounded() {
        let mut seat = Seat::new(Senders::default());
        admitted(seat.hear(c(0, "a"), None, 0));
        for i in 1..=MAX_REQUESTS as u8 {
            assert!(matches!(
                seat.hear(c(i, "x"), Some(100), 1),
                Heard::Requested { .. }
            ));
        }
        assert_eq!(seat.hear(c(200, "x"), Some(100), 1), Heard::Full);
        // a repeated request of one that waits is still heard
        assert!(matches!(
            seat.hear(c(3, "x"), Some(100), 2),
            Heard::Requested { again: true, .. }
        ));
    }
}
