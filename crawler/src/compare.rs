//! `crawler compare`: every policy through the real co-simulation in every case, one table.
//!
//! For each case (a scenario shipped with the project) and each policy, the plant, the recorder
//! and the controller run as three processes on loopback, exactly as `crawler run --task` runs
//! them: the plant ends the run when the body has travelled the task's distance (success) or its
//! actuator has spent the task's energy (failure), or at the end time. The plant's final report
//! gives the row of the table; each run leaves its recording `OUT/<case>/<policy>.rrd` (every
//! recording has the same entity paths, so the viewer shows them side by side) and the table goes
//! to `OUT/table.md` and `OUT/results.json`.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clap::Args;
use crawler_cli::{Exit, ScenarioArgs};

use crate::children::{Auth, ControllerRun, Invocation, PlantRun, Programs, RecorderRun};
use crate::supervise::{first_failure, interrupt, interrupted_with, spawn, Proc};

use crawler_policies::comparison::{route, share};
pub use crawler_policies::comparison::{Case, CASES, ORACLE, POLICIES};

/// Options of `crawler compare`.
#[derive(Args)]
pub struct CompareArgs {
    /// Cases, comma separated (default: all: nominal, mismatch, patchy, slippery,
    /// slippery-patches, drift, held-out-slippery, held-out-sticky, free, stick-slip).
    #[arg(long, value_delimiter = ',')]
    cases: Vec<String>,
    /// Policies, comma separated (default: optimal, oracle, adaptive, reflex, resonance; the
    /// oracle is the open-loop optimum given the true pipe).
    #[arg(long, value_delimiter = ',')]
    policies: Vec<String>,
    /// Directory for the scenarios used, the recordings and the table.
    #[arg(long, default_value = "out/compare")]
    out_dir: PathBuf,
    /// End time of every run, s (the task usually ends it earlier).
    #[arg(long, allow_hyphen_values = true, default_value_t = 60.0)]
    t_end: f64,
    /// Cells of every plant (default: each scenario's own; fewer for a quick look).
    #[arg(long, allow_hyphen_values = true)]
    cells: Option<i64>,
    /// Record the fields of every K-th step (every step's scalars, metrics and events are
    /// always recorded).
    #[arg(long, default_value_t = 1)]
    every: u64,
    /// Longest wall time of one run, s.
    #[arg(long, allow_hyphen_values = true, default_value_t = 900.0)]
    run_timeout: f64,
    /// More arguments for every controller (after `--`), e.g. `-- --reflex stick_gain=0.2`.
    #[arg(last = true)]
    controller_args: Vec<String>,
}

/// One row of the table: the library's row and what the co-simulation adds.
#[derive(Debug, Clone, Default)]
struct Row {
    row: crawler_policies::comparison::Row,
    wall: f64,
    state_digest: String,
    recording: String,
}

impl Row {
    fn json(&self, all: &[crawler_policies::comparison::Row]) -> serde_json::Value {
        let r = &self.row;
        serde_json::json!({
            "case": r.case,
            "policy": r.policy,
            "outcome": r.outcome,
            "succeeded": r.succeeded(),
            "time_to_distance": r.time_to_distance,
            "energy_used": r.energy,
            "distance": r.distance,
            "mileage": r.mileage,
            "peak_stress": r.peak_stress,
            "time_above_sigma_max": r.time_over,
            "share_of_oracle_gain": share(all, r),
            "wall_seconds": self.wall,
            "state_digest": self.state_digest,
            "recording": self.recording,
            "error": r.error,
        })
    }
}

fn pick<'a>(all: &'a [&'a str], asked: &[String], what: &str) -> anyhow::Result<Vec<String>> {
    if asked.is_empty() {
        return Ok(all.iter().map(|s| s.to_string()).collect());
    }
    for a in asked {
        anyhow::ensure!(
            all.contains(&a.as_str()) || what == "policy",
            "invalid --cases {a:?}: allowed {}",
            all.join(", ")
        );
        anyhow::ensure!(
            !a.is_empty() && a.chars().all(|c| c.is_ascii_alphanumeric() || c == '-'),
            "invalid --{what} {a:?}: allowed names of letters, digits and '-'"
        );
    }
    Ok(asked.to_vec())
}

