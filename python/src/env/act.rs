//! How an action (a wave's parameters or one force per segment) becomes an actuation.

use std::f64::consts::TAU;

use crawler_physics::execution::Actuation;
use crawler_physics::params::Boundary;
use crawler_physics::wave::Wave;
use crawler_policies::Context;

use super::sense::segment_bounds;

/// How an action becomes an actuation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ActionKind {
    /// `[f0 (N), omega (rad/s), k (rad/m)]`: a travelling wave.
    Wave,
    /// One muscle force per segment, N.
    Field,
}

/// Turns actions into actuations for a controller told `ctx`: clipped to the scenario's limits;
/// a wave's k snapped to one that fits the body; a new wave's phase chosen so that the muscle
/// force keeps its phase at that instant (as `adaptive` does).
#[derive(Debug, Clone)]
pub struct Actuator {
    pub(super) kind: ActionKind,
    pub(super) bounds: Vec<usize>,
    pub(super) cells: usize,
    pub(super) length: f64,
    pub(super) boundary: Boundary,
    pub(super) f0_max: f64,
    pub(super) omega: [f64; 2],
    pub(super) k: [f64; 2],
    pub(super) last: Option<Wave>,
}

impl Actuator {
    /// The actuator of `kind` (`"wave"` or `"field"` over `segments` segments).
    pub fn new(ctx: &Context, kind: &str, segments: usize) -> Result<Self, String> {
        let kind = match kind {
            "wave" => ActionKind::Wave,
            "field" => ActionKind::Field,
            other => return Err(format!("action = {other:?}: allowed \"wave\", \"field\"")),
        };
        if segments == 0 || segments > ctx.cells {
            return Err(format!(
                "segments = {segments}: allowed 1 to {} (the cells)",
                ctx.cells
            ));
        }
        let l = &ctx.scenario.limits;
        Ok(Self {
            kind,
            bounds: segment_bounds(ctx.cells, segments),
            cells: ctx.cells,
            length: ctx.length,
            boundary: ctx.boundary,
            f0_max: l.f0_max,
            omega: l.omega,
            k: l.k,
            last: None,
        })
    }

    /// Numbers per action.
    pub fn dim(&self) -> usize {
        match self.kind {
            ActionKind::Wave => 3,
            ActionKind::Field => self.bounds.len() - 1,
        }
    }

    /// Bounds of the action's entries.
    pub fn low_high(&self) -> (Vec<f64>, Vec<f64>) {
        match self.kind {
            ActionKind::Wave => (
                vec![0.0, self.omega[0], self.k[0]],
                vec![self.f0_max, self.omega[1], self.k[1]],
            ),
            ActionKind::Field => (
                vec![-self.f0_max; self.dim()],
                vec![self.f0_max; self.dim()],
            ),
        }
    }

    /// The largest wave number the grid resolves (8 cells per wavelength), rad/m.
    pub(super) fn k_resolved(&self) -> f64 {
        TAU * self.cells as f64 / (crawler_physics::wave::MIN_CELLS_PER_WAVELENGTH * self.length)
    }

    /// The admissible wave number nearest to `k` (within the limits where one fits): on a
    /// periodic body a whole number of wavelengths.
    pub fn snap_k(&self, k: f64) -> f64 {
        let k = k.clamp(self.k[0], self.k[1]);
        match self.boundary {
            Boundary::Periodic => {
                let per = TAU / self.length;
                let lo = (self.k[0] / per - 1e-9).ceil().max(1.0);
                let hi = (self.k[1] / per + 1e-9)
                    .floor()
                    .min((self.k_resolved() / per).floor());
                let m = (k / per).round();
                let m = if lo <= hi {
                    m.clamp(lo, hi)
                } else {
                    m.max(1.0)
                };
                per * m
            }
            Boundary::Free => k.min(self.k_resolved()),
        }
    }

    /// The actuation of `action` at time `time` (s). NaN entries are refused.
    pub fn decode(&mut self, action: &[f64], time: f64) -> Result<Actuation, String> {
        if action.len() != self.dim() {
            return Err(format!(
                "action: {} numbers: allowed exactly {}",
                action.len(),
                self.dim()
            ));
        }
        if let Some((i, x)) = action.iter().enumerate().find(|(_, x)| x.is_nan()) {
            return Err(format!("action[{i}] = {x}: allowed numbers (not NaN)"));
        }
        match self.kind {
            ActionKind::Wave => {
                let f0 = action[0].clamp(0.0, self.f0_max);
                let omega = action[1].clamp(self.omega[0], self.omega[1]);
                let k = self.snap_k(action[2]);
                let mut w = Wave {
                    f0,
                    k,
                    omega,
                    phase: 0.0,
                };
                if let Some(prev) = self.last {
                    // the muscle force f0 sin(k x - omega t + phase) keeps its phase now
                    w.phase = if prev.k == k {
                        (prev.phase + (omega - prev.omega) * time).rem_euclid(TAU)
                    } else {
                        prev.phase
                    };
                    if (prev.f0, prev.k, prev.omega) == (f0, k, omega) {
                        w = prev;
                    }
                }
                self.last = Some(w);
                Ok(Actuation::Wave(w))
            }
            ActionKind::Field => {
                let mut field = vec![0.0; self.cells];
                for (j, &a) in action.iter().enumerate() {
                    let a = a.clamp(-self.f0_max, self.f0_max);
                    field[self.bounds[j]..self.bounds[j + 1]].fill(a);
                }
                Ok(Actuation::Field(field))
            }
        }
    }
}
