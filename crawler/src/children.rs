//! The processes of a run as the launcher starts them: which executable, and their command lines
//! built from typed options in one place.
//!
//! The plant and the controller are this executable itself (`crawler plant run ...`, `crawler
//! controller run ...`), so every program a run starts comes from the one build that made the
//! launcher: no second build, no stale sibling binary.

use std::path::{Path, PathBuf};

use crawler_cli::ScenarioArgs;

/// How the run's processes authenticate.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Auth {
    /// With the run's credential file.
    Credential(PathBuf),
    /// With the credential the plant creates in the run's private directory (the others find it
    /// there).
    PlantMade,
    /// Without authentication (`--no-auth`).
    Open,
}

impl Auth {
    fn args(&self) -> Vec<String> {
        match self {
            Auth::Credential(p) => vec!["--credential".into(), p.display().to_string()],
            Auth::PlantMade => Vec::new(),
            Auth::Open => vec!["--no-auth".into()],
        }
    }
}

/// A program and its command line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Invocation {
    /// The executable.
    pub exe: PathBuf,
    /// Its arguments.
    pub args: Vec<String>,
}

impl Invocation {
    /// The same program asked only to check its inputs (`--check`).
    pub fn check(&self) -> Invocation {
        let mut c = self.clone();
        c.args.push("--check".into());
        c
    }
}

/// Where the programs of the project are.
#[derive(Debug, Clone)]
pub struct Programs {
    /// This executable (the plant, the controller and the recorder are its subcommands).
    pub exe: PathBuf,
}

/// The plant of a run.
#[derive(Debug, Clone)]
pub struct PlantRun<'a> {
    /// The run id.
    pub run_id: &'a str,
    /// The scenario and its overrides (ignored when resuming but for `t_end`).
    pub scenario: &'a ScenarioArgs,
    /// A checkpoint to resume from.
    pub resume: Option<&'a Path>,
    /// Seconds to wait for the controller.
    pub wait_timeout: f64,
    /// Where to write the checkpoint if the run stops early (default: the plant's).
    pub checkpoint: Option<&'a Path>,
    /// Print the final report as JSON.
    pub json: bool,
    /// Authentication.
    pub auth: &'a Auth,
}

/// The controller of a run.
#[derive(Debug, Clone)]
pub struct ControllerRun<'a> {
    /// The run id.
    pub run_id: &'a str,
    /// The policy.
    pub policy: &'a str,
    /// Its parameters, `KEY=VALUE`.
    pub params: &'a [String],
    /// The controller's scenario (its task, limits and default wave).
    pub scenario: &'a ScenarioArgs,
    /// Seconds to wait for the plant.
    pub wait_timeout: f64,
    /// Authentication.
    pub auth: &'a Auth,
    /// More arguments, as the user gave them.
    pub extra: &'a [String],
}

/// The recorder of a run.
#[derive(Debug, Clone)]
pub struct RecorderRun<'a> {
    /// The run id.
    pub run_id: &'a str,
    /// The recording.
    pub out: &'a Path,
    /// Fields of every K-th step.
    pub every: u64,
    /// Seconds without a message after which the recorder gives up.
    pub idle_timeout: f64,
    /// Authentication.
    pub auth: &'a Auth,
    /// A viewer to stream to: `Some(Some(url))` one listening at `url`, `Some(None)` one the
    /// recorder starts (`viewer_exe` if given).
    pub viewer: Option<Option<&'a str>>,
    /// The viewer's executable, when the recorder starts one.
    pub viewer_exe: Option<&'a Path>,
}

impl Programs {
    /// The programs next to this executable.
    pub fn here() -> anyhow::Result<Self> {
        Ok(Self {
            exe: std::env::current_exe()?,
        })
    }

    /// `crawler plant run ...`.
    pub fn plant(&self, p: &PlantRun) -> Invocation {
        let mut args: Vec<String> = vec![
            "plant".into(),
            "run".into(),
            "--run-id".into(),
            p.run_id.into(),
        ];
        match p.resume {
            Some(ckpt) => {
                args.extend(["--resume".into(), ckpt.display().to_string()]);
                if let Some(t) = p.scenario.t_end {
                    args.extend(["--t-end".into(), t.to_string()]);
                }
            }
            None => args.extend(p.scenario.to_args()),
        }
        args.extend(["--wait-timeout".into(), p.wait_timeout.to_string()]);
        if let Some(c) = p.checkpoint {
            args.extend(["--checkpoint".into(), c.display().to_string()]);
        }
        if p.json {
            args.push("--json".into());
        }
        args.extend(p.auth.args());
        Invocation {
            exe: self.exe.clone(),
            args,
        }
    }

