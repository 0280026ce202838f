//! The plant's variables by value reference, and the FMI 2.0 and FMI 3.0 `modelDescription.xml`
//! generated from them.
//!
//! One list of variables ([`ModelDescription::variables`]) describes the plant in both FMI
//! versions. FMI 3.0 has arrays (`u` is one variable of `cells` values); FMI 2.0 has none, so
//! every array is written as scalars `u[1]`..`u[N]` at the description's fixed N, with value
//! references from [`fmi2_element_reference`]. Start values are those of the plant the
//! description is made for (its parameters, and the wave it is driven by by default), so a
//! description and the binary that implements it agree by construction.

use serde::Serialize;

use crate::params::{Boundary, PlantParams};
use crate::wave::Wave;

mod variables;

/// FMI causality.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "camelCase")]
pub enum Causality {
    /// The independent variable (time).
    Independent,
    /// Fixed at instantiation; in FMI 3.0 set only in Configuration Mode (array sizes, the kind
    /// of body). FMI 2.0 has no such causality: it is written as `parameter`.
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

/// FMI variability.
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

/// Variable type (FMI 3.0 names; FMI 2.0 writes Float64 as Real and UInt64 as Integer).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum VarType {
    /// 64-bit float.
    Float64,
    /// 64-bit unsigned integer (FMI 2.0: 32-bit `Integer`; every value here fits).
    UInt64,
    /// Boolean.
    Boolean,
    /// Text.
    String,
    /// One of the items of [`BOUNDARY_ITEMS`] (FMI 3.0: read and written as Int64; FMI 2.0: as
    /// Integer).
    Enumeration,
}

/// A start value.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Start {
    /// A Float64 (for an array: every element).
    Float(f64),
    /// A UInt64.
    UInt(u64),
    /// An enumeration item's value.
    Enum(i64),
    /// A string.
    Text(String),
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
    /// SI unit (a name from [`UNITS`]), empty if dimensionless.
    pub unit: &'static str,
    /// Start value (for an array: the value of every element), if any.
    pub start: Option<Start>,
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
    /// Periodic body or free ends (enumeration, [`super::BOUNDARY_ITEMS`]).
    pub const BOUNDARY: u32 = 3;
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
    /// Requested communication step, s.
    pub const STEP: u32 = 18;
    /// Settle time, s.
    pub const SETTLE: u32 = 19;
    /// Shortest counted stick phase, in forcing periods.
    pub const MIN_STICK: u32 = 20;
    /// Averaging block for field actuation, s.
    pub const BLOCK: u32 = 21;
    /// Grid filter strength.
    pub const FILTER: u32 = 22;
    /// The pipe (friction map along it) as JSON text.
    pub const PIPE: u32 = 23;
    /// Integer clock H must fit, ticks per second (0: the plant's own clock).
    pub const TICKS_PER_SECOND: u32 = 24;
    /// Internal step dt, s.
    pub const DT: u32 = 30;
    /// Internal steps per communication step.
    pub const SUBSTEPS: u32 = 31;
    /// Cell size dx, m.
    pub const DX: u32 = 32;
    /// Wave speed c, m/s.
    pub const WAVE_SPEED: u32 = 33;
    /// The communication step H actually used, s.
    pub const COMMUNICATION_STEP: u32 = 34;
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
    /// Displacement of the tail node (node 0), m.
    pub const TAIL_DISPLACEMENT: u32 = 207;
    /// Mean displacement of the nodes, m.
    pub const MEAN_DISPLACEMENT: u32 = 208;
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

