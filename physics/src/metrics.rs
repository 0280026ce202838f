//! Running and steady-state metrics: averages over whole forcing periods.
//!
//! Every internal step adds its reductions to the current *block*. For a travelling wave a block
//! is one forcing period `2 pi / omega`, counted from the moment the wave was applied; for a
//! general muscle field it is `numerics.block` seconds. A block closes at the first internal step
//! that starts at or after its end, so it holds whole periods up to one internal step. Blocks that
//! start at least `numerics.settle` seconds after the last change of actuation form the steady
//! window; the steady metrics are the sums over that window.
//!
//! Beside them runs a second sequence of *clock blocks*: `numerics.block` seconds each, counted
//! from the tracker's creation (the run's start) and never restarted, whatever the actuation does.
//! They are the running metrics of any actuation, open loop or feedback: a controller that changes
//! its wave every step never closes a forcing-period block, but closes a clock block every
//! `numerics.block` seconds. Both sequences are reported as they close ([`BlockReport::clock`]);
//! the report's windows (steady, run, all) are made of forcing-period blocks only.

use crawler_facts::{Metric, MetricValues};
use serde::{Deserialize, Serialize};

use crate::solver::StepSums;

/// Additive sums over a span of internal steps (a block or the steady window).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sums {
    /// Internal steps in the span.
    pub steps: u64,
    /// First time in the span, s.
    pub start: f64,
    /// End time of the span (start of the step after the last), s.
    pub end: f64,
    /// Sum over steps and nodes of `v⁺`, m/s.
    pub sum_v: f64,
    /// Sum over steps and nodes of `v⁻`, m/s.
    pub sum_v_old: f64,
    /// Sum over nodes of `v⁻` at the first step of the span, m/s.
    pub first_v_old: f64,
    /// Sum over nodes of `v⁺` at the last step of the span, m/s.
    pub last_v: f64,
    /// Sum over steps and nodes of `s`.
    pub sum_s: f64,
    /// Sum over steps and nodes of the Coulomb force density `eps_i c_d (s - n_F,i)`, N/m.
    pub friction_force: f64,
    /// Node-steps spent stuck (stick phases timed inside their first and last steps).
    pub stuck: f64,
    /// Largest tension, N.
    pub max_tension: f64,
    /// Largest `|u_x|`.
    pub max_strain: f64,
    /// Work done by the actuator, J (over the whole body).
    pub energy_in: f64,
    /// Energy dissipated by friction, J (over the whole body).
    pub dissipated: f64,
    /// Stick-slip episodes that ended in the span.
    pub episodes: u64,
    /// Total duration of those episodes, s.
    pub stick_time: f64,
}

impl Sums {
    /// Every number one a run can have produced (sums read from a file): finite, counts and
    /// times non-negative, the largest tension `-inf` for an empty span.
    pub fn validate(&self, name: &str) -> Result<(), crate::error::ParamError> {
        use crate::error::{finite, non_negative};
        for (field, x) in [
            ("start", self.start),
            ("end", self.end),
            ("sum_v", self.sum_v),
            ("sum_v_old", self.sum_v_old),
            ("first_v_old", self.first_v_old),
            ("last_v", self.last_v),
            ("sum_s", self.sum_s),
            ("friction_force", self.friction_force),
            ("energy_in", self.energy_in),
            ("dissipated", self.dissipated),
        ] {
            finite(&format!("{name}.{field}"), x)?;
        }
        for (field, x) in [
            ("stuck", self.stuck),
            ("max_strain", self.max_strain),
            ("stick_time", self.stick_time),
        ] {
            non_negative(&format!("{name}.{field}"), x)?;
        }
        if self.max_tension != f64::NEG_INFINITY {
            finite(&format!("{name}.max_tension"), self.max_tension)?;
        }
        Ok(())
    }

