//! A policy's parameters: `key=value` settings (`--param key=value` on the command line, a sweep
//! plan's `[evaluate] params`, keyword arguments in Python), read by the policy itself.
//!
//! Each policy lists the keys it takes ([`Key`]) and reads them through a [`Reader`], which
//! refuses a value that is not of the key's kind and, when the policy is done, any key the
//! policy does not take, naming the keys it does.

use std::cell::RefCell;

/// A parameter a policy takes: its key, what kind of value, and what it means (with its unit
/// and default).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Key {
    /// The key.
    pub name: &'static str,
    /// What it is, with its unit, its range and its default.
    pub doc: &'static str,
}

/// The `key=value` settings given to a policy, in order (a later setting of a key wins).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Params {
    entries: Vec<(String, String)>,
}

impl Params {
    /// No settings.
    pub fn none() -> Self {
        Self::default()
    }

    /// Settings from `key=value` strings; an item without `=` or with an empty key is refused.
    pub fn parse<S: AsRef<str>>(items: &[S]) -> anyhow::Result<Self> {
        let mut entries = Vec::with_capacity(items.len());
        for item in items {
            let item = item.as_ref();
            let (k, v) = item
                .split_once('=')
                .ok_or_else(|| anyhow::anyhow!("invalid --param {item:?}: allowed KEY=VALUE"))?;
            let (k, v) = (k.trim(), v.trim());
            anyhow::ensure!(
                !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'),
                "invalid --param {item:?}: allowed KEY=VALUE with a KEY of letters, digits and _"
            );
            entries.push((k.to_string(), v.to_string()));
        }
        Ok(Self { entries })
    }

    /// Settings from `(key, value)` pairs.
    pub fn from_pairs<K: Into<String>, V: Into<String>>(
        pairs: impl IntoIterator<Item = (K, V)>,
    ) -> Self {
        Self {
            entries: pairs
                .into_iter()
                .map(|(k, v)| (k.into(), v.into()))
                .collect(),
        }
    }

    /// The settings as `key=value` strings (what [`Params::parse`] reads back).
    pub fn to_strings(&self) -> Vec<String> {
        self.entries
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect()
    }

    /// True if there are none.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// A reader for the policy `policy`, which takes `keys`.
    pub fn reader<'a>(&'a self, policy: &'a str, keys: &'a [Key]) -> Reader<'a> {
        Reader {
            params: self,
            policy,
            keys,
            used: RefCell::new(vec![false; self.entries.len()]),
        }
    }
}

/// Reads a policy's parameters, remembering which were read.
#[derive(Debug)]
pub struct Reader<'a> {
    params: &'a Params,
    policy: &'a str,
    keys: &'a [Key],
    used: RefCell<Vec<bool>>,
}