/// Name and type of the variable with value reference `r` (without building a description;
/// the same as [`ModelDescription::variable`] gives, which a test checks).
pub fn variable_name(r: u32) -> Option<(&'static str, VarType)> {
    use VarType::*;
    Some(match r {
        vr::TIME => ("time", Float64),
        vr::CELLS => ("cells", UInt64),
        vr::LENGTH => ("length", Float64),
        vr::BOUNDARY => ("boundary", Enumeration),
        vr::AREA => ("area", Float64),
        vr::DENSITY => ("density", Float64),
        vr::YOUNGS_MODULUS => ("youngs_modulus", Float64),
        vr::VISCOUS => ("viscous", Float64),
        vr::DRY => ("dry", Float64),
        vr::EPS => ("eps", Float64),
        vr::N_F => ("n_f", Float64),
        vr::COURANT => ("courant", Float64),
        vr::STEP => ("step", Float64),
        vr::SETTLE => ("settle", Float64),
        vr::MIN_STICK => ("min_stick_periods", Float64),
        vr::BLOCK => ("block", Float64),
        vr::FILTER => ("filter", Float64),
        vr::PIPE => ("pipe", String),
        vr::TICKS_PER_SECOND => ("ticks_per_second", UInt64),
        vr::DT => ("dt", Float64),
        vr::SUBSTEPS => ("substeps", UInt64),
        vr::DX => ("dx", Float64),
        vr::WAVE_SPEED => ("wave_speed", Float64),
        vr::COMMUNICATION_STEP => ("communication_step", Float64),
        vr::ACTUATION_MODE => ("actuation_mode", UInt64),
        vr::WAVE_F0 => ("wave_f0", Float64),
        vr::WAVE_K => ("wave_k", Float64),
        vr::WAVE_OMEGA => ("wave_omega", Float64),
        vr::WAVE_PHASE => ("wave_phase", Float64),
        vr::MUSCLE_FORCE => ("muscle_force", Float64),
        vr::U => ("u", Float64),
        vr::V => ("v", Float64),
        vr::TENSION => ("tension", Float64),
        vr::STUCK => ("stuck", Boolean),
        vr::MEAN_SPEED => ("mean_speed", Float64),
        vr::INPUT_POWER => ("input_power", Float64),
        vr::STUCK_NODES => ("stuck_nodes", UInt64),
        vr::TAIL_DISPLACEMENT => ("tail_displacement", Float64),
        vr::MEAN_DISPLACEMENT => ("mean_displacement", Float64),
        vr::VELOCITY => ("velocity", Float64),
        vr::POWER => ("power", Float64),
        vr::MILEAGE => ("mileage", Float64),
        vr::MAX_STRESS => ("max_stress", Float64),
        vr::MAX_STRAIN => ("max_strain", Float64),
        vr::STUCK_FRACTION => ("stuck_fraction", Float64),
        vr::MEAN_FRICTION_SELECTION => ("mean_friction_selection", Float64),
        vr::STEADY_PERIODS => ("steady_periods", Float64),
        vr::EPISODE_RATE => ("episode_rate", Float64),
        _ => return None,
    })
}

/// True for the array variables (`cells` values each).
pub fn is_array(r: u32) -> bool {
    matches!(
        r,
        vr::MUSCLE_FORCE | vr::U | vr::V | vr::TENSION | vr::STUCK
    )
}

/// The items of the `boundary` enumeration: `(name, value, description)`.
pub const BOUNDARY_ITEMS: [(&str, i64, &str); 2] = [
    (
        "periodic",
        1,
        "the body is closed on itself (the paper's setting)",
    ),
    ("free", 2, "two free ends with zero tension"),
];

/// The enumeration value of a boundary.
pub fn boundary_value(b: Boundary) -> i64 {
    match b {
        Boundary::Periodic => 1,
        Boundary::Free => 2,
    }
}

/// The boundary of an enumeration value, if it is one.
pub fn boundary_of(value: i64) -> Option<Boundary> {
    match value {
        1 => Some(Boundary::Periodic),
        2 => Some(Boundary::Free),
        _ => None,
    }
}

/// Value references of FMI 2.0 array elements start here: element `i` (0-based) of the array
/// with value reference `a` has `a * FMI2_ARRAY_STRIDE + i` (no scalar reaches this range, and
/// `i < MAX_CELLS = FMI2_ARRAY_STRIDE`).
pub const FMI2_ARRAY_STRIDE: u32 = 1 << 20;

/// The FMI 2.0 value reference of element `i` (0-based) of the array `array`.
pub fn fmi2_element_reference(array: u32, i: usize) -> u32 {
    array * FMI2_ARRAY_STRIDE + i as u32
}

