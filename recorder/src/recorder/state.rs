//! What one state adds to the columns: every state's scalars (the tail, the per-step values, the
//! task's progress, the applied wave, the friction under the body, the lanes and the acting
//! controller), and at the recorded states its fields, the body and the heatmap's row.

use std::time::Instant;

use crawler_protocol::State;

use super::{picture, Recorder};
use crate::paths;

impl Recorder {
    pub(super) fn log_state(&mut self, s: &State) -> anyhow::Result<()> {
        let n = s.u.len().max(1);
        let at = (s.step, s.time);
        self.last_step_time = at;
        self.log_acting(s, at);
        self.log_lanes(s, at);
        let mean = s.u.iter().sum::<f64>() / n as f64;
        self.log_step_values(s, at, mean);
        if let Some(&u0) = s.u.first() {
            self.columns
                .scalar(&format!("{}/plant", paths::TAIL), at, u0);
            self.log_tail_prediction(s.step, s.time, u0);
        }
        // what the plant applied over the step that ended here: a wave's numbers at every state
        if let Some(w) = s.applied.as_ref().and_then(|a| a.wave) {
            for (name, value) in paths::APPLIED_WAVE
                .iter()
                .zip([w.f0, w.k, w.omega, w.phase])
            {
                self.columns.scalar(&paths::applied(name), at, value);
            }
        }
        let centre = self.centre(mean);
        if let Some(env) = &self.environment {
            self.columns
                .scalar(paths::PIPE_CENTRE_EPS, at, env.at(centre).0);
        }
        if s.step.is_multiple_of(self.opts.every) || s.last {
            self.log_fields(s, at, mean, centre)?;
        }
        if s.last {
            self.last_state_at.get_or_insert_with(Instant::now);
        }
        Ok(())
    }

    /// The centre of mass's position in the pipe, m: the cells tile the body `[start, start +
    /// L)` at rest (on a periodic body node 0's cell is half at the tail, half at the head), so
    /// it is at `start + L / 2 + mean u`.
    fn centre(&self, mean: f64) -> f64 {
        let start = self.environment.as_ref().map_or(0.0, |e| e.start);
        let length = self.model.as_ref().map_or(1.0, |m| m.length);
        start + 0.5 * length + mean
    }

    /// The controller whose actuation the plant applied, where it changes.
    fn log_acting(&mut self, s: &State, at: (u64, f64)) {
        if self.acting.as_deref() != Some(s.controller.as_str()) {
            let label = if s.controller.is_empty() {
                "none"
            } else {
                s.controller.as_str()
            };
            self.columns.lane(paths::CONTROLLER, at, label);
            self.acting = Some(s.controller.clone());
        }
    }

    /// Stick/slip lanes of evenly spaced nodes, where they change.
    fn log_lanes(&mut self, s: &State, at: (u64, f64)) {
        let n = s.stuck.len();
        let label = |stuck: bool| if stuck { "stick" } else { "slip" };
        if self.lane_nodes.is_empty() || self.last_stuck.len() != n {
            let lanes = self.opts.lanes.clamp(1, n.max(1));
            self.lane_nodes = (0..lanes).map(|j| j * n / lanes).collect();
            for &i in &self.lane_nodes {
                self.columns.lane(&paths::lane(i), at, label(s.stuck[i]));
                let _ = self
                    .sinks
                    .log_static(paths::lane(i), &super::messages::lane_colours());
            }
        } else {
            for &i in &self.lane_nodes {
                if s.stuck[i] != self.last_stuck[i] {
                    self.columns.lane(&paths::lane(i), at, label(s.stuck[i]));
                }
            }
        }
        self.last_stuck.clone_from(&s.stuck);
    }

