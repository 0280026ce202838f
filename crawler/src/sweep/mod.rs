//! `crawler sweep` (also the `crawler-sweep` binary, which Slurm's job scripts call): runs a
//! sweep plan locally or on Slurm and writes its Parquet file, figures and recording. The sweep
//! itself is the `crawler-sweep` library; this module parses the command line and draws the maps
//! ([`Drawn`]: the heat maps of `crawler-figures` and the recording of [`recording`]).

mod recording;

pub use recording::write as write_recording;

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Arc;
use std::time::Duration;

use clap::{Args, Parser, Subcommand, ValueEnum};

use crawler_sweep::local::LocalOptions;
use crawler_sweep::plan::Plan;
use crawler_sweep::run::{Ending, Executor, MapOutputs, Paths, Sweep};
use crawler_sweep::slurm::{run_task, SlurmOptions};

#[derive(Parser)]
#[command(
    name = "crawler-sweep",
    version,
    about = "Runs a sweep plan of the soft crawler (plant, models, policies) on this machine or a Slurm cluster",
    long_about = "Runs a sweep plan: every point is evaluated once (the results are kept in a store keyed by the \
                  point's hash), so an interrupted or partly failed sweep resumes with the missing points only. \
                  Writes one Parquet file per sweep, and for plans with [figures] the heat maps and a Rerun recording.",
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Cmd>,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(Subcommand)]
enum Cmd {
    /// Merge the results of Slurm submissions into the store and write the outputs when complete.
    Collect(CollectArgs),
    /// One Slurm array task (run by the job script, not by hand).
    #[command(hide = true)]
    Task(TaskArgs),
}

#[derive(Clone, Copy, ValueEnum)]
enum ExecutorKind {
    /// All cores of this machine.
    Local,
    /// A Slurm job array.
    Slurm,
}

#[derive(Args)]
struct PathArgs {
    /// Parquet file to write (default: out/sweeps/<plan name>.parquet).
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Result store shared by plans (default: out/sweep-store).
    #[arg(long, value_name = "DIR")]
    store: Option<PathBuf>,
    /// Folder of the figures and the recording (default: out/sweeps/<plan name>/).
    #[arg(long, value_name = "DIR")]
    figures_dir: Option<PathBuf>,
    /// Folder of the Slurm submissions; must be shared with the compute nodes
    /// (default: out/sweeps/<plan name>.slurm/).
    #[arg(long, value_name = "DIR")]
    slurm_dir: Option<PathBuf>,
    /// Do not draw figures or write the recording.
    #[arg(long)]
    no_figures: bool,
}

#[derive(Args)]
struct RunArgs {
    /// The plan (TOML).
    #[arg(value_name = "PLAN.toml", required = true)]
    plan: Option<PathBuf>,
    #[command(flatten)]
    paths: PathArgs,
    /// Where the points run.
    #[arg(long, value_enum, default_value = "local")]
    executor: ExecutorKind,
    /// local: worker threads (default: all cores).
    #[arg(long, value_name = "N")]
    jobs: Option<usize>,
    /// Also rerun points whose evaluation failed before.
    #[arg(long)]
    retry_failed: bool,
    /// No progress bar.
    #[arg(long)]
    no_progress: bool,
    /// Resolve and validate the plan, print how many points are stored and to run, run nothing.
    #[arg(long)]
    dry_run: bool,
    /// slurm: points per array task (default: >= 16, and at most 1000 tasks).
    #[arg(long, value_name = "N")]
    chunk: Option<usize>,
    /// slurm: partition.
    #[arg(long)]
    partition: Option<String>,
    /// slurm: time limit per array task (e.g. 00:30:00).
    #[arg(long)]
    time: Option<String>,
    /// slurm: memory per array task (e.g. 1G).
    #[arg(long)]
    mem: Option<String>,
    /// slurm: at most this many array tasks at once.
    #[arg(long, value_name = "N")]
    max_running: Option<usize>,
    /// slurm: one more sbatch argument, as it is (repeat for several), e.g. --sbatch-arg=--account=lab.
    #[arg(long = "sbatch-arg", value_name = "ARG", allow_hyphen_values = true)]
    sbatch_args: Vec<String>,
    /// slurm: wait for the job array, then collect its results and write the outputs.
    #[arg(long)]
    wait: bool,
    /// slurm: seconds between queue polls while waiting.
    #[arg(long, default_value_t = 1.0, value_name = "SECONDS")]
    poll: f64,
}

#[derive(Args)]
struct CollectArgs {
    /// The plan (TOML).
    #[arg(value_name = "PLAN.toml")]
    plan: PathBuf,
    #[command(flatten)]
    paths: PathArgs,
}

#[derive(Args)]
struct TaskArgs {
    /// The submission's manifest.
    #[arg(long, value_name = "FILE")]
    manifest: PathBuf,
    /// The array task index ($SLURM_ARRAY_TASK_ID).
    #[arg(long)]
    task: usize,
}

fn paths_for(plan: &Plan, a: &PathArgs) -> Paths {
    let d = Paths::defaults(plan, &PathBuf::from("out"));
    Paths {
        out: a.out.clone().unwrap_or(d.out),
        store: a.store.clone().unwrap_or(d.store),
        figures: a.figures_dir.clone().unwrap_or(d.figures),
        slurm: a.slurm_dir.clone().unwrap_or(d.slurm),
    }
}

