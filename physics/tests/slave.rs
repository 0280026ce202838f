//! The FMI-style slave: lifecycle, value references, checkpoint/restore, bad input.

mod common;

use common::paper;
use crawler_physics::model_description::vr;
use crawler_physics::scenario::{Overrides, Scenario};
use crawler_physics::slave::{LifecycleState, Slave, SlaveError, StepStatus};
use crawler_physics::wave::Wave;

fn stick_slip() -> Scenario {
    let mut s = paper(Overrides {
        eps: Some(1.0),
        f0: Some(0.2),
        alpha: Some(0.5),
        t_end: Some(6.0),
        ..Default::default()
    });
    s.plant.numerics.settle = 1.0;
    s
}

fn started(s: &Scenario) -> Slave {
    let mut slave = Slave::instantiate("test", s.plant.clone()).unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.set_wave(s.wave).unwrap();
    slave.exit_initialization_mode().unwrap();
    slave
}

fn steps(slave: &mut Slave, n: u64) {
    let h = slave.plant().step_length();
    for _ in 0..n {
        let t = slave.plant().time();
        assert_eq!(slave.do_step(t, h), StepStatus::Ok);
    }
}

#[test]
fn checkpoint_restore_and_continue_is_bit_identical() {
    let s = stick_slip();
    let mut straight = started(&s);
    steps(&mut straight, 3000);

    let mut first = started(&s);
    steps(&mut first, 1234);
    let bytes = Slave::serialize_state(&first.get_state());
    drop(first);
    let state = Slave::deserialize_state(&bytes).unwrap();
    let mut resumed = Slave::instantiate("resumed", state.params.clone()).unwrap();
    resumed.enter_initialization_mode(0.0, None).unwrap();
    resumed.exit_initialization_mode().unwrap();
    resumed.set_state(&state).unwrap();
    steps(&mut resumed, 3000 - 1234);

    let (a, b) = (straight.get_state(), resumed.get_state());
    assert!(
        a.u.iter()
            .zip(&b.u)
            .all(|(x, y)| x.to_bits() == y.to_bits()),
        "u differs"
    );
    assert!(
        a.v.iter()
            .zip(&b.v)
            .all(|(x, y)| x.to_bits() == y.to_bits()),
        "v differs"
    );
    assert_eq!(a, b, "full state differs");
    let (ma, mb) = (
        straight.plant().steady_metrics().unwrap(),
        resumed.plant().steady_metrics().unwrap(),
    );
    assert_eq!(ma.velocity.to_bits(), mb.velocity.to_bits());
    assert_eq!(ma.episodes, mb.episodes);
}

#[test]
fn in_memory_state_rolls_back() {
    let s = stick_slip();
    let mut slave = started(&s);
    steps(&mut slave, 100);
    let saved = slave.get_state();
    let u100 = slave.plant().displacement().to_vec();
    steps(&mut slave, 50);
    assert_ne!(slave.plant().displacement(), &u100[..]);
    slave.set_state(&saved).unwrap();
    assert_eq!(slave.plant().displacement(), &u100[..]);
    assert_eq!(slave.plant().macro_step(), 100);
}

#[test]
fn corrupted_or_foreign_states_are_refused() {
    let s = stick_slip();
    let mut slave = started(&s);
    steps(&mut slave, 10);
    let bytes = Slave::serialize_state(&slave.get_state());
    assert!(
        Slave::deserialize_state(&bytes[..bytes.len() - 3]).is_err(),
        "truncated"
    );
    let mut flipped = bytes.clone();
    let last = flipped.len() - 1;
    flipped[last] ^= 1;
    assert!(Slave::deserialize_state(&flipped).is_err(), "bit flip");
    assert!(Slave::deserialize_state(b"garbage").is_err());
    let mut other = s.clone();
    other.plant.numerics.cells = 64;
    let mut foreign = started(&other);
    assert!(matches!(
        foreign.set_state(&slave.get_state()),
        Err(SlaveError::Invalid(_))
    ));
    let mut nan = slave.get_state();
    nan.u[3] = f64::NAN;
    let err = slave.set_state(&nan).unwrap_err().to_string();
    assert!(err.contains("state.u[3]"), "{err}");
}

