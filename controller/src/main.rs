//! `crawler-controller`: predictions, the optimal policy, figures, and controllers for co-simulation.

use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use serde_json::json;

use crawler_cli::Exit;
use crawler_cli::ScenarioArgs;
use crawler_controller::optimizer::{
    BodyLength, GridSpec, ModelChoice, Problem, DEFAULT_TIE_TOLERANCE,
};
use crawler_controller::paper_model::{PaperModel, PaperTerms};
use crawler_controller::policies::REGISTRY;
use crawler_controller::verify;
use crawler_controller::OperatingPoint;

/// `println!` that returns the error instead of panicking: a reader that closed the pipe ends
/// the output (`crawler_cli::stdout`).
macro_rules! out {
    ($($arg:tt)*) => {
        crawler_cli::stdout::line(format_args!($($arg)*))?
    };
}

#[derive(Parser)]
#[command(
    name = "crawler-controller",
    version,
    about = "Soft-crawler models, optimal policy and controllers"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Predict the steady state with a reduced model (same flags as `crawler-plant simulate`).
    Predict(PredictArgs),
    /// Maximise V subject to mileage, stress, strain and actuator limits.
    Optimize(OptimizeArgs),
    /// List the registered policies.
    Policies,
    /// Time the optimiser and the improved model against one plant run (prints JSON).
    Bench,
    /// Write the paper's Fig. 5 and Fig. 6 (paper model beside the improved model) as PNG and CSV.
    Figures(FiguresArgs),
    /// Control a co-simulation run over zenoh: answer every plant state with an actuation.
    Run(RunArgs),
}

#[derive(Args)]
struct FiguresArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// Output directory.
    #[arg(long, default_value = "figures")]
    out: std::path::PathBuf,
    /// Points per axis of the omega-k planes with the improved model.
    #[arg(long, default_value_t = 36)]
    improved_points: usize,
}

#[derive(Args)]
struct RunArgs {
    /// The policy (see `crawler-controller policies`).
    #[arg(long, default_value = "optimal")]
    policy: String,
    /// Scenario file for the task, the limits and the default wave (default: the paper's).
    /// The plant's physical parameters come from the plant itself.
    #[arg(long, value_name = "FILE")]
    scenario: Option<std::path::PathBuf>,
    #[command(flatten)]
    network: crawler_transport::NetworkArgs,
    /// Wave amplitude f0, N (wave, resonance, sweep).
    #[arg(long, allow_hyphen_values = true)]
    f0: Option<f64>,
    /// Wave number k, rad/m (must fit the plant's body).
    #[arg(long, allow_hyphen_values = true)]
    k: Option<f64>,
    /// Angular frequency, rad/s (wave).
    #[arg(long, conflicts_with = "alpha", allow_hyphen_values = true)]
    omega: Option<f64>,
    /// omega / omega_n (wave).
    #[arg(long, allow_hyphen_values = true)]
    alpha: Option<f64>,
    /// sweep: the alpha values, comma separated.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    sweep: Vec<f64>,
    /// sweep: seconds at each alpha.
    #[arg(long, allow_hyphen_values = true)]
    dwell: Option<f64>,
    /// optimal: the model (paper, improved).
    #[arg(long)]
    model: Option<String>,
    /// optimal: grid points per axis.
    #[arg(long)]
    grid: Option<usize>,
    /// optimal: skip certifying the constraints on the in-process plant.
    #[arg(long)]
    no_certify: bool,
    /// optimal: relative margin kept on every constraint when certifying.
    #[arg(long, default_value_t = 0.005, allow_hyphen_values = true)]
    margin: f64,
    /// adaptive: a setting KEY=VALUE (repeatable; `crawler-controller policies` lists the keys).
    #[arg(long = "adaptive", value_name = "KEY=VALUE")]
    adaptive: Vec<String>,
    /// reflex: a setting KEY=VALUE (repeatable; `crawler-controller policies` lists the keys).
    #[arg(long = "reflex", value_name = "KEY=VALUE")]
    reflex: Vec<String>,
    /// Seconds to wait for the plant.
    #[arg(long, default_value_t = 60.0)]
    wait_timeout: f64,
    /// Print the final summary as JSON.
    #[arg(long)]
    json: bool,
    /// Validate every input (policy, scenario, options, network) and exit without joining a run.
    #[arg(long)]
    check: bool,
}

