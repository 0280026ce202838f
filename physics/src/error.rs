//! Errors for invalid user input: each names the field, the value and what is allowed.

/// A parameter (from a scenario file, a flag, a wire message or a checkpoint) that is not allowed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("invalid {field} = {value}: allowed {allowed}")]
pub struct ParamError {
    /// Dotted name of the field, e.g. `friction.n_f`.
    pub field: String,
    /// The offending value, as text.
    pub value: String,
    /// What would be accepted, e.g. `0 <= n_f <= 1`.
    pub allowed: String,
}

impl ParamError {
    /// Builds an error for `field` holding `value`, where `allowed` says what is accepted.
    pub fn new(
        field: impl Into<String>,
        value: impl std::fmt::Display,
        allowed: impl Into<String>,
    ) -> Self {
        Self {
            field: field.into(),
            value: value.to_string(),
            allowed: allowed.into(),
        }
    }
}

/// Checks that `value` is finite and strictly positive.
pub fn positive(field: &str, value: f64) -> Result<f64, ParamError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ParamError::new(field, number(value), "a finite number > 0"))
    }
}

/// Checks that `value` is finite and not negative.
pub fn non_negative(field: &str, value: f64) -> Result<f64, ParamError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(ParamError::new(
            field,
            number(value),
            "a finite number >= 0",
        ))
    }
}

/// Checks that `value` is finite (any sign).
pub fn finite(field: &str, value: f64) -> Result<f64, ParamError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ParamError::new(field, number(value), "a finite number"))
    }
}

/// Checks `lo <= value <= hi` (and finiteness).
pub fn within(field: &str, value: f64, lo: f64, hi: f64) -> Result<f64, ParamError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(ParamError::new(
            field,
            number(value),
            format!("{lo} <= {field} <= {hi}"),
        ))
    }
}

/// `x` as text: as Rust writes it, or in exponent form where that would be long (`1e308` rather
/// than its 309 digits).
pub fn number(x: f64) -> String {
    let plain = x.to_string();
    if plain.len() > 24 {
        format!("{x:e}")
    } else {
        plain
    }
}
