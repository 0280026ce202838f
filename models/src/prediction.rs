//! What a model predicts about the steady state.

use crawler_facts::{Metric, MetricValues};
use serde::Serialize;

/// Whether a model's formulas apply at an operating point.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "status", content = "reason", rename_all = "snake_case")]
pub enum Validity {
    /// The model applies.
    Valid,
    /// The model's formulas are undefined here; the message says why.
    OutsideValidity(String),
}

impl Validity {
    /// True if valid.
    pub fn is_valid(&self) -> bool {
        matches!(self, Validity::Valid)
    }
}

/// Steady-state metrics predicted by a model (SI units). `None` where the model has no answer.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Prediction {
    /// Model name.
    pub model: &'static str,
    /// Mean speed V, m/s.
    pub velocity: Option<f64>,
    /// Input power over the body, W.
    pub power: Option<f64>,
    /// Mileage |V| / P, m/J.
    pub mileage: Option<f64>,
    /// sup T / A_c, Pa.
    pub max_stress: Option<f64>,
    /// max |u_x|.
    pub max_strain: Option<f64>,
    /// Share of node-time stuck.
    pub stuck_fraction: Option<f64>,
    /// Mean friction selection <s>.
    pub mean_friction_selection: Option<f64>,
    /// Stick episodes per node per period (at least `min_stick_periods` long).
    pub episodes_per_node_per_period: Option<f64>,
    /// Whether the model applies.
    pub validity: Validity,
}

impl Prediction {
    /// The value the model predicts for `metric` (`None`: no answer).
    pub fn value(&self, metric: Metric) -> Option<f64> {
        match metric {
            Metric::Velocity => self.velocity,
            Metric::Power => self.power,
            Metric::Mileage => self.mileage,
            Metric::MaxStress => self.max_stress,
            Metric::MaxStrain => self.max_strain,
            Metric::StuckFraction => self.stuck_fraction,
            Metric::MeanFrictionSelection => self.mean_friction_selection,
            Metric::EpisodesPerNodePerPeriod => self.episodes_per_node_per_period,
        }
    }

    /// Every metric of the table as the model predicts it (`None` where it has no answer or the
    /// number is not finite).
    pub fn values(&self) -> MetricValues {
        MetricValues::from_fn(|m| self.value(m))
    }

    /// A prediction with no numbers, for a point outside the model's validity.
    pub fn outside(model: &'static str, reason: String) -> Self {
        Self {
            model,
            velocity: None,
            power: None,
            mileage: None,
            max_stress: None,
            max_strain: None,
            stuck_fraction: None,
            mean_friction_selection: None,
            episodes_per_node_per_period: None,
            validity: Validity::OutsideValidity(reason),
        }
    }
}

/// A reduced model of the crawler's steady state under a travelling wave.
pub trait Model: Send + Sync {
    /// Short name (`paper`, `improved`, ...).
    fn name(&self) -> &'static str;
    /// The prediction at an operating point.
    fn predict(&self, op: &crate::operating_point::OperatingPoint) -> Prediction;
}