/// Runs the comparison.
pub fn compare(a: CompareArgs) -> anyhow::Result<ExitCode> {
    let case_names: Vec<&str> = CASES.iter().map(|c| c.name).collect();
    let cases = pick(&case_names, &a.cases, "cases")?;
    let policies = pick(&POLICIES, &a.policies, "policy")?;
    anyhow::ensure!(
        a.t_end.is_finite() && a.t_end > 0.0,
        "invalid --t-end = {}: allowed a time > 0 s",
        a.t_end
    );
    anyhow::ensure!(
        a.run_timeout.is_finite() && a.run_timeout > 0.0 && a.run_timeout < 1e9,
        "invalid --run-timeout = {}: allowed a number of seconds, 0 < run-timeout < 1e9",
        crawler_cli::number(a.run_timeout)
    );
    crate::preflight::check_every(a.every)?;
    let programs = Programs::here()?;
    let interrupted = Arc::new(AtomicBool::new(false));
    {
        let flag = interrupted.clone();
        ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst))?;
    }
    std::fs::create_dir_all(a.out_dir.join("scenarios"))?;
    let mut rows = Vec::new();
    for case in CASES.iter().filter(|c| cases.iter().any(|n| n == c.name)) {
        let scenario = a
            .out_dir
            .join("scenarios")
            .join(format!("{}.toml", case.name));
        std::fs::write(&scenario, case.scenario)?;
        std::fs::create_dir_all(a.out_dir.join(case.name))?;
        eprintln!("crawler: case {}: {}", case.name, case.about);
        for policy in &policies {
            // the oracle: the open-loop optimum in the same plant with the pipe disclosed
            let (run_policy, text) = route(case, policy)?;
            let scenario = if policy == ORACLE {
                let disclosed = a
                    .out_dir
                    .join("scenarios")
                    .join(format!("{}-disclosed.toml", case.name));
                std::fs::write(&disclosed, text)?;
                disclosed
            } else {
                scenario.clone()
            };
            let row = run_one(
                &programs,
                &a,
                case,
                (policy.as_str(), run_policy.as_str()),
                &scenario,
                &interrupted,
            );
            match &row {
                Ok(r) => eprintln!(
                    "crawler: {} / {}: {} ({:.1} s of wall time)",
                    r.row.case,
                    r.row.policy,
                    r.row.error.as_deref().unwrap_or(&r.row.outcome),
                    r.wall
                ),
                Err(e) => eprintln!("crawler: {} / {policy}: {e:#}", case.name),
            }
            if interrupted.load(Ordering::SeqCst) {
                eprintln!("crawler: interrupted; the table so far:");
                if let Ok(r) = row {
                    rows.push(r);
                }
                println!("{}", table(&rows));
                return Ok(Exit::Interrupted.into());
            }
            rows.push(row.unwrap_or_else(|e| Row {
                row: crawler_policies::comparison::Row {
                    case: case.name.into(),
                    policy: policy.clone(),
                    outcome: "failed".into(),
                    error: Some(format!("{e:#}")),
                    ..Default::default()
                },
                ..Row::default()
            }));
        }
    }
    let md = table(&rows);
    std::fs::write(a.out_dir.join("table.md"), &md)?;
    let all: Vec<_> = rows.iter().map(|r| r.row.clone()).collect();
    let json = serde_json::Value::Array(rows.iter().map(|r| r.json(&all)).collect());
    std::fs::write(
        a.out_dir.join("results.json"),
        serde_json::to_string_pretty(&json)? + "\n",
    )?;
    println!("{md}");
    println!(
        "table: {}, results: {}, recordings: {}/<case>/<policy>.rrd",
        a.out_dir.join("table.md").display(),
        a.out_dir.join("results.json").display(),
        a.out_dir.display()
    );
    Ok(if rows.iter().all(|r| r.row.error.is_none()) {
        Exit::Finished.into()
    } else {
        Exit::Failure.into()
    })
}

