//! Convergence under refinement of the metrics and the stick-slip statistics.

mod common;

use common::{paper, rel, run};
use crawler_physics::report::Report;
use crawler_physics::scenario::Overrides;

fn at(cells: i64, eps: f64, f0: f64, alpha: f64, courant: Option<f64>) -> Report {
    at_with(cells, eps, f0, alpha, courant, None)
}

fn at_with(
    cells: i64,
    eps: f64,
    f0: f64,
    alpha: f64,
    courant: Option<f64>,
    min_stick: Option<f64>,
) -> Report {
    let mut s = paper(Overrides {
        eps: Some(eps),
        f0: Some(f0),
        alpha: Some(alpha),
        cells: Some(cells),
        t_end: Some(12.0),
        ..Default::default()
    });
    if let Some(c) = courant {
        s.plant.numerics.courant = c;
    }
    if let Some(m) = min_stick {
        s.plant.numerics.min_stick_periods = m;
    }
    run(&s)
}

#[test]
fn metrics_converge_from_128_to_256_cells() {
    let (a, b) = (at(128, 0.1, 0.5, 0.5, None), at(256, 0.1, 0.5, 0.5, None));
    assert!(
        rel(a.velocity, b.velocity) < 0.01,
        "V {} vs {}",
        a.velocity,
        b.velocity
    );
    assert!(rel(a.power, b.power) < 0.01, "P {} vs {}", a.power, b.power);
    assert!(
        rel(a.max_stress, b.max_stress) < 0.01,
        "sigma {} vs {}",
        a.max_stress,
        b.max_stress
    );
}

#[test]
fn stick_slip_statistics_converge_where_the_body_really_sticks() {
    let (a, b) = (at(128, 1.0, 0.2, 0.5, None), at(256, 1.0, 0.2, 0.5, None));
    assert!(
        a.stuck_fraction > 0.3,
        "this case should stick for a large part of each period: {}",
        a.stuck_fraction
    );
    assert!(
        rel(a.stuck_fraction, b.stuck_fraction) < 0.1,
        "stuck fraction {} vs {}",
        a.stuck_fraction,
        b.stuck_fraction
    );
    let (ra, rb) = (a.events.per_node_per_period, b.events.per_node_per_period);
    assert!(
        ra > 0.5,
        "about one long episode per node per period expected, got {ra}"
    );
    assert!(
        rel(ra, rb) < 0.1,
        "episodes per node per period {ra} vs {rb}"
    );
    assert!(
        rel(a.events.mean_duration, b.events.mean_duration) < 0.1,
        "mean stick duration {} vs {}",
        a.events.mean_duration,
        b.events.mean_duration
    );
    // Also under a smaller time step at fixed grid (velocity reversals that land in the static
    // band for a step are not stick phases, whatever dt: stick_statistics.rs).
    let c = at(256, 1.0, 0.2, 0.5, Some(0.5));
    assert!(rel(c.stuck_fraction, b.stuck_fraction) < 0.1);
    assert!(rel(c.events.per_node_per_period, rb) < 0.1);
}
