//! Built-in policies and the registry that names them.

mod adaptive;
mod optimal;
mod pulse;
mod reflex;
mod sweep;
mod wave;

pub use adaptive::{Adaptive, AdaptiveOptions};
pub use optimal::Optimal;
pub use reflex::{Reflex, ReflexOptions};
pub use sweep::Sweep;
pub use wave::FixedWave;

use crate::controller::{Context, Controller};

/// Builds a controller from the context, or says why it cannot.
pub type Factory = fn(&Context) -> anyhow::Result<Box<dyn Controller>>;

/// Every policy: name, one-line help, factory. Add a line here to register a new controller.
pub const REGISTRY: &[(&str, &str, Factory)] = &[
    (
        "optimal",
        "the constrained optimal open-loop wave (max V s.t. mileage, stress, strain, f0)",
        optimal::build,
    ),
    (
        "wave",
        "a fixed travelling wave (f0, k, omega from flags or the scenario)",
        wave::build,
    ),
    (
        "resonance",
        "omega = omega_n for the given k",
        wave::build_resonance,
    ),
    (
        "sweep",
        "a schedule of waves: --sweep ALPHA,ALPHA,... held --dwell seconds each",
        sweep::build,
    ),
    (
        "adaptive",
        "the optimum re-solved in flight with the friction estimated from the plant's state",
        adaptive::build,
    ),
    (
        "reflex",
        "distributed: coupled phase oscillators per segment with local stick, energy and stress reflexes",
        reflex::build,
    ),
    (
        "pulse",
        "the scenario's wave, on and off every second",
        pulse::build,
    ),
];

/// The factory registered as `name`, or an error naming the policies there are.
pub fn lookup(name: &str) -> anyhow::Result<Factory> {
    match REGISTRY.iter().find(|(n, _, _)| *n == name) {
        Some((_, _, factory)) => Ok(*factory),
        None => anyhow::bail!(
            "unknown policy {name:?}: allowed {}",
            REGISTRY
                .iter()
                .map(|(n, _, _)| *n)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The controller registered as `name`.
pub fn build(name: &str, ctx: &Context) -> anyhow::Result<Box<dyn Controller>> {
    lookup(name)?(ctx)
}