fn run_one(
    programs: &Programs,
    a: &CompareArgs,
    case: &Case,
    (policy, run_policy): (&str, &str),
    scenario: &Path,
    interrupted: &AtomicBool,
) -> anyhow::Result<Row> {
    let started = Instant::now();
    let run_id = format!("compare-{}-{}-{policy}", std::process::id(), case.name);
    let out = a.out_dir.join(case.name);
    let recording = out.join(format!("{policy}.rrd"));
    let checkpoint = out.join(format!("{policy}.ckpt"));
    let Invocations {
        plant,
        recorder,
        controller,
    } = invocations(
        programs,
        a,
        &run_id,
        run_policy,
        scenario,
        &checkpoint,
        &recording,
    );
    let mut plant = spawn("plant", &plant.exe, &plant.args, None)?;
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let mut bridge = spawn(
        "recorder",
        &recorder.exe,
        &recorder.args,
        Some(("plant found", ready_tx)),
    )?;
    let _ = ready_rx.recv_timeout(Duration::from_secs(30));
    let mut controller = spawn("controller", &controller.exe, &controller.args, None)?;
    let deadline = started + Duration::from_secs_f64(a.run_timeout);
    watch(
        &mut plant,
        &mut controller,
        &mut bridge,
        deadline,
        a.run_timeout,
        interrupted,
    )?;
    let (_, plant_out) = plant.finish(Duration::ZERO);
    let (ctl_code, _) = controller.finish(Duration::from_secs(30));
    let (bridge_code, _) = bridge.finish(Duration::from_secs(60));
    let mut row =
        parse_report(&plant_out).map_err(|e| anyhow::anyhow!("the plant's report: {e}"))?;
    row.row.case = case.name.into();
    row.row.policy = policy.into();
    row.wall = started.elapsed().as_secs_f64();
    row.recording = recording.display().to_string();
    if !Exit::Finished.is(ctl_code) {
        row.row.error = Some(format!("the controller ended with {ctl_code:?}"));
    } else if Exit::Interrupted.is(bridge_code) {
        // still writing a minute after the run ended: stopped, its recording closed properly
        eprintln!(
            "crawler: {} / {policy}: the recorder was still catching up 60 s after the run and was stopped; {} holds what it had written",
            case.name,
            recording.display()
        );
    } else if !Exit::Finished.is(bridge_code) {
        row.row.error = Some(format!("the recorder ended with {bridge_code:?}"));
    }
    Ok(row)
}

/// The command lines of the three programs of one run.
struct Invocations {
    /// The plant.
    plant: Invocation,
    /// The recorder.
    recorder: Invocation,
    /// The controller.
    controller: Invocation,
}

/// The command lines of run `run_id`: the plant on `scenario` (with the task, `--t-end` and
/// `--cells` of `a`) writing `checkpoint`, the recorder writing `recording`, and the controller
/// running `run_policy` on the case's file.
fn invocations(
    programs: &Programs,
    a: &CompareArgs,
    run_id: &str,
    run_policy: &str,
    scenario: &Path,
    checkpoint: &Path,
    recording: &Path,
) -> Invocations {
    let flags = ScenarioArgs {
        scenario: Some(scenario.to_path_buf()),
        t_end: Some(a.t_end),
        cells: a.cells,
        task: true,
        ..ScenarioArgs::default()
    };
    let plant = programs.plant(&PlantRun {
        run_id,
        scenario: &flags,
        resume: None,
        wait_timeout: 300.0,
        checkpoint: Some(checkpoint),
        json: true,
        auth: &Auth::PlantMade,
    });
    let recorder = programs.recorder(&RecorderRun {
        run_id,
        out: recording,
        every: a.every,
        idle_timeout: 300.0,
        auth: &Auth::PlantMade,
        viewer: None,
        viewer_exe: None,
    });
    // The controller's own scenario: the case's file (its task and wave), not the plant's grid.
    let controller_flags = ScenarioArgs {
        scenario: Some(scenario.to_path_buf()),
        ..ScenarioArgs::default()
    };
    let controller = programs.controller(&ControllerRun {
        run_id,
        policy: run_policy,
        params: &[],
        scenario: &controller_flags,
        wait_timeout: 300.0,
        auth: &Auth::PlantMade,
        extra: &a.controller_args,
        take_over_at: None,
    });
    Invocations {
        plant,
        recorder,
        controller,
    }
}

