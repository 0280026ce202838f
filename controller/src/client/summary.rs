//! What `crawler-controller run` prints at the end of a run: the models' predictions for the
//! last wave against what the plant measured.

use serde::Serialize;

use crawler_facts::Metric;
use crawler_protocol::{FinalReport, ModelPrediction, WaveMsg};

/// Predicted against simulated metrics at the end of a run.
#[derive(Debug, Clone, Serialize)]
pub struct FinalSummary {
    /// Policy.
    pub policy: String,
    /// The last wave applied.
    pub wave: Option<WaveMsg>,
    /// The plant's final report, from its `finished` status, if received.
    pub plant: Option<FinalReport>,
    /// The models' predictions for the last wave.
    pub predictions: Vec<ModelPrediction>,
    /// Steps answered.
    pub steps: u64,
    /// The first step this controller answered (a controller that took a run over starts
    /// later than the run).
    pub first_step: Option<u64>,
    /// The controller this one handed the run over to, and at which step (its part of the run
    /// ended there; `plant` is then absent).
    pub handed_over: Option<HandOver>,
}

/// A hand-over of the run to another controller.
#[derive(Debug, Clone, Serialize)]
pub struct HandOver {
    /// The controller that took the run over.
    pub to: String,
    /// Its first step.
    pub step: u64,
}

impl FinalSummary {
    /// A table of predicted against simulated metrics, headed by what the plant's window was.
    /// Errors are relative, except for shares (the stuck fraction, often near zero), whose
    /// difference is given in absolute terms; a model without a value says why below the table.
    pub fn table(&self) -> String {
        if let Some(h) = &self.handed_over {
            return format!(
                "handed the run over to controller {} at step {} after answering {} steps{} (policy {})\n",
                h.to,
                h.step,
                self.steps,
                self.first_step
                    .map_or_else(String::new, |f| format!(" from step {f}")),
                self.policy
            );
        }
        let steady = self.plant.as_ref().map(|p| p.window.steady);
        let mut out = match steady {
            Some(false) => "predicted (steady state of the last wave) against simulated (run averages: \
                            the actuation changed within the plant's window, so it is not a steady state):\n"
                .to_string(),
            _ => "predicted against simulated (plant's steady window):\n".to_string(),
        };
        if let Some(w) = self.wave {
            out += &format!(
                "wave: f0 = {:.4} N, k = {:.4} rad/m, omega = {:.4} rad/s\n",
                w.f0, w.k, w.omega
            );
        }
        out += &format!("{:<20} {:>14}", "metric", "plant");
        for m in &self.predictions {
            out += &format!(" {:>14} {:>8}", m.model, "error");
        }
        out += "\n";
        for metric in ROWS {
            let info = metric.info();
            let sim = self.plant.as_ref().and_then(|r| r.values.get(metric));
            let label = match info.unit {
                "1" => info.label.to_string(),
                unit => format!("{} {unit}", info.label),
            };
            out += &format!("{label:<20} {:>14}", fmt(sim));
            for m in &self.predictions {
                let p = m.values.get(metric);
                let err = match (p, sim) {
                    (Some(p), Some(s)) if info.share => format!("{:+.4}", p - s),
                    (Some(p), Some(s)) if s != 0.0 => format!("{:+.2}%", 100.0 * (p / s - 1.0)),
                    _ => "-".into(),
                };
                out += &format!(" {:>14} {:>8}", fmt(p), err);
            }
            out += "\n";
        }
        // every "-" said in place: a model without a value says why
        for m in &self.predictions {
            if ROWS.iter().any(|&r| m.values.get(r).is_none()) && m.validity != "valid" {
                out += &format!("{}: - where {}\n", m.model, m.validity);
            }
        }
        out +=
            "errors: relative to the plant, except for shares (the stuck fraction: difference); \
             \"-\": no value (a model not valid there, as said above, or a plant value of 0 or \
             not received)\n";
        out += "models: the steady state of a periodic body in a uniform pipe with the friction \
                the controller was told (in another pipe or on a free body the errors include \
                that difference)\n";
        out
    }
}

/// The rows of the comparison table.
const ROWS: [Metric; 5] = [
    Metric::Velocity,
    Metric::Power,
    Metric::Mileage,
    Metric::MaxStress,
    Metric::StuckFraction,
];

fn fmt(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.5e}"))
}
