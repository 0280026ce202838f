//! Stick-slip episodes per node.
//!
//! An episode is a maximal run of internal steps in which a node is held at rest by static
//! friction, lasting at least `numerics.min_stick` seconds. The threshold is a physical time, not a
//! number of steps: a velocity that merely passes through zero can land in the static band for a
//! single step (a duration of order `dt`), and counting those would make the episode count grow as
//! `dt` shrinks. With a fixed physical threshold the count, the mean duration and the stuck
//! fraction converge under refinement (physics-notes §6).

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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EventTracker {
    /// Internal step at which each node's current stick phase began, or `u64::MAX` if sliding.
    stick_start: Vec<u64>,
    /// Shortest counted stick phase, s.
    pub min_stick: f64,
}

impl EventTracker {
    /// A tracker for `cells` sliding nodes.
    pub fn new(cells: usize, min_stick: f64) -> Self {
        Self {
            stick_start: vec![SLIDING; cells],
            min_stick,
        }
    }

    /// Number of nodes tracked.
    pub fn cells(&self) -> usize {
        self.stick_start.len()
    }

    /// Applies the transitions of internal step `step` (which spans `[t0 + step dt, t0 + (step+1) dt]`)
    /// and pushes completed episodes to `out`.
    pub fn apply(
        &mut self,
        step: u64,
        t0: f64,
        dt: f64,
        transitions: &[Transition],
        out: &mut Vec<Episode>,
    ) {
        for tr in transitions {
            let i = tr.node as usize;
            if tr.stuck {
                self.stick_start[i] = step;
            } else {
                let start = self.stick_start[i];
                self.stick_start[i] = SLIDING;
                if start == SLIDING {
                    continue;
                }
                let duration = (step - start) as f64 * dt;
                if duration + 1e-12 * dt >= self.min_stick {
                    out.push(Episode {
                        node: tr.node,
                        start: t0 + start as f64 * dt,
                        end: t0 + step as f64 * dt,
                        duration,
                        direction: if tr.velocity > 0.0 { 1 } else { -1 },
                    });
                }
            }
        }
    }

    /// Number of nodes currently in a stick phase.
    pub fn stuck_nodes(&self) -> usize {
        self.stick_start.iter().filter(|&&s| s != SLIDING).count()
    }

    /// Checks the tracker matches a body of `cells` nodes (for restored checkpoints).
    pub fn matches(&self, cells: usize) -> bool {
        self.stick_start.len() == cells
    }
}
