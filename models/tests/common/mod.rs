//! Shared test helpers.

use serde::de::{self, Deserialize, Deserializer, MapAccess, SeqAccess, Visitor};
use serde::Serialize;

/// Counts the floats in `value` and fails on the first that is not finite.
///
/// JSON cannot show the failure: serde_json writes NaN and infinities as `null`, the same as
/// `None`. So the value is encoded as MessagePack, which keeps every float as it is, and walked
/// back generically.
pub fn finite_floats<T: Serialize>(value: &T) -> Result<usize, String> {
    let bytes = rmp_serde::to_vec_named(value).map_err(|e| e.to_string())?;
    rmp_serde::from_slice::<Scan>(&bytes)
        .map(|s| s.0)
        .map_err(|e| e.to_string())
}

/// The number of floats in a value, all finite.
struct Scan(usize);

impl<'de> Deserialize<'de> for Scan {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(ScanVisitor)
    }
}

struct ScanVisitor;

impl<'de> Visitor<'de> for ScanVisitor {
    type Value = Scan;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("any value")
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Scan, E> {
        if v.is_finite() {
            Ok(Scan(1))
        } else {
            Err(E::custom(format!("a non-finite float: {v}")))
        }
    }

    fn visit_f32<E: de::Error>(self, v: f32) -> Result<Scan, E> {
        self.visit_f64(f64::from(v))
    }

    fn visit_bool<E>(self, _: bool) -> Result<Scan, E> {
        Ok(Scan(0))
    }

    fn visit_i64<E>(self, _: i64) -> Result<Scan, E> {
        Ok(Scan(0))
    }

    fn visit_u64<E>(self, _: u64) -> Result<Scan, E> {
        Ok(Scan(0))
    }

    fn visit_str<E>(self, _: &str) -> Result<Scan, E> {
        Ok(Scan(0))
    }

    fn visit_bytes<E>(self, _: &[u8]) -> Result<Scan, E> {
        Ok(Scan(0))
    }

    fn visit_unit<E>(self) -> Result<Scan, E> {
        Ok(Scan(0))
    }

    fn visit_none<E>(self) -> Result<Scan, E> {
        Ok(Scan(0))
    }

    fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<Scan, D::Error> {
        Scan::deserialize(d)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Scan, A::Error> {
        let mut n = 0;
        while let Some(Scan(k)) = seq.next_element()? {
            n += k;
        }
        Ok(Scan(n))
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Scan, A::Error> {
        let mut n = 0;
        while let Some((Scan(a), Scan(b))) = map.next_entry()? {
            n += a + b;
        }
        Ok(Scan(n))
    }
}
