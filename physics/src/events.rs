//! Stick-slip episodes per node.
//!
//! An episode is a maximal run of internal steps in which a node is held at rest by static
//! friction. The kernel decides a stop on the velocity at a step's midpoint and a release on the
//! force at its start, half a step earlier, so a discrete stick phase of `m` steps stands for a
//! true one of `m - 1/2` steps on average: that is its duration here, and the stuck node-steps
//! the kernel counted are corrected by the same half step. A velocity reversal (one step at rest
//! held by momentum alone, [`Transition::reversal`]) is no stick phase: duration zero. An episode
//! counts when it lasts at least `min_stick` seconds (`events.min_stick_periods` of the applied
//! wave's period), a physical time, so the count, the
//! mean duration and the stuck fraction converge under refinement (`docs/numerics.md`).

use serde::{Deserialize, Serialize};

use crate::solver::Transition;

/// A stick phase of one node.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Episode {
    /// Node index (position `x = node * dx`).
    pub node: u32,
    /// Time the node came to rest, s.
    pub start: f64,
    /// Time it started sliding again, s.
    pub end: f64,
    /// `end - start`, s.
    pub duration: f64,
    /// Direction it left towards: +1 forward (towards the head), -1 backward.
    pub direction: i8,
}

const SLIDING: u64 = u64::MAX;

/// Tracks the start of the current stick phase of every node.
#[derive(Debug, PartialEq, Serialize, Deserialize)]
pub struct EventTracker {
    /// Internal step at which each node's current stick phase began, or `u64::MAX` if sliding.
    stick_start: Vec<u64>,
    /// True if that stop was a [`Transition::reversal`].
    reversal: Vec<bool>,
    /// Shortest counted stick phase, s (set by the plant from the applied actuation).
    pub min_stick: f64,
}

/// `clone_from` copies into the existing buffers (the plant's rollback copy at every
/// communication step allocates nothing).
impl Clone for EventTracker {
    fn clone(&self) -> Self {
        Self {
            stick_start: self.stick_start.clone(),
            reversal: self.reversal.clone(),
            min_stick: self.min_stick,
        }
    }

    fn clone_from(&mut self, source: &Self) {
        // every field named, so that a new one cannot be forgotten here
        let Self {
            stick_start,
            reversal,
            min_stick,
        } = source;
        self.stick_start.clone_from(stick_start);
        self.reversal.clone_from(reversal);
        self.min_stick = *min_stick;
    }
}

/// What the transitions of one step changed in the statistics.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Applied {
    /// Correction to the stuck node-steps counted whole-step by the kernel for the stick phases
    /// that ended in this step, in node-steps: their durations minus their whole-step counts.
    pub stuck_correction: f64,
}

impl EventTracker {
    /// A tracker for `cells` sliding nodes.
    pub fn new(cells: usize, min_stick: f64) -> Self {
        Self {
            stick_start: vec![SLIDING; cells],
            reversal: vec![false; cells],
            min_stick,
        }
    }

    /// Number of nodes tracked.
    pub fn cells(&self) -> usize {
        self.stick_start.len()
    }

    /// Applies the transitions of internal step `step` (which spans `[t0 + step dt, t0 + (step+1) dt]`)
    /// and pushes completed episodes (at least `min_stick` long) to `out`.
    pub fn apply(
        &mut self,
        step: u64,
        t0: f64,
        dt: f64,
        transitions: &[Transition],
        out: &mut Vec<Episode>,
    ) -> Applied {
        let mut applied = Applied::default();
        for tr in transitions {
            let i = tr.node as usize;
            if tr.stuck {
                self.stick_start[i] = step;
                self.reversal[i] = tr.reversal;
            } else {
                let start = self.stick_start[i];
                self.stick_start[i] = SLIDING;
                if start == SLIDING {
                    continue;
                }
                let whole = step - start;
                if whole == 1 && self.reversal[i] {
                    applied.stuck_correction -= 1.0;
                    continue;
                }
                applied.stuck_correction -= 0.5;
                let duration = (whole as f64 - 0.5) * dt;
                if duration + 1e-12 * dt >= self.min_stick {
                    out.push(Episode {
                        node: tr.node,
                        start: t0 + start as f64 * dt,
                        end: t0 + (step as f64 - 0.5) * dt,
                        duration,
                        direction: if tr.velocity > 0.0 { 1 } else { -1 },
                    });
                }
            }
        }
        applied
    }

    /// Number of nodes currently in a stick phase.
    pub fn stuck_nodes(&self) -> usize {
        self.stick_start.iter().filter(|&&s| s != SLIDING).count()
    }

    /// Checks a restored tracker: one entry per node of a body of `cells` nodes.
    pub fn validate(&self, cells: usize) -> Result<(), crate::error::ParamError> {
        for (name, len) in [
            ("state.events.stick_start", self.stick_start.len()),
            ("state.events.reversal", self.reversal.len()),
        ] {
            if len != cells {
                return Err(crate::error::ParamError::new(
                    name,
                    format!("{len} values"),
                    format!("{cells} values (one per cell)"),
                ));
            }
        }
        crate::error::non_negative("state.events.min_stick", self.min_stick)?;
        Ok(())
    }
}
