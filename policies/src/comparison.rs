//! The comparison of the policies on the task: its cases, its oracle and its table, written once
//! for `crawler compare` (the co-simulation) and for the in-process table the docs show
//! ([`run_in_process`], bit-identical to the co-simulation by the one-result rule).
//!
//! The **oracle** of a case is the open-loop optimum (`optimal`) given the true pipe: the case's
//! scenario with its pipe disclosed ([`disclosed`]). A row's **share of the oracle's gain** is
//! `(t_open - t) / (t_open - t_oracle)` with `t` its time to D and `t_open` the open-loop
//! optimum's (planned for the friction it was told): 0 is no better than the open loop, 1 as
//! good as knowing the pipe. It is given when the open loop and the oracle reach D and the oracle
//! is at least 0.1 % sooner; where the open loop fails, the table says so.

use crawler_physics::scenario::{Overrides, Scenario};
use crawler_physics::task::TaskReport;

use crate::{in_process, Params};

/// A case: name, what it is, the scenario (embedded).
#[derive(Debug, Clone, Copy)]
pub struct Case {
    /// Short name (`--cases`).
    pub name: &'static str,
    /// One line.
    pub about: &'static str,
    /// The scenario file's text.
    pub scenario: &'static str,
}

/// The cases of the comparison.
pub const CASES: [Case; 10] = [
    Case {
        name: "nominal",
        about: "the paper's crawler and pipe (eps = 0.1, n_F = 0.5), as every controller is told",
        scenario: include_str!("../../scenarios/paper.toml"),
    },
    Case {
        name: "mismatch",
        about: "more friction than told: eps = 0.3, n_F = 0.7 while controllers are told the paper's 0.1 and 0.5",
        scenario: include_str!("../../scenarios/mismatch.toml"),
    },
    Case {
        name: "patchy",
        about: "dry patches (eps 0.8) on a quarter metre of every half metre of an eps = 0.1 pipe, not disclosed",
        scenario: include_str!("../../scenarios/patchy-pipe.toml"),
    },
    Case {
        name: "slippery",
        about: "less friction than told: eps = 0.07 while controllers are told 0.1 (n_F = 0.5 as told)",
        scenario: include_str!("../../scenarios/slippery.toml"),
    },
    Case {
        name: "slippery-patches",
        about: "slippery patches (eps 0.03) on a quarter metre of every half metre of an eps = 0.1 pipe, not disclosed",
        scenario: include_str!("../../scenarios/slippery-patches.toml"),
    },
    Case {
        name: "drift",
        about: "friction drifting along the pipe: eps from 0.1 to 0.04 and n_F from 0.5 to 0.4 over 2 m, not disclosed",
        scenario: include_str!("../../scenarios/drift.toml"),
    },
    Case {
        name: "held-out-slippery",
        about: "held out (no policy tuned on it): eps = 0.06, n_F = 0.35, told 0.1 and 0.5",
        scenario: include_str!("../../scenarios/held-out-slippery.toml"),
    },
    Case {
        name: "held-out-sticky",
        about: "held out (no policy tuned on it): eps = 0.2, n_F = 0.3, told 0.1 and 0.5",
        scenario: include_str!("../../scenarios/held-out-sticky.toml"),
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

/// The name of the oracle's row.
pub const ORACLE: &str = "oracle";

/// The policies compared by default (the oracle is the open-loop optimum given the true pipe).
pub const POLICIES: [&str; 5] = ["optimal", ORACLE, "adaptive", "reflex", "resonance"];

/// The case's scenario text with its pipe disclosed: what the oracle is told (controllers are
/// then told the true friction and its map; the plant's physics is unchanged).
pub fn disclosed(scenario: &str) -> anyhow::Result<String> {
    let mut doc: toml::Table = toml::from_str(scenario)?;
    let pipe = doc
        .entry("pipe")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    let Some(pipe) = pipe.as_table_mut() else {
        anyhow::bail!("invalid scenario: pipe is not a table");
    };
    pipe.insert("disclose".into(), toml::Value::Boolean(true));
    Ok(toml::to_string(&doc)?)
}

/// The policy that runs a row and the scenario text it runs in.
pub fn route(case: &Case, policy: &str) -> anyhow::Result<(String, String)> {
    Ok(if policy == ORACLE {
        ("optimal".into(), disclosed(case.scenario)?)
    } else {
        (policy.into(), case.scenario.into())
    })
}

/// One row of the table.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Row {
    /// The case's name.
    pub case: String,
    /// The policy's name (or [`ORACLE`]).
    pub policy: String,
    /// The task's outcome in words ("reached", "stress exceeded", "energy exhausted",
    /// "time up"), or "failed" when the run did not end with a report.
    pub outcome: String,
    /// Time to D, s.
    pub time_to_distance: Option<f64>,
    /// Energy spent at D, or in all when D was not reached, J.
    pub energy: Option<f64>,
    /// Distance travelled, m.
    pub distance: Option<f64>,
    /// D over the energy at D, or the distance travelled over the energy spent, m/J.
    pub mileage: Option<f64>,
    /// Largest stress, Pa.
    pub peak_stress: Option<f64>,
    /// Time above sigma_max, s.
    pub time_over: Option<f64>,
    /// Why the run failed to give a report.
    pub error: Option<String>,
}

impl Row {
    /// The row of a task report.
    pub fn of(case: &str, policy: &str, t: &TaskReport) -> Self {
        let energy = t.energy_at_distance.unwrap_or(t.energy_used);
        let travelled = if t.energy_at_distance.is_some() {
            t.distance_target
        } else {
            t.distance
        };
        Self {
            case: case.into(),
            policy: policy.into(),
            outcome: t.outcome.as_str().into(),
            time_to_distance: t.time_to_distance,
            energy: Some(energy),
            distance: Some(t.distance),
            mileage: (energy > 0.0).then(|| travelled / energy),
            peak_stress: Some(t.max_stress),
            time_over: Some(t.time_over_sigma_max),
            error: None,
        }
    }

    /// True if the task succeeded: D reached within J0, never above sigma_max for longer than
    /// the task allows (the outcome says "reached" only then).
    pub fn succeeded(&self) -> bool {
        self.error.is_none() && self.outcome == "reached"
    }
}

/// The share of the oracle's gain a row recovers, in words for the table.
pub fn share(rows: &[Row], row: &Row) -> String {
    let find = |p: &str| rows.iter().find(|r| r.case == row.case && r.policy == p);
    let (Some(open), Some(oracle)) = (find("optimal"), find(ORACLE)) else {
        return "-".into();
    };
    if !open.succeeded() {
        return "open loop fails".into();
    }
    let (Some(t_open), Some(t_oracle)) = (open.time_to_distance, oracle.time_to_distance) else {
        return "-".into();
    };
    if !oracle.succeeded() || t_open - t_oracle < 1e-3 * t_open {
        return "no gain to recover".into();
    }
    match row.time_to_distance.filter(|_| row.succeeded()) {
        Some(t) => format!("{:.2}", (t_open - t) / (t_open - t_oracle)),
        None => "-".into(),
    }
}

/// The table in Markdown.
pub fn table(rows: &[Row]) -> String {
    let f = |x: Option<f64>, p: usize| x.map_or("-".to_string(), |v| format!("{v:.p$}"));
    let mut s = String::from(
        "| case | policy | outcome | time to D (s) | energy used (J) | distance (m) | mileage (m/J) | peak stress (kPa) | time above sigma_max (s) | share of the oracle's gain |\n\
         | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for r in rows {
        let outcome = match &r.error {
            Some(e) => format!("failed: {}", e.replace('|', "/")),
            None if r.outcome == "reached" => "**reached**".into(),
            None => r.outcome.clone(),
        };
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            r.case,
            r.policy,
            outcome,
            f(r.time_to_distance, 3),
            f(r.energy, 2),
            f(r.distance, 3),
            f(r.mileage, 4),
            f(r.peak_stress.map(|s| s / 1e3), 1),
            f(r.time_over, 3),
            share(rows, r)
        );
    }
    s
}

