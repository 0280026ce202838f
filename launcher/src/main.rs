//! `crawler run`: the whole co-simulation in one command.
//!
//! Starts the recorder (`crawler-bridge`), the plant (`crawler-plant run`) and the controller
//! (`crawler-controller run`) as three processes on loopback for one run id, forwards their logs
//! with a prefix, waits for them, and prints the plant's summary and the controller's table of
//! predicted against simulated metrics. The recording is left in `--out` (default `crawler.rrd`).
//!
//! The run is authenticated: the launcher creates a fresh credential in the run's private
//! directory (mode 0600 in a 0700 directory), hands its path to the three processes and removes
//! it when they are done.

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitCode, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::{Args, Parser, Subcommand};
use crawler_cli::Exit;

mod compare;
mod preflight;

#[derive(Parser)]
#[command(
    name = "crawler",
    version,
    about = "Runs the soft-crawler co-simulation: plant, controller and recorder"
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run plant, controller and bridge on loopback and leave a Rerun recording.
    Run(RunArgs),
    /// Every policy through the co-simulation in every case of the task; a table and recordings.
    Compare(compare::CompareArgs),
    /// Run a sweep plan on all cores or on Slurm (`crawler sweep --help`; runs `crawler-sweep`).
    #[command(disable_help_flag = true)]
    Sweep {
        /// Arguments of `crawler-sweep` (a plan file, `collect PLAN`, options).
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
}

#[derive(Args)]
struct RunArgs {
    /// Scenario TOML file (default: the paper's, embedded).
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// Controller policy (optimal, wave, resonance, sweep, ...).
    #[arg(long, default_value = "optimal")]
    policy: String,
    /// Recording to write.
    #[arg(long, default_value = "crawler.rrd")]
    out: PathBuf,
    /// Run id (default: crawler-<pid>, unique on this machine).
    #[arg(long)]
    run_id: Option<String>,
    /// End time, s (default: the scenario's).
    #[arg(long, allow_hyphen_values = true)]
    t_end: Option<f64>,
    /// Number of cells (default: the scenario's).
    #[arg(long, allow_hyphen_values = true)]
    cells: Option<i64>,
    /// Task mode: the run ends when the body has travelled the task's distance (success) or
    /// spent its energy (failure).
    #[arg(long)]
    task: bool,
    /// Continue a stopped run from the plant's checkpoint (the checkpoint holds the plant's
    /// scenario and grid; `--scenario` and `--policy` still choose the controller's).
    #[arg(long, value_name = "FILE", conflicts_with = "cells")]
    resume: Option<PathBuf>,
    /// Record the fields of every K-th step.
    #[arg(long, default_value_t = 4)]
    every: u64,
    /// Watch the run live: the recorder streams to a Rerun viewer (it starts one on loopback,
    /// `.venv/bin/rerun` if the project's venv has it, else `rerun` from PATH, unless one already
    /// listens) while it writes `--out`. A missing or slow viewer never stops the run.
    #[arg(long)]
    view: bool,
    /// Watch the run live in the Rerun viewer already running at URL (its gRPC address, e.g.
    /// rerun+http://127.0.0.1:9876/proxy) while writing `--out`.
    #[arg(long, value_name = "URL", conflicts_with = "view")]
    view_url: Option<String>,
    /// Run without authentication (no credential, no message seals): any process of this machine
    /// that reaches the run's socket can then join, read and disturb it. For comparisons only.
    #[arg(long)]
    no_auth: bool,
    /// More arguments for the controller (after `--`), e.g. `-- --alpha 0.5`.
    #[arg(last = true)]
    controller_args: Vec<String>,
}

fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Cmd::Run(a) => run(a),
        Cmd::Compare(a) => compare::compare(a),
        Cmd::Sweep { args } => sweep(&args),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("crawler: error: {e:#}");
            Exit::Failure.into()
        }
    }
}

const BINARIES: [&str; 3] = ["crawler-plant", "crawler-controller", "crawler-bridge"];

