//! What the recorder accepts beyond a message that decodes: only what the run the plant described
//! (its `ModelInfo`) can have produced. A message failing a check is not recorded; the recorder
//! counts it and notes it in the recording.
//!
//! Pure functions of a message and the run's facts: no clock, no network, no recording.

use crawler_protocol::{Events, Metrics, ModelInfo, Prediction, ProcessState, State, Status};

/// What the plant said about its run, as the checks need it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunFacts {
    /// Number of cells N.
    pub cells: u64,
    /// Start time t0, s.
    pub start: f64,
    /// Communication step H, s.
    pub step: f64,
    /// The run's last step.
    pub last_step: u64,
}

impl RunFacts {
    /// The facts of the run described by `info`.
    pub fn of(info: &ModelInfo) -> Self {
        Self {
            cells: info.cells,
            start: info.start_time,
            step: info.step,
            last_step: info.last_step,
        }
    }

    /// The run's end time `t0 + last_step H`, s.
    pub fn end(&self) -> f64 {
        self.start + self.last_step as f64 * self.step
    }

    /// The run's length `last_step H`, s (from its first step, however it was resumed).
    pub fn length(&self) -> f64 {
        self.last_step as f64 * self.step
    }

    /// Rounding allowance on times, s: a millionth of a step (times are `t0 + n H` from integers).
    fn slack(&self) -> f64 {
        1e-6 * self.step + 1e-12 * self.end().abs()
    }

    /// True if `t` lies in the run, `[t0, t_end]`.
    fn inside(&self, t: f64) -> bool {
        t >= self.start - self.slack() && t <= self.end() + self.slack()
    }

    fn step_ok(&self, what: &str, step: u64) -> Result<(), String> {
        if step > self.last_step {
            return Err(format!(
                "{what}.step = {step}: the run ends at step {}",
                self.last_step
            ));
        }
        Ok(())
    }

    fn time_ok(&self, what: &str, t: f64) -> Result<(), String> {
        if !self.inside(t) {
            return Err(format!(
                "{what} = {t} s: outside the run [{}, {}] s",
                self.start,
                self.end()
            ));
        }
        Ok(())
    }
}

/// A state of this run: N values, a step of the run at its time `t0 + step H`.
pub fn state(s: &State, f: &RunFacts) -> Result<(), String> {
    if s.u.len() as u64 != f.cells {
        return Err(format!(
            "state.u has {} values: the run has {} cells",
            s.u.len(),
            f.cells
        ));
    }
    f.step_ok("state", s.step)?;
    let t = f.start + s.step as f64 * f.step;
    if (s.time - t).abs() > f.slack() {
        return Err(format!(
            "state.time = {} s at step {}: the run's clock says {t} s",
            s.time, s.step
        ));
    }
    Ok(())
}

/// Stick-slip episodes the run can have had: at most N per message, each of a node in range,
/// lasting a positive time no longer than the run, ending inside the run by the message's time.
pub fn events(e: &Events, f: &RunFacts) -> Result<(), String> {
    f.step_ok("events", e.step)?;
    f.time_ok("events.time", e.time)?;
    if e.episodes.is_empty() || e.episodes.len() as u64 > f.cells {
        return Err(format!(
            "events.episodes has {} episodes: allowed 1 to {} (one per node)",
            e.episodes.len(),
            f.cells
        ));
    }
    for (i, ep) in e.episodes.iter().enumerate() {
        let at = |field: &str| format!("events.episodes[{i}].{field}");
        if u64::from(ep.node) >= f.cells {
            return Err(format!(
                "{} = {}: the run's nodes are 0 to {}",
                at("node"),
                ep.node,
                f.cells - 1
            ));
        }
        if !(ep.duration > 0.0 && ep.duration <= f.length() + f.slack()) {
            return Err(format!(
                "{} = {} s: allowed > 0 and at most the run's length {} s",
                at("duration"),
                ep.duration,
                f.length()
            ));
        }
        f.time_ok(&at("start"), ep.start)?;
        f.time_ok(&at("end"), ep.end)?;
        if ep.end > e.time + f.slack() {
            return Err(format!(
                "{} = {} s: after the message's time {} s",
                at("end"),
                ep.end,
                e.time
            ));
        }
        if ep.start > ep.end {
            return Err(format!(
                "{} = {} s: after its end {} s",
                at("start"),
                ep.start,
                ep.end
            ));
        }
    }
    Ok(())
}

