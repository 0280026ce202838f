//! The `crawler-plant` program's command line (also `crawler plant`): the crawler plant, in
//! process (`simulate`) or as a co-simulation slave (`run`). The binary's `main` calls [`main`].

use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use crawler_cli::{Exit, ScenarioArgs};
use crawler_physics::simulate::{simulate, SimulateOptions};

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
    /// Time the stepping loop: cell updates per second, single thread (prints JSON).
    Bench(BenchArgs),
    /// Run as the co-simulation plant over zenoh: owns the clock, steps in lockstep with a controller.
    Run(Box<RunArgs>),
}

#[derive(Args)]
struct RunArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    #[command(flatten)]
    network: crawler_transport::NetworkArgs,
    /// Communication step H, s (default: the scenario's numerics.step).
    #[arg(long, allow_hyphen_values = true)]
    step: Option<f64>,
    /// Resume a stopped run from its checkpoint (the checkpoint's scenario and run id are used).
    #[arg(long, value_name = "CHECKPOINT", conflicts_with = "scenario")]
    resume: Option<std::path::PathBuf>,
    /// Where to write the checkpoint if the run stops early (default:
    /// runs/<run-id>/plant.ckpt, directories created as needed).
    #[arg(long, value_name = "FILE")]
    checkpoint: Option<std::path::PathBuf>,
    /// Validate every input (scenario, resume file, checkpoint path, network options), print
    /// what the run will cost, and exit without starting it.
    #[arg(long)]
    check: bool,
    /// Seconds to wait for a controller to join.
    #[arg(long, default_value_t = 60.0)]
    wait_timeout: f64,
    /// Seconds to wait for the controller's answer to one state.
    #[arg(long, default_value_t = 30.0)]
    step_timeout: f64,
    /// When the run's controller leaves: `stop` (with a checkpoint, exit code 3), or `wait` (keep
    /// the clock at its step until a controller takes the run over with `crawler-controller run
    /// --take-over`; `wait:SECONDS` bounds the wait, by default --wait-timeout, then stop).
    #[arg(long, default_value = "stop", value_name = "stop|wait[:SECONDS]")]
    on_controller_lost: String,
    /// Print the final report as JSON (the same object as `simulate --json`).
    #[arg(long)]
    json: bool,
    /// With --json: also list every stick-slip episode of the steady window (up to
    /// --max-episodes; without this flag the JSON gives only their count and statistics).
    #[arg(long, requires = "json")]
    episodes: bool,
    /// Largest number of stick-slip episodes listed (all are counted).
    #[arg(long, default_value_t = 10_000)]
    max_episodes: usize,
}

#[derive(Args)]
struct BenchArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// Wall time per measurement, s.
    #[arg(long, default_value_t = 2.0)]
    seconds: f64,
    /// Plants stepped in turn, one communication step each (1 to 1024).
    #[arg(long, default_value_t = 1)]
    plants: usize,
}

#[derive(Args)]
struct SimulateArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// Print one JSON object (SI units) instead of a summary.
    #[arg(long)]
    json: bool,
    /// With --json: also list every stick-slip episode of the steady window (up to
    /// --max-episodes; without this flag the JSON gives only their count and statistics).
    #[arg(long, requires = "json")]
    episodes: bool,
    /// Largest number of stick-slip episodes listed (all are counted).
    #[arg(long, default_value_t = 10_000)]
    max_episodes: usize,
    /// Also run on twice as many cells and report each metric's estimated discretisation error.
    #[arg(long)]
    convergence: bool,
}

#[derive(Args)]
struct DescribeArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// FMI 3.0 modelDescription.xml instead of JSON (the FMUs' own: scripts/build-fmu.sh).
    #[arg(long)]
    xml: bool,
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
    match dispatch(cli) {
        Ok(code) => code,
        // the reader of the output went away (`simulate --json | head`): the end of the output
        Err(e) if crawler_cli::stdout::is_broken_pipe(e.as_ref()) => Exit::Finished.into(),
        Err(e) => {
            eprintln!("crawler-plant: error: {e:#}");
            Exit::Failure.into()
        }
    }
}