/// `crawler sweep ARGS`: replaced by the sibling `crawler-sweep ARGS` (same signals, exit code).
fn sweep(args: &[String]) -> anyhow::Result<ExitCode> {
    let exe = std::env::current_exe()?;
    let bin = exe
        .parent()
        .map(|d| d.join("crawler-sweep"))
        .unwrap_or_default();
    if !bin.is_file() {
        // through `cargo run`: build it first, as `run` does for its binaries
        let Ok(cargo) = std::env::var("CARGO") else {
            anyhow::bail!(
                "crawler-sweep not found next to {}; build it with: cargo build --release -p crawler-sweep",
                exe.display()
            );
        };
        eprintln!("crawler: building crawler-sweep (first run only) ...");
        let mut build = Command::new(cargo);
        build.args(["build", "--bin", "crawler-sweep", "-p", "crawler-sweep"]);
        if exe.parent().is_some_and(|d| d.ends_with("release")) {
            build.arg("--release");
        }
        anyhow::ensure!(build.status()?.success(), "building crawler-sweep failed");
    }
    let mut cmd = Command::new(&bin);
    cmd.args(args);
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        let e = cmd.exec();
        anyhow::bail!("cannot run {}: {e}", bin.display());
    }
    #[cfg(not(unix))]
    {
        let status = cmd.status()?;
        Ok(ExitCode::from(status.code().unwrap_or(1) as u8))
    }
}

/// The directory of the sibling binaries. Through `cargo run` they are brought up to date first
/// (`cargo build` is a no-op when they are fresh), so a policy added to the controller is the
/// one that runs; otherwise they must sit next to this program.
fn binaries() -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe()?;
    let dir = exe.parent().map(Path::to_path_buf).unwrap_or_default();
    if let Ok(cargo) = std::env::var("CARGO") {
        let profile_release = dir.ends_with("release");
        let mut cmd = Command::new(cargo);
        cmd.arg("build").arg("--bins");
        // the workspace `cargo run` ran us from, wherever the user is now
        if let Ok(dir) = std::env::var("CARGO_MANIFEST_DIR") {
            cmd.arg("--manifest-path")
                .arg(Path::new(&dir).join("Cargo.toml"));
        }
        if profile_release {
            cmd.arg("--release");
        }
        // The packages of BINARIES.
        for p in ["crawler-plant-node", "crawler-controller", "crawler-bridge"] {
            cmd.args(["-p", p]);
        }
        eprintln!(
            "crawler: bringing {} up to date ({}cargo build; nothing to do when they are fresh)",
            BINARIES.join(", "),
            if profile_release { "release " } else { "" }
        );
        let status = cmd.status()?;
        anyhow::ensure!(status.success(), "building the binaries failed");
        return Ok(dir);
    }
    let missing: Vec<&str> = BINARIES
        .iter()
        .copied()
        .filter(|b| !dir.join(b).is_file())
        .collect();
    anyhow::ensure!(
        missing.is_empty(),
        "{} not found next to {}; build them with: cargo build --release --workspace",
        missing.join(", "),
        exe.display()
    );
    Ok(dir)
}

/// Forwards a child's stream line by line with a prefix, and signals the first line that
/// contains `needle` (if any).
fn forward(
    name: &'static str,
    stream: impl Read + Send + 'static,
    needle: Option<(&'static str, std::sync::mpsc::Sender<()>)>,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let mut needle = needle;
        for line in BufReader::new(stream).lines().map_while(Result::ok) {
            eprintln!("[{name}] {line}");
            if needle.as_ref().is_some_and(|(n, _)| line.contains(n)) {
                if let Some((_, tx)) = needle.take() {
                    let _ = tx.send(());
                }
            }
        }
    })
}

fn collect(stream: impl Read + Send + 'static) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut s = String::new();
        let _ = BufReader::new(stream).read_to_string(&mut s);
        s
    })
}

struct Proc {
    name: &'static str,
    child: Child,
    out: Option<std::thread::JoinHandle<String>>,
    err: Option<std::thread::JoinHandle<()>>,
}

fn spawn(
    name: &'static str,
    exe: &Path,
    args: &[String],
    needle: Option<(&'static str, std::sync::mpsc::Sender<()>)>,
) -> anyhow::Result<Proc> {
    let mut cmd = Command::new(exe);
    // Each process in its own process group: Ctrl-C in a terminal reaches the launcher alone,
    // which stops the run in order (plant, controller, recorder) and exits 130.
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        cmd.process_group(0);
    }
    let mut child = cmd
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| anyhow::anyhow!("cannot start {}: {e}", exe.display()))?;
    let out = child.stdout.take().map(collect);
    let err = child.stderr.take().map(|s| forward(name, s, needle));
    Ok(Proc {
        name,
        child,
        out,
        err,
    })
}

