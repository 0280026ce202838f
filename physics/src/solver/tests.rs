//! Tests of the whole step: the kernel against the step written out node by node
//! (`reference.rs`), and the runs of one friction interval against per-node coefficients.

use super::reference::reference_step;
use super::Solver;
use crate::node_friction::MIXED;
use crate::params::{Boundary, PlantParams};

/// The paper's plant on `cells` cells in a pipe with the `[pipe]` section `pipe`.
fn piped(pipe: &str, cells: usize) -> Solver {
    let p = paper_with(pipe, cells, Boundary::Periodic);
    Solver::new(&p, &p.discretisation().unwrap())
}

/// The paper's plant parameters on `cells` cells with `boundary`, in a pipe with the
/// `[pipe]` section `pipe`.
fn paper_with(pipe: &str, cells: usize, boundary: Boundary) -> PlantParams {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/paper.toml"
    ))
    .unwrap()
        + pipe;
    let s = crate::Scenario::from_toml(&text, "<test>", &Default::default()).unwrap();
    let mut p = s.plant.clone();
    p.numerics.cells = cells;
    p.boundary = boundary;
    p
}

#[test]
fn the_kernel_gives_the_bits_of_the_scheme_written_out_node_by_node() {
    // bodies of whole four-node blocks and of one to three nodes more, both ends, uniform
    // and textured pipes, with and without a muscle-force field
    let texture = "\n[pipe]\n[[pipe.features]]\nkind = \"texture\"\nfrom = -1.0\nto = 3.0\n\
                   eps_std = 0.3\nn_f_std = 0.05\ncorrelation = 0.01\nseed = 9\n";
    // a patch wide enough for runs of chunks in one interval
    let patch = "\n[pipe]\n[[pipe.features]]\nkind = \"patch\"\nfrom = 0.2\nto = 0.7\neps = 0.3\n";
    let (mut transitions, mut runs) = (0, 0);
    for cells in [9, 10, 11, 12, 13, 67, 130, 263] {
        for boundary in [Boundary::Periodic, Boundary::Free] {
            for (pipe, field, filter) in [
                ("", false, true),
                (texture, false, true),
                (patch, false, true),
                ("", true, true),
                (texture, false, false),
            ] {
                let mut p = paper_with(pipe, cells, boundary);
                if !filter {
                    p.numerics.filter = 0.0;
                }
                let disc = p.discretisation().unwrap();
                let mut s = Solver::new(&p, &disc);
                let origin: Vec<f64> = (0..cells)
                    .map(|i| p.pipe.start + boundary.node_position(i, disc.dx))
                    .collect();
                s.set_wave_number(2.0 * std::f64::consts::PI, disc.dx);
                if field {
                    for (i, g) in s.field.iter_mut().enumerate() {
                        *g = 0.2 * (i as f64 * 0.7).sin();
                    }
                    s.set_field_active(true);
                }
                let case = format!(
                    "{cells} cells, {boundary:?}, pipe {pipe:?}, field {field}, filter {filter}"
                );
                for step in 0..3000 {
                    let w = step as f64 * 2e-3;
                    let (a, b) = (w.sin() * 0.6, w.cos() * 0.6);
                    let (u, v, stuck, sums) = reference_step(&s, &origin, p.length, a, b);
                    let before = s.stuck.clone();
                    let kernel = s.step(a, b);
                    let wrong = sums.differences(&kernel);
                    assert!(wrong.is_empty(), "{case}, step {step}: {wrong:?}");
                    let bits = |x: &[f64]| x.iter().map(|y| y.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&s.u), bits(&u), "{case}, step {step}: u");
                    assert_eq!(bits(&s.v), bits(&v), "{case}, step {step}: v");
                    assert_eq!(s.stuck, stuck, "{case}, step {step}: stuck");
                    // the switches, in node order, each with its new state
                    let switched: Vec<(u32, bool)> = (0..cells)
                        .filter(|&i| before[i] != stuck[i])
                        .map(|i| (i as u32, stuck[i]))
                        .collect();
                    let reported: Vec<(u32, bool)> =
                        s.transitions.iter().map(|t| (t.node, t.stuck)).collect();
                    assert_eq!(reported, switched, "{case}, step {step}: switches");
                    transitions += switched.len();
                }
                if let Some(m) = &s.map {
                    runs += m.chunk_interval().iter().filter(|&&j| j != MIXED).count();
                }
            }
        }
    }
    assert!(transitions > 1000, "{transitions} stick/slip switches");
    assert!(
        runs > 0,
        "no chunk ran with its interval's coefficients broadcast"
    );
}

/// The paper's plant on 256 cells in a pipe whose eps (and with `n_f_std > 0` n_F) varies.
fn textured(n_f_std: f64) -> Solver {
    piped(
        &format!(
            "\n[pipe]\n[[pipe.features]]\nkind = \"texture\"\nfrom = -1.0\nto = 3.0\n\
             eps_std = 0.1\nn_f_std = {n_f_std:?}\ncorrelation = 0.002\nseed = 4\n"
        ),
        256,
    )
}

