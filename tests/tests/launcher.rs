//! The one command: `crawler run` starts plant, controller and bridge and leaves a recording.

use std::time::Duration;

use crawler_e2e::{bin, read_recording, Proc, Run};

#[test]
fn one_command_runs_the_whole_cosimulation() {
    let run = Run::new("launch");
    let rrd = run.path("crawler.rrd");
    let p = Proc::spawn(
        "crawler",
        &bin("crawler"),
        &[
            "run".into(),
            "--t-end".into(),
            "6".into(),
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
        out.stdout.contains("velocity V") && out.stdout.contains("improved"),
        "summary of predicted against simulated: {}",
        out.stdout
    );
    assert!(
        out.stdout.contains("state digest"),
        "the plant's summary: {}",
        out.stdout
    );
    let rec = read_recording(&rrd).unwrap();
    // one row per communication point 0..=last, the last at or after t = 6 s
    let last = crawler_plant::Scenario::paper()
        .plant
        .discretisation()
        .unwrap()
        .steps_until(6.0);
    assert_eq!(rec.entity("tail/plant").rows as u64, last + 1);
    assert!(rec.entity("summary/velocity").scalars[0] > 0.0);
}

#[test]
fn bad_flags_give_clear_errors_and_nonzero_exit() {
    let check = |exe: &str, args: &[&str], needle: &str| {
        let out = std::process::Command::new(bin(exe))
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{exe} {args:?} should fail");
        assert!(err.contains(needle), "{exe} {args:?}: {err}");
    };
    check("crawler-plant", &["simulate", "--n-f", "2"], "friction.n_f");
    check(
        "crawler-plant",
        &["simulate", "--eps", "nan"],
        "friction.eps",
    );
    check(
        "crawler-plant",
        &["simulate", "--cells", "2"],
        "numerics.cells",
    );
    check(
        "crawler-plant",
        &["simulate", "--omega", "0"],
        "actuation.omega",
    );
    check(
        "crawler-plant",
        &["simulate", "--t-end", "2"],
        "numerics.t_end",
    );
    check(
        "crawler-plant",
        &["simulate", "--scenario", "/nonexistent.toml"],
        "cannot read scenario",
    );
    check(
        "crawler-plant",
        &["run", "--endpoint", "tcp/0.0.0.0:7447"],
        "--endpoint",
    );
    check("crawler-plant", &["run", "--run-id", "a/b"], "run_id");
    check(
        "crawler-plant",
        &["run", "--resume", "/nonexistent.ckpt"],
        "checkpoint",
    );
    check(
        "crawler-controller",
        &["optimize", "--energy", "-5"],
        "task.energy",
    );
    check(
        "crawler-controller",
        &["optimize", "--omega-range", "300,10"],
        "limits.omega",
    );
    check(
        "crawler-controller",
        &["optimize", "--energy", "0.000001"],
        "mileage",
    );
    check(
        "crawler-controller",
        &["predict", "--model", "magic"],
        "unknown model",
    );
    check(
        "crawler-controller",
        &["run", "--policy", "nope", "--wait-timeout", "1"],
        "no plant answered",
    );
    check("crawler-bridge", &["record", "--every", "0"], "--every");
}
