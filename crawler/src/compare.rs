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

use crate::children::{Auth, ControllerRun, PlantRun, Programs, RecorderRun};
use crate::supervise::{first_failure, interrupt, interrupted_with, spawn, Proc};

/// A case: name, what it is, the scenario (embedded, written next to the results).
pub struct Case {
    /// Short name (`--cases`).
    pub name: &'static str,
    /// One line.
    pub about: &'static str,
    /// The scenario file's text.
    pub scenario: &'static str,
}

/// The cases of the comparison.
pub const CASES: [Case; 5] = [
    Case {
        name: "nominal",
        about: "the paper's crawler and pipe (eps = 0.1, n_F = 0.5), as every controller is told",
        scenario: include_str!("../../scenarios/paper.toml"),
    },
    Case {
        name: "mismatch",
        about: "friction eps = 0.3, n_F = 0.7 while controllers are told the paper's 0.1 and 0.5",
        scenario: include_str!("../../scenarios/mismatch.toml"),
    },
    Case {
        name: "patchy",
        about: "dry patches (eps 0.8) on a quarter metre of every half metre of an eps = 0.1 pipe, not disclosed",
        scenario: include_str!("../../scenarios/patchy-pipe.toml"),
    },
    Case {
        name: "free",
        about: "a free-ended body 2.5 m long (controllers' models assume a periodic body)",
        scenario: include_str!("../../scenarios/free-body.toml"),
    },
    Case {
        name: "stick-slip",
        about: "eps = 1: long stick phases (disclosed)",
        scenario: include_str!("../../scenarios/stick-slip.toml"),
    },
];

/// The policies compared by default.
pub const POLICIES: [&str; 4] = ["optimal", "adaptive", "reflex", "resonance"];

/// Options of `crawler compare`.
#[derive(Args)]
pub struct CompareArgs {
    /// Cases, comma separated (default: all: nominal, mismatch, patchy, free, stick-slip).
    #[arg(long, value_delimiter = ',')]
    cases: Vec<String>,
    /// Policies, comma separated (default: optimal, adaptive, reflex, resonance).
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

/// One row of the table.
#[derive(Debug, Clone, Default)]
struct Row {
    case: String,
    policy: String,
    outcome: String,
    time_to_distance: Option<f64>,
    energy: Option<f64>,
    distance: Option<f64>,
    mileage: Option<f64>,
    peak_stress: Option<f64>,
    time_over: Option<f64>,
    wall: f64,
    state_digest: String,
    recording: String,
    error: Option<String>,
}

impl Row {
    fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "case": self.case,
            "policy": self.policy,
            "outcome": self.outcome,
            "time_to_distance": self.time_to_distance,
            "energy_used": self.energy,
            "distance": self.distance,
            "mileage": self.mileage,
            "peak_stress": self.peak_stress,
            "time_above_sigma_max": self.time_over,
            "wall_seconds": self.wall,
            "state_digest": self.state_digest,
            "recording": self.recording,
            "error": self.error,
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
            let row = run_one(&programs, &a, case, policy, &scenario, &interrupted);
            match &row {
                Ok(r) => eprintln!(
                    "crawler: {} / {}: {} ({:.1} s of wall time)",
                    r.case,
                    r.policy,
                    r.error.as_deref().unwrap_or(&r.outcome),
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
                case: case.name.into(),
                policy: policy.clone(),
                outcome: "failed".into(),
                error: Some(format!("{e:#}")),
                ..Row::default()
            }));
        }
    }
    let md = table(&rows);
    std::fs::write(a.out_dir.join("table.md"), &md)?;
    let json = serde_json::Value::Array(rows.iter().map(Row::json).collect());
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
    Ok(if rows.iter().all(|r| r.error.is_none()) {
        Exit::Finished.into()
    } else {
        Exit::Failure.into()
    })
}

