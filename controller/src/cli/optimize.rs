//! `crawler-controller optimize`: the constrained optimum (paper Sec. V), verified or certified on
//! the in-process plant.

use clap::Args;
use serde_json::json;

use crawler_cli::ScenarioArgs;
use crawler_models::optimizer::{
    BodyLength, GridSpec, ModelChoice, Problem, DEFAULT_TIE_TOLERANCE,
};
use crawler_models::verify;

#[derive(Args)]
pub struct OptimizeArgs {
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
    /// Relative margin for --certify (0 <= margin < 0.5).
    #[arg(long, default_value_t = verify::DEFAULT_MARGIN, allow_hyphen_values = true)]
    margin: f64,
    /// Print JSON (with the whole grid).
    #[arg(long)]
    json: bool,
}

pub fn optimize(a: OptimizeArgs) -> anyhow::Result<()> {
    let scenario = a.scenario.load()?;
    let model = ModelChoice::parse(&a.model).map_err(anyhow::Error::msg)?;
    let problem = problem(&a, &scenario)?;
    let grid = grid(&a, &model)?;
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
    print_text(
        &report,
        &grid,
        elapsed,
        verification.as_ref(),
        certification.as_ref(),
    )?;
    Ok(())
}

/// The problem of the scenario with the flags' overrides; a bad value from a flag is named by
/// the flag and the key it sets.
fn problem(a: &OptimizeArgs, scenario: &crawler_physics::Scenario) -> anyhow::Result<Problem> {
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
    Ok(problem)
}

/// The search grid of the flags (defaults by model).
fn grid(a: &OptimizeArgs, model: &ModelChoice) -> anyhow::Result<GridSpec> {
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
    Ok(grid)
}

/// The optimum in words.
fn print_text(
    report: &crawler_models::optimizer::OptimizeReport,
    grid: &GridSpec,
    elapsed: f64,
    verification: Option<&verify::Verification>,
    certification: Option<&verify::Certification>,
) -> anyhow::Result<()> {
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
    if let Some(v) = verification {
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
    if let Some(c) = certification {
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
