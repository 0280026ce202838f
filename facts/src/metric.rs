//! The metric table: every steady-state metric of the crawler, with its name, symbol, unit and
//! meaning, written once.
//!
//! The plant computes them over whole forcing periods (`crawler-plant`'s `Metrics`), the models
//! predict them, a sweep stores them (one Parquet column per metric and source), the recorder
//! plots them (`metrics/<name>/<source>`), and the wire carries them under their names. Adding a
//! metric means a row here and its computation in the plant (and, where a model predicts it, in
//! the model): every other place takes the list from [`Metric::ALL`].

use serde::de::{IgnoredAny, MapAccess, Visitor};
use serde::ser::SerializeMap;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A steady-state metric.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Metric {
    /// Mean speed V of the body's centre of mass (the paper's eq. 5), m/s.
    Velocity,
    /// Mean input power P of the muscles over the body (eq. 7), W.
    Power,
    /// Mileage M = |V| / P, distance per energy, m/J.
    Mileage,
    /// Largest engineering stress sup T / A_c (eq. 4), Pa.
    MaxStress,
    /// Largest body strain max |u_x|.
    MaxStrain,
    /// Share of node-time held by static friction.
    StuckFraction,
    /// Space-time mean <s> of the friction selection s in Sgn(v), stuck points included.
    MeanFrictionSelection,
    /// Stick episodes per node per forcing period.
    EpisodesPerNodePerPeriod,
}

/// One row of the metric table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MetricInfo {
    /// The metric.
    pub metric: Metric,
    /// Its name in files, columns, entity paths and on the wire (snake case).
    pub name: &'static str,
    /// Its symbol in the paper's notation (`V`, `P`, ...; empty when it has none).
    pub symbol: &'static str,
    /// Its SI unit (`"1"` for a pure number).
    pub unit: &'static str,
    /// What it is, in a few words (a table's row label).
    pub label: &'static str,
    /// What it is, in one sentence.
    pub doc: &'static str,
    /// The least value it can take (`-inf`: unbounded).
    pub min: f64,
    /// The largest value it can take (`inf`: unbounded).
    pub max: f64,
    /// True for a share (a pure number between fixed bounds): errors of it are absolute
    /// differences, not relative ones.
    pub share: bool,
}

/// The table, in [`Metric::ALL`]'s order.
const TABLE: [MetricInfo; Metric::COUNT] = [
    MetricInfo {
        metric: Metric::Velocity,
        name: "velocity",
        symbol: "V",
        unit: "m/s",
        label: "velocity V",
        doc: "mean speed of the body's centre of mass over whole forcing periods",
        min: f64::NEG_INFINITY,
        max: f64::INFINITY,
        share: false,
    },
    MetricInfo {
        metric: Metric::Power,
        name: "power",
        symbol: "P",
        unit: "W",
        label: "power P",
        doc: "mean power the muscles put into the body",
        min: f64::NEG_INFINITY,
        max: f64::INFINITY,
        share: false,
    },
    MetricInfo {
        metric: Metric::Mileage,
        name: "mileage",
        symbol: "M",
        unit: "m/J",
        label: "mileage M",
        doc: "distance travelled per energy spent, |V| / P",
        min: f64::NEG_INFINITY,
        max: f64::INFINITY,
        share: false,
    },
    MetricInfo {
        metric: Metric::MaxStress,
        name: "max_stress",
        symbol: "sigma",
        unit: "Pa",
        label: "max stress",
        doc: "largest engineering stress sup T / A_c along the body",
        min: 0.0,
        max: f64::INFINITY,
        share: false,
    },
    MetricInfo {
        metric: Metric::MaxStrain,
        name: "max_strain",
        symbol: "",
        unit: "1",
        label: "max strain",
        doc: "largest body strain max |u_x|",
        min: 0.0,
        max: f64::INFINITY,
        share: false,
    },
    MetricInfo {
        metric: Metric::StuckFraction,
        name: "stuck_fraction",
        symbol: "",
        unit: "1",
        label: "stuck fraction",
        doc: "share of node-time held by static friction",
        min: 0.0,
        max: 1.0,
        share: true,
    },
    MetricInfo {
        metric: Metric::MeanFrictionSelection,
        name: "mean_friction_selection",
        symbol: "<s>",
        unit: "1",
        label: "<s>",
        doc: "space-time mean of the friction selection s in Sgn(v), stuck points included",
        min: -1.0,
        max: 1.0,
        share: true,
    },
    MetricInfo {
        metric: Metric::EpisodesPerNodePerPeriod,
        name: "episodes_per_node_per_period",
        symbol: "",
        unit: "1",
        label: "stick episodes",
        doc: "stick episodes per node per forcing period",
        min: 0.0,
        max: f64::INFINITY,
        share: true,
    },
];

