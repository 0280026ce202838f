//! The network as the execution's controller: waits for the answer of the run's controller to
//! each state (the state itself is published by the [`super::publisher::Publisher`]), resends
//! the state while none comes, hears join requests and departures, and, when the controller
//! leaves, stops the run or waits for another to take it over at that step.

use std::cell::RefCell;
use std::rc::Rc;
use std::time::{Duration, Instant};

use crawler_cli::Exit;
use crawler_physics::execution::{Actuation, Controller, Observation};
use crawler_protocol::{encode, ProcessId, ProcessState};

use super::seat::{Controller as Seated, Heard};
use super::{publish_status, rejected, OnLost, Shared, Stop, RESEND};
use crate::admission::Rejection;
use crate::link::{Control, Inbox, Outbox, Topic};
use crawler_transport::participant::Admitted;

/// The run's controllers, over the network, as the execution's controller.
pub(super) struct Network<'a, O: Outbox> {
    pub inbox: &'a Inbox,
    pub out: &'a O,
    pub shared: Rc<RefCell<Shared>>,
    pub id: ProcessId,
    pub step_timeout: Duration,
    pub on_lost: OnLost,
    /// When the controller's last valid answer arrived: how fast a lost controller is noticed
    /// is measured from there.
    pub last_answer: Instant,
}

impl<O: Outbox> Network<'_, O> {
    fn status(&self, state: ProcessState, message: &str, step: u64) {
        let s = self.shared.borrow();
        publish_status(
            self.out,
            &self.id,
            (state, message, step),
            rejected(&s.admission, self.inbox),
            None,
        );
    }

    /// Publishes the state of step `n` again, to whoever controls it now.
    fn republish(&self) {
        let mut s = self.shared.borrow_mut();
        let controller = s
            .seat
            .joined()
            .map(|c| c.id.to_string())
            .unwrap_or_default();
        if let Some(state) = s.state.as_mut() {
            state.controller = controller;
            let bytes = encode(&*state);
            self.out.put(Topic::State, bytes);
        }
    }

    /// A join request (admitted by the arrival gate) while at step `n`; true if the run's
    /// controller changed (the state of `n` must go to the new one).
    fn join(&mut self, m: &Admitted, n: u64) -> bool {
        let heard = {
            let mut s = self.shared.borrow_mut();
            let join = s.admission.join(&m.bytes, &m.header.sender);
            match join {
                Err(r) => {
                    warn(&r);
                    return false;
                }
                Ok(j) => s.seat.hear(
                    Seated {
                        id: m.header.sender,
                        policy: j.policy,
                    },
                    j.take_over,
                    n,
                ),
            }
        };
        match heard {
            Heard::Admitted(change) => {
                let said = format!("controller {} took over the run at step {n}", change.to);
                eprintln!("crawler-plant: {said}");
                self.status(ProcessState::Running, &said, n);
                true
            }
            Heard::Requested { at, again: false } => {
                let said = format!(
                    "controller {} (asked by {}) takes the run over at step {at}",
                    m.header.sender,
                    self.shared
                        .borrow()
                        .seat
                        .joined()
                        .map_or_else(String::new, |c| c.to_string())
                );
                eprintln!("crawler-plant: {said}");
                false
            }
            Heard::Kept(by) => {
                let mut s = self.shared.borrow_mut();
                if s.refused_joins.insert(m.header.sender) {
                    eprintln!(
                        "crawler-plant: another controller {} asked to join; the run keeps {by} (a controller takes a run over with crawler-controller run --take-over)",
                        m.header.sender
                    );
                }
                false
            }
            Heard::Full => {
                eprintln!(
                    "crawler-plant: too many take-over requests wait; {} is not heard",
                    m.header.sender
                );
                false
            }
            Heard::AlreadyIn | Heard::Requested { again: true, .. } => false,
        }
    }
}

