//! The body as a picture: its cells as boxes in its own frame, in body lengths (the centre of
//! mass at 0, the tail to the left), each as long as the cell is and as thick as its strain
//! makes it (a contracted cell thickens, a stretched one thins, magnified [`paths::STRAIN_GAIN`]
//! times), so the peristaltic wave shows as bands running along the body; and the pipe under it.

use crate::paths;

/// The body's geometry.
#[derive(Debug, Clone, Copy)]
pub struct Body {
    /// Length L, m.
    pub length: f64,
    /// Node `i` sits at `(i + node_offset) dx` from the tail at rest.
    pub node_offset: f64,
    /// A periodic body (closed on itself) or one with two free ends.
    pub periodic: bool,
}

impl Body {
    /// Node `i`'s position relative to the centre of mass, m (`mean` the mean displacement).
    fn node(&self, u: &[f64], i: usize, mean: f64) -> f64 {
        let dx = self.length / u.len() as f64;
        (i as f64 + self.node_offset) * dx + u[i] - mean - 0.5 * self.length
    }

    /// The edges of cell `i`, m from the centre of mass: on a periodic body its two nodes (the
    /// last cell closes on node 0, a body length on); on a free body, whose nodes are the cell
    /// centres, half-way to the neighbouring nodes (the end cells as long as their neighbours).
    fn edges(&self, u: &[f64], i: usize, mean: f64) -> (f64, f64) {
        let n = u.len();
        let x = |j: usize| self.node(u, j, mean);
        if n == 1 {
            let dx = self.length;
            return (x(0) - 0.5 * dx, x(0) + 0.5 * dx);
        }
        if self.periodic {
            let right = if i + 1 < n {
                x(i + 1)
            } else {
                x(0) + self.length
            };
            return (x(i), right);
        }
        let left = if i == 0 {
            x(0) - 0.5 * (x(1) - x(0))
        } else {
            0.5 * (x(i - 1) + x(i))
        };
        let right = if i + 1 == n {
            x(i) + 0.5 * (x(i) - x(i - 1))
        } else {
            0.5 * (x(i) + x(i + 1))
        };
        (left, right)
    }

    /// The cells as boxes `(centre, half size, class)` in body lengths: class 1 (stick) if the
    /// cell's node is held by static friction, else 0 (slip).
    pub fn segments<'a>(
        &'a self,
        u: &'a [f64],
        stuck: &'a [bool],
        mean: f64,
    ) -> impl Iterator<Item = ([f32; 2], [f32; 2], u16)> + 'a {
        let n = u.len();
        let dx = self.length / n.max(1) as f64;
        let rest = paths::BODY_HEIGHT;
        (0..n).map(move |i| {
            let (left, right) = self.edges(u, i, mean);
            let strain = (right - left) / dx - 1.0;
            let height = (rest * (1.0 - paths::STRAIN_GAIN * strain)).clamp(0.2 * rest, 2.0 * rest);
            let l = self.length;
            (
                [(0.5 * (left + right) / l) as f32, 0.0],
                [(0.5 * (right - left) / l) as f32, (0.5 * height) as f32],
                u16::from(stuck[i]),
            )
        })
    }

    /// Node `i`'s position in the pipe, m (the tail at `start` at rest).
    pub fn node_in_pipe(&self, u: &[f64], i: usize, start: f64) -> f64 {
        let dx = self.length / u.len().max(1) as f64;
        start + (i as f64 + self.node_offset) * dx + u[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At rest the cells tile the body from -L/2 to L/2 at the rest height; a cell stretched by
    /// 10 % is 10 % longer and thinner by the gain; a stuck node's cell is class 1.
    #[test]
    fn the_cells_tile_the_body_and_their_height_follows_the_strain() {
        for (periodic, offset) in [(true, 0.0), (false, 0.5)] {
            let body = Body {
                length: 2.0,
                node_offset: offset,
                periodic,
            };
            let u = vec![0.0; 8];
            let stuck = [false, true, false, false, false, false, false, false];
            let cells: Vec<_> = body.segments(&u, &stuck, 0.0).collect();
            assert_eq!(cells.len(), 8);
            let left = cells[0].0[0] - cells[0].1[0];
            let right = cells[7].0[0] + cells[7].1[0];
            assert!(
                (left + 0.5).abs() < 1e-6 && (right - 0.5).abs() < 1e-6,
                "{left} {right}"
            );
            for w in cells.windows(2) {
                let edge = w[0].0[0] + w[0].1[0];
                assert!(
                    (edge - (w[1].0[0] - w[1].1[0])).abs() < 1e-6,
                    "cells overlap or part"
                );
            }
            let rest = (0.5 * paths::BODY_HEIGHT) as f32;
            assert!(cells.iter().all(|c| (c.1[1] - rest).abs() < 1e-7));
            assert_eq!(
                cells.iter().map(|c| c.2).collect::<Vec<_>>(),
                [0, 1, 0, 0, 0, 0, 0, 0]
            );
        }
        // a periodic body whose node 4 moved forward by a tenth of a cell: cell 3 stretched by
        // 10 %, cell 4 contracted by 10 %
        let body = Body {
            length: 2.0,
            node_offset: 0.0,
            periodic: true,
        };
        let mut u = vec![0.0; 8];
        u[4] = 0.1 * 0.25;
        let mean = u.iter().sum::<f64>() / 8.0;
        let cells: Vec<_> = body.segments(&u, &[false; 8], mean).collect();
        let rest = 0.5 * paths::BODY_HEIGHT;
        let expect = |strain: f64| (rest * (1.0 - paths::STRAIN_GAIN * strain)) as f32;
        assert!((cells[3].1[1] - expect(0.1)).abs() < 1e-6);
        assert!((cells[4].1[1] - expect(-0.1)).abs() < 1e-6);
        assert!((cells[3].1[0] - (1.1 * 0.125 / 2.0) as f32).abs() < 1e-6);
        assert!(
            cells[4].1[1] > cells[3].1[1],
            "the contracted cell is the thicker"
        );
    }
}
