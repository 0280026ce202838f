//! What the other messages add: the pipe, metric blocks and the models' predictions, stick-slip
//! episodes, statuses and the plant's final report; and the recording's static parts.

use crawler_protocol::{
    Environment, Events, FinalReport, Metrics, Prediction, ProcessState, Role, Status,
};

use super::{Live, Recorder, HELD_FINISHED_MAX};
use crate::checks;
use crate::paths;
use crawler_facts::Metric;

/// Episodes sent to the recording as one chunk (at the first events message that reaches
/// it). In hard stick-slip tens of thousands of episodes end per second: a logging call, or a
/// formatted text row, apiece made the recorder fall behind the run.
pub const EPISODE_ROWS: usize = 4096;

/// Stick episodes waiting to be sent together, as columns: a row per episode, at the step (and
/// time) of the events message that brought it.
#[derive(Default)]
pub struct EpisodeRows {
    steps: Vec<i64>,
    times: Vec<f64>,
    node: Vec<u32>,
    start: Vec<f64>,
    end: Vec<f64>,
    duration: Vec<f64>,
    direction: Vec<i8>,
}

/// Colours of the metric series' sources (the plant's per-period blocks in the dark theme's
/// foreground, drawn widest: the truth).
const SOURCE_COLOURS: [(&str, [u8; 3], f32); 4] = [
    ("plant", [235, 235, 235], 2.5),
    ("running", [90, 170, 250], 1.5),
    ("paper", [230, 120, 20], 1.5),
    ("improved", [30, 160, 80], 1.5),
];

/// Stick red, slip blue, in a lane.
pub fn lane_colours() -> rerun::StateConfiguration {
    rerun::StateConfiguration::new()
        .with_values(["stick", "slip"])
        .with_colors([rgb([220, 50, 40]), rgb([60, 120, 230])])
}

fn rgb(c: [u8; 3]) -> rerun::Color {
    rerun::Color::from_rgb(c[0], c[1], c[2])
}

impl Recorder {
    pub(super) fn log_static(&self) -> anyhow::Result<()> {
        let s = &self.sinks;
        let classes = rerun::AnnotationContext::new([
            (0, "slip", rerun::Rgba32::from_rgb(60, 120, 230)),
            (1, "stick", rerun::Rgba32::from_rgb(220, 50, 40)),
        ]);
        s.log_static(paths::BODY, &classes)?;
        s.log_static(paths::PIPE, &classes)?;
        // the pipe is many body lengths long: points of a fixed size on screen
        s.log_static(
            paths::PIPE_BODY,
            &rerun::Points2D::update_fields().with_radii([rerun::Radius::new_ui_points(2.5)]),
        )?;
        for m in paths::METRICS.map(Metric::name) {
            for (source, c, width) in SOURCE_COLOURS {
                s.log_static(
                    paths::metric_series(m, source),
                    &rerun::SeriesLines::new()
                        .with_names([source])
                        .with_colors([rgb(c)])
                        .with_widths([width]),
                )?;
            }
            s.log_static(
                paths::step_series(m),
                &rerun::SeriesLines::new()
                    .with_names([format!("{m} of each step")])
                    .with_colors([rgb([150, 150, 150])])
                    .with_widths([1.0]),
            )?;
        }
        let line = |name: &str, c: [u8; 3], width: f32| {
            rerun::SeriesLines::new()
                .with_names([name])
                .with_colors([rgb(c)])
                .with_widths([width])
        };
        s.log_static(
            format!("{}/plant", paths::TAIL),
            &line("u(0, t) plant", [235, 235, 235], 2.0),
        )?;
        s.log_static(
            format!("{}/paper", paths::TAIL),
            &line("u(0, t) paper mu0 + eps mu1", [230, 120, 20], 1.5),
        )?;
        for (name, c) in [("distance", [235, 235, 235]), ("energy", [235, 235, 235])] {
            s.log_static(paths::task(name), &line(name, c, 2.0))?;
        }
        s.log_static(
            paths::task("distance/target"),
            &line("distance D", [230, 120, 20], 1.5),
        )?;
        s.log_static(
            paths::task("energy/target"),
            &line("energy budget J0", [230, 120, 20], 1.5),
        )?;
        Ok(())
    }

