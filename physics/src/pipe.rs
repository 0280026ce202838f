//! A pipe whose friction varies along it: `eps` and `n_F` as functions of the world position.
//!
//! A node at material position `x` (m along the body, from its tail) with displacement `u` is at the
//! world position `X = start + x + u` in the pipe (`start` is where the tail was at `t = 0`). Each
//! node uses the friction of the pipe at its own position, at every internal step.
//!
//! The map is built from the scenario's uniform values (`friction.eps`, `friction.n_f`) and a list
//! of features applied in order:
//!
//! - a **patch** sets `eps` and/or `n_F` to a constant on `[from, to)`;
//! - a **ramp** sets them to a linear interpolation between two values on `[from, to)`;
//! - a **texture** adds a zero-mean random field with standard deviations `eps_std`, `n_f_std` and
//!   correlation length `correlation` on `[from, to)`: an Ornstein–Uhlenbeck process (covariance
//!   `exp(-|dX| / correlation)`) sampled every `correlation / 8` from a seeded ChaCha8 generator and
//!   interpolated linearly in between.
//!
//! After every feature `eps` is clipped to `>= 0` and `n_F` to `[0, 1]`. The composed map is
//! compiled into a piecewise-constant function ([`FrictionMap`]): patch edges are kept exactly;
//! ramps and textures are held constant over intervals of `resolution` metres (their value at the
//! interval's midpoint). Outside all features the uniform values hold.

use rand_chacha::rand_core::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use crate::error::{finite, non_negative, positive, within, ParamError};

/// Largest number of constant pieces a compiled map may have (all features together).
pub const MAX_PIECES: usize = 1 << 20;

/// Largest number of features a pipe may have.
pub const MAX_FEATURES: usize = 1024;

/// Largest number of random samples of all textures together (two numbers each).
pub const MAX_SAMPLES: usize = 1 << 22;

/// Default resolution of ramps and textures, m.
pub const DEFAULT_RESOLUTION: f64 = 1e-3;

/// What controllers are told about the friction when the pipe is not disclosed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Nominal {
    /// Dry friction coefficient controllers are told.
    pub eps: f64,
    /// Asymmetry controllers are told.
    pub n_f: f64,
}

/// One change of friction along the pipe.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Feature {
    /// Constant values on `[from, to)`.
    Patch {
        /// Start, world position, m.
        from: f64,
        /// End, m.
        to: f64,
        /// `eps` on the patch (unchanged if absent).
        eps: Option<f64>,
        /// `n_F` on the patch (unchanged if absent).
        n_f: Option<f64>,
    },
    /// Linear change on `[from, to)` from the first value at `from` to the second at `to`.
    Ramp {
        /// Start, m.
        from: f64,
        /// End, m.
        to: f64,
        /// `[eps at from, eps at to]` (unchanged if absent).
        #[serde(default, deserialize_with = "crate::pair::optional_pair")]
        eps: Option<[f64; 2]>,
        /// `[n_F at from, n_F at to]` (unchanged if absent).
        #[serde(default, deserialize_with = "crate::pair::optional_pair")]
        n_f: Option<[f64; 2]>,
    },
    /// A seeded random texture added on `[from, to)`.
    Texture {
        /// Start, m.
        from: f64,
        /// End, m.
        to: f64,
        /// Standard deviation added to `eps`.
        #[serde(default)]
        eps_std: f64,
        /// Standard deviation added to `n_F`.
        #[serde(default)]
        n_f_std: f64,
        /// Correlation length, m.
        correlation: f64,
        /// Seed of the generator.
        seed: u64,
    },
}

impl Feature {
    fn range(&self) -> (f64, f64) {
        match *self {
            Feature::Patch { from, to, .. }
            | Feature::Ramp { from, to, .. }
            | Feature::Texture { from, to, .. } => (from, to),
        }
    }

