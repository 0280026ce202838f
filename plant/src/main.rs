//! `crawler-plant`: the crawler plant, in process (`simulate`) or as a co-simulation slave (`run`).

use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use crawler_plant::scenario_args::ScenarioArgs;
use crawler_plant::simulate::{simulate, SimulateOptions};

#[derive(Parser)]
#[command(
    name = "crawler-plant",
    version,
    about = "Soft-crawler plant: finite differences with exact stick-slip friction"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the plant in process under the scenario's travelling wave (no zenoh).
    Simulate(SimulateArgs),
    /// Print the model description (value references, units) as JSON or modelDescription.xml.
    Describe(DescribeArgs),
}

#[derive(Args)]
struct SimulateArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// Print one JSON object (SI units) instead of a summary.
    #[arg(long)]
    json: bool,
    /// Largest number of stick-slip episodes listed (all are counted).
    #[arg(long, default_value_t = 10_000)]
    max_episodes: usize,
}

#[derive(Args)]
struct DescribeArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// FMI-style modelDescription.xml instead of JSON.
    #[arg(long)]
    xml: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("crawler-plant: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Simulate(a) => {
            let scenario = a.scenario.load()?;
            let report = simulate(
                &scenario,
                SimulateOptions {
                    max_episodes: a.max_episodes,
                    progress: true,
                },
            )?;
            if a.json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                let p = &report.parameters;
                println!("scenario {}: eps = {}, n_F = {}, f0 = {} N, k = {:.4} rad/m, omega = {:.3} rad/s (alpha = {:.3})",
                    report.scenario, p.eps, p.n_f, p.f0, p.k, p.omega, p.alpha);
                println!("grid: {} cells, dt = {:.3e} s, {} steps to t = {} s; window {:.3}-{:.3} s ({:.1} periods)",
                    report.cells, report.dt, report.steps, report.t_end, report.window.start, report.window.end, report.window.periods);
                println!("  velocity V        {:+.6e} m/s", report.velocity);
                println!("  power P           {:.6e} W", report.power);
                println!("  mileage M         {:.6e} m/J", report.mileage);
                println!("  max stress        {:.6e} Pa", report.max_stress);
                println!("  max strain        {:.6e}", report.max_strain);
                println!("  stuck fraction    {:.4}", report.stuck_fraction);
                println!("  <s>               {:+.6}", report.mean_friction_selection);
                println!(
                    "  episodes          {} ({:.3} per node per period, mean {:.3e} s)",
                    report.events.count,
                    report.events.per_node_per_period,
                    report.events.mean_duration
                );
            }
            Ok(())
        }
        Command::Describe(a) => {
            let scenario = a.scenario.load()?;
            let md = crawler_plant::model_description::ModelDescription::new(&scenario.plant);
            if a.xml {
                print!("{}", md.to_xml());
            } else {
                println!("{}", md.to_json());
            }
            Ok(())
        }
    }
}
