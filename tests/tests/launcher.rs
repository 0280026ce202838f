//! The one command: `crawler run` starts plant, controller and bridge and leaves a recording.

use std::time::{Duration, Instant};

use crawler_e2e::{bin, read_recording, Proc, Run};

/// `crawler ARGS` in the run's directory, its own process group (as a shell runs a job).
fn launcher(run: &Run, args: &[&str]) -> std::process::Child {
    use std::os::unix::process::CommandExt;
    let mut args: Vec<String> = args.iter().map(|s| s.to_string()).collect();
    args.extend(["--run-id".into(), run.id.clone()]);
    std::process::Command::new(bin("crawler"))
        .arg("run")
        .args(&args)
        .current_dir(run.dir.path())
        .env_remove("CARGO")
        // the run's private directory where the test's other processes have it
        .env("XDG_RUNTIME_DIR", run.dir.path())
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::fs::File::create(run.path("launcher.err")).unwrap())
        .process_group(0)
        .spawn()
        .unwrap()
}

/// Waits at most `timeout` for `child`; kills its whole process group if it does not end.
fn wait_group(run: &Run, child: &mut std::process::Child, timeout: Duration) -> Option<i32> {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s.code();
        }
        if Instant::now() > deadline {
            // the launcher's group, and its children (each in its own group) by their run id
            let _ = std::process::Command::new("kill")
                .args(["-KILL", "--", &format!("-{}", child.id())])
                .status();
            let _ = std::process::Command::new("pkill")
                .args(["-KILL", "-f", &run.id])
                .status();
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "crawler run did not end within {timeout:?}: {}",
                std::fs::read_to_string(run.path("launcher.err")).unwrap_or_default()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_refused_start_leaves_an_existing_recording_untouched() {
    let run = Run::new("keep");
    let keep = run.path("keep.rrd");
    let bytes: Vec<u8> = (0..100_000u32).map(|i| (i % 251) as u8).collect();
    std::fs::write(&keep, &bytes).unwrap();
    let out = keep.display().to_string();
    for (args, needle) in [
        (vec!["--policy", "nosuch"], "unknown policy \"nosuch\""),
        (vec!["--cells", "3"], "numerics.cells"),
        // above the one cell limit: refused up front, not after 90 s of "invalid model description"
        (vec!["--cells", "10000000"], "numerics.cells"),
        (vec!["--t-end", "0"], "t_end"),
        (vec!["--resume", "/nonexistent.ckpt"], "checkpoint"),
        (vec!["--every", "0"], "--every"),
        // the recorder's inputs are checked before the plant starts, as the others' are
        (vec!["--view-url", "notaurl"], "invalid --connect = notaurl"),
        (
            vec!["--scenario", "/nonexistent.toml"],
            "cannot read scenario",
        ),
    ] {
        let mut all = args.clone();
        all.extend(["--out", &out]);
        let mut child = launcher(&run, &all);
        let code = wait_group(&run, &mut child, Duration::from_secs(60));
        let err = std::fs::read_to_string(run.path("launcher.err")).unwrap();
        assert_ne!(code, Some(0), "{args:?} should fail: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(
            !err.contains("recorder, plant and controller on loopback"),
            "{args:?} started processes: {err}"
        );
        assert_eq!(
            std::fs::read(&keep).unwrap(),
            bytes,
            "{args:?} touched the recording"
        );
    }
    // a directory is not a recording
    let mut child = launcher(&run, &["--out", &run.dir.path().display().to_string()]);
    assert_ne!(
        wait_group(&run, &mut child, Duration::from_secs(60)),
        Some(0)
    );
    let err = std::fs::read_to_string(run.path("launcher.err")).unwrap();
    assert!(
        err.contains("invalid --out") && err.contains("directory"),
        "{err}"
    );
}

#[test]
fn ctrl_c_in_a_terminal_stops_the_run_and_exits_130() {
    let run = Run::new("ctrlc");
    let rrd = run.path("c.rrd");
    let out = rrd.display().to_string();
    let mut child = launcher(&run, &["--policy", "wave", "--t-end", "600", "--out", &out]);
    // wait until the run is stepping
    let t0 = Instant::now();
    let err = || std::fs::read_to_string(run.path("launcher.err")).unwrap_or_default();
    while !err().contains("joined run") {
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "the run did not start: {}",
            err()
        );
        assert!(
            child.try_wait().unwrap().is_none(),
            "ended early: {}",
            err()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_millis(500));
    // SIGINT to the whole foreground process group, as a terminal's Ctrl-C does
    let pgid = child.id();
    assert!(std::process::Command::new("kill")
        .args(["-INT", "--", &format!("-{pgid}")])
        .status()
        .unwrap()
        .success());
    let code = wait_group(&run, &mut child, Duration::from_secs(90));
    let e = err();
    assert_eq!(code, Some(130), "{e}");
    assert!(e.contains("crawler: interrupted"), "{e}");
    assert!(!e.contains("failed"), "{e}");
    // the plant wrote its checkpoint; the recording is readable and holds the run so far
    assert!(
        run.path(&format!("runs/{}/plant.ckpt", run.id)).is_file(),
        "no checkpoint: {e}"
    );
    let rec = read_recording(&rrd).unwrap();
    assert!(rec.entity("tail/plant").rows > 10);
}

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
            "--every".into(),
            "1".into(),
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
    let last = crawler_physics::Scenario::paper()
        .plant
        .discretisation()
        .unwrap()
        .steps_until(6.0);
    assert_eq!(rec.entity("tail/plant").rows as u64, last + 1);
    assert!(rec.entity("summary/velocity").scalars[0] > 0.0);
    // every state's fields, and the recorder says so
    for path in ["fields/u", "fields/v", "fields/tension", "body/segments"] {
        assert_eq!(rec.entity(path).rows as u64, last + 1, "{path}");
    }
    assert!(
        out.stderr.contains(&format!(
            "{0} states ({0} with fields): every state's fields recorded",
            last + 1
        )),
        "{}",
        out.stderr
    );
    // nothing of the run refused (what the plant sent before the recorder found it is said apart)
    assert!(
        out.stderr
            .contains("0 rejected (0 invalid), 0 refused at arrival"),
        "{}",
        out.stderr
    );
    // chunks Rerun likes: at most twice the lower bound of its object-store profile
    let (chunks, bound) = chunks_and_lower_bound(&rrd);
    assert!(
        chunks <= 2 * bound,
        "{chunks} chunks, lower bound {bound}: {}",
        out.stderr
    );
}

