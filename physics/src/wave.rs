//! The travelling-wave actuation `A_m f(x, t) = f0 sin(k x - omega t + phase)` (paper eq. 2).

use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

use crate::error::{finite, non_negative, positive, ParamError};
use crate::params::Boundary;

/// Minimum number of cells per wavelength the plant accepts for a travelling wave.
pub const MIN_CELLS_PER_WAVELENGTH: f64 = 8.0;

/// A travelling muscle-force wave.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Wave {
    /// Amplitude of the muscle force `f0 = e0 A_m`, N.
    pub f0: f64,
    /// Wave number `k = 2 pi / lambda`, rad/m.
    pub k: f64,
    /// Angular frequency `omega`, rad/s.
    pub omega: f64,
    /// Phase, rad.
    pub phase: f64,
}

impl Wave {
    /// Forcing period `2 pi / omega`, s.
    pub fn period(&self) -> f64 {
        TAU / self.omega
    }

    /// Wavelength `2 pi / k`, m.
    pub fn wavelength(&self) -> f64 {
        TAU / self.k
    }

    /// Validates the numbers on their own (signs, finiteness).
    pub fn validate(&self) -> Result<(), ParamError> {
        non_negative("wave.f0", self.f0)?;
        positive("wave.k", self.k)?;
        positive("wave.omega", self.omega)?;
        finite("wave.phase", self.phase)?;
        Ok(())
    }

    /// Validates the wave against a body of `length` m with `cells` cells: on a periodic body the
    /// wavelength must fit the body a whole number of times; on any body it must be resolved by
    /// at least [`MIN_CELLS_PER_WAVELENGTH`] cells.
    pub fn validate_for_body(
        &self,
        length: f64,
        cells: usize,
        boundary: Boundary,
    ) -> Result<(), ParamError> {
        self.validate()?;
        let fits = self.k * length / TAU;
        if boundary == Boundary::Periodic {
            let whole = fits.round();
            if whole < 1.0 || (fits - whole).abs() > 1e-9 * whole.max(1.0) {
                return Err(ParamError::new(
                    "wave.k",
                    self.k,
                    format!(
                        "a wavelength that fits the periodic body (L = {length} m) a whole number of times: \
                         k = 2 pi m / L for integer m >= 1 (k L / 2 pi = {fits:.6}); a free body \
                         (body.boundary = \"free\") takes any wavelength"
                    ),
                ));
            }
        }
        let per_wave = cells as f64 / fits;
        if per_wave < MIN_CELLS_PER_WAVELENGTH * (1.0 - 1e-9) {
            return Err(ParamError::new(
                "wave.k",
                self.k,
                format!(
                    "at least {MIN_CELLS_PER_WAVELENGTH} cells per wavelength ({cells} cells give {per_wave:.1}); \
                     use a smaller k or more cells"
                ),
            ));
        }
        Ok(())
    }
}