fn dispatch(cli: Cli) -> anyhow::Result<ExitCode> {
    if let Command::Run(a) = cli.command {
        return cosim(*a);
    }
    run(cli).map(|()| Exit::Finished.into())
}

fn seconds(name: &str, x: f64) -> anyhow::Result<std::time::Duration> {
    anyhow::ensure!(
        x.is_finite() && x > 0.0 && x < 1e9,
        "invalid --{name} = {}: allowed a number of seconds, 0 < {name} < 1e9",
        crawler_cli::number(x)
    );
    Ok(std::time::Duration::from_secs_f64(x))
}

fn cosim(a: RunArgs) -> anyhow::Result<ExitCode> {
    use crate::checkpoint::Checkpoint;
    use crate::link::Control;
    use crate::runner::{run, Outcome, RunOptions};
    let resume = a.resume.as_deref().map(Checkpoint::load).transpose()?;
    let mut net_args = a.network.clone();
    if let (Some(c), None) = (&resume, &a.network.run_id) {
        net_args.run_id = Some(c.run_id.clone());
    }
    let network = net_args.network()?;
    let scenario = match &resume {
        Some(c) => c.scenario.clone(),
        None => {
            let mut s = a.scenario.load()?;
            if let Some(h) = a.step {
                s.plant.numerics.step = h;
                s.plant.validate()?;
                anyhow::ensure!(
                    h <= s.t_end,
                    "invalid --step = {h}: allowed 0 < step <= t_end = {}",
                    s.t_end
                );
            }
            s
        }
    };
    if let (Some(c), Some(t)) = (&resume, a.scenario.t_end) {
        anyhow::ensure!(
            (t - c.scenario.t_end).abs() < 1e-12,
            "--t-end = {t} differs from the checkpoint's t_end = {}: a resumed run ends where the original would",
            c.scenario.t_end
        );
    }
    let (tx, rx) = crossbeam_channel::unbounded::<Control>();
    let interrupt = tx.clone();
    ctrlc::set_handler(move || {
        let _ = interrupt.send(Control::Interrupt);
    })?;
    let checkpoint = a.checkpoint.clone().unwrap_or_else(|| {
        std::path::Path::new("runs")
            .join(&network.run_id)
            .join("plant.ckpt")
    });
    check_checkpoint_path(&checkpoint)?;
    let wait_timeout = seconds("wait-timeout", a.wait_timeout)?;
    let step_timeout = seconds("step-timeout", a.step_timeout)?;
    let on_controller_lost = on_lost(&a.on_controller_lost, wait_timeout)?;
    for note in crate::preflight::notes(&scenario) {
        eprintln!("crawler-plant: {note}");
    }
    if a.check {
        // the run id must be free (the claim is released at once)
        drop(crawler_transport::runtime_dir::claim(&network.run_id)?);
        eprintln!("crawler-plant: inputs valid ({})", network.describe());
        return Ok(Exit::Finished.into());
    }
    let opts = RunOptions {
        scenario,
        network,
        wait_timeout,
        step_timeout,
        checkpoint,
        resume,
        max_episodes: a.max_episodes,
        on_controller_lost,
    };
    match run(opts, tx, rx)? {
        Outcome::Finished(report) => {
            if a.json {
                crawler_cli::stdout::line(report_json(&report, a.episodes)?)?;
            } else {
                crawler_cli::stdout::line(report.summary())?;
            }
            Ok(Exit::Finished.into())
        }
        Outcome::Stopped {
            reason,
            checkpoint,
            exit,
        } => {
            match checkpoint {
                Some(c) => eprintln!(
                    "crawler-plant: run stopped: {reason}. Checkpoint: {} (continue with: crawler-plant run --resume {})",
                    c.display(),
                    c.display()
                ),
                None => eprintln!("crawler-plant: run stopped: {reason} (nothing simulated, no checkpoint written)"),
            }
            Ok(exit.into())
        }
    }
}

