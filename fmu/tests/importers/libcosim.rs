//! libcosim (DNV's Open Simulation Platform, `libcosimpy`) on its nanosecond clock: the FMI 2.0
//! FMU with the parameter `ticks_per_second`, against `crawler-plant simulate` with the scenario
//! key `numerics.ticks_per_second`.

use serde_json::Value;

use super::{
    assert_same_as_simulate, bits, example, fmu, importers, path_str, printed, run_python,
    simulate_in_process, simulate_scenario,
};

/// The paper scenario on a nanosecond clock.
pub(super) fn paper_on_nanoseconds() -> String {
    crawler_physics::scenario::PAPER_TOML.replace(
        "[numerics]\n",
        "[numerics]\nticks_per_second = 1000000000\n",
    )
}

/// H of a `simulate` report in nanoseconds, checked to be the double a nanosecond master computes
/// from it.
pub(super) fn step_ns(reference: &Value) -> u64 {
    let h = reference["parameters"]["step"].as_f64().unwrap();
    let ns = (h * 1e9).round() as u64;
    assert_eq!(
        (ns as f64 / 1e9).to_bits(),
        h.to_bits(),
        "H = {h} s is not a whole number of nanoseconds"
    );
    ns
}

/// libcosim steps the FMI 2.0 FMU `steps` times of `step_ns` after setting `parameters`.
fn libcosim(step_ns: u64, steps: u64, parameters: &[String]) -> Value {
    let fmu = fmu(2);
    let (step_ns, steps) = (step_ns.to_string(), steps.to_string());
    let mut args = vec!["libcosim", path_str(&fmu), &step_ns, &steps];
    args.extend(parameters.iter().map(String::as_str));
    importers(&args)
}

/// libcosim's run of `steps` steps of `step_ns` equals the `simulate` report `reference`.
fn assert_libcosim_run(who: &str, r: &Value, reference: &Value, step_ns: u64) {
    assert_eq!(r["ok"], true, "{who}: libcosim failed: {}", r["error"]);
    let steps = reference["macro_steps"].as_u64().unwrap();
    assert_eq!(r["time_ns"].as_u64(), Some(steps * step_ns), "{who}");
    assert_eq!(
        bits(&r["h"]),
        bits(&reference["parameters"]["step"]),
        "{who}"
    );
    assert_eq!(bits(&r["dt"]), bits(&reference["dt"]), "{who}");
    assert_same_as_simulate(who, r, reference);
}

#[test]
fn libcosim_runs_the_paper_scenario_on_its_nanosecond_clock_bit_for_bit_like_simulate() {
    let reference = simulate_scenario(&paper_on_nanoseconds());
    let ns = step_ns(&reference);
    let steps = reference["macro_steps"].as_u64().unwrap();
    let r = libcosim(ns, steps, &["ticks_per_second=1000000000".into()]);
    assert_libcosim_run("libcosim, paper scenario", &r, &reference, ns);
    assert_eq!(r["ticks_per_second"], 1_000_000_000);
}

#[test]
fn libcosim_runs_a_held_out_scenario_on_its_nanosecond_clock_bit_for_bit_like_simulate() {
    // another body, friction, wave and step than the FMU's defaults (N = 512: the FMI 2.0 FMU's)
    let text = r#"
name = "held-out"
[body]
area = 1.2e-4
density = 0.13
youngs_modulus = 95e3
length = 0.8
[friction]
viscous = 0.7
dry = 1.3
eps = 0.9
n_f = 0.3
[actuation]
f0 = 0.25
k = 7.853981633974483
omega = 41.0
phase = 0.4
[numerics]
cells = 512
step = 2.5e-3
t_end = 3.0
settle = 1.5
ticks_per_second = 1000000000
"#;
    let reference = simulate_scenario(text);
    let s = crawler_physics::scenario::Scenario::from_toml(text, "held-out", &Default::default())
        .unwrap();
    let (p, w) = (&s.plant, &s.wave);
    assert_eq!(p.numerics.cells, 512);
    let mut parameters: Vec<String> = [
        ("length", p.length),
        ("area", p.body.area),
        ("density", p.body.density),
        ("youngs_modulus", p.body.youngs_modulus),
        ("viscous", p.friction.viscous),
        ("dry", p.friction.dry),
        ("eps", p.friction.eps),
        ("n_f", p.friction.n_f),
        ("courant", p.numerics.courant),
        ("step", p.numerics.step),
        ("settle", p.numerics.settle),
        ("min_stick_periods", p.numerics.min_stick_periods),
        ("block", p.numerics.block),
        ("filter", p.numerics.filter),
        ("wave_f0", w.f0),
        ("wave_k", w.k),
        ("wave_omega", w.omega),
        ("wave_phase", w.phase),
    ]
    .iter()
    .map(|(name, x)| format!("{name}={x:?}"))
    .collect();
    parameters.push("ticks_per_second=1000000000".into());
    let ns = step_ns(&reference);
    let steps = reference["macro_steps"].as_u64().unwrap();
    let own = s.plant.discretisation().unwrap();
    assert!(own.substeps > 1, "H is several internal steps");
    assert!(
        reference["stuck_fraction"].as_f64().unwrap() > 0.01
            && reference["events"]["per_node_per_period"].as_f64().unwrap() > 0.5,
        "the held-out run sticks and slips: {}",
        reference["stuck_fraction"]
    );
    let r = libcosim(ns, steps, &parameters);
    assert_libcosim_run("libcosim, held-out scenario", &r, &reference, ns);
}

#[test]
fn libcosim_without_the_clock_is_refused_at_the_first_step() {
    let reference = simulate_in_process();
    let h = reference["parameters"]["step"].as_f64().unwrap();
    let r = libcosim((h * 1e9).round() as u64, 1, &[]);
    assert_eq!(r["ok"], false, "{r}");
    // libcosim passes on the FMU's reason, which names the parameter that fixes it
    let error = r["error"].as_str().unwrap();
    assert!(
        error.contains("fmi2DoStep") && error.contains("ticks_per_second"),
        "{error}"
    );
}

#[test]
fn the_fmu_doc_libcosim_example_runs_as_shown() {
    let code = example("docs/fmu.md", "from libcosimpy").expect("docs/fmu.md shows libcosim");
    assert!(code.lines().count() <= 18, "the example stays short");
    let stdout = run_python(&code);
    let reference = simulate_scenario(&paper_on_nanoseconds());
    let v = printed(&stdout, "steady V = ");
    let v_ref = reference["velocity"].as_f64().unwrap();
    assert!(
        (v - v_ref).abs() <= 5e-7 * v_ref.abs(),
        "docs/fmu.md's libcosim example V = {v}, simulate {v_ref}"
    );
    assert_eq!(printed(&stdout, "H = "), step_ns(&reference) as f64);
    assert!(
        code.contains(&format!("execution.step({})", reference["macro_steps"])),
        "the example runs the paper scenario's default experiment"
    );
}