    /// Draws the world under the body (in the body view, pipe coordinates scaled to body
    /// lengths by the world's transform): a ruler every 0.1 m, labelled every metre, and the
    /// pipe's friction as a band whose thickness is eps (patches orange, the rest grey).
    pub(super) fn draw_world(&self, env: Option<&Environment>) -> anyhow::Result<()> {
        let l = self.model.as_ref().map_or(1.0, |m| m.length);
        let start = env.map_or(0.0, |e| e.start);
        let last = env
            .and_then(|e| e.piece_start.last().copied())
            .unwrap_or(start);
        let (lo, hi) = (start - 2.0 * l, last.max(start) + 3.0 * l + 20.0);
        self.sinks.log_static(
            paths::BODY_WORLD,
            &rerun::Transform3D::update_fields().with_scale((1.0 / l) as f32),
        )?;
        let (y0, tall) = (-(0.06 * l) as f32, (0.012 * l) as f32);
        let first = (lo * 10.0).ceil() as i64;
        let last_tick = (hi * 10.0).floor() as i64;
        let ticks: Vec<Vec<[f32; 2]>> = (first..=last_tick)
            .map(|k| {
                let x = (k as f64 / 10.0) as f32;
                let h = if k % 10 == 0 { 2.5 * tall } else { tall };
                vec![[x, y0], [x, y0 - h]]
            })
            .collect();
        let labels: Vec<String> = (first..=last_tick)
            .map(|k| {
                if k % 10 == 0 {
                    format!("{} m", k / 10)
                } else {
                    String::new()
                }
            })
            .collect();
        self.sinks.log_static(
            paths::BODY_WORLD_RULER,
            &rerun::LineStrips2D::new(ticks)
                .with_labels(labels)
                .with_colors([rgb([140, 140, 140])]),
        )?;
        let Some(env) = env else {
            return Ok(());
        };
        let eps_max = env
            .piece_eps
            .iter()
            .fold(env.eps, |a, &b| a.max(b))
            .max(1e-12);
        let band = |eps: f64| 0.04 * l * eps / eps_max;
        let top = 0.05 * l;
        let mut edges = vec![lo];
        edges.extend(
            env.piece_start
                .iter()
                .copied()
                .filter(|x| *x > lo && *x < hi),
        );
        edges.push(hi);
        let boxes: Vec<(f64, f64, f64)> = edges
            .windows(2)
            .map(|w| (w[0], w[1], env.at(0.5 * (w[0] + w[1])).0))
            .collect();
        self.sinks.log_static(
            paths::BODY_WORLD_PIPE,
            &rerun::Boxes2D::from_centers_and_half_sizes(
                boxes
                    .iter()
                    .map(|&(a, b, e)| [(0.5 * (a + b)) as f32, (top + 0.5 * band(e)) as f32]),
                boxes
                    .iter()
                    .map(|&(a, b, e)| [(0.5 * (b - a)) as f32, (0.5 * band(e)) as f32]),
            )
            .with_colors(boxes.iter().map(|&(_, _, e)| {
                if e > env.eps {
                    rgb([230, 160, 40])
                } else {
                    rgb([120, 120, 120])
                }
            }))
            .with_labels(boxes.iter().map(|&(_, _, e)| format!("eps {e}"))),
        )?;
        Ok(())
    }

    /// Draws the pipe the plant resolved: eps(X) and n_F(X) as static step lines from a body
    /// length behind the tail's start to a body length past the last change (at least two body
    /// lengths ahead), and from now on the body's span on eps(X) at every recorded step.
    pub(super) fn set_environment(&mut self, env: Environment) -> anyhow::Result<()> {
        let length = self.model.as_ref().map_or(1.0, |m| m.length);
        let first = env.piece_start.first().copied().unwrap_or(env.start);
        let last = env.piece_start.last().copied().unwrap_or(env.start);
        let (lo, hi) = (
            first.min(env.start) - length,
            (last + length).max(env.start + 3.0 * length),
        );
        // a 2D view's y axis points down: values are drawn at y = -value, so up is larger
        let steps = |uniform: f64, values: &[f64]| -> Vec<[f32; 2]> {
            let mut line = vec![[lo as f32, -uniform as f32]];
            let mut level = uniform;
            for (&x, &v) in env.piece_start.iter().zip(values) {
                line.push([x as f32, -level as f32]);
                line.push([x as f32, -v as f32]);
                level = v;
            }
            line.push([hi as f32, -level as f32]);
            line
        };
        self.sinks.log_static(
            paths::PIPE_EPS,
            &rerun::LineStrips2D::new([steps(env.eps, &env.piece_eps)])
                .with_colors([rgb([230, 160, 40])])
                .with_labels(["eps(X)"]),
        )?;
        self.sinks.log_static(
            paths::PIPE_N_F,
            &rerun::LineStrips2D::new([steps(env.n_f, &env.piece_n_f)])
                .with_colors([rgb([40, 150, 60])])
                .with_labels(["n_F(X)"]),
        )?;
        let exact = if env.merged == 1 {
            "exactly".to_string()
        } else {
            format!("merged, {} of its pieces per piece drawn", env.merged)
        };
        let (e, n) = (&env.piece_eps, &env.piece_n_f);
        let range = |u: f64, v: &[f64]| v.iter().fold((u, u), |(a, b), &x| (a.min(x), b.max(x)));
        let ((e0, e1), (n0, n1)) = (range(env.eps, e), range(env.n_f, n));
        self.note(
            format!(
                "pipe as the plant resolved it ({exact}): {} pieces, eps in [{e0}, {e1}], n_F in [{n0}, {n1}], tail starts at X = {} m",
                env.piece_start.len(),
                env.start
            ),
            rerun::TextLogLevel::INFO,
        );
        self.environment = Some(env);
        Ok(())
    }

