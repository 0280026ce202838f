//! An integer clock (`numerics.ticks_per_second`, the FMU parameter `ticks_per_second`): the
//! communication step becomes a whole number of ticks, the internal step `H / substeps` stays
//! within `CLOCK_COURANT_TOLERANCE` below the Courant bound, a master that counts nanoseconds
//! drives the slave to the in-process result bit for bit, and without the key nothing changes.

use crawler_physics::model_description::vr;
use crawler_physics::params::{
    Discretisation, Numerics, PlantParams, CLOCK_COURANT_TOLERANCE, CLOCK_TICKS_ALWAYS_FIT,
};
use crawler_physics::report::state_digest;
use crawler_physics::scenario::{Overrides, Scenario, PAPER_TOML};
use crawler_physics::simulate::{simulate, SimulateOptions};
use crawler_physics::slave::{Slave, StepStatus};
use proptest::prelude::*;

const NANOSECONDS: u64 = 1_000_000_000;

fn paper_on_clock(ticks_per_second: u64) -> Result<Scenario, String> {
    let text = PAPER_TOML.replace(
        "[numerics]\n",
        &format!("[numerics]\nticks_per_second = {ticks_per_second}\n"),
    );
    Scenario::from_toml(&text, "clock.toml", &Overrides::default()).map_err(|e| e.to_string())
}

/// Every promise of the clocked discretisation `d` of `p` on `rate` ticks per second.
fn check_clocked(p: &PlantParams, d: &Discretisation, rate: u64) {
    let own = {
        let mut q = p.clone();
        q.numerics.ticks_per_second = None;
        q.discretisation().unwrap()
    };
    let ticks = d.ticks.expect("a clocked discretisation counts its ticks");
    // H is the double a master computes from its tick count
    assert_eq!(d.step.to_bits(), (ticks as f64 / rate as f64).to_bits());
    // the same number of internal steps as on the plant's own clock, dt = H / substeps
    assert_eq!(d.substeps, own.substeps);
    assert_eq!(d.dt.to_bits(), (d.step / d.substeps as f64).to_bits());
    // the Courant number at most the bound and within the stated tolerance below it
    let c = p.body.wave_speed();
    let bound = p.numerics.courant;
    assert_eq!(d.courant.to_bits(), (c * d.dt / d.dx).to_bits());
    assert!(d.courant <= bound, "{} > {bound}", d.courant);
    assert!(
        d.courant >= bound * (1.0 - CLOCK_COURANT_TOLERANCE),
        "Courant {} more than {CLOCK_COURANT_TOLERANCE:e} below {bound} (H = {ticks} ticks)",
        d.courant
    );
    // and H is the longest whole number of ticks that keeps the bound
    let longer = (ticks + 1) as f64 / rate as f64 / d.substeps as f64;
    assert!(
        c * longer / d.dx > bound,
        "one tick more ({ticks} + 1) would also keep the Courant bound"
    );
}

#[test]
fn on_a_nanosecond_clock_the_paper_step_is_whole_nanoseconds_just_below_courant_one() {
    let s = paper_on_clock(NANOSECONDS).unwrap();
    let d = s.plant.discretisation().unwrap();
    check_clocked(&s.plant, &d, NANOSECONDS);
    let own = Scenario::paper().plant.discretisation().unwrap();
    // H moves by less than one nanosecond, and so does the whole run's end
    assert!(own.step - d.step > 0.0 && own.step - d.step < 1e-9);
    assert_eq!(
        d.steps_until(s.t_end),
        own.steps_until(Scenario::paper().t_end)
    );
    // the model description states the real step
    let md =
        crawler_physics::model_description::ModelDescription::for_run(&s.plant, s.wave, s.t_end);
    assert_eq!(md.fixed_internal_step_size.to_bits(), d.step.to_bits());
    let e = md.default_experiment.unwrap();
    assert_eq!(e.step_size.to_bits(), d.step.to_bits());
    assert_eq!(
        md.variable(vr::TICKS_PER_SECOND).unwrap().start,
        Some(crawler_physics::model_description::Start::UInt(NANOSECONDS))
    );
}