#[test]
fn illegal_lifecycle_calls_are_refused() {
    let s = stick_slip();
    let mut slave = Slave::instantiate("x", s.plant.clone()).unwrap();
    // the communication step H: a whole number of internal steps near the requested 1 ms
    let h = s.plant.discretisation().unwrap().step;
    assert!(matches!(
        slave.do_step(0.0, h),
        StepStatus::Error(SlaveError::IllegalCall { .. })
    ));
    assert_eq!(slave.lifecycle(), LifecycleState::Error);
    slave.reset().unwrap();
    assert_eq!(slave.lifecycle(), LifecycleState::Instantiated);
    assert!(matches!(
        slave.exit_initialization_mode(),
        Err(SlaveError::IllegalCall { .. })
    ));
    slave.reset().unwrap();
    assert!(matches!(
        slave.terminate(),
        Err(SlaveError::IllegalCall { .. })
    ));
    slave.reset().unwrap();
    slave.enter_initialization_mode(0.0, Some(0.01)).unwrap();
    assert!(matches!(
        slave.enter_initialization_mode(0.0, None),
        Err(SlaveError::IllegalCall { .. })
    ));
    slave.reset().unwrap();
    slave.enter_initialization_mode(0.0, Some(0.01)).unwrap();
    slave.set_wave(s.wave).unwrap();
    slave.exit_initialization_mode().unwrap();
    // wrong current time
    assert!(matches!(slave.do_step(0.5, h), StepStatus::Error(_)));
    slave.reset().unwrap();
    slave.enter_initialization_mode(0.0, Some(0.01)).unwrap();
    slave.exit_initialization_mode().unwrap();
    // parameters are fixed in step mode
    assert!(matches!(
        slave.set_float64(&[vr::EPS], &[0.3]),
        Err(SlaveError::NotSettable { .. })
    ));
    slave.reset().unwrap();
    slave.enter_initialization_mode(0.0, Some(0.01)).unwrap();
    slave.exit_initialization_mode().unwrap();
    // not a whole number of communication steps: an Error (the step is fixed; a Discard would
    // invite a retry with the same h), nothing stepped
    assert!(
        matches!(slave.do_step(0.0, 1.5 * h), StepStatus::Error(SlaveError::Invalid(ref e)) if e.field == "h")
    );
    assert_eq!(slave.plant().macro_step(), 0);
    slave.reset().unwrap();
    slave.enter_initialization_mode(0.0, Some(0.01)).unwrap();
    slave.exit_initialization_mode().unwrap();
    assert_eq!(slave.do_step(0.0, 2.0 * h), StepStatus::Ok);
    // beyond the stop time
    assert!(matches!(
        slave.do_step(2.0 * h, 10.0 * h),
        StepStatus::Error(_)
    ));
    slave.reset().unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.exit_initialization_mode().unwrap();
    slave.terminate().unwrap();
    assert!(matches!(
        slave.do_step(0.0, h),
        StepStatus::Error(SlaveError::IllegalCall { .. })
    ));
}

#[test]
fn value_references_read_and_write() {
    let s = stick_slip();
    let mut slave = Slave::instantiate("vr", s.plant.clone()).unwrap();
    slave
        .set_float64(&[vr::EPS, vr::N_F], &[0.7, 0.25])
        .unwrap();
    assert_eq!(
        slave.get_float64(&[vr::EPS, vr::N_F]).unwrap(),
        vec![0.7, 0.25]
    );
    assert!(matches!(
        slave.set_float64(&[vr::N_F], &[1.5]),
        Err(SlaveError::Invalid(_))
    ));
    slave.reset().unwrap();
    assert!(matches!(
        slave.set_float64(&[9999], &[1.0]),
        Err(SlaveError::UnknownReference { .. })
    ));
    slave.reset().unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.set_uint64(&[vr::ACTUATION_MODE], &[1]).unwrap();
    slave
        .set_float64(
            &[vr::WAVE_F0, vr::WAVE_K, vr::WAVE_OMEGA, vr::WAVE_PHASE],
            &[s.wave.f0, s.wave.k, s.wave.omega, 0.0],
        )
        .unwrap();
    slave.exit_initialization_mode().unwrap();
    let h = slave.plant().step_length();
    assert_eq!(slave.do_step(0.0, h), StepStatus::Ok);
    let n = s.plant.numerics.cells;
    assert_eq!(
        slave
            .get_float64(&[vr::U, vr::V, vr::TENSION])
            .unwrap()
            .len(),
        3 * n
    );
    assert_eq!(slave.get_boolean(&[vr::STUCK]).unwrap().len(), n);
    assert_eq!(slave.get_uint64(&[vr::CELLS]).unwrap(), vec![n as u64]);
    // the same wave through the typed call gives the same trajectory
    let mut typed = started(&s);
    assert_eq!(typed.do_step(0.0, h), StepStatus::Ok);
    assert_eq!(typed.plant().displacement(), slave.plant().displacement());
    // field input of the wrong size is refused
    slave.set_uint64(&[vr::ACTUATION_MODE], &[2]).unwrap();
    assert!(matches!(
        slave.set_float64(&[vr::MUSCLE_FORCE], &[1.0; 3]),
        Err(SlaveError::WrongCount { .. })
    ));
}

