//! The paper's task as a way to end a run: travel `D` on an energy budget `J0` without exceeding
//! the stress limit `sigma_max`.
//!
//! A [`TaskTracker`] follows a run one communication step at a time: the distance travelled by the
//! body's centre of mass (the mean displacement since the start), the net work done by the
//! actuator (`∫ P dt`: work the body returns to the muscles counts as recovered, as in the paper's
//! mileage `M = V / P`), the largest stress and the time spent above `sigma_max`. It decides how
//! the run ends: the distance reached first (timed by interpolation inside the step), the energy
//! spent first, or neither by the end of the run. In task mode (`task.end_run = true`) the run
//! stops at the end of the step that decided it.
//!
//! The outcome adds the stress limit: a run whose time above `sigma_max` passed the task's
//! `stress_tolerance` (0 by default) before it reached `D` or spent `J0` has failed with "stress
//! exceeded", whatever came after. The stress does not end the run (a run goes on to `D` or `J0`
//! as it would without the limit, so its trajectory, its digest and the distance and energy it
//! reports are those of the same run without a limit); it is counted by whole communication
//! steps: the step in which the time above `sigma_max` passes the tolerance is the step the limit
//! broke, at its end ([`TaskTracker::stress_exceeded_at`]).

use serde::{Deserialize, Serialize};

use crate::plant::StepOutputs;
use crate::scenario::Task;

pub use crawler_facts::Outcome;

/// Running totals of a run against its task.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TaskTracker {
    /// The task.
    pub task: Task,
    /// Mean displacement at the start of the run, m.
    pub start_position: f64,
    /// Time of the start, s.
    pub start_time: f64,
    /// Distance travelled by the centre of mass so far, m.
    pub distance: f64,
    /// Net actuator work so far, J.
    pub energy: f64,
    /// Largest stress so far, Pa.
    pub max_stress: f64,
    /// Time spent above `sigma_max`, s.
    pub time_over_stress: f64,
    /// Time of the last observed step's end, s.
    pub time: f64,
    /// When the distance was reached (interpolated inside its step), s.
    pub reached_at: Option<f64>,
    /// Net work spent when the distance was reached, J.
    pub energy_at_distance: Option<f64>,
    /// When the budget was spent (interpolated), s.
    pub exhausted_at: Option<f64>,
    /// End of the step in which the time above `sigma_max` passed the task's tolerance, s (only
    /// before the run's end was decided).
    #[serde(default)]
    pub stress_exceeded_at: Option<f64>,
}

impl TaskTracker {
    /// Every number is one the tracker can have produced (a tracker read from a file): finite,
    /// the largest stress `-inf` before the first step or >= 0.
    pub fn validate(&self) -> Result<(), crate::error::ParamError> {
        use crate::error::{finite, non_negative};
        self.task.validate()?;
        finite("task.start_position", self.start_position)?;
        finite("task.start_time", self.start_time)?;
        finite("task.distance", self.distance)?;
        non_negative("task.energy", self.energy)?;
        if self.max_stress != f64::NEG_INFINITY {
            non_negative("task.max_stress", self.max_stress)?;
        }
        non_negative("task.time_over_stress", self.time_over_stress)?;
        finite("task.time", self.time)?;
        for (name, x) in [
            ("task.reached_at", self.reached_at),
            ("task.energy_at_distance", self.energy_at_distance),
            ("task.exhausted_at", self.exhausted_at),
            ("task.stress_exceeded_at", self.stress_exceeded_at),
        ] {
            if let Some(x) = x {
                finite(name, x)?;
            }
        }
        Ok(())
    }

    /// A tracker for `task` of a run starting at `time` with mean displacement `position`.
    pub fn new(task: Task, time: f64, position: f64) -> Self {
        Self {
            task,
            start_position: position,
            start_time: time,
            distance: 0.0,
            energy: 0.0,
            max_stress: f64::NEG_INFINITY,
            time_over_stress: 0.0,
            time,
            reached_at: None,
            energy_at_distance: None,
            exhausted_at: None,
            stress_exceeded_at: None,
        }
    }

