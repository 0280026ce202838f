//! The largest legal message of a run, per key: receivers drop anything larger at arrival.
//!
//! A run of N cells never needs a message larger than these bounds, which follow from the
//! MessagePack encoding (`docs/protocol.md`): a float64 takes 9 bytes, a boolean 1, an array or
//! map header at most 5, an identifier at most [`MAX_ID_LEN`] bytes, a free text at most
//! [`MAX_TEXT_LEN`] bytes. Every bound holds with margin for any valid message; tests encode the
//! largest messages and check them against these numbers.

use crate::messages::{MAX_ID_LEN, MAX_TEXT_LEN};

/// Room for a message's field names, scalars and headers, bytes (the largest fixed part of any
/// message is under 300 bytes, an identifier included).
const HEADER: usize = 2 * MAX_ID_LEN + 256;

/// Bytes of one encoded episode at most (a map of 5 named fields).
pub const EPISODE_BYTES: usize = 72;

/// The per-key size limits of a run with a given number of cells, bytes of payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunLimits {
    /// Number of cells N.
    pub cells: usize,
}

impl RunLimits {
    /// The limits of a run of `cells` cells.
    pub fn new(cells: usize) -> Self {
        Self { cells }
    }

    /// A `State`: three arrays of N float64 and one of N booleans, and the actuation applied
    /// over the last step (at most a field of N float64), about 37 N bytes.
    pub fn state(&self) -> usize {
        37 * self.cells + HEADER
    }

    /// An `Actuation`: a wave, or a field of N float64, about 9 N bytes.
    pub fn actuation(&self) -> usize {
        9 * self.cells + HEADER
    }

    /// An `Events` message: at most N episodes (the plant splits longer lists).
    pub fn events(&self) -> usize {
        EPISODE_BYTES * self.episodes_per_message() + HEADER
    }

    /// Episodes one `Events` message carries at most: N.
    pub fn episodes_per_message(&self) -> usize {
        self.cells.max(1)
    }

    /// A `Status`, `ModelInfo` or `Prediction`, whatever N: two free texts at their limit and
    /// room for the rest (a status holds one text, its message, and the plant's final report of
    /// under 2 KiB).
    pub fn text_message() -> usize {
        2 * MAX_TEXT_LEN + 4 * HEADER
    }

    /// An `Environment` (the pipe map), whatever N: [`crate::MAX_ENVIRONMENT_PIECES`] pieces of
    /// three float64 at most.
    pub fn environment() -> usize {
        27 * crate::environment::MAX_ENVIRONMENT_PIECES + HEADER
    }

    /// A `Join` message (two identifiers and a step).
    pub fn join() -> usize {
        HEADER
    }

    /// A `Metrics` message (fixed size).
    pub fn metrics() -> usize {
        HEADER + 256
    }

    /// The largest legal message of the run on any key: what zenoh is told to reassemble at
    /// most (`transport.link.rx.max_message_size`).
    pub fn largest(&self) -> usize {
        self.state()
            .max(self.actuation())
            .max(self.events())
            .max(Self::text_message())
            .max(Self::environment())
    }

