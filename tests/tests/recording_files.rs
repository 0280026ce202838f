//! The recorder's files and its live view, checked with the pinned Rerun CLI of the project's venv
//! (`scripts/setup-python.sh --viewer`): `rerun rrd verify` accepts the recordings of finished and
//! interrupted runs (with the footer), and a real Rerun gRPC server given `--connect` receives the
//! run's decimated stream while the file is written (every scalar, the fields of the last state
//! of each block).

use std::collections::BTreeMap;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crawler_e2e::{read_recording, repo_root, Recording, Run};

const PLANT: &[&str] = &["--eps", "1", "--t-end", "6"];
const WAVE: &[&str] = &["--policy", "wave", "--f0", "0.2", "--alpha", "0.5"];

/// The tests of this file one at a time: each is a whole co-simulation (plant, controller,
/// recorder, and a Rerun viewer) and the 2-core machines they run on would otherwise hold four of
/// them at once. The recorder's link to a viewer is bounded and never slows the run, so a viewer
/// starved of the CPU by the other runs misses data by design, and the test that a viewer which
/// keeps up receives the whole run would depend on the load the tests make themselves.
fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static ONE: std::sync::Mutex<()> = std::sync::Mutex::new(());
    ONE.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The venv's `rerun` (installs it on first use; idempotent).
fn rerun_cli() -> PathBuf {
    static READY: std::sync::OnceLock<Result<PathBuf, String>> = std::sync::OnceLock::new();
    READY
        .get_or_init(|| {
            let root = repo_root();
            let out = Command::new("bash")
                .arg(root.join("scripts/setup-python.sh"))
                .arg("--viewer")
                .output()
                .map_err(|e| format!("cannot run scripts/setup-python.sh: {e}"))?;
            let p = root.join(".venv/bin/rerun");
            if out.status.success() && p.is_file() {
                Ok(p)
            } else {
                Err(format!(
                    "scripts/setup-python.sh --viewer failed: {}",
                    String::from_utf8_lossy(&out.stderr)
                ))
            }
        })
        .clone()
        .unwrap_or_else(|e| panic!("{e}"))
}

/// `rerun rrd verify FILE` (footers checked): its success and what it said.
fn verify(rrd: &Path) -> (bool, String) {
    let out = Command::new(rerun_cli())
        .args(["rrd", "verify"])
        .arg(rrd)
        .env("CI", "1") // no usage analytics from tests
        .output()
        .expect("run rerun rrd verify");
    (
        out.status.success(),
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
    )
}

/// Runs plant, recorder (with `bridge_args`) and controller to the end; returns the recorder's
/// stderr.
fn full_run(run: &Run, rrd: &Path, bridge_args: &[&str]) -> String {
    let plant = run.plant(PLANT);
    let bridge = run.bridge(rrd, bridge_args);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let controller = run.controller(WAVE);
    let p = plant.wait(Duration::from_secs(60));
    assert!(p.status.success(), "{}", p.stderr);
    assert!(controller.wait(Duration::from_secs(30)).status.success());
    let b = bridge.wait(Duration::from_secs(60));
    assert!(b.status.success(), "{}", b.stderr);
    assert!(
        b.stderr.contains("run finished; recording closed"),
        "{}",
        b.stderr
    );
    b.stderr
}

#[test]
fn recordings_of_finished_and_interrupted_runs_pass_rerun_rrd_verify() {
    let _one = one_at_a_time();
    let run = Run::new("verify");
    // an existing recording is replaced by the new one
    let rrd = run.path("done.rrd");
    std::fs::write(&rrd, b"old").unwrap();
    full_run(&run, &rrd, &[]);
    let (ok, said) = verify(&rrd);
    assert!(ok, "finished run: {said}");
    assert!(read_recording(&rrd).unwrap().entity("tail/plant").rows > 1000);

    // without the footer the same check fails: it does look at the end of the file
    let run = Run::new("nofooter");
    let bare = run.path("bare.rrd");
    full_run(&run, &bare, &["--no-footer"]);
    let (ok, said) = verify(&bare);
    assert!(!ok && said.contains("footer"), "{said}");

    // interrupted mid-run: the recorder closes the file properly, footer included
    let run = Run::new("verify-int");
    let rrd = run.path("int.rrd");
    let plant = run.plant(&["--eps", "1", "--t-end", "40"]);
    let bridge = run.bridge(&rrd, &[]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let _controller = run.controller(WAVE);
    let t0 = Instant::now();
    while !rrd.exists() && t0.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(500));
    bridge.signal("-INT");
    let b = bridge.wait(Duration::from_secs(20));
    assert_eq!(b.status.code(), Some(130), "{}", b.stderr);
    assert!(
        b.stderr.contains("interrupted; recording closed properly"),
        "{}",
        b.stderr
    );
    drop(plant);
    let (ok, said) = verify(&rrd);
    assert!(ok, "interrupted run: {said}");
    assert!(read_recording(&rrd).unwrap().entity("tail/plant").rows > 10);
}