/// The array and 0-based element of an FMI 2.0 element reference (`None` for a scalar's).
pub fn fmi2_element_of(reference: u32) -> Option<(u32, usize)> {
    (reference >= FMI2_ARRAY_STRIDE).then_some((
        reference / FMI2_ARRAY_STRIDE,
        (reference % FMI2_ARRAY_STRIDE) as usize,
    ))
}

/// The SI units used, with their exponents of the base units `[kg, m, s, A, K, mol, cd, rad]`.
pub const UNITS: [(&str, [i8; 8]); 14] = [
    ("s", [0, 0, 1, 0, 0, 0, 0, 0]),
    ("m", [0, 1, 0, 0, 0, 0, 0, 0]),
    ("m2", [0, 2, 0, 0, 0, 0, 0, 0]),
    ("kg/m", [1, -1, 0, 0, 0, 0, 0, 0]),
    ("Pa", [1, -1, -2, 0, 0, 0, 0, 0]),
    ("N.s/m2", [1, -1, -1, 0, 0, 0, 0, 0]),
    ("N/m", [1, 0, -2, 0, 0, 0, 0, 0]),
    ("N", [1, 1, -2, 0, 0, 0, 0, 0]),
    ("m/s", [0, 1, -1, 0, 0, 0, 0, 0]),
    ("W", [1, 2, -3, 0, 0, 0, 0, 0]),
    ("m/J", [-1, -1, 2, 0, 0, 0, 0, 0]),
    ("rad", [0, 0, 0, 0, 0, 0, 0, 1]),
    ("rad/m", [0, -1, 0, 0, 0, 0, 0, 1]),
    ("rad/s", [0, 0, -1, 0, 0, 0, 0, 1]),
];

const BASE_UNITS: [&str; 8] = ["kg", "m", "s", "A", "K", "mol", "cd", "rad"];

/// The default run of an FMU: start and stop time and the communication step, s.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct DefaultExperiment {
    /// Start time, s.
    pub start_time: f64,
    /// Stop time: a whole number of communication steps, s.
    pub stop_time: f64,
    /// The communication step H, s.
    pub step_size: f64,
}

/// The model description of a plant instance.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct ModelDescription {
    /// FMI version the JSON form follows (the XML is written for 2.0 or 3.0).
    pub fmi_version: &'static str,
    /// Model name.
    pub model_name: &'static str,
    /// Instantiation token (FMI 3.0) and GUID (FMI 2.0): names the variables' layout (version
    /// and N); an FMU refuses an instantiation with another token.
    pub instantiation_token: String,
    /// Description.
    pub description: &'static str,
    /// The communication step H the plant uses (a whole number of internal steps), s.
    pub fixed_internal_step_size: f64,
    /// Supports get/set/serialize of the state.
    pub can_get_and_set_fmu_state: bool,
    /// Supports serialization of the state.
    pub can_serialize_fmu_state: bool,
    /// The default run, if the description is for a scenario.
    pub default_experiment: Option<DefaultExperiment>,
    /// The variables.
    pub variables: Vec<Variable>,
}

/// `modelIdentifier` of the FMUs: the shared library's name without extension.
pub const MODEL_IDENTIFIER: &str = "crawler_physics";

/// The instantiation token (FMI 3.0) or GUID (FMI 2.0) of a plant with `cells` cells.
pub fn instantiation_token(cells: usize) -> String {
    format!("{{crawler-plant-{}-{cells}}}", env!("CARGO_PKG_VERSION"))
}

impl ModelDescription {
    /// The description for a plant with `params` and no actuation by default.
    pub fn new(params: &PlantParams) -> Self {
        Self::build(params, None, None)
    }

    /// The description for a plant with `params` driven by `wave` unless the importer sets
    /// other inputs, with a default run to `t_end` seconds (rounded up to whole steps).
    pub fn for_run(params: &PlantParams, wave: Wave, t_end: f64) -> Self {
        Self::build(params, Some(wave), Some(t_end))
    }

    /// The description for a plant with `params`, driven by `wave` by default if given.
    pub fn with_inputs(params: &PlantParams, wave: Option<Wave>) -> Self {
        Self::build(params, wave, None)
    }

