//! Which of the plant's messages the controller believes, and when the run is over: a state
//! machine with no network in it (the client feeds it what arrives and acts on its verdicts),
//! so that the rules against reordered and inconsistent messages are tested without processes.
//!
//! Believed: statuses of the plant that answered the controller's challenge (the arrival gate
//! has checked their seal, run instance and order already), a `finished` status only at the step
//! of the plant's last state to this controller, and states addressed to this controller with a
//! field of the model's size. A `finished` status may overtake the last state (they travel on
//! different keys): it is held until that state comes, and dropped once the run goes past it.
//!
//! Exactly once: each step is answered once. A state for the step just answered (the plant
//! resends a state while no answer has reached it) gets that answer again, never a new call of
//! the policy; a state for an earlier step is ignored, and the step never moves backwards. A
//! state addressed to another controller after this one answered is the run's hand-over: this
//! controller's part ends there.

use std::collections::BTreeMap;

use crawler_protocol::{FinalReport, ModelInfo, ProcessState, Role, State, Status};

/// Most `finished` statuses held while the plant's last state is awaited.
const PENDING_FINISHED_MAX: usize = 8;

/// What the controller does after a message.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Nothing now (the message was held, ignored, or changed only what the watch knows).
    Wait,
    /// Answer this state with an actuation (a step not answered before).
    Answer,
    /// Send the answer already given to this state's step again (a resent state).
    Resend,
    /// Another controller controls the run from `step` on: this controller's part is over.
    HandedOver {
        /// The controller the states are now addressed to.
        to: String,
        /// Its first step.
        step: u64,
    },
    /// The run is over: the plant's final report, if its status carried one.
    Finished(Option<Box<FinalReport>>),
    /// The plant failed or stopped the run; why, for the user.
    Ended(String),
    /// The plant's liveliness token went away.
    PlantLeft,
}

/// What the controller knows of its plant and of the run's end.
#[derive(Debug)]
pub struct Watch {
    /// This controller's id (states for other ids are not ours).
    id: String,
    info: ModelInfo,
    /// The plant: the process that answered this controller's challenge.
    plant_id: String,
    /// The step of the plant's last state (`last: true`) to us: the model's `last_step` unless
    /// the plant ended the run early (task mode).
    last_state_step: Option<u64>,
    /// The step of the latest state answered.
    latest_step: Option<u64>,
    pending_finished: BTreeMap<u64, Status>,
    /// A controller that states were addressed to instead of us (who has the run).
    other_controller: Option<String>,
    ignored: u64,
    resent: u64,
    stale: u64,
    notes: Vec<String>,
}

impl Watch {
    /// The watch of controller `id` over the run that `info` describes, whose plant is `plant`.
    pub fn new(id: &str, info: &ModelInfo, plant: &str) -> Self {
        Self {
            id: id.to_string(),
            info: info.clone(),
            plant_id: plant.to_string(),
            last_state_step: None,
            latest_step: None,
            pending_finished: BTreeMap::new(),
            other_controller: None,
            ignored: 0,
            resent: 0,
            stale: 0,
            notes: Vec::new(),
        }
    }

    /// Messages ignored so far (invalid, or not from this run's plant).
    pub fn ignored(&self) -> u64 {
        self.ignored
    }

    /// Counts a message the client could not even decode.
    pub fn ignore(&mut self) {
        self.ignored += 1;
    }

    /// The controller that the plant's states were for, if they were for another one.
    pub fn other_controller(&self) -> Option<&str> {
        self.other_controller.as_deref()
    }

    /// Why messages were ignored since the last call, worth a line each on stderr.
    pub fn take_notes(&mut self) -> Vec<String> {
        std::mem::take(&mut self.notes)
    }

    /// A process of the plant's role went away.
    pub fn plant_down(&mut self, pid: &str) -> Verdict {
        if self.plant_id == pid {
            Verdict::PlantLeft
        } else {
            Verdict::Wait
        }
    }

    /// The step of the latest state answered.
    pub fn latest_step(&self) -> Option<u64> {
        self.latest_step
    }