impl Proc {
    /// `Some(exit code)` once the process has ended (`Some(None)`: killed by a signal).
    fn ended(&mut self) -> Option<Option<i32>> {
        match self.child.try_wait() {
            Ok(Some(s)) => Some(s.code()),
            Ok(None) => None,
            Err(_) => Some(None),
        }
    }

    /// Waits up to `timeout`; on timeout sends SIGINT, then kills after a grace period.
    fn finish(&mut self, timeout: Duration) -> (Option<i32>, String) {
        let deadline = Instant::now() + timeout;
        let status = loop {
            match self.child.try_wait() {
                Ok(Some(s)) => break Some(s),
                Ok(None) if Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(50))
                }
                _ => break None,
            }
        };
        let status = status.or_else(|| {
            eprintln!("crawler: {} still running; asking it to stop", self.name);
            interrupt(&self.child);
            let grace = Instant::now() + Duration::from_secs(10);
            loop {
                match self.child.try_wait() {
                    Ok(Some(s)) => break Some(s),
                    Ok(None) if Instant::now() < grace => {
                        std::thread::sleep(Duration::from_millis(50))
                    }
                    _ => {
                        let _ = self.child.kill();
                        break self.child.wait().ok();
                    }
                }
            }
        });
        let out = self
            .out
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        if let Some(h) = self.err.take() {
            let _ = h.join();
        }
        (status.and_then(|s| s.code()), out)
    }
}

