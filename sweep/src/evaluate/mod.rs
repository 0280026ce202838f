//! Evaluating one point: the plant (with its convergence estimate), the models and a policy.

pub mod convergence;
pub mod policy_run;

use std::time::Instant;

use crawler_models::operating_point::OperatingPoint;
use crawler_models::paper_model::PaperModel;
use crawler_models::prediction::{Model, Prediction, Validity};
use crawler_models::travelling_wave::TravellingWaveModel;

use crate::plan::Evaluate;
use crate::point::{Point, FORMAT};
use crate::record::{ModelResult, Record};

/// Steps per forcing period of the improved model's march (its default).
pub const IMPROVED_STEPS: usize = 1024;

fn model_result(p: &Prediction) -> ModelResult {
    ModelResult {
        model: p.model.to_string(),
        valid: p.validity.is_valid(),
        reason: match &p.validity {
            Validity::Valid => None,
            Validity::OutsideValidity(r) => Some(r.clone()),
        },
        metrics: p.values(),
    }
}

/// The prediction of model `name` at the point's operating point.
pub fn predict(name: &str, point: &Point) -> ModelResult {
    let op = OperatingPoint::of(&point.scenario);
    let p = match name {
        "paper" => PaperModel::default().predict(&op),
        "improved" => TravellingWaveModel {
            steps: IMPROVED_STEPS,
            min_stick_periods: point.scenario.min_stick_periods,
        }
        .predict(&op),
        other => unreachable!("model {other} was validated with the plan"),
    };
    model_result(&p)
}

/// Evaluates `point` as `spec` says. Failures (a plant step discarded, a policy refusing the
/// point, even a panic) are kept in the record's `error`, never lost and never fatal to a sweep.
pub fn evaluate(point: &Point, spec: &Evaluate) -> Record {
    let started = Instant::now();
    let mut rec = Record {
        id: point.id.clone(),
        format: FORMAT,
        plant: None,
        models: Vec::new(),
        policy: None,
        error: None,
        wall_time: 0.0,
    };
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        for m in &spec.models {
            rec.models.push(predict(m, point));
        }
        if spec.plant {
            rec.plant = Some(convergence::plant_with_estimate(
                &point.scenario,
                spec.convergence,
            )?);
        }
        if let Some(p) = &spec.policy {
            rec.policy = Some(policy_run::run_policy(&point.scenario, p)?);
        }
        Ok::<(), String>(())
    }));
    rec.error = match outcome {
        Ok(Ok(())) => None,
        Ok(Err(e)) => Some(e),
        Err(panic) => Some(format!(
            "internal error (panic): {}",
            panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("unknown")
        )),
    };
    rec.wall_time = started.elapsed().as_secs_f64();
    rec
}