/// An averaging block of the run: a time span inside the run; suprema of magnitudes and episode
/// rates not negative (the other values are the plant's averages: finite, by decoding).
pub fn metrics(m: &Metrics, f: &RunFacts) -> Result<(), String> {
    f.step_ok("metrics", m.step)?;
    f.time_ok("metrics.start", m.start)?;
    f.time_ok("metrics.end", m.end)?;
    if m.end <= m.start {
        return Err(format!(
            "metrics.end = {} s: not after metrics.start = {} s",
            m.end, m.start
        ));
    }
    // every value within its metric's range (the metric table's)
    m.values.validate("metrics").map_err(|e| e.to_string())
}

/// A prediction of the run's controller (`controller`, once known from the states) for a step
/// of the run.
pub fn prediction(p: &Prediction, f: &RunFacts, controller: Option<&str>) -> Result<(), String> {
    f.step_ok("prediction", p.step)?;
    if let Some(c) = controller {
        if p.controller != c {
            return Err(format!(
                "prediction.controller = {:?}: the run's controller is {c}",
                p.controller
            ));
        }
    }
    Ok(())
}

/// A plant status that can be what it says: `finished` only at the run's last step, `failed`
/// and `stopped` within the run's steps. The run's last step is that of the plant's last state
/// (`last_state`, once it came: the model's last step, or an earlier one where the plant decided
/// its task and ended the run), else the model's.
pub fn terminal(s: &Status, f: &RunFacts, last_state: Option<u64>) -> Result<(), String> {
    match (s.state, last_state) {
        (ProcessState::Finished, Some(l)) if s.step != l => Err(format!(
            "status finished at step {}: the plant's last state was step {l}",
            s.step
        )),
        (ProcessState::Finished, None) if s.step != f.last_step => Err(format!(
            "status finished at step {}: the run ends at step {} (or earlier, at the step of the \
             plant's last state, which has not come)",
            s.step, f.last_step
        )),
        (state, _) if state.is_terminal() => f.step_ok("status", s.step),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crawler_facts::{Metric, MetricValues};
    use crawler_protocol::{EpisodeMsg, Role, PROTOCOL_VERSION};

    fn facts() -> RunFacts {
        // 128 cells, t0 = 0, H = 1 ms, 8000 steps: the run is [0, 8] s
        RunFacts {
            cells: 128,
            start: 0.0,
            step: 1e-3,
            last_step: 8000,
        }
    }

    fn episode(node: u32, start: f64, end: f64) -> EpisodeMsg {
        EpisodeMsg {
            node,
            start,
            end,
            duration: end - start,
            direction: 1,
        }
    }

    fn events(step: u64, episodes: Vec<EpisodeMsg>) -> Events {
        Events {
            v: PROTOCOL_VERSION,
            step,
            time: step as f64 * 1e-3,
            episodes,
        }
    }

    #[test]
    fn possible_episodes_pass_and_each_impossible_one_is_named() {
        let f = facts();
        events_ok(
            &f,
            events(700, vec![episode(17, 0.6, 0.7), episode(127, 0.0, 0.7)]),
        );
        for (e, needle) in [
            (events(700, vec![episode(128, 0.6, 0.7)]), "node = 128"),
            (
                events(700, vec![episode(u32::MAX, 0.6, 0.7)]),
                "node = 4294967295",
            ),
            (
                events(
                    700,
                    vec![EpisodeMsg {
                        duration: -0.1,
                        ..episode(1, 0.6, 0.7)
                    }],
                ),
                "duration = -0.1",
            ),
            (
                events(
                    700,
                    vec![EpisodeMsg {
                        duration: 0.0,
                        ..episode(1, 0.6, 0.6)
                    }],
                ),
                "duration = 0",
            ),
            (
                events(
                    8000,
                    vec![EpisodeMsg {
                        duration: 9.0,
                        ..episode(1, 0.6, 0.7)
                    }],
                ),
                "duration = 9",
            ),
            (events(700, vec![episode(1, -1.0, 0.7)]), "start = -1"),
            (
                events(700, vec![episode(1, 0.6, 0.8)]),
                "after the message's time",
            ),
            (
                events(
                    700,
                    vec![EpisodeMsg {
                        start: 0.69,
                        end: 0.65,
                        ..episode(1, 0.6, 0.7)
                    }],
                ),
                "after its end",
            ),
            (
                events(8001, vec![episode(1, 0.6, 0.7)]),
                "events.step = 8001",
            ),
            (events(700, vec![]), "0 episodes"),
            (events(700, vec![episode(1, 0.6, 0.7); 129]), "129 episodes"),
        ] {
            let err = super::events(&e, &f).unwrap_err();
            assert!(err.contains(needle), "{needle}: {err}");
        }
    }

    fn events_ok(f: &RunFacts, e: Events) {
        super::events(&e, f).unwrap();
    }

    fn metrics() -> Metrics {
        Metrics {
            v: PROTOCOL_VERSION,
            step: 5000,
            block: 3,
            steady: true,
            start: 4.9,
            end: 5.0,
            values: MetricValues::of(&[
                (Metric::Velocity, 0.05),
                (Metric::Power, 1.0),
                (Metric::Mileage, 0.05),
                (Metric::MaxStress, 1.5e4),
                (Metric::MaxStrain, 0.1),
                (Metric::StuckFraction, 0.02),
                (Metric::MeanFrictionSelection, 0.4),
                (Metric::EpisodesPerNodePerPeriod, 0.01),
            ]),
            clock: false,
        }
    }

    #[test]
    fn possible_metrics_pass_and_each_impossible_block_is_named() {
        let f = facts();
        super::metrics(&metrics(), &f).unwrap();
        let mut nan_mileage = metrics();
        nan_mileage.values.set(Metric::Mileage, None); // P = 0
        super::metrics(&nan_mileage, &f).unwrap();
        for (edit, needle) in [
            (
                &(|m: &mut Metrics| m.step = 9000) as &dyn Fn(&mut Metrics),
                "step = 9000",
            ),
            (&|m: &mut Metrics| m.end = 4.0, "not after"),
            (&|m: &mut Metrics| m.start = -3.0, "start = -3"),
            (&|m: &mut Metrics| m.end = 9.5, "end = 9.5"),
            (
                &|m: &mut Metrics| m.values.set(Metric::MaxStress, Some(-1.0)),
                "max_stress = -1",
            ),
            (
                &|m: &mut Metrics| m.values.set(Metric::MaxStrain, Some(-0.1)),
                "max_strain = -0.1",
            ),
            (
                &|m: &mut Metrics| m.values.set(Metric::EpisodesPerNodePerPeriod, Some(-1.0)),
                "episodes_per_node_per_period = -1",
            ),
        ] {
            let mut m = metrics();
            edit(&mut m);
            let err = super::metrics(&m, &f).unwrap_err();
            assert!(err.contains(needle), "{needle}: {err}");
        }
    }

    #[test]
    fn a_terminal_status_must_fit_the_run() {
        let f = facts();
        let status = |state: &str, step: u64| Status {
            v: PROTOCOL_VERSION,
            role: Role::Plant,
            id: "p".into(),
            state: ProcessState::parse(state).unwrap(),
            message: String::new(),
            step,
            rejected: Default::default(),
            report: None,
        };
        terminal(&status("finished", 8000), &f, None).unwrap();
        terminal(&status("finished", 8000), &f, Some(8000)).unwrap();
        assert!(terminal(&status("finished", 4000), &f, None)
            .unwrap_err()
            .contains("ends at step 8000"));
        // a task-mode run the plant ended at step 4000: its last state said so
        terminal(&status("finished", 4000), &f, Some(4000)).unwrap();
        assert!(terminal(&status("finished", 8000), &f, Some(4000))
            .unwrap_err()
            .contains("last state was step 4000"));
        assert!(terminal(&status("finished", 3999), &f, Some(4000)).is_err());
        // never beyond the run
        assert!(terminal(&status("finished", 9000), &f, Some(9000)).is_err());
        terminal(&status("failed", 4000), &f, None).unwrap();
        assert!(terminal(&status("stopped", 9000), &f, None).is_err());
        terminal(&status("running", 4000), &f, None).unwrap();
    }

    #[test]
    fn a_state_must_fit_the_runs_grid_and_clock() {
        let f = facts();
        let st = |n: usize, step: u64, time: f64| State {
            v: PROTOCOL_VERSION,
            step,
            time,
            controller: String::new(),
            u: vec![0.0; n],
            vel: vec![0.0; n],
            tension: vec![0.0; n],
            stuck: vec![false; n],
            mean_speed: 0.0,
            input_power: 0.0,
            last: false,
            applied: None,
        };
        state(&st(128, 3000, 3.0), &f).unwrap();
        assert!(state(&st(127, 3000, 3.0), &f)
            .unwrap_err()
            .contains("128 cells"));
        assert!(state(&st(128, 3000, 3.5), &f)
            .unwrap_err()
            .contains("clock"));
        assert!(state(&st(128, 999_999, 999.999), &f).is_err());
    }
}