impl Reader<'_> {
    /// The raw value of `key` (the last setting), marking every setting of it read.
    fn raw(&self, key: &str) -> Option<&str> {
        debug_assert!(
            self.keys.iter().any(|k| k.name == key),
            "policy {} reads {key} without listing it",
            self.policy
        );
        let mut used = self.used.borrow_mut();
        let mut value = None;
        for (i, (k, v)) in self.params.entries.iter().enumerate() {
            if k == key {
                used[i] = true;
                value = Some(v.as_str());
            }
        }
        value
    }

    fn invalid(&self, key: &str, value: &str, allowed: &str) -> anyhow::Error {
        anyhow::anyhow!(
            "invalid parameter {key} = {value:?} of policy {}: allowed {allowed}",
            self.policy
        )
    }

    /// The number `key`, if given: finite and within `[min, max]`.
    pub fn number(&self, key: &str, min: f64, max: f64) -> anyhow::Result<Option<f64>> {
        let Some(v) = self.raw(key) else {
            return Ok(None);
        };
        let allowed = || format!("a number from {min} to {max}");
        let x: f64 = v.parse().map_err(|_| self.invalid(key, v, &allowed()))?;
        if !(x.is_finite() && (min..=max).contains(&x)) {
            return Err(self.invalid(key, v, &allowed()));
        }
        Ok(Some(x))
    }

    /// The number `key`, if given: any finite number (the policy checks its range).
    pub fn finite(&self, key: &str) -> anyhow::Result<Option<f64>> {
        let Some(v) = self.raw(key) else {
            return Ok(None);
        };
        match v.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(Some(x)),
            _ => Err(self.invalid(key, v, "a finite number")),
        }
    }

    /// Every listed key given as a finite number, in the order of the keys: for policies that
    /// set their options one number at a time.
    pub fn finite_all(&self) -> anyhow::Result<Vec<(&'static str, f64)>> {
        let mut out = Vec::new();
        for k in self.keys {
            if let Some(x) = self.finite(k.name)? {
                out.push((k.name, x));
            }
        }
        Ok(out)
    }

    /// The whole number `key`, if given, within `[min, max]`.
    pub fn count(&self, key: &str, min: usize, max: usize) -> anyhow::Result<Option<usize>> {
        let Some(v) = self.raw(key) else {
            return Ok(None);
        };
        let allowed = || format!("a whole number from {min} to {max}");
        let n: usize = v.parse().map_err(|_| self.invalid(key, v, &allowed()))?;
        if !(min..=max).contains(&n) {
            return Err(self.invalid(key, v, &allowed()));
        }
        Ok(Some(n))
    }

    /// The switch `key`, if given: `true` or `false`.
    pub fn switch(&self, key: &str) -> anyhow::Result<Option<bool>> {
        match self.raw(key) {
            None => Ok(None),
            Some("true") => Ok(Some(true)),
            Some("false") => Ok(Some(false)),
            Some(v) => Err(self.invalid(key, v, "true or false")),
        }
    }

    /// The word `key`, if given: one of `allowed`.
    pub fn word(
        &self,
        key: &str,
        allowed: &[&'static str],
    ) -> anyhow::Result<Option<&'static str>> {
        let Some(v) = self.raw(key) else {
            return Ok(None);
        };
        allowed
            .iter()
            .find(|a| **a == v)
            .copied()
            .map(Some)
            .ok_or_else(|| self.invalid(key, v, &allowed.join(" or ")))
    }

    /// The list of numbers `key` (separated by commas), if given: at least one, each finite and
    /// within `[min, max]`.
    pub fn numbers(&self, key: &str, min: f64, max: f64) -> anyhow::Result<Option<Vec<f64>>> {
        let Some(v) = self.raw(key) else {
            return Ok(None);
        };
        let allowed = || format!("numbers from {min} to {max}, separated by commas");
        let xs = v
            .split(',')
            .map(|s| s.trim().parse::<f64>())
            .collect::<Result<Vec<_>, _>>()
            .map_err(|_| self.invalid(key, v, &allowed()))?;
        if xs.is_empty()
            || xs
                .iter()
                .any(|x| !(x.is_finite() && (min..=max).contains(x)))
        {
            return Err(self.invalid(key, v, &allowed()));
        }
        Ok(Some(xs))
    }

    /// Refuses any setting the policy did not read, naming the keys it takes (a setting of a
    /// listed key counts as read).
    pub fn finish(self) -> anyhow::Result<()> {
        for k in self.keys {
            self.raw(k.name);
        }
        let used = self.used.borrow();
        if let Some((k, _)) = self
            .params
            .entries
            .iter()
            .zip(used.iter())
            .find(|(_, used)| !**used)
            .map(|(e, _)| e)
        {
            let takes = if self.keys.is_empty() {
                "none".to_string()
            } else {
                self.keys
                    .iter()
                    .map(|k| k.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            anyhow::bail!(
                "unknown parameter {k:?} for policy {}: it takes {takes}",
                self.policy
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEYS: [Key; 3] = [
        Key {
            name: "gain",
            doc: "a gain",
        },
        Key {
            name: "grid",
            doc: "points",
        },
        Key {
            name: "model",
            doc: "paper or improved",
        },
    ];

    #[test]
    fn a_policy_reads_its_parameters_by_kind_and_range() {
        let p = Params::parse(&["gain=0.5", "grid=48", "model=paper", "gain=0.25"]).unwrap();
        let r = p.reader("test", &KEYS);
        assert_eq!(r.number("gain", 0.0, 1.0).unwrap(), Some(0.25));
        assert_eq!(r.count("grid", 2, 1000).unwrap(), Some(48));
        assert_eq!(
            r.word("model", &["paper", "improved"]).unwrap(),
            Some("paper")
        );
        r.finish().unwrap();
    }

    #[test]
    fn a_bad_value_is_refused_naming_the_key_the_value_and_what_is_allowed() {
        let p = Params::parse(&["gain=2", "grid=x"]).unwrap();
        let r = p.reader("test", &KEYS);
        let e = r.number("gain", 0.0, 1.0).unwrap_err().to_string();
        assert_eq!(
            e,
            "invalid parameter gain = \"2\" of policy test: allowed a number from 0 to 1"
        );
        let e = r.count("grid", 2, 1000).unwrap_err().to_string();
        assert!(
            e.contains("grid = \"x\"") && e.contains("a whole number from 2 to 1000"),
            "{e}"
        );
        let p = Params::parse(&["gain=NaN"]).unwrap();
        assert!(p.reader("test", &KEYS).number("gain", 0.0, 1.0).is_err());
    }

    #[test]
    fn an_unknown_key_is_refused_naming_the_keys_the_policy_takes() {
        let p = Params::parse(&["gian=0.5"]).unwrap();
        let r = p.reader("test", &KEYS);
        assert_eq!(r.number("gain", 0.0, 1.0).unwrap(), None);
        let e = r.finish().unwrap_err().to_string();
        assert_eq!(
            e,
            "unknown parameter \"gian\" for policy test: it takes gain, grid, model"
        );
        assert!(Params::parse(&["no-equals"]).is_err());
        assert!(Params::parse(&["=1"]).is_err());
    }
}
