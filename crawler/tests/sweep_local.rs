//! The local executor end to end with the real binary: results, Parquet read by pyarrow,
//! determinism across worker counts, resume after Ctrl-C, shared points, input validation.

mod common;

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::*;

/// Four points: sliding and sticking, off and at resonance (k = 2 pi, one wavelength, coarse:
/// 64 and 128 cells).
const FOUR: &str = r#"
[set]
numerics.cells = 64
numerics.settle = 1.5
numerics.t_end = 3.0

[[axes]]
key = "friction.eps"
values = [0.1, 1.0]

[[axes]]
key = "actuation.alpha"
values = [0.5, 1.0]

[evaluate]
plant = true
models = ["paper", "improved"]
"#;

#[test]
fn a_local_sweep_writes_a_parquet_file_that_pyarrow_reads_and_that_checks_out() {
    let dir = tempfile::tempdir().unwrap();
    let plan = write_plan(dir.path(), "four", FOUR);
    let out = dir.path().join("four.parquet");
    let o = sweep(
        dir.path(),
        &[
            plan.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--store",
            "store",
            "--jobs",
            "2",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("4 points, 0 stored, 4 to run"),
        "{}",
        stderr(&o)
    );
    assert_eq!(stored(&dir.path().join("store")), 4);

    // read back by pyarrow, and checked against formulas computed in Python
    let py = Command::new(python())
        .arg(repo_root().join("crawler/tests/check_parquet.py"))
        .arg(&out)
        .arg("4")
        .output()
        .unwrap();
    assert!(
        py.status.success(),
        "pyarrow check failed:\n{}{}",
        String::from_utf8_lossy(&py.stdout),
        String::from_utf8_lossy(&py.stderr)
    );

    // physics: at eps = 0.1 on resonance (row 1) the paper's speed holds within 1 %; the
    // improved model's speed and power are within 1 % at the sliding points
    let b = read_parquet(&out);
    let e = f64s(&b, "paper.velocity.error");
    assert!(
        e[1].unwrap().abs() < 0.01,
        "paper V at resonance: {:?}",
        e[1]
    );
    for m in ["velocity", "power"] {
        let e = f64s(&b, &format!("improved.{m}.error"));
        for row in [0, 1] {
            assert!(
                e[row].unwrap().abs() < 0.01,
                "improved {m} row {row}: {:?}",
                e[row]
            );
        }
    }
    // the convergence estimate is reported and small at the sliding points
    let c = f64s(&b, "plant.power.conv_error");
    assert!(c[0].unwrap() < 0.02 && c[0].unwrap() > 0.0, "{:?}", c[0]);

    // a second run finds everything stored, runs nothing and writes the same file byte for byte
    let before = std::fs::read(&out).unwrap();
    let o = sweep(
        dir.path(),
        &[
            plan.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--store",
            "store",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("4 points, 4 stored, 0 to run"),
        "{}",
        stderr(&o)
    );
    assert_eq!(
        std::fs::read(&out).unwrap(),
        before,
        "a resumed complete sweep rewrites the same file"
    );
}

#[test]
fn results_do_not_depend_on_the_number_of_workers() {
    let dir = tempfile::tempdir().unwrap();
    let plan = write_plan(dir.path(), "four", FOUR);
    for (jobs, store) in [("1", "s1"), ("2", "s2")] {
        let o = sweep(
            dir.path(),
            &[
                plan.to_str().unwrap(),
                "--out",
                &format!("{store}.parquet"),
                "--store",
                store,
                "--jobs",
                jobs,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    assert_same_results(
        &dir.path().join("s1.parquet"),
        &dir.path().join("s2.parquet"),
    );
}

/// Twelve points of about equal cost (about 0.3 s each).
const TWELVE: &str = r#"
[set]
numerics.cells = 1024
numerics.settle = 2.0
numerics.t_end = 3.0
friction.eps = 0.5
actuation.k = 25.132741228718345

[[axes]]
key = "actuation.alpha"
linspace = { start = 0.6, stop = 1.7, num = 12 }

[evaluate]
plant = true
convergence = false
models = ["improved"]
"#;

#[test]
fn an_interrupted_sweep_keeps_its_finished_points_and_resumes_with_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let plan = write_plan(dir.path(), "twelve", TWELVE);
    let store = dir.path().join("store");
    let mut child = Command::new(sweep_bin())
        .args([
            plan.to_str().unwrap(),
            "--out",
            "twelve.parquet",
            "--store",
            "store",
            "--jobs",
            "1",
        ])
        .current_dir(dir.path())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    while stored(&store) < 2 {
        assert!(Instant::now() < deadline, "no points stored within 60 s");
        assert!(
            child.try_wait().unwrap().is_none(),
            "finished before the interrupt"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let deadline = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("no exit within 30 s of Ctrl-C");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut err).unwrap();
    assert_eq!(status.code(), Some(130), "{err}");
    assert!(
        err.contains("run the same command again to resume"),
        "{err}"
    );
    let kept = stored(&store);
    assert!((2..12).contains(&kept), "{kept} points kept");
    assert!(
        !dir.path().join("twelve.parquet").exists(),
        "no table of a partial sweep"
    );

    // the rerun runs exactly the missing points
    let o = sweep(
        dir.path(),
        &[
            plan.to_str().unwrap(),
            "--out",
            "twelve.parquet",
            "--store",
            "store",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let want = format!("12 points, {kept} stored, {} to run", 12 - kept);
    assert!(stderr(&o).contains(&want), "{want}: {}", stderr(&o));
    assert!(
        stderr(&o).contains(&format!("{} points evaluated", 12 - kept)),
        "{}",
        stderr(&o)
    );

    // and the result is the one an uninterrupted sweep gives
    let o = sweep(
        dir.path(),
        &[
            plan.to_str().unwrap(),
            "--out",
            "fresh.parquet",
            "--store",
            "fresh",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_same_results(
        &dir.path().join("twelve.parquet"),
        &dir.path().join("fresh.parquet"),
    );
}

#[test]
fn plans_that_share_points_share_results_and_the_convergence_estimate_tracks_the_true_error() {
    // eps = 0: the linear crawler, whose exact steady power is the paper's formula, so the
    // paper's power error is the plant's true discretisation error; settle 3 s leaves a
    // transient of exp(-15)
    const BASE: &str = "[set]\nnumerics.settle = 3.0\nnumerics.t_end = 4.0\nfriction.eps = 0.0\nactuation.alpha = 0.7\n";
    let dir = tempfile::tempdir().unwrap();
    let a = write_plan(
        dir.path(),
        "a",
        &format!("{BASE}[[axes]]\nkey = \"numerics.cells\"\nvalues = [32, 64]\n[evaluate]\nplant = true\nmodels = [\"paper\"]\n"),
    );
    let o = sweep(
        dir.path(),
        &[
            a.to_str().unwrap(),
            "--store",
            "store",
            "--out",
            "a.parquet",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // b reaches the point cells = 64 again (under another plan name) and adds cells = 128
    let b = write_plan(
        dir.path(),
        "b",
        &format!("{BASE}[[axes]]\nkey = \"numerics.cells\"\nvalues = [64, 128]\n[evaluate]\nplant = true\nmodels = [\"paper\"]\n"),
    );
    let o = sweep(
        dir.path(),
        &[
            b.to_str().unwrap(),
            "--store",
            "store",
            "--out",
            "b.parquet",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("2 points, 1 stored, 1 to run"),
        "{}",
        stderr(&o)
    );
    let (ta, tb) = (
        read_parquet(&dir.path().join("a.parquet")),
        read_parquet(&dir.path().join("b.parquet")),
    );
    assert_eq!(
        f64s(&ta, "plant.power")[1].unwrap().to_bits(),
        f64s(&tb, "plant.power")[0].unwrap().to_bits()
    );
    // reported runs at 128 and 256 cells (same Courant number 0.757): second order, and the
    // estimate |P(2N) - P(N)| / P(2N) is three times the true error of P(2N), as it must be
    let truth: Vec<f64> = f64s(&tb, "paper.power.error")
        .iter()
        .map(|e| e.unwrap().abs())
        .collect();
    let est: Vec<f64> = f64s(&tb, "plant.power.conv_error")
        .iter()
        .map(|e| e.unwrap())
        .collect();
    let order = truth[0] / truth[1];
    assert!(
        (3.6..4.4).contains(&order),
        "true error ratio {order} ({truth:?})"
    );
    for i in 0..2 {
        let r = est[i] / truth[i];
        assert!(
            (2.7..3.3).contains(&r),
            "estimate / true error = {r} at row {i} ({est:?} vs {truth:?})"
        );
    }
}

#[test]
fn a_policy_in_closed_loop_equals_the_plant_under_the_same_wave() {
    let dir = tempfile::tempdir().unwrap();
    let plan = write_plan(
        dir.path(),
        "pol",
        r#"
[set]
numerics.cells = 64
numerics.settle = 1.0
numerics.t_end = 2.0
friction.eps = 1.0
actuation.f0 = 0.2
[[axes]]
key = "actuation.alpha"
values = [0.5, 1.2]
[evaluate]
plant = true
convergence = false
policy = { name = "wave" }
"#,
    );
    let o = sweep(
        dir.path(),
        &[
            plan.to_str().unwrap(),
            "--store",
            "store",
            "--out",
            "p.parquet",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let t = read_parquet(&dir.path().join("p.parquet"));
    // the in-process lockstep is the co-simulation's; under the scenario's own wave it is the
    // plant's run, bit for bit
    for m in ["velocity", "power", "max_stress", "stuck_fraction"] {
        let (a, b) = (
            f64s(&t, &format!("plant.{m}")),
            f64s(&t, &format!("policy.{m}")),
        );
        for r in 0..2 {
            assert_eq!(
                a[r].unwrap().to_bits(),
                b[r].unwrap().to_bits(),
                "{m} row {r}"
            );
        }
    }
    assert!(
        f64s(&t, "plant.stuck_fraction")[0].unwrap() > 0.05,
        "a sticking point"
    );
}

#[test]
fn a_sweep_reports_each_runs_task_outcome_and_a_stress_limit_broken_is_not_a_success() {
    let dir = tempfile::tempdir().unwrap();
    // the same run twice but for the stress limit: far above the run's stress, then below it
    let plan = write_plan(
        dir.path(),
        "task",
        r#"
[set]
numerics.cells = 64
numerics.settle = 1.0
numerics.t_end = 2.0
task.distance = 0.01
task.energy = 100.0
[[axes]]
key = "task.sigma_max"
values = [1e9, 1.0]
[evaluate]
plant = true
convergence = false
policy = { name = "wave" }
"#,
    );
    let o = sweep(
        dir.path(),
        &[
            plan.to_str().unwrap(),
            "--store",
            "store",
            "--out",
            "t.parquet",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let t = read_parquet(&dir.path().join("t.parquet"));
    for who in ["plant", "policy"] {
        let outcome = strs(&t, &format!("{who}.task.outcome"));
        assert_eq!(outcome[0].as_deref(), Some("reached"), "{who}");
        assert_eq!(outcome[1].as_deref(), Some("stress exceeded"), "{who}");
        let reached = f64s(&t, &format!("{who}.task.time_to_distance"));
        let exceeded = f64s(&t, &format!("{who}.task.stress_exceeded_at"));
        let over = f64s(&t, &format!("{who}.task.time_over_sigma_max"));
        let distance = f64s(&t, &format!("{who}.task.distance"));
        // the limit does not change the run: the distance is reached at the same time in both
        assert_eq!(reached[0], reached[1], "{who}");
        assert!(distance[0].unwrap() >= 0.01, "{who}: {distance:?}");
        assert_eq!(exceeded[0], None, "{who}");
        assert_eq!(over[0], Some(0.0), "{who}");
        // above 1 Pa from the first step that stresses the body: exceeded at once (no tolerance),
        // before the distance was reached
        assert!(
            exceeded[1].unwrap() < reached[1].unwrap(),
            "{who}: {exceeded:?}"
        );
        assert!(
            over[1].unwrap() > 0.5 * reached[1].unwrap(),
            "{who}: {over:?}"
        );
    }
    // the wave policy's run is the plant's under the same wave: the same task, bit for bit
    for c in [
        "distance",
        "time_to_distance",
        "energy_used",
        "max_stress",
        "time_over_sigma_max",
    ] {
        let (a, b) = (
            f64s(&t, &format!("plant.task.{c}")),
            f64s(&t, &format!("policy.task.{c}")),
        );
        assert_eq!(
            a.iter().map(|x| x.map(f64::to_bits)).collect::<Vec<_>>(),
            b.iter().map(|x| x.map(f64::to_bits)).collect::<Vec<_>>(),
            "{c}"
        );
    }
}

#[test]
fn bad_plans_and_points_are_refused_with_the_field_and_nothing_is_overwritten() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("keep.parquet"), b"precious").unwrap();
    let cases = [
        (
            "[[axes]]\nkey = \"friction.eps\"\nlinspace = { start = 0.0, stop = 1.0, num = -3 }\n[evaluate]\nplant = true\n",
            "axes[0].linspace.num = -3: allowed 1 <= num <= 100000",
        ),
        (
            "[[axes]]\nkey = \"friction.n_f\"\nvalues = [0.5, 2.0]\n[evaluate]\nplant = true\n",
            "point 1 (friction.n_f = 2.0)",
        ),
        (
            "[[axes]]\nkey = \"actuation.alpha\"\nvalues = [\"fast\"]\n[evaluate]\nplant = true\n",
            "actuation.alpha",
        ),
        ("[evaluate]\nmodels = [\"paper\"]\nplant = \"yes\"\n", "invalid type"),
    ];
    for (i, (body, needle)) in cases.iter().enumerate() {
        let plan = write_plan(dir.path(), &format!("bad{i}"), body);
        let o = sweep(
            dir.path(),
            &[
                plan.to_str().unwrap(),
                "--out",
                "keep.parquet",
                "--store",
                "store",
            ],
        );
        assert_eq!(o.status.code(), Some(1), "{body}");
        assert!(
            stderr(&o).contains(needle),
            "{needle:?} not in {}",
            stderr(&o)
        );
        assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
    }
    assert_eq!(
        std::fs::read(dir.path().join("keep.parquet")).unwrap(),
        b"precious"
    );
    let o = sweep(dir.path(), &["missing.toml"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("cannot read plan missing.toml"),
        "{}",
        stderr(&o)
    );
    let o = sweep(
        dir.path(),
        &[
            dir.path().join("bad0.toml").to_str().unwrap(),
            "--jobs",
            "0",
        ],
    );
    assert_eq!(o.status.code(), Some(1));
}
