//! What a policy's control law costs per communication step, in process (no network): each
//! policy drives the plant of a scenario in closed loop, and the time spent in `act` is measured
//! apart from the plant's step. Policies are interleaved trial by trial.
//!
//! Usage: cargo run --release -p crawler-policies --example policy_cost --
//!        [SCENARIO.toml] [--cells N] [--t-end S] [--trials K]
//!        [--policies wave,adaptive,adaptive@0,reflex]
//!
//! `adaptive@L` is the adaptive policy with a re-plan latency of L s of simulated time (default
//! 1 s): a step that comes to the end of the latency before the worker thread has answered waits
//! for it (the price of a reproducible run); with `@0` no step ever waits.

use std::time::Instant;

use crawler_physics::scenario::{Overrides, Scenario};
use crawler_policies::{in_process, Actuation, Context, Insight, Observation, Params, Policy};

/// A policy with a stopwatch around `act`.
struct Timed {
    inner: Box<dyn Policy>,
    seconds: f64,
    calls: u64,
}

impl Policy for Timed {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn act(&mut self, obs: &Observation) -> Actuation {
        let t = Instant::now();
        let a = self.inner.act(obs);
        self.seconds += t.elapsed().as_secs_f64();
        self.calls += 1;
        a
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
    fn insight(&mut self) -> Option<Insight> {
        self.inner.insight()
    }
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let (mut file, mut cells, mut t_end, mut trials) = (None, 256i64, 20.0, 3usize);
    let mut names = vec![
        "wave".to_string(),
        "adaptive".into(),
        "adaptive@0".into(),
        "reflex".into(),
    ];
    while let Some(a) = args.next() {
        let mut value = || {
            args.next()
                .ok_or_else(|| anyhow::anyhow!("{a} needs a value"))
        };
        match a.as_str() {
            "--cells" => cells = value()?.parse()?,
            "--t-end" => t_end = value()?.parse()?,
            "--trials" => trials = value()?.parse()?,
            "--policies" => names = value()?.split(',').map(String::from).collect(),
            f if !f.starts_with("--") => file = Some(f.to_string()),
            f => anyhow::bail!("unknown flag {f}"),
        }
    }
    let path =
        std::path::PathBuf::from(file.unwrap_or_else(|| {
            concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/paper.toml").into()
        }));
    let scenario = Scenario::from_file(
        &path,
        &Overrides {
            cells: Some(cells),
            t_end: Some(t_end),
            ..Overrides::default()
        },
    )?;
    let mut act = vec![Vec::new(); names.len()];
    let mut total = vec![Vec::new(); names.len()];
    let mut steps = 0;
    for t in 0..trials {
        let order: Vec<usize> = if t % 2 == 0 {
            (0..names.len()).collect()
        } else {
            (0..names.len()).rev().collect()
        };
        for i in order {
            let (name, latency) = match names[i].split_once('@') {
                Some((n, l)) => (n, Some(l.parse::<f64>()?)),
                None => (names[i].as_str(), None),
            };
            let params = match latency {
                Some(l) => Params::parse(&[format!("latency={l}")])?,
                None => Params::none(),
            };
            let ctx = Context::of(&scenario)?;
            let mut p = Timed {
                inner: crawler_policies::build(name, &ctx, &params)?,
                seconds: 0.0,
                calls: 0,
            };
            let started = Instant::now();
            let run = in_process::run(&scenario, &mut p)?;
            total[i].push(started.elapsed().as_secs_f64() / run.steps as f64);
            act[i].push(p.seconds / p.calls as f64);
            steps = run.steps;
        }
    }
    println!(
        "{}: N = {cells}, {steps} steps, medians of {trials} trials, in process (no network)",
        path.display()
    );
    println!();
    println!("| policy | act, us per step | plant + act, us per step | act / (plant + act) |");
    println!("| --- | ---: | ---: | ---: |");
    for (i, name) in names.iter().enumerate() {
        let (a, t) = (median(act[i].clone()), median(total[i].clone()));
        println!(
            "| `{name}` | {:.2} | {:.2} | {:.3} |",
            a * 1e6,
            t * 1e6,
            a / t
        );
    }
    Ok(())
}