impl<O: Outbox> Controller for Network<'_, O> {
    type Stop = Stop;

    fn act(&mut self, obs: &Observation<'_>) -> Result<Option<Actuation>, Stop> {
        let n = obs.step;
        let mut deadline = Instant::now() + self.step_timeout;
        let mut resend = Instant::now() + RESEND;
        // set while the run has no controller (it left, and the plant waits for another)
        let mut vacant: Option<(Instant, ProcessId)> = None;
        loop {
            let now = Instant::now();
            let joined = self.shared.borrow().seat.joined().cloned();
            match (&joined, vacant) {
                (None, Some((until, left))) if now >= until => {
                    let OnLost::Wait(waited) = self.on_lost else {
                        unreachable!("vacant only when waiting")
                    };
                    return Err(Stop {
                        reason: format!(
                            "controller {left} left the run at step {n} and no controller took it over within {:.0} s",
                            waited.as_secs_f64()
                        ),
                        exit: Exit::PeerLost,
                    });
                }
                (j, None) if now >= deadline => {
                    let who = j.as_ref().map_or_else(
                        || "no controller".into(),
                        |j| format!("controller {}", j.id),
                    );
                    return Err(Stop {
                        reason: format!(
                            "{who} did not answer step {n} within {:.1} s",
                            self.step_timeout.as_secs_f64()
                        ),
                        exit: Exit::Timeout,
                    });
                }
                _ => {}
            }
            let wake = match vacant {
                Some((until, _)) => until,
                None => resend.min(deadline),
            };
            crossbeam_channel::select! {
                recv(self.inbox.control) -> ev => match ev {
                    Ok(Control::ControllerDown(id)) => {
                        let was_joined = self.shared.borrow_mut().seat.left(&id);
                        if !was_joined {
                            continue;
                        }
                        let ms = self.last_answer.elapsed().as_millis();
                        match self.on_lost {
                            OnLost::Stop => {
                                return Err(Stop {
                                    reason: format!(
                                        "controller {id} left the run at step {n} (its liveliness token disappeared {ms} ms after its last answer)"
                                    ),
                                    exit: Exit::PeerLost,
                                });
                            }
                            OnLost::Wait(wait) => {
                                let said = format!(
                                    "controller {id} left the run at step {n} ({ms} ms after its last answer); waiting up to {:.0} s for a controller to take it over at that step (crawler-controller run --take-over)",
                                    wait.as_secs_f64()
                                );
                                eprintln!("crawler-plant: {said}");
                                self.status(ProcessState::Waiting, &said, n);
                                vacant = Some((Instant::now() + wait, id));
                            }
                        }
                    }
                    Ok(Control::Interrupt) => {
                        return Err(Stop {
                            reason: format!("interrupted at step {n}"),
                            exit: Exit::Interrupted,
                        });
                    }
                    Err(_) => {}
                },
                recv(self.inbox.joins) -> m => {
                    let Ok(m) = m else { continue };
                    if self.join(m.get(), n) {
                        // a controller took over the vacant run: the state of n is now its
                        vacant = None;
                        self.republish();
                        deadline = Instant::now() + self.step_timeout;
                        resend = Instant::now() + RESEND;
                        self.last_answer = Instant::now();
                    }
                },
                recv(self.inbox.data) -> m => {
                    let Ok(m) = m else { continue };
                    let Some(j) = joined else { continue };
                    let m = m.get();
                    let admitted = self
                        .shared
                        .borrow_mut()
                        .admission
                        .admit(&m.bytes, &m.header.sender, n, &j.id);
                    match admitted {
                        Ok(command) => {
                            self.last_answer = Instant::now();
                            return Ok(Some(command));
                        }
                        Err(rejection) => warn(&rejection),
                    }
                },
                default(wake.saturating_duration_since(now)) => {
                    if vacant.is_none() && Instant::now() >= resend {
                        self.republish();
                        resend = Instant::now() + RESEND;
                    }
                },
            }
        }
    }
}

pub(super) fn warn(rejection: &Rejection) {
    if rejection.worth_reporting() {
        eprintln!(
            "crawler-plant: rejected ({:?}, #{}): {}",
            rejection.kind, rejection.count, rejection.reason
        );
    }
}