#[test]
fn runs_of_one_interval_give_the_bits_of_per_node_coefficients() {
    // patches wide and narrow (one of n_F too), so that the body has long runs of one
    // interval and chunks that straddle an edge
    let pipe = "\n[pipe]\n\
        [[pipe.features]]\nkind = \"patch\"\nfrom = 0.3\nto = 0.6\neps = 0.3\n\
        [[pipe.features]]\nkind = \"patch\"\nfrom = 0.71\nto = 0.7105\neps = 0.02\n\
        [[pipe.features]]\nkind = \"patch\"\nfrom = 0.75\nto = 1.2\nn_f = 0.0\n";
    let mut runs = piped(pipe, 1024);
    runs.set_wave_number(2.0 * std::f64::consts::PI, 1.0 / 1024.0);
    let mut per_node = runs.clone();
    per_node.map.as_mut().unwrap().broadcast = false;
    per_node.refresh_friction();
    let chunks = |s: &Solver| {
        let c = s.map.as_ref().unwrap().chunk_interval();
        (c.iter().filter(|&&j| j != MIXED).count(), c.len())
    };
    assert_eq!(chunks(&per_node).0, 0);
    let (mut transitions, mut backward) = (0, 0);
    for n in 0..20_000 {
        let (a, b) = ((n as f64 * 1e-3).sin() * 0.5, (n as f64 * 1e-3).cos() * 0.5);
        let (x, y) = (runs.step(a, b), per_node.step(a, b));
        backward += runs.v.iter().filter(|&&v| v < 0.0).count();
        assert_eq!(runs.u, per_node.u, "step {n}");
        assert_eq!(runs.v, per_node.v, "step {n}");
        assert_eq!(runs.stuck, per_node.stuck, "step {n}");
        // the sums are summed in another order: equal to round-off of the band's scale,
        // the Coulomb force sum a g_i (N/m summed over the nodes) and its power
        let band: f64 = runs.map.as_ref().unwrap().g.iter().sum::<f64>() * runs.coef.a;
        let speed = runs.v.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
        let close = |p: f64, q: f64, scale: f64| (p - q).abs() <= 1e-12 * scale;
        assert!(
            close(x.friction_force, y.friction_force, band),
            "step {n}: {x:?} {y:?}"
        );
        assert!(close(
            x.dissipation,
            y.dissipation,
            band * speed + x.dissipation.abs()
        ));
        assert!(close(x.sum_s, y.sum_s, runs.cells() as f64));
        transitions += runs.transitions.len();
    }
    let (uniform, all) = chunks(&runs);
    assert!(
        uniform > all / 2 && uniform < all,
        "{uniform} of {all} chunks in one interval"
    );
    assert!(transitions > 100, "{transitions} stick/slip switches");
    // nodes slid both ways (so `sum |v|` and `sum v` differ)
    assert!(backward > 1000, "{backward} node steps backwards");
}

#[test]
fn computing_push_from_a_uniform_n_f_gives_the_bits_of_reading_it() {
    let mut computed = textured(0.0);
    assert!(computed.map.as_ref().unwrap().uniform_n_f.is_some());
    let mut read = computed.clone();
    read.map.as_mut().unwrap().uniform_n_f = None;
    let mut transitions = 0;
    for n in 0..20_000 {
        let (a, b) = ((n as f64 * 1e-3).sin() * 0.3, (n as f64 * 1e-3).cos() * 0.3);
        let (x, y) = (computed.step(a, b), read.step(a, b));
        assert_eq!(x.dissipation.to_bits(), y.dissipation.to_bits(), "step {n}");
        assert_eq!(x.friction_force.to_bits(), y.friction_force.to_bits());
        transitions += computed.transitions.len();
    }
    let bits = |s: &Solver| {
        s.u.iter()
            .chain(&s.v)
            .map(|x| x.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&computed), bits(&read));
    assert!(transitions > 100, "{transitions} stick/slip switches");
    // and a map whose n_F varies reads its push
    assert!(textured(0.05).map.unwrap().uniform_n_f.is_none());
}

#[test]
fn the_observed_tension_is_stiffness_times_strain_plus_muscle_on_every_face_bit_for_bit() {
    for cells in [1, 2, 5, 8, 67] {
        for boundary in [Boundary::Periodic, Boundary::Free] {
            let p = paper_with("", cells, boundary);
            let disc = p.discretisation().unwrap();
            let mut s = Solver::new(&p, &disc);
            s.set_wave_number(2.0 * std::f64::consts::PI, disc.dx);
            for (i, g) in s.field.iter_mut().enumerate() {
                *g = 0.2 * (i as f64 * 0.7).sin();
            }
            for (i, u) in s.u.iter_mut().enumerate() {
                *u = 1e-3 * (i as f64 * 1.3).cos();
            }
            let (a, b) = (0.31, -0.47);
            let mut out = vec![7.0; 3];
            s.tension_into(a, b, &mut out);
            let per_face: Vec<u64> = (0..cells)
                .map(|i| {
                    let t = if s.is_interior_face(i) {
                        s.coef.stiffness * s.strain(i) + s.muscle(i, a, b)
                    } else {
                        0.0
                    };
                    t.to_bits()
                })
                .collect();
            let got: Vec<u64> = out.iter().map(|t| t.to_bits()).collect();
            assert_eq!(got, per_face, "{cells} cells, {boundary:?}");
            let end = out[cells - 1];
            if boundary == Boundary::Free {
                assert_eq!(end, 0.0, "a free body's end face carries no tension");
            } else {
                assert_ne!(end, 0.0, "a periodic body's last face wraps around to u_0");
            }
        }
    }
}
