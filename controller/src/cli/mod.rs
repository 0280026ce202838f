//! The `crawler-controller` program's command line (also `crawler controller`): predictions, the
//! optimal policy, figures, and policies controlling a co-simulation. The binary's `main` calls
//! [`main`]; each subcommand with options of its own has a module.

use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

use crawler_cli::Exit;
use crawler_cli::ScenarioArgs;
use crawler_policies::REGISTRY;

use optimize::OptimizeArgs;
use predict::PredictArgs;
use run::RunArgs;

/// `println!` that returns the error instead of panicking: a reader that closed the pipe ends
/// the output (`crawler_cli::stdout`).
macro_rules! out {
    ($($arg:tt)*) => {
        crawler_cli::stdout::line(format_args!($($arg)*))?
    };
}

mod optimize;
mod predict;
mod run;

#[derive(Parser)]
#[command(
    name = "crawler-controller",
    version,
    about = "Soft-crawler models, optimal policy and controllers"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Predict the steady state with a reduced model (same flags as `crawler-plant simulate`).
    Predict(PredictArgs),
    /// Maximise V subject to mileage, stress, strain and actuator limits.
    Optimize(OptimizeArgs),
    /// List the registered policies.
    Policies,
    /// Time the optimiser and the improved model against one plant run (prints JSON).
    Bench,
    /// Write the paper's Fig. 5 and Fig. 6 (paper model beside the improved model) as PNG and CSV.
    Figures(FiguresArgs),
    /// Control a co-simulation run over zenoh: answer every plant state with an actuation.
    Run(RunArgs),
}

#[derive(Args)]
struct FiguresArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// Output directory.
    #[arg(long, default_value = "out/figures")]
    out: std::path::PathBuf,
    /// Points per axis of the omega-k planes with the improved model.
    #[arg(long, default_value_t = 36)]
    improved_points: usize,
}

/// Runs the program with the command line `args` (the program's name first); the exit code says
/// how it ended (`crawler_cli::Exit`).
pub fn main<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    crawler_cli::cpu::ensure_cpu_features();
    let cli = Cli::parse_from(args);
    if let Command::Run(a) = cli.command {
        return match run::run_client(a) {
            Ok(code) => code,
            Err(e) if crawler_cli::stdout::is_broken_pipe(e.as_ref()) => Exit::Finished.into(),
            Err(e) => {
                eprintln!("crawler-controller: error: {e:#}");
                Exit::Failure.into()
            }
        };
    }
    match dispatch(cli) {
        Ok(()) => Exit::Finished.into(),
        // the reader of the output went away (`| head`): the output ends there
        Err(e) if crawler_cli::stdout::is_broken_pipe(e.as_ref()) => Exit::Finished.into(),
        Err(e) => {
            eprintln!("crawler-controller: error: {e:#}");
            Exit::Failure.into()
        }
    }
}

fn dispatch(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Run(_) => unreachable!("handled in main"),
        Command::Predict(a) => predict::predict(a),
        Command::Optimize(a) => optimize::optimize(a),
        Command::Figures(a) => {
            let scenario = a.scenario.load()?;
            anyhow::ensure!(
                (4..=400).contains(&a.improved_points),
                "invalid --improved-points = {}: allowed 4 to 400",
                a.improved_points
            );
            let opts = crawler_figures::FigureOptions {
                plane_points_improved: a.improved_points,
                ..Default::default()
            };
            for f in crawler_figures::write_figures(&scenario, &a.out, opts)? {
                out!("{}", f.display());
            }
            Ok(())
        }
        Command::Bench => {
            let r = crawler_models::bench::run(&crawler_physics::scenario::Scenario::paper())?;
            out!("{}", serde_json::to_string(&r)?);
            Ok(())
        }
        Command::Policies => {
            for e in REGISTRY {
                out!("{:<10} {}", e.name, e.help);
                for k in e.keys {
                    out!("    --param {}=...  {}", k.name, k.doc);
                }
            }
            Ok(())
        }
    }
}
