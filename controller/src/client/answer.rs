//! How the controller answers a state: the policy's decision as the run's `Actuation`, and,
//! when the wave changes or a feedback policy has something to say, a `Prediction` for the
//! recorder (published after the actuation, so that the plant never waits for it).

use crawler_physics::wave::Wave;
use crawler_protocol::{
    Actuation as ActuationMsg, FinalReport, ModelPrediction, Prediction as PredictionMsg, State,
    WaveMsg, PROTOCOL_VERSION,
};

use super::predictions::{insight_prediction, predictions};
use super::summary::FinalSummary;
use crawler_physics::execution::{Actuation, Observation};
use crawler_policies::{Context, Policy};

/// A policy at work in a run, with what it last applied.
pub struct Responder<'a> {
    policy: Box<dyn Policy>,
    ctx: &'a Context,
    /// This controller's id, which every actuation carries.
    id: String,
    last_wave: Option<Wave>,
    /// The models' predictions for `last_wave`.
    last_predictions: Vec<ModelPrediction>,
    answered: u64,
}

fn wave_msg(w: Wave) -> WaveMsg {
    WaveMsg {
        f0: w.f0,
        k: w.k,
        omega: w.omega,
        phase: w.phase,
    }
}

impl<'a> Responder<'a> {
    /// `policy` answering for controller `id` on the plant of `ctx`.
    pub fn new(policy: Box<dyn Policy>, ctx: &'a Context, id: &str) -> Self {
        Self {
            policy,
            ctx,
            id: id.to_string(),
            last_wave: None,
            last_predictions: Vec::new(),
            answered: 0,
        }
    }

    /// The policy's name.
    pub fn policy(&self) -> &str {
        self.policy.name()
    }

    /// States answered so far.
    pub fn answered(&self) -> u64 {
        self.answered
    }

    /// The actuation answering `state`, and the prediction to publish after it (if any).
    pub fn respond(&mut self, state: &State) -> (ActuationMsg, Option<PredictionMsg>) {
        let obs = Observation {
            step: state.step,
            time: state.time,
            u: &state.u,
            vel: &state.vel,
            tension: &state.tension,
            stuck: &state.stuck,
            mean_speed: state.mean_speed,
            input_power: state.input_power,
        };
        let (wave, field) = match self.policy.act(&obs) {
            Actuation::Wave(w) => (Some(w), None),
            Actuation::Field(f) => (None, Some(f)),
        };
        let insight = self.policy.insight();
        let mut prediction = None;
        if let Some(w) = wave {
            let changed = self.last_wave != Some(w);
            if changed || insight.is_some() {
                if changed {
                    self.last_predictions = predictions(self.ctx, w);
                }
                let mut models = self.last_predictions.clone();
                models.extend(insight.as_ref().map(insight_prediction));
                prediction = Some(PredictionMsg {
                    v: PROTOCOL_VERSION,
                    controller: self.id.clone(),
                    policy: self.policy.name().to_string(),
                    step: state.step,
                    wave: wave_msg(w),
                    models,
                });
                self.last_wave = Some(w);
            }
        }
        self.answered += 1;
        let actuation = ActuationMsg {
            v: PROTOCOL_VERSION,
            step: state.step,
            controller: self.id.clone(),
            wave: wave.map(wave_msg),
            field,
        };
        (actuation, prediction)
    }

    /// The end of the run: the last wave's predictions against the plant's report.
    pub fn summary(self, plant: Option<FinalReport>) -> FinalSummary {
        FinalSummary {
            policy: self.policy.name().to_string(),
            wave: self.last_wave.map(wave_msg),
            plant,
            predictions: self.last_predictions,
            steps: self.answered,
        }
    }
}
