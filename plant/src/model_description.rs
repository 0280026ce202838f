//! The plant's variables by value reference, modelled on an FMI 3.0 model description.

use serde::Serialize;

use crate::params::PlantParams;

/// FMI 3.0 causality.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "camelCase")]
pub enum Causality {
    /// The independent variable (time).
    Independent,
    /// Fixed at instantiation (array sizes, domain length).
    StructuralParameter,
    /// Set before the simulation starts.
    Parameter,
    /// Computed from parameters.
    CalculatedParameter,
    /// Set by the importer during the simulation.
    Input,
    /// Computed by the plant.
    Output,
}

/// FMI 3.0 variability.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "camelCase")]
pub enum Variability {
    /// Never changes after initialisation.
    Fixed,
    /// Changes only at communication points.
    Discrete,
    /// Changes continuously.
    Continuous,
}

/// FMI 3.0 variable type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum VarType {
    /// 64-bit float.
    Float64,
    /// 64-bit unsigned integer.
    UInt64,
    /// Boolean.
    Boolean,
}

/// One variable.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Variable {
    /// Name, unique.
    pub name: &'static str,
    /// Value reference, unique.
    pub value_reference: u32,
    /// Type.
    #[serde(rename = "type")]
    pub var_type: VarType,
    /// Causality.
    pub causality: Causality,
    /// Variability.
    pub variability: Variability,
    /// SI unit, empty if dimensionless.
    pub unit: &'static str,
    /// Start value (scalars), if any.
    pub start: Option<f64>,
    /// Array length (the number of cells), `None` for scalars.
    pub size: Option<usize>,
    /// What it is.
    pub description: &'static str,
}

/// Value references, stable across versions.
pub mod vr {
    /// Simulation time, s.
    pub const TIME: u32 = 0;
    /// Number of cells N.
    pub const CELLS: u32 = 1;
    /// Body length L, m.
    pub const LENGTH: u32 = 2;
    /// Cross-section A_c, m^2.
    pub const AREA: u32 = 10;
    /// Linear density, kg/m.
    pub const DENSITY: u32 = 11;
    /// Young's modulus, Pa.
    pub const YOUNGS_MODULUS: u32 = 12;
    /// Viscous coefficient, N s/m^2.
    pub const VISCOUS: u32 = 13;
    /// Normal load per length, N/m.
    pub const DRY: u32 = 14;
    /// Dry friction coefficient.
    pub const EPS: u32 = 15;
    /// Friction asymmetry n_F.
    pub const N_F: u32 = 16;
    /// Courant bound.
    pub const COURANT: u32 = 17;
    /// Communication step H, s.
    pub const STEP: u32 = 18;
    /// Settle time, s.
    pub const SETTLE: u32 = 19;
    /// Shortest counted stick phase, in forcing periods.
    pub const MIN_STICK: u32 = 20;
    /// Averaging block for field actuation, s.
    pub const BLOCK: u32 = 21;
    /// Internal step dt, s.
    pub const DT: u32 = 30;
    /// Internal steps per communication step.
    pub const SUBSTEPS: u32 = 31;
    /// Cell size dx, m.
    pub const DX: u32 = 32;
    /// Wave speed c, m/s.
    pub const WAVE_SPEED: u32 = 33;
    /// Actuation mode: 0 none, 1 travelling wave, 2 muscle-force field.
    pub const ACTUATION_MODE: u32 = 100;
    /// Wave amplitude f0, N.
    pub const WAVE_F0: u32 = 101;
    /// Wave number k, rad/m.
    pub const WAVE_K: u32 = 102;
    /// Wave angular frequency omega, rad/s.
    pub const WAVE_OMEGA: u32 = 103;
    /// Wave phase, rad.
    pub const WAVE_PHASE: u32 = 104;
    /// Muscle-force field at half nodes, N (array).
    pub const MUSCLE_FORCE: u32 = 105;
    /// Displacement, m (array).
    pub const U: u32 = 200;
    /// Velocity, m/s (array).
    pub const V: u32 = 201;
    /// Tension, N (array).
    pub const TENSION: u32 = 202;
    /// Stuck mask (array).
    pub const STUCK: u32 = 203;
    /// Mean speed over the last step, m/s.
    pub const MEAN_SPEED: u32 = 204;
    /// Input power over the last step, W.
    pub const INPUT_POWER: u32 = 205;
    /// Stuck nodes at the end of the last step.
    pub const STUCK_NODES: u32 = 206;
    /// Steady mean speed V, m/s.
    pub const VELOCITY: u32 = 210;
    /// Steady input power P, W.
    pub const POWER: u32 = 211;
    /// Steady mileage, m/J.
    pub const MILEAGE: u32 = 212;
    /// Steady max stress, Pa.
    pub const MAX_STRESS: u32 = 213;
    /// Steady max strain.
    pub const MAX_STRAIN: u32 = 214;
    /// Steady stuck fraction.
    pub const STUCK_FRACTION: u32 = 215;
    /// Steady mean friction selection.
    pub const MEAN_FRICTION_SELECTION: u32 = 216;
    /// Forcing periods in the steady window.
    pub const STEADY_PERIODS: u32 = 217;
    /// Episodes per node per period in the steady window.
    pub const EPISODE_RATE: u32 = 218;
}

