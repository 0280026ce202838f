//! Checking an optimum on the in-process plant (`--verify`) and making it hold there (`--certify`).

use serde::Serialize;

use crawler_physics::report::Report;
use crawler_physics::scenario::Scenario;
use crawler_physics::simulate::{simulate, SimulateOptions};
use crawler_physics::wave::Wave;

use crate::optimizer::{BodyLength, Margins, Optimum, Problem};

/// Predicted against simulated metrics at one wave.
#[derive(Debug, Clone, Serialize)]
pub struct Verification {
    /// Amplitude, N.
    pub f0: f64,
    /// Predicted / simulated speed, m/s.
    pub velocity: Pair,
    /// Predicted / simulated mileage, m/J.
    pub mileage: Pair,
    /// Predicted / simulated max stress, Pa.
    pub max_stress: Pair,
    /// Predicted / simulated max strain.
    pub max_strain: Pair,
    /// Predicted / simulated power, W.
    pub power: Pair,
    /// Constraint margins on the plant (>= 0: holds).
    pub plant_margins: Margins,
    /// Each constraint on the plant.
    pub holds: Holds,
    /// Cells and end time of the plant run.
    pub cells: usize,
    /// s.
    pub t_end: f64,
}

/// A predicted and a simulated value.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Pair {
    /// The model's value.
    pub predicted: Option<f64>,
    /// The plant's value.
    pub simulated: f64,
    /// predicted / simulated - 1.
    pub relative_error: Option<f64>,
}

impl Pair {
    fn new(predicted: Option<f64>, simulated: f64) -> Self {
        Self {
            predicted,
            simulated,
            relative_error: predicted.map(|p| p / simulated - 1.0),
        }
    }
}

/// Whether each constraint holds on the plant.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Holds {
    /// M >= D / J0.
    pub mileage: bool,
    /// sigma <= sigma_max.
    pub stress: bool,
    /// strain <= strain_max.
    pub strain: bool,
    /// f0 <= f0_max.
    pub f0: bool,
}

/// The plant scenario for a wave: the paper's one-wavelength body, or the fixed body.
pub fn plant_scenario(
    base: &Scenario,
    problem: &Problem,
    wave: Wave,
) -> Result<Scenario, crawler_physics::ParamError> {
    match problem.body_length {
        BodyLength::OneWavelength => base.with_wave(wave, Some(wave.wavelength())),
        BodyLength::Fixed(l) => base.with_wave(wave, Some(l)),
    }
}

/// Runs the plant at the wave `(optimum.omega, optimum.k, f0)`.
pub fn run_plant(
    base: &Scenario,
    problem: &Problem,
    optimum: &Optimum,
    f0: f64,
) -> anyhow::Result<Report> {
    let wave = Wave {
        f0,
        k: optimum.k,
        omega: optimum.omega,
        phase: 0.0,
    };
    let scenario = plant_scenario(base, problem, wave)?;
    Ok(simulate(&scenario, SimulateOptions::default())?)
}

/// Compares the optimum's prediction with a plant run at amplitude `f0`.
pub fn compare(problem: &Problem, optimum: &Optimum, f0: f64, plant: &Report) -> Verification {
    let p = &optimum.prediction;
    let same = (f0 - optimum.f0).abs() <= 1e-12 * optimum.f0;
    let pick = |x: Option<f64>| if same { x } else { None };
    let margins = Margins::of(
        problem,
        f0,
        plant.mileage,
        plant.max_stress,
        plant.max_strain,
    );
    Verification {
        f0,
        velocity: Pair::new(pick(p.velocity), plant.velocity),
        mileage: Pair::new(pick(p.mileage), plant.mileage),
        max_stress: Pair::new(pick(p.max_stress), plant.max_stress),
        max_strain: Pair::new(pick(p.max_strain), plant.max_strain),
        power: Pair::new(pick(p.power), plant.power),
        plant_margins: margins,
        holds: Holds {
            mileage: margins.mileage >= 0.0,
            stress: margins.stress >= 0.0,
            strain: margins.strain >= 0.0,
            f0: margins.f0 >= 0.0,
        },
        cells: plant.cells,
        t_end: plant.t_end,
    }
}

/// The result of `--certify`.
#[derive(Debug, Clone, Serialize)]
pub struct Certification {
    /// Required margin on every constraint (relative).
    pub margin: f64,
    /// The certified amplitude, N.
    pub f0: f64,
    /// Plant runs made, in order.
    pub runs: Vec<Verification>,
    /// True if every constraint holds on the plant with the margin at `f0`.
    pub certified: bool,
}

fn min_margin(m: &Margins) -> f64 {
    m.mileage.min(m.stress).min(m.strain).min(m.f0)
}

/// The relative margin a certification keeps on every constraint unless told otherwise.
pub const DEFAULT_MARGIN: f64 = 0.005;

/// A certification margin is a share of each constraint: `0 <= margin < 0.5`. The error names
/// `field`, the value and what is allowed.
pub fn check_margin(field: &str, margin: f64) -> anyhow::Result<()> {
    anyhow::ensure!(
        margin.is_finite() && (0.0..0.5).contains(&margin),
        "invalid {field} = {margin}: allowed 0 <= margin < 0.5"
    );
    Ok(())
}

/// Lowers `f0` from the optimum with a few plant runs (secant on the smallest margin, which falls
/// as f0 grows) until every constraint holds on the plant with `margin` to spare.
pub fn certify(
    base: &Scenario,
    problem: &Problem,
    optimum: &Optimum,
    margin: f64,
    max_runs: usize,
) -> anyhow::Result<Certification> {
    check_margin("margin", margin)?;
    let mut runs = Vec::new();
    let eval = |f0: f64, runs: &mut Vec<Verification>| -> anyhow::Result<f64> {
        let plant = run_plant(base, problem, optimum, f0)?;
        let v = compare(problem, optimum, f0, &plant);
        let m = min_margin(&v.plant_margins);
        runs.push(v);
        Ok(m - margin)
    };
    let mut f_hi = optimum.f0;
    let mut g_hi = eval(f_hi, &mut runs)?;
    if g_hi >= 0.0 {
        return Ok(Certification {
            margin,
            f0: f_hi,
            runs,
            certified: true,
        });
    }
    // Bracket: shrink f0 until the margin holds.
    let mut f_lo = f_hi;
    let mut g_lo = g_hi;
    while g_lo < 0.0 && runs.len() < max_runs {
        f_hi = f_lo;
        g_hi = g_lo;
        f_lo *= 0.9;
        g_lo = eval(f_lo, &mut runs)?;
    }
    if g_lo < 0.0 {
        return Ok(Certification {
            margin,
            f0: f_lo,
            runs,
            certified: false,
        });
    }
    // Regula falsi inside the bracket [f_lo (holds), f_hi (fails)]; keep the best holding f0.
    let mut best = f_lo;
    while runs.len() < max_runs && (f_hi - f_lo) > 1e-4 * f_hi {
        let f = f_lo - g_lo * (f_hi - f_lo) / (g_hi - g_lo);
        let f = f.clamp(f_lo + 0.1 * (f_hi - f_lo), f_hi - 0.1 * (f_hi - f_lo));
        let g = eval(f, &mut runs)?;
        if g >= 0.0 {
            f_lo = f;
            g_lo = g;
            best = f;
            if g < 0.25 * margin.max(1e-3) {
                break;
            }
        } else {
            f_hi = f;
            g_hi = g;
        }
    }
    Ok(Certification {
        margin,
        f0: best,
        runs,
        certified: true,
    })
}