#[derive(Args)]
struct PredictArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// paper, or improved (alias travelling-wave).
    #[arg(long, default_value = "improved")]
    model: String,
    /// The improved model's march steps per forcing period (default 1024; its stick statistics
    /// converge at first order in them, V, P and sigma at second).
    #[arg(long, value_name = "STEPS")]
    march_steps: Option<usize>,
}

#[derive(Args)]
struct OptimizeArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    /// paper, or improved (alias travelling-wave).
    #[arg(long, default_value = "paper")]
    model: String,
    /// Grid points in omega (default: 200 with the paper model, 32 with the improved one, whose
    /// every grid cell solves a nonsmooth ODE; the refinement of the best cell follows either way).
    #[arg(long)]
    omega_points: Option<usize>,
    /// Grid points in k (default: as for omega).
    #[arg(long)]
    k_points: Option<usize>,
    /// Keep the scenario's body length (k must fit it) instead of the paper's one-wavelength body.
    #[arg(long)]
    fixed_body: bool,
    /// Distance D, m (overrides the scenario's task).
    #[arg(long, allow_hyphen_values = true)]
    distance: Option<f64>,
    /// Energy budget J0, J.
    #[arg(long, allow_hyphen_values = true)]
    energy: Option<f64>,
    /// Stress limit sigma_max, Pa.
    #[arg(long, allow_hyphen_values = true)]
    sigma_max: Option<f64>,
    /// Strain limit max |u_x|.
    #[arg(long, allow_hyphen_values = true)]
    strain_max: Option<f64>,
    /// Actuator limit f0_max, N.
    #[arg(long, allow_hyphen_values = true)]
    f0_max: Option<f64>,
    /// Bounds on omega, rad/s: MIN,MAX.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    omega_range: Option<Vec<f64>>,
    /// Bounds on k, rad/m: MIN,MAX.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    k_range: Option<Vec<f64>>,
    /// Skip the local refinement of the best cell.
    #[arg(long)]
    no_refine: bool,
    /// Cells within this relative speed of the fastest are tied; the tie goes to the lowest f0
    /// (the optimum is a ridge: docs/physics.md §5.3). 0 takes the fastest cell.
    #[arg(long, default_value_t = DEFAULT_TIE_TOLERANCE, allow_hyphen_values = true)]
    tie_tolerance: f64,
    /// Run the in-process plant at the optimum and compare.
    #[arg(long)]
    verify: bool,
    /// Lower f0 with plant runs until every constraint holds on the plant with --margin to spare.
    #[arg(long)]
    certify: bool,
    /// Relative margin for --certify.
    #[arg(long, default_value_t = 0.01, allow_hyphen_values = true)]
    margin: f64,
    /// Print JSON (with the whole grid).
    #[arg(long)]
    json: bool,
}

fn main() -> ExitCode {
    crawler_cli::cpu::ensure_cpu_features();
    let cli = Cli::parse();
    if let Command::Run(a) = cli.command {
        return match run_client(a) {
            Ok(code) => code,
            Err(e) if crawler_cli::stdout::is_broken_pipe(e.as_ref()) => Exit::Finished.into(),
            Err(e) => {
                eprintln!("crawler-controller: error: {e:#}");
                Exit::Failure.into()
            }
        };
    }
    match run(cli) {
        Ok(()) => Exit::Finished.into(),
        // the reader of the output went away (`| head`): the output ends there
        Err(e) if crawler_cli::stdout::is_broken_pipe(e.as_ref()) => Exit::Finished.into(),
        Err(e) => {
            eprintln!("crawler-controller: error: {e:#}");
            Exit::Failure.into()
        }
    }
}