/// A Rerun gRPC server on a free loopback port that saves what it receives; the whole process
/// group is terminated on drop.
struct Viewer {
    child: Child,
    url: String,
    saved: PathBuf,
    err: PathBuf,
}

impl Viewer {
    fn start(dir: &Path) -> Self {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let saved = dir.join("viewer.rrd");
        let err = dir.join("viewer.err");
        let child = Command::new(rerun_cli())
            .arg("--save")
            .arg(&saved)
            .args(["--bind", "127.0.0.1", "--port", &port.to_string()])
            .env("CI", "1")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&err).unwrap())
            .process_group(0)
            .spawn()
            .expect("start rerun");
        let v = Self {
            child,
            url: format!("rerun+http://127.0.0.1:{port}/proxy"),
            saved,
            err,
        };
        let deadline = Instant::now() + Duration::from_secs(60);
        while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(
                Instant::now() < deadline,
                "rerun never listened: {}",
                std::fs::read_to_string(&v.err).unwrap_or_default()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        v
    }

    /// Terminates the server (its process group; `--` so that kill reads `-PGID` as a group),
    /// killing it if it does not end within 10 s.
    fn stop(&mut self) {
        let group = format!("-{}", self.child.id());
        let _ = Command::new("kill").args(["-TERM", "--", &group]).status();
        let deadline = Instant::now() + Duration::from_secs(10);
        while matches!(self.child.try_wait(), Ok(None)) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = Command::new("kill").args(["-KILL", "--", &group]).status();
        }
        let _ = self.child.wait();
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Rows per entity path.
fn rows(rec: &Recording) -> BTreeMap<String, usize> {
    rec.entities
        .iter()
        .map(|(k, e)| (k.clone(), e.rows))
        .collect()
}

/// The thick entities, of which a live viewer gets the last state of each block (the fields, the
/// body, the heatmap); it gets every row of the others.
const THICK: [&str; 6] = [
    "fields/u",
    "fields/v",
    "fields/tension",
    "body/segments",
    "body/world",
    "heatmap/u",
];

/// What the viewer got is the file's decimated stream: every row of every thin entity, and of
/// each thick one at least one row and never more than the file has.
fn is_the_decimated_stream(got: &BTreeMap<String, usize>, file: &BTreeMap<String, usize>) -> bool {
    got.keys().eq(file.keys())
        && file.iter().all(|(path, &rows)| {
            let g = got[path];
            if THICK.contains(&path.as_str()) {
                (1..=rows).contains(&g)
            } else {
                g == rows
            }
        })
}

