//! What each step produced, published as an observer of the execution: its episodes, the
//! averaging blocks it closed, and the next state, addressed to the controller of that step (a
//! take-over due at that step happens here, at the boundary); and the progress.

use std::cell::RefCell;
use std::rc::Rc;
use std::time::Instant;

use crawler_facts::Metric;
use crawler_physics::execution::{Observer, Stepped};
use crawler_physics::plant::{Drive, Plant};
use crawler_protocol::{
    encode, Applied, EpisodeMsg, Events, Metrics as MetricsMsg, ProcessId, ProcessState, RunLimits,
    State, WaveMsg, PROTOCOL_VERSION,
};

use super::{publish_status, rejected, Shared, STATUS_EVERY};
use crate::link::{Inbox, Outbox, Topic};

/// Publishes each step's outputs and the next state.
pub(super) struct Publisher<'a, O: Outbox> {
    pub out: &'a O,
    pub inbox: &'a Inbox,
    pub shared: Rc<RefCell<Shared>>,
    pub id: ProcessId,
    pub tension: Vec<f64>,
    pub bar: &'a crawler_cli::progress::ProgressBar,
    pub last_status: Instant,
    /// True once the end of the run by its task was said.
    pub announced: bool,
}

impl<O: Outbox> Publisher<'_, O> {
    /// Publishes the state of the plant's current step to the controller of that step (after
    /// the take-over due by then, if any).
    pub fn publish_state(&mut self, plant: &Plant, last_step: u64) {
        let n = plant.macro_step();
        let change = self.shared.borrow_mut().seat.due(n);
        if let Some((change, dropped)) = change {
            let said = format!(
                "controller {} takes the run over from {} at step {n}",
                change.to,
                change
                    .from
                    .as_ref()
                    .map_or_else(|| "nobody".to_string(), |c| c.to_string())
            );
            self.bar.suspend(|| eprintln!("crawler-plant: {said}"));
            for d in dropped {
                self.bar.suspend(|| {
                    eprintln!("crawler-plant: controller {d} does not take the run over (another request for a later step won)")
                });
            }
            let s = self.shared.borrow();
            publish_status(
                self.out,
                &self.id,
                (ProcessState::Running, &said, n),
                rejected(&s.admission, self.inbox),
                None,
            );
        }
        plant.tension_into(&mut self.tension);
        let out = plant.outputs();
        let controller = self
            .shared
            .borrow()
            .seat
            .joined()
            .map(|c| c.id.to_string())
            .unwrap_or_default();
        let s = State {
            v: PROTOCOL_VERSION,
            step: n,
            time: plant.time(),
            controller,
            u: plant.displacement().to_vec(),
            vel: plant.velocity().to_vec(),
            tension: self.tension.clone(),
            stuck: plant.stuck().to_vec(),
            mean_speed: out.mean_speed,
            input_power: out.input_power,
            last: n >= last_step,
            applied: applied(plant),
        };
        self.out.put(Topic::State, encode(&s));
        self.shared.borrow_mut().state = Some(s);
    }

    fn publish_step_outputs(&self, plant: &Plant) {
        let n = plant.macro_step();
        // At most N episodes per message, the run's legal size (rarely more than one message).
        let per_message = RunLimits::new(plant.cells()).episodes_per_message();
        for chunk in plant.episodes().chunks(per_message) {
            let ev = Events {
                v: PROTOCOL_VERSION,
                step: n,
                time: plant.time(),
                episodes: chunk
                    .iter()
                    .map(|e| EpisodeMsg {
                        node: e.node,
                        start: e.start,
                        end: e.end,
                        duration: e.duration,
                        direction: e.direction,
                    })
                    .collect(),
            };
            self.out.put(Topic::Events, encode(&ev));
        }
        for b in plant.closed_blocks() {
            let m = b.sums.metrics(
                plant.cells(),
                plant.discretisation().dt,
                plant.params().body.area,
                plant.block_length(),
            );
            let msg = MetricsMsg {
                v: PROTOCOL_VERSION,
                step: n,
                block: b.index,
                steady: b.steady,
                start: m.start,
                end: m.end,
                values: m.values(),
                clock: b.clock,
            };
            if msg.values.get(Metric::Velocity).is_some() && msg.values.get(Metric::Power).is_some()
            {
                self.out.put(Topic::Metrics, encode(&msg));
            }
        }
    }
}

impl<O: Outbox> Observer for Publisher<'_, O> {
    fn stepped(&mut self, s: &Stepped<'_>) {
        let n = s.step;
        self.publish_step_outputs(s.plant);
        self.publish_state(s.plant, s.last_step);
        if n.is_multiple_of(64) {
            self.bar.set_position(n + 1);
        }
        if self.last_status.elapsed() >= STATUS_EVERY {
            let shared = self.shared.borrow();
            publish_status(
                self.out,
                &self.id,
                (
                    ProcessState::Running,
                    &format!("step {} of {}", n + 1, s.last_step),
                    n + 1,
                ),
                rejected(&shared.admission, self.inbox),
                None,
            );
            self.last_status = Instant::now();
        }
        let ended_by_task = s.task.task.end_run && s.last_step == n + 1;
        if let Some(outcome) = s
            .task
            .decided()
            .filter(|_| ended_by_task && !self.announced)
        {
            eprintln!(
                "crawler-plant: task {} at step {}; the run ends there",
                outcome.as_str(),
                n + 1
            );
            self.announced = true;
        }
    }
}

/// What `plant` applied over its last communication step, as the protocol says it: the wave it
/// is driven by, or its muscle-force field (N, one value per cell); `None` before any actuation
/// (the first state of a run).
pub fn applied(plant: &Plant) -> Option<Applied> {
    match plant.drive() {
        Drive::Idle => None,
        Drive::Wave(w) => Some(Applied {
            wave: Some(WaveMsg {
                f0: w.f0,
                k: w.k,
                omega: w.omega,
                phase: w.phase,
            }),
            field: None,
        }),
        Drive::Field => Some(Applied {
            wave: None,
            field: Some(plant.field().to_vec()),
        }),
    }
}
