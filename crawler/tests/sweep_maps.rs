//! The validity map's machinery on a reduced plan, in process: maps, figures and the recording.

mod common;

use crawler_facts::Metric;
use crawler_sweep::evaluate::evaluate;
use crawler_sweep::maps::Maps;
use crawler_sweep::plan::Plan;
use crawler_sweep::point::resolve;

use common::*;

/// 2 x 2 panels of 4 x 5 points, coarse.
const REDUCED: &str = r#"
[set]
numerics.cells = 32
numerics.settle = 1.5
numerics.t_end = 3.0

[[axes]]
key = "actuation.k"
values = [6.283185307179586, 25.132741228718345]

[[axes]]
key = "actuation.f0"
values = [0.1, 2.5]

[[axes]]
key = "friction.eps"
linspace = { start = 0.0, stop = 1.5, num = 4 }

[[axes]]
key = "actuation.alpha"
linspace = { start = 0.2, stop = 2.0, num = 5 }

[evaluate]
plant = true
models = ["paper", "improved"]

[figures]
x = "actuation.alpha"
y = "friction.eps"
rows = "actuation.k"
columns = "actuation.f0"
"#;

#[test]
fn the_reduced_validity_map_marks_where_the_paper_model_is_undefined_and_draws_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_plan(dir.path(), "reduced", REDUCED);
    let plan = Plan::from_file(&path).unwrap();
    let points = resolve(&plan).unwrap();
    assert_eq!(points.len(), 80);
    let records: Vec<_> = points.iter().map(|p| evaluate(p, &plan.evaluate)).collect();
    assert!(records.iter().all(|r| r.error.is_none()));
    let maps = Maps::build(&plan, plan.figures.as_ref().unwrap(), &points, &records).unwrap();
    assert_eq!((maps.nrows(), maps.ncols(), maps.cells()), (2, 2, 20));

    // at eps = 0 (row iy = 0) both models hold: no dry friction, the linear solution
    for model in ["paper", "improved"] {
        for panel in 0..4 {
            for ix in 0..5 {
                let e = maps.errors[&(model.to_string(), Metric::Power)][panel][ix].unwrap();
                assert!(
                    e.abs() < 0.02,
                    "{model} power at eps = 0, panel {panel}, alpha #{ix}: {e}"
                );
            }
        }
    }
    // the paper's model is undefined where the body sticks: f0 = 0.1 N, k = 2 pi (panel 0),
    // eps = 1.5 (iy = 3), alpha = 0.2 (ix = 0): eps C0 / (R0 alpha) = 1.5 pi_r n_F / (zeta R0 0.2) >> 1
    let cell = 3 * 5;
    assert_eq!(maps.valid["paper"][0][cell], Some(0.0));
    assert_eq!(
        maps.errors[&("paper".into(), Metric::Velocity)][0][cell],
        None
    );
    assert!(
        maps.stuck[0][cell].unwrap() > 0.3,
        "the plant sticks there: {:?}",
        maps.stuck[0][cell]
    );
    // and the improved model is defined everywhere
    assert!(maps.valid["improved"]
        .iter()
        .flatten()
        .all(|v| *v == Some(1.0)));

    // figures and recording
    let figs = crawler_figures::maps::draw(&plan, &maps, dir.path()).unwrap();
    assert_eq!(figs.len(), 2 * 5 + 2, "{figs:?}");
    for f in &figs {
        let bytes = std::fs::read(f).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}", f.display());
        assert!(
            bytes.len() > 20_000,
            "{}: {} bytes",
            f.display(),
            bytes.len()
        );
    }
    let rrd = dir.path().join("reduced.rrd");
    crawler::sweep::write_recording(&plan, &maps, &rrd).unwrap();
    let bytes = std::fs::read(&rrd).unwrap();
    assert_eq!(&bytes[..4], b"RRF2", "a Rerun recording");
    assert!(bytes.len() > 50_000);
}
