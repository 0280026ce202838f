//! Physical and numerical parameters of the plant, validated on construction.

use serde::{Deserialize, Serialize};

use crate::error::{non_negative, positive, within, ParamError};
use crate::pipe::Pipe;

/// Largest number of cells a plant accepts: the one limit shared by the plant, the wire protocol
/// and every front end, defined once in the wire contract (a co-simulation state of this many
/// cells is about 26 MB).
pub use crawler_facts::MAX_CELLS;
/// Smallest number of cells a plant accepts.
pub const MIN_CELLS: usize = 8;
/// Largest number of internal steps per communication step (guards against absurd `step`).
pub const MAX_SUBSTEPS: u64 = 1 << 24;
/// Largest number of internal steps of a run to `t_end` (2^53: the step counter and the clock
/// `t = t0 + step dt` stay exact in a double, and the count fits the wire's 64-bit steps).
pub const MAX_RUN_STEPS: u64 = 1 << 53;

/// The crawler's body: a uniform elastic rod.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Body {
    /// Cross-sectional area `A_c`, m^2.
    pub area: f64,
    /// Linear mass density `rho`, kg/m (volume density times `A_c`).
    pub density: f64,
    /// Young's modulus `E`, Pa.
    pub youngs_modulus: f64,
}

impl Body {
    /// Axial stiffness `A_c E`, N.
    pub fn stiffness(&self) -> f64 {
        self.area * self.youngs_modulus
    }

    /// Longitudinal wave speed `c = sqrt(A_c E / rho)`, m/s.
    pub fn wave_speed(&self) -> f64 {
        (self.stiffness() / self.density).sqrt()
    }

    /// Validates signs and finiteness.
    pub fn validate(&self) -> Result<(), ParamError> {
        positive("body.area", self.area)?;
        positive("body.density", self.density)?;
        positive("body.youngs_modulus", self.youngs_modulus)?;
        // and what the plant works out of them: each positive number can be, their product or
        // quotient overflow to infinity or vanish
        let stiffness = self.stiffness();
        if !(stiffness.is_finite() && stiffness > 0.0) {
            return Err(ParamError::new(
                "body.area",
                crate::error::number(self.area),
                format!(
                    "an area whose axial stiffness A_c E is a finite number > 0 (E = {} Pa gives {stiffness:e} N)",
                    crate::error::number(self.youngs_modulus)
                ),
            ));
        }
        let c = self.wave_speed();
        if !(c.is_finite() && c > 0.0) {
            return Err(ParamError::new(
                "body.density",
                crate::error::number(self.density),
                format!(
                    "a density whose wave speed sqrt(A_c E / rho) is a finite number > 0 (A_c E = {stiffness:e} N gives {c:e} m/s)"
                ),
            ));
        }
        Ok(())
    }
}

/// Asymmetric Coulomb + viscous friction `F(v) = c_v v + eps c_d (s - n_F)`, `s ∈ Sgn(v)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Friction {
    /// Viscous coefficient `c_v`, N s/m^2 (force per unit length per unit speed).
    pub viscous: f64,
    /// Normal load per unit length `c_d`, N/m.
    pub dry: f64,
    /// Dry (Coulomb) friction coefficient `eps`, dimensionless.
    pub eps: f64,
    /// Asymmetry shift `n_F` in `[0, 1]`, dimensionless.
    pub n_f: f64,
}

impl Friction {
    /// Half width of the static-friction band, `eps c_d`, N/m.
    pub fn band(&self) -> f64 {
        self.eps * self.dry
    }

    /// Upper bound of any steady speed, `eps c_d (1 + n_F) / c_v`, m/s.
    pub fn speed_bound(&self) -> f64 {
        self.band() * (1.0 + self.n_f) / self.viscous
    }

    /// Validates signs, finiteness and `0 <= n_F <= 1`.
    pub fn validate(&self) -> Result<(), ParamError> {
        positive("friction.viscous", self.viscous)?;
        non_negative("friction.dry", self.dry)?;
        non_negative("friction.eps", self.eps)?;
        within("friction.n_f", self.n_f, 0.0, 1.0)?;
        Ok(())
    }
}

