//! Physical and numerical parameters of the plant, validated on construction.

use serde::{Deserialize, Serialize};

use crate::error::{non_negative, positive, within, ParamError};

/// Largest number of cells a plant accepts (memory guard: ~10 arrays of this many f64).
pub const MAX_CELLS: usize = 1 << 24;
/// Smallest number of cells a plant accepts.
pub const MIN_CELLS: usize = 8;
/// Largest number of internal steps per communication step (guards against absurd `step`).
pub const MAX_SUBSTEPS: u64 = 1 << 24;

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
    /// Number of cells `N` on the periodic body (= number of nodes).
    pub cells: usize,
    /// Upper bound of the Courant number `c dt / dx`, in (0, 1].
    pub courant: f64,
    /// Communication (macro) step `H`, s; an integer number of internal steps.
    pub step: f64,
    /// Transient skipped before steady-state averaging, s (counted from the last actuation change).
    pub settle: f64,
    /// Shortest stick phase counted as a stick-slip episode, s.
    pub min_stick: f64,
    /// Averaging block when the actuation is a general field (no forcing period), s.
    pub block: f64,
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
        non_negative("numerics.min_stick", self.min_stick)?;
        positive("numerics.block", self.block)?;
        Ok(())
    }
}

/// Everything fixed when a plant is instantiated.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlantParams {
    /// Body material and geometry.
    pub body: Body,
    /// Friction law.
    pub friction: Friction,
    /// Body length `L` (the periodic domain), m.
    pub length: f64,
    /// Discretisation.
    pub numerics: Numerics,
}

/// Grid and time step derived from [`PlantParams`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Discretisation {
    /// Cell size `dx = L / N`, m.
    pub dx: f64,
    /// Internal time step `dt = H / substeps`, s.
    pub dt: f64,
    /// Internal steps per communication step.
    pub substeps: u64,
    /// Achieved Courant number `c dt / dx`.
    pub courant: f64,
}

impl PlantParams {
    /// Validates every field, including that the time step exists.
    pub fn validate(&self) -> Result<(), ParamError> {
        self.body.validate()?;
        self.friction.validate()?;
        positive("body.length", self.length)?;
        self.numerics.validate()?;
        self.discretisation().map(|_| ())
    }

    /// The grid spacing and the internal step: the largest `dt = H / m` (m integer) with
    /// `c dt / dx <= courant`.
    pub fn discretisation(&self) -> Result<Discretisation, ParamError> {
        let dx = self.length / self.numerics.cells as f64;
        let c = self.body.wave_speed();
        let dt_max = self.numerics.courant * dx / c;
        let ratio = self.numerics.step / dt_max;
        if !ratio.is_finite() || ratio > MAX_SUBSTEPS as f64 {
            return Err(ParamError::new(
                "numerics.step",
                self.numerics.step,
                format!("at most {MAX_SUBSTEPS} internal steps of {dt_max:.3e} s (CFL) per step"),
            ));
        }
        // A tiny tolerance so that a step that is an exact multiple of dt_max is not split further.
        let substeps = ((ratio * (1.0 - 1e-12)).ceil() as u64).max(1);
        let dt = self.numerics.step / substeps as f64;
        Ok(Discretisation {
            dx,
            dt,
            substeps,
            courant: c * dt / dx,
        })
    }
}