    /// A span of `steps` internal steps of `dt` seconds, each starting at `t0 + j dt` (so
    /// `end - start = steps dt` to round-off); `closed`: a window made of whole blocks, which holds
    /// nothing while it holds no step (the open block can hold a muscle-force jump's work or an
    /// episode before its first step).
    pub fn validate_span(
        &self,
        name: &str,
        dt: f64,
        closed: bool,
    ) -> Result<(), crate::error::ParamError> {
        use crate::error::ParamError;
        if self.steps == 0 {
            let empty = Sums {
                start: self.start,
                end: self.end,
                ..Sums::empty(self.start)
            };
            if closed && *self != empty {
                return Err(ParamError::new(
                    format!("{name}.steps"),
                    0,
                    "steps > 0 for a window with sums in it (an empty window sums to zero)",
                ));
            }
            return Ok(());
        }
        let length = self.steps as f64 * dt;
        let tolerance =
            16.0 * f64::EPSILON * (self.start.abs() + self.end.abs() + length) + 1e-12 * dt;
        if ((self.end - self.start) - length).abs() > tolerance {
            return Err(ParamError::new(
                format!("{name}.steps"),
                self.steps,
                format!(
                    "the steps of dt = {dt:e} s from start = {} s to end = {} s",
                    self.start, self.end
                ),
            ));
        }
        Ok(())
    }

    /// An empty span starting at `start` seconds.
    pub fn empty(start: f64) -> Self {
        Self {
            steps: 0,
            start,
            end: start,
            sum_v: 0.0,
            sum_v_old: 0.0,
            first_v_old: 0.0,
            last_v: 0.0,
            sum_s: 0.0,
            friction_force: 0.0,
            stuck: 0.0,
            max_tension: f64::NEG_INFINITY,
            max_strain: 0.0,
            energy_in: 0.0,
            dissipated: 0.0,
            episodes: 0,
            stick_time: 0.0,
        }
    }

    /// Appends the span `other`, which must follow this one.
    pub fn merge(&mut self, other: &Sums) {
        if other.steps == 0 {
            return;
        }
        if self.steps == 0 {
            self.start = other.start;
            self.first_v_old = other.first_v_old;
        }
        self.steps += other.steps;
        self.end = other.end;
        self.last_v = other.last_v;
        self.sum_v += other.sum_v;
        self.sum_v_old += other.sum_v_old;
        self.sum_s += other.sum_s;
        self.friction_force += other.friction_force;
        self.stuck += other.stuck;
        self.max_tension = self.max_tension.max(other.max_tension);
        self.max_strain = self.max_strain.max(other.max_strain);
        self.energy_in += other.energy_in;
        self.dissipated += other.dissipated;
        self.episodes += other.episodes;
        self.stick_time += other.stick_time;
    }

    /// The metrics of this span, for a body of `cells` nodes, cross-section `area` (m^2), and a
    /// forcing period (or block length) `period` in seconds.
    pub fn metrics(&self, cells: usize, dt: f64, area: f64, period: f64) -> Metrics {
        let node_steps = (self.steps as f64) * cells as f64;
        let duration = self.steps as f64 * dt;
        let velocity = self.sum_v / node_steps;
        let n = cells as f64;
        let power = self.energy_in / duration;
        Metrics {
            start: self.start,
            end: self.end,
            periods: duration / period,
            velocity,
            power,
            mileage: velocity.abs() / power,
            max_stress: self.max_tension / area,
            max_tension: self.max_tension,
            max_strain: self.max_strain,
            stuck_fraction: self.stuck / node_steps,
            mean_friction_selection: self.sum_s / node_steps,
            mean_friction_force: self.friction_force / node_steps,
            dissipation: self.dissipated / duration,
            episodes: self.episodes,
            episodes_per_node_per_period: self.episodes as f64 / (cells as f64 * duration / period),
            mean_stick_duration: if self.episodes > 0 {
                self.stick_time / self.episodes as f64
            } else {
                0.0
            },
            centred_velocity: 0.5 * (self.sum_v + self.sum_v_old) / node_steps,
            mean_velocity_change: (self.last_v - self.first_v_old) / n,
        }
    }
}

