//! The reduced models (`predict`) and the constrained optimiser (`optimize`, verified or certified
//! on the in-process plant): `crawler_models`, as `crawler-controller predict` and `optimize
//! --json` call it.

use pyo3::prelude::*;
use serde_json::json;

use crawler_models::optimizer::{BodyLength, GridSpec, ModelChoice, Problem};
use crawler_models::paper_model::{PaperModel, PaperTerms};
use crawler_models::verify;
use crawler_models::OperatingPoint;

use crate::scenario::PyScenario;
use crate::{any_error, invalid, param_error, run_error};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(predict_json, m)?)?;
    m.add_function(wrap_pyfunction!(optimize_json, m)?)?;
    m.add("DEFAULT_MARGIN", verify::DEFAULT_MARGIN)?;
    m.add(
        "DEFAULT_TIE_TOLERANCE",
        crawler_models::optimizer::DEFAULT_TIE_TOLERANCE,
    )?;
    Ok(())
}

fn model_choice(py: Python<'_>, model: &str) -> PyResult<ModelChoice> {
    ModelChoice::parse(model).map_err(|_| {
        invalid(
            py,
            "model",
            model,
            "paper, improved (alias travelling-wave)",
        )
    })
}

/// The model's steady state at the scenario's wave, as `crawler-controller predict` prints it
/// (JSON).
#[pyfunction]
#[pyo3(signature = (scenario, model="improved", march_steps=None))]
fn predict_json(
    py: Python<'_>,
    scenario: &PyScenario,
    model: &str,
    march_steps: Option<usize>,
) -> PyResult<String> {
    let mut choice = model_choice(py, model)?;
    if let Some(steps) = march_steps {
        if !(16..=1 << 22).contains(&steps) {
            return Err(invalid(
                py,
                "march_steps",
                &steps.to_string(),
                "16 to 4194304 steps per period",
            ));
        }
        match &mut choice {
            ModelChoice::Improved(m) => m.steps = steps,
            ModelChoice::Paper => {
                return Err(invalid(
                    py,
                    "march_steps",
                    &steps.to_string(),
                    "only with the improved model",
                ))
            }
        }
    }
    let op = OperatingPoint::of(&scenario.inner);
    let out = py.detach(|| -> Result<serde_json::Value, serde_json::Error> {
        let prediction = choice.predict(&op);
        let mut out = serde_json::to_value(&prediction)?;
        out["alpha"] = json!(op.alpha());
        out["zeta"] = json!(op.zeta());
        out["pi_r"] = json!(op.pi_r());
        out["omega"] = json!(op.wave.omega);
        out["k"] = json!(op.wave.k);
        out["f0"] = json!(op.wave.f0);
        out["eps"] = json!(op.friction.eps);
        out["n_f"] = json!(op.friction.n_f);
        if let ModelChoice::Paper = choice {
            out["terms"] = serde_json::to_value(PaperTerms::at(&op))?;
            out["stress_eq30_as_printed"] = json!(PaperModel::stress_eq30(&op));
            out["resonance_velocity_eq34"] = json!(PaperModel::resonance_velocity(&op));
        }
        Ok(out)
    });
    let out = out.map_err(|e| run_error(py, e.to_string()))?;
    crate::to_json(py, &out)
}

/// The constrained optimum of the scenario's problem (its body, friction, task and limits), as
/// `crawler-controller optimize --json` prints it; with `verify` the plant's run at the optimum,
/// with `certify` the amplitude lowered until every constraint holds on the plant with `margin`.
#[pyfunction]
#[pyo3(signature = (scenario, model="paper", omega_points=None, k_points=None, fixed_body=false,
                    refine=true, tie_tolerance=crawler_models::optimizer::DEFAULT_TIE_TOLERANCE,
                    verify=false, certify=false, margin=verify::DEFAULT_MARGIN, max_runs=10))]
#[allow(clippy::too_many_arguments)]
fn optimize_json(
    py: Python<'_>,
    scenario: &PyScenario,
    model: &str,
    omega_points: Option<usize>,
    k_points: Option<usize>,
    fixed_body: bool,
    refine: bool,
    tie_tolerance: f64,
    verify: bool,
    certify: bool,
    margin: f64,
    max_runs: usize,
) -> PyResult<String> {
    let s = &scenario.inner;
    let choice = model_choice(py, model)?;
    let default_points = match choice {
        ModelChoice::Paper => 200,
        _ => 32,
    };
    let grid = GridSpec {
        omega_points: omega_points.unwrap_or(default_points),
        k_points: k_points.unwrap_or(default_points),
        refine,
        tie_tolerance,
    };
    if !(0.0..=0.1).contains(&tie_tolerance) {
        return Err(invalid(
            py,
            "tie_tolerance",
            &tie_tolerance.to_string(),
            "a relative speed tolerance in [0, 0.1]",
        ));
    }
    if certify && !(margin.is_finite() && (0.0..0.5).contains(&margin)) {
        return Err(invalid(
            py,
            "margin",
            &margin.to_string(),
            "0 <= margin < 0.5",
        ));
    }
    let problem = Problem {
        body: s.plant.body,
        friction: s.plant.friction,
        task: s.task,
        limits: s.limits,
        body_length: if fixed_body {
            BodyLength::Fixed(s.plant.length)
        } else {
            BodyLength::OneWavelength
        },
    };
    problem.validate().map_err(|e| param_error(py, &e))?;
    let out = py.detach(|| -> anyhow::Result<serde_json::Value> {
        let started = std::time::Instant::now();
        let report = problem.optimize(&choice, &grid)?;
        let elapsed = started.elapsed().as_secs_f64();
        let verification = if verify {
            let plant = verify::run_plant(s, &problem, &report.optimum, report.optimum.f0)?;
            Some(verify::compare(
                &problem,
                &report.optimum,
                report.optimum.f0,
                &plant,
            ))
        } else {
            None
        };
        let certification = if certify {
            Some(verify::certify(
                s,
                &problem,
                &report.optimum,
                margin,
                max_runs,
            )?)
        } else {
            None
        };
        let mut out = serde_json::to_value(&report)?;
        out["seconds"] = json!(elapsed);
        out["verification"] = serde_json::to_value(&verification)?;
        out["certification"] = serde_json::to_value(&certification)?;
        Ok(out)
    });
    let out = out.map_err(|e| any_error(py, e))?;
    crate::to_json(py, &out)
}
