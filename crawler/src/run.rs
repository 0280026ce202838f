//! `crawler run`: the whole co-simulation in one command.
//!
//! Starts the plant (`crawler plant run`), the recorder and the controller (`crawler controller
//! run`) as three processes on loopback for one run id, forwards their logs with a prefix, waits
//! for them, and prints the plant's summary and the controller's table of predicted against
//! simulated metrics. The recording is left in `--out` (default `crawler.rrd`).
//!
//! The run is authenticated: the launcher creates a fresh credential in the run's private
//! directory (mode 0600 in a 0700 directory), hands its path to the three processes and removes
//! it when they are done.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Args;
use crawler_cli::{Exit, ScenarioArgs};

use crate::children::{Auth, ControllerRun, Invocation, PlantRun, Programs, RecorderRun};
use crate::preflight;
use crate::supervise::{first_failure, interrupted_with, spawn, stop_all, stop_interrupted, Proc};

/// Options of `crawler run`.
#[derive(Args)]
pub struct RunArgs {
    /// The scenario (default: the paper's, embedded) and its overrides, for the plant and the
    /// controller alike.
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// Controller policy (`crawler controller policies` lists them).
    #[arg(long, default_value = "optimal")]
    policy: String,
    /// A parameter of the policy, KEY=VALUE (repeatable).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    params: Vec<String>,
    /// Recording to write.
    #[arg(long, default_value = "crawler.rrd")]
    out: PathBuf,
    /// Run id (default: crawler-<pid>, unique on this machine).
    #[arg(long)]
    run_id: Option<String>,
    /// Continue a stopped run from the plant's checkpoint (the checkpoint holds the plant's
    /// scenario and grid; `--scenario` and `--policy` still choose the controller's).
    #[arg(long, value_name = "FILE", conflicts_with = "cells")]
    resume: Option<PathBuf>,
    /// Record the fields of every K-th step (every step's scalars, metrics and events are
    /// always recorded).
    #[arg(long, default_value_t = 1)]
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
    /// More arguments for the controller (after `--`).
    #[arg(last = true)]
    controller_args: Vec<String>,
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

/// The run's three processes, as they will be started.
struct Plan {
    plant: Invocation,
    controller: Invocation,
    recorder: Invocation,
}

impl Plan {
    fn of(a: &RunArgs, programs: &Programs, run_id: &str, auth: &Auth) -> Self {
        let viewer_exe = std::env::current_dir()
            .map(|d| d.join(".venv/bin/rerun"))
            .ok()
            .filter(|p| p.is_file());
        let viewer = match (&a.view_url, a.view) {
            (Some(url), _) => Some(Some(url.as_str())),
            (None, true) => Some(None),
            (None, false) => None,
        };
        Self {
            plant: programs.plant(&PlantRun {
                run_id,
                scenario: &a.scenario,
                resume: a.resume.as_deref(),
                wait_timeout: 120.0,
                checkpoint: None,
                json: false,
                auth,
            }),
            controller: programs.controller(&ControllerRun {
                run_id,
                policy: &a.policy,
                params: &a.params,
                scenario: &a.scenario,
                wait_timeout: 60.0,
                auth,
                extra: &a.controller_args,
            }),
            recorder: programs.recorder(&RecorderRun {
                run_id,
                out: &a.out,
                every: a.every,
                idle_timeout: 300.0,
                auth,
                viewer,
                viewer_exe: viewer_exe.as_deref(),
            }),
        }
    }

