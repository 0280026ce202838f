//! The pipe as the plant resolved it, on the wire: the compiled friction map as a
//! [`crawler_protocol::Environment`], merged into at most
//! [`crawler_protocol::MAX_ENVIRONMENT_PIECES`] pieces if it has more.

use crawler_physics::pipe::{FrictionMap, Piece};
use crawler_protocol::{Environment, MAX_ENVIRONMENT_PIECES, PROTOCOL_VERSION};

/// The environment of run `run`: the map `map`, the body's tail at world position `start` (m) at
/// the start time.
pub fn environment(run: &str, start: f64, map: &FrictionMap) -> Environment {
    let pieces = &map.pieces;
    let merged = pieces.len().div_ceil(MAX_ENVIRONMENT_PIECES).max(1);
    let chunks: Vec<Piece> = pieces
        .chunks(merged)
        .enumerate()
        .map(|(c, chunk)| merge(chunk, pieces.get((c + 1) * merged).map(|p| p.start)))
        .collect();
    Environment {
        v: PROTOCOL_VERSION,
        run: run.to_string(),
        start,
        eps: map.eps,
        n_f: map.n_f,
        piece_start: chunks.iter().map(|p| p.start).collect(),
        piece_eps: chunks.iter().map(|p| p.eps).collect(),
        piece_n_f: chunks.iter().map(|p| p.n_f).collect(),
        merged: merged as u64,
    }
}

/// One piece standing for `chunk` (consecutive pieces; `end` is where the next chunk starts, none
/// for the last): the length-weighted means of eps and n_F. The last piece of the map extends to
/// infinity; it weighs as much as the mean piece before it.
fn merge(chunk: &[Piece], end: Option<f64>) -> Piece {
    if chunk.len() == 1 {
        return chunk[0];
    }
    let mut ends: Vec<f64> = chunk.iter().skip(1).map(|p| p.start).collect();
    let last = end.unwrap_or_else(|| {
        let span = ends[ends.len() - 1] - chunk[0].start;
        ends[ends.len() - 1] + span / (chunk.len() - 1) as f64
    });
    ends.push(last);
    let (mut w, mut eps, mut n_f) = (0.0, 0.0, 0.0);
    for (p, e) in chunk.iter().zip(&ends) {
        let len = e - p.start;
        w += len;
        eps += len * p.eps;
        n_f += len * p.n_f;
    }
    Piece {
        start: chunk[0].start,
        // means of values in [0, inf) and [0, 1] stay there (clamped against round-off)
        eps: (eps / w).max(0.0),
        n_f: (n_f / w).clamp(0.0, 1.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crawler_protocol::{decode, encode};

    fn map(n: usize) -> FrictionMap {
        FrictionMap {
            eps: 0.1,
            n_f: 0.5,
            pieces: (0..n)
                .map(|i| Piece {
                    start: i as f64 * 1e-3,
                    eps: if i % 2 == 0 { 0.8 } else { 0.2 },
                    n_f: 0.5,
                })
                .collect(),
        }
    }

    #[test]
    fn a_small_map_goes_exactly() {
        let m = map(1000);
        let e = environment("r", 0.25, &m);
        assert_eq!(e.merged, 1);
        assert_eq!(decode::<Environment>(&encode(&e)).unwrap(), e);
        for x in [-1.0, 0.0, 0.0005, 0.0015, 0.4, 0.9995, 2.0] {
            assert_eq!(e.at(x), m.at(x), "at {x}");
        }
        assert_eq!(e.start, 0.25);
    }

    #[test]
    fn a_large_map_is_merged_into_length_weighted_means() {
        // alternating 0.8 / 0.2 on equal lengths: every merged pair means 0.5
        let m = map(MAX_ENVIRONMENT_PIECES * 2 + 2);
        let e = environment("r", 0.0, &m);
        assert_eq!(e.merged, 3);
        assert_eq!(e.piece_start.len(), (m.pieces.len()).div_ceil(3));
        assert!(e.piece_start.len() <= MAX_ENVIRONMENT_PIECES);
        // chunks of three: (0.8 + 0.2 + 0.8) / 3 and (0.2 + 0.8 + 0.2) / 3 alternate
        assert!((e.piece_eps[0] - 0.6).abs() < 1e-12, "{}", e.piece_eps[0]);
        assert!((e.piece_eps[1] - 0.4).abs() < 1e-12, "{}", e.piece_eps[1]);
        assert_eq!(e.piece_start[1], m.pieces[3].start);
        decode::<Environment>(&encode(&e)).expect("the merged map is a valid message");
    }
}
