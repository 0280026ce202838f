//! The paper's figures: Fig. 5 carries the plant's points beside the models' curves.
//! Set `CRAWLER_FIGURES_OUT=DIR` to keep the PNGs to look at.

use std::path::PathBuf;

use crawler_figures::{write_figures, FigureOptions};
use crawler_physics::scenario::Scenario;

#[test]
fn fig5_draws_the_plant_beside_the_models_and_it_agrees_with_the_improved_model() {
    let tmp = tempfile::tempdir().unwrap();
    let dir: PathBuf = std::env::var_os("CRAWLER_FIGURES_OUT")
        .map(PathBuf::from)
        .unwrap_or_else(|| tmp.path().to_path_buf());
    let opts = FigureOptions {
        sweep_points: 40,
        plane_points: 12,
        plane_points_improved: 6,
        plant_points: 3,
    };
    let files = write_figures(&Scenario::paper(), &dir, opts).unwrap();
    for name in ["fig5.png", "fig6.png"] {
        assert!(files.iter().any(|f| f.ends_with(name)), "{files:?}");
    }
    for sweep in ["omega", "k", "f0"] {
        let plant = std::fs::read_to_string(dir.join(format!("fig5_{sweep}_plant.csv"))).unwrap();
        let models = std::fs::read_to_string(dir.join(format!("fig5_{sweep}.csv"))).unwrap();
        let rows: Vec<Vec<String>> = plant
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect();
        assert_eq!(rows.len(), 3, "{plant}");
        for r in &rows {
            let (x, v): (f64, f64) = (r[0].parse().unwrap(), r[1].parse().unwrap());
            // the plant point sits at one of the curve's samples; the improved model there
            let m = models
                .lines()
                .skip(1)
                .map(|l| l.split(',').map(str::to_string).collect::<Vec<_>>())
                .find(|c| c[0].parse::<f64>().unwrap() == x)
                .unwrap_or_else(|| panic!("{sweep} = {x} is a sample of the curve"));
            let improved: f64 = m[2].parse().unwrap();
            println!("{sweep} = {x}: plant V {v:e}, improved model {improved:e}");
            assert!(
                (v / improved - 1.0).abs() < 0.02,
                "{sweep} = {x}: plant {v:e} against the improved model {improved:e}"
            );
        }
    }
}