    /// The state's own V, P, M, stress and stuck fraction (`step/*`), and the task's progress.
    ///
    /// V and P are the plant's outputs over the step that ended at the state; the stress is the
    /// largest tension of the state over the cross-section, the stuck fraction the share of its
    /// nodes held by static friction (both at the state's instant).
    fn log_step_values(&mut self, s: &State, at: (u64, f64), mean: f64) {
        let (area, h) = self
            .model
            .as_ref()
            .map_or((f64::NAN, f64::NAN), |m| (m.area, m.step));
        let n = s.u.len().max(1) as f64;
        let max_tension = s.tension.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let stuck = s.stuck.iter().filter(|&&x| x).count() as f64 / n;
        let power = s.input_power;
        let mileage = (power > 0.0).then(|| s.mean_speed.abs() / power);
        let values = [
            Some(s.mean_speed),
            Some(power),
            mileage,
            Some(max_tension / area),
            Some(stuck),
        ];
        for (metric, value) in paths::METRICS.iter().zip(values) {
            if let Some(v) = value.filter(|v| v.is_finite()) {
                self.columns
                    .scalar(&paths::step_series(metric.name()), at, v);
            }
        }
        // the task's tracker: distance of the centre of mass and the actuator's work since the
        // first state, each step's work P H
        match self.task.start {
            None => {
                self.task.start = Some(mean);
                self.first_at.get_or_insert(at);
            }
            Some(_) if h.is_finite() => self.task.energy += power * h,
            Some(_) => {}
        }
        let start = self.task.start.unwrap_or(mean);
        self.columns
            .scalar(&paths::task("distance"), at, mean - start);
        self.columns
            .scalar(&paths::task("energy"), at, self.task.energy);
    }

    /// The fields of a recorded state, the body drawn from them, and the heatmap's row.
    fn log_fields(
        &mut self,
        s: &State,
        at: (u64, f64),
        mean: f64,
        centre: f64,
    ) -> anyhow::Result<()> {
        self.counts.recorded_steps += 1;
        let du = s.u.iter().map(|u| (u - mean) as f32);
        self.columns.field(paths::FIELD_U, at, du.clone());
        self.columns
            .field(paths::FIELD_V, at, s.vel.iter().map(|&v| v as f32));
        self.columns.field(
            paths::FIELD_TENSION,
            at,
            s.tension.iter().map(|&t| t as f32),
        );
        // a field with the other fields, in float64: the values applied
        if let Some(f) = s.applied.as_ref().and_then(|a| a.field.as_ref()) {
            self.columns.field64(paths::APPLIED_FIELD, at, f);
        }
        self.heat.push(at, du);
        if self.heat.full() {
            self.flush_heat()?;
        }
        let Some(m) = self.model.clone() else {
            return Ok(());
        };
        let body = picture::Body {
            length: m.length,
            node_offset: m.node_offset,
            periodic: m.periodic,
        };
        self.columns.boxes(
            paths::BODY_SEGMENTS,
            at,
            body.segments(&s.u, &s.stuck, mean),
        );
        // the camera follows the body: the world moves by minus the centre's position
        self.columns.translation(
            paths::BODY_WORLD,
            at,
            [(-centre / m.length) as f32, 0.0, 0.0],
        );
        // the nodes on the pipe's map, at their X, on eps(X), in a pipe whose friction varies
        if let Some(env) = self.environment.as_ref().filter(|e| !e.is_uniform()) {
            let nodes = (0..s.u.len()).map(|i| {
                let x = body.node_in_pipe(&s.u, i, env.start);
                ([x as f32, -env.at(x).0 as f32], u16::from(s.stuck[i]))
            });
            self.columns.points(paths::PIPE_BODY, at, nodes);
        }
        Ok(())
    }

    /// Sends the heatmap's block, if it holds rows.
    pub(super) fn flush_heat(&mut self) -> anyhow::Result<()> {
        if let Some((index, columns)) = self.heat.take()? {
            self.sinks
                .send(paths::HEATMAP, index, columns, super::Live::Last)?;
        }
        Ok(())
    }

    /// The paper's tail displacement beside the plant's, its drift's origin aligned with the
    /// plant's over the first steady forcing period.
    pub(super) fn log_tail_prediction(&mut self, step: u64, time: f64, u0: f64) {
        let Some(series) = &self.tail.series else {
            return;
        };
        let path = format!("{}/paper", paths::TAIL);
        let value = series.at(time);
        if let Some(offset) = self.tail.offset {
            self.columns.scalar(&path, (step, time), offset + value);
            return;
        }
        if !self.tail.settled {
            return;
        }
        self.tail.buffer.push((step, time, u0 - value));
        let period = std::f64::consts::TAU / series.omega;
        let first = self.tail.buffer[0].1;
        if time - first >= period {
            let buffer = std::mem::take(&mut self.tail.buffer);
            let offset = buffer.iter().map(|x| x.2).sum::<f64>() / buffer.len() as f64;
            self.tail.offset = Some(offset);
            let series = series.clone();
            for &(st, t, _) in &buffer {
                self.columns.scalar(&path, (st, t), offset + series.at(t));
            }
        }
    }
}
