//! `crawler run`: the whole co-simulation in one command.
//!
//! Starts the plant (`crawler plant run`), the recorder and the controller (`crawler controller
//! run`) as three processes on loopback for one run id, forwards their logs with a prefix, waits
//! for them, and prints the plant's summary and the controller's table of predicted against
//! simulated metrics. The recording is left in `--out` (default `crawler.rrd`).
//!
//! `--then POLICY@SECONDS` (repeatable) starts one more controller per hand-over, which takes the
//! run over at the first step at or after that simulated time (`crawler controller run
//! --take-over-at`): several controllers on one timeline, the recording saying who controlled
//! which steps.
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
    /// Hand the run over to another policy at a simulated time: POLICY@SECONDS (repeatable;
    /// each starts a controller that takes the run over at the first step at or after that
    /// time, with the policy's default parameters and the run's scenario).
    #[arg(long, value_name = "POLICY@SECONDS")]
    then: Vec<String>,
    /// Start this command as the controller instead of `crawler controller run` (any external
    /// controller, e.g. ".venv/bin/python examples/python_controller.py --alpha 0.5"): split
    /// into words as a shell would, started directly, given the run's `--run-id` and
    /// `--credential PATH` (or `--no-auth`) after its own words.
    #[arg(long, value_name = "COMMAND", conflicts_with_all = ["policy", "params"])]
    controller_cmd: Option<String>,
    /// More arguments for the controller (after `--`).
    #[arg(last = true)]
    controller_args: Vec<String>,
}

/// A hand-over of `crawler run --then`: the policy and the simulated time, s.
#[derive(Debug, Clone, PartialEq)]
struct Then {
    policy: String,
    at: f64,
}

/// Most `--then` hand-overs of one run.
const MAX_THEN: usize = 8;