fn run_client(a: RunArgs) -> anyhow::Result<ExitCode> {
    use crawler_controller::client::{run, ClientOptions, ClientOutcome, Interrupt};
    use crawler_controller::controller::PolicyOptions;
    let scenario =
        crawler_plant::scenario::Scenario::load(a.scenario.as_deref(), &Default::default())?;
    let network = a.network.network()?;
    anyhow::ensure!(
        a.wait_timeout.is_finite() && a.wait_timeout > 0.0 && a.wait_timeout < 1e9,
        "invalid --wait-timeout = {}: allowed a number of seconds, 0 < wait-timeout < 1e9",
        crawler_cli::number(a.wait_timeout)
    );
    for (name, x) in [
        ("f0", a.f0),
        ("k", a.k),
        ("omega", a.omega),
        ("alpha", a.alpha),
        ("dwell", a.dwell),
    ] {
        if let Some(x) = x {
            anyhow::ensure!(
                x.is_finite() && (x > 0.0 || (name == "f0" && x == 0.0)),
                "invalid --{name} = {x}: allowed a finite number > 0"
            );
        }
    }
    let model = a
        .model
        .as_deref()
        .map(ModelChoice::parse)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    crawler_controller::policies::lookup(&a.policy)?;
    anyhow::ensure!(
        a.margin.is_finite() && (0.0..0.5).contains(&a.margin),
        "invalid --margin = {}: allowed 0 <= margin < 0.5",
        a.margin
    );
    if a.check {
        eprintln!(
            "crawler-controller: inputs valid (policy {}, {})",
            a.policy,
            network.describe()
        );
        return Ok(Exit::Finished.into());
    }
    let options = PolicyOptions {
        f0: a.f0,
        k: a.k,
        omega: a.omega,
        alpha: a.alpha,
        sweep: a.sweep.clone(),
        dwell: a.dwell,
        model,
        grid: a.grid,
        certify: !a.no_certify,
        margin: a.margin,
    };
    let (tx, rx) = crossbeam_channel::unbounded::<Interrupt>();
    ctrlc::set_handler(move || {
        let _ = tx.send(Interrupt);
    })?;
    let feedback =
        crawler_controller::controller::FeedbackOptions::from_settings(&a.adaptive, &a.reflex)?;
    let opts = ClientOptions {
        policy: a.policy.clone(),
        options,
        feedback,
        scenario,
        network,
        wait_timeout: std::time::Duration::from_secs_f64(a.wait_timeout),
    };
    match run(opts, rx)? {
        ClientOutcome::Finished(summary) => {
            if a.json {
                out!("{}", serde_json::to_string_pretty(&summary)?);
            } else {
                crawler_cli::stdout::text(summary.table())?;
            }
            Ok(Exit::Finished.into())
        }
        ClientOutcome::Ended { reason, exit } => {
            eprintln!("crawler-controller: run ended: {reason}");
            Ok(exit.into())
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Run(_) => unreachable!("handled in main"),
        Command::Predict(a) => predict(a),
        Command::Optimize(a) => optimize(a),
        Command::Figures(a) => {
            let scenario = a.scenario.load()?;
            anyhow::ensure!(
                (4..=400).contains(&a.improved_points),
                "invalid --improved-points = {}: allowed 4 to 400",
                a.improved_points
            );
            let opts = crawler_controller::figures::FigureOptions {
                plane_points_improved: a.improved_points,
                ..Default::default()
            };
            for f in crawler_controller::figures::write_figures(&scenario, &a.out, opts)? {
                out!("{}", f.display());
            }
            Ok(())
        }
        Command::Bench => {
            let r = crawler_controller::bench::run(&crawler_plant::scenario::Scenario::paper())?;
            out!("{}", serde_json::to_string(&r)?);
            Ok(())
        }
        Command::Policies => {
            for (name, help, _) in REGISTRY {
                out!("{name:<10} {help}");
            }
            println!();
            println!(
                "--adaptive KEY=VALUE: {}",
                crawler_controller::policies::AdaptiveOptions::KEYS.join(", ")
            );
            println!(
                "--reflex KEY=VALUE:   {}",
                crawler_controller::policies::ReflexOptions::KEYS.join(", ")
            );
            Ok(())
        }
    }
}

fn predict(a: PredictArgs) -> anyhow::Result<()> {
    let scenario = a.scenario.load()?;
    let mut model = ModelChoice::parse(&a.model).map_err(anyhow::Error::msg)?;
    if let Some(steps) = a.march_steps {
        anyhow::ensure!(
            (16..=1 << 22).contains(&steps),
            "invalid --march-steps = {steps}: allowed 16 to {} steps per period",
            1 << 22
        );
        match &mut model {
            ModelChoice::Improved(m) => m.steps = steps,
            ModelChoice::Paper => anyhow::bail!(
                "invalid --march-steps with --model paper: allowed only with the improved model"
            ),
        }
    }
    let op = OperatingPoint::of(&scenario);
    let prediction = model.predict(&op);
    let mut out = serde_json::to_value(&prediction)?;
    out["alpha"] = json!(op.alpha());
    out["zeta"] = json!(op.zeta());
    out["pi_r"] = json!(op.pi_r());
    out["omega"] = json!(op.wave.omega);
    out["k"] = json!(op.wave.k);
    out["f0"] = json!(op.wave.f0);
    out["eps"] = json!(op.friction.eps);
    out["n_f"] = json!(op.friction.n_f);
    if let ModelChoice::Paper = model {
        let t = PaperTerms::at(&op);
        out["terms"] = serde_json::to_value(t)?;
        out["stress_eq30_as_printed"] = json!(PaperModel::stress_eq30(&op));
        out["resonance_velocity_eq34"] = json!(PaperModel::resonance_velocity(&op));
    }
    out!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}

fn optimize(a: OptimizeArgs) -> anyhow::Result<()> {
    let scenario = a.scenario.load()?;
    let model = ModelChoice::parse(&a.model).map_err(anyhow::Error::msg)?;
    let mut task = scenario.task;
    let mut limits = scenario.limits;
    if let Some(x) = a.distance {
        task.distance = x;
    }
    if let Some(x) = a.energy {
        task.energy = x;
    }
    if let Some(x) = a.sigma_max {
        task.sigma_max = x;
    }
    if let Some(x) = a.strain_max {
        limits.strain_max = x;
    }
    if let Some(x) = a.f0_max {
        limits.f0_max = x;
    }
    let pair = |name: &str, r: &Vec<f64>| -> anyhow::Result<[f64; 2]> {
        anyhow::ensure!(
            r.len() == 2,
            "invalid --{name} = {}: allowed MIN,MAX (two numbers)",
            r.iter().map(f64::to_string).collect::<Vec<_>>().join(",")
        );
        Ok([r[0], r[1]])
    };
    if let Some(r) = &a.omega_range {
        limits.omega = pair("omega-range", r)?;
    }
    if let Some(r) = &a.k_range {
        limits.k = pair("k-range", r)?;
    }
    let problem = Problem {
        body: scenario.plant.body,
        friction: scenario.plant.friction,
        task,
        limits,
        body_length: if a.fixed_body {
            BodyLength::Fixed(scenario.plant.length)
        } else {
            BodyLength::OneWavelength
        },
    };
    // a bad value from a flag is named by the flag and the key it sets
    let flags = [
        ("task.distance", "--distance", a.distance.is_some()),
        ("task.energy", "--energy", a.energy.is_some()),
        ("task.sigma_max", "--sigma-max", a.sigma_max.is_some()),
        ("limits.strain_max", "--strain-max", a.strain_max.is_some()),
        ("limits.f0_max", "--f0-max", a.f0_max.is_some()),
        ("limits.omega", "--omega-range", a.omega_range.is_some()),
        ("limits.k", "--k-range", a.k_range.is_some()),
    ];
    problem.validate().map_err(|mut e| {
        let key = e.field.split('[').next().unwrap_or_default().to_string();
        if let Some((_, flag, _)) = flags.iter().find(|(k, _, given)| *given && *k == key) {
            e.field = format!("{flag} ({})", e.field);
        }
        e
    })?;
    let default_points = match model {
        ModelChoice::Paper => 200,
        _ => 32,
    };
    let grid = GridSpec {
        omega_points: a.omega_points.unwrap_or(default_points),
        k_points: a.k_points.unwrap_or(default_points),
        refine: !a.no_refine,
        tie_tolerance: a.tie_tolerance,
    };
    anyhow::ensure!(
        (0.0..=0.1).contains(&grid.tie_tolerance),
        "invalid --tie-tolerance = {}: allowed a relative speed tolerance in [0, 0.1]",
        grid.tie_tolerance
    );
    let started = std::time::Instant::now();
    let report = problem.optimize(&model, &grid)?;
    let elapsed = started.elapsed().as_secs_f64();
    let verification = if a.verify {
        let plant = verify::run_plant(&scenario, &problem, &report.optimum, report.optimum.f0)?;
        Some(verify::compare(
            &problem,
            &report.optimum,
            report.optimum.f0,
            &plant,
        ))
    } else {
        None
    };
    let certification = if a.certify {
        Some(verify::certify(
            &scenario,
            &problem,
            &report.optimum,
            a.margin,
            10,
        )?)
    } else {
        None
    };
    if a.json {
        let mut out = serde_json::to_value(&report)?;
        out["seconds"] = json!(elapsed);
        out["verification"] = serde_json::to_value(&verification)?;
        out["certification"] = serde_json::to_value(&certification)?;
        out!("{}", serde_json::to_string(&out)?);
        return Ok(());
    }
    let o = &report.optimum;
    let p = &o.prediction;
    out!(
        "optimum ({} model, {} x {} grid{}, {:.3} s): omega = {:.4} rad/s (alpha = {:.4}), k = {:.4} rad/m, f0 = {:.4} N",
        report.model,
        report.omega_grid.len(),
        report.k_grid.len(),
        if grid.refine { " + refinement" } else { "" },
        elapsed,
        o.omega,
        o.alpha,
        o.k,
        o.f0
    );
    out!(
        "  body: {}; binding constraint: {:?}",
        match report.body_length {
            BodyLength::OneWavelength => "one wavelength of k (the paper's problem)".to_string(),
            BodyLength::Fixed(l) => format!("fixed, {l} m ({} wavelengths)", o.wavelengths),
        },
        o.binding
    );
    let t = &report.tie_break;
    out!(
        "  ridge: {} grid cells within {} % of the fastest speed (spread {:.1e}, omega {:.1}..{:.1} rad/s, k {:.2}..{:.2} rad/m); \
         chose the lowest f0 among them, giving up {:.1e} of the speed",
        t.tied_cells,
        100.0 * t.tolerance,
        t.tied_speed_spread,
        t.tied_omega[0],
        t.tied_omega[1],
        t.tied_k[0],
        t.tied_k[1],
        t.speed_given_up
    );
    out!(
        "  predicted: V = {:.5e} m/s, M = {:.5e} m/J (need {:.5e}), sigma = {:.5e} Pa, strain = {:.4}",
        p.velocity.unwrap_or(f64::NAN),
        p.mileage.unwrap_or(f64::NAN),
        report.min_mileage,
        p.max_stress.unwrap_or(f64::NAN),
        p.max_strain.unwrap_or(f64::NAN)
    );
    if let Some(v) = &verification {
        out!(
            "  plant ({} cells): V = {:.5e} m/s ({:+.2} %), M = {:.5e} m/J ({:+.2} %), sigma = {:.5e} Pa ({:+.2} %), strain = {:.4}",
            v.cells,
            v.velocity.simulated,
            100.0 * v.velocity.relative_error.unwrap_or(f64::NAN),
            v.mileage.simulated,
            100.0 * v.mileage.relative_error.unwrap_or(f64::NAN),
            v.max_stress.simulated,
            100.0 * v.max_stress.relative_error.unwrap_or(f64::NAN),
            v.max_strain.simulated
        );
        out!(
            "  constraints on the plant: mileage {}, stress {}, strain {}, f0 {}",
            ok(v.holds.mileage),
            ok(v.holds.stress),
            ok(v.holds.strain),
            ok(v.holds.f0)
        );
    }
    if let Some(c) = &certification {
        let last = c
            .runs
            .iter()
            .rev()
            .find(|r| (r.f0 - c.f0).abs() < 1e-15)
            .or(c.runs.last());
        out!(
            "  certified: {} at f0 = {:.4} N after {} plant runs (margin {:.1} %); plant V = {:.5e} m/s",
            c.certified,
            c.f0,
            c.runs.len(),
            100.0 * c.margin,
            last.map_or(f64::NAN, |r| r.velocity.simulated)
        );
    }
    Ok(())
}

fn ok(b: bool) -> &'static str {
    if b {
        "holds"
    } else {
        "VIOLATED"
    }
}
