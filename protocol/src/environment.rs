//! The pipe the crawler moves through, as the plant resolved it: friction as a function of the
//! world position. The plant answers it on [`crate::RunKeys::environment`] to the recorder,
//! whatever the scenario tells controllers (`disclose = false` gives controllers only nominal
//! values in [`crate::ModelInfo`]; a controller that queries the environment is cheating).

use serde::{Deserialize, Serialize};

use crate::error::ProtocolError;
use crate::messages::{finite, finite_all, short, Message};

/// Most pieces an [`Environment`] carries. A plant whose map has more sends it merged into
/// this many (and says how many of its pieces each one stands for in
/// [`Environment::merged`]); about 1.8 MB encoded.
pub const MAX_ENVIRONMENT_PIECES: usize = 1 << 16;

/// Friction along the pipe: `eps` and `n_F` are the uniform values before the first piece;
/// piece `j` holds `piece_eps[j]`, `piece_n_f[j]` from `piece_start[j]` to the next piece's start
/// (the last to `+inf`). All positions are world positions X = start + x + u, m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Environment {
    /// Protocol version.
    pub v: u16,
    /// Run id.
    pub run: String,
    /// World position of the body's tail (x = 0) at the start time, m.
    pub start: f64,
    /// Uniform dry friction coefficient eps (before the first piece).
    pub eps: f64,
    /// Uniform asymmetry n_F in [0, 1].
    pub n_f: f64,
    /// Where each piece starts, m, strictly increasing.
    pub piece_start: Vec<f64>,
    /// eps on each piece, >= 0.
    pub piece_eps: Vec<f64>,
    /// n_F on each piece, in [0, 1].
    pub piece_n_f: Vec<f64>,
    /// How many pieces of the plant's map each piece here stands for at most: 1 if this is the
    /// map exactly, more if it was merged (length-weighted means) to fit
    /// [`MAX_ENVIRONMENT_PIECES`].
    pub merged: u64,
}

impl Environment {
    /// `(eps, n_F)` at world position `x`, m.
    pub fn at(&self, x: f64) -> (f64, f64) {
        match self.piece_start.partition_point(|&s| s <= x) {
            0 => (self.eps, self.n_f),
            j => (self.piece_eps[j - 1], self.piece_n_f[j - 1]),
        }
    }

    /// True if friction is the same everywhere.
    pub fn is_uniform(&self) -> bool {
        self.piece_start.is_empty()
    }
}

fn coefficient(field: &str, x: f64) -> Result<(), ProtocolError> {
    if x.is_finite() && x >= 0.0 {
        Ok(())
    } else {
        Err(ProtocolError::invalid(field, x, "a finite number >= 0"))
    }
}

fn asymmetry(field: &str, x: f64) -> Result<(), ProtocolError> {
    if (0.0..=1.0).contains(&x) {
        Ok(())
    } else {
        Err(ProtocolError::invalid(field, x, "a number in [0, 1]"))
    }
}

impl Message for Environment {
    const NAME: &'static str = "environment";
    fn version(&self) -> u16 {
        self.v
    }
    fn validate(&self) -> Result<(), ProtocolError> {
        short("environment.run", &self.run)?;
        finite("environment.start", self.start)?;
        coefficient("environment.eps", self.eps)?;
        asymmetry("environment.n_f", self.n_f)?;
        let n = self.piece_start.len();
        if n > MAX_ENVIRONMENT_PIECES {
            return Err(ProtocolError::invalid(
                "environment.piece_start",
                format!("{n} pieces"),
                format!("at most {MAX_ENVIRONMENT_PIECES} pieces"),
            ));
        }
        for (field, len) in [
            ("environment.piece_eps", self.piece_eps.len()),
            ("environment.piece_n_f", self.piece_n_f.len()),
        ] {
            if len != n {
                return Err(ProtocolError::invalid(
                    field,
                    format!("{len} values"),
                    format!("{n} values, one per piece_start"),
                ));
            }
        }
        finite_all("environment.piece_start", &self.piece_start)?;
        if let Some(i) = self.piece_start.windows(2).position(|w| w[1] <= w[0]) {
            return Err(ProtocolError::invalid(
                format!("environment.piece_start[{}]", i + 1),
                self.piece_start[i + 1],
                format!("a position > piece_start[{i}] = {} m", self.piece_start[i]),
            ));
        }
        for (i, &e) in self.piece_eps.iter().enumerate() {
            coefficient(&format!("environment.piece_eps[{i}]"), e)?;
        }
        for (i, &a) in self.piece_n_f.iter().enumerate() {
            asymmetry(&format!("environment.piece_n_f[{i}]"), a)?;
        }
        if self.merged == 0 {
            return Err(ProtocolError::invalid(
                "environment.merged",
                0,
                "1 (the exact map) or more",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::{decode, encode, PROTOCOL_VERSION};

    fn env() -> Environment {
        Environment {
            v: PROTOCOL_VERSION,
            run: "r".into(),
            start: 0.5,
            eps: 0.1,
            n_f: 0.5,
            piece_start: vec![1.0, 2.0],
            piece_eps: vec![0.8, 0.1],
            piece_n_f: vec![0.5, 0.4],
            merged: 1,
        }
    }

    #[test]
    fn a_map_round_trips_and_answers_by_position() {
        let e = env();
        let back: Environment = decode(&encode(&e)).unwrap();
        assert_eq!(back, e);
        assert_eq!(e.at(0.999), (0.1, 0.5));
        assert_eq!(e.at(1.0), (0.8, 0.5), "a piece holds from its start");
        assert_eq!(e.at(1.5), (0.8, 0.5));
        assert_eq!(e.at(2.0), (0.1, 0.4));
        assert_eq!(e.at(1e9), (0.1, 0.4), "the last piece extends to +inf");
    }

    #[test]
    fn impossible_maps_are_refused_by_field() {
        type Spoil = Box<dyn Fn(&mut Environment)>;
        let cases: Vec<(Spoil, &str)> = vec![
            (Box::new(|e| e.start = f64::NAN), "environment.start"),
            (Box::new(|e| e.eps = -0.1), "environment.eps"),
            (Box::new(|e| e.n_f = 1.5), "environment.n_f"),
            (
                Box::new(|e| e.piece_eps.truncate(1)),
                "environment.piece_eps",
            ),
            (Box::new(|e| e.piece_n_f.push(0.1)), "environment.piece_n_f"),
            (
                Box::new(|e| e.piece_start[1] = 1.0),
                "environment.piece_start[1]",
            ),
            (
                Box::new(|e| e.piece_start[0] = f64::INFINITY),
                "environment.piece_start[0]",
            ),
            (
                Box::new(|e| e.piece_eps[1] = f64::NAN),
                "environment.piece_eps[1]",
            ),
            (
                Box::new(|e| e.piece_n_f[0] = -0.0001),
                "environment.piece_n_f[0]",
            ),
            (Box::new(|e| e.merged = 0), "environment.merged"),
            (
                Box::new(|e| {
                    let n = MAX_ENVIRONMENT_PIECES + 1;
                    e.piece_start = (0..n).map(|i| i as f64).collect();
                    e.piece_eps = vec![0.1; n];
                    e.piece_n_f = vec![0.5; n];
                }),
                "environment.piece_start",
            ),
        ];
        for (spoil, field) in cases {
            let mut e = env();
            spoil(&mut e);
            let err = decode::<Environment>(&encode(&e)).unwrap_err().to_string();
            assert!(
                err.contains(&format!("invalid {field} = ")),
                "{field}: {err}"
            );
        }
    }
}