    /// A status on the plant's key; `answered`: states answered so far.
    pub fn status(&mut self, st: Status, answered: u64) -> Verdict {
        if self.plant_id != st.id || st.role != Role::Plant {
            self.ignored += 1;
            return Verdict::Wait;
        }
        if self.latest_step.is_none()
            && self.last_state_step.is_none()
            && st.state.is_terminal()
            && st.step > 0
            && st.step <= self.info.last_step
        {
            // the run ended before this controller answered anything (a take-over that did not
            // happen in time)
            return Verdict::Ended(format!(
                "the run was {} at step {} before this controller answered any state: {}",
                st.state, st.step, st.message
            ));
        }
        if st.state == ProcessState::Finished
            && self.last_state_step.is_none()
            && finished_may_follow(&st, &self.info, self.latest_step)
        {
            // the last state may still be on its way (another key): wait for it
            if self.pending_finished.len() < PENDING_FINISHED_MAX {
                self.pending_finished.entry(st.step).or_insert(st);
            } else {
                self.ignored += 1;
            }
            return Verdict::Wait;
        }
        if !terminal_is_consistent(&st, &self.info, self.last_state_step) {
            self.ignored += 1;
            self.notes.push(format!(
                "ignoring an inconsistent plant status \"{}\" at step {} (the run ends at step {})",
                st.state, st.step, self.info.last_step
            ));
            return Verdict::Wait;
        }
        match st.state {
            ProcessState::Finished => Verdict::Finished(st.report.map(Box::new)),
            ProcessState::Failed | ProcessState::Stopped if answered > 0 || st.step > 0 => {
                Verdict::Ended(format!("the plant {}: {}", st.state, st.message))
            }
            _ => Verdict::Wait,
        }
    }

    /// A state on the run's state key.
    pub fn state(&mut self, state: &State) -> Verdict {
        if state.controller != self.id {
            if state.controller.is_empty() {
                self.ignored += 1;
                return Verdict::Wait; // before the plant took a controller
            }
            if self.latest_step.is_some_and(|l| state.step > l) {
                // this controller answered before: the run was handed over
                return Verdict::HandedOver {
                    to: state.controller.clone(),
                    step: state.step,
                };
            }
            self.other_controller = Some(state.controller.clone());
            self.ignored += 1;
            return Verdict::Wait; // another controller's, before we joined
        }
        if state.u.len() as u64 != self.info.cells {
            self.ignored += 1;
            return Verdict::Wait;
        }
        if let Some(l) = self.latest_step {
            if state.step < l {
                // never backwards
                self.ignored += 1;
                self.stale += 1;
                return Verdict::Wait;
            }
            if state.step == l && !state.last {
                self.resent += 1;
                return Verdict::Resend;
            }
        }
        if state.last {
            if self.last_state_step.is_none()
                && last_state_fits(state.step, &self.info, self.latest_step)
            {
                self.last_state_step = Some(state.step);
                if let Some(st) = self.pending_finished.remove(&state.step) {
                    return Verdict::Finished(st.report.map(Box::new));
                }
            } else if self.last_state_step != Some(state.step) {
                self.ignored += 1;
            }
            return Verdict::Wait; // the plant's finished status ends the run
        }
        self.latest_step = Some(state.step);
        // a finished status for a step the run went on past was not the plant's
        while let Some(entry) = self.pending_finished.first_entry() {
            if *entry.key() > state.step {
                break;
            }
            let st = entry.remove();
            self.ignored += 1;
            self.notes.push(format!(
                "ignoring an inconsistent plant status \"finished\" at step {} (the run went on to step {})",
                st.step, state.step
            ));
        }
        Verdict::Answer
    }

    /// States of steps already answered that came again (the plant resent them): answered
    /// again with the same actuation.
    pub fn resent(&self) -> u64 {
        self.resent
    }

    /// States of steps before the latest answered: ignored.
    pub fn stale(&self) -> u64 {
        self.stale
    }
}

/// Whether a plant status can be what it says: `finished` only at the step of the plant's last
/// state to this controller (`last_state_step`: the model's last step, or an earlier one where
/// the plant decided its task and ended the run), `failed` and `stopped` only within the run's
/// steps. Non-terminal states are always consistent.
pub fn terminal_is_consistent(st: &Status, info: &ModelInfo, last_state_step: Option<u64>) -> bool {
    match st.state {
        ProcessState::Finished => st.step <= info.last_step && last_state_step == Some(st.step),
        ProcessState::Failed | ProcessState::Stopped => st.step <= info.last_step,
        ProcessState::Waiting | ProcessState::Running => true,
    }
}

