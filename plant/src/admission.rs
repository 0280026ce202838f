//! Admission of the controller's actuation: one message, decoded and checked against the step
//! the plant waits for, the controller that joined and the body it drives; whatever is rejected
//! is counted by cause and never applied.
//!
//! Pure: no clock, no network, no process. The runner feeds it the bytes that arrive and applies
//! what it admits; the order of the checks (decoding, sender, step, body) decides the cause a
//! message is counted under.

use crawler_physics::error::ParamError;
use crawler_physics::execution::Actuation;
use crawler_physics::params::Boundary;
use crawler_physics::wave::Wave;
use crawler_protocol::{decode, Actuation as ActuationMsg, ProtocolError, Rejections, WaveMsg};

/// Why an actuation message was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reject {
    /// Undecodable.
    Malformed,
    /// Other protocol version.
    Version,
    /// Invalid values.
    Invalid,
    /// Not from the joined controller.
    Foreign,
    /// For an earlier step.
    Stale,
    /// A second answer to the step just taken.
    Duplicate,
    /// For a later step.
    Future,
}

impl Reject {
    /// The counter of this cause in `r`.
    fn counter(self, r: &mut Rejections) -> &mut u64 {
        match self {
            Reject::Malformed => &mut r.malformed,
            Reject::Version => &mut r.version,
            Reject::Invalid => &mut r.invalid,
            Reject::Foreign => &mut r.foreign,
            Reject::Stale => &mut r.stale,
            Reject::Duplicate => &mut r.duplicate,
            Reject::Future => &mut r.future,
        }
    }
}

/// A rejected message.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejection {
    /// The cause it was counted under.
    pub kind: Reject,
    /// Messages of this cause rejected so far in the run, this one included.
    pub count: u64,
    /// What was wrong, naming the field and the value.
    pub reason: String,
}

impl Rejection {
    /// Whether to tell the user: the first five of each cause, then every 1000th, so that a
    /// flood does not flood the terminal.
    pub fn worth_reporting(&self) -> bool {
        self.count <= 5 || self.count.is_multiple_of(1000)
    }
}

/// The plant's wave from its wire form (the numbers are checked where it is applied).
pub fn wave_of(w: &WaveMsg) -> Wave {
    Wave {
        f0: w.f0,
        k: w.k,
        omega: w.omega,
        phase: w.phase,
    }
}

/// The plant's actuation of a wire actuation that carries exactly one of `wave` and `field`.
pub fn command_of(a: ActuationMsg) -> Result<Actuation, ProtocolError> {
    match (a.wave, a.field) {
        (Some(w), None) => Ok(Actuation::Wave(wave_of(&w))),
        (None, Some(f)) => Ok(Actuation::Field(f)),
        _ => Err(ProtocolError::invalid(
            "actuation",
            "wave and field both given or both missing",
            "exactly one of wave and field",
        )),
    }
}

/// Checks `command` against a body of `cells` cells, `length` m and `boundary`: a field has one
/// finite value per cell, a wave is valid and fits the body (what the slave checks).
pub fn check(
    command: &Actuation,
    cells: usize,
    length: f64,
    boundary: Boundary,
) -> Result<(), ParamError> {
    {
        match command {
            Actuation::Wave(w) => w.validate_for_body(length, cells, boundary),
            Actuation::Field(f) => {
                if f.len() != cells {
                    return Err(ParamError::new(
                        "actuation.field",
                        format!("{} values", f.len()),
                        format!("{cells} values, one per cell"),
                    ));
                }
                match f.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                    Some((i, x)) => Err(ParamError::new(
                        format!("actuation.field[{i}]"),
                        x,
                        "finite numbers (N)",
                    )),
                    None => Ok(()),
                }
            }
        }
    }
}

/// The admission of one run: the body the actuation drives and what was rejected so far.
#[derive(Debug, Clone)]
pub struct Admission {
    cells: usize,
    length: f64,
    boundary: Boundary,
    rejections: Rejections,
}

impl Admission {
    /// Admission for a body of `cells` cells, `length` m and `boundary`, continuing the counts
    /// `rejections` (zero for a new run, the checkpoint's for a resumed one).
    pub fn new(cells: usize, length: f64, boundary: Boundary, rejections: Rejections) -> Self {
        Self {
            cells,
            length,
            boundary,
            rejections,
        }
    }

    /// What was rejected so far (`overflow` is counted by the inbox, not here).
    pub fn rejections(&self) -> Rejections {
        self.rejections
    }

    /// Decodes and checks `bytes` as the answer of controller `joined` to the state of step
    /// `step`. The command returned can be applied as is; a rejected message is counted.
    pub fn admit(&mut self, bytes: &[u8], step: u64, joined: &str) -> Result<Actuation, Rejection> {
        self.classify(bytes, step, joined)
            .map_err(|(kind, reason)| {
                let count = kind.counter(&mut self.rejections);
                *count += 1;
                Rejection {
                    kind,
                    count: *count,
                    reason,
                }
            })
    }

