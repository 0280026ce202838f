//! The registry that names every policy.

use crate::params::{Key, Params};
use crate::policy::{Context, Policy};

/// Builds a policy from the context and its parameters, or says why it cannot.
pub type Factory = fn(&Context, &Params) -> anyhow::Result<Box<dyn Policy>>;

/// A registered policy.
#[derive(Debug, Clone, Copy)]
pub struct Entry {
    /// Its name (`--policy NAME`).
    pub name: &'static str,
    /// What it does, in one line.
    pub help: &'static str,
    /// The parameters it takes (`--param KEY=VALUE`).
    pub keys: &'static [Key],
    /// Its factory.
    pub build: Factory,
    /// Checks its parameters without building it (building may run the plant); `None`: only
    /// that every key given is one of `keys`.
    pub check: Option<fn(&Params) -> anyhow::Result<()>>,
}

/// Every policy. Add a line here to register a new one.
pub const REGISTRY: &[Entry] = &[
    Entry {
        name: "optimal",
        help: "the constrained optimal open-loop wave (max V s.t. mileage, stress, strain, f0)",
        keys: &crate::optimal::KEYS,
        build: crate::optimal::build,
        check: Some(|p| crate::optimal::OptimalOptions::from_params(p).map(|_| ())),
    },
    Entry {
        name: "wave",
        help: "the scenario's travelling wave (f0, k, omega or alpha from the scenario flags)",
        keys: &[],
        build: crate::wave::build,
        check: None,
    },
    Entry {
        name: "resonance",
        help: "the scenario's wave at omega = omega_n for its k",
        keys: &[],
        build: crate::wave::build_resonance,
        check: None,
    },
    Entry {
        name: "sweep",
        help: "a schedule of waves: the scenario's wave at each alpha in turn, dwell seconds each",
        keys: &crate::sweep::KEYS,
        build: crate::sweep::build,
        check: Some(crate::sweep::check),
    },
    Entry {
        name: "adaptive",
        help: "the optimum re-solved in flight with the friction estimated from the plant's state",
        keys: &crate::adaptive::KEYS,
        build: crate::adaptive::build,
        check: Some(|p| crate::adaptive::AdaptiveOptions::from_params(p).map(|_| ())),
    },
    Entry {
        name: "reflex",
        help: "distributed: coupled phase oscillators per segment with local stick, energy and stress reflexes",
        keys: &crate::reflex::KEYS,
        build: crate::reflex::build,
        check: Some(|p| crate::reflex::ReflexOptions::from_params(p).map(|_| ())),
    },
    Entry {
        name: "pulse",
        help: "the scenario's wave, on and off every second",
        keys: &[],
        build: crate::pulse::build,
        check: None,
    },
];

/// The policy registered as `name`, or an error naming the policies there are.
pub fn lookup(name: &str) -> anyhow::Result<&'static Entry> {
    REGISTRY.iter().find(|e| e.name == name).ok_or_else(|| {
        anyhow::anyhow!(
            "unknown policy {name:?}: allowed {}",
            REGISTRY
                .iter()
                .map(|e| e.name)
                .collect::<Vec<_>>()
                .join(", ")
        )
    })
}

/// Checks the parameters of the policy registered as `name` without building it.
pub fn check(name: &str, params: &Params) -> anyhow::Result<()> {
    let entry = lookup(name)?;
    match entry.check {
        Some(check) => check(params),
        None => params.reader(entry.name, entry.keys).finish(),
    }
}

/// The policy registered as `name`, built for `ctx` with `params` (every parameter read and
/// checked by the policy; one it does not take is refused).
pub fn build(name: &str, ctx: &Context, params: &Params) -> anyhow::Result<Box<dyn Policy>> {
    let entry = lookup(name)?;
    (entry.build)(ctx, params)
}