/// Whether a `finished` status that arrives before the plant's last state can still turn out
/// consistent: its step is within the run and after the latest state this controller answered.
pub fn finished_may_follow(st: &Status, info: &ModelInfo, latest_step: Option<u64>) -> bool {
    st.step <= info.last_step && latest_step.is_none_or(|l| st.step > l)
}

/// Whether a state marked `last` at `step` can be the plant's last: within the run, and either
/// the model's last step or the step right after the latest state this controller answered (the
/// plant ends a task-mode run early, at the step that decided the task).
pub fn last_state_fits(step: u64, info: &ModelInfo, latest_step: Option<u64>) -> bool {
    step <= info.last_step && (step == info.last_step || latest_step.is_some_and(|l| l + 1 == step))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crawler_protocol::PROTOCOL_VERSION;

    fn info(last_step: u64) -> ModelInfo {
        ModelInfo::example("r", 2, last_step)
    }

    fn status(state: &str, step: u64) -> Status {
        Status {
            v: PROTOCOL_VERSION,
            role: Role::Plant,
            id: "p".into(),
            state: ProcessState::parse(state).unwrap(),
            message: String::new(),
            step,
            rejected: Default::default(),
            report: None,
        }
    }

    #[test]
    fn finished_is_believed_only_at_the_step_of_the_plants_last_state() {
        let info = info(8000);
        // the whole run
        assert!(terminal_is_consistent(
            &status("finished", 8000),
            &info,
            Some(8000)
        ));
        // before the last state came, and at another step than the last state's
        assert!(!terminal_is_consistent(
            &status("finished", 8000),
            &info,
            None
        ));
        assert!(!terminal_is_consistent(
            &status("finished", 1000),
            &info,
            Some(8000)
        ));
        // a task-mode run the plant ended at step 4321 (its last state said so)
        assert!(terminal_is_consistent(
            &status("finished", 4321),
            &info,
            Some(4321)
        ));
        assert!(!terminal_is_consistent(
            &status("finished", 8000),
            &info,
            Some(4321)
        ));
        // never beyond the run, whatever state came
        assert!(!terminal_is_consistent(
            &status("finished", 9000),
            &info,
            Some(9000)
        ));
        // failed and stopped: anywhere within the run
        assert!(terminal_is_consistent(&status("failed", 10), &info, None));
        assert!(terminal_is_consistent(
            &status("stopped", 8000),
            &info,
            None
        ));
        assert!(!terminal_is_consistent(
            &status("failed", 8001),
            &info,
            None
        ));
        assert!(!terminal_is_consistent(
            &status("stopped", u64::MAX),
            &info,
            None
        ));
        assert!(terminal_is_consistent(
            &status("running", 99_999),
            &info,
            None
        ));
    }

    #[test]
    fn a_last_state_fits_only_right_after_the_latest_answered_step_or_at_the_end() {
        let info = info(8000);
        assert!(last_state_fits(8000, &info, Some(7999)));
        // resumed at the end: no state answered before
        assert!(last_state_fits(8000, &info, None));
        // task mode: right after the step just answered
        assert!(last_state_fits(4321, &info, Some(4320)));
        // a gap, a step already answered, or beyond the run: not the plant's last state
        assert!(!last_state_fits(4321, &info, Some(100)));
        assert!(!last_state_fits(4321, &info, Some(4321)));
        assert!(!last_state_fits(4321, &info, None));
        assert!(!last_state_fits(999_999, &info, Some(999_998)));
        // a finished status ahead of the last state may wait for it only if it is ahead of the
        // run and within it
        assert!(finished_may_follow(
            &status("finished", 4321),
            &info,
            Some(4320)
        ));
        assert!(finished_may_follow(&status("finished", 8000), &info, None));
        assert!(!finished_may_follow(
            &status("finished", 1000),
            &info,
            Some(4320)
        ));
        assert!(!finished_may_follow(
            &status("finished", 8001),
            &info,
            Some(4320)
        ));
    }

    fn state(controller: &str, step: u64, cells: usize, last: bool) -> State {
        State {
            v: PROTOCOL_VERSION,
            step,
            time: step as f64 * 1e-3,
            controller: controller.into(),
            u: vec![0.0; cells],
            vel: vec![0.0; cells],
            tension: vec![0.0; cells],
            stuck: vec![false; cells],
            mean_speed: 0.0,
            input_power: 0.0,
            last,
            applied: None,
        }
    }

    /// A watch of controller "c" over a 2-cell run to step 8000 whose plant is "p".
    fn watching() -> Watch {
        Watch::new("c", &info(8000), "p")
    }

    #[test]
    fn a_whole_run_is_answered_and_ends_with_the_plants_finished_status() {
        let mut w = watching();
        for n in 0..8000 {
            assert_eq!(
                w.state(&state("c", n, 2, false)),
                Verdict::Answer,
                "step {n}"
            );
        }
        assert_eq!(w.state(&state("c", 8000, 2, true)), Verdict::Wait);
        let mut done = status("finished", 8000);
        done.message = "done".into();
        assert_eq!(w.status(done, 8000), Verdict::Finished(None));
        assert_eq!(w.ignored(), 0);
    }

    #[test]
    fn statuses_from_anyone_but_the_plant_are_ignored() {
        let mut w = watching();
        for n in 0..8000 {
            w.state(&state("c", n, 2, false));
        }
        w.state(&state("c", 8000, 2, true));
        // the second process of the plant's role, and a process that claims another role
        let mut forged = status("finished", 8000);
        forged.id = "q".into();
        assert_eq!(w.status(forged, 8000), Verdict::Wait);
        let mut forged = status("failed", 10);
        forged.role = Role::Controller;
        assert_eq!(w.status(forged, 8000), Verdict::Wait);
        assert_eq!(w.ignored(), 2);
    }

    #[test]
    fn each_step_is_answered_once_and_a_resent_state_gets_the_same_answer() {
        let mut w = watching();
        assert_eq!(w.state(&state("c", 0, 2, false)), Verdict::Answer);
        assert_eq!(w.state(&state("c", 1, 2, false)), Verdict::Answer);
        // the plant resent state 1 (no answer reached it in time): the answer again, twice
        assert_eq!(w.state(&state("c", 1, 2, false)), Verdict::Resend);
        assert_eq!(w.state(&state("c", 1, 2, false)), Verdict::Resend);
        assert_eq!(w.state(&state("c", 2, 2, false)), Verdict::Answer);
        // an earlier step is never answered again, and the step does not move back
        assert_eq!(w.state(&state("c", 0, 2, false)), Verdict::Wait);
        assert_eq!(w.state(&state("c", 1, 2, false)), Verdict::Wait);
        assert_eq!(w.latest_step(), Some(2));
        assert_eq!(w.state(&state("c", 2, 2, false)), Verdict::Resend);
        assert_eq!((w.resent(), w.stale()), (3, 2));
        assert_eq!(w.state(&state("c", 3, 2, false)), Verdict::Answer);
    }

    #[test]
    fn a_state_for_another_controller_after_this_ones_turn_is_the_hand_over() {
        let mut w = watching();
        for n in 0..10 {
            assert_eq!(w.state(&state("c", n, 2, false)), Verdict::Answer);
        }
        assert_eq!(
            w.state(&state("b", 10, 2, false)),
            Verdict::HandedOver {
                to: "b".into(),
                step: 10
            }
        );
        // a controller waiting to take over sees the other's states and waits, then answers
        // from its first step on
        let mut b = Watch::new("b", &info(8000), "p");
        for n in 0..10 {
            assert_eq!(b.state(&state("c", n, 2, false)), Verdict::Wait);
        }
        assert_eq!(b.other_controller(), Some("c"));
        assert_eq!(b.state(&state("b", 10, 2, false)), Verdict::Answer);
        // ... and if the run ends before its turn, it is told so
        let mut late = Watch::new("d", &info(8000), "p");
        assert_eq!(late.state(&state("c", 7999, 2, false)), Verdict::Wait);
        match late.status(status("finished", 8000), 0) {
            Verdict::Ended(why) => {
                assert!(why.contains("before this controller answered"), "{why}")
            }
            v => panic!("{v:?}"),
        }
    }

    #[test]
    fn a_finished_status_that_overtakes_the_last_state_waits_for_it() {
        let mut w = watching();
        for n in 0..4321 {
            w.state(&state("c", n, 2, false));
        }
        // task mode: the plant ended the run at step 4321, and its status came first
        assert_eq!(w.status(status("finished", 4321), 4321), Verdict::Wait);
        assert_eq!(w.state(&state("c", 4321, 2, true)), Verdict::Finished(None));
    }

    #[test]
    fn a_held_finished_status_is_dropped_once_the_run_goes_past_its_step() {
        let mut w = watching();
        for n in 0..100 {
            w.state(&state("c", n, 2, false));
        }
        // forged (sealed messages make this a replay or a bug, but the rule holds regardless)
        assert_eq!(w.status(status("finished", 100), 100), Verdict::Wait);
        assert_eq!(w.state(&state("c", 100, 2, false)), Verdict::Answer);
        let notes = w.take_notes();
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].contains("went on to step 100"), "{notes:?}");
        assert_eq!(w.ignored(), 1);
        // the real end still ends the run
        for n in 101..8000 {
            w.state(&state("c", n, 2, false));
        }
        assert_eq!(w.state(&state("c", 8000, 2, true)), Verdict::Wait);
        assert_eq!(
            w.status(status("finished", 8000), 8000),
            Verdict::Finished(None)
        );
    }

    #[test]
    fn a_finished_status_far_from_the_run_end_is_ignored_with_a_note() {
        let mut w = watching();
        for n in 0..100 {
            w.state(&state("c", n, 2, false));
        }
        // behind the latest answered step: it cannot be the end that is still coming
        assert_eq!(w.status(status("finished", 50), 100), Verdict::Wait);
        let notes = w.take_notes();
        assert!(
            notes[0].contains("inconsistent plant status \"finished\" at step 50"),
            "{notes:?}"
        );
        assert!(w.take_notes().is_empty());
        assert_eq!(w.state(&state("c", 100, 2, false)), Verdict::Answer);
    }

    #[test]
    fn states_for_others_or_of_the_wrong_size_are_not_answered() {
        let mut w = watching();
        assert_eq!(w.state(&state("other", 0, 2, false)), Verdict::Wait);
        assert_eq!(w.other_controller(), Some("other"));
        // before the plant took a controller its states name none
        assert_eq!(w.state(&state("", 0, 2, false)), Verdict::Wait);
        assert_eq!(w.other_controller(), Some("other"));
        assert_eq!(w.state(&state("c", 0, 3, false)), Verdict::Wait);
        assert_eq!(w.ignored(), 3);
        assert_eq!(w.state(&state("c", 0, 2, false)), Verdict::Answer);
        // a last state that does not fit (a gap after step 0) is not the end
        assert_eq!(w.state(&state("c", 4321, 2, true)), Verdict::Wait);
        assert_eq!(w.ignored(), 4);
        // so a finished status for that step can only wait for a last state that fits
        assert_eq!(w.status(status("finished", 4321), 1), Verdict::Wait);
        assert_eq!(w.state(&state("c", 1, 2, false)), Verdict::Answer);
        assert!(w.take_notes().is_empty());
    }

    #[test]
    fn the_plant_failing_or_leaving_ends_the_run() {
        let mut w = watching();
        // a failure before anything happened is a plant that refused to start: not ours to end
        assert_eq!(w.status(status("failed", 0), 0), Verdict::Wait);
        for n in 0..12 {
            w.state(&state("c", n, 2, false));
        }
        let mut failed = status("failed", 12);
        failed.message = "NaN in the field".into();
        assert_eq!(
            w.status(failed, 12),
            Verdict::Ended("the plant failed: NaN in the field".into())
        );
        assert_eq!(w.plant_down("q"), Verdict::Wait);
        assert_eq!(w.plant_down("p"), Verdict::PlantLeft);
    }
}
