//! What an FMU instance starts with: the paper scenario, as the `crawler-plant` program.
//!
//! The model description written into the `.fmu` ([`model_description`]) and the instances the
//! library creates ([`slave`]) both come from [`scenario`], so their start values agree.

use crawler_physics::model_description::ModelDescription;
use crawler_physics::scenario::Scenario;
use crawler_physics::slave::{Slave, SlaveError};

/// The scenario whose parameters and wave are the FMU's defaults (`scenarios/paper.toml`,
/// embedded in the library).
pub fn scenario() -> Scenario {
    Scenario::paper()
}

/// The model description of the FMU: the scenario's parameters and N, driven by its wave
/// unless the importer sets other inputs, a default experiment to its `t_end` (rounded up to
/// whole communication steps) in steps of H.
pub fn model_description() -> ModelDescription {
    let s = scenario();
    ModelDescription::for_run(&s.plant, s.wave, s.t_end)
}

/// A new slave with the defaults, named `name`.
pub fn slave(name: &str) -> Result<Slave, SlaveError> {
    let s = scenario();
    Slave::instantiate_with_wave(name, s.plant, s.wave)
}
