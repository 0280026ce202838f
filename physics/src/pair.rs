//! Two numbers read strictly: `[a, b]` in a scenario file or a message is exactly two numbers
//! (serde's fixed-size arrays would take the first two of a longer list and drop the rest).

use serde::de::Error;
use serde::{Deserialize, Deserializer};

/// `[a, b]`, refusing a list of any other length.
pub fn pair<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    exactly_two::<D>(Vec::deserialize(d)?)
}

/// An optional `[a, b]`, as [`pair`].
pub fn optional_pair<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 2]>, D::Error> {
    Option::<Vec<f64>>::deserialize(d)?
        .map(exactly_two::<D>)
        .transpose()
}

fn exactly_two<'de, D: Deserializer<'de>>(v: Vec<f64>) -> Result<[f64; 2], D::Error> {
    <[f64; 2]>::try_from(v.as_slice())
        .map_err(|_| D::Error::invalid_length(v.len(), &"two numbers [a, b]"))
}