    /// A metric block of the plant: its V, P, M, stress and stuck fraction at the block's end
    /// (`plant` for a forcing-period block, `running` for a clock block), and beside them the
    /// models' predictions for the wave applied.
    pub(super) fn log_metrics(&mut self, m: &Metrics) {
        self.counts.metric_blocks += 1;
        self.counts.clock_blocks += u64::from(m.clock);
        if m.steady && !m.clock {
            self.tail.settled = true;
        }
        let at = (m.step, m.end);
        let source = if m.clock { "running" } else { "plant" };
        for metric in paths::METRICS {
            if let Some(value) = m.values.get(metric).filter(|v| v.is_finite()) {
                self.columns
                    .scalar(&paths::metric_series(metric.name(), source), at, value);
            }
        }
        if self.predicted_at == Some(m.step) {
            return;
        }
        self.predicted_at = Some(m.step);
        for p in &self.predictions {
            for metric in paths::METRICS {
                if let Some(v) = p.values.get(metric).filter(|v| v.is_finite()) {
                    self.columns
                        .scalar(&paths::metric_series(metric.name(), &p.model), at, v);
                }
            }
        }
    }

    pub(super) fn set_prediction(&mut self, p: Prediction) {
        self.tail.series = p
            .models
            .iter()
            .find(|m| m.model == "paper")
            .and_then(|m| m.tail.clone());
        self.tail.offset = None;
        self.tail.buffer.clear();
        self.tail.settled = false;
        let opt = |x: Option<f64>| x.map_or("-".into(), |v| format!("{v:.4e}"));
        let text = p
            .models
            .iter()
            .map(|m| {
                format!(
                    "{}: V = {}, P = {}, M = {}, sigma = {} ({})",
                    m.model,
                    opt(m.values.get(Metric::Velocity)),
                    opt(m.values.get(Metric::Power)),
                    opt(m.values.get(Metric::Mileage)),
                    opt(m.values.get(Metric::MaxStress)),
                    m.validity
                )
            })
            .collect::<Vec<_>>()
            .join("; ");
        self.note(
            format!(
                "controller {} ({}) applies f0 = {:.4} N, k = {:.4} rad/m, omega = {:.4} rad/s from step {}: {text}",
                p.controller, p.policy, p.wave.f0, p.wave.k, p.wave.omega, p.step
            ),
            rerun::TextLogLevel::INFO,
        );
        self.predictions = p.models;
    }

    /// One row of numbers per episode at its message's step and time, sent in chunks of at
    /// least [`EPISODE_ROWS`] (and whatever is pending at every block sent and at the end).
    pub(super) fn log_events(&mut self, e: &Events) -> anyhow::Result<()> {
        let rows = &mut self.episodes;
        self.counts.episodes += e.episodes.len() as u64;
        for ep in &e.episodes {
            rows.steps.push(e.step as i64);
            rows.times.push(e.time);
            rows.node.push(ep.node);
            rows.start.push(ep.start);
            rows.end.push(ep.end);
            rows.duration.push(ep.duration);
            rows.direction.push(ep.direction);
        }
        if rows.node.len() >= EPISODE_ROWS {
            self.send_episodes()?;
        }
        Ok(())
    }