#[test]
fn without_the_key_the_discretisation_and_the_written_parameters_are_unchanged() {
    let s = Scenario::paper();
    assert_eq!(s.plant.numerics.ticks_per_second, None);
    let d = s.plant.discretisation().unwrap();
    assert_eq!(d.ticks, None);
    assert_eq!(d.step, d.substeps as f64 * d.dt);
    // no key is written, so states, checkpoints and reports of such runs keep their bytes, and
    // ones written before the key existed read back
    let json = serde_json::to_string(&s.plant.numerics).unwrap();
    assert!(!json.contains("ticks"), "{json}");
    assert!(!serde_json::to_string(&d).unwrap().contains("ticks"));
    let back: Numerics = serde_json::from_str(&json).unwrap();
    assert_eq!(back, s.plant.numerics);
    let packed = rmp_serde::to_vec(&s.plant).unwrap();
    let clocked = paper_on_clock(NANOSECONDS).unwrap();
    assert_eq!(
        rmp_serde::from_slice::<PlantParams>(&packed).unwrap(),
        s.plant
    );
    // with the key, both forms carry it
    let packed = rmp_serde::to_vec(&clocked.plant).unwrap();
    assert_eq!(
        rmp_serde::from_slice::<PlantParams>(&packed).unwrap(),
        clocked.plant
    );
    let json = serde_json::to_string(&clocked.plant).unwrap();
    assert_eq!(
        serde_json::from_str::<PlantParams>(&json).unwrap(),
        clocked.plant
    );
}