/// Ctrl-C: the first stops starting new points (or stops waiting for Slurm); the second exits.
fn interrupt_flag() -> anyhow::Result<Arc<AtomicBool>> {
    let flag = Arc::new(AtomicBool::new(false));
    let presses = Arc::new(AtomicU32::new(0));
    let f = flag.clone();
    ctrlc::set_handler(move || {
        if presses.fetch_add(1, Ordering::SeqCst) == 0 {
            f.store(true, Ordering::SeqCst);
            eprintln!("\ncrawler-sweep: interrupted: finishing the running points (Ctrl-C again to abort them)");
        } else {
            eprintln!("\ncrawler-sweep: aborted; the points finished so far are stored");
            std::process::exit(130);
        }
    })?;
    Ok(flag)
}

fn exit_of(ending: Ending) -> ExitCode {
    match ending {
        Ending::Complete { .. } => ExitCode::SUCCESS,
        Ending::Interrupted { .. } => ExitCode::from(130),
        Ending::Submitted { .. } => ExitCode::SUCCESS,
        Ending::Incomplete { missing, logs } => {
            eprintln!(
                "crawler-sweep: {missing} points have no result yet (tasks still running, or failed); \
                 run the plan again to submit them again"
            );
            for l in logs.iter().take(10) {
                eprintln!("{l}");
            }
            ExitCode::FAILURE
        }
    }
}

/// The maps of a plan as this program draws them: PNG heat maps and a Rerun recording.
struct Drawn;

impl MapOutputs for Drawn {
    fn write(
        &self,
        plan: &Plan,
        maps: &crawler_sweep::maps::Maps,
        dir: &std::path::Path,
    ) -> anyhow::Result<Vec<PathBuf>> {
        let mut written = crawler_figures::maps::draw(plan, maps, dir)?;
        let rrd = dir.join(format!("{}.rrd", plan.name));
        recording::write(plan, maps, &rrd)?;
        written.push(rrd);
        Ok(written)
    }
}

/// The map outputs unless `--no-figures`.
fn drawn(no_figures: bool) -> Option<&'static dyn MapOutputs> {
    (!no_figures).then_some(&Drawn as &dyn MapOutputs)
}

fn run(a: RunArgs) -> anyhow::Result<ExitCode> {
    let plan_path = a.plan.expect("clap requires the plan");
    let plan = Plan::from_file(&plan_path)?;
    let paths = paths_for(&plan, &a.paths);
    let sweep = Sweep::open(plan, paths)?;
    if a.dry_run {
        let missing = sweep.missing(a.retry_failed)?;
        let cost: f64 = missing
            .iter()
            .map(|p| crawler_sweep::point::cost(p, &sweep.plan.evaluate))
            .sum();
        println!(
            "plan {}: {} points, {} stored, {} to run (about {cost:.3e} plant cell updates)",
            sweep.plan.name,
            sweep.points.len(),
            sweep.points.len() - missing.len(),
            missing.len()
        );
        return Ok(ExitCode::SUCCESS);
    }
    anyhow::ensure!(
        a.poll.is_finite() && (0.05..=600.0).contains(&a.poll),
        "invalid --poll = {}: allowed 0.05 <= seconds <= 600",
        a.poll
    );
    if let Some(0) = a.jobs {
        anyhow::bail!("invalid --jobs = 0: allowed an integer >= 1");
    }
    if let Some(0) = a.chunk {
        anyhow::bail!("invalid --chunk = 0: allowed an integer >= 1");
    }
    if let Some(0) = a.max_running {
        anyhow::bail!("invalid --max-running = 0: allowed an integer >= 1");
    }
    let progress = !a.no_progress;
    let executor = match a.executor {
        ExecutorKind::Local => Executor::Local(LocalOptions {
            jobs: a
                .jobs
                .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())),
            progress,
        }),
        ExecutorKind::Slurm => Executor::Slurm {
            options: SlurmOptions {
                chunk: a.chunk,
                partition: a.partition,
                time: a.time,
                mem: a.mem,
                max_running: a.max_running,
                sbatch_args: a.sbatch_args,
            },
            wait: a.wait,
            poll: Duration::from_secs_f64(a.poll),
            progress,
        },
    };
    let interrupt = interrupt_flag()?;
    let ending = sweep.run(
        &executor,
        a.retry_failed,
        drawn(a.paths.no_figures),
        &interrupt,
    )?;
    if interrupt.load(Ordering::SeqCst) {
        if let Ending::Submitted { .. } = ending {
            return Ok(ExitCode::from(130));
        }
    }
    Ok(exit_of(ending))
}

/// Runs the program with the command line `args` (the program's name first).
pub fn main<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = Cli::parse_from(args);
    let result = match cli.command {
        Some(Cmd::Collect(c)) => (|| {
            let plan = Plan::from_file(&c.plan)?;
            let paths = paths_for(&plan, &c.paths);
            let sweep = Sweep::open(plan, paths)?;
            Ok(exit_of(sweep.collect(drawn(c.paths.no_figures))?))
        })(),
        Some(Cmd::Task(t)) => run_task(&t.manifest, t.task).map(|n| {
            eprintln!("crawler-sweep: task {} finished: {n} points", t.task);
            ExitCode::SUCCESS
        }),
        None => run(cli.run),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("crawler-sweep: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
