//! The recorder's command line (`crawler-recorder record`, also `crawler record`): parses it and
//! hands it to [`crate::session`].

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

use crate::session::{self, Settings};
use crate::RecorderOptions;
use crawler_cli::Exit;

#[derive(Parser)]
#[command(
    name = "crawler-recorder",
    version,
    about = "Records a soft-crawler co-simulation into a Rerun .rrd file"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Subscribe to a run (before or after it starts) and record it until it ends.
    Record(RecordArgs),
}

#[derive(Args)]
struct RecordArgs {
    #[command(flatten)]
    network: crawler_transport::NetworkArgs,
    /// Output file.
    #[arg(long, value_name = "FILE.rrd", default_value = "crawler.rrd")]
    out: PathBuf,
    /// Record the fields of every K-th step (every step's scalars, metrics, events and lanes are
    /// always recorded).
    #[arg(long, value_name = "K", default_value_t = 1)]
    every: u64,
    /// Most stick/slip lanes (evenly spaced nodes).
    #[arg(long, default_value_t = 64)]
    lanes: usize,
    /// Recorded steps per heatmap block.
    #[arg(long, default_value_t = 256)]
    heatmap_rows: usize,
    /// States per block sent to the file (one chunk per entity per block; default: as many as
    /// make the body's chunk about 512 KiB).
    #[arg(long, value_name = "STATES")]
    block: Option<usize>,
    /// Capacity of the inbox between the zenoh callbacks and the writer, messages (the byte
    /// budgets bound its memory: 8 MiB of states, 16 MiB of the rest, 4 MiB of statuses).
    #[arg(long, default_value_t = 65536)]
    inbox: usize,
    /// Leave out the index of chunks (Rerun's footer) at the end of the file: memory stays flat
    /// however long the run (the index costs about 40 MB per 10^6 steps), but `rerun rrd verify`
    /// needs `--check-footers=false` (or add the index later with `rerun rrd optimize`).
    #[arg(long)]
    no_footer: bool,
    /// Leave the file's chunks as they were written (one per entity per block, or per flush)
    /// instead of merging them at close, the equivalent of `rerun rrd optimize`.
    #[arg(long)]
    no_optimize: bool,
    /// Also stream the recording live to a running Rerun viewer at URL (its gRPC address) while
    /// writing the file: every scalar, and the fields of the last state of each block. Start one
    /// with `rerun` (or `.venv/bin/rerun`), or pass --spawn. A viewer that is absent, slow or
    /// closed never stops the recording: it misses data, the file does not.
    #[arg(long, value_name = "URL", num_args = 0..=1, default_missing_value = crate::viewer::DEFAULT_URL)]
    connect: Option<String>,
    /// Start a Rerun viewer (listening on loopback at the --connect port, default 9876) unless one
    /// already runs there, and stream to it; implies --connect.
    #[arg(long)]
    spawn: bool,
    /// The `rerun` executable --spawn starts (default: `rerun` from PATH).
    #[arg(long, value_name = "PATH", requires = "spawn")]
    viewer_exe: Option<PathBuf>,
    /// Give up if no message arrives for this many seconds (default: wait as long as it takes).
    #[arg(long)]
    idle_timeout: Option<f64>,
    /// Validate every input (flags, --out, --connect, network options) and exit without
    /// creating a file or subscribing to anything.
    #[arg(long)]
    check: bool,
}

/// One malloc arena for the whole process. glibc gives threads their own arenas; the Rerun SDK's
/// batcher and file writer allocate chunk buffers on one thread and free them on another, which
/// fragments the arenas, and the resident memory crept up by about 55 % over a 10^6-step run.
/// With one arena it stays flat (`bench/long_run.py`). Must run before any thread starts.
fn one_malloc_arena() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes allocator tuning; called before any other thread exists.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}

fn settings(a: RecordArgs) -> anyhow::Result<Settings> {
    Ok(Settings {
        network: a.network.network()?,
        out: a.out,
        opts: RecorderOptions {
            every: a.every,
            lanes: a.lanes,
            heatmap_rows: a.heatmap_rows,
            block_states: a.block,
            ..Default::default()
        },
        inbox: a.inbox,
        footer: !a.no_footer,
        optimize: !a.no_optimize,
        connect: a.connect,
        spawn: a.spawn,
        viewer_exe: a.viewer_exe,
        idle_timeout: a.idle_timeout,
    })
}

/// Runs the recorder's command line `args` (the program's name first) and returns its exit code.
pub fn main<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    one_malloc_arena();
    crawler_cli::cpu::ensure_cpu_features();
    let Command::Record(a) = Cli::parse_from(args).command;
    let check = a.check;
    let run = || -> anyhow::Result<Exit> {
        let s = settings(a)?;
        if check {
            s.validate()?;
            eprintln!("crawler-recorder: inputs valid ({})", s.network.describe());
            return Ok(Exit::Finished);
        }
        session::record(s)
    };
    match run() {
        Ok(code) => code.into(),
        Err(e) => {
            eprintln!("crawler-recorder: error: {e:#}");
            Exit::Failure.into()
        }
    }
}