#[test]
fn model_description_lists_every_variable_once() {
    use crawler_physics::model_description::{variable_name, Causality};
    let s = stick_slip();
    let slave = Slave::instantiate("md", s.plant.clone()).unwrap();
    let md = slave.model_description();
    let mut refs: Vec<u32> = md.variables.iter().map(|v| v.value_reference).collect();
    refs.sort_unstable();
    let len = refs.len();
    refs.dedup();
    assert_eq!(refs.len(), len, "duplicate value references");
    for v in &md.variables {
        assert_eq!(
            variable_name(v.value_reference),
            Some((v.name, v.var_type)),
            "the name table disagrees with the description"
        );
    }
    let xml = md.to_fmi3_xml();
    assert!(xml.contains("fmiVersion=\"3.0\""));
    for v in &md.variables {
        assert_eq!(
            xml.matches(&format!(" name=\"{}\"", v.name)).count(),
            1,
            "{}",
            v.name
        );
    }
    let outputs = md
        .variables
        .iter()
        .filter(|v| v.causality == Causality::Output)
        .count();
    let unknowns = outputs
        + md.variables
            .iter()
            .filter(|v| v.causality == Causality::CalculatedParameter)
            .count();
    assert_eq!(xml.matches("<Output ").count(), outputs);
    assert_eq!(xml.matches("<InitialUnknown ").count(), unknowns);
    // FMI 2.0: arrays as N scalars each
    let n = s.plant.numerics.cells;
    let fmi2 = md.to_fmi2_xml();
    let arrays = md.variables.iter().filter(|v| v.size.is_some()).count();
    assert_eq!(
        fmi2.matches("<ScalarVariable ").count(),
        len - arrays + arrays * n
    );
    assert!(
        fmi2.contains(&format!("name=\"u[{n}]\""))
            && !fmi2.contains(&format!("name=\"u[{}]\"", n + 1))
    );
    let json: serde_json::Value = serde_json::from_str(&md.to_json()).unwrap();
    assert_eq!(json["variables"].as_array().unwrap().len(), len);
}

#[test]
fn every_variable_reads_back_its_start_value() {
    use crawler_physics::model_description::{Causality, ModelDescription, Start, VarType};
    let s = stick_slip();
    let md = ModelDescription::with_inputs(&s.plant, Some(s.wave));
    let slave = Slave::instantiate_with_wave("starts", s.plant.clone(), s.wave).unwrap();
    for v in &md.variables {
        let Some(start) = &v.start else {
            assert!(
                matches!(
                    v.causality,
                    Causality::Output | Causality::CalculatedParameter | Causality::Independent
                ),
                "{} has no start value",
                v.name
            );
            continue;
        };
        let r = [v.value_reference];
        match (v.var_type, start) {
            (VarType::Float64, Start::Float(x)) => {
                let got = slave.get_float64(&r).unwrap();
                assert!(got.iter().all(|g| g.to_bits() == x.to_bits()), "{}", v.name)
            }
            (VarType::UInt64, Start::UInt(x)) => {
                assert_eq!(slave.get_uint64(&r).unwrap(), vec![*x], "{}", v.name)
            }
            (VarType::Enumeration, Start::Enum(x)) => {
                assert_eq!(slave.get_int64(&r).unwrap(), vec![*x])
            }
            (VarType::String, Start::Text(x)) => assert_eq!(&slave.get_string(&r).unwrap()[0], x),
            other => panic!("{}: start {other:?} of the wrong type", v.name),
        }
    }
}

