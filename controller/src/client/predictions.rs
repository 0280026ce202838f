//! What the controller tells its policy about the plant ([`context_of`]) and what it publishes
//! for the recorder about the wave it applies: the models' predictions ([`predictions`]) and a
//! feedback policy's own report ([`insight_prediction`]).

use crawler_physics::params::{Body, Boundary, Friction};
use crawler_physics::scenario::Scenario;
use crawler_physics::wave::Wave;
use crawler_protocol::{ModelInfo, ModelPrediction, Series};

use crawler_facts::MetricValues;
use crawler_models::operating_point::OperatingPoint;
use crawler_models::paper_model::{first_order_harmonic, PaperModel, PaperTerms};
use crawler_models::prediction::{Model, Prediction, Validity};
use crawler_models::travelling_wave::TravellingWaveModel;
use crawler_physics::execution::Briefing;
use crawler_policies::{Context, Insight};

/// What the plant's `model` reply tells a controller, as the plant library's [`Briefing`] (the
/// plant decides it with `Briefing::of`; the wire only carries its fields).
pub fn briefing_of(info: &ModelInfo) -> Briefing {
    Briefing {
        body: Body {
            area: info.area,
            density: info.density,
            youngs_modulus: info.youngs_modulus,
        },
        friction: Friction {
            viscous: info.viscous,
            dry: info.dry,
            eps: info.eps,
            n_f: info.n_f,
        },
        length: info.length,
        boundary: if info.boundary == "free" {
            Boundary::Free
        } else {
            Boundary::Periodic
        },
        cells: info.cells as usize,
        step: info.step,
        start_time: info.start_time,
        last_step: info.last_step,
        settle: info.settle,
        disclosed: info.disclosed,
    }
}

/// The context of a policy told `info` by the plant, over the controller's own `scenario`.
pub fn context_of(info: &ModelInfo, scenario: &Scenario) -> Context {
    Context::new(&briefing_of(info), scenario)
}

/// The paper's reconstructed tail displacement `u(0, t) = u_c (mu0 + eps mu1)` as a series.
pub fn paper_tail(op: &OperatingPoint, harmonics: u32) -> Option<Series> {
    let t = PaperTerms::at(op);
    let v = PaperModel::velocity(op)?;
    let uc = op.u_c();
    let eps = op.friction.eps;
    let shift = t.phi0 - op.wave.phase;
    // xi at x = 0 is -(omega t + phi0 - phase): cos(n xi - phi_n) = cos(n omega t + n shift + phi_n).
    let mut h = Vec::new();
    for n in 1..=harmonics {
        let (rn, phin) = first_order_harmonic(&t, n)?;
        let (mut re, mut im) = (
            (n as f64 * shift + phin).cos() * eps * rn,
            (n as f64 * shift + phin).sin() * eps * rn,
        );
        if n == 1 {
            re -= t.r0 * shift.cos();
            im -= t.r0 * shift.sin();
        }
        h.push((uc * (re * re + im * im).sqrt(), im.atan2(re)));
    }
    Some(Series {
        omega: op.wave.omega,
        drift: v,
        harmonics: h,
    })
}

fn model_prediction(p: &Prediction, tail: Option<Series>) -> ModelPrediction {
    ModelPrediction {
        model: p.model.to_string(),
        values: p.values(),
        validity: match &p.validity {
            Validity::Valid => "valid".into(),
            Validity::OutsideValidity(r) => r.clone(),
        },
        tail,
    }
}

/// The paper model's and the improved model's predictions for `wave` on the plant of `ctx`.
pub fn predictions(ctx: &Context, wave: Wave) -> Vec<ModelPrediction> {
    let op = OperatingPoint {
        body: ctx.body,
        friction: ctx.friction,
        wave,
        wavelengths: (wave.k * ctx.length / std::f64::consts::TAU)
            .round()
            .max(1.0),
    };
    let paper = PaperModel { harmonics: 15 };
    vec![
        model_prediction(&paper.predict(&op), paper_tail(&op, 15)),
        model_prediction(&TravellingWaveModel::default().predict(&op), None),
    ]
}

/// A feedback controller's report as a model prediction: its own model's numbers (if any) under
/// its name, and its text (estimates, confidence, decision) where a model says how valid it is.
pub fn insight_prediction(i: &Insight) -> ModelPrediction {
    let mut m = match &i.prediction {
        Some(p) => model_prediction(p, None),
        None => ModelPrediction {
            model: "controller".into(),
            values: MetricValues::NONE,
            validity: String::new(),
            tail: None,
        },
    };
    m.validity = i.text.clone();
    m
}