#[test]
fn a_clock_of_zero_ticks_or_too_coarse_for_the_courant_tolerance_is_refused_by_name() {
    let e = paper_on_clock(0).unwrap_err();
    assert!(
        e.contains("numerics.ticks_per_second") && e.contains("= 0"),
        "{e}"
    );
    // a millisecond clock has no whole tick in H's 0.99 ms: far too coarse
    let e = paper_on_clock(1000).unwrap_err();
    assert!(
        e.contains("numerics.ticks_per_second")
            && e.contains("1000")
            && e.contains(&format!("{CLOCK_COURANT_TOLERANCE:e}"))
            && e.contains(&format!("{CLOCK_TICKS_ALWAYS_FIT} ticks per H")),
        "{e}"
    );
    // microseconds: H = 990 us lowers the Courant number by 1.4e-4; 10 ns ticks: by 1.4e-5
    assert!(paper_on_clock(1_000_000).is_err());
    assert!(paper_on_clock(100_000_000).is_err());
    for rate in [1_000_000_000, 1_000_000_000_000] {
        let ok = paper_on_clock(rate).unwrap();
        check_clocked(&ok.plant, &ok.plant.discretisation().unwrap(), rate);
    }
    let e = paper_on_clock(1 << 60).unwrap_err();
    assert!(e.contains("numerics.ticks_per_second"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn any_clocked_discretisation_keeps_its_promises_or_is_refused_only_below_a_million_ticks_per_step(
        cells in 8usize..5000,
        length in 0.05f64..20.0,
        youngs in 1e3f64..1e9,
        courant in 0.05f64..=1.0,
        step in 1e-6f64..0.1,
        rate_exp in 3u32..13,
        rate_mantissa in 1u64..10,
    ) {
        let mut p = Scenario::paper().plant;
        p.numerics.cells = cells;
        p.length = length;
        p.body.youngs_modulus = youngs;
        p.numerics.courant = courant;
        p.numerics.step = step;
        let rate = rate_mantissa * 10u64.pow(rate_exp);
        p.numerics.ticks_per_second = Some(rate);
        let mut own = p.clone();
        own.numerics.ticks_per_second = None;
        let Ok(o) = own.discretisation() else {
            // (more than MAX_SUBSTEPS internal steps per H: refused on either clock)
            prop_assert!(p.discretisation().is_err());
            return Ok(());
        };
        match p.discretisation() {
            Ok(d) => check_clocked(&p, &d, rate),
            Err(e) => {
                prop_assert_eq!(&e.field, "numerics.ticks_per_second");
                // refused only when H holds fewer ticks than always fit
                prop_assert!(
                    o.step * (rate as f64) < CLOCK_TICKS_ALWAYS_FIT as f64 * (1.0 + 1e-9),
                    "refused with {} ticks per H: {}", o.step * rate as f64, e
                );
            }
        }
    }
}

/// The time points and steps libcosim gives an FMU: it counts whole nanoseconds and converts
/// each point to seconds (`t = ns / 1e9`) and each step to the difference of two such points.
fn libcosim_times(n: u64, step_ns: u64) -> (f64, f64) {
    let t = (n * step_ns) as f64 / 1e9;
    let next = ((n + 1) * step_ns) as f64 / 1e9;
    (t, next - t)
}

#[test]
fn a_master_counting_nanoseconds_drives_the_slave_to_the_in_process_result_bit_for_bit() {
    let s = paper_on_clock(NANOSECONDS).unwrap();
    let d = s.plant.discretisation().unwrap();
    let step_ns = d.ticks.unwrap();
    let reference = simulate(&s, SimulateOptions::default()).unwrap();
    // the FMU's way in: the paper's defaults, then the parameter set before initialisation
    let paper = Scenario::paper();
    let mut slave = Slave::instantiate_with_wave("clocked", paper.plant, paper.wave).unwrap();
    slave
        .set_uint64(&[vr::TICKS_PER_SECOND], &[NANOSECONDS])
        .unwrap();
    assert_eq!(slave.plant().discretisation(), &d);
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.exit_initialization_mode().unwrap();
    slave.set_stress_limit(Some(s.task.sigma_max)).unwrap();
    for n in 0..reference.macro_steps {
        let (t, h) = libcosim_times(n, step_ns);
        assert_eq!(
            slave.do_step(t, h),
            StepStatus::Ok,
            "step {n}: t = {t}, h = {h}"
        );
    }
    assert_eq!(state_digest(slave.plant()), reference.state_digest);
    let m = slave.plant().steady_metrics().unwrap();
    assert_eq!(m.velocity.to_bits(), reference.velocity.to_bits());
    assert_eq!(m.power.to_bits(), reference.power.to_bits());
    assert_eq!(
        m.stuck_fraction.to_bits(),
        reference.stuck_fraction.to_bits()
    );
    assert_eq!(m.max_stress.to_bits(), reference.max_stress.to_bits());
    // the master's clock and the plant's agree at the end (no drift: both count whole steps)
    let (t_end, _) = libcosim_times(reference.macro_steps, step_ns);
    assert!((slave.plant().time() - t_end).abs() <= 1e-15 * t_end);
}

#[test]
fn on_its_own_clock_the_plant_refuses_a_nanosecond_master_and_names_the_parameter() {
    let paper = Scenario::paper();
    let mut slave = Slave::instantiate_with_wave("own", paper.plant, paper.wave).unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.exit_initialization_mode().unwrap();
    let h = slave.plant().step_length();
    let step_ns = (h * 1e9).round() as u64;
    let (t, h_ns) = libcosim_times(0, step_ns);
    match slave.do_step(t, h_ns) {
        StepStatus::Error(e) => {
            let e = e.to_string();
            assert!(e.contains("ticks_per_second"), "{e}");
        }
        other => panic!("a step {} ns short of H was taken: {other:?}", h - h_ns),
    }
}

#[test]
fn the_clock_is_a_parameter_fixed_before_stepping_and_zero_is_the_plants_own() {
    let paper = Scenario::paper();
    let own = paper.plant.discretisation().unwrap();
    let mut slave = Slave::instantiate_with_wave("p", paper.plant, paper.wave).unwrap();
    assert_eq!(slave.get_uint64(&[vr::TICKS_PER_SECOND]).unwrap(), [0]);
    slave
        .set_uint64(&[vr::TICKS_PER_SECOND], &[NANOSECONDS])
        .unwrap();
    assert_eq!(
        slave.get_uint64(&[vr::TICKS_PER_SECOND]).unwrap(),
        [NANOSECONDS]
    );
    assert_ne!(slave.plant().discretisation(), &own);
    slave.set_uint64(&[vr::TICKS_PER_SECOND], &[0]).unwrap();
    assert_eq!(slave.plant().discretisation(), &own);
    // too coarse a clock is an error naming the field
    let e = slave
        .set_uint64(&[vr::TICKS_PER_SECOND], &[1000])
        .unwrap_err()
        .to_string();
    assert!(e.contains("numerics.ticks_per_second"), "{e}");
    slave.reset().unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.exit_initialization_mode().unwrap();
    let e = slave
        .set_uint64(&[vr::TICKS_PER_SECOND], &[NANOSECONDS])
        .unwrap_err()
        .to_string();
    assert!(e.contains("ticks_per_second"), "{e}");
}