    /// Takes one communication step that ended at `time` (s) with mean displacement `position`
    /// (m) and the step's outputs (over `h` seconds). Returns how the run ends once that is
    /// decided (the distance or the budget reached first), and keeps returning it.
    pub fn observe(
        &mut self,
        time: f64,
        h: f64,
        position: f64,
        out: &StepOutputs,
    ) -> Option<Outcome> {
        let (d0, e0, t0) = (self.distance, self.energy, self.time);
        let d1 = position - self.start_position;
        let e1 = e0 + out.input_power * h;
        self.distance = d1;
        self.energy = e1;
        self.time = time;
        self.max_stress = self.max_stress.max(out.max_stress);
        self.time_over_stress += out.time_over_stress;
        if self.decided().is_some() {
            return self.decided();
        }
        if self.stress_exceeded_at.is_none() && self.time_over_stress > self.task.stress_tolerance {
            self.stress_exceeded_at = Some(time);
        }
        // Linear interpolation inside the step of when each threshold was crossed.
        let crossing = |a: f64, b: f64, level: f64| {
            (b >= level && a < level)
                .then(|| t0 + (time - t0) * ((level - a) / (b - a)).clamp(0.0, 1.0))
        };
        let reach = crossing(d0, d1, self.task.distance);
        let spend = crossing(e0, e1, self.task.energy);
        match (reach, spend) {
            (Some(r), Some(s)) if s < r => self.exhausted_at = Some(s),
            (Some(r), _) => {
                self.reached_at = Some(r);
                self.energy_at_distance = Some(e0 + (e1 - e0) * (r - t0) / (time - t0).max(1e-300));
            }
            (None, Some(s)) => self.exhausted_at = Some(s),
            (None, None) => {}
        }
        self.decided()
    }

    /// How the run ends, if decided: [`Outcome::Reached`] when `D` came first,
    /// [`Outcome::EnergyExhausted`] when `J0` was spent first (what ends a run in task mode; the
    /// stress limit does not, see [`Self::outcome`]).
    pub fn decided(&self) -> Option<Outcome> {
        if self.reached_at.is_some() {
            Some(Outcome::Reached)
        } else if self.exhausted_at.is_some() {
            Some(Outcome::EnergyExhausted)
        } else {
            None
        }
    }

    /// The outcome of the run so far: "stress exceeded" if the stress limit broke before the
    /// run's end was decided, else how it ended ("time up" if undecided).
    pub fn outcome(&self) -> Outcome {
        if self.stress_exceeded_at.is_some() {
            Outcome::StressExceeded
        } else {
            self.decided().unwrap_or(Outcome::TimeUp)
        }
    }

    /// The report of the run so far.
    pub fn report(&self) -> TaskReport {
        let t = self.task;
        TaskReport {
            outcome: self.outcome(),
            distance_target: t.distance,
            distance: self.distance,
            time_to_distance: self.reached_at.map(|r| r - self.start_time),
            energy_budget: t.energy,
            energy_used: self.energy,
            energy_at_distance: self.energy_at_distance,
            energy_exhausted_at: self.exhausted_at.map(|e| e - self.start_time),
            sigma_max: t.sigma_max,
            max_stress: self.max_stress,
            time_over_sigma_max: self.time_over_stress,
            stress_tolerance: t.stress_tolerance,
            stress_exceeded_at: self.stress_exceeded_at.map(|e| e - self.start_time),
            run_time: self.time - self.start_time,
        }
    }
}

