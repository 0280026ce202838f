//! The heat maps of a small plan with a convergence estimate: every figure is drawn, the
//! stuck fraction on a logarithmic scale. Set `CRAWLER_FIGURES_OUT=DIR` to keep the PNGs to look at.

use std::path::{Path, PathBuf};

use crawler_sweep::evaluate::evaluate;
use crawler_sweep::maps::Maps;
use crawler_sweep::plan::Plan;
use crawler_sweep::point::resolve;

/// One k, two amplitudes, eps x alpha across the Courant switch at alpha = 1.1; coarse.
const SMALL: &str = r#"
name = "small"
scenario = "../scenarios/paper.toml"
metrics = ["velocity", "power", "mileage", "max_stress", "stuck_fraction"]

[set]
numerics.cells = 32
numerics.settle = 1.5
numerics.t_end = 3.0

[[axes]]
key = "actuation.k"
values = [12.566370614359172]

[[axes]]
key = "actuation.f0"
values = [0.1, 0.5, 2.5]

[[axes]]
key = "friction.eps"
linspace = { start = 0.0, stop = 1.5, num = 5 }

[[axes]]
key = "actuation.alpha"
linspace = { start = 0.2, stop = 2.0, num = 10 }

[evaluate]
plant = true
convergence = true
models = ["paper", "improved"]

[figures]
x = "actuation.alpha"
y = "friction.eps"
rows = "actuation.k"
columns = "actuation.f0"
"#;

#[test]
fn a_small_plans_maps_are_all_drawn_with_the_stuck_fraction_and_the_estimate() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../plans");
    let plan = Plan::from_toml(SMALL, "small.toml", &repo).unwrap();
    let points = resolve(&plan).unwrap();
    let records: Vec<_> = points.iter().map(|p| evaluate(p, &plan.evaluate)).collect();
    assert!(records.iter().all(|r| r.error.is_none()));
    let maps = Maps::build(&plan, plan.figures.as_ref().unwrap(), &points, &records).unwrap();
    // the stuck fraction spans decades where the body sticks and is exactly 0 where it slides
    let stuck: Vec<f64> = maps.stuck.iter().flatten().flatten().copied().collect();
    assert!(stuck.contains(&0.0));
    assert!(stuck.iter().any(|&s| s > 0.0 && s < 0.01) || stuck.iter().any(|&s| s > 0.1));
    let tmp = tempfile::tempdir().unwrap();
    let dir: PathBuf = std::env::var_os("CRAWLER_FIGURES_OUT")
        .map(PathBuf::from)
        .unwrap_or_else(|| tmp.path().to_path_buf());
    let figs = crawler_figures::maps::draw(&plan, &maps, &dir).unwrap();
    assert_eq!(figs.len(), 2 * 5 + 2, "{figs:?}");
    for f in &figs {
        let bytes = std::fs::read(f).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}", f.display());
    }
}
