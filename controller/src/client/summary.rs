//! What `crawler-controller run` prints at the end of a run: the models' predictions for the
//! last wave against what the plant measured.

use serde::Serialize;

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
}

impl FinalSummary {
    /// A table of predicted against simulated metrics, headed by what the plant's window was.
    /// Errors are relative, except for the stuck fraction (a share, often near zero), whose
    /// difference is given in absolute terms.
    pub fn table(&self) -> String {
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
        let rows: [Row; 5] = [
            ("velocity V", "m/s", |m| m.velocity, |r| Some(r.velocity)),
            ("power P", "W", |m| m.power, |r| Some(r.power)),
            ("mileage M", "m/J", |m| m.mileage, |r| r.mileage),
            ("max stress", "Pa", |m| m.max_stress, |r| Some(r.max_stress)),
            (
                "stuck fraction",
                "",
                |m| m.stuck_fraction,
                |r| Some(r.stuck_fraction),
            ),
        ];
        out += &format!("{:<16} {:>14}", "metric", "plant");
        for m in &self.predictions {
            out += &format!(" {:>14} {:>8}", m.model, "error");
        }
        out += "\n";
        for (name, unit, get, simulated) in &rows {
            let sim = self.plant.as_ref().and_then(simulated);
            let share = *name == "stuck fraction";
            out += &format!(
                "{:<16} {:>14}",
                format!("{name} {unit}").trim_end(),
                fmt(sim)
            );
            for m in &self.predictions {
                let p = get(m);
                let err = match (p, sim) {
                    (Some(p), Some(s)) if share => format!("{:+.4}", p - s),
                    (Some(p), Some(s)) if s != 0.0 => format!("{:+.2}%", 100.0 * (p / s - 1.0)),
                    _ => "-".into(),
                };
                out += &format!(" {:>14} {:>8}", fmt(p), err);
            }
            out += "\n";
        }
        out
    }
}

/// A row of the comparison table: label, unit, the model's value, the plant's value.
type Row = (
    &'static str,
    &'static str,
    fn(&ModelPrediction) -> Option<f64>,
    fn(&FinalReport) -> Option<f64>,
);

fn fmt(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.5e}"))
}
