//! Sums over spans of an array whose bits are those of the plain loop, computed faster.
//!
//! A sum of floating-point numbers depends on the order of its additions. [`span_sums`] adds
//! each span's terms in order, from a given zero, so its result is the one of
//! `terms.iter().fold(zero, |s, x| s + x)`; it only runs the spans' chains of dependent
//! additions side by side (the additions of one chain wait for each other, those of different
//! chains do not), which is what makes a short sum's time its additions' latency, not their
//! count.

/// Chains added side by side.
const LANES: usize = 8;

/// `out[j]`: for span `j`, whose terms are at `span(j) = (a, b)`, the sum from `zero`, in order,
/// of `values[i]` for `i` in `a..b`, or with `DIFF` of `values[i + 1] - values[i]`: the bits of
/// the plain loop. Eight spans at a time; a last group of fewer repeats its last span, whose
/// extra sums are dropped.
pub fn span_sums<const DIFF: bool>(
    values: &[f64],
    span: impl Fn(usize) -> (usize, usize),
    zero: f64,
    out: &mut [f64],
) {
    let extra = usize::from(DIFF);
    let term = |s: &[f64], k: usize| if DIFF { s[k + 1] - s[k] } else { s[k] };
    let n = out.len();
    for (g, group) in out.chunks_mut(LANES).enumerate() {
        let lanes: [&[f64]; LANES] = std::array::from_fn(|l| {
            let (a, b) = span((LANES * g + l).min(n - 1));
            &values[a..b.max(a) + extra]
        });
        let common = lanes.iter().map(|s| s.len() - extra).min().unwrap_or(0);
        // each lane cut to the common length, so the loop below indexes without checks
        let cut: [&[f64]; LANES] = std::array::from_fn(|l| &lanes[l][..common + extra]);
        let mut acc = [zero; LANES];
        for k in 0..common {
            for (acc, s) in acc.iter_mut().zip(&cut) {
                *acc += term(s, k);
            }
        }
        for (acc, s) in acc.iter_mut().zip(lanes) {
            for k in common..s.len() - extra {
                *acc += term(s, k);
            }
        }
        group.copy_from_slice(&acc[..group.len()]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Terms whose sums depend on the order of their additions.
    fn terms(n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| {
                let x = (i as f64 * 0.754_877_666).sin();
                x * 10f64.powi((i % 7) as i32 - 3)
            })
            .collect()
    }

    #[test]
    fn each_span_sum_has_the_bits_of_the_plain_loop_in_order() {
        let values = terms(203);
        for spans in [1, 3, 7, 8, 9, 17, 203] {
            let bounds: Vec<usize> = (0..=spans).map(|j| j * values.len() / spans).collect();
            for zero in [0.0, -0.0] {
                let mut got = vec![f64::NAN; spans];
                span_sums::<false>(&values, |j| (bounds[j], bounds[j + 1]), zero, &mut got);
                for (j, g) in got.iter().enumerate() {
                    let want = values[bounds[j]..bounds[j + 1]]
                        .iter()
                        .fold(zero, |s, x| s + x);
                    assert_eq!(g.to_bits(), want.to_bits(), "span {j} of {spans}");
                }
            }
        }
    }

    #[test]
    fn each_span_sum_of_differences_has_the_bits_of_the_plain_loop_in_order() {
        let values = terms(203);
        for spans in [1, 3, 8, 9, 202] {
            let bounds: Vec<usize> = (0..=spans).map(|j| j * 202 / spans).collect();
            let mut got = vec![f64::NAN; spans];
            span_sums::<true>(&values, |j| (bounds[j], bounds[j + 1]), 0.0, &mut got);
            for (j, g) in got.iter().enumerate() {
                let want =
                    (bounds[j]..bounds[j + 1]).fold(0.0, |s, i| s + (values[i + 1] - values[i]));
                assert_eq!(g.to_bits(), want.to_bits(), "span {j} of {spans}");
            }
        }
    }

    #[test]
    fn an_empty_span_sums_to_its_zero() {
        let values = terms(10);
        let mut got = [f64::NAN; 3];
        span_sums::<false>(&values, |j| [(0, 4), (4, 4), (4, 10)][j], -0.0, &mut got);
        assert_eq!(got[1].to_bits(), (-0.0f64).to_bits());
        assert_eq!(got[2], values[4..].iter().fold(-0.0, |s, x| s + x));
    }
}
