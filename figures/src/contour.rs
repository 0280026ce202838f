//! Contour lines of a gridded field by marching squares, as line segments in data coordinates.

/// The segments of the level set `f = level` of `values` (`values[iy * xs.len() + ix]` at
/// `(xs[ix], ys[iy])`), linearly interpolated along the cell edges. Cells with an undefined
/// corner have no segment. Saddles are resolved by the cell's mean.
pub fn segments(
    xs: &[f64],
    ys: &[f64],
    values: &[Option<f64>],
    level: f64,
) -> Vec<[(f64, f64); 2]> {
    let nx = xs.len();
    let mut out = Vec::new();
    if nx < 2 || ys.len() < 2 {
        return out;
    }
    for iy in 0..ys.len() - 1 {
        for ix in 0..nx - 1 {
            // corners counter-clockwise from bottom-left
            let idx = [
                iy * nx + ix,
                iy * nx + ix + 1,
                (iy + 1) * nx + ix + 1,
                (iy + 1) * nx + ix,
            ];
            let pos = [
                (xs[ix], ys[iy]),
                (xs[ix + 1], ys[iy]),
                (xs[ix + 1], ys[iy + 1]),
                (xs[ix], ys[iy + 1]),
            ];
            let Some(v) = idx.iter().map(|&i| values[i]).collect::<Option<Vec<f64>>>() else {
                continue;
            };
            let above: Vec<bool> = v.iter().map(|x| *x >= level).collect();
            // crossing points on the edges (edge e joins corner e and e+1)
            let cross = |e: usize| -> (f64, f64) {
                let (a, b) = (e, (e + 1) % 4);
                let t = (level - v[a]) / (v[b] - v[a]);
                let t = if t.is_finite() {
                    t.clamp(0.0, 1.0)
                } else {
                    0.5
                };
                (
                    pos[a].0 + t * (pos[b].0 - pos[a].0),
                    pos[a].1 + t * (pos[b].1 - pos[a].1),
                )
            };
            let edges: Vec<usize> = (0..4).filter(|&e| above[e] != above[(e + 1) % 4]).collect();
            match edges.len() {
                2 => out.push([cross(edges[0]), cross(edges[1])]),
                4 => {
                    // saddle: join so that the corners on the mean's side are connected
                    let mean_above = v.iter().sum::<f64>() / 4.0 >= level;
                    if mean_above == above[0] {
                        out.push([cross(0), cross(1)]);
                        out.push([cross(2), cross(3)]);
                    } else {
                        out.push([cross(3), cross(0)]);
                        out.push([cross(1), cross(2)]);
                    }
                }
                _ => {}
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_contour_of_a_cone_is_a_circle_of_the_right_radius() {
        let n = 41;
        let xs: Vec<f64> = (0..n)
            .map(|i| -1.0 + 2.0 * i as f64 / (n - 1) as f64)
            .collect();
        let values: Vec<Option<f64>> = xs
            .iter()
            .flat_map(|y| xs.iter().map(move |x| Some((x * x + y * y).sqrt())))
            .collect();
        let segs = segments(&xs, &xs, &values, 0.5);
        assert!(segs.len() > 40, "{} segments", segs.len());
        let mut length = 0.0;
        for [a, b] in &segs {
            for p in [a, b] {
                let r = (p.0 * p.0 + p.1 * p.1).sqrt();
                assert!((r - 0.5).abs() < 0.01, "point at radius {r}");
            }
            length += ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt();
        }
        // a closed curve: its length is the circumference (chords: slightly less)
        let c = std::f64::consts::TAU * 0.5;
        assert!(length < c && length > 0.99 * c, "length {length} vs {c}");
        // undefined corners remove the segments of their cells
        let mut holes = values.clone();
        for v in holes.iter_mut().take(n * n / 2) {
            *v = None;
        }
        let half = segments(&xs, &xs, &holes, 0.5);
        assert!(half.len() < segs.len() / 2 + 2);
        assert!(half.iter().all(|[a, b]| a.1 >= 0.0 && b.1 >= 0.0));
    }
}
