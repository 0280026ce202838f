//! How a run did against the paper's task: travel the distance `D` on the energy budget `J0`
//! without exceeding the stress limit `sigma_max`.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// The outcome of a run against its task. It travels and prints as its words
/// ([`Outcome::as_str`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Outcome {
    /// The centre of mass travelled `D` within the energy budget.
    Reached,
    /// The actuator spent the budget before `D` was reached.
    EnergyExhausted,
    /// The run ended (its end time) with neither.
    TimeUp,
}

impl Outcome {
    /// Every outcome.
    pub const ALL: [Outcome; 3] = [Outcome::Reached, Outcome::EnergyExhausted, Outcome::TimeUp];

    /// The outcome in words: `"reached"`, `"energy exhausted"`, `"time up"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Reached => "reached",
            Outcome::EnergyExhausted => "energy exhausted",
            Outcome::TimeUp => "time up",
        }
    }

    /// The outcome named `name`.
    pub fn parse(name: &str) -> Option<Outcome> {
        Outcome::ALL.into_iter().find(|o| o.as_str() == name)
    }

    /// Every outcome's words, for an error message (equal to [`Outcome::allowed`]).
    pub const ALLOWED: &'static str = "\"reached\", \"energy exhausted\" or \"time up\"";

    /// Every outcome's words, for an error message: `"reached", "energy exhausted" or "time up"`.
    pub fn allowed() -> String {
        let names: Vec<String> = Outcome::ALL
            .iter()
            .map(|o| format!("{:?}", o.as_str()))
            .collect();
        match names.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
            _ => names.join(""),
        }
    }
}

impl std::fmt::Display for Outcome {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for Outcome {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl<'de> Deserialize<'de> for Outcome {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        Outcome::parse(&name).ok_or_else(|| {
            serde::de::Error::custom(format!(
                "invalid outcome {name:?}: allowed {}",
                Outcome::allowed()
            ))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_outcome_reads_back_from_its_words() {
        for o in Outcome::ALL {
            assert_eq!(Outcome::parse(o.as_str()), Some(o));
            let json = serde_json::to_string(&o).unwrap();
            assert_eq!(serde_json::from_str::<Outcome>(&json).unwrap(), o);
        }
        assert_eq!(Outcome::allowed(), Outcome::ALLOWED);
        assert!(serde_json::from_str::<Outcome>("\"arrived\"").is_err());
    }
}