    /// Checks the values of a feature on `[from, to)` (m, a valid range): a patch's or a ramp's
    /// `eps` and `n_f` (at least one given), a texture's deviations and correlation length (m,
    /// at most [`MAX_PIECES`] samples). `name` gives a field's full name in errors.
    fn validate_values(
        &self,
        from: f64,
        to: f64,
        name: &impl Fn(&str) -> String,
    ) -> Result<(), ParamError> {
        match *self {
            Feature::Patch { eps, n_f, .. } => {
                if let Some(e) = eps {
                    non_negative(&name("eps"), e)?;
                }
                if let Some(n) = n_f {
                    within(&name("n_f"), n, 0.0, 1.0)?;
                }
                if eps.is_none() && n_f.is_none() {
                    return Err(ParamError::new(
                        name("eps"),
                        "missing",
                        "eps and/or n_f for a patch",
                    ));
                }
            }
            Feature::Ramp { eps, n_f, .. } => {
                if let Some([a, b]) = eps {
                    non_negative(&name("eps[0]"), a)?;
                    non_negative(&name("eps[1]"), b)?;
                }
                if let Some([a, b]) = n_f {
                    within(&name("n_f[0]"), a, 0.0, 1.0)?;
                    within(&name("n_f[1]"), b, 0.0, 1.0)?;
                }
                if eps.is_none() && n_f.is_none() {
                    return Err(ParamError::new(
                        name("eps"),
                        "missing",
                        "eps = [from, to] and/or n_f = [from, to] for a ramp",
                    ));
                }
            }
            Feature::Texture {
                eps_std,
                n_f_std,
                correlation,
                ..
            } => {
                non_negative(&name("eps_std"), eps_std)?;
                non_negative(&name("n_f_std"), n_f_std)?;
                positive(&name("correlation"), correlation)?;
                let samples = (to - from) / (correlation / 8.0);
                if samples > MAX_PIECES as f64 {
                    return Err(ParamError::new(
                        name("correlation"),
                        correlation,
                        format!(
                            "at least (to - from) * 8 / {MAX_PIECES} m (the texture is sampled every correlation / 8)"
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The pipe: where the body starts, what controllers are told, and how friction varies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pipe {
    /// World position of the body's tail (`x = 0`) at `t = 0`, m.
    #[serde(default)]
    pub start: f64,
    /// True if controllers are told the true friction (uniform values and map).
    #[serde(default = "yes")]
    pub disclose: bool,
    /// What controllers are told when `disclose` is false.
    #[serde(default)]
    pub nominal: Option<Nominal>,
    /// Hold ramps and textures constant over intervals of this length, m.
    #[serde(default = "default_resolution")]
    pub resolution: f64,
    /// Changes of friction, applied in order.
    #[serde(default)]
    pub features: Vec<Feature>,
}

fn yes() -> bool {
    true
}

fn default_resolution() -> f64 {
    DEFAULT_RESOLUTION
}

impl Default for Pipe {
    fn default() -> Self {
        Self {
            start: 0.0,
            disclose: true,
            nominal: None,
            resolution: DEFAULT_RESOLUTION,
            features: Vec::new(),
        }
    }
}

impl Pipe {
    /// True if no feature changes the friction (the plant then takes its uniform fast path).
    pub fn is_uniform(&self) -> bool {
        self.features.is_empty()
    }

    /// Validates every field; `base_eps`/`base_n_f` are the uniform values the features modify.
    pub fn validate(&self) -> Result<(), ParamError> {
        self.validate_settings()?;
        // pieces and texture samples of all features together (each also bounded on its own
        // below), so that a map's memory and the time to build it stay bounded
        let (mut pieces, mut samples) = (0.0, 0.0);
        for (i, f) in self.features.iter().enumerate() {
            self.validate_feature(i, f)?;
            let (from, to) = f.range();
            pieces += match f {
                Feature::Patch { .. } => 1.0,
                _ => ((to - from) / self.resolution).ceil(),
            };
            if let Feature::Texture { correlation, .. } = *f {
                samples += ((to - from) / (correlation / 8.0)).ceil() + 1.0;
            }
        }
        self.validate_totals(pieces, samples)
    }

    /// Checks the fields other than the features themselves: the start (m), the resolution
    /// (m), the nominal values and the number of features.
    fn validate_settings(&self) -> Result<(), ParamError> {
        finite("pipe.start", self.start)?;
        positive("pipe.resolution", self.resolution)?;
        match (self.disclose, &self.nominal) {
            (false, None) => {
                return Err(ParamError::new(
                    "pipe.nominal",
                    "missing",
                    "the values controllers are told when pipe.disclose = false: nominal = { eps = .., n_f = .. }",
                ))
            }
            (_, Some(n)) => {
                non_negative("pipe.nominal.eps", n.eps)?;
                within("pipe.nominal.n_f", n.n_f, 0.0, 1.0)?;
            }
            (true, None) => {}
        }
        if self.features.len() > MAX_FEATURES {
            return Err(ParamError::new(
                "pipe.features",
                format!("{} features", self.features.len()),
                format!("at most {MAX_FEATURES} features"),
            ));
        }
        Ok(())
    }

    /// Checks feature `i`: its range `[from, to)` (m), its values and, for a ramp or a texture,
    /// its number of pieces at the pipe's resolution.
    fn validate_feature(&self, i: usize, f: &Feature) -> Result<(), ParamError> {
        let name = |field: &str| format!("pipe.features[{i}].{field}");
        let (from, to) = f.range();
        finite(&name("from"), from)?;
        finite(&name("to"), to)?;
        if to <= from {
            return Err(ParamError::new(
                name("to"),
                to,
                format!("a position > from = {from} m"),
            ));
        }
        f.validate_values(from, to, &name)?;
        if matches!(f, Feature::Ramp { .. } | Feature::Texture { .. })
            && (to - from) / self.resolution > MAX_PIECES as f64
        {
            return Err(ParamError::new(
                "pipe.resolution",
                self.resolution,
                format!(
                    "at least {:.3e} m so that features[{i}] has at most {MAX_PIECES} pieces",
                    (to - from) / MAX_PIECES as f64
                ),
            ));
        }
        Ok(())
    }

    /// Checks the `pieces` and texture `samples` of all features together.
    fn validate_totals(&self, pieces: f64, samples: f64) -> Result<(), ParamError> {
        if pieces > MAX_PIECES as f64 {
            return Err(ParamError::new(
                "pipe.features",
                format!("{pieces:.0} pieces in all"),
                format!(
                    "at most {MAX_PIECES} pieces in all (a patch is one; a ramp or texture is held \
                     constant every resolution = {} m, (to - from) / resolution pieces)",
                    self.resolution
                ),
            ));
        }
        if samples > MAX_SAMPLES as f64 {
            return Err(ParamError::new(
                "pipe.features",
                format!("{samples:.0} texture samples in all"),
                format!(
                    "at most {MAX_SAMPLES} texture samples in all (a texture is sampled every \
                     correlation / 8 from `from` to `to`)"
                ),
            ));
        }
        Ok(())
    }

    /// Compiles the map for the uniform values `eps`, `n_f` (validate first).
    pub fn compile(&self, eps: f64, n_f: f64) -> FrictionMap {
        let textures: Vec<Option<TextureSamples>> = self
            .features
            .iter()
            .map(|f| match *f {
                Feature::Texture {
                    from,
                    to,
                    eps_std,
                    n_f_std,
                    correlation,
                    seed,
                } => Some(TextureSamples::new(
                    from,
                    to,
                    eps_std,
                    n_f_std,
                    correlation,
                    seed,
                )),
                _ => None,
            })
            .collect();
        // Edges: every feature's ends; inside ramps and textures, every `resolution`.
        let mut edges = Vec::new();
        for f in &self.features {
            let (from, to) = f.range();
            edges.push(from);
            edges.push(to);
            if !matches!(f, Feature::Patch { .. }) {
                let n = ((to - from) / self.resolution).ceil() as usize;
                edges.extend((1..n).map(|j| from + j as f64 * self.resolution));
            }
        }
        edges.sort_by(f64::total_cmp);
        edges.dedup();
        // Each interval between edges takes the value at its midpoint (at its start where the
        // midpoint rounds onto its end: an interval one ulp wide); the features are applied in
        // order, each to the intervals whose point it covers (found by binary search, so a
        // feature costs the intervals it covers).
        let points: Vec<f64> = edges
            .windows(2)
            .map(|w| {
                let mid = 0.5 * (w[0] + w[1]);
                if mid < w[1] {
                    mid
                } else {
                    w[0]
                }
            })
            .collect();
        let mut values = vec![(eps, n_f); points.len()];
        for (f, tex) in self.features.iter().zip(&textures) {
            let (from, to) = f.range();
            let covered =
                points.partition_point(|&x| x < from)..points.partition_point(|&x| x < to);
            for (&x, (e, n)) in points[covered.clone()].iter().zip(&mut values[covered]) {
                match *f {
                    Feature::Patch {
                        eps: pe, n_f: pn, ..
                    } => {
                        *e = pe.unwrap_or(*e);
                        *n = pn.unwrap_or(*n);
                    }
                    Feature::Ramp {
                        eps: re, n_f: rn, ..
                    } => {
                        let w = (x - from) / (to - from);
                        if let Some([a, b]) = re {
                            *e = a + w * (b - a);
                        }
                        if let Some([a, b]) = rn {
                            *n = a + w * (b - a);
                        }
                    }
                    Feature::Texture { .. } => {
                        let t = tex.as_ref().expect("texture samples");
                        let (de, dn) = t.at(x);
                        *e += de;
                        *n += dn;
                    }
                }
                *e = e.max(0.0);
                *n = n.clamp(0.0, 1.0);
            }
        }
        let mut pieces: Vec<Piece> = Vec::with_capacity(edges.len());
        for (&start, &(e, n)) in edges.iter().zip(&values) {
            match pieces.last() {
                Some(last) if last.eps == e && last.n_f == n => {}
                _ => pieces.push(Piece {
                    start,
                    eps: e,
                    n_f: n,
                }),
            }
        }
        // Beyond the last edge the uniform values hold again.
        if let Some(&end) = edges.last() {
            if pieces.last().is_some_and(|p| (p.eps, p.n_f) != (eps, n_f)) {
                pieces.push(Piece {
                    start: end,
                    eps,
                    n_f,
                });
            }
        }
        // A first piece equal to the uniform values is redundant.
        while pieces.first().is_some_and(|p| (p.eps, p.n_f) == (eps, n_f)) {
            pieces.remove(0);
        }
        FrictionMap { eps, n_f, pieces }
    }
}

/// A texture's Ornstein–Uhlenbeck samples.
struct TextureSamples {
    from: f64,
    spacing: f64,
    eps: Vec<f64>,
    n_f: Vec<f64>,
}

impl TextureSamples {
    fn new(from: f64, to: f64, eps_std: f64, n_f_std: f64, correlation: f64, seed: u64) -> Self {
        let spacing = correlation / 8.0;
        let n = ((to - from) / spacing).ceil() as usize + 1;
        let rho = (-spacing / correlation).exp();
        let kick = (1.0 - rho * rho).sqrt();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut process = |std: f64| -> Vec<f64> {
            let mut g: f64 = StandardNormal.sample(&mut rng);
            (0..n)
                .map(|j| {
                    if j > 0 {
                        let xi: f64 = StandardNormal.sample(&mut rng);
                        g = rho * g + kick * xi;
                    }
                    std * g
                })
                .collect()
        };
        let eps = process(eps_std);
        let n_f = process(n_f_std);
        Self {
            from,
            spacing,
            eps,
            n_f,
        }
    }

    fn at(&self, x: f64) -> (f64, f64) {
        let s = ((x - self.from) / self.spacing).max(0.0);
        let j = (s.floor() as usize).min(self.eps.len() - 2);
        let w = s - j as f64;
        (
            self.eps[j] + w * (self.eps[j + 1] - self.eps[j]),
            self.n_f[j] + w * (self.n_f[j + 1] - self.n_f[j]),
        )
    }
}

/// A constant piece of the map, from `start` to the next piece's start.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Piece {
    /// World position where the piece starts, m.
    pub start: f64,
    /// Dry friction coefficient on the piece.
    pub eps: f64,
    /// Asymmetry on the piece.
    pub n_f: f64,
}

/// The compiled map: uniform values, overridden on `[pieces[j].start, pieces[j+1].start)`; the
/// last piece extends to `+inf` and the uniform values hold before the first.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrictionMap {
    /// Uniform `eps` (before the first piece).
    pub eps: f64,
    /// Uniform `n_F`.
    pub n_f: f64,
    /// The pieces, sorted by start.
    pub pieces: Vec<Piece>,
}

/// Where a position lies in a [`FrictionMap`]: `index` 0 is before the first piece, `j + 1` is piece `j`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Located {
    /// Interval index.
    pub index: usize,
    /// Start of the interval (`-inf` for index 0), m.
    pub lo: f64,
    /// End of the interval (`+inf` for the last), m.
    pub hi: f64,
    /// `eps` on it.
    pub eps: f64,
    /// `n_F` on it.
    pub n_f: f64,
}

impl FrictionMap {
    /// True if the map has no pieces (friction is uniform).
    pub fn is_uniform(&self) -> bool {
        self.pieces.is_empty()
    }

    /// The interval holding `x`, found by binary search.
    pub fn locate(&self, x: f64) -> Located {
        let index = self.pieces.partition_point(|p| p.start <= x);
        self.interval(index)
    }

    /// Interval `index` (0 = before the first piece).
    pub fn interval(&self, index: usize) -> Located {
        let lo = if index == 0 {
            f64::NEG_INFINITY
        } else {
            self.pieces[index - 1].start
        };
        let hi = self.pieces.get(index).map_or(f64::INFINITY, |p| p.start);
        let (eps, n_f) = if index == 0 {
            (self.eps, self.n_f)
        } else {
            let p = &self.pieces[index - 1];
            (p.eps, p.n_f)
        };
        Located {
            index,
            lo,
            hi,
            eps,
            n_f,
        }
    }

    /// `(eps, n_F)` at world position `x`.
    pub fn at(&self, x: f64) -> (f64, f64) {
        let l = self.locate(x);
        (l.eps, l.n_f)
    }

    /// The smallest and largest `eps` and `n_F` anywhere in the pipe.
    pub fn ranges(&self) -> ([f64; 2], [f64; 2]) {
        let mut e = [self.eps, self.eps];
        let mut n = [self.n_f, self.n_f];
        for p in &self.pieces {
            e = [e[0].min(p.eps), e[1].max(p.eps)];
            n = [n[0].min(p.n_f), n[1].max(p.n_f)];
        }
        (e, n)
    }
}

/// A patch of `eps` on `[from, to)` (for the tests of this crate).
#[cfg(test)]
pub(crate) fn patch(from: f64, to: f64, eps: f64) -> Feature {
    Feature::Patch {
        from,
        to,
        eps: Some(eps),
        n_f: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_patch_one_ulp_wide_is_kept() {
        let (from, to) = (0.3, 0.3f64.next_up());
        let pipe = Pipe {
            features: vec![patch(from, to, 0.7)],
            ..Default::default()
        };
        pipe.validate().unwrap();
        let m = pipe.compile(0.1, 0.5);
        assert_eq!(m.at(from.next_down()), (0.1, 0.5));
        assert_eq!(m.at(from), (0.7, 0.5));
        assert_eq!(m.at(to), (0.1, 0.5));
    }

    #[test]
    fn patches_are_exact_and_later_features_win() {
        let pipe = Pipe {
            features: vec![patch(1.0, 2.0, 0.8), patch(1.5, 3.0, 0.3)],
            ..Default::default()
        };
        pipe.validate().unwrap();
        let m = pipe.compile(0.1, 0.5);
        assert_eq!(m.at(0.999_999), (0.1, 0.5));
        assert_eq!(m.at(1.0), (0.8, 0.5));
        assert_eq!(m.at(1.499_999), (0.8, 0.5));
        assert_eq!(m.at(1.5), (0.3, 0.5));
        assert_eq!(m.at(2.999_999), (0.3, 0.5));
        assert_eq!(m.at(3.0), (0.1, 0.5));
        assert_eq!(m.at(100.0), (0.1, 0.5));
        assert_eq!(m.pieces.len(), 3);
    }

    #[test]
    fn ramps_are_held_at_their_midpoints() {
        let pipe = Pipe {
            resolution: 0.1,
            features: vec![Feature::Ramp {
                from: 0.0,
                to: 1.0,
                eps: Some([0.0, 1.0]),
                n_f: Some([0.5, 0.7]),
            }],
            ..Default::default()
        };
        pipe.validate().unwrap();
        let m = pipe.compile(0.3, 0.5);
        for j in 0..10 {
            let x = 0.1 * j as f64 + 0.03;
            let mid = 0.1 * j as f64 + 0.05;
            let (e, n) = m.at(x);
            assert!((e - mid).abs() < 1e-12, "{x}: {e}");
            assert!((n - (0.5 + 0.2 * mid)).abs() < 1e-12);
        }
        assert_eq!(m.at(1.0), (0.3, 0.5));
        assert_eq!(m.at(-0.01), (0.3, 0.5));
    }

    #[test]
    fn textures_are_reproducible_zero_mean_and_correlated() {
        let tex = |seed| Pipe {
            resolution: 0.01,
            features: vec![Feature::Texture {
                from: 0.0,
                to: 200.0,
                eps_std: 0.05,
                n_f_std: 0.0,
                correlation: 0.5,
                seed,
            }],
            ..Default::default()
        };
        let a = tex(7).compile(0.5, 0.5);
        assert_eq!(a, tex(7).compile(0.5, 0.5), "same seed, same map");
        assert_ne!(a, tex(8).compile(0.5, 0.5), "another seed, another map");
        let xs: Vec<f64> = (0..20_000).map(|j| 0.01 * j as f64 + 0.005).collect();
        let e: Vec<f64> = xs.iter().map(|&x| a.at(x).0 - 0.5).collect();
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        let var = e.iter().map(|d| d * d).sum::<f64>() / e.len() as f64;
        // 400 correlation lengths: the sample mean's standard error is about 0.05 / 14.
        assert!(mean.abs() < 0.012, "mean {mean}");
        assert!((var.sqrt() - 0.05).abs() < 0.01, "std {}", var.sqrt());
        // Correlation at one correlation length: exp(-1) for the OU process (interpolation
        // smooths it slightly).
        let lag = 50;
        let c =
            e.iter().zip(&e[lag..]).map(|(a, b)| a * b).sum::<f64>() / (e.len() - lag) as f64 / var;
        assert!((c - (-1.0f64).exp()).abs() < 0.1, "correlation {c}");
        assert!(a.pieces.iter().all(|p| p.n_f == 0.5));
    }

    /// The map's value on each interval between edges by the rule written out point by point:
    /// every feature looked at for the interval's point, in order.
    fn reference_values(pipe: &Pipe, eps: f64, n_f: f64, edges: &[f64]) -> Vec<(f64, f64)> {
        let at = |x: f64| {
            let (mut e, mut n) = (eps, n_f);
            for f in &pipe.features {
                let (from, to) = f.range();
                if !(from <= x && x < to) {
                    continue;
                }
                match *f {
                    Feature::Patch {
                        eps: pe, n_f: pn, ..
                    } => {
                        e = pe.unwrap_or(e);
                        n = pn.unwrap_or(n);
                    }
                    Feature::Ramp {
                        eps: re, n_f: rn, ..
                    } => {
                        let w = (x - from) / (to - from);
                        if let Some([a, b]) = re {
                            e = a + w * (b - a);
                        }
                        if let Some([a, b]) = rn {
                            n = a + w * (b - a);
                        }
                    }
                    Feature::Texture {
                        eps_std,
                        n_f_std,
                        correlation,
                        seed,
                        ..
                    } => {
                        let t = TextureSamples::new(from, to, eps_std, n_f_std, correlation, seed);
                        let (de, dn) = t.at(x);
                        e += de;
                        n += dn;
                    }
                }
                e = e.max(0.0);
                n = n.clamp(0.0, 1.0);
            }
            (e, n)
        };
        edges
            .windows(2)
            .map(|w| {
                let mid = 0.5 * (w[0] + w[1]);
                at(if mid < w[1] { mid } else { w[0] })
            })
            .collect()
    }

    #[test]
    fn overlapping_features_compile_to_the_point_by_point_rule() {
        let pipe = Pipe {
            resolution: 0.05,
            features: vec![
                Feature::Texture {
                    from: -1.0,
                    to: 2.0,
                    eps_std: 0.3,
                    n_f_std: 0.2,
                    correlation: 0.2,
                    seed: 4,
                },
                patch(0.5, 0.9, 0.0),
                Feature::Ramp {
                    from: 0.7,
                    to: 1.4,
                    eps: Some([0.2, 0.6]),
                    n_f: None,
                },
                patch(1.0, 1.0f64.next_up(), 0.9),
                Feature::Texture {
                    from: 1.2,
                    to: 3.0,
                    eps_std: 0.1,
                    n_f_std: 0.0,
                    correlation: 0.3,
                    seed: 5,
                },
                Feature::Patch {
                    from: 2.5,
                    to: 2.6,
                    eps: None,
                    n_f: Some(1.0),
                },
            ],
            ..Default::default()
        };
        pipe.validate().unwrap();
        let (eps, n_f) = (0.1, 0.5);
        let m = pipe.compile(eps, n_f);
        let mut edges: Vec<f64> = m.pieces.iter().map(|p| p.start).collect();
        // every edge the features make, to test the value between each pair
        for f in &pipe.features {
            let (from, to) = f.range();
            edges.extend([from, to]);
            if !matches!(f, Feature::Patch { .. }) {
                let n = ((to - from) / pipe.resolution).ceil() as usize;
                edges.extend((1..n).map(|j| from + j as f64 * pipe.resolution));
            }
        }
        edges.sort_by(f64::total_cmp);
        edges.dedup();
        let want = reference_values(&pipe, eps, n_f, &edges);
        let mut clipped = 0;
        for (w, &(e, n)) in edges.windows(2).zip(&want) {
            assert_eq!(m.at(w[0]), (e, n), "[{}, {})", w[0], w[1]);
            clipped += usize::from(e == 0.0 || n == 0.0 || n == 1.0);
        }
        assert!(clipped > 0, "the clipping is exercised");
        assert_eq!(m.at(edges[0].next_down()), (eps, n_f));
        assert_eq!(m.at(*edges.last().unwrap()), (eps, n_f));
        assert_eq!(m.at(1.0), (0.9, m.at(1.0).1), "the one-ulp patch is kept");
    }

    #[test]
    fn the_features_are_bounded_in_all() {
        let texture = |i: usize, correlation: f64| Feature::Texture {
            from: -500.0 + i as f64 * 1e-4,
            to: 500.0 + i as f64 * 1e-4,
            eps_std: 0.01,
            n_f_std: 0.0,
            correlation,
            seed: i as u64,
        };
        // each texture alone is allowed (1e6 pieces of 1 mm), two together are not
        let one = Pipe {
            features: vec![texture(0, 1.0)],
            ..Default::default()
        };
        one.validate().unwrap();
        let two = Pipe {
            features: vec![texture(0, 1.0), texture(1, 1.0)],
            ..Default::default()
        };
        let e = two.validate().unwrap_err();
        assert_eq!(e.field, "pipe.features");
        assert!(e.to_string().contains("pieces in all"), "{e}");
        // samples: each texture of 1e6 samples is allowed, five together are not
        let coarse = |k| Pipe {
            resolution: 1.0,
            features: (0..k).map(|i| texture(i, 8e-3)).collect(),
            ..Default::default()
        };
        coarse(4).validate().unwrap();
        let e = coarse(5).validate().unwrap_err();
        assert_eq!(e.field, "pipe.features");
        assert!(e.to_string().contains("texture samples in all"), "{e}");
        let many = Pipe {
            features: (0..=MAX_FEATURES)
                .map(|i| patch(i as f64, i as f64 + 0.5, 0.3))
                .collect(),
            ..Default::default()
        };
        let e = many.validate().unwrap_err();
        assert_eq!(e.field, "pipe.features");
        assert!(e.to_string().contains("1025 features"), "{e}");
        let most = Pipe {
            features: many.features[..MAX_FEATURES].to_vec(),
            ..Default::default()
        };
        most.validate().unwrap();
        assert_eq!(most.compile(0.1, 0.5).pieces.len(), 2 * MAX_FEATURES);
    }

    #[test]
    fn values_are_clipped_and_bad_fields_named() {
        let pipe = Pipe {
            features: vec![Feature::Ramp {
                from: 0.0,
                to: 1.0,
                eps: None,
                n_f: Some([0.9, 1.0]),
            }],
            ..Default::default()
        };
        assert!(pipe.validate().is_ok());
        let bad = Pipe {
            features: vec![patch(2.0, 1.0, 0.3)],
            ..Default::default()
        };
        let e = bad.validate().unwrap_err();
        assert_eq!(e.field, "pipe.features[0].to");
        let hidden = Pipe {
            disclose: false,
            ..Default::default()
        };
        assert_eq!(hidden.validate().unwrap_err().field, "pipe.nominal");
    }
}