/// The chunks of the recording at `rrd` (not the layout's) and their lower bound as Rerun's
/// `rrd stats` counts it: the chunks of each entity's column set merged up to 2 MiB and 65 536
/// rows (its object-store profile), at least one each.
fn chunks_and_lower_bound(rrd: &std::path::Path) -> (u64, u64) {
    use rerun::dataframe::external::re_chunk_store::{ChunkStore, ChunkStoreConfig};
    use rerun::SizeBytes;
    let file = std::fs::File::open(rrd).unwrap();
    let stores = ChunkStore::from_rrd_reader(
        &ChunkStoreConfig::ALL_DISABLED,
        &mut std::io::BufReader::new(file),
    )
    .unwrap();
    let mut groups: std::collections::BTreeMap<String, (u64, u64)> = Default::default();
    let mut chunks = 0;
    for (id, store) in &stores {
        if !id.is_recording() {
            continue;
        }
        for c in store.iter_physical_chunks() {
            if c.is_static() {
                continue;
            }
            chunks += 1;
            let mut columns: Vec<String> = c.components().keys().map(|k| k.to_string()).collect();
            columns.sort();
            let g = groups
                .entry(format!("{}|{}", c.entity_path(), columns.join(",")))
                .or_default();
            g.0 += c.heap_size_bytes();
            g.1 += c.num_rows() as u64;
        }
    }
    let bound = groups
        .values()
        .map(|&(bytes, rows)| bytes.div_ceil(2 << 20).max(rows.div_ceil(65_536)).max(1))
        .sum();
    (chunks, bound)
}