impl Metric {
    /// How many metrics there are.
    pub const COUNT: usize = 8;

    /// Every metric, in the table's order.
    pub const ALL: [Metric; Metric::COUNT] = [
        Metric::Velocity,
        Metric::Power,
        Metric::Mileage,
        Metric::MaxStress,
        Metric::MaxStrain,
        Metric::StuckFraction,
        Metric::MeanFrictionSelection,
        Metric::EpisodesPerNodePerPeriod,
    ];

    /// The metric's row of the table.
    pub fn info(self) -> &'static MetricInfo {
        &TABLE[self.index()]
    }

    /// Position in [`Metric::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// Name in files, columns, entity paths and on the wire.
    pub fn name(self) -> &'static str {
        self.info().name
    }

    /// SI unit (`"1"` for a pure number).
    pub fn unit(self) -> &'static str {
        self.info().unit
    }

    /// The metric called `name`.
    pub fn parse(name: &str) -> Option<Metric> {
        Metric::ALL.into_iter().find(|m| m.name() == name)
    }

    /// The metric called `name`, or an error naming the field, the value and every metric.
    pub fn parse_field(field: &str, name: &str) -> Result<Metric, String> {
        Metric::parse(name).ok_or_else(|| {
            format!(
                "invalid {field} = {name:?}: allowed {}",
                Metric::ALL.map(Metric::name).join(", ")
            )
        })
    }
}

impl std::fmt::Display for Metric {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Serialize for Metric {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for Metric {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        Metric::parse_field("metric", &name).map_err(serde::de::Error::custom)
    }
}

/// A metric's value outside the metric's range.
#[derive(Debug, Clone, PartialEq)]
pub struct OutOfRange {
    /// Where: `prefix.metric`.
    pub field: String,
    /// The value.
    pub value: f64,
    /// What is allowed, in words.
    pub allowed: String,
}

impl std::fmt::Display for OutOfRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "invalid {} = {}: allowed {}",
            self.field, self.value, self.allowed
        )
    }
}

impl std::error::Error for OutOfRange {}

/// A value per metric, `None` where there is none (a model outside its validity, a metric it
/// does not predict, a number that is not finite). Serialised as a map from metric name to
/// number or null, so that a struct that flattens it carries the metrics as its own fields.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MetricValues([Option<f64>; Metric::COUNT]);

impl MetricValues {
    /// No values.
    pub const NONE: MetricValues = MetricValues([None; Metric::COUNT]);

    /// Values from `f`, one call per metric (a non-finite value is dropped).
    pub fn from_fn(mut f: impl FnMut(Metric) -> Option<f64>) -> Self {
        Self(Metric::ALL.map(|m| f(m).filter(|x| x.is_finite())))
    }

    /// Values of the metrics listed (the others `None`; a non-finite value is dropped).
    pub fn of(pairs: &[(Metric, f64)]) -> Self {
        let mut v = Self::NONE;
        for &(m, x) in pairs {
            v.set(m, Some(x));
        }
        v
    }

    /// The value of `metric`.
    pub fn get(&self, metric: Metric) -> Option<f64> {
        self.0[metric.index()]
    }

    /// Sets the value of `metric` (a non-finite value is dropped).
    pub fn set(&mut self, metric: Metric, value: Option<f64>) {
        self.0[metric.index()] = value.filter(|x| x.is_finite());
    }

    /// `self` with `metric` set to `value` as it is, finite or not: what a file or a message may
    /// hold before [`MetricValues::validate`] (for tests of validators).
    pub fn with_raw(mut self, metric: Metric, value: Option<f64>) -> Self {
        self.0[metric.index()] = value;
        self
    }

    /// Checks every value against its metric's range (finite, from `min` to `max`); the error
    /// names `prefix.metric`, the value and the range. Values read from a file or a message are
    /// kept as read until this is called.
    pub fn validate(&self, prefix: &str) -> Result<(), OutOfRange> {
        for (m, x) in self.iter() {
            let (Some(x), info) = (x, m.info()) else {
                continue;
            };
            if !(x.is_finite() && (info.min..=info.max).contains(&x)) {
                return Err(OutOfRange {
                    field: format!("{prefix}.{}", m.name()),
                    value: x,
                    allowed: match (info.min.is_finite(), info.max.is_finite()) {
                        (false, false) => "a finite number".to_string(),
                        (true, false) => format!("a finite number >= {}", info.min),
                        _ => format!("a finite number from {} to {}", info.min, info.max),
                    },
                });
            }
        }
        Ok(())
    }

