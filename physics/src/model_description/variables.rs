//! The variables of the plant's model description, in the order they are listed: one function
//! per group (structure, body and friction, numerics, calculated, inputs, outputs), each built
//! from the plant's parameters so that start values match the plant.

use super::{boundary_value, vr, Causality, Start, VarType, Variability, Variable};
use crate::params::PlantParams;
use crate::wave::Wave;

use Causality::*;
use VarType::*;
use Variability::*;

/// Every variable of a plant with `params`, driven by `wave` by default if given (actuation
/// mode 1 and its wave as the inputs' start values), in value-reference listing order.
pub(super) fn variables(params: &PlantParams, wave: Option<Wave>) -> Vec<Variable> {
    [
        structure(params),
        body_and_friction(params),
        numerics(params),
        calculated_parameters(),
        inputs(params, wave),
        outputs(params.numerics.cells),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// A scalar variable (no array size); `unit` is an SI unit name from [`super::UNITS`] or empty.
#[allow(clippy::too_many_arguments)]
fn scalar(
    name: &'static str,
    value_reference: u32,
    var_type: VarType,
    causality: Causality,
    variability: Variability,
    unit: &'static str,
    start: Option<Start>,
    description: &'static str,
) -> Variable {
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
}

/// A fixed Float64 parameter starting at `x` (in `unit`).
fn param(
    name: &'static str,
    value_reference: u32,
    unit: &'static str,
    x: f64,
    description: &'static str,
) -> Variable {
    scalar(
        name,
        value_reference,
        Float64,
        Parameter,
        Fixed,
        unit,
        Some(Start::Float(x)),
        description,
    )
}

/// A fixed parameter the plant computes from the others (no start value).
fn calculated(
    name: &'static str,
    value_reference: u32,
    var_type: VarType,
    unit: &'static str,
    description: &'static str,
) -> Variable {
    scalar(
        name,
        value_reference,
        var_type,
        CalculatedParameter,
        Fixed,
        unit,
        None,
        description,
    )
}

/// A discrete Float64 input starting at `x` (in `unit`).
fn input(
    name: &'static str,
    value_reference: u32,
    unit: &'static str,
    x: f64,
    description: &'static str,
) -> Variable {
    scalar(
        name,
        value_reference,
        Float64,
        Input,
        Discrete,
        unit,
        Some(Start::Float(x)),
        description,
    )
}

/// A discrete scalar output (no start value).
fn output(
    name: &'static str,
    value_reference: u32,
    var_type: VarType,
    unit: &'static str,
    description: &'static str,
) -> Variable {
    scalar(
        name,
        value_reference,
        var_type,
        Output,
        Discrete,
        unit,
        None,
        description,
    )
}

/// A discrete array variable of `n` values (one per cell); `start` is every element's.
#[allow(clippy::too_many_arguments)]
fn array(
    n: usize,
    name: &'static str,
    value_reference: u32,
    var_type: VarType,
    causality: Causality,
    unit: &'static str,
    start: Option<Start>,
    description: &'static str,
) -> Variable {
    Variable {
        name,
        value_reference,
        var_type,
        causality,
        variability: Discrete,
        unit,
        start,
        size: Some(n),
        description,
    }
}

/// Time, and the structure of the body: the number of cells, its length (m) and its ends.
fn structure(params: &PlantParams) -> Vec<Variable> {
    let n = params.numerics.cells;
    vec![
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
            Some(Start::UInt(n as u64)),
            "Number of cells N (the size of every array; fixed per FMI 2.0 FMU)",
        ),
        param(
            "length",
            vr::LENGTH,
            "m",
            params.length,
            "Body length L; a travelling wave must fit a periodic body a whole number of times",
        ),
        scalar(
            "boundary",
            vr::BOUNDARY,
            Enumeration,
            StructuralParameter,
            Fixed,
            "",
            Some(Start::Enum(boundary_value(params.boundary))),
            "What holds the body's ends: 1 periodic (closed on itself), 2 free ends",
        ),
    ]
}

/// The body's material (SI units) and the friction's uniform values.
fn body_and_friction(params: &PlantParams) -> Vec<Variable> {
    let f = params.friction;
    let b = params.body;
    vec![
        param("area", vr::AREA, "m2", b.area, "Cross-sectional area A_c"),
        param(
            "density",
            vr::DENSITY,
            "kg/m",
            b.density,
            "Linear mass density rho",
        ),
        param(
            "youngs_modulus",
            vr::YOUNGS_MODULUS,
            "Pa",
            b.youngs_modulus,
            "Young's modulus E",
        ),
        param(
            "viscous",
            vr::VISCOUS,
            "N.s/m2",
            f.viscous,
            "Viscous friction coefficient c_v",
        ),
        param(
            "dry",
            vr::DRY,
            "N/m",
            f.dry,
            "Normal load per unit length c_d",
        ),
        param(
            "eps",
            vr::EPS,
            "",
            f.eps,
            "Dry friction coefficient eps (uniform value; the pipe map may vary it)",
        ),
        param(
            "n_f",
            vr::N_F,
            "",
            f.n_f,
            "Friction asymmetry n_F in [0, 1] (uniform value; the pipe map may vary it)",
        ),
    ]
}

/// The numerical settings, the pipe (as JSON text) and the master's clock.
fn numerics(params: &PlantParams) -> Vec<Variable> {
    let nm = params.numerics;
    vec![
        param("courant", vr::COURANT, "", nm.courant, "Upper bound of the Courant number c dt/dx, in (0, 1]"),
        param("step", vr::STEP, "s", nm.step, "Requested communication step; the plant uses the nearest whole multiple of dt (communication_step)"),
        param("settle", vr::SETTLE, "s", nm.settle, "Transient skipped before steady averaging"),
        param("min_stick_periods", vr::MIN_STICK, "", nm.min_stick_periods, "Shortest stick phase counted as an episode, in periods of the applied wave"),
        param("block", vr::BLOCK, "s", nm.block, "Averaging block under field actuation"),
        param("filter", vr::FILTER, "", nm.filter, "Grid filter: share of the grid-scale velocity mode removed per internal step, in [0, 1)"),
        scalar(
            "pipe",
            vr::PIPE,
            String,
            Parameter,
            Fixed,
            "",
            Some(Start::Text(
                serde_json::to_string(&params.pipe).expect("the pipe serializes"),
            )),
            "Friction along the pipe, JSON of the scenario's [pipe] section: start (m), disclose, nominal, resolution (m), features (patch/ramp/texture)",
        ),
        scalar(
            "ticks_per_second",
            vr::TICKS_PER_SECOND,
            UInt64,
            Parameter,
            Fixed,
            "",
            Some(Start::UInt(nm.ticks_per_second.unwrap_or(0))),
            "Integer clock of the master, ticks per second (1000000000 for libcosim's nanoseconds): communication_step is then a whole number of ticks and dt = communication_step / substeps, the Courant number at most 1e-6 below courant; 0: the plant's own clock (dt at the Courant bound)",
        ),
    ]
}

/// The parameters the plant computes: dt (s), substeps, dx (m), wave speed (m/s) and H (s).
fn calculated_parameters() -> Vec<Variable> {
    vec![
        calculated("dt", vr::DT, Float64, "s", "Internal time step"),
        calculated(
            "substeps",
            vr::SUBSTEPS,
            UInt64,
            "",
            "Internal steps per communication step",
        ),
        calculated("dx", vr::DX, Float64, "m", "Cell size L/N"),
        calculated(
            "wave_speed",
            vr::WAVE_SPEED,
            Float64,
            "m/s",
            "Wave speed sqrt(A_c E / rho)",
        ),
        calculated(
            "communication_step",
            vr::COMMUNICATION_STEP,
            Float64,
            "s",
            "Communication step H = substeps dt: every doStep covers a whole number of it",
        ),
    ]
}

/// The inputs: the actuation mode, the travelling wave (starting at `wave`, or at a zero-amplitude
/// wave of one wavelength on the body) and the muscle-force field (N).
fn inputs(params: &PlantParams, wave: Option<Wave>) -> Vec<Variable> {
    let n = params.numerics.cells;
    let w = wave.unwrap_or(Wave {
        f0: 0.0,
        k: std::f64::consts::TAU / params.length,
        omega: 1.0,
        phase: 0.0,
    });
    vec![
        scalar(
            "actuation_mode",
            vr::ACTUATION_MODE,
            UInt64,
            Input,
            Discrete,
            "",
            Some(Start::UInt(if wave.is_some() { 1 } else { 0 })),
            "0 none, 1 travelling wave (wave_*), 2 muscle-force field (muscle_force)",
        ),
        input(
            "wave_f0",
            vr::WAVE_F0,
            "N",
            w.f0,
            "Travelling-wave amplitude f0",
        ),
        input(
            "wave_k",
            vr::WAVE_K,
            "rad/m",
            w.k,
            "Travelling-wave number k (on a periodic body: 2 pi m / L, m whole)",
        ),
        input(
            "wave_omega",
            vr::WAVE_OMEGA,
            "rad/s",
            w.omega,
            "Travelling-wave angular frequency omega",
        ),
        input(
            "wave_phase",
            vr::WAVE_PHASE,
            "rad",
            w.phase,
            "Travelling-wave phase",
        ),
        array(
            n,
            "muscle_force",
            vr::MUSCLE_FORCE,
            Float64,
            Input,
            "N",
            Some(Start::Float(0.0)),
            "Muscle force A_m f at the half nodes, held over each step (actuation_mode 2)",
        ),
    ]
}

/// The outputs: the fields at the nodes (arrays of `n` values), the last step's values and the
/// steady metrics.
fn outputs(n: usize) -> Vec<Variable> {
    vec![
        array(n, "u", vr::U, Float64, Output, "m", None, "Displacement at the nodes"),
        array(n, "v", vr::V, Float64, Output, "m/s", None, "Velocity at the nodes over the last internal step"),
        array(n, "tension", vr::TENSION, Float64, Output, "N", None, "Tension A_c E u_x + A_m f at the half nodes"),
        array(n, "stuck", vr::STUCK, Boolean, Output, "", None, "Nodes held by static friction"),
        output("mean_speed", vr::MEAN_SPEED, Float64, "m/s", "Mean speed of the body over the last step"),
        output("input_power", vr::INPUT_POWER, Float64, "W", "Actuator input power over the last step"),
        output("stuck_nodes", vr::STUCK_NODES, UInt64, "", "Nodes stuck at the end of the last step"),
        output("tail_displacement", vr::TAIL_DISPLACEMENT, Float64, "m", "Displacement of the tail (node 0)"),
        output("mean_displacement", vr::MEAN_DISPLACEMENT, Float64, "m", "Mean displacement of the nodes (the body's travel)"),
        output("velocity", vr::VELOCITY, Float64, "m/s", "Steady mean speed V (eq. 5) over whole periods; 0 until the first steady period closes (steady_periods = 0)"),
        output("power", vr::POWER, Float64, "W", "Steady input power P (eq. 7) over the body; 0 until steady_periods > 0"),
        output("mileage", vr::MILEAGE, Float64, "m/J", "Steady mileage |V|/P; 0 until steady_periods > 0"),
        output("max_stress", vr::MAX_STRESS, Float64, "Pa", "Steady sup T / A_c (eq. 4) over whole periods; 0 until steady_periods > 0"),
        output("max_strain", vr::MAX_STRAIN, Float64, "", "Steady max |u_x|; 0 until steady_periods > 0"),
        output("stuck_fraction", vr::STUCK_FRACTION, Float64, "", "Steady share of node-time stuck; 0 until steady_periods > 0"),
        output("mean_friction_selection", vr::MEAN_FRICTION_SELECTION, Float64, "", "Steady space-time mean of s; 0 until steady_periods > 0"),
        output("steady_periods", vr::STEADY_PERIODS, Float64, "", "Forcing periods (averaging blocks) in the steady window so far"),
        output("episode_rate", vr::EPISODE_RATE, Float64, "", "Stick-slip episodes per node per period (steady); 0 until steady_periods > 0"),
    ]
}
