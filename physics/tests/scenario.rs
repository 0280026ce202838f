//! Scenario files and overrides: every bad input gets a clear error, never a panic.

use crawler_physics::scenario::{Overrides, Scenario, ScenarioError, PAPER_TOML};

fn load(text: &str) -> Result<Scenario, ScenarioError> {
    Scenario::from_toml(text, "test.toml", &Overrides::default())
}

#[test]
fn the_paper_scenario_has_the_papers_parameters() {
    let s = Scenario::paper();
    assert_eq!(s.plant.body.stiffness(), 14.0);
    assert!((s.plant.body.wave_speed() - 11.832).abs() < 1e-3);
    assert!((s.natural_frequency() - 74.34).abs() < 0.01);
    assert_eq!(s.wave.f0, 0.5);
    assert_eq!(s.plant.friction.n_f, 0.5);
    assert!((s.plant.length - 1.0).abs() < 1e-15);
}

#[test]
fn unknown_keys_and_wrong_types_name_the_line() {
    let text = PAPER_TOML.replace("eps = 0.1 ", "eps = 0.1\nfoo = 3 ");
    let e = load(&text).unwrap_err().to_string();
    assert!(e.contains("foo") && e.contains("line"), "{e}");
    let text = PAPER_TOML.replace("cells = 512 ", "cells = \"many\" ");
    let e = load(&text).unwrap_err().to_string();
    assert!(e.contains("line") && e.contains("cells"), "{e}");
}

#[test]
fn invalid_values_name_field_value_and_range() {
    let cases = [
        (
            Overrides {
                n_f: Some(1.5),
                ..Default::default()
            },
            "friction.n_f",
            "1.5",
        ),
        (
            Overrides {
                eps: Some(-0.1),
                ..Default::default()
            },
            "friction.eps",
            "-0.1",
        ),
        (
            Overrides {
                eps: Some(f64::NAN),
                ..Default::default()
            },
            "friction.eps",
            "NaN",
        ),
        (
            Overrides {
                f0: Some(f64::INFINITY),
                ..Default::default()
            },
            "actuation.f0",
            "inf",
        ),
        (
            Overrides {
                k: Some(-1.0),
                ..Default::default()
            },
            "actuation.k",
            "-1",
        ),
        (
            Overrides {
                alpha: Some(0.0),
                ..Default::default()
            },
            "actuation.alpha",
            "0",
        ),
        (
            Overrides {
                omega: Some(-3.0),
                ..Default::default()
            },
            "actuation.omega",
            "-3",
        ),
        (
            Overrides {
                cells: Some(3),
                ..Default::default()
            },
            "numerics.cells",
            "3",
        ),
        (
            Overrides {
                cells: Some(-5),
                ..Default::default()
            },
            "numerics.cells",
            "-5",
        ),
        (
            Overrides {
                t_end: Some(0.0),
                ..Default::default()
            },
            "numerics.t_end",
            "0",
        ),
        (
            // so long that the count of internal steps would not fit (it used to saturate)
            Overrides {
                t_end: Some(1e300),
                ..Default::default()
            },
            "numerics.t_end",
            "1e300",
        ),
    ];
    for (o, field, value) in cases {
        let e = Scenario::load(None, &o).unwrap_err().to_string();
        assert!(
            e.contains(field) && e.contains(value) && e.contains("allowed"),
            "{field}: {e}"
        );
    }
    let e = Scenario::load(
        None,
        &Overrides {
            omega: Some(3.0),
            alpha: Some(1.0),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("omega"), "{e}");
}

#[test]
fn a_wave_that_does_not_fit_an_explicit_body_is_refused() {
    let text = PAPER_TOML
        .replace("# length = 1.0", "length = 1.0")
        .replace("k = 6.283185307179586", "k = 9.42477796076938");
    let e = load(&text).unwrap_err().to_string();
    // named as the file has it, not as the plant's wave
    assert!(
        e.contains("invalid actuation.k = ") && e.contains("whole number"),
        "{e}"
    );
}

#[test]
fn names_and_descriptions_with_control_characters_are_refused() {
    for (field, bad) in [
        ("name", "name = \"\\u001b[31mred\""),
        ("description", "description = \"two\\nlines\""),
    ] {
        let text = PAPER_TOML.replace(&format!("{field} = "), &format!("{bad}\n#{field} = "));
        let e = load(&text).unwrap_err().to_string();
        assert!(
            e.contains(&format!("invalid {field} = ")) && e.contains("control characters"),
            "{e}"
        );
    }
}

#[test]
fn a_file_of_unbounded_length_is_refused_not_read_to_the_end() {
    let e = Scenario::from_file(std::path::Path::new("/dev/zero"), &Overrides::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("/dev/zero") && e.contains("larger than"), "{e}");
}

#[test]
fn huge_numbers_are_written_in_exponent_form() {
    let text = PAPER_TOML.replace("viscous = 1.0 ", "viscous = -1e300 ");
    let e = load(&text).unwrap_err().to_string();
    assert!(e.contains("invalid friction.viscous = -1e300:"), "{e}");
}

#[test]
fn inverted_limits_are_refused() {
    let text = PAPER_TOML.replace("omega = [10.0, 300.0]", "omega = [300.0, 10.0]");
    let e = load(&text).unwrap_err().to_string();
    assert!(e.contains("limits.omega"), "{e}");
}

#[test]
fn garbage_never_panics() {
    for text in [
        "",
        "[[[",
        "body = 3",
        "\u{0}\u{1}",
        "[body]\narea = 1e999",
        &PAPER_TOML[..PAPER_TOML.find("alpha = 1.0").unwrap() + 7],
    ] {
        assert!(load(text).is_err());
    }
}

#[test]
fn every_shipped_scenario_loads_and_the_embedded_one_is_the_file() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let text = std::fs::read_to_string(&path).unwrap();
            let s = load(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(!s.name.is_empty());
            n += 1;
        }
    }
    assert!(n >= 2, "scenarios/ holds paper.toml and stick-slip.toml");
    let paper = std::fs::read_to_string(dir.join("paper.toml")).unwrap();
    assert_eq!(paper, PAPER_TOML);
    let ss = std::fs::read_to_string(dir.join("stick-slip.toml")).unwrap();
    let ss = load(&ss).unwrap();
    assert_eq!(
        (ss.plant.friction.eps, ss.wave.f0, ss.plant.numerics.cells),
        (1.0, 0.2, 512)
    );
    assert!((ss.wave.omega / ss.natural_frequency() - 0.5).abs() < 1e-12);
}