    /// `(metric, value)` for every metric, in the table's order.
    pub fn iter(&self) -> impl Iterator<Item = (Metric, Option<f64>)> + '_ {
        Metric::ALL.into_iter().map(|m| (m, self.get(m)))
    }
}

impl Serialize for MetricValues {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(Metric::COUNT))?;
        for (m, x) in self.iter() {
            map.serialize_entry(m.name(), &x)?;
        }
        map.end()
    }
}

impl<'de> Deserialize<'de> for MetricValues {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Values;
        impl<'de> Visitor<'de> for Values {
            type Value = MetricValues;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a map from metric name to number or null")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<MetricValues, A::Error> {
                let mut values = MetricValues::NONE;
                // Keys that are not metrics belong to the struct that flattens the values.
                while let Some(key) = map.next_key::<std::borrow::Cow<'de, str>>()? {
                    match Metric::parse(&key) {
                        // Kept as read: the reader validates ([`MetricValues::validate`]) and
                        // names the field with its own prefix.
                        Some(m) => values.0[m.index()] = map.next_value()?,
                        None => {
                            map.next_value::<IgnoredAny>()?;
                        }
                    }
                }
                Ok(values)
            }
        }
        d.deserialize_map(Values)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_lists_every_metric_once_in_order() {
        for (i, m) in Metric::ALL.into_iter().enumerate() {
            assert_eq!(m.index(), i);
            assert_eq!(m.info().metric, m);
            assert_eq!(Metric::parse(m.name()), Some(m));
            assert!(!m.unit().is_empty() && !m.info().doc.is_empty());
        }
        let mut names: Vec<_> = Metric::ALL.map(Metric::name).to_vec();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), Metric::COUNT);
    }

    #[test]
    fn an_unknown_metric_is_refused_naming_every_metric() {
        let e = Metric::parse_field("plan.metric", "speed").unwrap_err();
        assert!(e.contains("plan.metric = \"speed\""), "{e}");
        assert!(e.contains("velocity, power, mileage"), "{e}");
    }

    #[test]
    fn values_travel_as_a_map_of_names_and_come_back_bit_for_bit() {
        let v = MetricValues::from_fn(|m| {
            (m != Metric::Mileage).then(|| 0.1 * m.index() as f64 + 1e-17)
        });
        let json = serde_json::to_string(&v).unwrap();
        assert!(
            json.contains("\"mileage\":null") && json.contains("\"velocity\":"),
            "{json}"
        );
        assert_eq!(serde_json::from_str::<MetricValues>(&json).unwrap(), v);
        let packed = rmp_serde::to_vec_named(&v).unwrap();
        assert_eq!(rmp_serde::from_slice::<MetricValues>(&packed).unwrap(), v);
    }

    #[test]
    fn values_flattened_into_a_struct_leave_its_other_fields_alone() {
        #[derive(Serialize, Deserialize, PartialEq, Debug)]
        struct Block {
            step: u64,
            #[serde(flatten)]
            values: MetricValues,
        }
        let b = Block {
            step: 7,
            values: MetricValues::from_fn(|m| Some(m.index() as f64)),
        };
        let packed = rmp_serde::to_vec_named(&b).unwrap();
        assert_eq!(rmp_serde::from_slice::<Block>(&packed).unwrap(), b);
    }

    #[test]
    fn a_value_outside_its_metrics_range_is_refused_by_name() {
        let mut v = MetricValues::NONE;
        v.set(Metric::StuckFraction, Some(1.5));
        let e = v.validate("report").unwrap_err().to_string();
        assert_eq!(
            e,
            "invalid report.stuck_fraction = 1.5: allowed a finite number from 0 to 1"
        );
        v.set(Metric::StuckFraction, Some(1.0));
        v.set(Metric::Velocity, Some(-3.0));
        assert!(v.validate("report").is_ok());
    }

    #[test]
    fn a_non_finite_value_is_never_kept() {
        let mut v = MetricValues::NONE;
        v.set(Metric::Power, Some(f64::NAN));
        assert_eq!(v.get(Metric::Power), None);
        let read = MetricValues::NONE.with_raw(Metric::Power, Some(f64::INFINITY));
        let e = read.validate("metrics").unwrap_err().to_string();
        assert_eq!(e, "invalid metrics.power = inf: allowed a finite number");
    }
}