    /// The description of a plant with `params`, driven by `wave` by default if given, with a
    /// default run to `t_end` seconds (rounded up to whole steps) if given.
    fn build(params: &PlantParams, wave: Option<Wave>, t_end: Option<f64>) -> Self {
        let n = params.numerics.cells;
        let h = params
            .discretisation()
            .map(|d| d.step)
            .unwrap_or(params.numerics.step);
        let variables = variables::variables(params, wave);
        let default_experiment = t_end.map(|t| {
            let steps = params
                .discretisation()
                .map(|d| d.steps_until(t))
                .unwrap_or(1);
            DefaultExperiment {
                start_time: 0.0,
                stop_time: steps as f64 * h,
                step_size: h,
            }
        });
        Self {
            fmi_version: "3.0",
            model_name: "crawler-plant",
            instantiation_token: instantiation_token(n),
            description: "Soft peristaltic crawler: nonlinear wave equation with asymmetric Coulomb + viscous friction and exact stick",
            fixed_internal_step_size: h,
            can_get_and_set_fmu_state: true,
            can_serialize_fmu_state: true,
            default_experiment,
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

    /// The FMI 3.0 `modelDescription.xml` (same as [`Self::to_fmi3_xml`]).
    pub fn to_xml(&self) -> String {
        self.to_fmi3_xml()
    }

    fn units_used(&self) -> Vec<(&'static str, [i8; 8])> {
        UNITS
            .iter()
            .filter(|(name, _)| self.variables.iter().any(|v| v.unit == *name))
            .copied()
            .collect()
    }

    fn write_units(&self, x: &mut String) {
        x.push_str("  <UnitDefinitions>\n");
        for (name, exps) in self.units_used() {
            x.push_str(&format!(
                "    <Unit name=\"{}\">\n      <BaseUnit",
                xml_escape(name)
            ));
            for (base, e) in BASE_UNITS.iter().zip(exps) {
                if e != 0 {
                    x.push_str(&format!(" {base}=\"{e}\""));
                }
            }
            x.push_str("/>\n    </Unit>\n");
        }
        x.push_str("  </UnitDefinitions>\n");
    }

    fn write_default_experiment(&self, x: &mut String) {
        if let Some(e) = self.default_experiment {
            x.push_str(&format!(
                "  <DefaultExperiment startTime=\"{}\" stopTime=\"{}\" stepSize=\"{}\"/>\n",
                real(e.start_time),
                real(e.stop_time),
                real(e.step_size)
            ));
        }
    }

    fn header(&self, x: &mut String, version: &str, token_attribute: &str) {
        x.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        x.push_str(&format!(
            "<fmiModelDescription fmiVersion=\"{version}\" modelName=\"{}\" {token_attribute}=\"{}\" description=\"{}\" version=\"{}\" generationTool=\"crawler-plant {}\" variableNamingConvention=\"structured\">\n",
            self.model_name,
            xml_escape(&self.instantiation_token),
            xml_escape(self.description),
            env!("CARGO_PKG_VERSION"),
            env!("CARGO_PKG_VERSION"),
        ));
    }

    /// The FMI 3.0 `modelDescription.xml`: arrays with a `Dimension` given by `cells`,
    /// `fixedInternalStepSize` = H, the `boundary` enumeration type, SI unit definitions and
    /// every output and calculated parameter listed as an initial unknown.
    pub fn to_fmi3_xml(&self) -> String {
        let mut x = String::new();
        self.header(&mut x, "3.0", "instantiationToken");
        x.push_str(&format!(
            "  <CoSimulation modelIdentifier=\"{MODEL_IDENTIFIER}\" canGetAndSetFMUState=\"true\" canSerializeFMUState=\"true\" fixedInternalStepSize=\"{}\" canHandleVariableCommunicationStepSize=\"false\" hasEventMode=\"false\"/>\n",
            real(self.fixed_internal_step_size)
        ));
        self.write_units(&mut x);
        x.push_str("  <TypeDefinitions>\n    <EnumerationType name=\"Boundary\">\n");
        for (name, value, description) in BOUNDARY_ITEMS {
            x.push_str(&format!(
                "      <Item name=\"{name}\" value=\"{value}\" description=\"{}\"/>\n",
                xml_escape(description)
            ));
        }
        x.push_str("    </EnumerationType>\n  </TypeDefinitions>\n");
        x.push_str("  <LogCategories>\n    <Category name=\"logStatusError\" description=\"Calls that failed, with the reason\"/>\n    <Category name=\"logStatusDiscard\" description=\"Steps that were discarded\"/>\n    <Category name=\"logStatusWarning\" description=\"Calls that succeeded with a warning\"/>\n    <Category name=\"logEvents\" description=\"Lifecycle messages (with debug logging on)\"/>\n  </LogCategories>\n");
        self.write_default_experiment(&mut x);
        x.push_str("  <ModelVariables>\n");
        for v in &self.variables {
            let tag = match v.var_type {
                VarType::Float64 => "Float64",
                VarType::UInt64 => "UInt64",
                VarType::Boolean => "Boolean",
                VarType::String => "String",
                VarType::Enumeration => "Enumeration",
            };
            x.push_str(&format!(
                "    <{tag} name=\"{}\" valueReference=\"{}\" description=\"{}\" causality=\"{}\" variability=\"{}\"",
                v.name,
                v.value_reference,
                xml_escape(v.description),
                causality_name(v.causality, 3),
                variability_name(v.variability),
            ));
            if v.var_type == VarType::Enumeration {
                x.push_str(" declaredType=\"Boundary\"");
            }
            if !v.unit.is_empty() {
                x.push_str(&format!(" unit=\"{}\"", xml_escape(v.unit)));
            }
            let mut children = String::new();
            match &v.start {
                Some(Start::Text(s)) => {
                    children.push_str(&format!("      <Start value=\"{}\"/>\n", xml_escape(s)))
                }
                Some(s) => {
                    let one = start_text(s);
                    let text = match v.size {
                        Some(n) => vec![one; n].join(" "),
                        None => one,
                    };
                    x.push_str(&format!(" start=\"{text}\""));
                }
                None => {}
            }
            if v.size.is_some() {
                children.push_str(&format!(
                    "      <Dimension valueReference=\"{}\"/>\n",
                    vr::CELLS
                ));
            }
            if children.is_empty() {
                x.push_str("/>\n");
            } else {
                x.push_str(&format!(">\n{children}    </{tag}>\n"));
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
        for v in self.variables.iter().filter(|v| is_initial_unknown(v)) {
            x.push_str(&format!(
                "    <InitialUnknown valueReference=\"{}\"/>\n",
                v.value_reference
            ));
        }
        x.push_str("  </ModelStructure>\n</fmiModelDescription>\n");
        x
    }

    /// The FMI 2.0 `modelDescription.xml`: every array as scalars `name[1]`..`name[N]` (value
    /// references from [`fmi2_element_reference`]), UInt64 as Integer, the DefaultExperiment's
    /// step size = H, `canHandleVariableCommunicationStepSize="false"`.
    pub fn to_fmi2_xml(&self) -> String {
        let mut x = String::new();
        self.header(&mut x, "2.0", "guid");
        x.push_str(&format!(
            "  <CoSimulation modelIdentifier=\"{MODEL_IDENTIFIER}\" canHandleVariableCommunicationStepSize=\"false\" canGetAndSetFMUstate=\"true\" canSerializeFMUstate=\"true\" canNotUseMemoryManagementFunctions=\"true\"/>\n"
        ));
        self.write_units(&mut x);
        x.push_str(
            "  <TypeDefinitions>\n    <SimpleType name=\"Boundary\">\n      <Enumeration>\n",
        );
        for (name, value, description) in BOUNDARY_ITEMS {
            x.push_str(&format!(
                "        <Item name=\"{name}\" value=\"{value}\" description=\"{}\"/>\n",
                xml_escape(description)
            ));
        }
        x.push_str("      </Enumeration>\n    </SimpleType>\n  </TypeDefinitions>\n");
        x.push_str("  <LogCategories>\n    <Category name=\"logStatusError\" description=\"Calls that failed, with the reason\"/>\n    <Category name=\"logStatusDiscard\" description=\"Steps that were discarded\"/>\n    <Category name=\"logStatusWarning\" description=\"Calls that succeeded with a warning\"/>\n    <Category name=\"logEvents\" description=\"Lifecycle messages (with debug logging on)\"/>\n  </LogCategories>\n");
        self.write_default_experiment(&mut x);
        x.push_str("  <ModelVariables>\n");
        // (1-based index in ModelVariables, variable) of every scalar written, for ModelStructure.
        let mut outputs = Vec::new();
        let mut unknowns = Vec::new();
        let mut index = 0usize;
        for v in &self.variables {
            let count = v.size.unwrap_or(1);
            for i in 0..count {
                index += 1;
                let (name, reference) = match v.size {
                    Some(_) => (
                        format!("{}[{}]", v.name, i + 1),
                        fmi2_element_reference(v.value_reference, i),
                    ),
                    None => (v.name.to_string(), v.value_reference),
                };
                let (tag, extra) = match v.var_type {
                    VarType::Float64 => ("Real", String::new()),
                    VarType::UInt64 => ("Integer", String::new()),
                    VarType::Boolean => ("Boolean", String::new()),
                    VarType::String => ("String", String::new()),
                    VarType::Enumeration => ("Enumeration", " declaredType=\"Boundary\"".into()),
                };
                let mut attrs = extra;
                if !v.unit.is_empty() {
                    attrs.push_str(&format!(" unit=\"{}\"", xml_escape(v.unit)));
                }
                if let Some(s) = &v.start {
                    attrs.push_str(&format!(" start=\"{}\"", xml_escape(&start_text(s))));
                }
                let variability = match v.causality {
                    Causality::Independent => String::new(),
                    _ => format!(" variability=\"{}\"", variability_name(v.variability)),
                };
                x.push_str(&format!(
                    "    <ScalarVariable name=\"{name}\" valueReference=\"{reference}\" description=\"{}\" causality=\"{}\"{variability}>\n      <{tag}{attrs}/>\n    </ScalarVariable>\n",
                    xml_escape(v.description),
                    causality_name(v.causality, 2),
                ));
                if v.causality == Causality::Output {
                    outputs.push(index);
                }
                if is_initial_unknown(v) {
                    unknowns.push(index);
                }
            }
        }
        x.push_str("  </ModelVariables>\n  <ModelStructure>\n    <Outputs>\n");
        for i in &outputs {
            x.push_str(&format!("      <Unknown index=\"{i}\"/>\n"));
        }
        x.push_str("    </Outputs>\n    <InitialUnknowns>\n");
        for i in &unknowns {
            x.push_str(&format!("      <Unknown index=\"{i}\"/>\n"));
        }
        x.push_str("    </InitialUnknowns>\n  </ModelStructure>\n</fmiModelDescription>\n");
        x
    }
}

/// Outputs (all computed: initial = calculated) and calculated parameters are the unknowns of
/// initialisation.
fn is_initial_unknown(v: &Variable) -> bool {
    matches!(
        v.causality,
        Causality::Output | Causality::CalculatedParameter
    )
}

fn causality_name(c: Causality, fmi: u8) -> &'static str {
    match c {
        Causality::Independent => "independent",
        Causality::StructuralParameter if fmi == 2 => "parameter",
        Causality::StructuralParameter => "structuralParameter",
        Causality::Parameter => "parameter",
        Causality::CalculatedParameter => "calculatedParameter",
        Causality::Input => "input",
        Causality::Output => "output",
    }
}

fn variability_name(v: Variability) -> &'static str {
    match v {
        Variability::Fixed => "fixed",
        Variability::Discrete => "discrete",
        Variability::Continuous => "continuous",
    }
}

/// A float as XML text that reads back to the same bits (shortest round-trip form).
fn real(x: f64) -> String {
    format!("{x:e}")
}

fn start_text(s: &Start) -> String {
    match s {
        Start::Float(x) => real(*x),
        Start::UInt(n) => n.to_string(),
        Start::Enum(n) => n.to_string(),
        Start::Text(t) => t.clone(),
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
