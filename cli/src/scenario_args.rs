//! The scenario flags shared by `crawler-plant` and `crawler-controller`.

use std::path::PathBuf;

use clap::Args;

use crawler_physics::scenario::{Overrides, Scenario, ScenarioError};

/// Scenario file and the common overrides.
#[derive(Args, Debug, Clone, Default)]
pub struct ScenarioArgs {
    /// Scenario TOML file (default: the embedded scenarios/paper.toml).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Dry friction coefficient eps (>= 0).
    #[arg(long, allow_hyphen_values = true)]
    pub eps: Option<f64>,
    /// Friction asymmetry n_F (0 <= n_F <= 1).
    #[arg(long = "n-f", allow_hyphen_values = true)]
    pub n_f: Option<f64>,
    /// Wave amplitude f0, N.
    #[arg(long, allow_hyphen_values = true)]
    pub f0: Option<f64>,
    /// Wave number k, rad/m (the body is one wavelength unless the scenario sets body.length).
    #[arg(long, allow_hyphen_values = true)]
    pub k: Option<f64>,
    /// Angular frequency omega, rad/s.
    #[arg(long, conflicts_with = "alpha", allow_hyphen_values = true)]
    pub omega: Option<f64>,
    /// Frequency ratio: omega = alpha * omega_n, omega_n = k sqrt(A_c E / rho).
    #[arg(long, allow_hyphen_values = true)]
    pub alpha: Option<f64>,
    /// Number of cells N.
    #[arg(long, allow_hyphen_values = true)]
    pub cells: Option<i64>,
    /// End time, s.
    #[arg(long = "t-end", allow_hyphen_values = true)]
    pub t_end: Option<f64>,
    /// Task mode: end the run when the body has travelled task.distance (success) or spent
    /// task.energy (failure), as `task.end_run = true` in the scenario.
    #[arg(long)]
    pub task: bool,
}

impl ScenarioArgs {
    /// The overrides given.
    pub fn overrides(&self) -> Overrides {
        Overrides {
            eps: self.eps,
            n_f: self.n_f,
            f0: self.f0,
            k: self.k,
            omega: self.omega,
            alpha: self.alpha,
            cells: self.cells,
            t_end: self.t_end,
            end_run: self.task.then_some(true),
        }
    }

    /// The flags as a command line that gives these flags again (for a program that starts
    /// another with the same scenario); numbers in full precision.
    pub fn to_args(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(s) = &self.scenario {
            out.extend(["--scenario".to_string(), s.display().to_string()]);
        }
        let numbers = [
            ("--eps", self.eps),
            ("--n-f", self.n_f),
            ("--f0", self.f0),
            ("--k", self.k),
            ("--omega", self.omega),
            ("--alpha", self.alpha),
            ("--t-end", self.t_end),
        ];
        for (flag, x) in numbers {
            if let Some(x) = x {
                out.extend([flag.to_string(), x.to_string()]);
            }
        }
        if let Some(n) = self.cells {
            out.extend(["--cells".to_string(), n.to_string()]);
        }
        if self.task {
            out.push("--task".to_string());
        }
        out
    }

    /// Loads the scenario with the overrides applied. An invalid value that came from a flag is
    /// reported under the flag's name with the scenario key it overrides
    /// (`invalid --eps (friction.eps) = NaN: ...`), not under the key alone.
    pub fn load(&self) -> Result<Scenario, ScenarioError> {
        Scenario::load(self.scenario.as_deref(), &self.overrides()).map_err(|e| match e {
            ScenarioError::Invalid { origin, mut cause } => {
                if let Some(flag) = self.flag_for(&cause.field) {
                    cause.field = format!("{flag} ({})", cause.field);
                }
                ScenarioError::Invalid { origin, cause }
            }
            other => other,
        })
    }

    /// The flag given on the command line that set the scenario key `field`, if any.
    fn flag_for(&self, field: &str) -> Option<&'static str> {
        [
            ("friction.eps", "--eps", self.eps.is_some()),
            ("friction.n_f", "--n-f", self.n_f.is_some()),
            ("actuation.f0", "--f0", self.f0.is_some()),
            ("actuation.k", "--k", self.k.is_some()),
            ("actuation.omega", "--omega", self.omega.is_some()),
            ("actuation.alpha", "--alpha", self.alpha.is_some()),
            ("numerics.cells", "--cells", self.cells.is_some()),
            ("numerics.t_end", "--t-end", self.t_end.is_some()),
        ]
        .into_iter()
        .find(|&(key, _, given)| given && key == field)
        .map(|(_, flag, _)| flag)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn error(args: ScenarioArgs) -> String {
        args.load().unwrap_err().to_string()
    }

    #[test]
    fn a_bad_flag_is_named_by_its_flag_and_its_key() {
        let e = error(ScenarioArgs {
            eps: Some(f64::NAN),
            ..Default::default()
        });
        assert!(e.contains("invalid --eps (friction.eps) = NaN"), "{e}");
        let e = error(ScenarioArgs {
            n_f: Some(2.0),
            ..Default::default()
        });
        assert!(e.contains("invalid --n-f (friction.n_f) = 2"), "{e}");
        let e = error(ScenarioArgs {
            cells: Some(1),
            ..Default::default()
        });
        assert!(e.contains("invalid --cells (numerics.cells) = 1"), "{e}");
        let e = error(ScenarioArgs {
            alpha: Some(-1.0),
            ..Default::default()
        });
        assert!(e.contains("invalid --alpha (actuation.alpha) = -1"), "{e}");
        let e = error(ScenarioArgs {
            t_end: Some(f64::INFINITY),
            ..Default::default()
        });
        assert!(e.contains("invalid --t-end (numerics.t_end) = inf"), "{e}");
    }

    #[test]
    fn the_flags_given_again_parse_back_to_the_same_flags() {
        use clap::Parser;
        #[derive(Parser)]
        struct P {
            #[command(flatten)]
            s: ScenarioArgs,
        }
        let a = ScenarioArgs {
            scenario: Some("x.toml".into()),
            eps: Some(0.1 + 0.2),
            alpha: Some(-1e-300),
            cells: Some(-3),
            t_end: Some(7.0),
            task: true,
            ..Default::default()
        };
        let args = std::iter::once("p".to_string()).chain(a.to_args());
        let back = P::try_parse_from(args).unwrap().s;
        assert_eq!(back.to_args(), a.to_args());
        assert_eq!(back.eps.unwrap().to_bits(), (0.1f64 + 0.2).to_bits());
        assert_eq!((back.cells, back.task), (Some(-3), true));
    }

    #[test]
    fn a_bad_value_from_the_file_keeps_its_key() {
        let dir = std::env::temp_dir().join(format!("crawler-cli-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bad.toml");
        let text = crawler_physics::scenario::PAPER_TOML.replace("eps = 0.1", "eps = -0.5");
        std::fs::write(&path, text).unwrap();
        // --f0 is given but valid: the error is about the file's eps, named by its key only
        let e = error(ScenarioArgs {
            scenario: Some(path.clone()),
            f0: Some(0.3),
            ..Default::default()
        });
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(e.contains("invalid friction.eps = -0.5"), "{e}");
        assert!(!e.contains("--"), "{e}");
    }
}