/// Metrics of a span of whole forcing periods (SI units).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Start of the averaging window, s.
    pub start: f64,
    /// End of the averaging window, s.
    pub end: f64,
    /// Length of the window in forcing periods (or blocks).
    pub periods: f64,
    /// Mean speed `V` (eq. 5), m/s.
    pub velocity: f64,
    /// Input power over the body `P` (eq. 7), W.
    pub power: f64,
    /// Mileage `M = |V| / P`, m/J.
    pub mileage: f64,
    /// Largest engineering stress `sigma_s = sup T / A_c` (eq. 4), Pa.
    pub max_stress: f64,
    /// Largest tension `sup T`, N.
    pub max_tension: f64,
    /// Largest body strain `max |u_x|`.
    pub max_strain: f64,
    /// Share of node-time spent stuck.
    pub stuck_fraction: f64,
    /// Space-time mean of the friction selection `<s>`, stuck points included.
    pub mean_friction_selection: f64,
    /// Space-time mean of the Coulomb force density `<eps c_d (s - n_F)>` (local `eps`, `n_F` in a
    /// pipe whose friction varies), N/m.
    pub mean_friction_force: f64,
    /// Power dissipated by friction, W (equals `power` in a steady state).
    pub dissipation: f64,
    /// Stick-slip episodes that ended in the window.
    pub episodes: u64,
    /// Episodes per node per forcing period.
    pub episodes_per_node_per_period: f64,
    /// Mean duration of those episodes, s.
    pub mean_stick_duration: f64,
    /// Space-time mean of the centred velocity `(v⁺ + v⁻) / 2` on which the viscous force acts, m/s.
    pub centred_velocity: f64,
    /// Change of the body's mean velocity over the window, m/s.
    pub mean_velocity_change: f64,
}

impl Metrics {
    /// The value of `metric` (the plant's computation of each row of the metric table).
    pub fn value(&self, metric: Metric) -> f64 {
        match metric {
            Metric::Velocity => self.velocity,
            Metric::Power => self.power,
            Metric::Mileage => self.mileage,
            Metric::MaxStress => self.max_stress,
            Metric::MaxStrain => self.max_strain,
            Metric::StuckFraction => self.stuck_fraction,
            Metric::MeanFrictionSelection => self.mean_friction_selection,
            Metric::EpisodesPerNodePerPeriod => self.episodes_per_node_per_period,
        }
    }

    /// Every metric of the table (a value that is not finite, such as the mileage of a body that
    /// takes no power, is `None`).
    pub fn values(&self) -> MetricValues {
        MetricValues::from_fn(|m| Some(self.value(m)))
    }

    /// Relative residual of the scheme's exact momentum balance over the window,
    /// `rho dV/T_w + c_v <(v⁺+v⁻)/2> + <eps c_d (s - n_F)> = 0` (elastic and muscle forces cancel
    /// in the sum over the body, periodic or free), scaled by `c_v |<(v⁺+v⁻)/2>|`. Round-off
    /// level for a correct plant.
    pub fn momentum_residual(&self, density: f64, viscous: f64) -> f64 {
        let duration = self.end - self.start;
        let r = density * self.mean_velocity_change / duration
            + viscous * self.centred_velocity
            + self.mean_friction_force;
        r.abs() / (viscous * self.centred_velocity.abs())
    }
}

fn empty_sums() -> Sums {
    Sums::empty(0.0)
}

/// A completed block, reported as it closes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BlockReport {
    /// Block number since the last change of actuation.
    pub index: u64,
    /// True if the block belongs to the steady window.
    pub steady: bool,
    /// The block's sums.
    pub sums: Sums,
    /// True for a clock block ([`ClockBlocks`]); false for a forcing-period block.
    #[serde(default)]
    pub clock: bool,
}

/// Blocks of a fixed length on the run's clock: the `index`-th spans
/// `[origin + index len, origin + (index + 1) len)`, whatever the actuation did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ClockBlocks {
    /// Block length, s.
    pub len: f64,
    /// Start of block 0 (the tracker's creation), s.
    pub origin: f64,
    /// Index of the open block.
    pub index: u64,
    /// End of the open block, s.
    pub end: f64,
    /// The open block.
    pub block: Sums,
}

impl ClockBlocks {
    fn new(origin: f64, len: f64) -> Self {
        Self {
            len,
            origin,
            index: 0,
            end: origin + len,
            block: Sums::empty(origin),
        }
    }