/// Parses `--then` values (POLICY@SECONDS, times increasing, at most [`MAX_THEN`]).
fn parse_then(values: &[String]) -> anyhow::Result<Vec<Then>> {
    anyhow::ensure!(
        values.len() <= MAX_THEN,
        "invalid --then: {} hand-overs; allowed at most {MAX_THEN}",
        values.len()
    );
    let mut out: Vec<Then> = Vec::new();
    for v in values {
        let bad = || {
            anyhow::anyhow!(
                "invalid --then = {v:?}: allowed POLICY@SECONDS, a policy name and a simulated time in seconds >= 0 (e.g. reflex@10)"
            )
        };
        let (policy, at) = v.rsplit_once('@').ok_or_else(bad)?;
        let at: f64 = at.parse().map_err(|_| bad())?;
        if policy.is_empty() || !at.is_finite() || at < 0.0 {
            return Err(bad());
        }
        if let Some(prev) = out.last() {
            anyhow::ensure!(
                at > prev.at,
                "invalid --then = {v:?}: its time must be later than the hand-over before ({}@{})",
                prev.policy,
                prev.at
            );
        }
        out.push(Then {
            policy: policy.to_string(),
            at,
        });
    }
    Ok(out)
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

/// The run's processes, as they will be started.
struct Plan {
    plant: Invocation,
    controller: Invocation,
    /// The controllers of `--then`, in the order of their hand-overs.
    then: Vec<Invocation>,
    recorder: Invocation,
}

impl Plan {
    fn of(
        a: &RunArgs,
        then: &[Then],
        programs: &Programs,
        run_id: &str,
        auth: &Auth,
    ) -> anyhow::Result<Self> {
        let viewer_exe = std::env::current_dir()
            .map(|d| d.join(".venv/bin/rerun"))
            .ok()
            .filter(|p| p.is_file());
        let viewer = match (&a.view_url, a.view) {
            (Some(url), _) => Some(Some(url.as_str())),
            (None, true) => Some(None),
            (None, false) => None,
        };
        let controller = match &a.controller_cmd {
            Some(cmd) => crate::external::invocation(cmd, run_id, auth, &a.controller_args)?,
            None => programs.controller(&ControllerRun {
                run_id,
                policy: &a.policy,
                params: &a.params,
                scenario: &a.scenario,
                wait_timeout: 60.0,
                auth,
                take_over_at: None,
                extra: &a.controller_args,
            }),
        };
        Ok(Self {
            plant: programs.plant(&PlantRun {
                run_id,
                scenario: &a.scenario,
                resume: a.resume.as_deref(),
                wait_timeout: 120.0,
                checkpoint: None,
                json: false,
                auth,
            }),
            controller,
            then: then
                .iter()
                .map(|t| {
                    programs.controller(&ControllerRun {
                        run_id,
                        policy: &t.policy,
                        params: &[],
                        scenario: &a.scenario,
                        wait_timeout: 60.0,
                        auth,
                        take_over_at: Some(t.at),
                        extra: &[],
                    })
                })
                .collect(),
            recorder: programs.recorder(&RecorderRun {
                run_id,
                out: &a.out,
                every: a.every,
                idle_timeout: 300.0,
                auth,
                viewer,
                viewer_exe: viewer_exe.as_deref(),
            }),
        })
    }

    /// Every input is checked by the program that owns it before anything starts.
    fn check(&self, a: &RunArgs) -> anyhow::Result<()> {
        preflight::check_child("plant", &self.plant.check())?;
        // an external controller's program was found when the plan was made; its own inputs
        // are its own to check when it starts
        if a.controller_cmd.is_none() {
            preflight::check_child("controller", &self.controller.check())?;
        }
        for t in &self.then {
            preflight::check_child("controller", &t.check())?;
        }
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
    let then = parse_then(&a.then)?;
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
    let plan = Plan::of(&a, &then, &programs, &run_id, &auth)?;
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
    /// The first controller, then those of `--then`.
    controllers: Vec<Proc>,
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
    let mut controllers = vec![spawn(
        "controller",
        &plan.controller.exe,
        &plan.controller.args,
        None,
    )?];
    // the controllers of the hand-overs ask at once; the plant keeps each request for its step
    for (i, t) in plan.then.iter().enumerate() {
        let name: &'static str = Box::leak(format!("controller {}", i + 2).into_boxed_str());
        controllers.push(spawn(name, &t.exe, &t.args, None)?);
    }
    Ok(Started::Running(Box::new(Running {
        plant,
        controllers,
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
        mut controllers,
        mut recorder,
    } = *procs;
    loop {
        let mut all: Vec<&mut Proc> = vec![&mut plant];
        all.extend(controllers.iter_mut());
        all.push(&mut recorder);
        let failed = first_failure(&mut all);
        if interrupted_with(interrupted, failed) {
            return Ok(stop_interrupted(&mut all));
        }
        if let Some(failed) = failed {
            return Ok(stop_all(failed, &mut all));
        }
        if plant.ended().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let (plant_code, plant_out) = plant.finish(Duration::ZERO);
    let ctl: Vec<(Option<i32>, String)> = controllers
        .iter_mut()
        .map(|c| c.finish(Duration::from_secs(30)))
        .collect();
    let (recorder_code, _) = recorder.finish(Duration::from_secs(60));
    println!("{}", plant_out.trim_end());
    println!();
    for (_, out) in &ctl {
        println!("{}", out.trim_end());
        println!();
    }
    let ctl_codes: Vec<Option<i32>> = ctl.iter().map(|(c, _)| *c).collect();
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
    if std::iter::once(plant_code)
        .chain(ctl_codes.iter().copied())
        .all(|c| Exit::Finished.is(c))
        && recorded
    {
        Ok(Exit::Finished.into())
    } else {
        eprintln!("crawler: exit codes: plant {plant_code:?}, controllers {ctl_codes:?}, recorder {recorder_code:?}");
        Ok(Exit::Failure.into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn then_is_a_policy_and_a_later_time_each() {
        let v = |xs: &[&str]| xs.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(
            parse_then(&v(&["reflex@10", "wave@12.5"])).unwrap(),
            [
                Then {
                    policy: "reflex".into(),
                    at: 10.0
                },
                Then {
                    policy: "wave".into(),
                    at: 12.5
                }
            ]
        );
        for bad in [
            v(&["reflex"]),
            v(&["@10"]),
            v(&["reflex@"]),
            v(&["reflex@-1"]),
            v(&["reflex@nan"]),
            v(&["reflex@inf"]),
        ] {
            let e = parse_then(&bad).unwrap_err().to_string();
            assert!(
                e.contains("invalid --then") && e.contains("POLICY@SECONDS"),
                "{bad:?}: {e}"
            );
        }
        let e = parse_then(&v(&["reflex@10", "wave@10"]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("later than the hand-over before"), "{e}");
        assert!(parse_then(&v(&["wave@1"; 9])).is_err());
    }
}