/// The model description of a plant instance.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct ModelDescription {
    /// FMI version the description follows.
    pub fmi_version: &'static str,
    /// Model name.
    pub model_name: &'static str,
    /// Instantiation token.
    pub instantiation_token: String,
    /// Description.
    pub description: &'static str,
    /// Default communication step, s.
    pub fixed_internal_step_size: f64,
    /// Supports get/set/serialize of the state.
    pub can_get_and_set_fmu_state: bool,
    /// Supports serialization of the state.
    pub can_serialize_fmu_state: bool,
    /// The variables.
    pub variables: Vec<Variable>,
}

impl ModelDescription {
    /// The description for a plant with `params`.
    pub fn new(params: &PlantParams) -> Self {
        use Causality::*;
        use VarType::*;
        use Variability::*;
        let n = params.numerics.cells;
        let f = params.friction;
        let b = params.body;
        let nm = params.numerics;
        let scalar =
            |name, value_reference, var_type, causality, variability, unit, start, description| {
                Variable {
                    name,
                    value_reference,
                    var_type,
                    causality,
                    variability,
                    unit,
                    start,
                    size: None,
                    description,
                }
            };
        let array = |name, value_reference, var_type, causality, unit, description| Variable {
            name,
            value_reference,
            var_type,
            causality,
            variability: Discrete,
            unit,
            start: None,
            size: Some(n),
            description,
        };
        let variables = vec![
            scalar(
                "time",
                vr::TIME,
                Float64,
                Independent,
                Continuous,
                "s",
                None,
                "Simulation time",
            ),
            scalar(
                "cells",
                vr::CELLS,
                UInt64,
                StructuralParameter,
                Fixed,
                "",
                Some(n as f64),
                "Number of cells N on the periodic body",
            ),
            scalar(
                "length",
                vr::LENGTH,
                Float64,
                StructuralParameter,
                Fixed,
                "m",
                Some(params.length),
                "Body length L (periodic domain)",
            ),
            scalar(
                "area",
                vr::AREA,
                Float64,
                Parameter,
                Fixed,
                "m2",
                Some(b.area),
                "Cross-sectional area A_c",
            ),
            scalar(
                "density",
                vr::DENSITY,
                Float64,
                Parameter,
                Fixed,
                "kg/m",
                Some(b.density),
                "Linear mass density rho",
            ),
            scalar(
                "youngs_modulus",
                vr::YOUNGS_MODULUS,
                Float64,
                Parameter,
                Fixed,
                "Pa",
                Some(b.youngs_modulus),
                "Young's modulus E",
            ),
            scalar(
                "viscous",
                vr::VISCOUS,
                Float64,
                Parameter,
                Fixed,
                "N.s/m2",
                Some(f.viscous),
                "Viscous friction coefficient c_v",
            ),
            scalar(
                "dry",
                vr::DRY,
                Float64,
                Parameter,
                Fixed,
                "N/m",
                Some(f.dry),
                "Normal load per unit length c_d",
            ),
            scalar(
                "eps",
                vr::EPS,
                Float64,
                Parameter,
                Fixed,
                "",
                Some(f.eps),
                "Dry friction coefficient eps",
            ),
            scalar(
                "n_f",
                vr::N_F,
                Float64,
                Parameter,
                Fixed,
                "",
                Some(f.n_f),
                "Friction asymmetry n_F in [0, 1]",
            ),
            scalar(
                "courant",
                vr::COURANT,
                Float64,
                Parameter,
                Fixed,
                "",
                Some(nm.courant),
                "Upper bound of the Courant number c dt/dx",
            ),
            scalar(
                "step",
                vr::STEP,
                Float64,
                Parameter,
                Fixed,
                "s",
                Some(nm.step),
                "Communication step H",
            ),
            scalar(
                "settle",
                vr::SETTLE,
                Float64,
                Parameter,
                Fixed,
                "s",
                Some(nm.settle),
                "Transient skipped before steady averaging",
            ),
            scalar(
                "min_stick_periods",
                vr::MIN_STICK,
                Float64,
                Parameter,
                Fixed,
                "",
                Some(nm.min_stick_periods),
                "Shortest stick phase counted as an episode, in periods of the applied wave",
            ),
            scalar(
                "block",
                vr::BLOCK,
                Float64,
                Parameter,
                Fixed,
                "s",
                Some(nm.block),
                "Averaging block under field actuation",
            ),
            scalar(
                "dt",
                vr::DT,
                Float64,
                CalculatedParameter,
                Fixed,
                "s",
                None,
                "Internal time step",
            ),
            scalar(
                "substeps",
                vr::SUBSTEPS,
                UInt64,
                CalculatedParameter,
                Fixed,
                "",
                None,
                "Internal steps per communication step",
            ),
            scalar(
                "dx",
                vr::DX,
                Float64,
                CalculatedParameter,
                Fixed,
                "m",
                None,
                "Cell size L/N",
            ),
            scalar(
                "wave_speed",
                vr::WAVE_SPEED,
                Float64,
                CalculatedParameter,
                Fixed,
                "m/s",
                None,
                "Wave speed sqrt(A_c E / rho)",
            ),
            scalar(
                "actuation_mode",
                vr::ACTUATION_MODE,
                UInt64,
                Input,
                Discrete,
                "",
                Some(0.0),
                "0 none, 1 travelling wave, 2 muscle-force field",
            ),
            scalar(
                "wave_f0",
                vr::WAVE_F0,
                Float64,
                Input,
                Discrete,
                "N",
                Some(0.0),
                "Travelling-wave amplitude f0",
            ),
            scalar(
                "wave_k",
                vr::WAVE_K,
                Float64,
                Input,
                Discrete,
                "rad/m",
                None,
                "Travelling-wave number k (must fit L a whole number of times)",
            ),
            scalar(
                "wave_omega",
                vr::WAVE_OMEGA,
                Float64,
                Input,
                Discrete,
                "rad/s",
                None,
                "Travelling-wave angular frequency",
            ),
            scalar(
                "wave_phase",
                vr::WAVE_PHASE,
                Float64,
                Input,
                Discrete,
                "rad",
                Some(0.0),
                "Travelling-wave phase",
            ),
            array(
                "muscle_force",
                vr::MUSCLE_FORCE,
                Float64,
                Input,
                "N",
                "Muscle force A_m f at the half nodes (i + 1/2) dx, held over the step",
            ),
            array(
                "u",
                vr::U,
                Float64,
                Output,
                "m",
                "Displacement at the nodes i dx",
            ),
            array(
                "v",
                vr::V,
                Float64,
                Output,
                "m/s",
                "Velocity at the nodes over the last internal step",
            ),
            array(
                "tension",
                vr::TENSION,
                Float64,
                Output,
                "N",
                "Tension A_c E u_x + A_m f at the half nodes",
            ),
            array(
                "stuck",
                vr::STUCK,
                Boolean,
                Output,
                "",
                "Nodes held by static friction",
            ),
            scalar(
                "mean_speed",
                vr::MEAN_SPEED,
                Float64,
                Output,
                Discrete,
                "m/s",
                None,
                "Mean speed of the body over the last step",
            ),
            scalar(
                "input_power",
                vr::INPUT_POWER,
                Float64,
                Output,
                Discrete,
                "W",
                None,
                "Actuator input power over the last step",
            ),
            scalar(
                "stuck_nodes",
                vr::STUCK_NODES,
                UInt64,
                Output,
                Discrete,
                "",
                None,
                "Nodes stuck at the end of the last step",
            ),
            scalar(
                "velocity",
                vr::VELOCITY,
                Float64,
                Output,
                Discrete,
                "m/s",
                None,
                "Steady mean speed V (eq. 5) over whole periods",
            ),
            scalar(
                "power",
                vr::POWER,
                Float64,
                Output,
                Discrete,
                "W",
                None,
                "Steady input power P (eq. 7) over the body",
            ),
            scalar(
                "mileage",
                vr::MILEAGE,
                Float64,
                Output,
                Discrete,
                "m/J",
                None,
                "Steady mileage |V|/P",
            ),
            scalar(
                "max_stress",
                vr::MAX_STRESS,
                Float64,
                Output,
                Discrete,
                "Pa",
                None,
                "Steady sup T / A_c (eq. 4) over whole periods",
            ),
            scalar(
                "max_strain",
                vr::MAX_STRAIN,
                Float64,
                Output,
                Discrete,
                "",
                None,
                "Steady max |u_x|",
            ),
            scalar(
                "stuck_fraction",
                vr::STUCK_FRACTION,
                Float64,
                Output,
                Discrete,
                "",
                None,
                "Steady share of node-time stuck",
            ),
            scalar(
                "mean_friction_selection",
                vr::MEAN_FRICTION_SELECTION,
                Float64,
                Output,
                Discrete,
                "",
                None,
                "Steady space-time mean of s",
            ),
            scalar(
                "steady_periods",
                vr::STEADY_PERIODS,
                Float64,
                Output,
                Discrete,
                "",
                None,
                "Forcing periods in the steady window",
            ),
            scalar(
                "episode_rate",
                vr::EPISODE_RATE,
                Float64,
                Output,
                Discrete,
                "",
                None,
                "Stick-slip episodes per node per period (steady)",
            ),
        ];
        Self {
            fmi_version: "3.0",
            model_name: "crawler-plant",
            instantiation_token: format!("{{crawler-plant-{}-{n}}}", env!("CARGO_PKG_VERSION")),
            description: "Soft peristaltic crawler: nonlinear wave equation with asymmetric Coulomb + viscous friction and exact stick",
            fixed_internal_step_size: nm.step,
            can_get_and_set_fmu_state: true,
            can_serialize_fmu_state: true,
            variables,
        }
    }