/// Runs one row in process (the plant's execution loop with the policy; the same bits as the
/// co-simulation), in task mode with `cells` cells (the scenario's own if `None`) until `t_end`.
pub fn run_in_process(
    case: &Case,
    policy: &str,
    cells: Option<i64>,
    t_end: f64,
) -> anyhow::Result<Row> {
    let (name, text) = route(case, policy)?;
    let sc = Scenario::from_toml(
        &text,
        case.name,
        &Overrides {
            cells,
            t_end: Some(t_end),
            end_run: Some(true),
            ..Overrides::default()
        },
    )?;
    let run = in_process::run_named(&sc, &name, &Params::none())?;
    let task = run
        .report
        .task
        .ok_or_else(|| anyhow::anyhow!("{} / {policy}: no task in the report", case.name))?;
    Ok(Row::of(case.name, policy, &task))
}

/// The whole table in process, `threads` runs at a time, rows in the order of `cases` and
/// `policies`.
pub fn in_process_table(
    cases: &[Case],
    policies: &[&str],
    cells: Option<i64>,
    t_end: f64,
    threads: usize,
) -> anyhow::Result<Vec<Row>> {
    let jobs: Vec<(Case, &str)> = cases
        .iter()
        .flat_map(|c| policies.iter().map(move |p| (*c, *p)))
        .collect();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(vec![None; jobs.len()]);
    std::thread::scope(|s| {
        for _ in 0..threads.max(1) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                let Some((case, policy)) = jobs.get(i) else {
                    break;
                };
                let row = run_in_process(case, policy, cells, t_end).map_err(|e| format!("{e:#}"));
                results.lock().expect("no thread panicked holding it")[i] = Some(row);
            });
        }
    });
    results
        .into_inner()
        .expect("no thread panicked holding it")
        .into_iter()
        .map(|r| match r {
            Some(Ok(row)) => Ok(row),
            Some(Err(e)) => Err(anyhow::anyhow!(e)),
            None => Err(anyhow::anyhow!("a run did not finish")),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_oracle_is_told_the_true_pipe_and_runs_the_same_plant() {
        for case in CASES {
            let told =
                Scenario::from_toml(case.scenario, case.name, &Overrides::default()).unwrap();
            let text = disclosed(case.scenario).unwrap();
            let oracle = Scenario::from_toml(&text, case.name, &Overrides::default()).unwrap();
            assert!(oracle.plant.pipe.disclose, "{}", case.name);
            // the plant is the same but for what controllers are told
            let mut same = told.clone();
            same.plant.pipe.disclose = true;
            assert_eq!(
                format!("{:?}", same.plant),
                format!("{:?}", oracle.plant),
                "{}",
                case.name
            );
            assert_eq!(oracle.plant.told().friction, oracle.plant.friction);
        }
    }

    fn row(case: &str, policy: &str, outcome: &str, t: Option<f64>) -> Row {
        Row {
            case: case.into(),
            policy: policy.into(),
            outcome: outcome.into(),
            time_to_distance: t,
            ..Row::default()
        }
    }

    #[test]
    fn the_share_of_the_oracles_gain_is_zero_for_the_open_loop_and_one_for_the_oracle() {
        let rows = [
            row("a", "optimal", "reached", Some(6.0)),
            row("a", ORACLE, "reached", Some(5.0)),
            row("a", "adaptive", "reached", Some(5.5)),
            row("a", "reflex", "stress exceeded", Some(4.0)),
            row("b", "optimal", "energy exhausted", None),
            row("b", ORACLE, "reached", Some(30.0)),
            row("b", "adaptive", "reached", Some(31.0)),
        ];
        let shares: Vec<String> = rows.iter().map(|r| share(&rows, r)).collect();
        assert_eq!(
            shares,
            [
                "0.00",
                "1.00",
                "0.50",
                "-",
                "open loop fails",
                "open loop fails",
                "open loop fails"
            ]
        );
        // a run over the stress limit is not a success, whatever its time
        let t = table(&rows);
        assert!(
            t.contains("| a | reflex | stress exceeded | 4.000 |"),
            "{t}"
        );
        assert!(t.contains("| a | adaptive | **reached** | 5.500 |"), "{t}");
    }
}
