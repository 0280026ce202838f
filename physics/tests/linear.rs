//! eps = 0: the model is linear and solved exactly (docs/physics.md §2.3).

mod common;

use common::{paper, rel, Linear};
use crawler_physics::scenario::{Overrides, Scenario};
use crawler_physics::slave::{Slave, StepStatus};

/// Runs to `t_end` and returns the complex amplitude (a, b) of u(x, t_end) against
/// cos(kx - wt) and sin(kx - wt), plus the steady metrics.
fn amplitude(s: &Scenario) -> ((f64, f64), crawler_physics::metrics::Metrics) {
    let mut slave = Slave::instantiate("linear", s.plant.clone()).unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.set_wave(s.wave).unwrap();
    slave.exit_initialization_mode().unwrap();
    let h = slave.plant().step_length();
    let steps = slave.plant().discretisation().steps_until(s.t_end);
    for n in 0..steps {
        assert_eq!(slave.do_step(n as f64 * h, h), StepStatus::Ok);
    }
    let plant = slave.plant();
    let t = plant.time();
    let dx = plant.discretisation().dx;
    let n = plant.cells() as f64;
    let (mut a, mut b) = (0.0, 0.0);
    for (i, u) in plant.displacement().iter().enumerate() {
        let theta = s.wave.k * i as f64 * dx - s.wave.omega * t;
        a += 2.0 / n * u * theta.cos();
        b += 2.0 / n * u * theta.sin();
    }
    ((a, b), plant.steady_metrics().unwrap())
}

fn scenario(cells: i64, alpha: f64) -> Scenario {
    paper(Overrides {
        eps: Some(0.0),
        alpha: Some(alpha),
        cells: Some(cells),
        t_end: Some(7.0),
        ..Default::default()
    })
}

#[test]
fn amplitude_phase_power_and_stress_match_the_exact_solution() {
    for alpha in [0.5, 1.0, 1.5] {
        let s = scenario(128, alpha);
        let exact = Linear::of(&s);
        let ((a, b), m) = amplitude(&s);
        // u = -u_c R0 cos(theta - phi0) => a = -u_c R0 cos(phi0), b = -u_c R0 sin(phi0)
        let amp = (a * a + b * b).sqrt();
        let phase = (-b).atan2(-a);
        assert!(
            rel(amp, exact.u_c * exact.r0) < 0.01,
            "alpha {alpha}: amplitude {amp} vs {}",
            exact.u_c * exact.r0
        );
        assert!(
            rel(phase, exact.phi0) < 0.01,
            "alpha {alpha}: phase {phase} vs {}",
            exact.phi0
        );
        assert!(
            rel(m.power, exact.power) < 0.01,
            "alpha {alpha}: power {} vs {}",
            m.power,
            exact.power
        );
        assert!(
            rel(m.max_stress, exact.stress) < 0.01,
            "alpha {alpha}: stress {} vs {}",
            m.max_stress,
            exact.stress
        );
        println!(
            "alpha {alpha}: amp {} phase {} P {} sigma {}",
            rel(amp, exact.u_c * exact.r0),
            rel(phase, exact.phi0),
            rel(m.power, exact.power),
            rel(m.max_stress, exact.stress)
        );
        assert!(
            m.velocity.abs() < 1e-12,
            "alpha {alpha}: V = {} at eps = 0",
            m.velocity
        );
        // Energy balance: what the actuator puts in, friction takes out.
        assert!(
            rel(m.dissipation, m.power) < 0.01,
            "alpha {alpha}: dissipation {} vs power {}",
            m.dissipation,
            m.power
        );
    }
}

#[test]
fn error_converges_at_second_order_in_dx() {
    // Fixed Courant number: the step H is a whole number of CFL steps at every resolution.
    let alpha = 0.7;
    let mut errors = Vec::new();
    for cells in [32, 64, 128, 256] {
        let mut s = scenario(cells, alpha);
        let c = s.plant.body.wave_speed();
        let dx = s.plant.length / cells as f64;
        s.plant.numerics.step = 0.5 * dx / c * 4.0; // four internal steps at Courant 0.5
        s.plant.numerics.courant = 0.5;
        s.t_end = (6.0 / s.plant.numerics.step).round() * s.plant.numerics.step;
        let exact = Linear::of(&s);
        let ((a, b), _) = amplitude(&s);
        let (ea, eb) = (
            -exact.u_c * exact.r0 * exact.phi0.cos(),
            -exact.u_c * exact.r0 * exact.phi0.sin(),
        );
        errors.push(((a - ea).powi(2) + (b - eb).powi(2)).sqrt() / (exact.u_c * exact.r0));
    }
    let orders: Vec<f64> = errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
    println!("errors {errors:?} orders {orders:?}");
    for (i, p) in orders.iter().enumerate() {
        assert!(
            (1.8..2.2).contains(p),
            "observed order {p} between refinements {i} and {} (errors {errors:?})",
            i + 1
        );
    }
}