/// How a run did against its task (SI units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TaskReport {
    /// "reached", "stress exceeded", "energy exhausted" or "time up".
    pub outcome: Outcome,
    /// The task's distance D, m.
    pub distance_target: f64,
    /// Distance the centre of mass travelled, m.
    pub distance: f64,
    /// Time from the start until D was reached, s.
    pub time_to_distance: Option<f64>,
    /// The task's energy J0, J.
    pub energy_budget: f64,
    /// Net actuator work over the run, J.
    pub energy_used: f64,
    /// Net actuator work when D was reached, J.
    pub energy_at_distance: Option<f64>,
    /// Time from the start until J0 was spent, s.
    pub energy_exhausted_at: Option<f64>,
    /// The stress limit, Pa.
    pub sigma_max: f64,
    /// Largest stress over the run, Pa.
    pub max_stress: f64,
    /// Time during which the stress exceeded sigma_max, s.
    pub time_over_sigma_max: f64,
    /// Time the stress may spend above sigma_max, s.
    pub stress_tolerance: f64,
    /// Time from the start until the stress had been above sigma_max for longer than the
    /// tolerance (end of that step), s; only if that came before D or J0.
    pub stress_exceeded_at: Option<f64>,
    /// Length of the run, s.
    pub run_time: f64,
}