    /// The variable with value reference `vr`.
    pub fn variable(&self, vr: u32) -> Option<&Variable> {
        self.variables.iter().find(|v| v.value_reference == vr)
    }

    /// JSON text of the description.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("model description serializes")
    }

    /// An FMI 3.0 style `modelDescription.xml`.
    pub fn to_xml(&self) -> String {
        let mut x = String::new();
        x.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        x.push_str(&format!(
            "<fmiModelDescription fmiVersion=\"{}\" modelName=\"{}\" instantiationToken=\"{}\" description=\"{}\">\n",
            self.fmi_version,
            self.model_name,
            xml_escape(&self.instantiation_token),
            xml_escape(self.description)
        ));
        x.push_str(&format!(
            "  <CoSimulation modelIdentifier=\"crawler_plant\" canGetAndSetFMUState=\"true\" canSerializeFMUState=\"true\" fixedInternalStepSize=\"{}\" hasEventMode=\"false\"/>\n",
            self.fixed_internal_step_size
        ));
        x.push_str("  <UnitDefinitions>\n");
        let mut units: Vec<&str> = self
            .variables
            .iter()
            .map(|v| v.unit)
            .filter(|u| !u.is_empty())
            .collect();
        units.sort_unstable();
        units.dedup();
        for u in units {
            x.push_str(&format!("    <Unit name=\"{}\"/>\n", xml_escape(u)));
        }
        x.push_str("  </UnitDefinitions>\n  <ModelVariables>\n");
        for v in &self.variables {
            let tag = match v.var_type {
                VarType::Float64 => "Float64",
                VarType::UInt64 => "UInt64",
                VarType::Boolean => "Boolean",
            };
            let causality = serde_json::to_value(v.causality).unwrap();
            let variability = serde_json::to_value(v.variability).unwrap();
            x.push_str(&format!(
                "    <{tag} name=\"{}\" valueReference=\"{}\" causality=\"{}\" variability=\"{}\"",
                v.name,
                v.value_reference,
                causality.as_str().unwrap(),
                variability.as_str().unwrap()
            ));
            if !v.unit.is_empty() {
                x.push_str(&format!(" unit=\"{}\"", xml_escape(v.unit)));
            }
            if let Some(s) = v.start {
                if v.size.is_none() {
                    match v.var_type {
                        VarType::Float64 => x.push_str(&format!(" start=\"{s:e}\"")),
                        _ => x.push_str(&format!(" start=\"{}\"", s as u64)),
                    }
                }
            }
            x.push_str(&format!(" description=\"{}\"", xml_escape(v.description)));
            match v.size {
                Some(_) => x.push_str(&format!(
                    ">\n      <Dimension valueReference=\"{}\"/>\n    </{tag}>\n",
                    vr::CELLS
                )),
                None => x.push_str("/>\n"),
            }
        }
        x.push_str("  </ModelVariables>\n  <ModelStructure>\n");
        for v in self
            .variables
            .iter()
            .filter(|v| v.causality == Causality::Output)
        {
            x.push_str(&format!(
                "    <Output valueReference=\"{}\"/>\n",
                v.value_reference
            ));
        }
        x.push_str("  </ModelStructure>\n</fmiModelDescription>\n");
        x
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