    /// Closes the open block if the step starting at `t` (s) reaches its end; returns it.
    fn close_at(&mut self, t: f64) -> Option<BlockReport> {
        if t < self.end {
            return None;
        }
        let closed = (self.block.steps > 0).then_some(BlockReport {
            index: self.index,
            steady: false,
            sums: self.block,
            clock: true,
        });
        // Block ends from the integer index, skipping empty blocks (a step longer than a block).
        while self.end <= t {
            self.index += 1;
            self.end = self.origin + (self.index + 1) as f64 * self.len;
        }
        self.block = Sums::empty(t);
        closed
    }
}

/// Splits the internal steps into blocks and accumulates the steady window.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetricsTracker {
    /// Block length, s (the forcing period, or `numerics.block` for a field).
    pub block_len: f64,
    /// Time the current block sequence started (last actuation change), s.
    pub origin: f64,
    /// Blocks starting before this time are transient, s.
    pub settle_until: f64,
    /// Index of the current block.
    pub block_index: u64,
    /// End time of the current block, s.
    pub block_end: f64,
    /// The current (open) block.
    pub block: Sums,
    /// The steady window so far (complete blocks only).
    pub steady: Sums,
    /// Blocks starting before this time are the run's initial transient, s (set when the
    /// tracker is created, kept across restarts).
    pub run_settle_until: f64,
    /// Every complete block after the run's initial transient, whatever the actuation did: the
    /// fallback window when the actuation changed too recently for a steady window.
    pub run: Sums,
    /// Every complete block since the tracker was created, transient included (the fallback of a
    /// run that ended early).
    #[serde(default = "empty_sums")]
    pub all: Sums,
    /// The clock blocks (`None` in a tracker read from a checkpoint written before they
    /// existed: that run reports none).
    #[serde(default)]
    pub clock: Option<ClockBlocks>,
    /// Blocks closed since the caller last drained them.
    #[serde(skip)]
    pub closed: Vec<BlockReport>,
}

impl MetricsTracker {
    /// Every number one a run can have produced (a tracker read from a file).
    pub fn validate(&self) -> Result<(), crate::error::ParamError> {
        use crate::error::{finite, positive};
        positive("state.metrics.block_len", self.block_len)?;
        for (field, x) in [
            ("origin", self.origin),
            ("settle_until", self.settle_until),
            ("block_end", self.block_end),
            ("run_settle_until", self.run_settle_until),
        ] {
            finite(&format!("state.metrics.{field}"), x)?;
        }
        self.block.validate("state.metrics.block")?;
        self.steady.validate("state.metrics.steady")?;
        self.run.validate("state.metrics.run")?;
        self.all.validate("state.metrics.all")?;
        if let Some(c) = &self.clock {
            positive("state.metrics.clock.len", c.len)?;
            finite("state.metrics.clock.origin", c.origin)?;
            finite("state.metrics.clock.end", c.end)?;
            c.block.validate("state.metrics.clock.block")?;
        }
        Ok(())
    }