    fn classify(&self, bytes: &[u8], n: u64, joined: &str) -> Result<Actuation, (Reject, String)> {
        let a: ActuationMsg = decode(bytes).map_err(|e| (cause(&e), e.to_string()))?;
        if a.controller != joined {
            return Err((
                Reject::Foreign,
                format!(
                    "actuation from controller {:?}, the run's controller is {joined:?}",
                    a.controller
                ),
            ));
        }
        if a.step < n {
            let kind = if a.step + 1 == n {
                Reject::Duplicate
            } else {
                Reject::Stale
            };
            return Err((
                kind,
                format!("actuation for step {} while at step {n}", a.step),
            ));
        }
        if a.step > n {
            return Err((
                Reject::Future,
                format!("actuation for step {} while at step {n}", a.step),
            ));
        }
        let command = command_of(a).map_err(|e| (cause(&e), e.to_string()))?;
        check(&command, self.cells, self.length, self.boundary)
            .map_err(|e| (Reject::Invalid, e.to_string()))?;
        Ok(command)
    }
}

/// The cause a decoding error is counted under.
fn cause(e: &ProtocolError) -> Reject {
    match e {
        ProtocolError::Version { .. } => Reject::Version,
        ProtocolError::Invalid { .. } => Reject::Invalid,
        _ => Reject::Malformed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crawler_physics::scenario::Scenario;
    use crawler_physics::slave::Slave;
    use crawler_protocol::{encode, PROTOCOL_VERSION};
    use proptest::prelude::*;
    use std::f64::consts::TAU;

    const CELLS: usize = 64;
    const LENGTH: f64 = 0.25;

    fn wave(k: f64) -> WaveMsg {
        WaveMsg {
            f0: 0.05,
            k,
            omega: 300.0,
            phase: 0.0,
        }
    }

    fn actuation(step: u64, controller: &str) -> ActuationMsg {
        ActuationMsg {
            v: PROTOCOL_VERSION,
            step,
            controller: controller.into(),
            wave: Some(wave(TAU / LENGTH)),
            field: None,
        }
    }

    fn admission() -> Admission {
        Admission::new(CELLS, LENGTH, Boundary::Periodic, Rejections::default())
    }

    fn kind(bytes: &[u8], n: u64) -> Reject {
        admission().admit(bytes, n, "c1").unwrap_err().kind
    }

    #[test]
    fn the_answer_to_the_current_step_is_admitted_as_the_plants_wave_or_field() {
        let a = actuation(7, "c1");
        let got = admission().admit(&encode(&a), 7, "c1").unwrap();
        assert_eq!(
            got,
            Actuation::Wave(Wave {
                f0: 0.05,
                k: TAU / LENGTH,
                omega: 300.0,
                phase: 0.0
            })
        );
        let field: Vec<f64> = (0..CELLS).map(|i| i as f64 * 1e-3).collect();
        let a = ActuationMsg {
            wave: None,
            field: Some(field.clone()),
            ..actuation(7, "c1")
        };
        assert_eq!(
            admission().admit(&encode(&a), 7, "c1").unwrap(),
            Actuation::Field(field)
        );
    }

    #[test]
    fn each_fault_is_rejected_under_its_cause() {
        let n = 10;
        let bytes = |a: &ActuationMsg| encode(a);
        assert_eq!(kind(&[0xc1, 0x00], n), Reject::Malformed);
        assert_eq!(kind(&bytes(&actuation(n, "c1"))[..5], n), Reject::Malformed);
        let other_version = ActuationMsg {
            v: PROTOCOL_VERSION + 1,
            ..actuation(n, "c1")
        };
        assert_eq!(kind(&bytes(&other_version), n), Reject::Version);
        assert_eq!(kind(&bytes(&actuation(n, "intruder")), n), Reject::Foreign);
        assert_eq!(kind(&bytes(&actuation(n - 1, "c1")), n), Reject::Duplicate);
        assert_eq!(kind(&bytes(&actuation(n - 2, "c1")), n), Reject::Stale);
        assert_eq!(kind(&bytes(&actuation(0, "c1")), n), Reject::Stale);
        assert_eq!(kind(&bytes(&actuation(n + 1, "c1")), n), Reject::Future);
        let invalid = [
            // a wavelength that does not fit the body
            ActuationMsg {
                wave: Some(wave(1.5 * TAU / LENGTH)),
                ..actuation(n, "c1")
            },
            // fewer than 8 cells per wavelength
            ActuationMsg {
                wave: Some(wave(16.0 * TAU / LENGTH)),
                ..actuation(n, "c1")
            },
            ActuationMsg {
                wave: Some(WaveMsg {
                    f0: -1.0,
                    ..wave(TAU / LENGTH)
                }),
                ..actuation(n, "c1")
            },
            ActuationMsg {
                wave: Some(WaveMsg {
                    omega: f64::NAN,
                    ..wave(TAU / LENGTH)
                }),
                ..actuation(n, "c1")
            },
            ActuationMsg {
                wave: None,
                field: Some(vec![0.0; CELLS + 1]),
                ..actuation(n, "c1")
            },
            ActuationMsg {
                wave: None,
                field: Some(vec![f64::INFINITY; CELLS]),
                ..actuation(n, "c1")
            },
            ActuationMsg {
                wave: None,
                field: None,
                ..actuation(n, "c1")
            },
            ActuationMsg {
                field: Some(vec![0.0; CELLS]),
                ..actuation(n, "c1")
            },
        ];
        for a in &invalid {
            let r = admission().admit(&bytes(a), n, "c1").unwrap_err();
            assert_eq!(r.kind, Reject::Invalid, "{a:?}: {}", r.reason);
            assert!(r.reason.contains("allowed"), "{}", r.reason);
        }
    }

    #[test]
    fn the_sender_is_checked_before_the_step_and_the_step_before_the_body() {
        // A foreign message for an old step is foreign, and a stale one with bad values is
        // stale: the counts say who sent what, not which check came first by chance.
        let bad = ActuationMsg {
            wave: Some(wave(1.5 * TAU / LENGTH)),
            ..actuation(3, "intruder")
        };
        assert_eq!(kind(&encode(&bad), 9), Reject::Foreign);
        let bad = ActuationMsg {
            wave: Some(wave(1.5 * TAU / LENGTH)),
            ..actuation(3, "c1")
        };
        assert_eq!(kind(&encode(&bad), 9), Reject::Stale);
    }

    #[test]
    fn rejections_are_counted_by_cause_from_where_the_run_left_off() {
        let resumed = Rejections {
            stale: 41,
            overflow: 5,
            ..Rejections::default()
        };
        let mut adm = Admission::new(CELLS, LENGTH, Boundary::Periodic, resumed);
        let stale = encode(&actuation(1, "c1"));
        let foreign = encode(&actuation(9, "x"));
        for i in 1..=3 {
            let r = adm.admit(&stale, 9, "c1").unwrap_err();
            assert_eq!((r.kind, r.count), (Reject::Stale, 41 + i));
            let r = adm.admit(&foreign, 9, "c1").unwrap_err();
            assert_eq!((r.kind, r.count), (Reject::Foreign, i));
        }
        adm.admit(&encode(&actuation(9, "c1")), 9, "c1").unwrap();
        let r = adm.rejections();
        assert_eq!((r.stale, r.foreign, r.overflow), (44, 3, 5));
        assert_eq!(r.total(), 44 + 3 + 5);
    }

    #[test]
    fn the_first_five_of_a_cause_are_reported_then_every_thousandth() {
        let reported: Vec<u64> = (1..=3000)
            .filter(|&count| {
                Rejection {
                    kind: Reject::Stale,
                    count,
                    reason: String::new(),
                }
                .worth_reporting()
            })
            .collect();
        assert_eq!(reported, [1, 2, 3, 4, 5, 1000, 2000, 3000]);
    }

    fn slave(boundary: Boundary) -> Slave {
        let mut s = Scenario::paper();
        s.plant.numerics.cells = CELLS;
        s.plant.length = LENGTH;
        s.plant.boundary = boundary;
        let mut slave = Slave::instantiate("admission", s.plant).unwrap();
        slave.enter_initialization_mode(0.0, None).unwrap();
        slave.exit_initialization_mode().unwrap();
        slave
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

        /// What admission lets through the slave accepts, and a well-formed answer it refuses
        /// the slave refuses too: the plant never applies unchecked input, and never fails on
        /// input it admitted.
        #[test]
        fn admission_agrees_with_the_slave(
            f0 in prop_oneof![Just(-0.1), 0.0..1.0f64],
            m in prop_oneof![0.5..20.0f64, (1u32..12).prop_map(f64::from)],
            omega in prop_oneof![Just(0.0), 1.0..500.0f64],
            len in prop_oneof![Just(CELLS), 0usize..2 * CELLS],
            field in any::<bool>(),
            free in any::<bool>(),
        ) {
            let boundary = if free { Boundary::Free } else { Boundary::Periodic };
            let a = ActuationMsg {
                wave: (!field).then_some(WaveMsg { f0, k: m * TAU / LENGTH, omega, phase: 0.3 }),
                field: field.then(|| vec![0.01; len]),
                ..actuation(4, "c1")
            };
            let admitted = Admission::new(CELLS, LENGTH, boundary, Rejections::default())
                .admit(&encode(&a), 4, "c1");
            let mut s = slave(boundary);
            let applied = match (&a.wave, &a.field) {
                (Some(w), _) => s.set_wave(wave_of(w)),
                (_, Some(f)) => s.set_field(f),
                _ => unreachable!(),
            };
            prop_assert_eq!(admitted.is_ok(), applied.is_ok(), "{:?} / {:?}", admitted, applied);
            if let Ok(c) = admitted {
                prop_assert!(c.apply(&mut slave(boundary)).is_ok());
            }
        }
    }
}
