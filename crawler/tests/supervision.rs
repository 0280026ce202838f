//! The one command fails fast and says why when one of its processes fails, and leaves nothing
//! behind (the full run is tested in tests/tests/launcher.rs).

use std::process::Command;
use std::time::Duration;

fn crawler_run(args: &[&str], cwd: &std::path::Path) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_crawler"))
        // the binaries under test, not a `cargo run` that would rebuild them
        .env_remove("CARGO")
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
    // refused before anything starts: by the program that owns the input, or by the launcher
    let cases: [(&[&str], &str, &str); 3] = [
        (
            &["--t-end=-1"],
            "the plant refused its inputs",
            "(numerics.t_end) = -1",
        ),
        (
            &["--policy", "nosuch"],
            "the controller refused its inputs",
            "unknown policy \"nosuch\"",
        ),
        (&["--every", "0"], "crawler: error", "invalid --every = 0"),
    ];
    for (i, (args, who, why)) in cases.into_iter().enumerate() {
        let run_id = format!("{id}-{i}");
        let mut a = vec!["--run-id", &run_id, "--out", &out];
        a.extend_from_slice(args);
        let (code, err) = crawler_run(&a, dir.path());
        assert_eq!(code, Some(1), "{args:?}: {err}");
        assert!(err.contains(why), "{args:?}: {err}");
        assert!(err.contains(who), "{args:?}: {err}");
        assert!(
            !err.contains("recorder, plant and controller on loopback"),
            "{args:?} started the run: {err}"
        );
        // the error chain is printed once, not repeated
        assert_eq!(err.matches(why).count(), 1, "{args:?}: {err}");
    }
    assert!(
        !dir.path().join("x.rrd").exists(),
        "a recording was created"
    );
    // nothing was simulated, so no checkpoint was left in the working directory
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".ckpt"))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn ctrl_c_stops_every_process_cleanly_and_the_run_resumes() {
    use std::io::{BufRead, BufReader};
    let dir = tempfile::tempdir().unwrap();
    let run_id = format!("sigint-{}", std::process::id());
    let mut child = Command::new(env!("CARGO_BIN_EXE_crawler"))
        // the binaries under test, not a `cargo run` that would rebuild them
        .env_remove("CARGO")
        .args([
            "run", "--run-id", &run_id, "--t-end", "30", "--out", "x.rrd",
        ])
        .current_dir(dir.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run crawler");
    // Read stderr on a thread; the test waits for the plant to start stepping.
    let (tx, rx) = std::sync::mpsc::channel();
    let err = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut all = String::new();
        for line in BufReader::new(err).lines().map_while(Result::ok) {
            let _ = tx.send(line.clone());
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    let started = loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        match rx.recv_timeout(left) {
            Ok(line) if line.contains("joined run") => break true,
            Ok(_) => {}
            Err(_) => break false,
        }
    };
    if !started {
        let _ = child.kill();
        panic!("the plant never started stepping");
    }
    let _ = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    while child.try_wait().expect("wait").is_none() {
        if std::time::Instant::now() > deadline {
            let _ = child.kill();
            panic!("crawler run did not stop after Ctrl-C");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let status = child.wait().unwrap();
    let err = reader.join().unwrap();
    assert_eq!(status.code(), Some(130), "{err}");
    assert!(
        err.contains("crawler: interrupted; stopping the run"),
        "{err}"
    );
    assert!(
        err.contains("[plant] crawler-plant: run stopped: interrupted at step"),
        "{err}"
    );
    // The recorder closes its file whether it sees the plant's stop first ("run finished;
    // recording closed x.rrd") or its own SIGINT first ("interrupted; recording closed properly
    // x.rrd"); which comes first is a race between processes, and both are a clean close.
    assert!(
        err.lines()
            .any(|l| l.starts_with("[recorder] crawler-recorder: ")
                && (l.contains("run finished; recording closed x.rrd")
                    || l.contains("interrupted; recording closed properly x.rrd"))),
        "{err}"
    );
    let ckpt = dir.path().join("runs").join(&run_id).join("plant.ckpt");
    assert!(ckpt.is_file(), "no checkpoint: {err}");
    let rrd = std::fs::metadata(dir.path().join("x.rrd")).expect("recording");
    assert!(rrd.len() > 0);

    // The one command continues the run from the checkpoint to the original end.
    let ckpt = ckpt.display().to_string();
    let id2 = format!("{run_id}-resumed");
    let args = ["--resume", &ckpt, "--run-id", &id2, "--out", "y.rrd"];
    let mut child = Command::new(env!("CARGO_BIN_EXE_crawler"))
        // the binaries under test, not a `cargo run` that would rebuild them
        .env_remove("CARGO")
        .arg("run")
        .args(args)
        .current_dir(dir.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run crawler");
    let deadline = std::time::Instant::now() + Duration::from_secs(120);
    while child.try_wait().expect("wait").is_none() {
        if std::time::Instant::now() > deadline {
            let _ = child.kill();
            panic!("the resumed run did not finish");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = child.wait_with_output().unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    // to the original end: the first communication point at or after t = 30 s, as announced
    let last = stderr
        .split("communication point at or after t_end = 30 s (")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|n| n.parse::<u64>().ok())
        .unwrap_or_else(|| panic!("no end announced: {stderr}"));
    assert!((30_000..30_400).contains(&last), "{last}");
    assert!(
        stderr.contains(&format!("stepping to step {last}")),
        "{stderr}"
    );
    assert!(stdout.contains("velocity V"), "{stdout}");
}