    /// The windows agree with the plant's clock: each spans its steps of `dt` (s), and the closed
    /// blocks and the open one hold the `steps` internal steps taken since the tracker began.
    pub fn validate_steps(&self, dt: f64, steps: u64) -> Result<(), crate::error::ParamError> {
        self.block.validate_span("state.metrics.block", dt, false)?;
        self.steady
            .validate_span("state.metrics.steady", dt, true)?;
        self.run.validate_span("state.metrics.run", dt, true)?;
        self.all.validate_span("state.metrics.all", dt, true)?;
        if let Some(c) = &self.clock {
            c.block
                .validate_span("state.metrics.clock.block", dt, false)?;
        }
        let counted = self.all.steps.checked_add(self.block.steps);
        if counted != Some(steps) {
            return Err(crate::error::ParamError::new(
                "state.metrics.all.steps",
                self.all.steps,
                format!(
                    "the steps taken ({steps}) less the open block's ({})",
                    self.block.steps
                ),
            ));
        }
        for (name, window) in [("steady", &self.steady), ("run", &self.run)] {
            if window.steps > self.all.steps {
                return Err(crate::error::ParamError::new(
                    format!("state.metrics.{name}.steps"),
                    window.steps,
                    format!(
                        "at most the steps of all closed blocks ({})",
                        self.all.steps
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Starts a block sequence at `origin` with blocks of `block_len` s and a transient of `settle` s.
    pub fn new(origin: f64, block_len: f64, settle: f64) -> Self {
        Self {
            block_len,
            origin,
            settle_until: origin + settle,
            block_index: 0,
            block_end: origin + block_len,
            block: Sums::empty(origin),
            steady: Sums::empty(origin),
            run_settle_until: origin + settle,
            run: Sums::empty(origin),
            all: Sums::empty(origin),
            clock: Some(ClockBlocks::new(origin, block_len)),
            closed: Vec::new(),
        }
    }

    /// Restarts the block sequence at `origin` (actuation changed): the open block is dropped
    /// from the steady window and the steady window is cleared. The run window keeps every step
    /// after the run's transient, the open block's included, so it stays contiguous.
    pub fn restart(&mut self, origin: f64, block_len: f64, settle: f64) {
        if self.after_run_transient(&self.block) {
            let open = self.block;
            self.run.merge(&open);
        }
        let open = self.block;
        self.all.merge(&open);
        let closed = std::mem::take(&mut self.closed);
        let (run, run_settle_until, all) = (self.run, self.run_settle_until, self.all);
        let clock = self.clock;
        *self = Self::new(origin, block_len, settle);
        self.clock = clock;
        self.closed = closed;
        self.run = run;
        self.all = all;
        self.run_settle_until = run_settle_until;
    }

    /// Adds the internal step starting at `t` (s) of length `dt` with reductions `sums`,
    /// `energy_in` and `dissipated` (J), after closing the block if `t` reached its end.
    pub fn add_step(&mut self, t: f64, dt: f64, sums: &StepSums, energy_in: f64, dissipated: f64) {
        if t >= self.block_end {
            self.close_block(t);
        }
        add_to(&mut self.block, t, dt, sums, energy_in, dissipated);
        if let Some(c) = &mut self.clock {
            if let Some(report) = c.close_at(t) {
                self.closed.push(report);
            }
            add_to(&mut c.block, t, dt, sums, energy_in, dissipated);
        }
    }

    /// Records a stick-slip episode of `duration` s that ended in the current block.
    pub fn add_episode(&mut self, duration: f64) {
        for b in self.open_blocks() {
            b.episodes += 1;
            b.stick_time += duration;
        }
    }

    /// Corrects the stuck node-steps of the current block by `node_steps` (stick phases timed
    /// inside their steps, see [`crate::events::Applied`]).
    pub fn correct_stuck(&mut self, node_steps: f64) {
        for b in self.open_blocks() {
            b.stuck += node_steps;
        }
    }

    /// Adds actuator work done outside a step (a jump of the muscle force), J.
    pub fn add_energy(&mut self, energy: f64) {
        for b in self.open_blocks() {
            b.energy_in += energy;
        }
    }

    /// The open forcing-period block and the open clock block.
    fn open_blocks(&mut self) -> impl Iterator<Item = &mut Sums> {
        std::iter::once(&mut self.block).chain(self.clock.as_mut().map(|c| &mut c.block))
    }

    fn after_run_transient(&self, block: &Sums) -> bool {
        block.steps > 0 && block.start >= self.run_settle_until - 1e-12 * self.block_len
    }

    fn close_block(&mut self, t: f64) {
        let steady =
            self.block.start >= self.settle_until - 1e-12 * self.block_len && self.block.steps > 0;
        if steady {
            self.steady.merge(&self.block);
        }
        if self.after_run_transient(&self.block) {
            let block = self.block;
            self.run.merge(&block);
        }
        let block = self.block;
        self.all.merge(&block);
        self.closed.push(BlockReport {
            index: self.block_index,
            steady,
            sums: self.block,
            clock: false,
        });
        self.block_index += 1;
        // Block ends are computed from the integer block index: no drift from adding floats.
        self.block_end = self.origin + (self.block_index + 1) as f64 * self.block_len;
        // A step longer than a block (coarse dt, fast wave) skips empty blocks.
        while self.block_end <= t {
            self.block_index += 1;
            self.block_end = self.origin + (self.block_index + 1) as f64 * self.block_len;
        }
        self.block = Sums::empty(t);
    }
}

/// Adds the internal step starting at `t` (s) of length `dt` to the span `b`.
fn add_to(b: &mut Sums, t: f64, dt: f64, sums: &StepSums, energy_in: f64, dissipated: f64) {
    if b.steps == 0 {
        b.start = t;
        b.first_v_old = sums.sum_v_old;
    }
    b.steps += 1;
    b.end = t + dt;
    b.last_v = sums.sum_v;
    b.sum_v += sums.sum_v;
    b.sum_v_old += sums.sum_v_old;
    b.sum_s += sums.sum_s;
    b.friction_force += sums.friction_force;
    b.stuck += sums.stuck;
    b.max_tension = b.max_tension.max(sums.max_tension);
    b.max_strain = b.max_strain.max(sums.max_strain);
    b.energy_in += energy_in;
    b.dissipated += dissipated;
}

/// The first internal step `j` (steps start at `j dt`, s) that starts at or after `t` (s).
fn first_step_from(t: f64, dt: f64) -> u64 {
    let mut j = (t / dt).ceil().max(0.0) as u64;
    while j > 0 && (j - 1) as f64 * dt >= t {
        j -= 1;
    }
    while (j as f64) * dt < t {
        j += 1;
    }
    j
}

/// The end of the block that holds the step starting at `t` (s): the first multiple of
/// `block_len` (s) after `t`, as [`MetricsTracker`] works it out.
fn block_end_after(t: f64, block_len: f64) -> f64 {
    let mut m = (t / block_len).floor().max(0.0) as u64 + 1;
    while m > 1 && (m - 1) as f64 * block_len > t {
        m -= 1;
    }
    while m as f64 * block_len <= t {
        m += 1;
    }
    m as f64 * block_len
}

/// Internal steps (of `dt` s, from the moment the actuation was applied) a run must take before
/// its steady window holds a block: blocks of `block_len` s are counted from that moment, the
/// first steady block is the first whose first step starts at least `settle` s in, and a block
/// closes at the first step that starts at or after its end, so that step must be taken too.
/// The same rules as [`MetricsTracker`], worked out from the block edges. `None` where step or
/// block counts reach 2^52 before that (the edges' integer arithmetic would not be exact).
pub fn steps_to_steady_block(dt: f64, block_len: f64, settle: f64) -> Option<u64> {
    let span = settle + 2.0 * block_len + 2.0 * dt;
    let limit = (1u64 << 52) as f64;
    if !(span / dt < limit && span / block_len < limit) {
        return None;
    }
    let from = settle - 1e-12 * block_len;
    let j = first_step_from(from, dt);
    // does step `j` open a block (an edge lies after the step before it and at or before it)?
    let opens = j == 0 || block_end_after((j - 1) as f64 * dt, block_len) <= j as f64 * dt;
    let first = if opens {
        j
    } else {
        first_step_from(block_end_after(j as f64 * dt, block_len), dt)
    };
    let close = first_step_from(block_end_after(first as f64 * dt, block_len), dt);
    Some(close + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step_sums(v: f64) -> StepSums {
        StepSums {
            sum_v: v,
            sum_v_old: v,
            sum_s: 0.0,
            friction_force: 0.0,
            stuck: 1.0,
            max_tension: v,
            max_strain: 0.0,
            tension_sin: 0.0,
            tension_cos: 0.0,
            dissipation: 0.0,
        }
    }

    /// Clock blocks close every `block_len` seconds from the run's start whatever the actuation
    /// does: with a restart at every step no forcing-period block ever closes, yet the clock
    /// blocks do, hold every step taken between them, and sum what was added. Without restarts
    /// they are the forcing-period blocks, bit for bit.
    #[test]
    fn clock_blocks_close_on_the_runs_clock_whatever_the_actuation_does() {
        let (dt, block_len) = (1.0 / 1024.0, 0.125); // 128 steps a block, exact in binary
        let mut restarted = MetricsTracker::new(0.0, block_len, 0.5);
        let mut steady = MetricsTracker::new(0.0, block_len, 0.5);
        let mut clock = Vec::new();
        let mut periods = Vec::new();
        for j in 0..1000u64 {
            let t = j as f64 * dt;
            // a new wave every step (another period each time)
            restarted.restart(t, 0.05 + 1e-5 * j as f64, 0.5);
            for m in [&mut restarted, &mut steady] {
                m.add_step(t, dt, &step_sums(j as f64), 2.0 * dt, dt);
                m.add_episode(1e-3);
            }
            clock.append(&mut restarted.closed);
            periods.append(&mut steady.closed);
        }
        assert!(clock.iter().all(|b| b.clock), "only clock blocks closed");
        let indices: Vec<u64> = clock.iter().map(|b| b.index).collect();
        assert_eq!(
            indices,
            (0..7).collect::<Vec<_>>(),
            "blocks 0 to 6 of 0.125 s"
        );
        for b in &clock {
            assert_eq!(b.sums.steps, 128);
            assert_eq!(b.sums.episodes, 128);
            assert_eq!(b.sums.stuck, 128.0);
            let first = b.index as f64 * 128.0;
            assert_eq!(
                b.sums.sum_v,
                (0..128).map(|k| first + k as f64).sum::<f64>()
            );
            assert_eq!(b.sums.max_tension, first + 127.0);
            assert_eq!(b.sums.energy_in, 0.25);
        }
        let open = restarted.clock.unwrap().block;
        assert_eq!(7 * 128 + open.steps, 1000, "every step in a clock block");
        // without restarts: the same blocks as the forcing period's
        let (period_blocks, clock_blocks): (Vec<_>, Vec<_>) =
            periods.into_iter().partition(|b| !b.clock);
        assert_eq!(period_blocks.len(), clock_blocks.len());
        for (p, c) in period_blocks.iter().zip(&clock_blocks) {
            assert_eq!((p.index, p.sums), (c.index, c.sums));
        }
        // a tracker of an older checkpoint has no clock blocks, and is still valid
        let mut old = steady.clone();
        old.clock = None;
        old.validate().unwrap();
        old.add_step(1.0, dt, &step_sums(1.0), 0.0, 0.0);
    }

    /// The steps [`steps_to_steady_block`] asks for are exactly those after which the tracker's
    /// steady window first holds a block, for fine and coarse steps, blocks shorter than a step,
    /// and settle times on, just before and just after block edges.
    #[test]
    fn the_steps_to_a_steady_block_are_those_the_tracker_needs() {
        let sums = StepSums {
            sum_v: 0.0,
            sum_v_old: 0.0,
            sum_s: 0.0,
            friction_force: 0.0,
            stuck: 0.0,
            max_tension: 0.0,
            max_strain: 0.0,
            tension_sin: 0.0,
            tension_cos: 0.0,
            dissipation: 0.0,
        };
        let mut cases = 0;
        for dt in [1.0e-3, 1.3e-3, 7.0e-3, 0.05, 0.2] {
            for block_len in [0.0845, 0.1, 0.25, 0.03] {
                for settle in [
                    0.0,
                    0.5,
                    1.0,
                    0.0845 * 6.0,
                    0.3 - 1e-9,
                    0.3 + 1e-9,
                    0.7 + 0.5 * dt,
                ] {
                    let needed = steps_to_steady_block(dt, block_len, settle).unwrap();
                    let mut m = MetricsTracker::new(0.0, block_len, settle);
                    let mut j = 0u64;
                    while m.steady.steps == 0 {
                        m.add_step(j as f64 * dt, dt, &sums, 0.0, 0.0);
                        j += 1;
                        assert!(j < 100_000, "no steady block: dt {dt}, block {block_len}");
                    }
                    assert_eq!(
                        needed, j,
                        "dt {dt} s, block {block_len} s, settle {settle} s"
                    );
                    cases += 1;
                }
            }
        }
        assert_eq!(cases, 140);
        // counts beyond exact integer arithmetic have no answer (and no endless loop)
        assert_eq!(steps_to_steady_block(1e-4, 6e300, 5.0), None);
        assert_eq!(steps_to_steady_block(1e-4, 6e-300, 5.0), None);
        assert_eq!(steps_to_steady_block(6e-300, 0.1, 5.0), None);
        assert_eq!(steps_to_steady_block(1e-4, 0.1, f64::MAX), None);
    }
}