#[test]
fn the_recorder_checks_its_inputs_without_creating_anything() {
    let run = Run::new("recorder-check");
    let out = run.path("x.rrd");
    let check = |extra: &[&str]| {
        std::process::Command::new(bin("crawler-recorder"))
            .args([
                "record",
                "--no-auth",
                "--check",
                "--run-id",
                &run.id,
                "--out",
            ])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap()
    };
    let ok = check(&[]);
    let err = String::from_utf8_lossy(&ok.stderr);
    assert!(ok.status.success(), "{err}");
    assert!(err.contains("inputs valid"), "{err}");
    let bad = check(&["--connect", "notaurl"]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success());
    assert!(err.contains("invalid --connect = notaurl"), "{err}");
    // nothing written next to --out: no recording, no temporary twin
    let left: Vec<_> = std::fs::read_dir(run.dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("x.rrd"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// Bad flags and what each one's error must say: (program, arguments, text of the error).
const BAD_FLAGS: &[(&str, &[&str], &str)] = &[
    ("crawler-plant", &["simulate", "--n-f", "2"], "friction.n_f"),
    (
        "crawler-plant",
        &["simulate", "--eps", "nan"],
        "friction.eps",
    ),
    (
        "crawler-plant",
        &["simulate", "--cells", "2"],
        "numerics.cells",
    ),
    (
        "crawler-plant",
        &["simulate", "--omega", "0"],
        "actuation.omega",
    ),
    (
        "crawler-plant",
        &["simulate", "--t-end", "2"],
        "numerics.t_end",
    ),
    (
        "crawler-plant",
        &["simulate", "--scenario", "/nonexistent.toml"],
        "cannot read scenario",
    ),
    (
        "crawler-plant",
        &["run", "--endpoint", "tcp/0.0.0.0:7447"],
        "--endpoint",
    ),
    ("crawler-plant", &["run", "--run-id", "a/b"], "run_id"),
    (
        "crawler-plant",
        &["run", "--resume", "/nonexistent.ckpt"],
        "checkpoint",
    ),
    // a checkpoint the plant could not write when the run stops (it was said to be valid)
    (
        "crawler-plant",
        &[
            "run",
            "--no-auth",
            "--check",
            "--checkpoint",
            "/proc/1/nope/x.ckpt",
        ],
        "invalid --checkpoint = /proc/1/nope/x.ckpt: the directory /proc/1 is read-only",
    ),
    (
        "crawler-controller",
        &["optimize", "--energy", "-5"],
        "task.energy",
    ),
    (
        "crawler-controller",
        &["optimize", "--omega-range", "300,10"],
        "limits.omega",
    ),
    (
        "crawler-controller",
        &["optimize", "--energy", "0.000001"],
        "mileage",
    ),
    (
        "crawler-controller",
        &["predict", "--model", "magic"],
        "unknown model",
    ),
    (
        "crawler-controller",
        &["run", "--policy", "nope", "--wait-timeout", "1"],
        "unknown policy \"nope\"",
    ),
    (
        "crawler-controller",
        &["run", "--wait-timeout", "1", "--no-auth"],
        "no plant answered",
    ),
    // an authenticated run (the default) without its plant: no credential to read
    (
        "crawler-controller",
        &["run", "--run-id", "nobody-runs-this", "--wait-timeout", "1"],
        "no credential",
    ),
    (
        "crawler-controller",
        &["run", "--credential", "/", "--wait-timeout", "1"],
        "--credential",
    ),
    ("crawler-recorder", &["record", "--every", "0"], "--every"),
    // a negative number is a value (not a flag the launcher suggests passing on with `--`)
    (
        "crawler",
        &["run", "--t-end", "-1"],
        "--t-end (numerics.t_end) = -1: allowed",
    ),
    // times too long for a clock (they panicked turning into a Duration), written as given
    (
        "crawler-recorder",
        &["record", "--idle-timeout", "1e300"],
        "invalid --idle-timeout = 1e300: allowed",
    ),
    (
        "crawler",
        &["compare", "--run-timeout", "1e300"],
        "invalid --run-timeout = 1e300: allowed",
    ),
    (
        "crawler-plant",
        &["run", "--wait-timeout", "1e300"],
        "invalid --wait-timeout = 1e300: allowed",
    ),
    (
        "crawler-plant",
        &["bench", "--seconds", "1e308"],
        "invalid --seconds = 1e308: allowed",
    ),
    (
        "crawler-plant",
        &["bench", "--plants", "0"],
        "invalid --plants = 0: allowed 1 to 1024",
    ),
];

/// Runs `exe args` and checks that it fails with an error that contains `needle`.
fn fails_with(exe: &str, args: &[&str], needle: &str) {
    // without CARGO the launcher uses the binaries beside it rather than running cargo build
    // (which would rebuild them under the other tests' feet), as in `Proc::spawn`
    let out = std::process::Command::new(bin(exe))
        .env_remove("CARGO")
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{exe} {args:?} should fail");
    assert!(err.contains(needle), "{exe} {args:?}: {err}");
}

#[test]
fn bad_flags_give_clear_errors_and_nonzero_exit() {
    for (exe, args, needle) in BAD_FLAGS {
        fails_with(exe, args, needle);
    }
}

#[test]
fn a_run_id_in_use_is_refused_and_the_running_run_keeps_its_credential() {
    let run = Run::new("dup");
    let plant = |extra: &[&str]| {
        let mut args: Vec<String> = vec!["run".into(), "--run-id".into(), run.id.clone()];
        args.extend(extra.iter().map(|s| s.to_string()));
        Proc::spawn("plant", &bin("crawler-plant"), &args, run.dir.path())
    };
    let first = plant(&["--wait-timeout", "60"]);
    let t0 = Instant::now();
    while !first.stderr_so_far().contains("waiting for a controller") {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "{}",
            first.stderr_so_far()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let credential = first
        .stderr_so_far()
        .split("authenticated with the credential ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .map(std::path::PathBuf::from)
        .expect("the plant names its credential");
    let before = std::fs::read(&credential).unwrap();
    for extra in [&["--wait-timeout", "5"][..], &["--check"][..]] {
        let second = plant(extra).wait(Duration::from_secs(30));
        assert_eq!(second.status.code(), Some(1), "{}", second.stderr);
        assert!(
            second.stderr.contains("--run-id") && second.stderr.contains("already in use"),
            "{}",
            second.stderr
        );
        assert!(!second.stderr.contains(".cargo"), "{}", second.stderr);
    }
    // the launcher refuses it before it creates anything
    let mut child = launcher(&run, &["--out", "x.rrd"]);
    assert_ne!(
        wait_group(&run, &mut child, Duration::from_secs(60)),
        Some(0)
    );
    let err = std::fs::read_to_string(run.path("launcher.err")).unwrap();
    assert!(err.contains("already in use"), "{err}");
    assert_eq!(
        std::fs::read(&credential).unwrap(),
        before,
        "credential replaced"
    );
    first.signal("-INT");
    first.wait(Duration::from_secs(30));
}