/// Discretisation and averaging settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Numerics {
    /// Number of cells `N` (= number of nodes).
    pub cells: usize,
    /// Courant number `c dt / dx` of the internal step, in (0, 1]; 1 (the default) makes the
    /// scheme exact along characteristics for the undamped wave equation.
    pub courant: f64,
    /// Requested communication (macro) step, s. The plant uses the nearest whole multiple of the
    /// internal step `dt` (at least one), [`Discretisation::step`].
    pub step: f64,
    /// Transient skipped before steady-state averaging, s (counted from the last actuation change).
    pub settle: f64,
    /// Shortest stick phase counted as a stick-slip episode, as a share of the forcing period of
    /// the wave being applied (of `block` under a muscle-force field).
    pub min_stick_periods: f64,
    /// Averaging block when the actuation is a general field (no forcing period), s.
    pub block: f64,
    /// Strength of the grid filter per internal step, in [0, 1): the share of the grid-scale
    /// (Nyquist) mode of the sliding nodes' velocity removed each step by a conservative
    /// fourth-difference filter. At Courant number 1 the scheme's two interleaved sub-lattices
    /// do not exchange information and their difference, the Nyquist mode, is not damped by the
    /// centred viscous term; friction switching feeds it. 0 turns the filter off.
    #[serde(default = "default_filter")]
    pub filter: f64,
    /// An integer clock the communication step must fit, ticks per second (1/s): for a master
    /// that counts time in whole ticks (libcosim counts nanoseconds: `1_000_000_000`). `H` is
    /// then a whole number of ticks, the largest whose `H / substeps` keeps the Courant number
    /// at or below `courant`, and `dt = H / substeps`: the Courant number is lowered by less
    /// than one tick over `H`, at most [`CLOCK_COURANT_TOLERANCE`] (relative), see
    /// [`PlantParams::discretisation`]. `None` (the default): the plant's own clock, `dt` at the
    /// Courant bound and `H = m dt`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ticks_per_second: Option<u64>,
}

/// Default strength of the grid filter (see [`Numerics::filter`] and `docs/numerics.md`).
pub const DEFAULT_FILTER: f64 = 0.1;

/// How far below its target an integer clock ([`Numerics::ticks_per_second`]) may put the
/// Courant number, relative. `H` is rounded down to whole ticks, which lowers `dt` and the
/// Courant number by less than one tick over `H`: a step of at least [`CLOCK_TICKS_ALWAYS_FIT`]
/// ticks always fits, a shorter one when its rounding happens to be small enough. At resonance
/// the metrics move linearly with the shortfall, by up to about `1e3` times it (relative) at 128
/// cells per wavelength (docs/numerics.md, "Integer clocks").
pub const CLOCK_COURANT_TOLERANCE: f64 = 1e-6;

/// Ticks per communication step that always keep the Courant number within
/// [`CLOCK_COURANT_TOLERANCE`] of its target (1 ms at nanoseconds).
pub const CLOCK_TICKS_ALWAYS_FIT: u64 = 1_000_000;

/// Fastest integer clock, ticks per second (2^53: a tick count stays exact in a double).
pub const MAX_TICKS_PER_SECOND: u64 = 1 << 53;

fn default_filter() -> f64 {
    DEFAULT_FILTER
}

