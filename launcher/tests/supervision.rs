//! The one command fails fast and says why when one of its processes fails, and leaves nothing
//! behind (the full run is tested in tests/tests/launcher.rs).

use std::process::Command;
use std::time::Duration;

fn crawler_run(args: &[&str], cwd: &std::path::Path) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_crawler"))
        .arg("run")
        .args(args)
        .current_dir(cwd)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run crawler");
    // Bounded: a launcher that waits for a failed process must not hang the test suite.
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    while child.try_wait().expect("wait").is_none() {
        if std::time::Instant::now() > deadline {
            let _ = child.kill();
            panic!("crawler run {args:?} did not stop after a process failed");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().expect("output");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_failing_process_stops_the_run_with_its_reason() {
    let dir = tempfile::tempdir().unwrap();
    let id = format!("sup-{}", std::process::id());
    let out = dir.path().join("x.rrd").display().to_string();
    let cases: [(&[&str], &str, &str); 3] = [
        (&["--t-end=-1"], "plant", "invalid numerics.t_end = -1"),
        (
            &["--policy", "nosuch"],
            "controller",
            "unknown policy \"nosuch\"",
        ),
        (&["--every", "0"], "bridge", "invalid --every = 0"),
    ];
    for (i, (args, who, why)) in cases.into_iter().enumerate() {
        let run_id = format!("{id}-{i}");
        let mut a = vec!["--run-id", &run_id, "--out", &out];
        a.extend_from_slice(args);
        let (code, err) = crawler_run(&a, dir.path());
        assert_eq!(code, Some(1), "{args:?}: {err}");
        assert!(err.contains(why), "{args:?}: {err}");
        assert!(
            err.contains(&format!("the {who} failed")),
            "{args:?}: {err}"
        );
        // the error chain is printed once, not repeated
        assert_eq!(err.matches(why).count(), 1, "{args:?}: {err}");
    }
    // nothing was simulated, so no checkpoint was left in the working directory
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".ckpt"))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}