/// Waits until the plant ends. If the run is interrupted, a process fails or `deadline`
/// passes (`run_timeout`, s, names it), interrupts the processes still running, waits for all
/// (20 s each at most) and fails.
fn watch(
    plant: &mut Proc,
    controller: &mut Proc,
    bridge: &mut Proc,
    deadline: Instant,
    run_timeout: f64,
    interrupted: &AtomicBool,
) -> anyhow::Result<()> {
    let stop = |why: &str, procs: &mut [&mut Proc]| {
        for p in procs.iter_mut() {
            if p.ended().is_none() {
                interrupt(&p.child);
            }
        }
        for p in procs.iter_mut() {
            let _ = p.finish(Duration::from_secs(20));
        }
        anyhow::anyhow!("{why}")
    };
    loop {
        let failed = first_failure(&mut [&mut *plant, &mut *controller, &mut *bridge]);
        if interrupted_with(interrupted, failed) {
            return Err(stop(
                "interrupted",
                &mut [&mut *plant, &mut *controller, &mut *bridge],
            ));
        }
        if let Some((name, code)) = failed {
            return Err(stop(
                &format!("the {name} failed (exit code {code:?}; its messages are above)"),
                &mut [&mut *plant, &mut *controller, &mut *bridge],
            ));
        }
        if Instant::now() >= deadline {
            return Err(stop(
                &format!("no result within --run-timeout {run_timeout} s"),
                &mut [&mut *plant, &mut *controller, &mut *bridge],
            ));
        }
        if plant.ended().is_some() {
            return Ok(());
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The numbers of a `Report` in JSON (the plant's `--json` output) that the table needs.
fn parse_report(json: &str) -> anyhow::Result<Row> {
    let v: serde_json::Value = serde_json::from_str(json)?;
    let task = v
        .get("task")
        .filter(|t| t.is_object())
        .ok_or_else(|| anyhow::anyhow!("no task in the report"))?;
    let num = |key: &str| task.get(key).and_then(|x| x.as_f64());
    let outcome = task
        .get("outcome")
        .and_then(|x| x.as_str())
        .ok_or_else(|| anyhow::anyhow!("no task outcome"))?
        .to_string();
    let distance = num("distance");
    let at_distance = num("energy_at_distance");
    let energy = at_distance.or(num("energy_used"));
    let travelled = if at_distance.is_some() {
        num("distance_target")
    } else {
        distance
    };
    Ok(Row {
        row: crawler_policies::comparison::Row {
            outcome,
            time_to_distance: num("time_to_distance"),
            energy,
            distance,
            mileage: match (travelled, energy) {
                (Some(d), Some(e)) if e > 0.0 => Some(d / e),
                _ => None,
            },
            peak_stress: num("max_stress"),
            time_over: num("time_over_sigma_max"),
            ..Default::default()
        },
        state_digest: v
            .get("state_digest")
            .and_then(|x| x.as_str())
            .unwrap_or_default()
            .to_string(),
        ..Row::default()
    })
}

/// The table (written once, in `crawler_policies::comparison`).
fn table(rows: &[Row]) -> String {
    let rows: Vec<_> = rows.iter().map(|r| r.row.clone()).collect();
    crawler_policies::comparison::table(&rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_gives_its_row() {
        let json = r#"{
  "velocity": 0.05,
  "max_stress": 1.0,
  "task": {
    "outcome": "reached",
    "distance_target": 1.0,
    "distance": 1.0004,
    "time_to_distance": 20.5,
    "energy_budget": 20.0,
    "energy_used": 19.9,
    "energy_at_distance": 19.5,
    "energy_exhausted_at": null,
    "sigma_max": 100000.0,
    "max_stress": 15900.0,
    "time_over_sigma_max": 0.0,
    "run_time": 20.6
  }
}"#;
        let r = parse_report(json).unwrap().row;
        assert_eq!(r.outcome, "reached");
        assert_eq!(r.time_to_distance, Some(20.5));
        assert_eq!(r.energy, Some(19.5));
        assert_eq!(r.mileage, Some(1.0 / 19.5));
        assert_eq!(r.peak_stress, Some(15900.0));
        assert_eq!(r.time_over, Some(0.0));
        let failed = json
            .replace("\"reached\"", "\"energy exhausted\"")
            .replace(
                "\"energy_at_distance\": 19.5",
                "\"energy_at_distance\": null",
            )
            .replace("\"time_to_distance\": 20.5", "\"time_to_distance\": null");
        let r = parse_report(&failed).unwrap().row;
        assert_eq!(r.outcome, "energy exhausted");
        assert_eq!(r.time_to_distance, None);
        assert_eq!(r.energy, Some(19.9));
        assert_eq!(r.mileage, Some(1.0004 / 19.9));
        assert!(!r.succeeded());
        assert!(
            crawler_policies::comparison::table(&[r]).contains("| energy exhausted | - | 19.90 |")
        );
        // a run above sigma_max for longer than the task allows is not a success, even at D
        let over = json.replace("\"reached\"", "\"stress exceeded\"").replace(
            "\"time_over_sigma_max\": 0.0",
            "\"time_over_sigma_max\": 1.765",
        );
        let r = parse_report(&over).unwrap().row;
        assert_eq!(r.outcome, "stress exceeded");
        assert!(!r.succeeded());
        assert!(crawler_policies::comparison::table(&[r])
            .contains("| stress exceeded | 20.500 | 19.50 | 1.000 | 0.0513 | 15.9 | 1.765 |"));
    }
}