impl Numerics {
    /// Validates ranges.
    pub fn validate(&self) -> Result<(), ParamError> {
        if !(MIN_CELLS..=MAX_CELLS).contains(&self.cells) {
            return Err(ParamError::new(
                "numerics.cells",
                self.cells,
                format!("an integer in [{MIN_CELLS}, {MAX_CELLS}]"),
            ));
        }
        if !(self.courant.is_finite() && self.courant > 0.0 && self.courant <= 1.0) {
            return Err(ParamError::new(
                "numerics.courant",
                self.courant,
                "0 < courant <= 1",
            ));
        }
        positive("numerics.step", self.step)?;
        non_negative("numerics.settle", self.settle)?;
        non_negative("events.min_stick_periods", self.min_stick_periods)?;
        positive("numerics.block", self.block)?;
        if !(self.filter.is_finite() && (0.0..1.0).contains(&self.filter)) {
            return Err(ParamError::new(
                "numerics.filter",
                self.filter,
                "0 <= filter < 1 (share of the grid-scale mode removed per step)",
            ));
        }
        if let Some(t) = self.ticks_per_second {
            if !(1..=MAX_TICKS_PER_SECOND).contains(&t) {
                return Err(ParamError::new(
                    "numerics.ticks_per_second",
                    t,
                    format!(
                        "an integer clock of 1 to {MAX_TICKS_PER_SECOND} ticks per second \
                         (1000000000 for nanoseconds), or no key for the plant's own clock"
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// What holds the body's ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Boundary {
    /// The body is closed on itself (`u(0) = u(L)`), the paper's setting: nodes at `x_i = i dx`,
    /// tensions at `x_{i+1/2}`, the last one wrapping around.
    #[default]
    Periodic,
    /// Two free ends with zero tension: nodes at the cell centres `x_i = (i + 1/2) dx`, tensions
    /// at the interior faces `x = (i + 1) dx`; the last tension entry (the head's end face) is 0.
    Free,
}

impl Boundary {
    /// The name used in scenario files.
    pub fn as_str(self) -> &'static str {
        match self {
            Boundary::Periodic => "periodic",
            Boundary::Free => "free",
        }
    }

    /// Material position of node `i` for cells of `dx` m, m.
    pub fn node_position(self, i: usize, dx: f64) -> f64 {
        match self {
            Boundary::Periodic => i as f64 * dx,
            Boundary::Free => (i as f64 + 0.5) * dx,
        }
    }

    /// Material position of the tension/muscle-force point `i` (a half node), m.
    pub fn face_position(self, i: usize, dx: f64) -> f64 {
        match self {
            Boundary::Periodic => (i as f64 + 0.5) * dx,
            Boundary::Free => (i as f64 + 1.0) * dx,
        }
    }
}

/// Everything fixed when a plant is instantiated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlantParams {
    /// Body material and geometry.
    pub body: Body,
    /// Friction law (the uniform values; [`Self::pipe`] may vary them along the pipe).
    pub friction: Friction,
    /// Body length `L`, m.
    pub length: f64,
    /// Periodic body or free ends.
    pub boundary: Boundary,
    /// Friction along the pipe.
    pub pipe: Pipe,
    /// Discretisation.
    pub numerics: Numerics,
}

/// Grid and time step derived from [`PlantParams`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Discretisation {
    /// Cell size `dx = L / N`, m.
    pub dx: f64,
    /// Internal time step `dt = courant dx / c` (never above the requested Courant number), s.
    pub dt: f64,
    /// Internal steps per communication step.
    pub substeps: u64,
    /// The communication step actually used, `H = substeps dt`, s.
    pub step: f64,
    /// Achieved Courant number `c dt / dx`.
    pub courant: f64,
    /// `H` in ticks of the integer clock [`Numerics::ticks_per_second`], if there is one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ticks: Option<u64>,
}

impl Discretisation {
    /// Communication steps of a run to `t_end` seconds: the first communication point at or after
    /// `t_end` (at least one step).
    pub fn steps_until(&self, t_end: f64) -> u64 {
        ((t_end / self.step) * (1.0 - 1e-12)).ceil().max(1.0) as u64
    }
}

impl PlantParams {
    /// Validates every field, including that the time step exists.
    pub fn validate(&self) -> Result<(), ParamError> {
        self.body.validate()?;
        self.friction.validate()?;
        positive("body.length", self.length)?;
        self.numerics.validate()?;
        self.pipe.validate()?;
        self.discretisation().map(|_| ())
    }

    /// The grid spacing and the internal step: `dt = courant dx / c` (rounded down if rounding
    /// made `c dt / dx` exceed `courant`), and the communication step `H = m dt` with `m` the
    /// whole number nearest to `numerics.step / dt` (at least 1).
    ///
    /// With an integer clock of `r` ticks per second ([`Numerics::ticks_per_second`]), `m` is
    /// chosen the same way, then `H` is the largest whole number of ticks `n` with
    /// `c (H / m) / dx <= courant` (`H = n / r`, the double a master that counts ticks computes),
    /// and `dt = H / m`. The Courant number falls short of `courant` by less than `1 / n` of it,
    /// and the clock is refused if the shortfall exceeds [`CLOCK_COURANT_TOLERANCE`].
    pub fn discretisation(&self) -> Result<Discretisation, ParamError> {
        let dx = self.length / self.numerics.cells as f64;
        let c = self.body.wave_speed();
        let mut dt = self.numerics.courant * dx / c;
        while dt > 0.0 && c * dt / dx > self.numerics.courant {
            dt = f64::from_bits(dt.to_bits() - 1);
        }
        let ratio = self.numerics.step / dt;
        if !(ratio.is_finite() && dt > 0.0) || ratio > MAX_SUBSTEPS as f64 {
            return Err(ParamError::new(
                "numerics.step",
                self.numerics.step,
                format!(
                    "at most {MAX_SUBSTEPS} internal steps of dt = {dt:.3e} s (Courant {:.6e} on {} cells) per step",
                    self.numerics.courant, self.numerics.cells
                ),
            ));
        }
        let substeps = (ratio.round() as u64).max(1);
        if let Some(rate) = self.numerics.ticks_per_second {
            return self.clocked(dx, c, dt, substeps, rate);
        }
        Ok(Discretisation {
            dx,
            dt,
            substeps,
            step: substeps as f64 * dt,
            courant: c * dt / dx,
            ticks: None,
        })
    }

    /// The discretisation on an integer clock of `rate` ticks per second: `substeps` internal
    /// steps of at most `dt_max` (the Courant bound's step) per communication step of whole
    /// ticks (see [`Self::discretisation`]).
    fn clocked(
        &self,
        dx: f64,
        c: f64,
        dt_max: f64,
        substeps: u64,
        rate: u64,
    ) -> Result<Discretisation, ParamError> {
        let m = substeps as f64;
        let courant = self.numerics.courant;
        let bound = m * dt_max * rate as f64;
        if bound > MAX_TICKS_PER_SECOND as f64 {
            return Err(ParamError::new(
                "numerics.ticks_per_second",
                rate,
                format!(
                    "a clock of at most {MAX_TICKS_PER_SECOND} ticks per communication step \
                     (H = {:e} s)",
                    m * dt_max
                ),
            ));
        }
        // H and dt of `ticks`, if its internal step keeps the Courant bound (monotone in
        // `ticks`: every operation is a correctly rounded, monotone one)
        let keeps = |ticks: u64| {
            let step = ticks as f64 / rate as f64;
            let dt = step / m;
            (c * dt / dx <= courant).then_some((step, dt))
        };
        // the float `bound` is within a few ulps of the exact one: move to the largest count
        // that keeps the bound
        let mut ticks = bound.floor() as u64;
        while keeps(ticks + 1).is_some() {
            ticks += 1;
        }
        while keeps(ticks).is_none() {
            ticks -= 1;
        }
        let (step, dt) = keeps(ticks).expect("checked by the loop");
        let achieved = c * dt / dx;
        if achieved < courant * (1.0 - CLOCK_COURANT_TOLERANCE) {
            return Err(ParamError::new(
                "numerics.ticks_per_second",
                rate,
                format!(
                    "a clock on which H = {substeps} internal steps of at most dt = {dt_max:e} s \
                     (Courant number {courant}) rounds down to whole ticks lowering the Courant \
                     number by at most {CLOCK_COURANT_TOLERANCE:e} (relative); H = {ticks} ticks \
                     lowers it to {achieved:.9}: use a clock with at least \
                     {CLOCK_TICKS_ALWAYS_FIT} ticks per H (always fits), or a longer numerics.step"
                ),
            ));
        }
        Ok(Discretisation {
            dx,
            dt,
            substeps,
            step,
            courant: c * dt / dx,
            ticks: Some(ticks),
        })
    }

    /// The parameters as controllers are told them: identical when the pipe is disclosed;
    /// otherwise the nominal friction, uniform, without the map (`pipe.disclose = false`: a real
    /// crawler does not know its pipe).
    pub fn told(&self) -> PlantParams {
        let mut p = self.clone();
        if !self.pipe.disclose {
            if let Some(n) = self.pipe.nominal {
                p.friction.eps = n.eps;
                p.friction.n_f = n.n_f;
            }
            p.pipe.features.clear();
        }
        p
    }

    /// The friction map along the pipe (uniform when the pipe has no features).
    pub fn friction_map(&self) -> crate::pipe::FrictionMap {
        self.pipe.compile(self.friction.eps, self.friction.n_f)
    }
}