    /// `crawler controller run ...`.
    pub fn controller(&self, c: &ControllerRun) -> Invocation {
        let mut args: Vec<String> = vec![
            "controller".into(),
            "run".into(),
            "--run-id".into(),
            c.run_id.into(),
            "--policy".into(),
            c.policy.into(),
        ];
        for p in c.params {
            args.extend(["--param".into(), p.clone()]);
        }
        args.extend(c.scenario.to_args());
        args.extend(["--wait-timeout".into(), c.wait_timeout.to_string()]);
        args.extend(c.auth.args());
        args.extend(c.extra.iter().cloned());
        Invocation {
            exe: self.exe.clone(),
            args,
        }
    }

    /// `crawler record ...`.
    pub fn recorder(&self, r: &RecorderRun) -> Invocation {
        let mut args: Vec<String> = vec![
            "record".into(),
            "--run-id".into(),
            r.run_id.into(),
            "--out".into(),
            r.out.display().to_string(),
            "--every".into(),
            r.every.to_string(),
            "--idle-timeout".into(),
            r.idle_timeout.to_string(),
        ];
        args.extend(r.auth.args());
        match r.viewer {
            Some(Some(url)) => args.extend(["--connect".into(), url.into()]),
            Some(None) => {
                args.push("--spawn".into());
                if let Some(exe) = r.viewer_exe {
                    args.extend(["--viewer-exe".into(), exe.display().to_string()]);
                }
            }
            None => {}
        }
        Invocation {
            exe: self.exe.clone(),
            args,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plant_and_the_controller_get_the_same_scenario_flags() {
        let programs = Programs {
            exe: "/x/crawler".into(),
        };
        let scenario = ScenarioArgs {
            scenario: Some("s.toml".into()),
            eps: Some(0.3),
            task: true,
            ..Default::default()
        };
        let auth = Auth::Credential("/run/c".into());
        let plant = programs.plant(&PlantRun {
            run_id: "r",
            scenario: &scenario,
            resume: None,
            wait_timeout: 120.0,
            checkpoint: None,
            json: false,
            auth: &auth,
        });
        let ctl = programs.controller(&ControllerRun {
            run_id: "r",
            policy: "reflex",
            params: &["stick_gain=0.2".into()],
            scenario: &scenario,
            wait_timeout: 60.0,
            auth: &auth,
            extra: &[],
        });
        let flags = scenario.to_args();
        let has = |args: &[String]| args.windows(flags.len()).any(|w| w == flags.as_slice());
        assert!(has(&plant.args) && has(&ctl.args), "{plant:?} {ctl:?}");
        assert_eq!(&plant.args[..2], ["plant", "run"]);
        assert_eq!(&ctl.args[..2], ["controller", "run"]);
        assert!(ctl
            .args
            .windows(2)
            .any(|w| w == ["--param", "stick_gain=0.2"]));
        assert!(plant.check().args.ends_with(&["--check".to_string()]));
    }

    #[test]
    fn a_resumed_plant_takes_its_scenario_from_the_checkpoint() {
        let programs = Programs {
            exe: "/x/crawler".into(),
        };
        let scenario = ScenarioArgs {
            scenario: Some("s.toml".into()),
            t_end: Some(20.0),
            ..Default::default()
        };
        let plant = programs.plant(&PlantRun {
            run_id: "r",
            scenario: &scenario,
            resume: Some(Path::new("runs/r/plant.ckpt")),
            wait_timeout: 120.0,
            checkpoint: None,
            json: false,
            auth: &Auth::Open,
        });
        assert!(!plant.args.contains(&"--scenario".to_string()));
        assert!(plant.args.windows(2).any(|w| w == ["--t-end", "20"]));
        assert!(plant.args.contains(&"--no-auth".to_string()));
    }
}