#[test]
fn the_communication_step_is_a_whole_number_of_characteristic_steps() {
    use crawler_physics::params::Boundary;
    let s = Scenario::paper();
    let d = s.plant.discretisation().unwrap();
    let c = s.plant.body.wave_speed();
    // Courant number 1 to round-off, never above.
    assert!(d.courant <= 1.0 && d.courant > 1.0 - 1e-15, "{}", d.courant);
    assert!((c * d.dt / d.dx - 1.0).abs() < 1e-15);
    // H is the whole multiple of dt nearest to the requested 1 ms.
    assert_eq!(d.step, d.substeps as f64 * d.dt);
    assert!((d.step - 1e-3).abs() <= 0.5 * d.dt, "H = {}", d.step);
    // A run ends at the first communication point at or after t_end.
    let n = d.steps_until(s.t_end);
    assert!(n as f64 * d.step >= s.t_end * (1.0 - 1e-12));
    assert!((n - 1) as f64 * d.step < s.t_end);
    // A requested step far from a multiple of dt is rounded, and t_end is still reached.
    let text = PAPER_TOML.replace("step = 1.0e-3", "step = 0.3");
    let s = load(&text).unwrap();
    let d = s.plant.discretisation().unwrap();
    assert!((d.step - 0.3).abs() <= 0.5 * d.dt);
    assert!(d.steps_until(s.t_end) as f64 * d.step >= s.t_end * (1.0 - 1e-12));
    assert_eq!(s.plant.boundary, Boundary::Periodic);
}

