//! What the README shows is what the code is: the example controller is the real `pulse` policy
//! and its registration line, every registered policy is listed, and the example runs.

use std::time::Duration;

use crawler_e2e::{bin, repo_root, simulate, Run};

fn squeeze(s: &str) -> String {
    s.chars()
        .filter(|c| !c.is_whitespace() && *c != ',')
        .collect()
}

fn readme() -> String {
    std::fs::read_to_string(repo_root().join("README.md")).unwrap()
}

#[test]
fn readme_shows_the_real_example_controller_and_its_registration() {
    let readme = squeeze(&readme());
    let file = std::fs::read_to_string(repo_root().join("policies/src/pulse.rs")).unwrap();
    assert!(
        readme.contains(&squeeze(&file)),
        "README.md must show policies/src/pulse.rs as it is"
    );
    let registry = std::fs::read_to_string(repo_root().join("policies/src/registry.rs")).unwrap();
    let entry = r#"Entry {
        name: "pulse",
        help: "the scenario's wave, on and off every second",
        keys: &[],
        build: crate::pulse::build,
        check: None,
    },"#;
    assert!(readme.contains(&squeeze(entry)));
    assert!(squeeze(&registry).contains(&squeeze(entry)));
}

#[test]
fn every_registered_policy_is_in_the_readme() {
    let out = std::process::Command::new(bin("crawler-controller"))
        .arg("policies")
        .output()
        .unwrap();
    assert!(out.status.success());
    let listed = String::from_utf8_lossy(&out.stdout).to_string();
    let readme = readme();
    for name in ["optimal", "wave", "resonance", "sweep", "pulse"] {
        assert!(listed.contains(name), "policies: {listed}");
        assert!(
            readme.contains(&format!("`{name}`")),
            "README misses {name}"
        );
    }
}

#[test]
fn the_example_controller_drives_a_cosimulation() {
    let run = Run::new("pulse");
    let plant = run.plant(&["--t-end", "8", "--json"]);
    let ctl = run.controller(&["--policy", "pulse"]);
    let p = plant.wait(Duration::from_secs(120));
    let c = ctl.wait(Duration::from_secs(30));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    let report: serde_json::Value = serde_json::from_str(&p.stdout).unwrap();
    // The actuation changes every second, so no steady window: run averages after 5 s, said so.
    assert_eq!(report["window"]["steady"], false, "{report}");
    assert!(
        c.stdout.contains("run averages"),
        "controller: {}",
        c.stdout
    );
    // Driven part of the time: it crawls forwards, slower than under the wave all along.
    let pulse = report["velocity"].as_f64().unwrap();
    let wave = simulate(&["--t-end", "8"])["velocity"].as_f64().unwrap();
    assert!(
        pulse > 0.2 * wave && pulse < 0.9 * wave,
        "pulse {pulse} m/s, wave {wave} m/s"
    );
    // The window is contiguous: the discrete momentum balance still holds to round-off.
    assert!(
        report["momentum_residual"].as_f64().unwrap() < 1e-9,
        "{report}"
    );
}
