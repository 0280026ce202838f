//! A body with two free ends (zero tension at both), of any length.

mod common;

use std::f64::consts::TAU;

use common::{custom, custom_body, rel, run};
use crawler_physics::slave::{Slave, StepStatus};
use crawler_physics::Scenario;

/// Just enough complex arithmetic for the closed form.
#[derive(Debug, Clone, Copy)]
struct C(f64, f64);

impl C {
    fn add(self, o: C) -> C {
        C(self.0 + o.0, self.1 + o.1)
    }
    fn sub(self, o: C) -> C {
        C(self.0 - o.0, self.1 - o.1)
    }
    fn mul(self, o: C) -> C {
        C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
    fn div(self, o: C) -> C {
        let d = o.0 * o.0 + o.1 * o.1;
        C(
            (self.0 * o.0 + self.1 * o.1) / d,
            (self.1 * o.0 - self.0 * o.1) / d,
        )
    }
    fn scale(self, x: f64) -> C {
        C(self.0 * x, self.1 * x)
    }
    fn exp_i(theta: f64) -> C {
        C(theta.cos(), theta.sin())
    }
    fn sqrt(self) -> C {
        let r = (self.0 * self.0 + self.1 * self.1).sqrt();
        let re = ((r + self.0) / 2.0).sqrt();
        let im = ((r - self.0) / 2.0).sqrt().copysign(self.1);
        C(re, im)
    }
    /// sin and cos of a complex argument.
    fn sin_cos(self) -> (C, C) {
        let (s, c) = self.0.sin_cos();
        let (sh, ch) = (self.1.sinh(), self.1.cosh());
        (C(s * ch, c * sh), C(c * ch, -s * sh))
    }
}

/// The exact steady state of the linear (eps = 0) free rod under the travelling wave
/// `A_m f = f0 sin(kx - omega t)`: `u = Re[U(x) e^{-i omega t}]` with
/// `U'' + kappa^2 U = -(f0 k / A_c E) e^{ikx}`, `kappa^2 = (rho omega^2 + i c_v omega) / A_c E`, and
/// zero tension `A_c E U' + M = 0`, `M = -i f0 e^{ikx}`, at `x = 0` and `x = L`: a particular
/// travelling wave plus the free modes `A cos(kappa x) + B sin(kappa x)` that cancel its tension
/// at the ends.
struct FreeRod {
    p: C,
    a: C,
    b: C,
    kappa: C,
    k: f64,
    omega: f64,
}

impl FreeRod {
    fn of(s: &Scenario) -> Self {
        let body = s.plant.body;
        let ae = body.stiffness();
        let (f0, k, omega, l) = (s.wave.f0, s.wave.k, s.wave.omega, s.plant.length);
        let kappa2 = C(
            body.density * omega * omega,
            s.plant.friction.viscous * omega,
        )
        .scale(1.0 / ae);
        let kappa = kappa2.sqrt();
        let p = C(-f0 * k / ae, 0.0).div(kappa2.sub(C(k * k, 0.0)));
        let ik = C(0.0, k);
        let drive = C(0.0, f0 / ae); // U' at an end must be i f0 e^{ikx} / A_c E
        let b = drive.sub(ik.mul(p)).div(kappa);
        let (sl, cl) = kappa.scale(l).sin_cos();
        let e = C::exp_i(k * l);
        let a = ik
            .mul(p)
            .mul(e)
            .add(kappa.mul(b).mul(cl))
            .sub(drive.mul(e))
            .div(kappa.mul(sl));
        Self {
            p,
            a,
            b,
            kappa,
            k,
            omega,
        }
    }

    /// `U(x)`, m.
    fn amplitude(&self, x: f64) -> C {
        let (s, c) = self.kappa.scale(x).sin_cos();
        self.p
            .mul(C::exp_i(self.k * x))
            .add(self.a.mul(c))
            .add(self.b.mul(s))
    }

