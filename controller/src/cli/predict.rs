//! `crawler-controller predict`: a reduced model's steady state at the scenario's wave.

use clap::Args;
use serde_json::json;

use crawler_cli::ScenarioArgs;
use crawler_models::optimizer::ModelChoice;
use crawler_models::paper_model::{PaperModel, PaperTerms};
use crawler_models::OperatingPoint;

#[derive(Args)]
pub struct PredictArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// paper, or improved (alias travelling-wave).
    #[arg(long, default_value = "improved")]
    model: String,
    /// The improved model's march steps per forcing period (default 1024; its stick statistics
    /// converge at first order in them, V, P and sigma at second).
    #[arg(long, value_name = "STEPS")]
    march_steps: Option<usize>,
}

pub fn predict(a: PredictArgs) -> anyhow::Result<()> {
    let scenario = a.scenario.load()?;
    let mut model = ModelChoice::parse(&a.model).map_err(anyhow::Error::msg)?;
    if let Some(steps) = a.march_steps {
        anyhow::ensure!(
            (16..=1 << 22).contains(&steps),
            "invalid --march-steps = {steps}: allowed 16 to {} steps per period",
            1 << 22
        );
        match &mut model {
            ModelChoice::Improved(m) => m.steps = steps,
            ModelChoice::Paper => anyhow::bail!(
                "invalid --march-steps with --model paper: allowed only with the improved model"
            ),
        }
    }
    let op = OperatingPoint::of(&scenario);
    let prediction = model.predict(&op);
    let mut out = serde_json::to_value(&prediction)?;
    out["alpha"] = json!(op.alpha());
    out["zeta"] = json!(op.zeta());
    out["pi_r"] = json!(op.pi_r());
    out["omega"] = json!(op.wave.omega);
    out["k"] = json!(op.wave.k);
    out["f0"] = json!(op.wave.f0);
    out["eps"] = json!(op.friction.eps);
    out["n_f"] = json!(op.friction.n_f);
    if let ModelChoice::Paper = model {
        let t = PaperTerms::at(&op);
        out["terms"] = serde_json::to_value(t)?;
        out["stress_eq30_as_printed"] = json!(PaperModel::stress_eq30(&op));
        out["resonance_velocity_eq34"] = json!(PaperModel::resonance_velocity(&op));
    }
    out!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