    /// The largest legal message on any key before the run's size is known: what a client's
    /// first session (opened to fetch the plant's `ModelInfo`) reassembles at most. A larger
    /// run (N beyond about 29 000 cells) makes the client reopen its session with the run's
    /// own limit.
    pub fn before_model() -> usize {
        Self::text_message()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::{encode, EpisodeMsg, Events, Metrics, State, Status};
    use crate::{
        Actuation, Applied, EpisodeStats, FinalReport, Outcome, ProcessState, Rejections,
        ReportWindow, Role, TaskResult, WaveMsg, MAX_SCENARIO_NAME_LEN,
    };
    use crawler_facts::{Metric, MetricValues};

    fn id() -> String {
        "x".repeat(MAX_ID_LEN)
    }

    /// A float64 of the largest encoding: no value of a run takes more bytes.
    const BIG: f64 = -1.234_567_890_123_456_7e300;

    #[test]
    fn the_largest_messages_of_a_run_fit_its_limits() {
        for n in [1usize, 2, 17, 256, 4096] {
            largest_messages_of_n_cells_fit(n);
        }
        let report = largest_report();
        let r = rmp_serde::to_vec_named(&report).unwrap().len();
        assert!(r < 2048, "a final report takes {r} bytes");
        largest_status_fits(report);
        largest_environment_fits();
        largest_metrics_and_join_fit();
    }

    /// Checks the largest `State`, `Actuation` and `Events` of a run of `n` cells against the
    /// run's limits (and the state's bound for tightness).
    fn largest_messages_of_n_cells_fit(n: usize) {
        let l = RunLimits::new(n);
        let big = BIG;
        let state = State {
            v: u16::MAX,
            step: u64::MAX,
            time: big,
            controller: id(),
            u: vec![big; n],
            vel: vec![big; n],
            tension: vec![big; n],
            stuck: vec![true; n],
            mean_speed: big,
            input_power: big,
            last: true,
            applied: Some(Applied {
                wave: None,
                field: Some(vec![big; n]),
            }),
        };
        let s = encode(&state).len();
        assert!(s <= l.state(), "state {s} > {}", l.state());
        // an applied wave is smaller than an applied field
        let wave = State {
            applied: Some(Applied {
                wave: Some(WaveMsg {
                    f0: big,
                    k: big,
                    omega: big,
                    phase: big,
                }),
                field: None,
            }),
            ..state.clone()
        };
        assert!(encode(&wave).len() <= l.state());
        // the bound is tight: within a header of the real size
        assert!(
            l.state() - s < HEADER,
            "state bound too loose: {s} vs {}",
            l.state()
        );
        let act = Actuation {
            v: u16::MAX,
            step: u64::MAX,
            controller: id(),
            wave: None,
            field: Some(vec![big; n]),
        };
        assert!(encode(&act).len() <= l.actuation());
        let ep = EpisodeMsg {
            node: u32::MAX,
            start: big,
            end: big,
            duration: big,
            direction: -1,
        };
        let events = Events {
            v: u16::MAX,
            step: u64::MAX,
            time: big,
            episodes: vec![ep; l.episodes_per_message()],
        };
        let e = encode(&events).len();
        assert!(e <= l.events(), "events {e} > {}", l.events());
        assert!(l.largest() >= l.state().max(l.events()));
    }

    /// The largest final report: every text at its limit, every number of the largest encoding.
    fn largest_report() -> FinalReport {
        let big = BIG;
        FinalReport {
            scenario: "s".repeat(MAX_SCENARIO_NAME_LEN),
            values: MetricValues::of(&[
                (Metric::Velocity, big),
                (Metric::Power, big),
                (Metric::Mileage, big),
                (Metric::MaxStress, big),
                (Metric::MaxStrain, big),
                (Metric::StuckFraction, big),
                (Metric::MeanFrictionSelection, big),
            ]),
            dissipation: big,
            identity_velocity: big,
            momentum_residual: Some(big),
            events: EpisodeStats {
                count: u64::MAX,
                per_node_per_period: big,
                mean_duration: big,
                min_duration: big,
            },
            window: ReportWindow {
                start: big,
                end: big,
                periods: big,
                steady: true,
                whole_run: true,
            },
            cells: u64::MAX,
            dt: big,
            step: big,
            courant: big,
            dx: big,
            cells_per_wavelength: Some(big),
            steps: u64::MAX,
            macro_steps: u64::MAX,
            t_end: big,
            state_digest: "f".repeat(8),
            task: Some(TaskResult {
                outcome: Outcome::EnergyExhausted,
                distance_target: big,
                distance: big,
                time_to_distance: Some(big),
                energy_budget: big,
                energy_used: big,
                energy_at_distance: Some(big),
                energy_exhausted_at: Some(big),
                sigma_max: big,
                max_stress: big,
                time_over_sigma_max: big,
                stress_tolerance: big,
                stress_exceeded_at: Some(big),
                run_time: big,
            }),
        }
    }

    /// Checks the largest `Status`, carrying `report`, against the limit of text messages.
    fn largest_status_fits(report: FinalReport) {
        let status = Status {
            v: u16::MAX,
            role: Role::Controller,
            id: id(),
            state: ProcessState::Finished,
            message: "m".repeat(MAX_TEXT_LEN),
            step: u64::MAX,
            rejected: Rejections {
                malformed: u64::MAX,
                version: u64::MAX,
                invalid: u64::MAX,
                foreign: u64::MAX,
                other_run: u64::MAX,
                replayed: u64::MAX,
                stale: u64::MAX,
                duplicate: u64::MAX,
                future: u64::MAX,
                overflow: u64::MAX,
            },
            report: Some(report),
        };
        assert!(encode(&status).len() <= RunLimits::text_message());
    }

    /// Checks the largest `Environment` against its limit, and that a client's first session
    /// reassembles it.
    fn largest_environment_fits() {
        let n = crate::MAX_ENVIRONMENT_PIECES;
        let big = BIG;
        let env = crate::Environment {
            v: u16::MAX,
            run: id(),
            start: big,
            eps: big,
            n_f: big,
            piece_start: vec![big; n],
            piece_eps: vec![big; n],
            piece_n_f: vec![big; n],
            merged: u64::MAX,
        };
        let e = encode(&env).len();
        assert!(e <= RunLimits::environment(), "environment {e}");
        // every client session, even the first one, reassembles the largest map
        assert!(RunLimits::environment() <= RunLimits::before_model());
    }

    /// Checks the largest `Metrics` and `Join` against their limits.
    fn largest_metrics_and_join_fit() {
        let m = Metrics {
            v: u16::MAX,
            step: u64::MAX,
            block: u64::MAX,
            steady: true,
            start: -1e300,
            end: -1e300,
            values: MetricValues::of(&[
                (Metric::Velocity, -1e300),
                (Metric::Power, -1e300),
                (Metric::Mileage, -1e300),
                (Metric::MaxStress, -1e300),
                (Metric::MaxStrain, -1e300),
                (Metric::StuckFraction, -1e300),
                (Metric::MeanFrictionSelection, -1e300),
                (Metric::EpisodesPerNodePerPeriod, -1e300),
            ]),
            clock: true,
        };
        assert!(encode(&m).len() <= RunLimits::metrics());
        let join = crate::Join {
            v: u16::MAX,
            controller: id(),
            policy: id(),
            take_over: Some(u64::MAX),
        };
        assert!(encode(&join).len() <= RunLimits::join());
    }
}