#[test]
fn boundary_and_pipe_sections_are_read_and_checked() {
    use crawler_physics::params::Boundary;
    let free = PAPER_TOML.replace(
        "youngs_modulus = 140e3  # E, Pa (earthworm); A_c E = 14 N",
        "youngs_modulus = 140e3\nboundary = \"free\"\nlength = 0.7",
    );
    let s = load(&free).unwrap();
    assert_eq!(s.plant.boundary, Boundary::Free);
    // a free body takes a wave that does not fit it
    assert!((s.plant.length - 0.7).abs() < 1e-15);
    let periodic = free.replace("boundary = \"free\"\n", "");
    let e = load(&periodic).unwrap_err().to_string();
    assert!(e.contains("actuation.k") && e.contains("free"), "{e}");
    let bad = free.replace("boundary = \"free\"", "boundary = \"clamped\"");
    let e = load(&bad).unwrap_err().to_string();
    assert!(e.contains("clamped") && e.contains("line"), "{e}");

    let pipe = format!(
        "{PAPER_TOML}\n[pipe]\ndisclose = false\nnominal = {{ eps = 0.1, n_f = 0.5 }}\n\
         [[pipe.features]]\nkind = \"patch\"\nfrom = 2.0\nto = 3.0\neps = 0.8\n"
    );
    let s = load(&pipe).unwrap();
    assert!(!s.plant.pipe.disclose);
    let m = s.plant.friction_map();
    assert_eq!(m.at(2.5), (0.8, 0.5));
    assert_eq!(m.at(1.5), (0.1, 0.5));
    for (text, field) in [
        (
            pipe.replace("nominal = { eps = 0.1, n_f = 0.5 }\n", ""),
            "pipe.nominal",
        ),
        (pipe.replace("to = 3.0", "to = 1.0"), "pipe.features[0].to"),
        (
            pipe.replace("eps = 0.8", "eps = -0.8"),
            "pipe.features[0].eps",
        ),
        (
            pipe.replace("n_f = 0.5 }", "n_f = 1.5 }"),
            "pipe.nominal.n_f",
        ),
    ] {
        let e = load(&text).unwrap_err().to_string();
        assert!(e.contains(field), "expected an error naming {field}: {e}");
    }
    let e = load(&pipe.replace("kind = \"patch\"", "kind = \"hole\"")).unwrap_err();
    assert!(e.to_string().contains("hole"), "{e}");
}

#[test]
fn a_name_longer_than_the_report_carries_is_refused_by_field_and_length() {
    let most = crawler_facts::MAX_SCENARIO_NAME_LEN;
    let named = |name: &str| PAPER_TOML.replace("name = \"paper\"", &format!("name = \"{name}\""));
    assert_eq!(load(&named(&"x".repeat(most))).unwrap().name.len(), most);
    // a multi-byte name is counted in bytes
    let e = load(&named(&"é".repeat(most / 2 + 1)))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("name") && e.contains(&format!("{} bytes", most + 2)) && e.contains("at most"),
        "{e}"
    );
}

#[test]
fn a_body_whose_stiffness_or_wave_speed_overflows_is_named() {
    for (from, to, field) in [
        (
            "area = 1.0e-4 ",
            "area = 1e308 ",
            "invalid body.area = 1e308: allowed an area whose axial stiffness",
        ),
        (
            "youngs_modulus = 140e3 ",
            "youngs_modulus = 5e-324 ",
            "invalid body.area",
        ),
        (
            "density = 0.1 ",
            "density = 1e-308 ",
            "invalid body.density = 1e-308: allowed a density whose wave speed",
        ),
    ] {
        let e = load(&PAPER_TOML.replace(from, to)).unwrap_err().to_string();
        assert!(e.contains(field), "{to}: {e}");
    }
}

#[test]
fn a_step_rounded_past_the_run_says_which_body_made_the_internal_step_long() {
    // c = sqrt(1e-308 * 140e3 / 0.1) = 1.18e-151 m/s: one cell of 1/512 m takes 1.65e148 s
    let e = load(&PAPER_TOML.replace("area = 1.0e-4 ", "area = 1e-308 "))
        .unwrap_err()
        .to_string();
    for part in [
        "invalid numerics.step = 0.001",
        "H = 1.650691903766634e148 s",
        "dt = Courant dx / c = 1.650691903766634e148 s",
        "dx = body.length / numerics.cells = 1.953125e-3 m",
        "c = sqrt(body.area body.youngs_modulus / body.density) = 1.18321595661992",
    ] {
        assert!(e.contains(part), "{part}: {e}");
    }
}