    /// `u(x, t)`, m.
    fn displacement(&self, x: f64, t: f64) -> f64 {
        self.amplitude(x).mul(C::exp_i(-self.omega * t)).0
    }
}

fn free(eps: f64, k: f64, alpha: f64, length: f64, cells: usize) -> Scenario {
    custom_body(eps, 0.5, k, alpha, length, "free", cells, 7.0, "")
}

/// The displacement field at the end of the run, with its (free) mean removed, against the
/// closed form with its mean removed; relative L2 error.
fn field_error(s: &Scenario) -> f64 {
    let mut slave = Slave::instantiate("free", s.plant.clone()).unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.set_wave(s.wave).unwrap();
    slave.exit_initialization_mode().unwrap();
    let h = slave.plant().step_length();
    let steps = slave.plant().discretisation().steps_until(s.t_end);
    for n in 0..steps {
        assert_eq!(slave.do_step(n as f64 * h, h), StepStatus::Ok);
    }
    let plant = slave.plant();
    let (t, dx) = (plant.time(), plant.discretisation().dx);
    let exact = FreeRod::of(s);
    let u = plant.displacement();
    let x = |i: usize| (i as f64 + 0.5) * dx;
    let e: Vec<f64> = (0..u.len()).map(|i| exact.displacement(x(i), t)).collect();
    let (mu, me) = (
        u.iter().sum::<f64>() / u.len() as f64,
        e.iter().sum::<f64>() / e.len() as f64,
    );
    let (mut num, mut den) = (0.0, 0.0);
    for (ui, ei) in u.iter().zip(&e) {
        num += ((ui - mu) - (ei - me)).powi(2);
        den += (ei - me).powi(2);
    }
    (num / den).sqrt()
}

#[test]
fn without_dry_friction_the_free_rod_matches_its_closed_form() {
    // A body 0.7 m long under a wave of 1 m: the wave does not fit it; the ends reflect.
    for alpha in [0.6, 1.0, 1.7] {
        let errors: Vec<f64> = [128, 256]
            .iter()
            .map(|&cells| field_error(&free(0.0, TAU, alpha, 0.7, cells)))
            .collect();
        println!("alpha {alpha}: relative L2 errors {errors:?}");
        assert!(errors[1] < 2e-3, "alpha {alpha}: {errors:?}");
        // second order in dx
        let order = (errors[0] / errors[1]).log2();
        assert!(
            order > 1.7,
            "alpha {alpha}: observed order {order} ({errors:?})"
        );
    }
}

#[test]
fn without_dry_friction_a_free_body_does_not_travel() {
    // Internal forces cancel and the ends carry no tension: only viscosity acts on the centre of
    // mass, so its steady speed is zero.
    let r = run(&free(0.0, TAU, 1.0, 0.7, 128));
    assert!(r.velocity.abs() < 1e-9, "V = {}", r.velocity);
    assert!(rel(r.dissipation, r.power) < 0.01);
}

#[test]
fn the_momentum_identity_holds_for_the_centre_of_mass() {
    for (eps, alpha, length) in [(0.3, 1.0, 0.8), (1.0, 0.5, 2.3)] {
        let r = run(&free(eps, TAU, alpha, length, 256));
        assert!(
            r.momentum_residual < 1e-9,
            "eps {eps}: discrete momentum balance off by {:e}",
            r.momentum_residual
        );
        // The continuous identity up to the window's momentum change rho dV / T_w (the window holds
        // whole periods only to within a step, and a free body's mean speed swings within each).
        assert!(
            rel(r.velocity, r.identity_velocity) < 1e-3,
            "eps {eps}: V {} vs eps c_d (n_F - <s>) / c_v = {}",
            r.velocity,
            r.identity_velocity
        );
        assert!(r.velocity > 0.0, "the free body crawls forward");
    }
}

#[test]
fn a_free_body_converges_under_refinement() {
    let (a, b) = (
        run(&free(0.3, TAU, 0.8, 1.3, 256)),
        run(&free(0.3, TAU, 0.8, 1.3, 512)),
    );
    for (name, x, y) in [
        ("V", a.velocity, b.velocity),
        ("P", a.power, b.power),
        ("sigma", a.max_stress, b.max_stress),
    ] {
        assert!(rel(x, y) < 5e-3, "{name}: {x} at 256 cells, {y} at 512");
    }
}

#[test]
fn at_resonance_the_power_of_a_long_free_body_approaches_the_periodic_one() {
    // The wave enters at the tail with zero amplitude and grows as it travels, over the damping
    // length 2 rho c / c_v (2.4 m here), so shorter bodies draw less power per metre.
    let periodic = run(&custom(0.1, 0.5, TAU, 1.0, 1.0, 128, 10.0, ""));
    let per_metre: Vec<f64> = [1.0, 2.0, 4.0]
        .iter()
        .map(|&l| {
            let r = run(&custom_body(
                0.1,
                0.5,
                TAU,
                1.0,
                l,
                "free",
                (128.0 * l) as usize,
                10.0,
                "",
            ));
            r.power / l
        })
        .collect();
    println!("P per metre {per_metre:?}, periodic {}", periodic.power);
    assert!(per_metre.windows(2).all(|w| w[1] > w[0]), "{per_metre:?}");
    assert!(per_metre.iter().all(|&p| p < periodic.power));
}