/// `--on-controller-lost`: `stop`, `wait` (as long as `wait_timeout`) or `wait:SECONDS`.
fn on_lost(text: &str, wait_timeout: std::time::Duration) -> anyhow::Result<crate::runner::OnLost> {
    use crate::runner::OnLost;
    let bad = || {
        anyhow::anyhow!(
            "invalid --on-controller-lost = {text:?}: allowed stop, wait or wait:SECONDS (0 < SECONDS < 1e9)"
        )
    };
    match text.split_once(':') {
        None if text == "stop" => Ok(OnLost::Stop),
        None if text == "wait" => Ok(OnLost::Wait(wait_timeout)),
        Some(("wait", secs)) => {
            let x: f64 = secs.parse().map_err(|_| bad())?;
            seconds("on-controller-lost", x)
                .map(OnLost::Wait)
                .map_err(|_| bad())
        }
        _ => Err(bad()),
    }
}

/// A checkpoint path the plant can write when the run stops: not a directory, and its
/// directory exists or can be created (the nearest existing one is a directory whose mode lets
/// its owner write). Nothing is created or truncated here.
fn check_checkpoint_path(path: &std::path::Path) -> anyhow::Result<()> {
    anyhow::ensure!(
        !path.is_dir(),
        "invalid --checkpoint = {}: a directory; allowed a file path",
        path.display()
    );
    let mut dir = path.parent();
    loop {
        let d = match dir.filter(|d| !d.as_os_str().is_empty()) {
            Some(d) => d,
            None => std::path::Path::new("."),
        };
        if let Ok(meta) = std::fs::metadata(d) {
            anyhow::ensure!(
                meta.is_dir(),
                "invalid --checkpoint = {}: {} is not a directory",
                path.display(),
                d.display()
            );
            anyhow::ensure!(
                !meta.permissions().readonly(),
                "invalid --checkpoint = {}: the directory {} is read-only; allowed a file path where the plant can write",
                path.display(),
                d.display()
            );
            return Ok(());
        }
        match d.parent() {
            Some(p) if d != std::path::Path::new(".") => dir = Some(p),
            _ => return Ok(()),
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Run(_) => unreachable!("handled by dispatch"),
        Command::Simulate(a) => {
            let scenario = a.scenario.load()?;
            for note in crate::preflight::notes(&scenario) {
                eprintln!("crawler-plant: {note}");
            }
            let bar = crawler_cli::progress::bar(0, "simulating");
            let mut show = |done: u64, total: u64| {
                bar.set_length(total);
                bar.set_position(done);
            };
            if a.convergence {
                let c = crawler_physics::convergence::estimate(
                    &scenario,
                    listed(a.json && a.episodes, a.max_episodes),
                    Some(&mut show),
                )?;
                bar.finish_and_clear();
                if a.json {
                    crawler_cli::stdout::line(report_json(&c, a.episodes)?)?;
                } else {
                    crawler_cli::stdout::line(format!(
                        "{}\n\n{}",
                        c.coarse.summary(),
                        c.summary()
                    ))?;
                }
                return Ok(());
            }
            let report = simulate(
                &scenario,
                SimulateOptions {
                    max_episodes: listed(a.json && a.episodes, a.max_episodes),
                    progress: Some(&mut show),
                },
            )?;
            bar.finish_and_clear();
            if a.json {
                crawler_cli::stdout::line(report_json(&report, a.episodes)?)?;
            } else {
                crawler_cli::stdout::line(report.summary())?;
            }
            Ok(())
        }
        Command::Bench(a) => {
            let scenario = a.scenario.load()?;
            anyhow::ensure!(
                a.seconds.is_finite() && a.seconds > 0.0 && a.seconds <= 3600.0,
                "invalid --seconds = {}: allowed a wall time in seconds, 0 < seconds <= 3600",
                crawler_cli::number(a.seconds)
            );
            anyhow::ensure!(
                (1..=1024).contains(&a.plants),
                "invalid --plants = {}: allowed 1 to 1024 plants",
                a.plants
            );
            let cells = scenario.plant.numerics.cells;
            let r = crate::bench::bench(&scenario, cells, a.plants, a.seconds)?;
            crawler_cli::stdout::line(serde_json::to_string(&r)?)?;
            Ok(())
        }
        Command::Describe(a) => {
            let scenario = a.scenario.load()?;
            // The scenario's wave as the inputs' start values and its run as the default
            // experiment: the description of the FMU built from this scenario.
            let md = crawler_physics::model_description::ModelDescription::for_run(
                &scenario.plant,
                scenario.wave,
                scenario.t_end,
            );
            if a.xml {
                crawler_cli::stdout::text(md.to_xml())?;
            } else {
                crawler_cli::stdout::line(md.to_json())?;
            }
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runner::OnLost;
    use std::time::Duration;

    #[test]
    fn on_controller_lost_is_stop_wait_or_wait_for_some_seconds() {
        let w = Duration::from_secs(60);
        assert_eq!(on_lost("stop", w).unwrap(), OnLost::Stop);
        assert_eq!(on_lost("wait", w).unwrap(), OnLost::Wait(w));
        assert_eq!(
            on_lost("wait:2.5", w).unwrap(),
            OnLost::Wait(Duration::from_millis(2500))
        );
        for bad in [
            "", "Stop", "wait:", "wait:-1", "wait:0", "wait:nan", "stop:3", "go",
        ] {
            let e = on_lost(bad, w).unwrap_err().to_string();
            assert!(
                e.contains("invalid --on-controller-lost")
                    && e.contains("allowed stop, wait or wait:SECONDS"),
                "{bad}: {e}"
            );
        }
    }
}

/// A report as pretty JSON; without `episodes` every `events` object keeps the episodes' count
/// and statistics but not their list (a steady window holds hundreds of thousands of them, which
/// made the default output megabytes long).
fn report_json<T: serde::Serialize>(report: &T, episodes: bool) -> anyhow::Result<String> {
    let mut value = serde_json::to_value(report)?;
    if !episodes {
        drop_episode_lists(&mut value);
    }
    Ok(serde_json::to_string_pretty(&value)?)
}

/// How many episodes a run keeps in its list: none unless the output shows the list (the counts
/// and statistics do not depend on it), so a long run does not hold them in memory for nothing.
fn listed(shown: bool, max_episodes: usize) -> usize {
    if shown {
        max_episodes
    } else {
        0
    }
}

fn drop_episode_lists(value: &mut serde_json::Value) {
    match value {
        serde_json::Value::Object(map) => {
            if let Some(serde_json::Value::Object(events)) = map.get_mut("events") {
                events.remove("episodes");
                events.remove("episodes_truncated");
            }
            map.values_mut().for_each(drop_episode_lists);
        }
        serde_json::Value::Array(items) => items.iter_mut().for_each(drop_episode_lists),
        _ => {}
    }
}

#[cfg(test)]
mod json_tests {
    use super::*;

    #[test]
    fn the_json_report_lists_episodes_only_when_asked() {
        let report = serde_json::json!({
            "velocity": 1.0,
            "events": {"count": 2, "episodes": [{"node": 1}, {"node": 2}], "episodes_truncated": false},
            "coarse": {"events": {"count": 1, "episodes": [{"node": 3}], "episodes_truncated": false}},
        });
        let compact: serde_json::Value =
            serde_json::from_str(&report_json(&report, false).unwrap()).unwrap();
        assert_eq!(compact["events"]["count"], 2);
        assert!(compact["events"].get("episodes").is_none());
        assert!(compact["coarse"]["events"].get("episodes").is_none());
        let full: serde_json::Value =
            serde_json::from_str(&report_json(&report, true).unwrap()).unwrap();
        assert_eq!(full, report);
    }
}
