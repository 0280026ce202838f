//! The Python feedback example closes the loop over the protocol: its proportional stick reflex,
//! written again here in Rust and run in process, gives the same trajectory bit for bit.

use std::f64::consts::TAU;
use std::time::Duration;

use crawler_e2e::{json, Run};
use crawler_physics::scenario::Scenario;
use crawler_policies::in_process;
use crawler_policies::{Actuation, Observation, Policy};

/// `examples/python_reflex_controller.py`'s law: the wave at the faces, mid-step, plus
/// `gain f0 (stuck[i + 1] - stuck[i])`.
struct StickReflex {
    f0: f64,
    k: f64,
    omega: f64,
    gain: f64,
    dx: f64,
    step: f64,
}

impl Policy for StickReflex {
    fn name(&self) -> &str {
        "stick-reflex"
    }

    fn act(&mut self, obs: &Observation) -> Actuation {
        let n = obs.u.len();
        let t = obs.time + 0.5 * self.step;
        let s = |i: usize| if obs.stuck[i % n] { 1.0 } else { 0.0 };
        Actuation::Field(
            (0..n)
                .map(|i| {
                    self.f0 * (self.k * ((i as f64 + 0.5) * self.dx) - self.omega * t).sin()
                        + self.gain * self.f0 * (s(i + 1) - s(i))
                })
                .collect(),
        )
    }
}

#[test]
fn the_python_reflex_controller_closes_the_loop_as_its_law_says() {
    // the venv and the package first (a fresh clone builds it): the plant's wait for a
    // controller is bounded
    crawler_e2e::softcrawler();
    let run = Run::new("pyreflex");
    // the shortest run the scenario allows: the transient (5 s) and one forcing period
    let plant = run.plant(&["--eps", "1", "--cells", "128", "--t-end", "5.2", "--json"]);
    let py = run.python_example(
        "python_reflex_controller.py",
        &["--f0", "0.2", "--alpha", "0.5", "--gain", "0.5"],
    );
    let p = plant.wait(Duration::from_secs(120));
    let c = py.wait(Duration::from_secs(30));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "python reflex controller: {}", c.stderr);
    let mut sc = Scenario::paper();
    sc.plant.friction.eps = 1.0;
    sc.plant.numerics.cells = 128;
    sc.t_end = 5.2;
    let b = sc.plant.body;
    let length = sc.plant.length;
    let k = TAU / length;
    let law = |gain: f64| StickReflex {
        f0: 0.2,
        k,
        omega: 0.5 * (k * (b.area * b.youngs_modulus / b.density).sqrt()),
        gain,
        dx: length / 128.0,
        step: sc.plant.discretisation().unwrap().step,
    };
    let local = in_process::run(&sc, &mut law(0.5)).unwrap().report;
    assert_eq!(json(&p.stdout)["state_digest"], local.state_digest.as_str());
    // the reflex acts: without it the trajectory is another one
    let open = in_process::run(&sc, &mut law(0.0)).unwrap().report;
    assert_ne!(open.state_digest, local.state_digest);
    assert!(local.stuck_fraction > 0.0, "no anchors to react to");
}