    /// Every input is checked by the program that owns it before anything starts.
    fn check(&self, a: &RunArgs) -> anyhow::Result<()> {
        preflight::check_child("plant", &self.plant.check())?;
        preflight::check_child("controller", &self.controller.check())?;
        if let Err(e) = preflight::check_child("recorder", &self.recorder.check()) {
            if let Some(url) = &a.view_url {
                eprintln!("crawler: the recorder's --connect above is --view-url = {url}");
            }
            return Err(e);
        }
        Ok(())
    }
}

/// Runs `crawler run`.
pub fn run(a: RunArgs) -> anyhow::Result<ExitCode> {
    preflight::check_out(&a.out)?;
    preflight::check_every(a.every)?;
    let programs = Programs::here()?;
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
    let auth = match &credential {
        Some(c) => Auth::Credential(c.path.clone()),
        None => Auth::Open,
    };
    let plan = Plan::of(&a, &programs, &run_id, &auth);
    plan.check(&a)?;
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
    let procs = match start(&plan, &interrupted)? {
        Started::Running(procs) => procs,
        Started::Ended(code) => return Ok(code),
    };
    supervise(procs, &interrupted, &a)
}

/// The processes of a started run.
struct Running {
    plant: Proc,
    controller: Proc,
    recorder: Proc,
}

enum Started {
    Running(Box<Running>),
    Ended(ExitCode),
}

/// Starts the plant, then the recorder, and the controller once the recorder is connected to the
/// plant (the plant publishes nothing before a controller joins, so the recording starts at step
/// 0).
fn start(plan: &Plan, interrupted: &AtomicBool) -> anyhow::Result<Started> {
    let mut plant = spawn("plant", &plan.plant.exe, &plan.plant.args, None)?;
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let mut recorder = spawn(
        "recorder",
        &plan.recorder.exe,
        &plan.recorder.args,
        Some(("plant found", ready_tx)),
    )?;
    let connect_by = Instant::now() + Duration::from_secs(30);
    loop {
        if ready_rx.try_recv().is_ok() {
            break;
        }
        let failed = first_failure(&mut [&mut plant, &mut recorder]);
        if interrupted_with(interrupted, failed) {
            return Ok(Started::Ended(stop_interrupted(&mut [
                &mut plant,
                &mut recorder,
            ])));
        }
        if let Some(failed) = failed {
            return Ok(Started::Ended(stop_all(
                failed,
                &mut [&mut plant, &mut recorder],
            )));
        }
        if Instant::now() >= connect_by {
            eprintln!(
                "crawler: the recorder did not connect within 30 s; starting the controller anyway"
            );
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let controller = spawn(
        "controller",
        &plan.controller.exe,
        &plan.controller.args,
        None,
    )?;
    Ok(Started::Running(Box::new(Running {
        plant,
        controller,
        recorder,
    })))
}

/// Supervises the run until the plant ends (if any process fails first, the others are stopped
/// at once), then prints what the plant and the controller said.
fn supervise(
    procs: Box<Running>,
    interrupted: &AtomicBool,
    a: &RunArgs,
) -> anyhow::Result<ExitCode> {
    let Running {
        mut plant,
        mut controller,
        mut recorder,
    } = *procs;
    loop {
        let all = &mut [&mut plant, &mut controller, &mut recorder];
        let failed = first_failure(all);
        if interrupted_with(interrupted, failed) {
            return Ok(stop_interrupted(all));
        }
        if let Some(failed) = failed {
            return Ok(stop_all(failed, all));
        }
        if plant.ended().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let (plant_code, plant_out) = plant.finish(Duration::ZERO);
    let (ctl_code, ctl_out) = controller.finish(Duration::from_secs(30));
    let (recorder_code, _) = recorder.finish(Duration::from_secs(60));
    println!("{}", plant_out.trim_end());
    println!();
    println!("{}", ctl_out.trim_end());
    println!();
    // A recorder still catching up a minute after the run ended was stopped by us (130): its
    // recording is closed properly and holds what it had written; the run itself finished.
    let cut_short = Exit::Interrupted.is(recorder_code);
    if cut_short {
        eprintln!(
            "crawler: the recorder was still writing 60 s after the run ended and was stopped; {} holds what it had written (its drops are noted in it)",
            a.out.display()
        );
    }
    let recorded = Exit::Finished.is(recorder_code) || cut_short;
    if recorded {
        println!(
            "recording: {} (open it with: .venv/bin/rerun {}; scripts/setup-python.sh --viewer installs it)",
            a.out.display(),
            a.out.display()
        );
    }
    if [plant_code, ctl_code]
        .into_iter()
        .all(|c| Exit::Finished.is(c))
        && recorded
    {
        Ok(Exit::Finished.into())
    } else {
        eprintln!("crawler: exit codes: plant {plant_code:?}, controller {ctl_code:?}, recorder {recorder_code:?}");
        Ok(Exit::Failure.into())
    }
}
