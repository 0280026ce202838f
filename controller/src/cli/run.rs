//! `crawler-controller run`: a policy controlling a co-simulation run over zenoh.

use std::process::ExitCode;

use clap::Args;

use crate::client::{run, ClientOptions, ClientOutcome, Interrupt, TakeOver};
use crawler_cli::{Exit, ScenarioArgs};
use crawler_policies::Params;

#[derive(Args)]
pub struct RunArgs {
    /// The policy (see `crawler-controller policies`).
    #[arg(long, default_value = "optimal")]
    policy: String,
    /// A parameter of the policy, KEY=VALUE (repeatable; `crawler-controller policies` lists
    /// each policy's keys).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    params: Vec<String>,
    /// The scenario: the controller's task, limits and default wave. The plant's physical
    /// parameters, grid and step come from the plant itself (what it tells its controllers).
    #[command(flatten)]
    scenario: ScenarioArgs,
    #[command(flatten)]
    network: crawler_transport::NetworkArgs,
    /// Seconds to wait for the plant.
    #[arg(long, default_value_t = 60.0, allow_hyphen_values = true)]
    wait_timeout: f64,
    /// Take the run over from its controller at the next step boundary (the plant hands it
    /// over between two steps: no step is lost or answered twice; the other controller ends
    /// cleanly). Without it a controller joins only a run that has no controller.
    #[arg(long)]
    take_over: bool,
    /// Take the run over at the first step at or after this simulated time, s (the plant keeps
    /// its controller until then). Implies --take-over.
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true)]
    take_over_at: Option<f64>,
    /// Testing the plant's resend path: hold the answer to step STEP for MS milliseconds (the
    /// plant resends the state meanwhile; the answer is given once, and sent again unchanged).
    #[arg(long, value_name = "STEP:MS", help_heading = "Testing")]
    stall: Option<String>,
    /// Print the final summary as JSON.
    #[arg(long)]
    json: bool,
    /// Validate every input (policy, parameters, scenario, network) and exit without joining a
    /// run.
    #[arg(long)]
    check: bool,
}

/// Runs the controller; the exit code says how the run ended.
pub fn run_client(a: RunArgs) -> anyhow::Result<ExitCode> {
    let scenario = a.scenario.load()?;
    let network = a.network.network()?;
    anyhow::ensure!(
        a.wait_timeout.is_finite() && a.wait_timeout > 0.0 && a.wait_timeout < 1e9,
        "invalid --wait-timeout = {}: allowed a number of seconds, 0 < wait-timeout < 1e9",
        crawler_cli::number(a.wait_timeout)
    );
    let params = Params::parse(&a.params)?;
    let take_over = match (a.take_over, a.take_over_at) {
        (_, Some(t)) => {
            anyhow::ensure!(
                t.is_finite() && t >= 0.0,
                "invalid --take-over-at = {}: allowed a simulated time in seconds >= 0",
                crawler_cli::number(t)
            );
            Some(TakeOver::At(t))
        }
        (true, None) => Some(TakeOver::Next),
        (false, None) => None,
    };
    let stall = a.stall.as_deref().map(parse_stall).transpose()?;
    // The policy's parameters are checked before anything starts (the policy itself is built
    // once the plant has told its body, friction and grid).
    crawler_policies::check(&a.policy, &params)?;
    if a.check {
        eprintln!(
            "crawler-controller: inputs valid (policy {}, {})",
            a.policy,
            network.describe()
        );
        return Ok(Exit::Finished.into());
    }
    let (tx, rx) = crossbeam_channel::unbounded::<Interrupt>();
    ctrlc::set_handler(move || {
        let _ = tx.send(Interrupt);
    })?;
    let opts = ClientOptions {
        policy: a.policy.clone(),
        params,
        scenario,
        network,
        wait_timeout: std::time::Duration::from_secs_f64(a.wait_timeout),
        take_over,
        stall,
    };
    match run(opts, rx)? {
        ClientOutcome::Finished(summary) => {
            if a.json {
                crawler_cli::stdout::line(format_args!(
                    "{}",
                    serde_json::to_string_pretty(&summary)?
                ))?;
            } else {
                crawler_cli::stdout::text(summary.table())?;
            }
            Ok(Exit::Finished.into())
        }
        ClientOutcome::HandedOver(summary) => {
            if a.json {
                crawler_cli::stdout::line(format_args!(
                    "{}",
                    serde_json::to_string_pretty(&summary)?
                ))?;
            } else {
                crawler_cli::stdout::text(summary.table())?;
            }
            Ok(Exit::Finished.into())
        }
        ClientOutcome::Ended { reason, exit } => {
            eprintln!("crawler-controller: run ended: {reason}");
            Ok(exit.into())
        }
    }
}

/// `--stall STEP:MS`.
fn parse_stall(text: &str) -> anyhow::Result<(u64, std::time::Duration)> {
    let bad = || {
        anyhow::anyhow!(
            "invalid --stall = {text:?}: allowed STEP:MS, two whole numbers (MS at most 600000)"
        )
    };
    let (step, ms) = text.split_once(':').ok_or_else(bad)?;
    let step: u64 = step.parse().map_err(|_| bad())?;
    let ms: u64 = ms.parse().map_err(|_| bad())?;
    if ms > 600_000 {
        return Err(bad());
    }
    Ok((step, std::time::Duration::from_millis(ms)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stall_is_a_step_and_milliseconds() {
        assert_eq!(
            parse_stall("100:600").unwrap(),
            (100, std::time::Duration::from_millis(600))
        );
        for bad in [
            "",
            "100",
            "100:",
            ":600",
            "-1:600",
            "100:-5",
            "1.5:600",
            "100:700000",
        ] {
            let e = parse_stall(bad).unwrap_err().to_string();
            assert!(
                e.contains("invalid --stall") && e.contains("allowed STEP:MS"),
                "{bad}: {e}"
            );
        }
    }
}