/// True if Ctrl-C reached the launcher, waiting briefly when a child ended interrupted (130): a
/// terminal's Ctrl-C reaches every process of the group at once, and a child may end before the
/// launcher's own handler has run. A child interrupted alone (another SIGINT to it) is a failure.
fn interrupted_with(flag: &AtomicBool, failed: Option<(&'static str, Option<i32>)>) -> bool {
    if flag.load(Ordering::SeqCst) {
        return true;
    }
    if !failed.is_some_and(|(_, code)| Exit::Interrupted.is(code)) {
        return false;
    }
    let until = Instant::now() + Duration::from_millis(500);
    while Instant::now() < until {
        std::thread::sleep(Duration::from_millis(10));
        if flag.load(Ordering::SeqCst) {
            return true;
        }
    }
    false
}

/// The name and exit code of the first process that ended with a failure, if any.
fn first_failure(procs: &mut [&mut Proc]) -> Option<(&'static str, Option<i32>)> {
    procs.iter_mut().find_map(|p| match p.ended() {
        Some(code) if !Exit::Finished.is(code) => Some((p.name, code)),
        _ => None,
    })
}

/// Stops every process after `failed` ended with a failure; the exit status of the launcher.
fn stop_all(failed: (&'static str, Option<i32>), procs: &mut [&mut Proc]) -> ExitCode {
    let (name, code) = failed;
    let what = if Exit::Interrupted.is(code) {
        "was interrupted"
    } else {
        "failed"
    };
    let code = code.map_or_else(|| "a signal".to_string(), |c| format!("exit code {c}"));
    eprintln!("crawler: the {name} {what} ({code}; its messages are above); stopping the others");
    for p in procs.iter_mut() {
        if p.ended().is_none() {
            interrupt(&p.child);
        }
    }
    for p in procs.iter_mut() {
        let _ = p.finish(Duration::from_secs(10));
    }
    Exit::Failure.into()
}

/// After Ctrl-C: asks every running process to stop (they finish cleanly: the plant writes its
/// checkpoint, the recorder closes its file), waits for them and prints what the plant said.
fn stop_interrupted(procs: &mut [&mut Proc]) -> ExitCode {
    eprintln!("crawler: interrupted; stopping the run");
    for p in procs.iter_mut() {
        if p.ended().is_none() {
            interrupt(&p.child);
        }
    }
    for p in procs.iter_mut() {
        let (_, out) = p.finish(Duration::from_secs(30));
        if p.name == "plant" && !out.trim().is_empty() {
            println!("{}", out.trim_end());
        }
    }
    Exit::Interrupted.into()
}

fn interrupt(child: &Child) {
    // SIGINT lets the process finish cleanly (the bridge closes its recording properly).
    let _ = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
}

/// The run's credential, created by the launcher and removed when it is dropped.
struct RunCredential {
    path: PathBuf,
    dir: PathBuf,
}

impl RunCredential {
    /// A fresh credential for `run_id` in the run's private directory.
    fn create(run_id: &str) -> anyhow::Result<Self> {
        crawler_protocol::validate_run_id(run_id)?;
        // never replace the credential of a run that is going on
        drop(crawler_transport::runtime_dir::claim(run_id)?);
        let dir = crawler_transport::runtime_dir::ensure_run_dir(run_id)?;
        let path = dir.join("credential");
        crawler_transport::Credential::generate(run_id, &path)?.save()?;
        Ok(Self { path, dir })
    }
}

impl Drop for RunCredential {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
        let _ = std::fs::remove_dir(&self.dir);
    }
}

fn run(a: RunArgs) -> anyhow::Result<ExitCode> {
    preflight::check_out(&a.out)?;
    preflight::check_every(a.every)?;
    let dir = binaries()?;
    let interrupted = Arc::new(AtomicBool::new(false));
    {
        let flag = interrupted.clone();
        ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst))?;
    }
    let run_id = a
        .run_id
        .clone()
        .unwrap_or_else(|| format!("crawler-{}", std::process::id()));
    let credential = if a.no_auth {
        None
    } else {
        Some(RunCredential::create(&run_id)?)
    };
    let auth_args: Vec<String> = match &credential {
        Some(c) => vec!["--credential".into(), c.path.display().to_string()],
        None => vec!["--no-auth".into()],
    };
    let mut scenario_args: Vec<String> = Vec::new();
    if let Some(s) = &a.scenario {
        scenario_args.extend(["--scenario".into(), s.display().to_string()]);
    }
    let mut plant_args: Vec<String> = vec!["run".into(), "--run-id".into(), run_id.clone()];
    match &a.resume {
        Some(ckpt) => plant_args.extend(["--resume".into(), ckpt.display().to_string()]),
        None => plant_args.extend(scenario_args.iter().cloned()),
    }
    if let Some(t) = a.t_end {
        plant_args.extend(["--t-end".into(), t.to_string()]);
    }
    if let Some(n) = a.cells {
        plant_args.extend(["--cells".into(), n.to_string()]);
    }
    if a.task {
        plant_args.push("--task".into());
    }
    plant_args.extend(["--wait-timeout".into(), "120".into()]);
    plant_args.extend(auth_args.iter().cloned());
    let mut ctl_args: Vec<String> = vec![
        "run".into(),
        "--run-id".into(),
        run_id.clone(),
        "--policy".into(),
        a.policy.clone(),
    ];
    ctl_args.extend(scenario_args.iter().cloned());
    ctl_args.extend(auth_args.iter().cloned());
    ctl_args.extend(a.controller_args.iter().cloned());
    let bridge_args: Vec<String> = vec![
        "record".into(),
        "--run-id".into(),
        run_id.clone(),
        "--out".into(),
        a.out.display().to_string(),
        "--every".into(),
        a.every.to_string(),
        "--idle-timeout".into(),
        "300".into(),
    ];
    let mut bridge_args: Vec<String> = bridge_args.into_iter().chain(auth_args).collect();
    if let Some(url) = &a.view_url {
        bridge_args.extend(["--connect".into(), url.clone()]);
    } else if a.view {
        bridge_args.push("--spawn".into());
        let venv = std::env::current_dir()
            .map(|d| d.join(".venv/bin/rerun"))
            .ok()
            .filter(|p| p.is_file());
        if let Some(exe) = venv {
            bridge_args.extend(["--viewer-exe".into(), exe.display().to_string()]);
        }
    }
    // Every input is checked by the program that owns it before anything starts.
    preflight::check_child("plant", &dir.join("crawler-plant"), &plant_args)?;
    preflight::check_child("controller", &dir.join("crawler-controller"), &ctl_args)?;
    if let Err(e) = preflight::check_child("recorder", &dir.join("crawler-bridge"), &bridge_args) {
        if let Some(url) = &a.view_url {
            eprintln!("crawler: the recorder's --connect above is --view-url = {url}");
        }
        return Err(e);
    }
    if interrupted.load(Ordering::SeqCst) {
        eprintln!("crawler: interrupted before the run started");
        return Ok(Exit::Interrupted.into());
    }
    eprintln!(
        "crawler: run {run_id}: recorder, plant and controller on loopback, {}; recording to {}",
        match &credential {
            Some(c) => format!("authenticated with {}", c.path.display()),
            None => "NOT authenticated (--no-auth)".to_string(),
        },
        a.out.display()
    );
    // Order: plant, then the recorder, and the controller once the recorder is connected to the
    // plant (the plant publishes nothing before a controller joins, so the recording starts at
    // step 0).
    let mut plant = spawn("plant", &dir.join("crawler-plant"), &plant_args, None)?;
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let mut bridge = spawn(
        "bridge",
        &dir.join("crawler-bridge"),
        &bridge_args,
        Some(("plant found", ready_tx)),
    )?;
    let connect_by = Instant::now() + Duration::from_secs(30);
    loop {
        if ready_rx.try_recv().is_ok() {
            break;
        }
        let failed = first_failure(&mut [&mut plant, &mut bridge]);
        if interrupted_with(&interrupted, failed) {
            return Ok(stop_interrupted(&mut [&mut plant, &mut bridge]));
        }
        if let Some(failed) = failed {
            return Ok(stop_all(failed, &mut [&mut plant, &mut bridge]));
        }
        if Instant::now() >= connect_by {
            eprintln!(
                "crawler: the recorder did not connect within 30 s; starting the controller anyway"
            );
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut controller = spawn(
        "controller",
        &dir.join("crawler-controller"),
        &ctl_args,
        None,
    )?;
    // Supervise until the plant ends: if any process fails first, stop the others at once.
    loop {
        let failed = first_failure(&mut [&mut plant, &mut controller, &mut bridge]);
        if interrupted_with(&interrupted, failed) {
            return Ok(stop_interrupted(&mut [
                &mut plant,
                &mut controller,
                &mut bridge,
            ]));
        }
        if let Some(failed) = failed {
            return Ok(stop_all(
                failed,
                &mut [&mut plant, &mut controller, &mut bridge],
            ));
        }
        if plant.ended().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let (plant_code, plant_out) = plant.finish(Duration::ZERO);
    let (ctl_code, ctl_out) = controller.finish(Duration::from_secs(30));
    let (bridge_code, _) = bridge.finish(Duration::from_secs(60));
    println!("{}", plant_out.trim_end());
    println!();
    println!("{}", ctl_out.trim_end());
    println!();
    // A recorder still catching up a minute after the run ended was stopped by us (130): its
    // recording is closed properly and holds what it had written; the run itself finished.
    let cut_short = Exit::Interrupted.is(bridge_code);
    if cut_short {
        eprintln!(
            "crawler: the recorder was still writing 60 s after the run ended and was stopped; {} holds what it had written (its drops are noted in it)",
            a.out.display()
        );
    }
    let ok = [plant_code, ctl_code]
        .into_iter()
        .all(|c| Exit::Finished.is(c))
        && (Exit::Finished.is(bridge_code) || cut_short);
    if Exit::Finished.is(bridge_code) || cut_short {
        println!(
            "recording: {} (open it with: rerun {})",
            a.out.display(),
            a.out.display()
        );
    }
    if ok {
        Ok(Exit::Finished.into())
    } else {
        eprintln!("crawler: exit codes: plant {plant_code:?}, controller {ctl_code:?}, bridge {bridge_code:?}");
        Ok(Exit::Failure.into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_child_interrupted_with_the_launcher_is_a_ctrl_c_and_alone_a_failure() {
        let flag = AtomicBool::new(false);
        let interrupted = Some(("controller", Some(130)));
        // nothing ended, no Ctrl-C; a child failed on its own
        assert!(!interrupted_with(&flag, None));
        assert!(!interrupted_with(&flag, Some(("plant", Some(1)))));
        assert!(!interrupted_with(&flag, Some(("plant", None))));
        // a child ended with 130 and no Ctrl-C reached the launcher: a failure, after the wait
        let t0 = Instant::now();
        assert!(!interrupted_with(&flag, interrupted));
        assert!(t0.elapsed() >= Duration::from_millis(500));
        // the launcher's handler runs a little after the child ended
        let late = Arc::new(AtomicBool::new(false));
        let setter = {
            let late = late.clone();
            std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(50));
                late.store(true, Ordering::SeqCst);
            })
        };
        assert!(interrupted_with(&late, interrupted));
        setter.join().unwrap();
        // Ctrl-C reached the launcher: interrupted whatever the children did
        flag.store(true, Ordering::SeqCst);
        assert!(interrupted_with(&flag, None));
        assert!(interrupted_with(&flag, Some(("plant", Some(1)))));
    }
}