    /// Sends the pending episodes as one chunk: `node`, `start` (s), `end` (s), `duration` (s)
    /// and `direction` (+1 the node left forward, -1 backward), a row apiece (read as a table:
    /// the viewer's dataframe view shows their numbers).
    pub(super) fn send_episodes(&mut self) -> anyhow::Result<()> {
        use rerun::external::arrow::array::{ArrayRef, Float64Array, Int8Array, UInt32Array};
        use std::sync::Arc;
        let rows = std::mem::take(&mut self.episodes);
        if rows.steps.is_empty() {
            return Ok(());
        }
        let arrays: [(&str, ArrayRef); 5] = [
            ("node", Arc::new(UInt32Array::from(rows.node))),
            ("start", Arc::new(Float64Array::from(rows.start))),
            ("end", Arc::new(Float64Array::from(rows.end))),
            ("duration", Arc::new(Float64Array::from(rows.duration))),
            ("direction", Arc::new(Int8Array::from(rows.direction))),
        ];
        let episodes = arrays.into_iter().fold(
            rerun::DynamicArchetype::new(paths::EPISODE_ARCHETYPE),
            |a, (name, array)| a.with_component_from_data(name, array),
        );
        let columns = rerun::AsComponents::as_serialized_batches(&episodes)
            .into_iter()
            .map(|batch| batch.column_of_unit_batches())
            .collect::<Result<Vec<_>, _>>()?;
        self.sinks.send(
            paths::EPISODES,
            [
                rerun::TimeColumn::new_sequence(paths::STEP_TIMELINE, rows.steps),
                rerun::TimeColumn::new_duration_secs(paths::TIME_TIMELINE, rows.times),
            ],
            columns,
            Live::All,
        )
    }

    pub(super) fn log_status(&mut self, s: &Status) -> anyhow::Result<()> {
        // Only the plant whose liveliness token we saw speaks for the plant, and only what fits
        // the run.
        let from_plant = s.role == Role::Plant && self.plant_id.as_deref() == Some(s.id.as_str());
        if s.role == Role::Plant && !from_plant {
            self.invalid(
                "status",
                &format!("a plant status from {:?}, not from the run's plant", s.id),
            );
            return Ok(());
        }
        if from_plant {
            if let Some(f) = self.model.as_ref().map(|m| m.facts) {
                if let Err(reason) = checks::terminal(s, &f, self.plant_last_state) {
                    let early = s.state == ProcessState::Finished
                        && self.plant_last_state.is_none()
                        && s.step < f.last_step;
                    if early && self.held_finished.len() < HELD_FINISHED_MAX {
                        // a task-mode run may end early: its last state may be on its way
                        self.held_finished
                            .entry(s.step)
                            .or_insert_with(|| s.clone());
                    } else {
                        self.invalid("status", &reason);
                    }
                    return Ok(());
                }
            }
        }
        let level = match s.state {
            ProcessState::Failed => rerun::TextLogLevel::ERROR,
            ProcessState::Stopped => rerun::TextLogLevel::WARN,
            _ => rerun::TextLogLevel::INFO,
        };
        self.sinks.log_at(
            self.last_step_time,
            paths::LOG_STATUS,
            &rerun::TextLog::new(format!(
                "{} {}: {} (step {}): {}",
                s.role, s.id, s.state, s.step, s.message
            ))
            .with_level(level),
        )?;
        if from_plant && s.state == ProcessState::Finished {
            if let Some(report) = &s.report {
                self.log_report(report)?;
            }
        }
        if from_plant && s.state.is_terminal() {
            self.finished = true;
        }
        Ok(())
    }

    /// The plant's final report: its metrics as scalars under `summary/`, the whole report as a
    /// JSON document at `summary`, and the task's targets beside its progress.
    fn log_report(&mut self, r: &FinalReport) -> anyhow::Result<()> {
        let at = self.last_step_time;
        let values = r.values.iter().map(|(m, x)| (m.name(), x)).chain(
            paths::SUMMARY_EXTRA
                .iter()
                .map(|&k| (k, Some(r.dissipation))),
        );
        for (key, value) in values {
            if let Some(x) = value {
                self.sinks.log_at(
                    at,
                    format!("{}/{key}", paths::SUMMARY_ROOT),
                    &rerun::Scalars::single(x),
                )?;
            }
        }
        self.sinks.log_at(
            at,
            paths::SUMMARY_ROOT,
            &rerun::TextDocument::new(serde_json::to_string_pretty(r)?),
        )?;
        if let (Some(task), Some(first)) = (&r.task, self.first_at) {
            for (name, target) in [
                ("distance/target", task.distance_target),
                ("energy/target", task.energy_budget),
            ] {
                for when in [first, at] {
                    self.columns.scalar(&paths::task(name), when, target);
                }
            }
        }
        Ok(())
    }
}