fn run_one(
    programs: &Programs,
    a: &CompareArgs,
    case: &Case,
    policy: &str,
    scenario: &Path,
    interrupted: &AtomicBool,
) -> anyhow::Result<Row> {
    let started = Instant::now();
    let run_id = format!("compare-{}-{}-{policy}", std::process::id(), case.name);
    let out = a.out_dir.join(case.name);
    let recording = out.join(format!("{policy}.rrd"));
    let flags = ScenarioArgs {
        scenario: Some(scenario.to_path_buf()),
        t_end: Some(a.t_end),
        cells: a.cells,
        task: true,
        ..ScenarioArgs::default()
    };
    let checkpoint = out.join(format!("{policy}.ckpt"));
    let plant = programs.plant(&PlantRun {
        run_id: &run_id,
        scenario: &flags,
        resume: None,
        wait_timeout: 300.0,
        checkpoint: Some(&checkpoint),
        json: true,
        auth: &Auth::PlantMade,
    });
    let recorder = programs.recorder(&RecorderRun {
        run_id: &run_id,
        out: &recording,
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
        run_id: &run_id,
        policy,
        params: &[],
        scenario: &controller_flags,
        wait_timeout: 300.0,
        auth: &Auth::PlantMade,
        extra: &a.controller_args,
    });
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
        let failed = first_failure(&mut [&mut plant, &mut controller, &mut bridge]);
        if interrupted_with(interrupted, failed) {
            return Err(stop(
                "interrupted",
                &mut [&mut plant, &mut controller, &mut bridge],
            ));
        }
        if let Some((name, code)) = failed {
            return Err(stop(
                &format!("the {name} failed (exit code {code:?}; its messages are above)"),
                &mut [&mut plant, &mut controller, &mut bridge],
            ));
        }
        if Instant::now() >= deadline {
            return Err(stop(
                &format!("no result within --run-timeout {} s", a.run_timeout),
                &mut [&mut plant, &mut controller, &mut bridge],
            ));
        }
        if plant.ended().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let (_, plant_out) = plant.finish(Duration::ZERO);
    let (ctl_code, _) = controller.finish(Duration::from_secs(30));
    let (bridge_code, _) = bridge.finish(Duration::from_secs(60));
    let mut row =
        parse_report(&plant_out).map_err(|e| anyhow::anyhow!("the plant's report: {e}"))?;
    row.case = case.name.into();
    row.policy = policy.into();
    row.wall = started.elapsed().as_secs_f64();
    row.recording = recording.display().to_string();
    if !Exit::Finished.is(ctl_code) {
        row.error = Some(format!("the controller ended with {ctl_code:?}"));
    } else if Exit::Interrupted.is(bridge_code) {
        // still writing a minute after the run ended: stopped, its recording closed properly
        eprintln!(
            "crawler: {} / {policy}: the recorder was still catching up 60 s after the run and was stopped; {} holds what it had written",
            case.name,
            recording.display()
        );
    } else if !Exit::Finished.is(bridge_code) {
        row.error = Some(format!("the recorder ended with {bridge_code:?}"));
    }
    Ok(row)
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
        state_digest: v
            .get("state_digest")
            .and_then(|x| x.as_str())
            .unwrap_or_default()
            .to_string(),
        ..Row::default()
    })
}

fn table(rows: &[Row]) -> String {
    let f = |x: Option<f64>, p: usize| x.map_or("-".to_string(), |v| format!("{v:.p$}"));
    let mut s = String::from(
        "| case | policy | outcome | time to D (s) | energy used (J) | distance (m) | mileage (m/J) | peak stress (kPa) | time above sigma_max (s) |\n\
         | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for r in rows {
        let outcome = match &r.error {
            Some(e) => format!("failed: {}", e.replace('|', "/")),
            None if r.outcome == "reached" => "**reached**".into(),
            None => r.outcome.clone(),
        };
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            r.case,
            r.policy,
            outcome,
            f(r.time_to_distance, 2),
            f(r.energy, 2),
            f(r.distance, 3),
            f(r.mileage, 4),
            f(r.peak_stress.map(|s| s / 1e3), 1),
            f(r.time_over, 3)
        );
    }
    s
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
        let r = parse_report(json).unwrap();
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
        let r = parse_report(&failed).unwrap();
        assert_eq!(r.outcome, "energy exhausted");
        assert_eq!(r.time_to_distance, None);
        assert_eq!(r.energy, Some(19.9));
        assert_eq!(r.mileage, Some(1.0004 / 19.9));
        assert!(table(&[r]).contains("| energy exhausted | - | 19.90 |"));
    }
}
