//! `crawler-controller run`: a policy controlling a co-simulation run over zenoh.

use std::process::ExitCode;

use clap::Args;

use crate::client::{run, ClientOptions, ClientOutcome, Interrupt};
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
        ClientOutcome::Ended { reason, exit } => {
            eprintln!("crawler-controller: run ended: {reason}");
            Ok(exit.into())
        }
    }
}
