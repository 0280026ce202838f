//! The Python package `softcrawler` (python/, docs/python.md): it installs into the project's venv
//! from the repository with the README's command (`pip install ./python`, through
//! `scripts/setup-python.sh --package`), and its pytest suite passes against the programs of this
//! build; `crawler run --controller-cmd` starts a Python controller written with it and records
//! the run.

use std::process::Command;
use std::time::Duration;

use crawler_e2e::{bin, bin_dir, python, read_recording, repo_root, Proc, Run};

#[test]
fn the_package_installs_from_the_repository_and_its_pytest_suite_passes() {
    crawler_e2e::softcrawler();
    // the programs the suite compares with
    for b in ["crawler-plant", "crawler-controller", "crawler-sweep"] {
        bin(b);
    }
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(python())
        .args([
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "python/tests",
        ])
        .current_dir(repo_root())
        .env("CRAWLER_BIN_DIR", bin_dir())
        .env("XDG_RUNTIME_DIR", dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "pytest failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains(" passed"), "{stdout}");
    assert!(
        !stdout.contains("skipped"),
        "every test of the suite runs: {stdout}"
    );
}

#[test]
fn crawler_run_starts_a_python_controller_and_records_the_run() {
    crawler_e2e::softcrawler();
    let run = Run::new("pyctl");
    let rrd = run.path("py.rrd");
    let example = repo_root().join("examples/python_controller.py");
    let cmd = format!(
        "'{}' '{}' --f0 0.5 --alpha 0.5",
        python().display(),
        example.display()
    );
    let p = Proc::spawn(
        "crawler",
        &bin("crawler"),
        &[
            "run".into(),
            "--controller-cmd".into(),
            cmd,
            "--t-end".into(),
            "6".into(),
            "--cells".into(),
            "128".into(),
            "--out".into(),
            rrd.display().to_string(),
            "--run-id".into(),
            run.id.clone(),
        ],
        run.dir.path(),
    );
    let out = p.wait(Duration::from_secs(300));
    assert!(out.status.success(), "{}\n{}", out.stdout, out.stderr);
    assert!(
        out.stderr
            .contains("[controller] python-controller: answered"),
        "{}",
        out.stderr
    );
    // the plant's summary names the trajectory: the Rust wave policy's, bit for bit
    let local = {
        let mut s = crawler_physics::Scenario::paper();
        s.plant.numerics.cells = 128;
        s.t_end = 6.0;
        let w = s.wave;
        let omega = 0.5 * (w.k * s.plant.body.wave_speed());
        let s = s
            .with_wave(crawler_physics::Wave { omega, ..w }, None)
            .unwrap();
        crawler_physics::simulate::simulate(&s, Default::default()).unwrap()
    };
    assert!(
        out.stdout.contains(&local.state_digest),
        "state digest {} in {}",
        local.state_digest,
        out.stdout
    );
    let rec = read_recording(&rrd).unwrap();
    let last = local.macro_steps;
    assert_eq!(rec.entity("tail/plant").rows as u64, last + 1);
}