#[test]
fn a_pair_of_numbers_is_exactly_two() {
    let e = load(&PAPER_TOML.replace("omega = [10.0, 300.0]", "omega = [10.0, 300.0, 3.0]"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("invalid length 3") && e.contains("two numbers"),
        "{e}"
    );
    let ramp = |eps: &str| {
        format!(
            "{PAPER_TOML}\n[pipe]\n[[pipe.features]]\nkind = \"ramp\"\nfrom = 0.0\nto = 1.0\neps = {eps}\n"
        )
    };
    let s = load(&ramp("[0.1, 0.3]")).unwrap();
    // held at the midpoint of [0.990, 0.991): 0.1 + 0.2 * 0.9905
    let eps = s.plant.pipe.compile(0.1, 0.5).at(0.99).0;
    assert!((eps - 0.2981).abs() < 1e-12, "{eps}");
    let e = load(&ramp("[0.1, 0.2, 0.3]")).unwrap_err().to_string();
    assert!(e.contains("invalid length 3"), "{e}");
    let e = load(&ramp("[0.1]")).unwrap_err().to_string();
    assert!(e.contains("invalid length 1"), "{e}");
}

/// The stick-slip scenario with `alpha` and, if given, `numerics.courant` (and `eps`).
fn stick_slip_at(alpha: f64, courant: Option<f64>, eps: f64) -> Scenario {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
    let text = std::fs::read_to_string(dir.join("stick-slip.toml")).unwrap();
    let text = text
        .replace("alpha = 0.5 ", &format!("alpha = {alpha} "))
        .replace("eps = 1.0 ", &format!("eps = {eps} "));
    let text = match courant {
        Some(c) => text.replace("# courant ", &format!("courant = {c} #")),
        None => text,
    };
    load(&text).unwrap()
}

#[test]
fn a_courant_number_known_to_bias_stick_statistics_is_named_with_what_is_allowed() {
    // the measured case: Courant 0.9 at alpha 1.7 gives a stuck fraction of 0.351 against 0.390
    let s = stick_slip_at(1.7, Some(0.9), 1.0);
    assert_eq!(s.plant.numerics.courant, 0.9);
    let c = s.caveats();
    assert_eq!(c.len(), 1, "{c:?}");
    assert_eq!((c[0].field, c[0].value), ("numerics.courant", 0.9));
    let text = c[0].to_string();
    assert!(text.contains("numerics.courant = 0.9"), "{text}");
    // what is allowed: 1 / alpha, written out
    assert!(text.contains("0.588235"), "{text}");
    assert!(text.contains("1 / alpha"), "{text}");
    // Courant 1 at exact resonance's side of the switch is biased too when it is not the default
    let below = stick_slip_at(0.5, Some(0.9), 1.0).caveats();
    assert_eq!(below.len(), 1);
    assert!(
        below[0].to_string().contains("use 1.000000 "),
        "{}",
        below[0]
    );
    let above = stick_slip_at(1.7, Some(1.0), 1.0).caveats();
    assert_eq!(
        above.len(),
        1,
        "Courant 1 above alpha 1.1 smears the stick phases too"
    );
}

#[test]
fn the_default_courant_number_and_a_body_without_dry_friction_have_no_caveat() {
    for alpha in [0.5, 1.0, 1.1, 1.7, 2.0] {
        let s = stick_slip_at(alpha, None, 1.0);
        assert!(s.caveats().is_empty(), "alpha {alpha}: {:?}", s.caveats());
        // the default written out is not a caveat either
        let c = s.plant.numerics.courant;
        assert!(stick_slip_at(alpha, Some(c), 1.0).caveats().is_empty());
    }
    // without dry friction there are no stick phases to bias
    assert!(stick_slip_at(1.7, Some(0.9), 0.0).caveats().is_empty());
}
