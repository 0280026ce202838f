//! The peers' benchmark (`bench/peers/`, docs/peers.md) in its quick mode: the same crawler in
//! this project's plant, in MuJoCo and in PyElastica, one second simulated per case, so the
//! scripts cannot rot. It asserts outcomes only (no timing): every tool runs and reports finite
//! numbers of the sign and size the physics demands, and the plant's static hold is exactly at
//! rest.

use std::time::Duration;

use crawler_e2e::{bin, bin_dir, python, repo_root, Proc, Run};
use serde_json::Value;

/// The paper's pipe: c_d = 1 N/m, c_v = 1 N s/m^2, n_F = 0.5.
const C_D: f64 = 1.0;
const C_V: f64 = 1.0;
const N_F: f64 = 0.5;

/// `bench/peers/run.py --quick --case CASE` with the workspace's binaries: its JSON object,
/// keyed "tool/case".
fn quick(case: &str) -> serde_json::Map<String, Value> {
    // the binaries the script runs, built if missing
    bin("crawler-plant");
    bin("crawler-controller");
    let run = Run::new(&format!("peers-{case}"));
    let script = repo_root().join("bench/peers/run.py");
    let p = Proc::spawn(
        "peers",
        &python(),
        &[
            script.display().to_string(),
            "--quick".into(),
            "--case".into(),
            case.into(),
            "--bin-dir".into(),
            bin_dir().display().to_string(),
        ],
        run.dir.path(),
    );
    // a fresh venv compiles PyElastica's numba kernels on first use (about a minute)
    let o = p.wait(Duration::from_secs(900));
    assert!(o.status.success(), "{}\n{}", o.stdout, o.stderr);
    match serde_json::from_str::<Value>(o.stdout.trim()) {
        Ok(Value::Object(m)) => m,
        other => panic!("not a JSON object: {other:?}\n{}", o.stdout),
    }
}

fn num(r: &serde_json::Map<String, Value>, key: &str, field: &str) -> f64 {
    let v = r
        .get(key)
        .unwrap_or_else(|| panic!("no {key} in {r:?}"))
        .get(field)
        .and_then(Value::as_f64)
        .unwrap_or_else(|| panic!("{key}: no number {field} in {:?}", r[key]));
    assert!(v.is_finite(), "{key}.{field} = {v}");
    v
}

/// V, P and the stuck fraction of every tool: finite, forward, within the momentum identity's
/// bound |V| <= eps c_d (1 + n_F) / c_v (docs/physics.md §2.1), positive power.
fn crawls_forward(r: &serde_json::Map<String, Value>, case: &str, eps: f64) {
    let bound = eps * C_D * (1.0 + N_F) / C_V;
    for tool in ["exact", "ours", "mujoco", "pyelastica"] {
        let key = format!("{tool}/{case}");
        if tool != "exact" {
            assert_eq!(r[&key]["finite"], Value::Bool(true), "{key}: {:?}", r[&key]);
        }
        let v = num(r, &key, "velocity");
        assert!(v > 0.0 && v <= bound, "{key}: V = {v} m/s, bound {bound}");
        let p = num(r, &key, "power");
        assert!(p > 0.0, "{key}: P = {p} W");
        let stuck = num(r, &key, "stuck_fraction");
        assert!(
            (0.0..=1.0).contains(&stuck),
            "{key}: stuck fraction {stuck}"
        );
    }
}

#[test]
fn the_static_hold_is_exactly_at_rest_in_the_plant_and_the_peers_report_their_drift() {
    let r = quick("static");
    // a forward load of half the forward static band, no drive: the set-valued friction holds
    // every node, to the last bit
    assert_eq!(
        num(&r, "ours/static", "velocity"),
        0.0,
        "{:?}",
        r["ours/static"]
    );
    assert_eq!(num(&r, "exact/static", "velocity"), 0.0);
    for tool in ["mujoco", "pyelastica"] {
        let key = format!("{tool}/static");
        assert_eq!(r[&key]["finite"], Value::Bool(true), "{key}: {:?}", r[&key]);
        // a drift, if any, is a creep: far below the free drift speed the load alone would give
        // (load / c_v = 0.025 m/s), and never backwards by more than round-off
        let v = num(&r, &key, "velocity");
        assert!(v.abs() < 0.025 / C_V * 0.1, "{key}: drift {v} m/s");
        let u = num(&r, &key, "max_abs_displacement_end");
        assert!(u < 0.01, "{key}: moved {u} m in one second");
    }
}

#[test]
fn at_the_papers_point_every_tool_crawls_forward_within_the_speed_bound() {
    let r = quick("paper");
    crawls_forward(&r, "paper", 0.1);
    // resonance: the stress of the linear wave, f0 R0 alpha sqrt(alpha^2 + zeta^2) / A_c = 37.5
    // kPa, reached within a factor of two by every tool within its first second
    for tool in ["exact", "ours", "mujoco", "pyelastica"] {
        let key = format!("{tool}/paper");
        let s = num(&r, &key, "max_stress");
        assert!(
            s > 37.5e3 / 2.0 && s < 37.5e3 * 2.0,
            "{key}: sigma = {s} Pa"
        );
    }
}

#[test]
fn in_the_stick_slip_case_every_tool_crawls_forward_and_the_plant_sticks() {
    let r = quick("stickslip");
    crawls_forward(&r, "stickslip", 1.0);
    // long stick phases (43 % of node-time in the steady state): well under way after a second
    for key in ["exact/stickslip", "ours/stickslip"] {
        let stuck = num(&r, key, "stuck_fraction");
        assert!(stuck > 0.2, "{key}: stuck fraction {stuck}");
    }
}