impl TaskReport {
    /// One paragraph for the summaries.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "task: {} ({:.4} of {} m travelled, {:.4} of {} J spent",
            self.outcome, self.distance, self.distance_target, self.energy_used, self.energy_budget
        );
        if let Some(t) = self.time_to_distance {
            s += &format!("; distance reached after {t:.3} s");
            if let Some(e) = self.energy_at_distance {
                s += &format!(" on {e:.4} J");
            }
        }
        if let Some(t) = self.energy_exhausted_at {
            s += &format!("; budget spent after {t:.3} s");
        }
        s += &format!(
            "); largest stress {:.4e} Pa against {:.4e}, {:.4} s above it",
            self.max_stress, self.sigma_max, self.time_over_sigma_max
        );
        if let Some(t) = self.stress_exceeded_at {
            s += &format!(
                " (more than the {} s allowed after {t:.3} s)",
                self.stress_tolerance
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step(power: f64, max_stress: f64, over: f64) -> StepOutputs {
        StepOutputs {
            mean_speed: 0.0,
            input_power: power,
            stuck_nodes: 0,
            max_stress,
            time_over_stress: over,
        }
    }

    const TASK: Task = Task {
        distance: 1.0,
        energy: 20.0,
        sigma_max: 100e3,
        stress_tolerance: 0.0,
        end_run: true,
    };

    #[test]
    fn reaching_the_distance_is_timed_inside_its_step() {
        let mut t = TaskTracker::new(TASK, 0.0, 0.5);
        // 0.3 m per 1 s step on 1 W: the centre passes 1 m at t = 3 + 0.1 / 0.3 s
        let mut outcome = None;
        for n in 1..=4 {
            outcome = t.observe(n as f64, 1.0, 0.5 + 0.3 * n as f64, &step(1.0, 5e4, 0.0));
        }
        assert_eq!(outcome, Some(Outcome::Reached));
        let r = t.report();
        assert!((r.time_to_distance.unwrap() - (3.0 + 0.1 / 0.3)).abs() < 1e-12);
        assert!((r.energy_at_distance.unwrap() - (3.0 + 0.1 / 0.3)).abs() < 1e-12);
        assert_eq!(r.energy_used, 4.0);
        assert_eq!(r.outcome, Outcome::Reached);
    }

    #[test]
    fn the_budget_spent_first_is_a_failure_and_stays_one() {
        let mut t = TaskTracker::new(TASK, 10.0, 0.0);
        // 8 J per step, 0.1 m per step: the budget runs out at 12.5 s, the distance never comes
        assert_eq!(t.observe(11.0, 1.0, 0.1, &step(8.0, 1e5, 0.2)), None);
        assert_eq!(t.observe(12.0, 1.0, 0.2, &step(8.0, 2e5, 0.5)), None);
        assert_eq!(
            t.observe(13.0, 1.0, 0.3, &step(8.0, 1e5, 0.0)),
            Some(Outcome::EnergyExhausted)
        );
        assert_eq!(
            t.observe(14.0, 1.0, 2.0, &step(8.0, 1e5, 0.0)),
            Some(Outcome::EnergyExhausted)
        );
        let r = t.report();
        assert!((r.energy_exhausted_at.unwrap() - 2.5).abs() < 1e-12);
        assert_eq!(r.max_stress, 2e5);
        assert!((r.time_over_sigma_max - 0.7).abs() < 1e-12);
        // the stress was above the limit (tolerance 0) in the first step, before the budget ran
        // out: that is the failure named
        assert_eq!(r.outcome, Outcome::StressExceeded);
        assert_eq!(r.stress_exceeded_at, Some(1.0));
    }

    #[test]
    fn a_run_that_reaches_the_distance_above_the_stress_limit_has_failed() {
        let over = |tolerance: f64| {
            let mut t = TaskTracker::new(
                Task {
                    stress_tolerance: tolerance,
                    ..TASK
                },
                0.0,
                0.0,
            );
            // 0.3 m per 1 s step; 0.25 s above sigma_max in each of the first two steps
            for n in 1..=4 {
                let over = if n <= 2 { 0.25 } else { 0.0 };
                t.observe(n as f64, 1.0, 0.3 * n as f64, &step(1.0, 1.2e5, over));
            }
            t
        };
        // with no tolerance the first step broke the limit: the distance came later
        let t = over(0.0);
        assert_eq!(t.decided(), Some(Outcome::Reached), "the run ended at D");
        let r = t.report();
        assert_eq!(r.outcome, Outcome::StressExceeded);
        assert_eq!(r.stress_exceeded_at, Some(1.0));
        assert!(r.time_to_distance.is_some() && r.energy_at_distance.is_some());
        assert!(r.summary().contains("stress exceeded"), "{}", r.summary());
        // 0.4 s allowed: broken in the second step (0.5 s above)
        assert_eq!(over(0.4).report().stress_exceeded_at, Some(2.0));
        assert_eq!(over(0.4).report().outcome, Outcome::StressExceeded);
        // 0.5 s allowed: never more than that, so the task is done
        let r = over(0.5).report();
        assert_eq!(r.outcome, Outcome::Reached);
        assert_eq!(r.stress_exceeded_at, None);
        assert!((r.time_over_sigma_max - 0.5).abs() < 1e-12);
    }

    #[test]
    fn stress_after_the_run_was_decided_does_not_change_its_outcome() {
        let mut t = TaskTracker::new(TASK, 0.0, 0.0);
        assert_eq!(
            t.observe(1.0, 1.0, 1.5, &step(1.0, 5e4, 0.0)),
            Some(Outcome::Reached)
        );
        // a run that is not in task mode goes on: its stress is reported, the outcome stays
        t.observe(2.0, 1.0, 3.0, &step(1.0, 2e5, 0.5));
        let r = t.report();
        assert_eq!(r.outcome, Outcome::Reached);
        assert_eq!(r.max_stress, 2e5);
        assert_eq!(r.time_over_sigma_max, 0.5);
    }

    #[test]
    fn within_one_step_the_earlier_crossing_wins() {
        let mut t = TaskTracker::new(TASK, 0.0, 0.0);
        // one step crossing both: distance at 0.5 s, budget at 0.8 s
        let out = t.observe(1.0, 1.0, 2.0, &step(25.0, 0.0, 0.0));
        assert_eq!(out, Some(Outcome::Reached));
        let mut t = TaskTracker::new(TASK, 0.0, 0.0);
        // distance at 0.8 s, budget at 0.5 s
        let out = t.observe(1.0, 1.0, 1.25, &step(40.0, 0.0, 0.0));
        assert_eq!(out, Some(Outcome::EnergyExhausted));
        assert_eq!(t.report().outcome, Outcome::EnergyExhausted);
        let t = TaskTracker::new(TASK, 0.0, 0.0);
        assert_eq!(t.report().outcome, Outcome::TimeUp);
    }
}