#[test]
fn the_pipe_parameter_round_trips_and_is_validated() {
    let s = stick_slip();
    let mut slave = Slave::instantiate("pipe", s.plant.clone()).unwrap();
    let map = r#"{"start":0.1,"features":[{"kind":"ramp","from":0.0,"to":2.0,"eps":[1.0,0.2]}]}"#;
    slave.set_string(&[vr::PIPE], &[map]).unwrap();
    assert_eq!(slave.params().pipe.start, 0.1);
    assert_eq!(slave.params().pipe.features.len(), 1);
    let back = slave.get_string(&[vr::PIPE]).unwrap();
    let mut again = Slave::instantiate("pipe2", s.plant.clone()).unwrap();
    again.set_string(&[vr::PIPE], &[back[0].as_str()]).unwrap();
    assert_eq!(again.params(), slave.params());
    let err = slave
        .set_string(&[vr::PIPE], &[r#"{"resolution":-1}"#])
        .unwrap_err()
        .to_string();
    assert!(err.contains("pipe.resolution"), "{err}");
    slave.reset().unwrap();
    let err = slave
        .set_string(&[vr::PIPE], &["{"])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("invalid pipe") && err.contains("JSON"),
        "{err}"
    );
}

#[test]
fn outputs_are_never_nan_before_the_steady_window() {
    let s = stick_slip();
    let mut slave = started(&s);
    steps(&mut slave, 3);
    let all: Vec<u32> = (200..=218)
        .filter(|r| !matches!(r, 203 | 206 | 209))
        .collect();
    let values = slave.get_float64(&all).unwrap();
    assert!(values.iter().all(|x| x.is_finite()));
    assert_eq!(slave.get_float64(&[vr::STEADY_PERIODS]).unwrap(), vec![0.0]);
    assert_eq!(slave.get_float64(&[vr::VELOCITY]).unwrap(), vec![0.0]);
    let u = slave.plant().displacement().to_vec();
    assert_eq!(
        slave.get_float64(&[vr::TAIL_DISPLACEMENT]).unwrap(),
        vec![u[0]]
    );
    let mean = u.iter().sum::<f64>() / u.len() as f64;
    assert_eq!(
        slave.get_float64(&[vr::MEAN_DISPLACEMENT]).unwrap(),
        vec![mean]
    );
}

#[test]
fn importer_times_are_accepted_within_a_tolerance_that_grows_with_t() {
    use crawler_physics::slave::time_tolerance;
    let s = stick_slip();
    let mut slave = started(&s);
    let h = slave.plant().step_length();
    // t accumulated by addition, h as a difference of two such times
    let mut t = 0.0;
    for _ in 0..3000 {
        let next = t + h;
        assert_eq!(slave.do_step(t, next - t), StepStatus::Ok);
        t = next;
    }
    let now = slave.plant().time();
    assert!(time_tolerance(now, h) > time_tolerance(0.0, h));
    assert!(
        time_tolerance(1e9, h) <= 0.25 * h,
        "never more than a quarter step"
    );
    // half a step off is another communication point: refused
    assert!(matches!(
        slave.do_step(now + 0.5 * h, h),
        StepStatus::Error(_)
    ));
}

#[test]
fn waves_that_do_not_fit_the_body_are_refused() {
    let s = stick_slip();
    let mut slave = Slave::instantiate("fit", s.plant.clone()).unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    let bad = Wave {
        k: 1.5 * s.wave.k,
        ..s.wave
    };
    let err = slave.set_wave(bad).unwrap_err().to_string();
    assert!(
        err.contains("wave.k") && err.contains("whole number"),
        "{err}"
    );
    slave.reset().unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    let twice = Wave {
        k: 2.0 * s.wave.k,
        ..s.wave
    };
    slave.set_wave(twice).unwrap();
}

#[test]
fn huge_actuation_is_discarded_and_rolled_back() {
    let s = stick_slip();
    let mut slave = started(&s);
    steps(&mut slave, 5);
    let before = slave.get_state();
    // only the gradient of the muscle force pushes: alternate signs to make it overflow
    let field: Vec<f64> = (0..s.plant.numerics.cells)
        .map(|i| if i % 2 == 0 { 1e308 } else { -1e308 })
        .collect();
    slave.set_field(&field).unwrap();
    let h = slave.plant().step_length();
    match slave.do_step(slave.plant().time(), h) {
        StepStatus::Discard {
            last_successful_time,
            ..
        } => assert_eq!(last_successful_time, 5.0 * h),
        other => panic!("expected a discard, got {other:?}"),
    }
    assert_eq!(slave.get_state().u, before.u);
    assert!(slave.plant().displacement().iter().all(|x| x.is_finite()));
}

#[test]
fn states_of_the_earlier_format_are_refused_with_the_reason() {
    // A state blob as format 1 wrote it: magic, version 1, CRC-32 of the payload, payload.
    let s = stick_slip();
    let slave = started(&s);
    let mut bytes = Slave::serialize_state(&slave.get_state());
    bytes[8..12].copy_from_slice(&1u32.to_le_bytes());
    let e = Slave::deserialize_state(&bytes).unwrap_err().to_string();
    assert!(
        e.contains("format version 1") && e.contains("Courant number 0.9") && e.contains("rerun"),
        "{e}"
    );
}
