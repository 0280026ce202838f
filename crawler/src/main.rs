//! `crawler`: the soft-crawler co-simulation in one command (`crawler run`), the policy
//! comparison (`crawler compare`), sweeps (`crawler sweep`), and each program of the project
//! under one name (`crawler plant ...`, `crawler controller ...`, `crawler record ...`).

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use crawler::{compare, run};
use crawler_cli::Exit;

#[derive(Parser)]
#[command(
    name = "crawler",
    version,
    about = "The soft-crawler co-simulation: plant, controller and recorder in one command, comparisons and sweeps"
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run plant, controller and recorder on loopback and leave a Rerun recording.
    Run(Box<run::RunArgs>),
    /// Every policy through the co-simulation in every case of the task; a table and recordings.
    Compare(compare::CompareArgs),
    /// Run a sweep plan on all cores or on Slurm (`crawler sweep --help`).
    #[command(disable_help_flag = true)]
    Sweep {
        /// The sweep's arguments (a plan file, `collect PLAN`, options).
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// The plant: `simulate`, `describe`, `bench`, `run` (also the `crawler-plant` binary).
    #[command(disable_help_flag = true)]
    Plant {
        /// The plant's arguments (`crawler plant --help`).
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// The recorder: subscribe to a run and record it into a Rerun file (also the
    /// `crawler-recorder record` binary).
    #[command(disable_help_flag = true)]
    Record {
        /// The recorder's arguments (`crawler record --help`).
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// The controller: `predict`, `optimize`, `figures`, `policies`, `run` (also the
    /// `crawler-controller` binary).
    #[command(disable_help_flag = true)]
    Controller {
        /// The controller's arguments (`crawler controller --help`).
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
}

/// A program's command line: its name, then `args`.
fn named(name: &str, args: Vec<String>) -> Vec<String> {
    std::iter::once(name.to_string()).chain(args).collect()
}

fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Cmd::Run(a) => run::run(*a),
        Cmd::Compare(a) => compare::compare(a),
        Cmd::Sweep { args } => Ok(crawler::sweep::main(named("crawler sweep", args))),
        Cmd::Plant { args } => Ok(crawler_plant::cli::main(named("crawler plant", args))),
        Cmd::Record { args } => Ok(crawler_recorder::cli::main(
            ["crawler".to_string(), "record".to_string()]
                .into_iter()
                .chain(args),
        )),
        Cmd::Controller { args } => Ok(crawler_controller::cli::main(named(
            "crawler controller",
            args,
        ))),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("crawler: error: {e:#}");
            Exit::Failure.into()
        }
    }
}