#[test]
fn a_running_viewer_receives_the_decimated_run_while_the_file_gets_every_state() {
    let _one = one_at_a_time();
    let run = Run::new("live");
    let mut viewer = Viewer::start(run.dir.path());
    let rrd = run.path("live.rrd");
    let stderr = full_run(&run, &rrd, &["--connect", &viewer.url]);
    assert!(
        stderr.contains(&format!("the viewer got everything at {}", viewer.url)),
        "{stderr}"
    );
    let file = rows(&read_recording(&rrd).unwrap());
    assert!(file["tail/plant"] > 1000, "{file:?}");
    // the server writes what it received as it arrives; wait (bounded) until it holds it all
    let deadline = Instant::now() + Duration::from_secs(30);
    let got = loop {
        let got = read_recording(&viewer.saved).map(|r| rows(&r)).ok();
        if got
            .as_ref()
            .is_some_and(|g| is_the_decimated_stream(g, &file))
            || Instant::now() > deadline
        {
            break got;
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    viewer.stop();
    assert!(
        got.as_ref()
            .is_some_and(|g| is_the_decimated_stream(g, &file)),
        "the viewer got {got:?}, the file has {file:?}; viewer log: {}",
        std::fs::read_to_string(&viewer.err).unwrap_or_default()
    );
    // the thick entities are decimated: fewer rows than the file, which has every state's
    let got = got.unwrap();
    assert!(got["fields/u"] < file["fields/u"], "{got:?}");
}

#[test]
fn a_viewer_that_goes_away_mid_run_does_not_stop_the_recording() {
    let _one = one_at_a_time();
    let run = Run::new("gone");
    let mut viewer = Viewer::start(run.dir.path());
    let rrd = run.path("gone.rrd");
    let plant = run.plant(&["--eps", "1", "--t-end", "6"]);
    let bridge = run.bridge(&rrd, &["--connect", &viewer.url]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let controller = run.controller(WAVE);
    let t0 = Instant::now();
    while !rrd.exists() && t0.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    viewer.stop();
    let p = plant.wait(Duration::from_secs(60));
    assert!(p.status.success(), "{}", p.stderr);
    assert!(controller.wait(Duration::from_secs(30)).status.success());
    let b = bridge.wait(Duration::from_secs(60));
    assert!(b.status.success(), "{}", b.stderr);
    assert!(
        b.stderr.contains("run finished; recording closed"),
        "{}",
        b.stderr
    );
    assert!(b.stderr.contains("the viewer went away"), "{}", b.stderr);
    // the file has every state all the same
    let tail = read_recording(&rrd).unwrap().entity("tail/plant").clone();
    assert_eq!(tail.steps.first(), Some(&0));
    assert!(tail.steps.windows(2).all(|w| w[1] == w[0] + 1));
    let (ok, said) = verify(&rrd);
    assert!(ok, "{said}");
}

/// `--spawn` starts the viewer itself (here `--viewer-exe`, a wrapper that runs the venv's Rerun
/// as a headless server saving what it receives, with every argument the recorder gives it), on
/// the port of `--connect`, and the viewer gets the decimated run while the file is written.
#[test]
fn spawn_starts_a_viewer_that_receives_the_decimated_run() {
    let _one = one_at_a_time();
    let run = Run::new("spawn");
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let saved = run.path("spawned.rrd");
    let pid_file = run.path("viewer.pid");
    let wrapper = run.path("viewer.sh");
    std::fs::write(
        &wrapper,
        format!(
            "#!/bin/sh\necho $$ > '{}'\nexec env CI=1 '{}' --save '{}' \"$@\" 2>'{}'\n",
            pid_file.display(),
            rerun_cli().display(),
            saved.display(),
            run.path("viewer.err").display()
        ),
    )
    .unwrap();
    std::fs::set_permissions(
        &wrapper,
        std::os::unix::fs::PermissionsExt::from_mode(0o755),
    )
    .unwrap();
    /// Terminates the spawned viewer (by the pid its wrapper wrote) and the process the venv's
    /// `rerun` script starts under it, whatever happens.
    struct Spawned(PathBuf);
    impl Drop for Spawned {
        fn drop(&mut self) {
            if let Ok(pid) = std::fs::read_to_string(&self.0) {
                let _ = Command::new("pkill")
                    .args(["-TERM", "-P", pid.trim()])
                    .status();
                let _ = Command::new("kill").args(["-TERM", pid.trim()]).status();
            }
        }
    }
    let spawned = Spawned(pid_file.clone());
    let url = format!("rerun+http://127.0.0.1:{port}/proxy");
    let rrd = run.path("spawn.rrd");
    let wrapper_arg = wrapper.display().to_string();
    let stderr = full_run(
        &run,
        &rrd,
        &["--connect", &url, "--spawn", "--viewer-exe", &wrapper_arg],
    );
    // the viewer outlives the recorder (the user closes it): the test does, on drop
    assert!(pid_file.is_file(), "the wrapper never ran: {stderr}");
    let file = rows(&read_recording(&rrd).unwrap());
    let deadline = Instant::now() + Duration::from_secs(30);
    let got = loop {
        let got = read_recording(&saved).map(|r| rows(&r)).ok();
        if got
            .as_ref()
            .is_some_and(|g| is_the_decimated_stream(g, &file))
            || Instant::now() > deadline
        {
            break got;
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    drop(spawned);
    assert!(file["tail/plant"] > 1000, "{file:?}");
    let got = got.unwrap_or_else(|| {
        panic!(
            "the spawned viewer saved nothing readable: {stderr}; viewer log: {}",
            std::fs::read_to_string(run.path("viewer.err")).unwrap_or_default()
        )
    });
    if stderr.contains(&format!("the viewer got everything at {url}")) {
        assert!(
            is_the_decimated_stream(&got, &file),
            "the recorder said the viewer got everything: {got:?} of {file:?}"
        );
    } else {
        // A viewer that starts cold with the run may fall behind on a loaded machine: the
        // recorder's link is bounded and never slows the run (tested with a warm viewer above).
        // Then the recorder must say so, and what the viewer has is part of the file.
        assert!(
            stderr.contains("the viewer missed") && stderr.contains("(it was behind)"),
            "neither complete nor said to be incomplete: {stderr}"
        );
        assert!(got["tail/plant"] > 0, "the viewer got no state: {got:?}");
        for (path, rows) in &got {
            assert!(
                file.get(path).is_some_and(|f| rows <= f),
                "{path}: {rows} rows in the viewer, {:?} in the file",
                file.get(path)
            );
        }
    }
}
